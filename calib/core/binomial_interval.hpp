#pragma once
// An exact (Clopper–Pearson) confidence interval for a rate from k events in n trials: the false-
// alarm rate of the gap check measured on null runs (issue #22), where k is often 0 or 1 and the
// normal approximation says nothing useful.
namespace imucal::calib::core {

struct RateInterval {
  double rate = 0.0;   ///< k / n
  double lower = 0.0;  ///< P(Bin(n, lower) >= k) = (1 - level) / 2 (0 when k = 0)
  double upper = 1.0;  ///< P(Bin(n, upper) <= k) = (1 - level) / 2 (1 when k = n)
};

/// The central `level` interval (e.g. 0.95) of a binomial rate, 0 <= k <= n, n >= 1. Throws
/// std::invalid_argument otherwise.
RateInterval clopper_pearson(int k, int n, double level = 0.95);

}  // namespace imucal::calib::core
