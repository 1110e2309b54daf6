#include "calib/core/chi2.hpp"

#include <cmath>
#include <limits>

namespace imucal::calib::core {

namespace {

// P(a, x) by its power series: e^{-x} x^a / Γ(a+1) Σ x^n / ((a+1)...(a+n)).
double gamma_p_series(double a, double x) {
  double term = 1.0 / a, sum = term;
  for (int n = 1; n < 10000; ++n) {
    term *= x / (a + n);
    sum += term;
    if (std::abs(term) < std::abs(sum) * 1e-16) break;
  }
  return sum * std::exp(-x + a * std::log(x) - std::lgamma(a));
}

// Q(a, x) by the continued fraction of Γ(a, x) (modified Lentz).
double gamma_q_fraction(double a, double x) {
  constexpr double tiny = 1e-300;
  double b = x + 1.0 - a, c = 1.0 / tiny, d = 1.0 / b, h = d;
  for (int i = 1; i < 10000; ++i) {
    const double an = -i * (i - a);
    b += 2.0;
    d = an * d + b;
    if (std::abs(d) < tiny) d = tiny;
    c = b + an / c;
    if (std::abs(c) < tiny) c = tiny;
    d = 1.0 / d;
    const double del = d * c;
    h *= del;
    if (std::abs(del - 1.0) < 1e-16) break;
  }
  return std::exp(-x + a * std::log(x) - std::lgamma(a)) * h;
}

}  // namespace

double regularized_gamma_q(double a, double x) {
  if (!(a > 0.0) || std::isnan(x)) return std::numeric_limits<double>::quiet_NaN();
  if (x <= 0.0) return 1.0;
  if (x < a + 1.0) return 1.0 - gamma_p_series(a, x);
  return gamma_q_fraction(a, x);
}

double chi2_survival(double x, double k) { return regularized_gamma_q(0.5 * k, 0.5 * x); }

double chi2_quantile_upper(double p, double k) {
  double lo = 0.0, hi = k + 10.0 * std::sqrt(2.0 * k) + 100.0;
  while (chi2_survival(hi, k) > p) hi *= 2.0;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (chi2_survival(mid, k) > p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace imucal::calib::core
