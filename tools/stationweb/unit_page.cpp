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
    p.value = row.calibration->params.to_vector();
    p.sigma = row.calibration->sigma.to_vector();
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

}  // namespace

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
  b += "<h2>Parameter trend</h2>\n<p class='muted'>Each calibration's AINS estimate (<span "
       "id='trend-count' data-value='" +
       std::to_string(points.size()) + "'>" + std::to_string(points.size()) +
       "</span> runs with one) at its run's start time; the dark band is ±1σ, the light band "
       "±3σ; the dashed line marks the run of the active set. Parameters a run does not "
       "determine are not drawn.</p>\n";
  const std::optional<db::history::RunId> active_run =
      active ? std::optional<db::history::RunId>(active->run.run_id) : std::nullopt;
  if (points.empty()) b += "<p>No calibration stored yet.</p>\n";
  if (!points.empty())
    for (calib::core::ParamGroup g : kGroups) b += trend_svg(g, points, active_run);
  b += "<h2>History</h2>\n" + run_table(runs, false, "history");
  return page("Unit " + serial, b);
}

}  // namespace imucal::tools::stationweb
