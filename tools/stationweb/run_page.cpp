// "/run/ID": everything `stationctl show ID` shows (station/control/record_json.hpp's show_result
// is the content, its render_show_text the text at the page's end), laid out as a page: state,
// verdict, reasons, the run's facts and archive, capture counters, the gap diagnosis, the other
// units of its table run, both methods' parameters with 1-σ, and the cross-check per parameter.
#include <algorithm>
#include <cctype>
#include <optional>

#include "db/history/fleet_stats.hpp"
#include "station/control/record_json.hpp"
#include "tools/stationweb/html.hpp"
#include "tools/stationweb/next_step.hpp"
#include "tools/stationweb/pages.hpp"
#include "tools/stationweb/run_page_parts.hpp"
#include "tools/stationweb/run_table.hpp"

namespace imucal::tools::stationweb {

namespace {

using nlohmann::json;

db::history::RunId parse_run_id(const std::string& text) {
  bool digits = !text.empty() && text.size() <= 18;
  for (char c : text) digits = digits && std::isdigit(static_cast<unsigned char>(c));
  const db::history::RunId id = digits ? std::stoll(text) : 0;
  if (id < 1)
    bad_input("run id", "\"" + text.substr(0, 40) + "\" is not a run number (a whole number >= 1)");
  return id;
}

std::string head(const db::history::RunRecord& r) {
  const std::string cv = r.crosscheck_verdict ? db::history::to_string(*r.crosscheck_verdict) : "";
  std::string s = "<h1>Run " + std::to_string(r.run_id) + " · " + unit_link(r.serial) + "</h1>\n";
  s += "<p id='run-head' data-run-id='" + std::to_string(r.run_id) + "' data-serial='" +
       esc(r.serial) + "' data-state='" + db::history::to_string(r.state) + "' data-verdict='" +
       (r.verdict ? db::history::to_string(*r.verdict) : "") + "' data-crosscheck-verdict='" + cv +
       "'>State <b>" + db::history::to_string(r.state) + "</b>, verdict " +
       verdict_html(r.verdict) + (cv.empty() ? "" : " (cross-check " + cv + ")") + "</p>\n";
  if (!r.reasons.empty()) {
    s += "<ul id='reasons'>\n";
    for (const db::history::RunReason& reason : r.reasons)
      s += "<li data-source='" + esc(reason.source) + "'>[" + esc(reason.source) + "] " +
           esc(reason.text) + "</li>\n";
    s += "</ul>\n";
  }
  return s;
}

/// The other units of the run's table run (several units on one fixture), if any.
std::string siblings(const History& history, const db::history::RunRecord& r) {
  const db::history::RunId table_run = r.table_run_id ? *r.table_run_id : r.run_id;
  const std::vector<db::history::RunId> ids = history.stats->table_run_members(table_run);
  if (ids.size() < 2) return "";
  std::vector<db::history::RunRecord> runs;
  for (db::history::RunId id : ids) runs.push_back(history.repo->show(id).run);
  return "<h2>Units of table run " + std::to_string(table_run) + "</h2>\n" +
         run_table(runs, true, "siblings");
}

/// The runs reprocessed from `r` (newest first): the other direction of "reprocessed from", so a
/// run whose reason says "reprocess it" leads to its reprocess (issue #52 item 8).
std::vector<db::history::RunRecord> reprocesses_of(const History& history,
                                                   const db::history::RunRecord& r) {
  std::vector<db::history::RunRecord> out;
  try {
    for (db::history::RunRecord& x : history.repo->history(r.serial))
      if (x.reprocessed_from && *x.reprocessed_from == r.run_id) out.push_back(std::move(x));
  } catch (const db::history::DbError&) {
    // a serial stored before the serial rule cannot be looked up by name: no links, no failure
  }
  return out;
}

/// The newest run of the reprocess chain from `r`: its newest reprocess, that one's newest, ...
/// (21 → 22 → 23: 23); nullopt when `r` has none.
std::optional<db::history::RunRecord> newest_of_chain(
    const History& history, const std::vector<db::history::RunRecord>& reprocesses) {
  if (reprocesses.empty()) return std::nullopt;
  db::history::RunRecord n = reprocesses.front();
  for (int hops = 0; hops < 1000; ++hops) {
    const std::vector<db::history::RunRecord> next = reprocesses_of(history, n);
    if (next.empty()) break;
    n = next.front();
  }
  return n;
}

std::string reprocess_links(const std::vector<db::history::RunRecord>& reprocesses,
                            const std::optional<db::history::RunRecord>& newest) {
  if (reprocesses.empty()) return "";
  std::string s = "<p id='reprocessed-as'>Reprocessed as run";
  s += reprocesses.size() > 1 ? "s " : " ";
  for (std::size_t i = 0; i < reprocesses.size(); ++i)
    s += (i ? ", " : "") + run_link(reprocesses[i].run_id) + " (" +
         verdict_html(reprocesses[i].verdict) + ")";
  if (newest && newest->run_id != reprocesses.front().run_id)
    s += "; reprocessed again since: the newest of the chain is run " + run_link(newest->run_id) +
         " (" + verdict_html(newest->verdict) + ")";
  return s + ".</p>\n";
}

bool has_method(const History& history, db::history::RunId id, db::history::Method m) {
  try {
    for (const auto& c : history.repo->show(id).calibrations)
      if (c.method == m) return true;
  } catch (const db::history::NotFound&) {
  }
  return false;
}

/// "Compare this run with another" where the run has an AINS calibration (/compare's default
/// method; a run without one — interrupted, a station fault, aborted — has nothing to compare:
/// the link was a 400), paired with its newest reprocess or the run it reprocessed when that one
/// has a calibration too.
std::string compare_link(const History& history, const db::history::RunDetails& d,
                         const std::optional<db::history::RunRecord>& newest) {
  const auto ains = [](const db::history::CalibrationRecord& c) {
    return c.method == db::history::Method::kAins;
  };
  if (std::none_of(d.calibrations.begin(), d.calibrations.end(), ains)) return "";
  std::optional<db::history::RunId> other;
  if (newest)
    other = newest->run_id;
  else if (d.run.reprocessed_from)
    other = *d.run.reprocessed_from;
  if (other && !has_method(history, *other, db::history::Method::kAins)) other.reset();
  return "<p class='muted' id='compare-link'><a href='/compare?a=" + std::to_string(d.run.run_id) +
         (other ? "&amp;b=" + std::to_string(*other) : std::string()) +
         "'>Compare this run with another</a></p>\n";
}

std::optional<bool> capture_complete(const json& run) {
  if (!run.contains("capture") || !run["capture"].is_object()) return std::nullopt;
  const json& c = run["capture"];
  if (!c.contains("complete") || !c["complete"].is_boolean()) return std::nullopt;
  return c["complete"].get<bool>();
}

/// The run's details, or 404 naming it.
db::history::RunDetails details_of(const History& history, db::history::RunId id) {
  try {
    return history.repo->show(id);
  } catch (const db::history::NotFound&) {
    throw PageError(404, "run id", "No run " + std::to_string(id) + " in this history.");
  }
}

}  // namespace

Reply run_reply(const History& history, const std::string& run_id_text, const Params& query) {
  check_known_params(query, {"format"});
  const Format format = parse_format(query);
  if (format == Format::kHtml) return Reply(run_page(history, run_id_text));
  const db::history::RunId id = parse_run_id(run_id_text);
  const db::history::RunDetails details = details_of(history, id);
  const std::string name = "run-" + std::to_string(id);
  if (format == Format::kJson)  // what `stationctl show ID --json` prints
    return {station::control::show_result(details).dump(2) + "\n", "application/json",
            name + ".json"};
  // CSV: the parameter table, a row per method and parameter, SI values.
  std::string out = "run_id,method,parameter,value_si,sigma_si,determined,human_unit,si_to_human\n";
  for (const auto& c : details.calibrations) {
    const calib::core::ParamVector v = c.params.to_vector(), sd = c.sigma.to_vector();
    for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
      const calib::core::ParamInfo& info = calib::core::param_info(i);
      const bool determined = std::find(c.unobservable.begin(), c.unobservable.end(), info.name) ==
                              c.unobservable.end();
      out += std::to_string(id) + "," + db::history::to_string(c.method) + "," + info.name + "," +
             (determined ? exact(v(i)) : "") + "," + (determined ? exact(sd(i)) : "") + "," +
             (determined ? "1" : "0") + "," + csv_field(info.human_unit) + "," +
             exact(info.si_to_human) + "\n";
    }
  }
  return {out, "text/csv; charset=utf-8", name + ".csv"};
}

std::string run_page(const History& history, const std::string& run_id_text) {
  const db::history::RunId id = parse_run_id(run_id_text);
  const db::history::RunDetails details = details_of(history, id);
  const json show = station::control::show_result(details);
  const db::history::RunRecord& r = details.run;
  const std::vector<db::history::RunRecord> reprocesses = reprocesses_of(history, r);
  const std::optional<db::history::RunRecord> newest = newest_of_chain(history, reprocesses);
  std::string b = head(r);
  b += next_step_section(next_steps(r, reprocesses, capture_complete(show["run"]), newest));
  b += reprocess_links(reprocesses, newest);
  b += compare_link(history, details, newest);
  b += "<h2>Run</h2>\n" + facts_table(r);
  b += siblings(history, r);
  b += capture_section(show["run"]);
  b += diagnosis_section(show["run"]);
  b += "<h2>Calibration (value ± 1σ)</h2>\n" + calibration_table(details.calibrations);
  if (!details.calibrations
           .empty())  // CSV: the parameters; JSON: what stationctl show --json prints
    b += download_links("/run/" + std::to_string(id));
  b += method_lines(details.calibrations);
  b += crosscheck_section(details);
  b += "<details id='show-text'><summary>As <code>stationctl show " + std::to_string(id) +
       "</code> prints it</summary>\n<pre>" + esc(station::control::render_show_text(show)) +
       "</pre></details>\n";
  return page("Run " + std::to_string(id), b);
}

}  // namespace imucal::tools::stationweb
