#include "tools/stationweb/run_table.hpp"

#include "station/control/record_json.hpp"
#include "tools/stationweb/html.hpp"

namespace imucal::tools::stationweb {

std::string verdict_html(const std::optional<db::history::RunVerdict>& verdict) {
  if (!verdict) return "-";
  const std::string v = db::history::to_string(*verdict);
  return "<span class='" + v + "'>" + v + "</span>";
}

namespace {

std::string run_row(const db::history::RunRecord& r, bool with_serial) {
  const nlohmann::json j = station::control::run_record_json(r);
  std::string s = "<tr class='run' data-run-id='" + std::to_string(r.run_id) + "' data-serial='" +
                  esc(r.serial) + "' data-state='" + db::history::to_string(r.state) +
                  "' data-verdict='" + (r.verdict ? db::history::to_string(*r.verdict) : "") +
                  "' data-station='" + esc(r.station) + "' data-started-ms='" +
                  std::to_string(r.started_at_ms) + "'>";
  s += "<td class='num'>" + run_link(r.run_id) + "</td>";
  if (with_serial) s += "<td>" + unit_link(r.serial) + "</td>";
  s += "<td>" + short_time(r.started_at_ms) + "</td><td>" + db::history::to_string(r.state) +
       "</td>";
  s += "<td>" + verdict_html(r.verdict) + "</td>";
  s += "<td>" +
       std::string(r.crosscheck_verdict ? db::history::to_string(*r.crosscheck_verdict) : "-") +
       "</td>";
  s += "<td>" + esc(r.station) + "</td><td>" + esc(station::control::slot_cell(j)) + "</td>";
  s += "<td>" + esc(r.sequence_name) + "</td><td>" + esc(station::control::gap_cell(j)) +
       "</td></tr>\n";
  return s;
}

}  // namespace

std::string run_table(const std::vector<db::history::RunRecord>& runs, bool with_serial,
                      const std::string& id) {
  std::string s = "<table id='" + esc(id) + "'>\n<tr><th>Run</th>";
  if (with_serial) s += "<th>Serial</th>";
  s += "<th>Started (UTC)</th><th>State</th><th>Verdict</th><th>Cross-check</th><th>Station</th>"
       "<th>Slot</th><th>Sequence</th><th>Gap (best effect)</th></tr>\n";
  for (const db::history::RunRecord& r : runs) s += run_row(r, with_serial);
  return s + "</table>\n";
}

}  // namespace imucal::tools::stationweb
