#include "tools/stationweb/run_table.hpp"

#include <algorithm>
#include <map>

#include "calib/core/param_set.hpp"
#include "db/history/fleet_stats.hpp"
#include "station/control/record_json.hpp"
#include "tools/stationweb/html.hpp"

namespace imucal::tools::stationweb {

std::string verdict_html(const std::optional<db::history::RunVerdict>& verdict) {
  if (!verdict) return "-";
  const std::string v = db::history::to_string(*verdict);
  return "<span class='" + v + "'>" + v + "</span>";
}

namespace {

/// Each run's direct reprocesses and, for a run that does not stand for its capture, the run that
/// does (db::history::superseded_runs: the one run of a capture it does not list).
struct Reprocesses {
  std::map<db::history::RunId, std::vector<db::history::RunId>> as;
  std::map<db::history::RunId, db::history::RunId> newest;
};

Reprocesses reprocesses_of(const std::vector<db::history::ReprocessLink>& links) {
  Reprocesses out;
  std::map<db::history::RunId, db::history::RunId> origin_of;
  for (const auto& l : links) out.as[l.origin].push_back(l.run), origin_of[l.run] = l.origin;
  const auto root_of = [&](db::history::RunId run) {
    for (std::size_t hops = 0; hops <= origin_of.size(); ++hops) {
      const auto it = origin_of.find(run);
      if (it == origin_of.end()) break;
      run = it->second;
    }
    return run;
  };
  const std::vector<db::history::RunId> superseded = db::history::superseded_runs(links);
  std::map<db::history::RunId, db::history::RunId> standing;  // root -> the run standing for it
  for (const auto& l : links)
    for (const auto run : {l.run, l.origin})
      if (!std::binary_search(superseded.begin(), superseded.end(), run))
        standing[root_of(run)] = run;
  for (const auto run : superseded) out.newest[run] = standing[root_of(run)];
  return out;
}

/// The reason cell's links: "reprocess of run N", "→ run M" (and the capture's newest).
std::string reprocess_note(const db::history::RunRecord& r, const Reprocesses* rep) {
  if (!rep) return "";
  std::string s;
  if (r.reprocessed_from)
    s += " <span class='reprocess-of'>reprocess of <a href='/run/" +
         std::to_string(*r.reprocessed_from) + "'>run " + std::to_string(*r.reprocessed_from) +
         "</a></span>";
  if (const auto it = rep->as.find(r.run_id); it != rep->as.end()) {
    s += " <span class='reprocessed-as'>→ reprocessed as ";
    for (std::size_t i = 0; i < it->second.size(); ++i)
      s += std::string(i ? ", " : "") + "<a href='/run/" + std::to_string(it->second[i]) +
           "'>run " + std::to_string(it->second[i]) + "</a>";
    const auto newest = rep->newest.find(r.run_id);
    if (newest != rep->newest.end() &&
        std::find(it->second.begin(), it->second.end(), newest->second) == it->second.end())
      s += "; the capture's newest, which decides: <a href='/run/" +
           std::to_string(newest->second) + "'>run " + std::to_string(newest->second) + "</a>";
    s += "</span>";
  }
  return s;
}

/// Seconds from start to end, or nullopt while live.
std::optional<double> duration_s(const db::history::RunRecord& r) {
  if (!r.ended_at_ms) return std::nullopt;
  return static_cast<double>(*r.ended_at_ms - r.started_at_ms) / 1000.0;
}

/// "land (imported)": a run recorded elsewhere says so in its setting cell.
std::string setting_text(const db::history::RunRecord& r) {
  std::string s = calib::core::setting_name(r.setting);
  if (!r.origin.empty()) s += " (imported)";
  return s;
}

/// The run cell: its link, * (reprocessed, the origin linked in the tooltip's place) and ^.
std::string run_cell(const db::history::RunRecord& r) {
  std::string s = run_link(r.run_id);
  if (r.reprocessed_from)
    s += "<a class='mark' title='reprocessed from run " + std::to_string(*r.reprocessed_from) +
         "' href='/run/" + std::to_string(*r.reprocessed_from) + "'>*</a>";
  if (r.promoted_at_ms) s += "<span class='mark' title='promoted by QA'>^</span>";
  return s;
}

std::string reprocess_attrs(const db::history::RunRecord& r, const Reprocesses* rep) {
  if (!rep) return "";
  std::string as;
  if (const auto it = rep->as.find(r.run_id); it != rep->as.end())
    for (const auto m : it->second) as += (as.empty() ? "" : ",") + std::to_string(m);
  const auto newest = rep->newest.find(r.run_id);
  return " data-reprocessed-as='" + as + "' data-capture-newest='" +
         (newest != rep->newest.end() ? std::to_string(newest->second) : "") + "'";
}

std::string row_attrs(const db::history::RunRecord& r, const Reprocesses* rep) {
  const auto d = duration_s(r);
  return "<tr class='run' data-run-id='" + std::to_string(r.run_id) + "' data-serial='" +
         esc(r.serial) + "' data-state='" + db::history::to_string(r.state) + "' data-verdict='" +
         (r.verdict ? db::history::to_string(*r.verdict) : "") + "' data-station='" +
         esc(r.station) + "' data-started-ms='" + std::to_string(r.started_at_ms) +
         "' data-setting='" + calib::core::setting_name(r.setting) + "' data-origin='" +
         esc(r.origin) + "' data-operator='" + esc(r.operator_name) + "' data-duration-s='" +
         (d ? fmt("%.3f", *d) : "") + "' data-reprocessed-from='" +
         (r.reprocessed_from ? std::to_string(*r.reprocessed_from) : "") + "'" +
         reprocess_attrs(r, rep) + ">";
}

std::string run_row(const db::history::RunRecord& r, bool with_serial, const std::string* extra,
                    const Reprocesses* rep) {
  const nlohmann::json j = station::control::run_record_json(r);
  const auto d = duration_s(r);
  std::string s = row_attrs(r, rep) + "<td class='num'>" + run_cell(r) + "</td>";
  if (with_serial) s += "<td>" + unit_link(r.serial) + "</td>";
  s += "<td>" + short_time(r.started_at_ms) + "</td><td>" + esc(setting_text(r)) + "</td><td>" +
       db::history::to_string(r.state) + "</td><td>" + verdict_html(r.verdict) + "</td><td>" +
       std::string(r.crosscheck_verdict ? db::history::to_string(*r.crosscheck_verdict) : "-") +
       "</td>";
  s += "<td>" + esc(r.station) + "</td><td>" + esc(station::control::slot_cell(j)) + "</td><td>" +
       esc(r.sequence_name) + "</td><td>" + esc(r.operator_name) + "</td><td class='num'>" +
       (d ? station::control::format_duration_s(*d) : "-") + "</td><td>" +
       esc(station::control::gap_cell(j)) + "</td><td class='reason'>" + esc(r.failure_reason) +
       reprocess_note(r, rep) + "</td>";
  if (extra) s += "<td class='num'>" + *extra + "</td>";
  return s + "</tr>\n";
}

std::string table(const std::vector<db::history::RunRecord>& runs, bool with_serial,
                  const std::string& id, const std::string& extra_header,
                  const std::vector<std::string>& extra_cells, const Reprocesses* rep) {
  std::string s = "<table id='" + esc(id) + "'>\n<tr><th>Run</th>";
  if (with_serial) s += "<th>Serial</th>";
  s += "<th>Started (UTC)</th><th>Setting</th><th>State</th><th>Verdict</th><th>Cross-check</th>"
       "<th>Station</th><th>Slot</th><th>Sequence</th><th>Operator</th><th>Duration</th>"
       "<th>Gap (best effect)</th><th>Reason</th>";
  if (!extra_header.empty()) s += "<th>" + extra_header + "</th>";
  s += "</tr>\n";
  for (std::size_t i = 0; i < runs.size(); ++i)
    s += run_row(runs[i], with_serial, i < extra_cells.size() ? &extra_cells[i] : nullptr, rep);
  s += "</table>\n";
  bool reprocessed = false, promoted = false;
  for (const auto& r : runs) {
    reprocessed = reprocessed || r.reprocessed_from;
    promoted = promoted || r.promoted_at_ms;
  }
  if (reprocessed) s += "<p class='muted'>* reprocessed from an earlier run's archive</p>\n";
  if (promoted) s += "<p class='muted'>^ field run promoted by QA to the active parameters</p>\n";
  return s;
}

}  // namespace

std::string run_table(const std::vector<db::history::RunRecord>& runs, bool with_serial,
                      const std::string& id, const std::string& extra_header,
                      const std::vector<std::string>& extra_cells) {
  return table(runs, with_serial, id, extra_header, extra_cells, nullptr);
}

std::string run_table(const History& history, const std::vector<db::history::RunRecord>& runs,
                      bool with_serial, const std::string& id, const std::string& extra_header,
                      const std::vector<std::string>& extra_cells) {
  const Reprocesses rep = reprocesses_of(history.stats->reprocess_links());
  return table(runs, with_serial, id, extra_header, extra_cells, &rep);
}

std::string run_list_json(const std::string& serial,
                          const std::vector<db::history::RunRecord>& runs, std::size_t total) {
  nlohmann::json h = station::control::history_result(serial, runs, total);
  if (serial.empty()) h["serial"] = nullptr;
  return h.dump(2) + "\n";
}

std::string download_links(const std::string& target) {
  const char sep = target.find('?') == std::string::npos ? '?' : '&';
  return "<p class='downloads muted'>This table as <a class='csv' href='" + esc(target) + sep +
         "format=csv'>CSV</a> · <a class='json' href='" + esc(target) + sep +
         "format=json'>JSON</a></p>\n";
}

std::string csv_field(const std::string& text) {
  if (text.find_first_of(",\"\r\n") == std::string::npos) return text;
  std::string s = "\"";
  for (char c : text) s += c == '"' ? std::string("\"\"") : std::string(1, c);
  return s + "\"";
}

std::string run_list_csv(const std::vector<db::history::RunRecord>& runs,
                         const std::string& extra_header,
                         const std::vector<std::string>& extra_values) {
  std::string s =
      "run_id,serial,started_at,setting,origin,state,verdict,crosscheck_verdict,station,slot,"
      "sequence,operator,duration_s,reprocessed_from,promoted,gap,reason";
  if (!extra_header.empty()) s += "," + csv_field(extra_header);
  s += "\n";
  for (std::size_t i = 0; i < runs.size(); ++i) {
    const db::history::RunRecord& r = runs[i];
    const auto d = duration_s(r);
    const nlohmann::json j = station::control::run_record_json(r);
    const std::vector<std::string> cells = {
        std::to_string(r.run_id),
        r.serial,
        db::history::format_time_utc(r.started_at_ms),
        calib::core::setting_name(r.setting),
        r.origin,
        db::history::to_string(r.state),
        r.verdict ? db::history::to_string(*r.verdict) : "",
        r.crosscheck_verdict ? db::history::to_string(*r.crosscheck_verdict) : "",
        r.station,
        r.slot,
        r.sequence_name,
        r.operator_name,
        d ? fmt("%.3f", *d) : "",
        r.reprocessed_from ? std::to_string(*r.reprocessed_from) : "",
        r.promoted_at_ms ? "yes" : "",
        station::control::gap_cell(j),
        r.failure_reason};
    std::string line;
    for (const std::string& c : cells) line += (line.empty() ? "" : ",") + csv_field(c);
    if (!extra_header.empty())
      line += "," + csv_field(i < extra_values.size() ? extra_values[i] : "");
    s += line + "\n";
  }
  return s;
}

}  // namespace imucal::tools::stationweb
