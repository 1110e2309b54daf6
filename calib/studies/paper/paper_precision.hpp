#pragma once
// How precisely the paper's own IMUs fix each column's mean (issue #26). Six units are a small
// sample: a column whose mean rests on one unit's event is not known to the 25 % the issue holds a
// model to. Three figures say how well a mean is known from its own units: its standard error,
// the mean with its most influential unit left out, and the share of the exact bootstrap's
// resamples (n units drawn with replacement from the n) whose mean stays within the bar. Where the
// paper's own units, one left out, already leave the bar, no model drawn alike for every unit is
// expected to meet it: the column's mean is that unit's event, not the population's.
#include <array>
#include <cstddef>
#include <vector>

#include "calib/studies/paper/paper_spread.hpp"

namespace imucal::calib::studies::paper {

/// The exact bootstrap enumerates n^n resamples; above this many units it is not computed.
inline constexpr size_t kMaxExactBootstrapUnits = 8;

struct MeanPrecision {
  double mean = 0.0;
  double standard_error = 0.0;   ///< sample standard deviation / sqrt(n)
  size_t most_influential = 0;   ///< index of the unit whose leaving out moves the mean most
  double mean_without_it = 0.0;  ///< the mean of the other n - 1 units
  /// Exact bootstrap: the share of the n^n equally likely resamples whose mean lies within the
  /// bar (|resample mean / mean - 1| <= bar). Negative when n > kMaxExactBootstrapUnits.
  double resamples_within_bar = -1.0;
  /// Whether the mean, any one unit left out, stays within the bar: whether the bar is one the
  /// units themselves hold.
  bool bar_held_by_own_units = true;
};

/// The standard error of the mean of `values` (sample sd / sqrt(n)). Throws std::invalid_argument
/// for fewer than two values.
double mean_standard_error(const std::vector<double>& values);

/// The precision of the mean of `values` against a relative bar (0.25: ±25 %). Throws
/// std::invalid_argument for fewer than two values, a mean of zero or a bar not > 0.
MeanPrecision mean_precision(const std::vector<double>& values, double bar);

/// Per column and metric ([column][0 orientation, 1 acceleration]) of a table's units.
using PaperPrecision = std::array<std::array<MeanPrecision, 2>, kNumPaperColumns>;
PaperPrecision paper_precision(const std::vector<PaperRow>& rows, double bar);

/// How many standard errors a model's mean lies from the paper's:
/// (model - paper) / sqrt(se_paper^2 + se_model^2), signed.
double mean_distance_in_standard_errors(double model_mean, double model_standard_error,
                                        const MeanPrecision& paper);

}  // namespace imucal::calib::studies::paper
