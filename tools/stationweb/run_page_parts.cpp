#include "tools/stationweb/run_page_parts.hpp"

#include <algorithm>
#include <cmath>

#include "calib/core/param_set.hpp"
#include "station/control/record_json.hpp"
#include "tools/report/diagnosis_text.hpp"
#include "tools/stationweb/html.hpp"
#include "tools/stationweb/page_util.hpp"

namespace imucal::tools::stationweb {

namespace {

using nlohmann::json;

std::string row(const std::string& label, const std::string& value_html) {
  return "<tr><th>" + esc(label) + "</th><td>" + value_html + "</td></tr>\n";
}

/// A JSON value for people: nested objects as nested tables, lists joined, numbers to 6 digits.
std::string json_html(const json& v) {
  if (v.is_object()) {
    std::string s = "<table>\n";
    for (auto it = v.begin(); it != v.end(); ++it)
      s += "<tr data-key='" + esc(it.key()) + "'><th>" + esc(it.key()) + "</th><td>" +
           json_html(it.value()) + "</td></tr>\n";
    return s + "</table>";
  }
  if (v.is_array()) {
    std::string s;
    for (const json& e : v) s += (s.empty() ? "" : e.is_structured() ? "" : ", ") + json_html(e);
    return s.empty() ? "-" : s;
  }
  if (v.is_number_float()) return fmt("%.6g", v.get<double>());
  if (v.is_string()) return esc(v.get<std::string>());
  if (v.is_null()) return "-";
  return esc(v.dump());
}

std::string optional_rows(const db::history::RunRecord& r) {
  std::string s;
  if (!r.origin.empty()) s += row("origin", esc(r.origin));
  if (!r.slot.empty())
    s +=
        row("slot", esc(r.slot) + (r.table_run_id ? " (table run " + run_link(*r.table_run_id) + ")"
                                                  : " (first unit of its table run)"));
  if (!r.holding_reason.empty())
    s += row("holds", esc(method_label(r.holding_method)) + ": " + esc(r.holding_reason));
  if (r.promoted_at_ms)
    s += row("promoted", short_time(*r.promoted_at_ms) + " UTC by " + esc(r.promoted_by) + ": " +
                             esc(r.promote_reason));
  if (r.reprocessed_from) s += row("reprocessed", "from run " + run_link(*r.reprocessed_from));
  return s;
}

/// The diagnosis in words with units (issue #52 item 6): the one renderer `stationctl diagnose` and
/// `imucal diagnose` print with (tools/report/diagnosis_text.hpp), given the stored summary and the
/// run it belongs to. A diagnosis that did not run says why instead.
std::string diagnosis_words(const json& run, const json& g) {
  if (g.value("verdict", std::string()) == "not run")
    return "<p id='diagnosis-text'>Not run: " + esc(g.value("reason", std::string("-"))) + "</p>\n";
  json d = g;
  d["run_id"] = run.value("run_id", json(nullptr));
  d["serial"] = run.value("serial", std::string());
  d["sequence"] = run.value("sequence_name", std::string());
  d["archive"] = run.value("archive_path", std::string());
  const std::string id = run.contains("run_id") ? run["run_id"].dump() : "RUN_ID";
  return "<pre id='diagnosis-text'>" + esc(tools::report::diagnosis_report_text(d)) +
         "</pre>\n<p class='muted'>The stored summary; the whole diagnosis (candidate effects, "
         "segments, rest samples) from the archive: <code>stationctl diagnose " +
         esc(id) + "</code>.</p>\n";
}

}  // namespace

std::string method_label(db::history::Method m) {
  return m == db::history::Method::kAins   ? "AINS"
         : m == db::history::Method::kNlsq ? "NLSQ"
                                           : "legacy";
}

std::string facts_table(const db::history::RunRecord& r) {
  std::string s = "<table id='run-facts'>\n";
  s += row("sequence", esc(r.sequence_name) + (r.sequence_sha256.empty()
                                                   ? ""
                                                   : " <span class='muted'>(sha256 " +
                                                         esc(r.sequence_sha256) + ")</span>"));
  s += row("setting", esc(calib::core::setting_name(r.setting)));
  s += optional_rows(r);
  s += row("operator", esc(r.operator_name)) + row("station", esc(r.station));
  s += row("software", esc(r.software_version));
  s += row("started", "<span data-ms='" + std::to_string(r.started_at_ms) + "'>" +
                          short_time(r.started_at_ms) + " UTC</span>");
  if (r.ended_at_ms)
    s += row("ended",
             "<span data-ms='" + std::to_string(*r.ended_at_ms) + "'>" +
                 short_time(*r.ended_at_ms) + " UTC</span> (" +
                 station::control::format_duration_s((*r.ended_at_ms - r.started_at_ms) / 1000.0) +
                 ")");
  s += "</table>\n<p id='archive' data-path='" + esc(r.archive_path) + "' data-sha256='" +
       esc(r.archive_sha256) + "'>Archive <code>" +
       (r.archive_path.empty() ? "(none)" : esc(r.archive_path)) + "</code><br>SHA-256 <code>" +
       (r.archive_sha256.empty() ? "(none)" : esc(r.archive_sha256)) + "</code></p>\n";
  return s;
}

std::string capture_section(const json& run) {
  if (!run.contains("capture") || !run["capture"].is_object()) return "";
  const json& c = run["capture"];
  std::string s = "<h2>Capture";
  if (c.contains("complete") && c["complete"].is_boolean())
    s += c["complete"].get<bool>() ? " (complete)" : " (INCOMPLETE: recovered archive)";
  s += "</h2>\n<table id='capture'>\n";
  for (auto it = c.begin(); it != c.end(); ++it) {
    if (it.key() == "complete") continue;
    s += "<tr data-counter='" + esc(it.key()) + "' data-value='" +
         esc(it->is_string() ? it->get<std::string>() : it->dump()) + "'><th>" + esc(it.key()) +
         "</th><td class='num'>" + json_html(*it) + "</td></tr>\n";
  }
  return s + "</table>\n";
}

std::string diagnosis_section(const json& run) {
  if (!run.contains("diagnosis") || !run["diagnosis"].is_object()) return "";
  const json& g = run["diagnosis"];
  const std::string verdict = g.value("verdict", std::string("?"));
  const std::string cell = station::control::gap_cell(run);
  std::string s = "<h2>Gap diagnosis</h2>\n<div id='diagnosis' data-verdict='" + esc(verdict) +
                  "'>\n<p>Verdict <b>" + esc(verdict) + "</b>" +
                  (cell == verdict ? "" : " (" + esc(cell) + ")") + "</p>\n";
  if (g.contains("summary") && g["summary"].is_string())
    s += "<p>" + esc(g["summary"].get<std::string>()) + "</p>\n";
  if (g.value("known_effects_only", false))
    s += "<p>Explained by the product's known effects alone ([calibration] known_effects): no "
         "review.</p>\n";
  s += diagnosis_words(run, g);
  // Every stored field, for whoever needs one the text leaves out; closed: it is not the report.
  return s + "<details id='diagnosis-fields'><summary>Stored fields</summary>\n" + json_html(g) +
         "\n</details>\n</div>\n";
}

std::string calibration_table(const std::vector<db::history::CalibrationRecord>& cals) {
  if (cals.empty()) return "<p id='calibrations'>No calibration results.</p>\n";
  std::string s = "<table id='calibrations'>\n<tr><th>parameter</th><th>unit</th>";
  for (const auto& c : cals)
    s += "<th class='num'>" + method_label(c.method) + "</th><th class='num'>± 1σ</th>";
  s += "</tr>\n";
  std::vector<calib::core::ParamVector> value, sigma;
  for (const auto& c : cals) {
    value.push_back(c.params.to_vector());
    sigma.push_back(c.sigma.to_vector());
  }
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
    const calib::core::ParamInfo& info = calib::core::param_info(i);
    s += "<tr><td>" + info.name + "</td><td>" + esc(info.human_unit) + "</td>";
    for (std::size_t k = 0; k < cals.size(); ++k) {
      const std::string attrs = " data-method='" +
                                std::string(db::history::to_string(cals[k].method)) +
                                "' data-param='" + info.name + "'";
      if (listed(cals[k].unobservable, info.name)) {
        s += "<td colspan='2' class='muted'" + attrs + ">not observable</td>";
        continue;
      }
      s += "<td class='num'" + attrs + " data-value-si='" + exact(value[k](i)) +
           "' data-sigma-si='" + exact(sigma[k](i)) + "'>" +
           fmt_signed_to_sigma(value[k](i) * info.si_to_human, sigma[k](i) * info.si_to_human) +
           "</td><td class='num'>" + fmt_sigma(sigma[k](i) * info.si_to_human) + "</td>";
    }
    s += "</tr>\n";
  }
  return s + "</table>\n";
}

std::string method_lines(const std::vector<db::history::CalibrationRecord>& cals) {
  std::string s = "<ul id='methods'>\n";
  for (const auto& c : cals) {
    s += "<li data-method='" + std::string(db::history::to_string(c.method)) + "'><b>" +
         method_label(c.method) + "</b>: " + (c.converged ? "converged" : "NOT converged") + ", " +
         std::to_string(c.iterations) + " iterations, " + fmt("%.2f", c.runtime_s) + " s";
    if (c.metrics)
      s += "; orientation RMSE " + fmt("%.3f", c.metrics->orientation_rmse_mdeg) +
           " mdeg, acceleration RMSE " + fmt("%.2f", c.metrics->accel_rmse_ug) + " µg";
    if (c.body_frame == calib::core::BodyFrame::kAccelSymmetric)
      s += "; misalignments in the accelerometer triad's own orthogonal frame";
    for (const auto& n : c.notes) s += "<br>not observable: " + esc(n);
    for (const auto& w : c.warnings) s += "<br>warning: " + esc(w);
    s += "</li>\n";
  }
  return s + "</ul>\n";
}

}  // namespace imucal::tools::stationweb
