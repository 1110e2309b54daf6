// Cross-check (ARCHITECTURE §6): per-parameter agreement within k·sqrt(σA² + σB²) and both methods'
// metrics under their limits. Expected numbers in the messages are computed here from the
// inputs and the unit definitions, not read back from the code.
#include "calib/checks/crosscheck.hpp"

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

CalibrationResult result(const std::string& method) {
  return calib::testing::plausible_result(method);
}

EvaluationMetrics metrics(double orientation_mdeg, double accel_ug) {
  EvaluationMetrics m;
  m.orientation_rmse_mdeg = orientation_mdeg;
  m.accel_rmse_ug = accel_ug;
  return m;
}

/// Index of a parameter by name, found through the metadata (so the test does not assume the
/// flat order).
int index_of(const std::string& name) {
  for (int i = 0; i < ParamSet::kSize; ++i)
    if (param_info(i).name == name) return i;
  ADD_FAILURE() << "no parameter " << name;
  return 0;
}

}  // namespace

TEST(CrossCheck, IdenticalResultsPass) {
  const CalibrationResult a = result("ains"), b = result("nlsq");
  const CrossCheckResult r = cross_check(a, metrics(22.5, 27.7), b, metrics(22.6, 24.6));
  EXPECT_TRUE(r.pass);
  EXPECT_TRUE(r.failures.empty());
  EXPECT_EQ(r.verdict(), "PASS");
}

TEST(CrossCheck, ParameterMovedByFiveSigmaIsNamedWithHumanUnits) {
  const CalibrationResult a = result("ains");
  CalibrationResult b = result("nlsq");
  // σA = σB = 3 µg -> combined 3√2 = 4.243 µg; 5σ = 21.21 µg; the 4σ bound is 16.97 µg.
  const double combined_ug = std::sqrt(2.0) * 3.0;
  b.params.accel_bias_mps2(1) += 5.0 * combined_ug * kMicroG_mps2;
  const CrossCheckResult r = cross_check(a, metrics(10, 10), b, metrics(10, 10));
  EXPECT_FALSE(r.pass);
  EXPECT_EQ(r.verdict(), "REVIEW");
  ASSERT_EQ(r.failures.size(), 1u);
  EXPECT_EQ(r.failures[0].term, "accel_bias_mps2[1]");
  EXPECT_EQ(r.failures[0].detail, "accel_bias_mps2[1]: |Δ| = 21.2 µg > 4σ bound 17.0 µg");
}

TEST(CrossCheck, EachGroupReportsItsOwnUnit) {
  const CalibrationResult a = result("ains");
  CalibrationResult b = result("nlsq");
  // Gyro bias: σ 0.001 deg/h each -> bound 4·√2·0.001 = 0.00566 deg/h; move by 0.01 deg/h.
  b.params.gyro_bias_radps(2) += 0.01 * kDegPerHourToRadPerSec;
  // Gyro scale: σ 4 ppm each -> bound 22.6 ppm; move by 50 ppm.
  b.params.gyro_M(1, 1) -= 50e-6;
  // Accel misalignment: σ 5 ppm (µrad) each -> bound 28.3 µrad; move by 30 µrad.
  b.params.accel_M(0, 2) += 30e-6;
  // Table misalignment: σ 1 arcsec each -> bound 5.66 arcsec; move by 12 arcsec.
  b.params.table_misalignment_rad(0) += 12.0 * kArcsecToRad;
  const CrossCheckResult r = cross_check(a, metrics(10, 10), b, metrics(10, 10));
  ASSERT_EQ(r.failures.size(), 4u);
  auto detail_of = [&](const std::string& term) -> std::string {
    for (const auto& f : r.failures)
      if (f.term == term) return f.detail;
    return "<missing " + term + ">";
  };
  EXPECT_EQ(detail_of("gyro_bias_radps[2]"),
            "gyro_bias_radps[2]: |Δ| = 0.01 deg/h > 4σ bound 0.00566 deg/h");
  EXPECT_EQ(detail_of("gyro_M[1][1]"), "gyro_M[1][1]: |Δ| = 50.0 ppm > 4σ bound 22.6 ppm");
  EXPECT_EQ(detail_of("accel_M[0][2]"), "accel_M[0][2]: |Δ| = 30.0 µrad > 4σ bound 28.3 µrad");
  EXPECT_EQ(detail_of("table_misalignment_rad[0]"),
            "table_misalignment_rad[0]: |Δ| = 12.0 arcsec > 4σ bound 5.7 arcsec");
}

TEST(CrossCheck, KFromOptionsIsRespected) {
  const CalibrationResult a = result("ains");
  CalibrationResult b = result("nlsq");
  const int i = index_of("gyro_M[2][0]");
  ParamVector x = b.params.to_vector();
  const double combined = std::sqrt(2.0) * 4e-6;
  x(i) += 5.0 * combined;  // 5σ apart
  b.params = ParamSet::from_vector(x);

  CrossCheckOptions k6;
  k6.k_sigma = 6.0;
  EXPECT_TRUE(cross_check(a, metrics(10, 10), b, metrics(10, 10), k6).pass);
  CrossCheckOptions k4;  // default k = 4
  const CrossCheckResult r4 = cross_check(a, metrics(10, 10), b, metrics(10, 10), k4);
  ASSERT_EQ(r4.failures.size(), 1u);
  EXPECT_EQ(r4.failures[0].term, "gyro_M[2][0]");
  EXPECT_NE(r4.failures[0].detail.find("> 4σ bound"), std::string::npos) << r4.failures[0].detail;
  CrossCheckOptions k5p5;
  k5p5.k_sigma = 5.5;
  EXPECT_TRUE(cross_check(a, metrics(10, 10), b, metrics(10, 10), k5p5).pass);
  k5p5.k_sigma = 4.5;
  const CrossCheckResult r45 = cross_check(a, metrics(10, 10), b, metrics(10, 10), k5p5);
  ASSERT_EQ(r45.failures.size(), 1u);
  EXPECT_NE(r45.failures[0].detail.find("> 4.5σ bound"), std::string::npos)
      << r45.failures[0].detail;
}

TEST(CrossCheck, MetricOverLimitIsNamed) {
  const CalibrationResult a = result("ains"), b = result("nlsq");
  const CrossCheckResult r = cross_check(a, metrics(35.0, 20.0), b, metrics(20.0, 41.5));
  EXPECT_EQ(r.verdict(), "REVIEW");
  ASSERT_EQ(r.failures.size(), 2u);
  EXPECT_EQ(r.failures[0].term, "orientation_rmse_mdeg");
  EXPECT_EQ(r.failures[0].detail, "ains: orientation RMSE 35.0 mdeg > limit 30.0 mdeg");
  EXPECT_EQ(r.failures[1].term, "accel_rmse_ug");
  EXPECT_EQ(r.failures[1].detail, "nlsq: acceleration RMSE 41.5 µg > limit 40.0 µg");

  CrossCheckOptions loose;
  loose.max_orientation_rmse_mdeg = 40.0;
  loose.max_accel_rmse_ug = 45.0;
  EXPECT_TRUE(cross_check(a, metrics(35.0, 20.0), b, metrics(20.0, 41.5), loose).pass);
}

TEST(CrossCheck, NonFiniteInputsNeverPass) {
  const CalibrationResult a = result("ains");
  CalibrationResult b = result("nlsq");
  b.sigma.accel_M(2, 2) = std::nan("");
  const CrossCheckResult r1 = cross_check(a, metrics(10, 10), b, metrics(10, 10));
  ASSERT_EQ(r1.failures.size(), 1u);
  EXPECT_EQ(r1.failures[0].term, "accel_M[2][2]");

  const CrossCheckResult r2 =
      cross_check(a, metrics(std::nan(""), 10), result("nlsq"), metrics(10, 10));
  ASSERT_EQ(r2.failures.size(), 1u);
  EXPECT_EQ(r2.failures[0].term, "orientation_rmse_mdeg");
}

TEST(CrossCheck, RejectsInvalidOptions) {
  const CalibrationResult a = result("ains");
  CrossCheckOptions o;
  o.k_sigma = 0.0;
  EXPECT_THROW(cross_check(a, metrics(1, 1), a, metrics(1, 1), o), std::invalid_argument);
  o = {};
  o.max_accel_rmse_ug = -1.0;
  EXPECT_THROW(cross_check(a, metrics(1, 1), a, metrics(1, 1), o), std::invalid_argument);
}
