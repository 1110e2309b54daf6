#include "station/control/record_json.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <stdexcept>
#include <utility>

#include "calib/core/param_set.hpp"
#include "db/archive/param_json.hpp"
#include "db/history/export.hpp"
#include "db/history/export_per_run.hpp"

namespace imucal::station::control {

using nlohmann::json;

namespace {

std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

std::string str(const json& o, const char* key, const std::string& fallback = "") {
  const auto it = o.find(key);
  if (it == o.end() || it->is_null()) return fallback;
  if (it->is_string()) return it->get<std::string>();
  return it->dump();
}

bool has(const json& o, const char* key) {
  const auto it = o.find(key);
  return it != o.end() && !it->is_null();
}

/// Pads (by code points, so "µg" counts as two columns) or leaves as is when longer.
std::string pad(const std::string& s, std::size_t width) {
  std::size_t cols = 0;
  for (unsigned char c : s)
    if ((c & 0xC0) != 0x80) ++cols;
  return cols >= width ? s : s + std::string(width - cols, ' ');
}

std::string lpad(const std::string& s, std::size_t width) {
  std::size_t cols = 0;
  for (unsigned char c : s)
    if ((c & 0xC0) != 0x80) ++cols;
  return cols >= width ? s : std::string(width - cols, ' ') + s;
}

std::string rtrim(std::string s) {
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s;
}

/// Duration of a run from its ms timestamps, or "" when not ended.
std::string run_duration(const json& run) {
  if (!has(run, "ended_at_ms") || !has(run, "started_at_ms")) return "";
  const double s = static_cast<double>(run["ended_at_ms"].get<long long>() -
                                       run["started_at_ms"].get<long long>()) /
                   1000.0;
  return format_duration_s(s);
}

/// The run's state as people read it: with stationctl's "state_note" when the database said it
/// and the daemon did not answer ("running (daemon not answering)", issue #50 item 2).
std::string state_cell(const json& run) {
  const std::string state = str(run, "state");
  return has(run, "state_note") ? state + " (" + str(run, "state_note") + ")" : state;
}

/// "yyyy-mm-dd hh:mm:ss" out of the ISO text (people do not need the milliseconds in a table).
std::string short_time(const std::string& iso) {
  if (iso.size() < 19) return iso;
  std::string s = iso.substr(0, 19);
  s[10] = ' ';
  return s;
}

}  // namespace

// ----- JSON shapes ------------------------------------------------------------------------------

json run_record_json(const db::history::RunRecord& run) {
  // db::history::run_json carries "capture" (RunRecord::capture_json parsed, null when empty) since
  // schema v2; one definition of the run's JSON for the export and the control socket.
  return db::history::run_json(run);
}

json history_result(const std::string& serial, const std::vector<db::history::RunRecord>& runs,
                    std::size_t total) {
  json list = json::array();
  for (const auto& r : runs) list.push_back(run_record_json(r));
  return {{"serial", serial}, {"runs", std::move(list)}, {"total", std::max(total, runs.size())}};
}

json show_result(const db::history::RunDetails& details) {
  json o = db::history::run_details_json(details);
  o["run"] = run_record_json(details.run);
  return o;
}

json params_result(const db::history::ActiveCalibration& active) {
  return db::history::active_params_json(active);
}

json export_result(const db::history::Repository& repo, const db::history::ExportFilter& filter,
                   const std::string& format, bool per_run) {
  // A whole-history export is hundreds of MB: keep one copy of the text at a time (the stream's
  // buffer is gone before the JSON takes the string over by move).
  std::size_t rows = 0;
  std::string content;
  {
    std::ostringstream out;
    rows = db::history::export_in_shape(repo, filter, format, per_run, out);
    content = out.str();
  }
  json result = json::object();
  result["format"] = format;
  result["rows"] = rows;
  result["content"] = std::move(content);
  return result;
}

db::history::ExportFilter export_filter(const db::history::Repository& repo, const json& args) {
  db::history::ExportFilter filter;
  if (args.contains("serial")) {
    filter.serial = args.at("serial").get<std::string>();
    // The export of an unknown or malformed serial would silently be empty; say so instead.
    (void)repo.history(*filter.serial, 1);
  }
  if (args.contains("since"))
    filter.since_ms = db::history::parse_time_utc(args.at("since").get<std::string>());
  if (args.contains("station")) filter.station = args.at("station").get<std::string>();
  return filter;
}

json answer_repository_read(const db::history::Repository& repo, const Request& request) {
  const json& a = request.args;
  if (request.cmd == cmd::kHistory && a.contains("station")) {
    // One station's runs (in the fleet store: one of many), of a unit or of every unit.
    std::optional<std::string> serial;
    if (a.contains("serial")) serial = a.at("serial").get<std::string>();
    const std::size_t limit = a.contains("limit") ? a.at("limit").get<std::size_t>()
                              : serial            ? 0
                                                  : kAllUnitsHistoryLimit;
    const std::string station = a.at("station").get<std::string>();
    const auto runs = repo.station_runs(station, serial, limit);
    // N of the station's runs, not of every station's.
    json h = history_result(serial.value_or(""), runs, repo.station_run_count(station, serial));
    if (!serial) h["serial"] = nullptr;
    h["station"] = a.at("station");
    return h;
  }
  if (request.cmd == cmd::kHistory) {
    if (!a.contains("serial")) {
      // Every unit's newest runs (issue #19 item 11), a screenful unless asked for more.
      const std::size_t limit =
          a.contains("limit") ? a.at("limit").get<std::size_t>() : kAllUnitsHistoryLimit;
      json h = history_result("", repo.recent_runs(limit), repo.total_run_count());
      h["serial"] = nullptr;
      return h;
    }
    const std::string serial = a.at("serial").get<std::string>();
    const std::size_t limit = a.contains("limit") ? a.at("limit").get<std::size_t>() : 0;
    return history_result(serial, repo.history(serial, limit), repo.run_count(serial));
  }
  if (request.cmd == cmd::kShow)
    return show_result(repo.show(a.at("run_id").get<db::history::RunId>()));
  if (request.cmd == cmd::kParams)
    return params_result(repo.active_params(a.at("serial").get<std::string>()));
  if (request.cmd == cmd::kExport)
    return export_result(repo, export_filter(repo, a), a.at("format").get<std::string>(),
                         a.value("per_run", false));
  throw std::invalid_argument("not a repository read: " + request.cmd);
}

// ----- Text -------------------------------------------------------------------------------------

std::string format_duration_s(double seconds) {
  if (!std::isfinite(seconds) || seconds < 0) return "?";
  const long long s = std::llround(seconds);
  char buf[64];
  if (s < 60)
    std::snprintf(buf, sizeof buf, "%lld s", s);
  else if (s < 3600)
    std::snprintf(buf, sizeof buf, "%lld min %02lld s", s / 60, s % 60);
  else
    std::snprintf(buf, sizeof buf, "%lld h %02lld min", s / 3600, (s % 3600) / 60);
  return buf;
}

namespace {

std::string magnitude_text(const json& best) {
  char buf[96];
  const double m = best.value("magnitude", 0.0), sg = best.value("sigma", 0.0);
  std::snprintf(buf, sizeof buf, "%.3g±%.2g %s", m, sg, best.value("unit", std::string()).c_str());
  return buf;
}

}  // namespace

/// The history's SLOT cell: the slot, and the table run it shared with its siblings.
std::string slot_cell(const json& r) {
  std::string s = str(r, "slot");
  if (has(r, "table_run")) s += " of " + str(r, "table_run");
  return s.empty() ? "-" : s;
}

std::string gap_cell(const json& run) {
  if (!has(run, "diagnosis") || !run["diagnosis"].is_object()) return "-";
  const json& d = run["diagnosis"];
  if (d.contains("best") && d["best"].is_object())
    return d["best"].value("effect", std::string("?")) + " " + magnitude_text(d["best"]);
  if (d.contains("ambiguous") && d["ambiguous"].is_array() && !d["ambiguous"].empty()) {
    std::string s;
    for (const auto& a : d["ambiguous"]) s += (s.empty() ? "" : "|") + a.get<std::string>();
    return s;
  }
  return d.value("verdict", std::string("?"));
}

namespace {

/// A unit's yield over the runs listed (issue #50): PASS among its own outcomes (PASS, REVIEW,
/// FAILED); the station's faults, operators' aborts and interrupted runs are named apart and never
/// count against the unit. "" when nothing has ended.
std::string unit_yield_line(const json& runs) {
  long own = 0, pass = 0, station = 0, aborted = 0, interrupted = 0;
  for (const auto& r : runs) {
    const std::string v = str(r, "verdict");
    own += v == "PASS" || v == "REVIEW" || v == "FAILED";
    pass += v == "PASS";
    station += v == "STATION-FAULT";
    aborted += v == "ABORTED";
    interrupted += v == "INTERRUPTED";
  }
  if (own + station + aborted + interrupted == 0) return "";
  std::string s = "Yield: " + std::to_string(pass) + " PASS of " + std::to_string(own) +
                  " run(s) the unit decided";
  if (own > 0) s += " (" + std::to_string((100 * pass + own / 2) / own) + " %)";
  if (station + aborted + interrupted > 0)
    s += "; not the unit's: " + std::to_string(station) + " station fault(s), " +
         std::to_string(aborted) + " abort(s), " + std::to_string(interrupted) + " interrupted";
  return s + "\n";
}

}  // namespace

std::string render_history_text(const json& history) {
  std::ostringstream os;
  const json& runs = history.at("runs");
  const std::string serial = str(history, "serial");
  const bool all_units = serial.empty();
  if (runs.empty()) {
    os << "No runs of " << (all_units ? std::string("any unit") : serial) << ".\n";
    return os.str();
  }
  const std::size_t total = history.value("total", runs.size());
  os << "History of " << (all_units ? std::string("all units") : serial) << " (";
  if (total > runs.size())
    os << "newest " << runs.size() << " of " << total << " runs";
  else
    os << runs.size() << (runs.size() == 1 ? " run" : " runs") << ", newest first";
  os << ")\n";
  bool any_slot = false;  // a fixture with several slots: which slot and table run
  for (const auto& r : runs) any_slot = any_slot || !str(r, "slot").empty();
  std::size_t state_width = 13;  // wider where a state carries its note
  for (const auto& r : runs) state_width = std::max(state_width, state_cell(r).size() + 2);
  os << pad("RUN", 7) << (all_units ? pad("SERIAL", 16) : "") << (any_slot ? pad("SLOT", 10) : "")
     << pad("STARTED (UTC)", 21) << pad("SETTING", 9) << pad("STATE", state_width)
     << pad("VERDICT", 15) << pad("CROSS-CHECK", 13) << pad("SEQUENCE", 16) << pad("OPERATOR", 14)
     << pad("DURATION", 13) << pad("GAP (best effect)", 40) << "REASON\n";
  for (const auto& r : runs) {
    std::string id = str(r, "run_id");
    if (has(r, "reprocessed_from")) id += "*";
    if (has(r, "promoted_at")) id += "^";
    const std::string duration = run_duration(r);
    os << rtrim(pad(id, 7) + (all_units ? pad(str(r, "serial"), 16) : "") +
                (any_slot ? pad(slot_cell(r), 10) : "") +
                pad(short_time(str(r, "started_at")), 21) + pad(str(r, "setting", "factory"), 9) +
                pad(state_cell(r), state_width) + pad(str(r, "verdict", "-"), 15) +
                pad(str(r, "crosscheck_verdict", "-"), 13) + pad(str(r, "sequence_name"), 16) +
                pad(str(r, "operator"), 14) + pad(duration.empty() ? "-" : duration, 13) +
                pad(gap_cell(r), 40) + str(r, "failure_reason"))
       << "\n";
  }
  bool any_reprocessed = false;
  for (const auto& r : runs) any_reprocessed = any_reprocessed || has(r, "reprocessed_from");
  if (any_reprocessed) os << "* reprocessed from an earlier run's archive\n";
  bool any_promoted = false;
  for (const auto& r : runs) any_promoted = any_promoted || has(r, "promoted_at");
  if (any_promoted)
    os << "^ field run promoted by QA to the active parameters (stationctl show RUN for why)\n";
  if (!all_units) os << unit_yield_line(runs);
  return os.str();
}

namespace {

void render_capture(std::ostream& os, const json& capture) {
  os << "Capture";
  if (capture.contains("complete") && capture["complete"].is_boolean())
    os << (capture["complete"].get<bool>() ? " (complete)" : " (INCOMPLETE: recovered archive)");
  os << "\n";
  int column = 0;
  for (auto it = capture.begin(); it != capture.end(); ++it) {
    if (it.key() == "complete") continue;
    os << "  " << pad(it.key(), 20)
       << lpad(it->is_string() ? it->get<std::string>() : it->dump(), 12);
    os << (++column % 2 == 0 ? "\n" : "");
  }
  if (column % 2 != 0) os << "\n";
}

/// The run's reasons, one per line with its source ("  gap: sim-to-real gap: ..."); a run stored
/// without the list (none in JSON) falls back to its failure_reason.
void render_reasons(std::ostream& os, const json& run) {
  const bool listed = run.contains("reasons") && run["reasons"].is_array();
  if (listed && run["reasons"].empty()) return;
  if (!listed) {
    if (!str(run, "failure_reason").empty())
      os << "  reason: " << str(run, "failure_reason") << "\n";
    return;
  }
  const std::size_t n = run["reasons"].size();
  os << "  " << (n == 1 ? "reason" : std::to_string(n) + " reasons") << ":\n";
  for (const json& r : run["reasons"])
    os << "    [" << str(r, "source", "?") << "] " << str(r, "text") << "\n";
}

struct MethodColumns {
  std::string method;
  calib::core::ParamVector value = calib::core::ParamVector::Zero();
  calib::core::ParamVector sigma = calib::core::ParamVector::Zero();
};

/// The method names as people read them: "AINS", "NLSQ", "legacy".
std::string method_label(const std::string& m) {
  if (m == "ains") return "AINS";
  if (m == "nlsq") return "NLSQ";
  return m;
}

bool listed(const json& c, const char* key, const std::string& name) {
  if (!c.contains(key) || !c[key].is_array()) return false;
  for (const json& n : c[key])
    if (n.is_string() && n.get<std::string>() == name) return true;
  return false;
}

void render_method_line(std::ostream& os, const json& c);

/// Both (or all) calibrations side by side in human units with 1-σ; a parameter a method does not
/// determine reads "not observable", never a value with σ 0. Then each method's line and notes.
void render_calibration_table(std::ostream& os, const json& run, const json& cals) {
  std::vector<MethodColumns> cols;
  for (const auto& c : cals) {
    MethodColumns m;
    m.method = str(c, "method");
    calib::core::ParamSet sigma;
    const calib::core::ParamSet p = db::archive::param_set_from_json(
        c.at("params"), "run " + str(run, "run_id") + " " + m.method, &sigma);
    m.value = p.to_vector();
    m.sigma = sigma.to_vector();
    cols.push_back(m);
  }
  os << "Calibration (value ± 1-σ)\n";
  std::string header = "  " + pad("parameter", 26) + pad("unit", 8);
  for (const auto& m : cols) header += lpad(m.method, 12) + pad("   ± 1-σ", 13);
  os << rtrim(header) << "\n";
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
    const calib::core::ParamInfo& info = calib::core::param_info(i);
    std::string line = "  " + pad(info.name, 26) + pad(info.human_unit, 8);
    for (std::size_t k = 0; k < cols.size(); ++k) {
      if (listed(cals[k], "unobservable", info.name)) {
        line += lpad("not observable", 25);
        continue;
      }
      line += lpad(fmt("%.3f", cols[k].value(i) * info.si_to_human), 12) + " ± " +
              pad(fmt("%.3f", cols[k].sigma(i) * info.si_to_human), 10);
    }
    os << rtrim(line) << "\n";
  }
  for (const auto& c : cals) render_method_line(os, c);
}

void render_method_line(std::ostream& os, const json& c) {
  os << "  " << pad(str(c, "method"), 8)
     << (c.value("converged", false) ? "converged" : "NOT converged") << ", "
     << str(c, "iterations") << " iterations, " << fmt("%.2f", c.value("runtime_s", 0.0)) << " s";
  if (has(c, "metrics")) {
    const json& m = c["metrics"];
    os << "; orientation RMSE " << fmt("%.3f", m.value("orientation_rmse_mdeg", 0.0))
       << " mdeg, accel RMSE " << fmt("%.2f", m.value("accel_rmse_ug", 0.0)) << " µg";
  }
  os << "\n";
  if (str(c, "body_frame") == "accel_symmetric")
    os << "    frame: misalignments in the accelerometer triad's own orthogonal frame\n";
  if (c.contains("notes"))
    for (const auto& n : c["notes"]) os << "    not observable: " << n.get<std::string>() << "\n";
  if (c.contains("warnings"))
    for (const auto& w : c["warnings"]) os << "    warning: " << w.get<std::string>() << "\n";
}

/// "Cross-check PASS (AINS against legacy, bound 4σ): they agree on every compared parameter;
/// 3 not compared (not observable by both): ..." — the methods named as stored.
void render_crosscheck(std::ostream& os, const json& show, const json& cals) {
  if (!has(show, "crosscheck")) {
    os << "No cross-check.\n";
    return;
  }
  const json& x = show["crosscheck"];
  std::string methods;
  for (const auto& c : cals)
    methods += (methods.empty() ? "" : " against ") + method_label(str(c, "method"));
  os << "Cross-check " << str(x, "verdict") << " (" << (methods.empty() ? "" : methods + ", ")
     << "bound " << fmt("%g", x.value("k_sigma", 0.0)) << "σ)";
  const json& failures = x.at("failures");
  if (failures.empty()) {
    os << ": they agree on every compared parameter";
  } else {
    os << ", " << failures.size() << " disagreement" << (failures.size() == 1 ? "" : "s") << ":";
  }
  const std::size_t skipped = x.contains("not_compared") ? x["not_compared"].size() : 0;
  if (skipped > 0) {
    std::string names;
    for (const auto& n : x["not_compared"])
      names += (names.empty() ? "" : ", ") + n.get<std::string>();
    os << (failures.empty() ? "; " : " ") << skipped
       << " not compared (not observable by both: " << names << ")";
  }
  os << "\n";
  for (const auto& f : failures) os << "  " << str(f, "detail") << "\n";
}

}  // namespace

namespace {

/// Whose a run's end was, for people (db::history::outcome_of's words).
std::string outcome_owner_text(const std::string& owner) {
  if (owner == "station") return "a station fault (table, CAN bus, disk); the unit is not blamed";
  if (owner == "operator") return "aborted by an operator";
  if (owner == "daemon")
    return "the station daemon stopped mid-run (it died, or it was stopped: not an operator)";
  return owner;
}

}  // namespace

std::string render_show_text(const json& show) {
  std::ostringstream os;
  const json& run = show.at("run");
  os << "Run " << str(run, "run_id") << "  " << str(run, "serial") << "  " << state_cell(run);
  if (has(run, "verdict")) os << "  verdict " << str(run, "verdict");
  if (has(run, "crosscheck_verdict"))
    os << "  (cross-check " << str(run, "crosscheck_verdict") << ")";
  os << "\n";
  if (has(run, "outcome_of") && str(run, "outcome_of") != "unit")
    os << "  not the unit's outcome: " << outcome_owner_text(str(run, "outcome_of")) << "\n";
  render_reasons(os, run);
  auto row = [&os](const char* label, const std::string& value) {
    if (!value.empty()) os << "  " << pad(label, 13) << value << "\n";
  };
  std::string seq = str(run, "sequence_name");
  if (!str(run, "sequence_sha256").empty())
    seq += "  (sha256 " + str(run, "sequence_sha256").substr(0, 16) + "...)";
  row("sequence", seq);
  row("setting", str(run, "setting", "factory"));
  row("origin", str(run, "origin"));
  if (!str(run, "slot").empty())
    row("slot",
        str(run, "slot") + (has(run, "table_run") ? " (table run " + str(run, "table_run") + ")"
                                                  : " (first unit of its table run)"));
  if (!str(run, "holding_reason").empty())
    row("holds", str(run, "holding_method") + ": " + str(run, "holding_reason"));
  if (has(run, "promoted_at"))
    row("promoted", str(run, "promoted_at") + " by " + str(run, "promoted_by") + ": " +
                        str(run, "promote_reason"));
  row("operator", str(run, "operator"));
  row("station", str(run, "station"));
  row("software", str(run, "software_version"));
  row("started", str(run, "started_at"));
  if (has(run, "ended_at")) row("ended", str(run, "ended_at") + "  (" + run_duration(run) + ")");
  if (has(run, "reprocessed_from")) row("reprocessed", "from run " + str(run, "reprocessed_from"));
  row("archive", str(run, "archive_path"));
  row("archive sha", str(run, "archive_sha256"));

  if (has(run, "capture")) render_capture(os, run["capture"]);
  if (has(run, "diagnosis") && run["diagnosis"].is_object()) {
    const json& g = run["diagnosis"];
    // The cell repeats the verdict when no effect is named ("consistent"): say it once.
    const std::string cell = gap_cell(run);
    os << "Gap diagnosis: " << str(g, "verdict", "?")
       << (cell == str(g, "verdict") ? "" : "  (" + cell + ")") << "\n";
    if (!str(g, "summary").empty()) os << "  " << str(g, "summary") << "\n";
    if (!str(g, "reason").empty()) os << "  " << str(g, "reason") << "\n";
    if (g.value("known_effects_only", false))
      os << "  explained by the product's known effects alone ([calibration] known_effects): no "
            "review\n";
  }

  const json& cals = show.at("calibrations");
  if (cals.empty()) {
    os << "No calibration results.\n";
  } else {
    render_calibration_table(os, run, cals);
  }
  render_crosscheck(os, show, cals);
  return os.str();
}

std::string render_params_text(const json& params) { return params.dump(2) + "\n"; }

namespace {
std::string run_head(const json& run) {
  const std::string slot = str(run, "slot");
  return "run " + str(run, "run_id", "?") + " " + str(run, "serial", "?") +
         (slot.empty() ? "" : " (slot " + slot + ")");
}

/// A table run's other units in one clause: "; B SN-2 running, C SN-3 failed" ("" alone).
std::string siblings_clause(const json& run) {
  if (!has(run, "units") || !run["units"].is_array() || run["units"].size() < 2) return "";
  std::string s;
  const json& units = run["units"];
  for (std::size_t i = 1; i < units.size(); ++i) {
    const json& u = units[i];
    s += (s.empty() ? "; " : ", ") + str(u, "slot") + " " + str(u, "serial") + " " +
         str(u, "state") + (has(u, "verdict") ? " " + str(u, "verdict") : "");
  }
  return s;
}

}  // namespace

std::string progress_line(const json& run) {
  std::string s = run_head(run) + ": ";
  const std::string state = str(run, "state");
  if (has(run, "state_note")) return s + state_cell(run) + siblings_clause(run);
  if (state == "running" || state == "preparing") {
    if (has(run, "step") && has(run, "steps"))
      s += "step " + str(run, "step") + "/" + str(run, "steps") + " ";
    s += str(run, "phase", state);
    if (has(run, "time_left_s") && run["time_left_s"].is_number())
      s += ", " + format_duration_s(run["time_left_s"].get<double>()) + " left";
    return s + siblings_clause(run);
  }
  s += state;
  if (has(run, "phase") && str(run, "phase") != state) s += " (" + str(run, "phase") + ")";
  if (has(run, "verdict")) s += ", verdict " + str(run, "verdict");
  return s + siblings_clause(run);
}

std::string outcome_line(const json& run) {
  std::string s = run_head(run) + ": " + str(run, "state", "?");
  if (has(run, "verdict")) s += ", verdict " + str(run, "verdict");
  if (has(run, "crosscheck_verdict")) s += " (cross-check " + str(run, "crosscheck_verdict") + ")";
  const std::string reason = has(run, "reason") ? str(run, "reason") : str(run, "failure_reason");
  if (!reason.empty()) s += " — " + reason;
  return s;
}

std::string render_status_text(const json& status) {
  std::ostringstream os;
  if (has(status, "daemon")) {
    const json& d = status["daemon"];
    os << "stationd " << str(d, "version", "?") << " (pid " << str(d, "pid", "?") << ") at station "
       << str(d, "station", "?");
    if (has(d, "uptime_s") && d["uptime_s"].is_number())
      os << ", up " << format_duration_s(d["uptime_s"].get<double>());
    os << ": " << str(status, "state", "?") << "\n";
  }
  auto describe = [&os](const char* title, const json& r) {
    os << title << progress_line(r) << "\n";
    std::string info;
    if (!str(r, "sequence").empty()) info += "sequence " + str(r, "sequence");
    if (!str(r, "operator").empty())
      info += (info.empty() ? "" : ", ") + ("operator " + str(r, "operator"));
    if (!str(r, "started_at").empty())
      info += (info.empty() ? "" : ", ") + ("started " + str(r, "started_at"));
    if (!info.empty()) os << "  " << info << "\n";
    if (!str(r, "reason").empty()) os << "  reason: " << str(r, "reason") << "\n";
    if (has(r, "capture") && r["capture"].is_object()) {
      const json& c = r["capture"];
      std::string counters;
      for (const char* k : {"samples_decoded", "samples_lost", "samples_corrupt", "samples_filled",
                            "frames_received", "imu_resets"})
        if (c.contains(k))
          counters += std::string(counters.empty() ? "" : ", ") + k + " " + c[k].dump();
      if (!counters.empty()) os << "  capture: " << counters << "\n";
    }
    if (has(r, "units") && r["units"].is_array())
      for (std::size_t i = 1; i < r["units"].size(); ++i)
        os << "  also on the table: " << outcome_line(r["units"][i]) << "\n";
  };
  if (status.contains("run")) {
    if (status["run"].is_object())
      describe(has(status, "daemon") ? "Active " : "", status["run"]);
    else
      os << "No active run.\n";
  }
  if (has(status, "last_run") && status["last_run"].is_object())
    describe("Last ", status["last_run"]);
  if (has(status, "fleet") && status["fleet"].is_object()) {
    const json& f = status["fleet"];
    os << "Fleet store " << str(f, "url", "?") << " as station " << str(f, "station_id", "?")
       << ": " << (f.value("connected", false) ? "connected" : "not connected") << ", outbox "
       << str(f, "outbox_length", "?") << " entries";
    if (!str(f, "last_delivery_at").empty()) os << ", last delivery " << str(f, "last_delivery_at");
    os << "\n";
    if (!str(f, "last_error").empty())
      os << "  last error (" << str(f, "last_error_at", "?") << "): " << str(f, "last_error")
         << "\n";
  }
  return os.str();
}

}  // namespace imucal::station::control
