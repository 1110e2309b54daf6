// The held-out check (calib/checks/held_out_check.hpp, issue #48 item 6) on simulated land runs,
// judged by physics the code under test does not compute:
//  * with the unit's true parameters what is left is the sensors' white noise: at a rest of T
//    seconds the mean specific force scatters by VRW/√T along gravity, so the residuals' RMS is
//    √(mean VRW²/T); across a move of Δt the gravity carried by the gyros is off by the angle
//    random walk (ARW²Δt per axis, two axes move gravity) plus each rest's direction noise
//    ((VRW²/T)/g² per axis, two axes), plus — below navigation grade, where no gyro finds north —
//    the Earth's turn under gravity, Ω cos φ · Δt (north is horizontal, so the whole turn tips
//    gravity);
//  * with nothing compensated the MEMS unit's biases (up to 200 mg, 5 °/s) and scales (10 %, 24 %)
//    dwarf that;
//  * a parameter set with its x accelerometer bias off by δ moves the specific force by
//    −(I + dM_a)⁻¹ δ e_x (ARCHITECTURE §3's error model, inverted), so the magnitude at a rest
//    whose upward direction in body axes is u changes by −δ u·(I + dM_a)⁻¹ e_x to first order
//    (second order δ²/2g: 5 µg at 10 mg);
//  * at navigation grade each rest finds north from its gyros, so the Earth's turn is removed;
//    read as a tactical unit's (no north), each move's figure is that turn itself.
#include "calib/checks/held_out_check.hpp"

#include <gtest/gtest.h>

#include <Eigen/LU>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "calib/core/conventions.hpp"
#include "calib/core/earth.hpp"
#include "calib/core/site_presets.hpp"
#include "sequences/library.hpp"
#include "tests/support/field_unit.hpp"
#include "tests/support/mems_runs.hpp"

namespace imucal::calib::held_out_test {
using namespace imucal::calib::checks;
using namespace imucal::calib::core;
using namespace imucal::calib::sim;

/// The sample whose interval ends nearest t_s.
size_t sample_at(const ImuSeries& imu, double t_s) {
  size_t lo = 0, hi = imu.size() - 1;
  while (hi - lo > 1) {
    const size_t mid = (lo + hi) / 2;
    (imu[mid].t_s < t_s ? lo : hi) = mid;
  }
  return std::abs(imu[lo].t_s - t_s) < std::abs(imu[hi].t_s - t_s) ? lo : hi;
}

/// √(mean over rests of VRW²/T): the rests' residual RMS that white noise alone leaves.
double rest_noise_floor(const HeldOutCheck& c, const NoiseModel& noise) {
  double s = 0.0;
  for (const RestFigure& r : c.rests)
    s += noise.vrw_mps_per_sqrt_s * noise.vrw_mps_per_sqrt_s / (r.t_end_s - r.t_begin_s);
  return std::sqrt(s / static_cast<double>(c.rests.size()));
}

/// √(mean over moves of E[angle²]): white noise, and the Earth's turn where it is left in.
double move_noise_floor(const HeldOutCheck& c, const NoiseModel& noise, double g, double lat_rad,
                        bool earth_left_in) {
  double s = 0.0;
  for (size_t p = 0; p < c.moves.size(); ++p) {
    const double dt = c.moves[p].t_to_s - c.moves[p].t_from_s;
    auto dir2 = [&](const RestFigure& r) {
      return noise.vrw_mps_per_sqrt_s * noise.vrw_mps_per_sqrt_s / (r.t_end_s - r.t_begin_s) /
             (g * g);
    };
    const double earth = earth_left_in ? wgs84::kEarthRate_radps * std::cos(lat_rad) * dt : 0.0;
    s += 2.0 * (noise.arw_rad_per_sqrt_s * noise.arw_rad_per_sqrt_s * dt + dir2(c.rests[p]) +
                dir2(c.rests[p + 1])) +
         earth * earth;
  }
  return std::sqrt(s / static_cast<double>(c.moves.size()));
}

TEST(HeldOutCheck, TheTrueParametersLeaveTheNoiseAndNothingLeavesTheUnitsErrors) {
  for (uint64_t seed : {11u, 12u, 13u}) {
    const FieldSimResult sim = calib::testing::simulate_mems(seed);
    const CalibrationInput in = calib::testing::mems_input(sim);
    const HeldOutCheck c = check_held_out(in, sim.truth);
    ASSERT_GE(c.rests.size(), 30u) << "seed " << seed;  // 38 hand-placed positions and the start
    ASSERT_EQ(c.moves.size(), c.rests.size() - 1);
    EXPECT_FALSE(c.earth_rate_heading);
    const double rest_floor = rest_noise_floor(c, in.noise);
    const double move_floor = move_noise_floor(c, in.noise, c.gravity_mps2, in.site.lat_rad, true);
    std::printf(
        "seed %llu: %zu rests, |f|-g RMS raw %.2f mg, corrected %.3f mg (noise %.3f mg); %zu "
        "moves, carried gravity RMS raw %.2f deg, corrected %.4f deg (noise and Earth %.4f deg)\n",
        static_cast<unsigned long long>(seed), c.rests.size(),
        c.rest_rms_raw_mps2 / kStandardGravity_mps2 * 1e3,
        c.rest_rms_corrected_mps2 / kStandardGravity_mps2 * 1e3,
        rest_floor / kStandardGravity_mps2 * 1e3, c.moves.size(), c.move_rms_raw_rad * kRadToDeg,
        c.move_rms_corrected_rad * kRadToDeg, move_floor * kRadToDeg);
    // χ² of ~35 degrees of freedom: its RMS lies within [0.6, 1.5] of the expected at far beyond
    // 3σ (moves: per move an exponential-like square, ~1/√35 relative on the mean).
    EXPECT_GT(c.rest_rms_corrected_mps2, 0.6 * rest_floor) << "seed " << seed;
    EXPECT_LT(c.rest_rms_corrected_mps2, 1.5 * rest_floor) << "seed " << seed;
    EXPECT_GT(c.move_rms_corrected_rad, 0.6 * move_floor) << "seed " << seed;
    EXPECT_LT(c.move_rms_corrected_rad, 1.5 * move_floor) << "seed " << seed;
    EXPECT_GT(c.rest_rms_raw_mps2, 20.0 * c.rest_rms_corrected_mps2) << "seed " << seed;
    EXPECT_GT(c.move_rms_raw_rad, 20.0 * c.move_rms_corrected_rad) << "seed " << seed;
    // Below navigation grade the Earth's turn is left in, bounded by the longest move's.
    double longest = 0.0;
    for (const MoveFigure& m : c.moves) longest = std::max(longest, m.t_to_s - m.t_from_s);
    EXPECT_NEAR(c.earth_rate_bound_rad,
                wgs84::kEarthRate_radps * std::cos(in.site.lat_rad) * longest, 1e-12);
  }
}

TEST(HeldOutCheck, ZeroParametersAreTheRawFigures) {
  const FieldSimResult sim = calib::testing::simulate_mems(14);
  const HeldOutCheck c = check_held_out(calib::testing::mems_input(sim), ParamSet{});
  ASSERT_GE(c.rests.size(), 2u);
  for (const RestFigure& r : c.rests) EXPECT_EQ(r.corrected_mps2, r.raw_mps2);
  for (const MoveFigure& m : c.moves) EXPECT_EQ(m.corrected_rad, m.raw_rad);
  EXPECT_EQ(c.rest_rms_corrected_mps2, c.rest_rms_raw_mps2);
  EXPECT_EQ(c.move_rms_corrected_rad, c.move_rms_raw_rad);
}

TEST(HeldOutCheck, AnAccelerometerBiasOffBy10MgShowsWhereItsAxisSeesGravity) {
  const FieldSimResult sim = calib::testing::simulate_mems(15);
  const CalibrationInput in = calib::testing::mems_input(sim);
  const double delta = 10e-3 * kStandardGravity_mps2;
  ParamSet wrong = sim.truth;
  wrong.accel_bias_mps2(0) += delta;
  const HeldOutCheck right = check_held_out(in, sim.truth), off = check_held_out(in, wrong);
  ASSERT_EQ(right.rests.size(), off.rests.size());
  // What a bias error in the x channel is in true specific force.
  const Eigen::Vector3d e_x_true =
      (Eigen::Matrix3d::Identity() + sim.truth.accel_M).inverse() * Eigen::Vector3d::UnitX();
  int x_vertical = 0;
  for (size_t p = 0; p < right.rests.size(); ++p) {
    const RestFigure& r = right.rests[p];
    const size_t mid = sample_at(in.imu, 0.5 * (r.t_begin_s + r.t_end_s));
    const Eigen::Vector3d up_b = sim.C_bn[mid].transpose() * Eigen::Vector3d(0.0, 0.0, -1.0);
    const double expected = -delta * up_b.dot(e_x_true);
    const double change = off.rests[p].corrected_mps2 - r.corrected_mps2;
    EXPECT_NEAR(change, expected, 0.05e-3 * kStandardGravity_mps2) << "rest " << p;
    EXPECT_EQ(off.rests[p].raw_mps2, r.raw_mps2);
    if (std::abs(up_b(0)) > 0.6) {
      ++x_vertical;
      // About 10 mg times the share of gravity on x: the unit's scale (≤ 10 %) and misalignment
      // (≤ 50 mrad, on the other axes' share ≤ 0.8 each) move it by at most a fifth.
      const double ratio = std::abs(change) / (delta * std::abs(up_b(0)));
      EXPECT_GT(ratio, 0.75) << "rest " << p << ", up_x " << up_b(0);
      EXPECT_LT(ratio, 1.25) << "rest " << p << ", up_x " << up_b(0);
    }
  }
  EXPECT_GE(x_vertical, 4);  // the hand tipped x well up or down several times
  EXPECT_GT(off.rest_rms_corrected_mps2, 3.0 * right.rest_rms_corrected_mps2);
}

TEST(HeldOutCheck, AtNavigationGradeTheEarthsTurnIsRemovedAndBelowItIsWhatRemains) {
  FieldSimOptions o;
  o.setting = Setting::kLand;
  o.seed = 3;
  const effects::UnitModel unit = test_support::field_unit();
  const FieldSimResult sim =
      simulate_field(sequences::load_profile("short"), demo_factory_site(), unit, o);
  CalibrationInput in = input_from_field_data(Setting::kLand, sim.imu, {}, demo_factory_site(),
                                              unit.noise, Grade::kNavigation);
  const HeldOutCheck nav = check_held_out(in, sim.truth);
  ASSERT_GE(nav.moves.size(), 10u);
  EXPECT_TRUE(nav.earth_rate_heading);
  EXPECT_EQ(nav.earth_rate_bound_rad, 0.0);
  const double floor = move_noise_floor(nav, in.noise, nav.gravity_mps2, in.site.lat_rad, false);
  const double om_h = wgs84::kEarthRate_radps * std::cos(in.site.lat_rad);
  double mean_dt = 0.0;
  for (const MoveFigure& m : nav.moves)
    mean_dt += (m.t_to_s - m.t_from_s) / static_cast<double>(nav.moves.size());
  std::printf(
      "navigation grade: carried gravity RMS %.2f µrad (noise %.2f µrad; Earth's turn over "
      "a mean move %.0f µrad)\n",
      nav.move_rms_corrected_rad * 1e6, floor * 1e6, om_h * mean_dt * 1e6);
  // The heading comes from each rest's gyros (0.0015 °/√h over 25 s: a few mrad of heading), so
  // what is left of the turn is a few thousandths of it, beside the noise.
  EXPECT_LT(nav.move_rms_corrected_rad, 2.0 * floor + 0.01 * om_h * mean_dt);
  // Read as a tactical unit's: each move's figure is the Earth's turn, Ω cos φ Δt.
  in.grade = Grade::kTactical;
  const HeldOutCheck tac = check_held_out(in, sim.truth);
  EXPECT_FALSE(tac.earth_rate_heading);
  ASSERT_EQ(tac.moves.size(), nav.moves.size());
  for (const MoveFigure& m : tac.moves) {
    const double turn = om_h * (m.t_to_s - m.t_from_s);
    EXPECT_NEAR(m.corrected_rad, turn, 0.02 * turn + 5.0 * floor) << "move from " << m.t_from_s;
    EXPECT_LE(m.corrected_rad, tac.earth_rate_bound_rad + 5.0 * floor);
  }
}

TEST(HeldOutCheck, FewerThanTwoRestsIsRefusedSayingHowManyWereFound) {
  const FieldSimResult sim = calib::testing::simulate_mems(16);
  CalibrationInput in = calib::testing::mems_input(sim);
  auto message = [](const CalibrationInput& i) {
    try {
      check_held_out(i, ParamSet{});
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  // Keep only the first rest (the 50 s start).
  bool first_done = false;
  for (size_t k = 0; k < in.reference.size(); ++k) {
    if (!in.reference[k].at_rest && k > 0 && in.reference[k - 1].at_rest) first_done = true;
    if (first_done) in.reference[k].at_rest = false;
  }
  const std::string one = message(in);
  EXPECT_NE(one.find("found 1 usable rest "), std::string::npos) << one;
  EXPECT_NE(one.find("needs at least 2"), std::string::npos) << one;
  for (ReferenceSample& r : in.reference) r.at_rest = false;
  const std::string none = message(in);
  EXPECT_NE(none.find("found 0 usable rests"), std::string::npos) << none;
}

}  // namespace imucal::calib::held_out_test
