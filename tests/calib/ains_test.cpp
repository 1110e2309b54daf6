// AINS calibration against the truth simulator (paper §IV, ARCHITECTURE §6). Expected values come
// from the simulator's truth (and, for the smoother, from the simulator's true attitude), never
// from the estimator's own output.
#include "calib/ains/ains.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <set>
#include <stdexcept>
#include <string>

#include "ains_test_support.hpp"
#include "calib/ains/ains_model.hpp"
#include "calib/core/rotation.hpp"
#include "calib/sim/sim_input.hpp"

namespace imucal::calib {
using namespace imucal::calib::ains;
using namespace imucal::calib::core;
using namespace imucal::calib::effects;
using namespace imucal::calib::sim;
namespace {

using testing::factory_site;
using testing::short_profile;
using testing::simulate_run;

CalibrationInput make_input(const sequences::MotionProfile& profile, const UnitModel& unit,
                            uint64_t seed, bool noise) {
  const TableGeometry geom{};
  const SimResult sim = simulate_run(profile, geom, unit, seed, noise);
  return input_from_simulation(sim, geom, factory_site(), unit.noise);
}

void expect_within_ains(const CalibrationResult& r, const ParamSet& truth, double k) {
  const ParamVector e = r.params.to_vector() - truth.to_vector();
  const ParamVector s = r.sigma.to_vector();
  for (int i = 0; i < ParamSet::kSize; ++i)
    EXPECT_LT(std::abs(e(i)), k * s(i))
        << param_info(i).name << ": error " << e(i) * param_info(i).si_to_human << " "
        << param_info(i).human_unit << ", sigma " << s(i) * param_info(i).si_to_human;
}

TEST(AinsModel, StateLayoutMapsParamSetRowMajorToColumnMajorBlocks) {
  // Paper eq. 22: the state block multiplying f_c (I3 f_c) is column c of dM.
  EXPECT_EQ(ains::state_index_of_param(3 + 3 * 0 + 1), ains::kAccM + 3 * 1 + 0);    // M_a(0,1)
  EXPECT_EQ(ains::state_index_of_param(3 + 3 * 2 + 0), ains::kAccM + 3 * 0 + 2);    // M_a(2,0)
  EXPECT_EQ(ains::state_index_of_param(15 + 3 * 1 + 2), ains::kGyroM + 3 * 2 + 1);  // M_g(1,2)
  EXPECT_EQ(ains::state_index_of_param(26), ains::kTableMis + 2);
  std::set<int> seen;
  for (int i = 0; i < ParamSet::kSize; ++i) seen.insert(ains::state_index_of_param(i));
  EXPECT_EQ(seen.size(), 27u);
  EXPECT_EQ(*seen.begin(), ains::kNumNav);
  EXPECT_EQ(*seen.rbegin(), ains::kNumStates - 1);
  // Round trip through a state vector.
  ParamVector p;
  for (int i = 0; i < ParamSet::kSize; ++i) p(i) = 1.0 + i;
  ains::StateVec x = ains::StateVec::Zero();
  ains::params_to_sensor_states(p, x);
  EXPECT_EQ(ains::sensor_states_to_params(x), p);
  const ParamSet ps = ParamSet::from_vector(p);
  EXPECT_EQ(x(ains::kGyroM + 3 * 0 + 1), ps.gyro_M(1, 0));
}

TEST(Ains, NoiseFreeRecoversEveryParameterTightly) {
  UnitModel unit = default_unit();
  const CalibrationInput in = make_input(short_profile(), unit, 1, false);
  AinsOptions opt;
  // A vague prior on the table heading: with noise-free data only the prior could pull the
  // estimate off the truth (ς_z is gyrocompass-limited, its posterior is within 2x of 1 mrad).
  opt.prior_sigma.table_misalignment_rad.setConstant(0.05);
  const AinsResult r = calibrate_ains_detailed(in, opt);
  EXPECT_TRUE(r.calibration.converged);
  EXPECT_EQ(r.calibration.method, "ains");
  expect_within_ains(r.calibration, unit.params, 0.05);
  // Absolute sanity against the truth in human units (independent of the reported σ).
  const ParamSet e =
      ParamSet::from_vector(r.calibration.params.to_vector() - unit.params.to_vector());
  EXPECT_LT(e.accel_bias_mps2.cwiseAbs().maxCoeff(), 0.1 * kMicroG_mps2);
  EXPECT_LT(e.gyro_M.cwiseAbs().maxCoeff(), 0.1e-6);
  EXPECT_LT(e.accel_M.cwiseAbs().maxCoeff(), 0.1e-6);
}

TEST(Ains, WithNoiseEveryParameterWithinFourSigma) {
  UnitModel unit = default_unit();
  const CalibrationInput in = make_input(short_profile(), unit, 11, true);
  const AinsResult r = calibrate_ains_detailed(in);
  EXPECT_TRUE(r.calibration.converged);
  EXPECT_LE(r.calibration.iterations, 6);
  expect_within_ains(r.calibration, unit.params, 4.0);
  // The estimate must actually carry information: σ far below the prior everywhere but ς_z.
  const ParamVector s = r.calibration.sigma.to_vector();
  const ParamVector prior = default_prior_sigma().to_vector();
  for (int i = 0; i < ParamSet::kSize - 1; ++i)
    EXPECT_LT(s(i), 0.01 * prior(i)) << param_info(i).name;
  EXPECT_TRUE(r.calibration.warnings.empty());
}

TEST(Ains, FarFromNominalStillConvergesWithinFourSigma) {
  UnitModel unit = default_unit();
  ParamSet& p = unit.params;
  p.accel_bias_mps2 = Eigen::Vector3d(2.0, -2.0, 1.5) * 1e-3 * kStandardGravity_mps2;  // ±2 mg
  p.accel_M << 2000e-6, -2e-3, 1.5e-3,                                                 //
      2e-3, -2000e-6, -2e-3,                                                           //
      -1.5e-3, 2e-3, 2000e-6;
  p.gyro_bias_radps = Eigen::Vector3d(0.1, -0.1, 0.08) * kDegPerHourToRadPerSec;  // ±0.1 deg/h
  p.gyro_M << -2000e-6, 2e-3, -2e-3,                                              //
      -2e-3, 2000e-6, 1.8e-3,                                                     //
      2e-3, -1.8e-3, -2000e-6;
  const CalibrationInput in = make_input(short_profile(), unit, 5, true);
  const AinsResult r = calibrate_ains_detailed(in);
  EXPECT_TRUE(r.calibration.converged) << "passes: " << r.calibration.iterations;
  expect_within_ains(r.calibration, unit.params, 4.0);
  // The first pass linearises about zero: far from the truth, so more than one pass is needed and
  // the updates shrink.
  ASSERT_GE(r.update_norm_sigma.size(), 2u);
  EXPECT_LT(r.update_norm_sigma.back(), r.update_norm_sigma.front());
}

TEST(Ains, SmoothedNavigationMatchesTrueAttitudeAndZeroVelocity) {
  UnitModel unit = default_unit();
  const auto profile = short_profile();
  const CalibrationInput in = make_input(profile, unit, 21, true);
  const AinsResult r = calibrate_ains_detailed(in);
  ASSERT_FALSE(r.smoothed.empty());
  // Random-constant parameters: smoothed at the first epoch == filtered at the last.
  EXPECT_LT(r.smoother_param_mismatch_sigma, 1e-6);
  const TableModel table(TableGeometry{});
  size_t n_checked = 0, n_att_out = 0;
  for (const SmoothedNav& s : r.smoothed) {
    ASSERT_LT(s.sample_index, in.imu.size());
    EXPECT_DOUBLE_EQ(s.t_s, in.imu[s.sample_index].t_s);
    if (!in.reference[s.sample_index].at_rest) continue;
    // The simulator's true attitude (with ς) at that instant; the body is at rest (v = 0).
    const Eigen::Matrix3d C_true = true_C_bn(profile, table, unit, s.t_s);
    const Eigen::Vector3d att_err = matrix_to_rotvec(C_true * s.nav.C_bn.transpose());
    for (int i = 0; i < 3; ++i) {
      EXPECT_GT(s.sigma_psi_rad(i), 0.0);
      n_att_out += std::abs(att_err(i)) > 4.0 * s.sigma_psi_rad(i);
      EXPECT_LT(std::abs(s.nav.v_n_mps(i)), 5.0 * s.sigma_v_mps(i)) << "t " << s.t_s;
    }
    EXPECT_LT(std::abs(s.nav.height_m - factory_site().height_m), 5.0 * s.sigma_p_m(2) + 1e-4);
    ++n_checked;
  }
  EXPECT_GT(n_checked, 100u);
  // 4σ: allow the Gaussian tail (6e-5 per component) a few outliers, not a systematic error.
  EXPECT_LE(n_att_out, 3u) << "of " << 3 * n_checked;
}

TEST(Ains, SubIntervalLengthDoesNotMoveTheEstimate) {
  // The transition is accumulated over sub-intervals of propagation_interval_s, re-linearised in
  // each (issue #11 lengthened them from 0.1 s to 1 s for speed). Tenfold shorter sub-intervals
  // must give the same estimate to far below its σ, on the moves too (the short profile turns
  // the table through every axis).
  UnitModel unit = default_unit();
  const CalibrationInput in = make_input(short_profile(), unit, 31, true);
  AinsOptions fine, coarse;
  fine.propagation_interval_s = 0.1;
  coarse.propagation_interval_s = 1.0;
  ASSERT_EQ(AinsOptions{}.propagation_interval_s, coarse.propagation_interval_s);
  const CalibrationResult a = calibrate_ains(in, fine), b = calibrate_ains(in, coarse);
  const ParamVector d = (a.params.to_vector() - b.params.to_vector()).cwiseAbs();
  for (int i = 0; i < ParamSet::kSize; ++i) {
    EXPECT_LT(d(i), 0.005 * a.sigma.to_vector()(i)) << param_info(i).name;
    EXPECT_NEAR(a.sigma.to_vector()(i), b.sigma.to_vector()(i), 1e-3 * a.sigma.to_vector()(i))
        << param_info(i).name;
  }
}

TEST(Ains, CalibrationWithoutTheSmootherIsTheDetailedCalibration) {
  // calibrate_ains skips the epoch records and the RTS pass (they only feed the smoothed
  // navigation output): its calibration must be the detailed one's, bit for bit.
  UnitModel unit = default_unit();
  const CalibrationInput in = make_input(short_profile(), unit, 32, true);
  const AinsResult detailed = calibrate_ains_detailed(in);
  const CalibrationResult plain = calibrate_ains(in);
  EXPECT_EQ(plain.params.to_vector(), detailed.calibration.params.to_vector());
  EXPECT_EQ(plain.cov, detailed.calibration.cov);
  EXPECT_EQ(plain.iterations, detailed.calibration.iterations);
  EXPECT_EQ(plain.converged, detailed.calibration.converged);
  EXPECT_EQ(plain.warnings, detailed.calibration.warnings);
}

TEST(Ains, NoRestPeriodsIsRejectedWithAClearMessage) {
  UnitModel unit = default_unit();
  CalibrationInput in = make_input(short_profile(), unit, 2, true);
  for (auto& r : in.reference) r.at_rest = false;
  try {
    calibrate_ains(in);
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("no rest periods"), std::string::npos) << e.what();
    // Issue #19 item 9: the method's name, not the function's.
    EXPECT_EQ(std::string(e.what()).rfind("AINS: ", 0), 0u) << e.what();
  }
}

TEST(Ains, MalformedInputIsRejectedNamingTheField) {
  UnitModel unit = default_unit();
  const CalibrationInput good = make_input(short_profile(), unit, 2, true);
  auto expect_message = [](const CalibrationInput& in, const std::string& needle) {
    try {
      calibrate_ains(in);
      ADD_FAILURE() << "expected std::invalid_argument mentioning " << needle;
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
    }
  };
  CalibrationInput in = good;
  in.reference.pop_back();
  expect_message(in, "reference has");
  in = good;
  in.imu[1234].dv_mps(1) = std::numeric_limits<double>::quiet_NaN();
  expect_message(in, "imu[1234].dv_mps");
  in = good;
  in.reference[77].C_bn_ref(0, 0) = 2.0;
  expect_message(in, "reference[77].C_bn_ref");
  in = good;
  in.imu.clear();
  in.reference.clear();
  expect_message(in, "no IMU samples");
  // A sea run needs GNSS fixes; a factory run must not carry them.
  in = good;
  in.setting = Setting::kSea;
  expect_message(in, "GNSS");
  in = good;
  in.gnss.push_back({good.imu[10].t_s, good.site.lat_rad, good.site.lon_rad, 0.3});
  expect_message(in, "factory run");
  in = good;
  in.setting = Setting::kSea;
  in.gnss.push_back({good.imu.back().t_s + 5.0, good.site.lat_rad, good.site.lon_rad, 0.3});
  expect_message(in, "gnss[0].t_s");
}

}  // namespace
}  // namespace imucal::calib
