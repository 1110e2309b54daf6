#pragma once
// The fleet page's pictures (tools/report/svg_panel.hpp panels, one slot per day or station):
//   runs_chart      <svg id='runs-chart'>: runs per UTC day, stacked by station
//   verdict_chart   <svg id='verdict-chart'>: each station's PASS/REVIEW/FAILED/live shares
//   box_plot        <svg id='distribution-chart'>: one parameter per station — min–max whisker,
//                   quartile box, median line, mean dot — in human units
//   signature_trend_svg  <svg id='signature-trend'>: each station's strongest |z| per period
//                   (station_signature_trend), the flag threshold dashed, flagged points ringed
#include <cstdint>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "calib/core/param_set.hpp"
#include "db/history/fleet_stats.hpp"

namespace imucal::tools::stationweb {

/// `stations` in legend order (their colour is their index); days first_day..last_day inclusive.
std::string runs_chart(const std::vector<db::history::StationDayCount>& counts,
                       const std::vector<std::string>& stations, std::int64_t first_day,
                       std::int64_t last_day);
std::string verdict_chart(const std::vector<db::history::StationVerdictCounts>& verdicts);
std::string box_plot(const std::vector<db::history::ParamSummary>& summaries,
                     const calib::core::ParamInfo& info);

/// One line per station (colour by its index in trend["stations"]), one slot per period; every
/// point a <circle class='pt'> ('pt flagged' when flagged) with data-station and data-period.
std::string signature_trend_svg(const nlohmann::json& trend);

/// A station's colour by its index in the page's station list.
const char* station_colour(std::size_t index);

}  // namespace imucal::tools::stationweb
