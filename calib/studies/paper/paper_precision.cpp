#include "calib/studies/paper/paper_precision.hpp"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace imucal::calib::studies::paper {

namespace {

double mean_of(const std::vector<double>& v) {
  return std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

/// Counts the ordered resamples (n draws with replacement) whose sum lies in [lo, hi]: n^n of
/// them, enumerated depth first with the partial sum carried.
size_t count_resamples_within(const std::vector<double>& v, size_t depth, double partial, double lo,
                              double hi) {
  if (depth == v.size()) return partial >= lo && partial <= hi ? 1 : 0;
  size_t count = 0;
  for (double x : v) count += count_resamples_within(v, depth + 1, partial + x, lo, hi);
  return count;
}

}  // namespace

double mean_standard_error(const std::vector<double>& values) {
  if (values.size() < 2) throw std::invalid_argument("mean precision: needs two or more values");
  const double n = static_cast<double>(values.size());
  const double mean = mean_of(values);
  double ss = 0.0;
  for (double x : values) ss += (x - mean) * (x - mean);
  return std::sqrt(ss / (n - 1.0) / n);
}

MeanPrecision mean_precision(const std::vector<double>& values, double bar) {
  if (!(bar > 0.0)) throw std::invalid_argument("mean precision: the bar must be > 0");
  MeanPrecision p;
  p.standard_error = mean_standard_error(values);
  p.mean = mean_of(values);
  if (p.mean == 0.0) throw std::invalid_argument("mean precision: the mean is zero");
  const double n = static_cast<double>(values.size());
  double worst_shift = -1.0;
  for (size_t i = 0; i < values.size(); ++i) {
    const double without = (p.mean * n - values[i]) / (n - 1.0);
    const double shift = std::abs(without / p.mean - 1.0);
    if (shift > bar) p.bar_held_by_own_units = false;
    if (shift > worst_shift) {
      worst_shift = shift;
      p.most_influential = i;
      p.mean_without_it = without;
    }
  }
  if (values.size() <= kMaxExactBootstrapUnits) {
    // In sums: a resample's mean within the bar is its sum within n * mean * (1 ± bar); the
    // relative slack keeps a resample that lies on the edge in spite of rounding.
    const double slack = 1e-12 * std::abs(p.mean) * n;
    const double a = (1.0 - bar) * p.mean * n, b = (1.0 + bar) * p.mean * n;
    const size_t within =
        count_resamples_within(values, 0, 0.0, std::min(a, b) - slack, std::max(a, b) + slack);
    p.resamples_within_bar = static_cast<double>(within) / std::pow(n, n);
  }
  return p;
}

PaperPrecision paper_precision(const std::vector<PaperRow>& rows, double bar) {
  PaperPrecision out{};
  for (size_t c = 0; c < out.size(); ++c)
    for (size_t m = 0; m < 2; ++m) out[c][m] = mean_precision(paper_column_values(rows, c, m), bar);
  return out;
}

double mean_distance_in_standard_errors(double model_mean, double model_standard_error,
                                        const MeanPrecision& paper) {
  const double se = std::hypot(paper.standard_error, model_standard_error);
  return se > 0.0 ? (model_mean - paper.mean) / se : 0.0;
}

}  // namespace imucal::calib::studies::paper
