#pragma once
// The counts of the suite's Monte Carlo and validation tests (issue #51 item 3). ctest runs each at
// a reduced "CI count" that keeps tools/test.sh short; IMUCAL_WHOLE_COUNTS=1 selects, everywhere at
// once, the "whole count" that an issue's "What it must show" names (tools/bench_whole_counts.sh,
// docs/validation/ci-counts.md). A test's own variable (IMUCAL_GAP_NULL_SEEDS, IMUCAL_MC_SEEDS,
// IMUCAL_VALIDATION_RUNS...) still overrides both.
//
// A bound on a count of events (REVIEW verdicts of null runs, false alarms) has to stay a valid
// test at the smaller count: binomial_tail_above gives the probability that a process exactly at
// the rate exceeds an allowed count (the test's false-fail probability), and
// allowed_events the smallest allowed count whose false-fail probability is at most a level.
#include <cmath>
#include <cstdlib>
#include <stdexcept>
#include <string>

namespace imucal::test_support {

/// IMUCAL_WHOLE_COUNTS=1: the issues' counts instead of the CI counts.
inline bool whole_counts() {
  const char* env = std::getenv("IMUCAL_WHOLE_COUNTS");
  return env && std::string(env) == "1";
}

/// The count of a test: `override_var` when set to a positive integer, else `whole` under
/// IMUCAL_WHOLE_COUNTS=1, else `ci`. `override_var` may be null (no per-test variable).
inline int test_count(const char* override_var, int ci, int whole) {
  if (override_var) {
    if (const char* env = std::getenv(override_var); env && std::atoi(env) > 0)
      return std::atoi(env);
  }
  return whole_counts() ? whole : ci;
}

/// P(X > k) for X ~ Binomial(n, p): the chance that more than k of n independent trials, each an
/// event with probability p, are events. Summed term by term in logs (exact enough for n ≤ 10^4).
inline double binomial_tail_above(int k, int n, double p) {
  if (n < 0 || !(p >= 0.0 && p <= 1.0)) throw std::invalid_argument("binomial_tail_above");
  if (k >= n) return 0.0;
  if (k < 0) return 1.0;
  if (p == 0.0) return 0.0;
  if (p == 1.0) return 1.0;
  double tail = 0.0;
  for (int j = k + 1; j <= n; ++j)
    tail += std::exp(std::lgamma(n + 1.0) - std::lgamma(j + 1.0) - std::lgamma(n - j + 1.0) +
                     j * std::log(p) + (n - j) * std::log1p(-p));
  return std::min(1.0, tail);
}

/// The smallest k with P(Binomial(n, p) > k) ≤ level: the most events a test of n trials may allow
/// so that a process at rate p fails it with probability at most `level`.
inline int allowed_events(int n, double p, double level) {
  int k = 0;
  while (k < n && binomial_tail_above(k, n, p) > level) ++k;
  return k;
}

}  // namespace imucal::test_support
