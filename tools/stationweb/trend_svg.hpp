#pragma once
// The unit page's pictures: one SVG panel per parameter group (accelerometer bias, scale factors,
// misalignments, gyro ..., table misalignment), x = calibration time (the run's start), y = each
// run's AINS value in human units (µg, ppm, µrad, deg/h, arcsec) with a ±1σ band and a lighter
// ±3σ band; the active set's run marked. Drawn with the panels of tools/report/svg_panel.hpp.
//
// Every point is a <circle class='pt'> with data-run-id, data-verdict (PASS filled, REVIEW a
// hollow ring, any other verdict a dark hollow ring: issue #52 item 9), data-t-ms, data-param (the
// parameter-set JSON name), data-value-si and data-sigma-si (as stored, full precision) and a
// tooltip.
//
// Misalignments depend on the body frame (calib/core/body_frame.hpp: a factory run's are in the
// housing frame, a land, sea or legacy run's in the accelerometer triad's; a change of frame
// rotates them by the housing angle). In the misalignment panels each frame is its own series —
// housing solid, the triad's frame dashed, never joined into one line or band — said in a legend;
// every point and line carries data-frame ("housing", "accel_symmetric").
#include <array>
#include <optional>
#include <string>
#include <vector>

#include "calib/core/param_set.hpp"
#include "db/history/repository.hpp"

namespace imucal::tools::stationweb {

struct TrendPoint {
  db::history::RunId run_id = 0;
  db::history::TimestampMs t_ms = 0;
  calib::core::ParamVector value = calib::core::ParamVector::Zero();
  calib::core::ParamVector sigma = calib::core::ParamVector::Zero();
  std::array<bool, calib::core::ParamSet::kSize>
      observable{};     ///< false: not determined, not drawn
  std::string verdict;  ///< the run's verdict ("PASS", "REVIEW", ...): its marker's shape
  calib::core::BodyFrame body_frame = calib::core::BodyFrame::kHousing;  ///< of its calibration
};

/// <svg id='trend-GROUP'> for one group, points in time order.
std::string trend_svg(calib::core::ParamGroup group, const std::vector<TrendPoint>& points,
                      std::optional<db::history::RunId> active_run);

}  // namespace imucal::tools::stationweb
