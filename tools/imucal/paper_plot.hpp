#pragma once
// The per-IMU picture of the gap budget (`imucal gap-budget --plot FILE.svg`): for each of the
// paper's five columns, the paper's six IMUs (open circles) beside a model's simulated units
// (dots), each side's mean as a bar — orientation above, acceleration below. What the spread
// in kind (calib/studies/paper/paper_spread.hpp) puts in numbers, to look at.
#include <string>
#include <vector>

#include "calib/studies/paper/paper_spread.hpp"

namespace imucal::tools::imucal {

/// SVG text: the paper's rows (paper_published_rows) against `model` (at least one unit); `title`
/// shown, `description` (the model, however long) kept as the picture's <desc>.
std::string paper_units_svg(const std::vector<calib::studies::paper::PaperRow>& model,
                            const std::string& title, const std::string& description);

}  // namespace imucal::tools::imucal
