#include "calib/core/binomial_interval.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace imucal::calib::core {

namespace {

/// P(Bin(n, p) <= k), summed in log space (n up to millions stays accurate enough for bisection).
double binomial_cdf(int k, int n, double p) {
  if (p <= 0.0) return 1.0;
  if (p >= 1.0) return k >= n ? 1.0 : 0.0;
  const double lp = std::log(p), lq = std::log1p(-p);
  double sum = 0.0;
  for (int i = 0; i <= k; ++i)
    sum += std::exp(std::lgamma(n + 1.0) - std::lgamma(i + 1.0) - std::lgamma(n - i + 1.0) +
                    i * lp + (n - i) * lq);
  return std::min(1.0, sum);
}

/// The p in (0, 1) where f(p) crosses `target`, f decreasing in p (bisection to 1e-12).
template <typename F>
double solve_decreasing(F f, double target) {
  double lo = 0.0, hi = 1.0;
  for (int it = 0; it < 200 && hi - lo > 1e-12; ++it) {
    const double mid = 0.5 * (lo + hi);
    (f(mid) > target ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace

RateInterval clopper_pearson(int k, int n, double level) {
  if (n < 1 || k < 0 || k > n || !(level > 0.0 && level < 1.0))
    throw std::invalid_argument("clopper_pearson: need 0 <= k <= n, n >= 1, 0 < level < 1 (k " +
                                std::to_string(k) + ", n " + std::to_string(n) + ")");
  const double tail = 0.5 * (1.0 - level);
  RateInterval r;
  r.rate = static_cast<double>(k) / n;
  // Upper: the p at which seeing k or fewer is as unlikely as the tail.
  if (k < n) r.upper = solve_decreasing([&](double p) { return binomial_cdf(k, n, p); }, tail);
  // Lower: the p at which seeing k or more is as unlikely as the tail, P(X >= k) = 1 - cdf(k-1).
  if (k > 0)
    r.lower = solve_decreasing([&](double p) { return binomial_cdf(k - 1, n, p); }, 1.0 - tail);
  return r;
}

}  // namespace imucal::calib::core
