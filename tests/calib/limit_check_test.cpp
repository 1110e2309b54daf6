// Limit checks of one method's result (calib/checks/limit_check.hpp): convergence, finite numbers,
// the datasheet envelope, and the paper's metrics where no cross-check looks at them. The limits in
// the expected messages are computed here from the options, not read back from the code.
#include "calib/checks/limit_check.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>

#include "calib/sim/truth_sim.hpp"
#include "plausible_result.hpp"

using namespace imucal;
using namespace imucal::calib;
using namespace imucal::calib::checks;
using namespace imucal::calib::core;

namespace {

CalibrationResult healthy(const std::string& method) {
  return calib::testing::plausible_result(method);
}

EvaluationMetrics metrics_limit_check(double orientation_mdeg, double accel_ug) {
  EvaluationMetrics m;
  m.orientation_rmse_mdeg = orientation_mdeg;
  m.accel_rmse_ug = accel_ug;
  return m;
}

LimitCheckResult check(const CalibrationResult& r, const EvaluationMetrics& m = metrics_limit_check(5, 5),
                       bool with_metrics = true, const LimitCheckOptions& o = {}) {
  LimitCheckResult out;
  check_limits(r, m, with_metrics, o, out);
  return out;
}

bool names(const LimitCheckResult& r, const std::string& term, const std::string& text) {
  for (const auto& f : r.failures)
    if (f.term == term && f.detail.find(text) != std::string::npos) return true;
  return false;
}

TEST(LimitCheck, HealthyUnitPasses) {
  const LimitCheckResult r = check(healthy("ains"));
  EXPECT_TRUE(r.pass);
  EXPECT_TRUE(r.failures.empty());
}

TEST(LimitCheck, AbsurdScaleFactorNamedInHumanUnits) {
  CalibrationResult r = healthy("nlsq");
  r.params.gyro_M(1, 1) = 0.02;  // 2 %: a broken or wrong unit, not a calibration
  const LimitCheckResult c = check(r);
  EXPECT_FALSE(c.pass);
  ASSERT_EQ(c.failures.size(), 1u);
  EXPECT_TRUE(names(c, "gyro_M[1][1]", "nlsq: gyro_M[1][1] = 20000 ppm")) << c.failures[0].detail;
  const double limit_ppm = LimitCheckOptions{}.datasheet.gyro_scale * 1e6;
  EXPECT_NE(c.failures[0].detail.find(std::to_string(static_cast<int>(limit_ppm)) + " ppm"),
            std::string::npos)
      << c.failures[0].detail;
}

TEST(LimitCheck, BiasBeyondTheEnvelopeFailsBothSigns) {
  CalibrationResult r = healthy("ains");
  const LimitCheckOptions o;
  r.params.accel_bias_mps2(2) = -1.5 * o.datasheet.accel_bias_mps2;
  r.params.gyro_bias_radps(0) = 1.01 * o.datasheet.gyro_bias_radps;
  const LimitCheckResult c = check(r);
  EXPECT_EQ(c.failures.size(), 2u);
  EXPECT_TRUE(names(c, "accel_bias_mps2[2]", "µg"));
  EXPECT_TRUE(names(c, "gyro_bias_radps[0]", "deg/h"));
  r.params.gyro_bias_radps(0) = 0.99 * o.datasheet.gyro_bias_radps;  // just inside
  EXPECT_EQ(check(r).failures.size(), 1u);
}

TEST(LimitCheck, NotConvergedFails) {
  CalibrationResult r = healthy("ains");
  r.converged = false;
  r.iterations = 30;
  const LimitCheckResult c = check(r);
  EXPECT_FALSE(c.pass);
  EXPECT_TRUE(names(c, "converged", "did not converge in 30 iterations"));
}

TEST(LimitCheck, NonFiniteEstimateOrSigmaFails) {
  CalibrationResult r = healthy("ains");
  r.sigma.accel_M(0, 2) = std::nan("");
  r.params.gyro_M(2, 0) = INFINITY;
  const LimitCheckResult c = check(r);
  EXPECT_TRUE(names(c, "accel_M[0][2]", "not a finite number"));
  EXPECT_TRUE(names(c, "gyro_M[2][0]", "not a finite number"));
}

TEST(LimitCheck, UnobservableTermsAreNotJudged) {
  CalibrationResult r = healthy("ains");
  r.params.table_misalignment_rad(0) = 1.0;  // a placeholder, e.g. no table on land
  EXPECT_FALSE(check(r).pass);
  for (int i = 24; i < 27; ++i) r.observable[static_cast<size_t>(i)] = false;
  EXPECT_TRUE(check(r).pass);
}

TEST(LimitCheck, MetricsOnlyWhenAskedAndEvaluated) {
  const EvaluationMetrics bad = metrics_limit_check(31.0, 41.0);
  EXPECT_EQ(check(healthy("ains"), bad, true).failures.size(), 2u);
  EXPECT_TRUE(check(healthy("ains"), bad, false).pass);  // the cross-check holds them
  EvaluationMetrics none = bad;
  none.evaluated = false;
  EXPECT_TRUE(check(healthy("ains"), none, true).pass);
}

TEST(LimitCheck, RefusesNonPositiveLimits) {
  LimitCheckOptions o;
  o.datasheet.accel_scale = 0.0;
  EXPECT_THROW(check(healthy("ains"), metrics_limit_check(5, 5), true, o), std::invalid_argument);
}

}  // namespace
