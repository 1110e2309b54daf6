// CRLB / observability (ARCHITECTURE §6): the covariance-only run of the AINS model along the true
// trajectory. Checked against the AINS on simulated data and against what the physics of a
// rank-deficient sequence says must be unobservable.
#include "calib/checks/crlb.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <set>
#include <stdexcept>
#include <string>

#include "ains_test_support.hpp"
#include "calib/sim/sim_input.hpp"

namespace imucal::calib {
using namespace imucal::calib::ains;
using namespace imucal::calib::checks;
using namespace imucal::calib::core;
using namespace imucal::calib::effects;
using namespace imucal::calib::sim;
namespace {

using testing::factory_site;

CrlbResult crlb_of(const sequences::MotionProfile& profile) {
  return compute_crlb(profile, TableGeometry{}, factory_site(), NoiseModel{}, 100.0);
}

TEST(Crlb, EqualsTheAinsReportedSigmaOnTheSameSequence) {
  const auto profile = testing::short_profile();
  const UnitModel unit = default_unit();
  const SimResult sim = testing::simulate_run(profile, TableGeometry{}, unit, 4, true);
  const CalibrationInput in =
      input_from_simulation(sim, TableGeometry{}, factory_site(), unit.noise);
  const CalibrationResult ains = calibrate_ains(in);
  const CrlbResult crlb = compute_crlb(profile, TableGeometry{}, factory_site(), unit.noise, 100.0);
  const ParamVector a = ains.sigma.to_vector(), c = crlb.sigma.to_vector();
  for (int i = 0; i < ParamSet::kSize; ++i) {
    // Same linear model; the AINS linearises about its estimate instead of the truth and runs on
    // the recorded time axis, so agreement is close but not bit-exact.
    EXPECT_GT(a(i) / c(i), 0.9) << param_info(i).name;
    EXPECT_LT(a(i) / c(i), 1.1) << param_info(i).name;
  }
  EXPECT_TRUE(crlb.cov.isApprox(crlb.cov.transpose(), 1e-9));
}

TEST(Crlb, MoreNoiseMeansLargerBound) {
  const auto profile = testing::short_profile();
  NoiseModel quiet, loud;
  loud.arw_rad_per_sqrt_s = 4.0 * quiet.arw_rad_per_sqrt_s;
  loud.vrw_mps_per_sqrt_s = 4.0 * quiet.vrw_mps_per_sqrt_s;
  const ParamVector q =
      compute_crlb(profile, TableGeometry{}, factory_site(), quiet, 100.0).sigma.to_vector();
  const ParamVector l =
      compute_crlb(profile, TableGeometry{}, factory_site(), loud, 100.0).sigma.to_vector();
  // Away from the prior the bound scales with the noise (aiding noise is fixed, so not exactly 4x).
  for (int i = 0; i < ParamSet::kSize - 1; ++i) {
    EXPECT_GT(l(i) / q(i), 2.0) << param_info(i).name;
    EXPECT_LT(l(i) / q(i), 4.5) << param_info(i).name;
  }
}

TEST(Crlb, FullSequenceHasNoUnobservableParameter) {
  const CrlbResult c = crlb_of(testing::short_profile());
  const std::vector<std::string> names = unobservable_parameters(c);
  EXPECT_TRUE(names.empty()) << "first: " << (names.empty() ? "" : names.front());
}

TEST(Crlb, InnerAxisOnlySequenceIsRankDeficientAndNamesTheParameters) {
  // Inner-axis turns at outer = 0: the body turns about z only, z always down. Physics: f_x = f_y
  // = 0 (accel dM columns 0 and 1 unseen), the accel biases alias with g·dM column 2, and the gyro
  // sees x/y rates only from the Earth rate (gyro dM columns 0 and 1 weakly seen at best).
  const CrlbResult c = crlb_of(testing::inner_only_profile());
  const std::vector<std::string> names = unobservable_parameters(c);
  const std::set<std::string> got(names.begin(), names.end());
  for (const char* must :
       {"gyro_M[0][0]", "gyro_M[1][1]", "gyro_M[0][1]", "gyro_M[2][0]", "accel_M[0][0]",
        "accel_M[1][1]", "accel_M[2][1]", "accel_bias_mps2[2]", "accel_M[2][2]"})
    EXPECT_TRUE(got.count(must)) << must << " should be unobservable";
  // Turning about z does excite the gyro's z column, and the tilt is seen through gravity.
  for (const char* must_not : {"gyro_M[0][2]", "gyro_M[1][2]", "gyro_M[2][2]",
                               "table_misalignment_rad[0]", "table_misalignment_rad[1]"})
    EXPECT_FALSE(got.count(must_not)) << must_not << " should be observable";
  // Nothing outside what the physics allows.
  for (const std::string& n : names) {
    const bool allowed = n.rfind("accel_", 0) == 0 || n.rfind("gyro_bias", 0) == 0 ||
                         n == "table_misalignment_rad[2]" ||
                         (n.rfind("gyro_M[", 0) == 0 && n.substr(9) != "[2]");
    EXPECT_TRUE(allowed) << n;
  }
  // The flagged ones are near their prior; the excited ones far below.
  const ParamVector ratio = crlb_prior_ratio(c);
  EXPECT_GT(ratio(3 + 0), 0.9);    // accel_M[0][0]: no signal at all
  EXPECT_LT(ratio(15 + 8), 1e-3);  // gyro_M[2][2]
}

TEST(Crlb, BadProfilesAreRejected) {
  sequences::MotionProfile empty;
  empty.name = "empty";
  EXPECT_THROW(crlb_of(empty), std::invalid_argument);
  EXPECT_THROW(
      compute_crlb(testing::short_profile(), TableGeometry{}, factory_site(), NoiseModel{}, 0.0),
      std::invalid_argument);
  // A profile that never rests long enough cannot be aided.
  sequences::MotionProfile moving = testing::start_profile("moving", 0.5);
  testing::append_move(moving, true, 180.0, 0.5);
  try {
    crlb_of(moving);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("moving"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("no rest periods"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace imucal::calib
