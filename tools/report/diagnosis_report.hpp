#pragma once
// The gap diagnosis as a self-contained HTML page (`imucal diagnose DIR --report OUTDIR`): inline
// CSS and inline SVG, no scripts, no external resources, so it opens anywhere and can be attached
// to a quality record. For a test engineer chasing a discrepancy:
//   * the verdict and the one-sentence summary, the overall gap against its expectation;
//   * the heat map of the normalised gap by segment (time order) × sensor axis (id "heatmap"),
//     each column labelled on the axis (segment, start time, table angles of a rest), hover a cell
//     for the z and the raw residual in human units;
//   * each segment's NIS on a log axis (they span 1 to 10^4) against its expectation and the
//     χ² 99 % line (id "nis");
//   * the candidate ranking as a table (id "candidates") and a bar chart of the scores (id
//     "scores"); the explained set step by step (id "steps");
//   * the held-out gap before and after the best effect and the whole explained set (id
//     "heldout"), and the calibration parameters that move when it is added; where the gap
//     remains.
#include <nlohmann/json.hpp>
#include <string>

namespace imucal::tools::report {

/// `diagnosis` is the JSON of db::archive::diagnosis_to_json (with "archive", "serial",
/// "sequence").
std::string diagnosis_report_html(const nlohmann::json& diagnosis);

}  // namespace imucal::tools::report
