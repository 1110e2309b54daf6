// "/unit/SN": a unit's history (the columns of `stationctl history SN`) and the trend of its AINS
// parameters across its calibrations, one panel per parameter group.
#include <algorithm>

#include "tools/stationweb/html.hpp"
#include "tools/stationweb/pages.hpp"
#include "tools/stationweb/run_page_parts.hpp"
#include "tools/stationweb/run_table.hpp"
#include "tools/stationweb/trend_svg.hpp"

namespace imucal::tools::stationweb {

namespace {

constexpr calib::core::ParamGroup kGroups[] = {
    calib::core::ParamGroup::kAccelBias,     calib::core::ParamGroup::kAccelScale,
    calib::core::ParamGroup::kAccelMisalign, calib::core::ParamGroup::kGyroBias,
    calib::core::ParamGroup::kGyroScale,     calib::core::ParamGroup::kGyroMisalign,
    calib::core::ParamGroup::kTableMisalign};

/// Every AINS calibration of the serial, oldest first (one export pass, no query per run).
std::vector<TrendPoint> ains_points(const db::history::Repository& repo,
                                    const std::string& serial) {
  std::vector<TrendPoint> points;
  db::history::ExportFilter filter;
  filter.serial = serial;
  repo.export_rows(filter, [&](const db::history::ExportRow& row) {
    if (!row.calibration || row.calibration->method != db::history::Method::kAins) return;
    TrendPoint p;
    p.run_id = row.run.run_id;
    p.t_ms = row.run.started_at_ms;
    p.verdict = row.run.verdict ? db::history::to_string(*row.run.verdict) : "";
    p.value = row.calibration->params.to_vector();
    p.sigma = row.calibration->sigma.to_vector();
    p.body_frame = row.calibration->body_frame;
    for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
      const auto& names = row.calibration->unobservable;
      p.observable[static_cast<std::size_t>(i)] =
          std::find(names.begin(), names.end(), calib::core::param_info(i).name) == names.end();
    }
    points.push_back(p);
  });
  return points;
}

std::optional<db::history::ActiveCalibration> active_of(const db::history::Repository& repo,
                                                        const std::string& serial) {
  try {
    return repo.active_params(serial);
  } catch (const db::history::NotFound&) {
    return std::nullopt;  // no PASS factory run (yet): the page says so
  }
}

std::string active_line(const std::optional<db::history::ActiveCalibration>& active) {
  if (!active)
    return "<p id='active-set' data-run-id=''>No active parameter set: the unit has no PASS "
           "factory run (and no promoted field run).</p>\n";
  const db::history::RunRecord& r = active->run;
  return "<p id='active-set' data-run-id='" + std::to_string(r.run_id) +
         "'>Active parameter set: the " + esc(method_label(active->active.method)) +
         " set of run " + run_link(r.run_id) + " (" + esc(calib::core::setting_name(r.setting)) +
         ", started " + short_time(r.started_at_ms) + " UTC, station " + esc(r.station) +
         (r.promoted_at_ms ? ", promoted by QA" : "") + ").</p>\n";
}

/// <table id='active-values'>: the values an INS loads for this unit, each ± 1σ in human units
/// (issue #52 item 9: the page named the active set's run but not its values).
std::string active_values(const std::optional<db::history::ActiveCalibration>& active) {
  if (!active) return "";
  const db::history::CalibrationRecord& c = active->active;
  const calib::core::ParamVector v = c.params.to_vector(), sg = c.sigma.to_vector();
  std::string s = "<details id='active-values-box' open><summary>The active set's values (" +
                  esc(method_label(c.method)) + ", run " + std::to_string(active->run.run_id) +
                  ")</summary>\n<table id='active-values' data-run-id='" +
                  std::to_string(active->run.run_id) + "' data-method='" +
                  db::history::to_string(c.method) +
                  "'>\n<tr><th>parameter</th><th>unit</th><th class='num'>value</th><th "
                  "class='num'>± 1σ</th></tr>\n";
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
    const calib::core::ParamInfo& info = calib::core::param_info(i);
    s += "<tr data-param='" + info.name + "'><td>" + info.name + "</td><td>" +
         esc(info.human_unit) + "</td>";
    if (std::find(c.unobservable.begin(), c.unobservable.end(), info.name) !=
        c.unobservable.end()) {
      s += "<td colspan='2' class='muted'>not observable</td></tr>\n";
      continue;
    }
    s += "<td class='num' data-value-si='" + exact(v(i)) + "' data-sigma-si='" + exact(sg(i)) +
         "'>" + fmt_signed_to_sigma(v(i) * info.si_to_human, sg(i) * info.si_to_human) +
         "</td><td class='num'>" + fmt_sigma(sg(i) * info.si_to_human) + "</td></tr>\n";
  }
  return s + "</table>\n</details>\n";
}

}  // namespace

Reply unit_reply(const History& history, const std::string& serial_text, const Params& query) {
  check_known_params(query, {"format"});
  const Format format = parse_format(query);
  const std::string serial = trimmed(serial_text);  // a pasted " SN-0008 " is SN-0008
  check_serial(serial, "serial");
  check_known_serial(history, serial, "serial");
  if (format == Format::kHtml) return {unit_page(history, serial)};
  const std::vector<db::history::RunRecord> runs = history.repo->history(serial);
  if (format == Format::kJson)
    return {run_list_json(serial, runs, runs.size()), "application/json", serial + "-history.json"};
  return {run_list_csv(runs), "text/csv; charset=utf-8", serial + "-history.csv"};
}

std::string unit_page(const History& history, const std::string& serial) {
  check_serial(serial, "serial");
  std::vector<db::history::RunRecord> runs;
  try {
    runs = history.repo->history(serial);
  } catch (const db::history::NotFound&) {
    throw PageError(404, "serial",
                    "No unit with serial number \"" + serial + "\" in this history.");
  }
  const auto active = active_of(*history.repo, serial);
  const std::vector<TrendPoint> points = ains_points(*history.repo, serial);
  std::string b = "<h1>Unit " + esc(serial) + "</h1>\n<p><span id='run-count' data-value='" +
                  std::to_string(runs.size()) + "'>" + std::to_string(runs.size()) +
                  "</span> runs, newest first.</p>\n" + active_line(active);
  // The history first (issue #52 item 9: it sat ~2 500 px below the charts), then the active
  // set's values, then the trend.
  b += "<p id='jump'><a href='#history'>History</a> · <a href='#active-values-box'>Active "
       "set's values</a> · <a href='#trend'>Parameter trend</a></p>\n";
  b += "<h2>History</h2>\n" + run_table(history, runs, false, "history") +
       download_links("/unit/" + url_encode(serial)) + active_values(active);
  b += "<h2 id='trend'>Parameter trend</h2>\n<p class='muted'>Each calibration's AINS estimate "
       "(<span "
       "id='trend-count' data-value='" +
       std::to_string(points.size()) + "'>" + std::to_string(points.size()) +
       "</span> runs with one) at its run's start time; the dark band is ±1σ, the light band "
       "±3σ; the dashed line marks the run of the active set. Markers by verdict: ● PASS "
       "(filled), ○ REVIEW (a ring in the colour), a dark ring any other; runs closer in time "
       "than a marker are spread apart (each point's tooltip has its exact time). Parameters a "
       "run does not determine are not drawn. Misalignments depend on the body frame: a factory "
       "run's are in the housing frame, a land, sea or legacy run's in the accelerometer triad's "
       "(the frames differ by the housing angle, which only a factory run determines), so each "
       "frame is its own series (solid and dashed), never joined.</p>\n";
  const std::optional<db::history::RunId> active_run =
      active ? std::optional<db::history::RunId>(active->run.run_id) : std::nullopt;
  if (points.empty()) b += "<p>No calibration stored yet.</p>\n";
  if (!points.empty())
    for (calib::core::ParamGroup g : kGroups) b += trend_svg(g, points, active_run);
  return page("Unit " + serial, b);
}

}  // namespace imucal::tools::stationweb
