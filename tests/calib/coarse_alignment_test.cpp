// Levelling and gyrocompassing from the IMU data (calib/core/coarse_alignment.hpp) against the
// table simulator's true attitude; error sizes from the gyrocompass physics, worked out by hand.
#include "calib/core/coarse_alignment.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "ains_test_support.hpp"
#include "calib/core/calibration_input.hpp"
#include "calib/sim/sim_input.hpp"

namespace imucal::calib {
using namespace imucal::calib::core;
using namespace imucal::calib::effects;
using namespace imucal::calib::sim;
namespace {

using testing::factory_site;

struct AlignRun {
  SimResult sim;
  CalibrationInput in;
  RestPeriod first;
};

AlignRun table_run(const UnitModel& unit, bool noise, double heading_rad = 0.3) {
  sequences::MotionProfile p = testing::start_profile("align", 120.0);
  testing::append_move(p, true, 90.0, 30.0);
  TableGeometry g;
  g.heading_rad = heading_rad;
  AlignRun r;
  r.sim = testing::simulate_run(p, g, unit, 11, noise);
  r.in = input_from_simulation(r.sim, g, factory_site(), unit.noise);
  r.first = find_rest_periods(r.in, 100).front();
  return r;
}

/// Tilt (north/east) and heading parts of the attitude error, rad.
Eigen::Vector3d attitude_error(const Eigen::Matrix3d& C_est, const Eigen::Matrix3d& C_true) {
  return matrix_to_rotvec(C_est * C_true.transpose());
}

TEST(CoarseAlignment, ErrorFreeUnitAlignsExactly) {
  UnitModel unit = default_unit();
  unit.params = ParamSet{};
  const AlignRun r = table_run(unit, false);
  const CoarseAlignment a =
      coarse_align(r.in.imu, r.first.begin, r.first.end, factory_site(), ParamSet{}, 0.0);
  const Eigen::Vector3d e = attitude_error(a.C_bn, r.in.reference[r.first.begin].C_bn_ref);
  EXPECT_LT(e.norm(), 1e-7) << e.transpose();
  EXPECT_GT(a.window_s, 100.0);
}

TEST(CoarseAlignment, HeadingErrorIsEastGyroBiasOverHorizontalEarthRate) {
  // Classic gyrocompass limit: an east gyro bias b_E is read as Earth rate, giving a heading
  // error of b_E / (Ω cos φ); a north accel bias tilts the level by b_N / g. Body x = north at
  // table heading 0, outer 0 (calib/core/table_model.hpp), so body y = east.
  UnitModel unit = default_unit();
  unit.params = ParamSet{};
  const double bE = 0.01 * kDegPerHourToRadPerSec, bN = 50 * kMicroG_mps2;
  unit.params.gyro_bias_radps(1) = bE;
  unit.params.accel_bias_mps2(0) = bN;
  const AlignRun r = table_run(unit, false, 0.0);
  const CoarseAlignment a =
      coarse_align(r.in.imu, r.first.begin, r.first.end, factory_site(), ParamSet{}, 0.0);
  const Eigen::Vector3d e = attitude_error(a.C_bn, r.in.reference[r.first.begin].C_bn_ref);
  const double g = EarthModel(factory_site()).gravity_mps2();
  const double heading = bE / (wgs84::kEarthRate_radps * std::cos(factory_site().lat_rad));
  EXPECT_NEAR(std::abs(e(2)), heading, 0.05 * heading) << e.transpose();
  EXPECT_NEAR(std::abs(e(1)), bN / g, 0.05 * bN / g) << e.transpose();  // tilt about east
  // Compensating with the true parameters removes both.
  const CoarseAlignment b =
      coarse_align(r.in.imu, r.first.begin, r.first.end, factory_site(), unit.params, 0.0);
  EXPECT_LT(attitude_error(b.C_bn, r.in.reference[r.first.begin].C_bn_ref).norm(), 1e-7);
}

TEST(CoarseAlignment, NoisyRunWithinAFewMilliradians) {
  const UnitModel unit = default_unit();
  const AlignRun r = table_run(unit, true);
  const CoarseAlignment a = coarse_align(r.in.imu, r.first.begin, r.first.end, factory_site(),
                                         ParamSet{}, unit.noise.vrw_mps_per_sqrt_s);
  const Eigen::Vector3d e = attitude_error(a.C_bn, r.in.reference[r.first.begin].C_bn_ref);
  // Tilt: accel misalignment ≤ 150 µrad, bias ≤ 50 µg (5e-5 rad), ς ≤ 15" (7e-5 rad): < 3e-4.
  // Heading: gyro bias 0.01 °/h (≈ 1 mrad), ARW over 120 s, ς_z 30": a few mrad at most.
  EXPECT_LT(e.head<2>().norm(), 3e-4) << e.transpose();
  EXPECT_LT(std::abs(e(2)), 5e-3) << e.transpose();
  EXPECT_GT(a.heading_noise_sigma_rad, 0.0);
  EXPECT_LT(a.heading_noise_sigma_rad, 5e-3);
}

TEST(CoarseAlignment, ToleratesRotationInsideTheWindow) {
  // The gyros carry b0 through any turning (a rocking deck, a hand rotation), so a window that
  // spans the table's 90° move still finds the attitude at its start.
  UnitModel unit = default_unit();
  unit.params = ParamSet{};
  const AlignRun r = table_run(unit, false);
  const size_t b = r.first.end - 3000;  // 30 s before the move, through it and the next rest
  const CoarseAlignment a =
      coarse_align(r.in.imu, b, r.in.imu.size(), factory_site(), ParamSet{}, 0.0);
  EXPECT_LT(attitude_error(a.C_bn, r.in.reference[b].C_bn_ref).norm(), 1e-7);
}

TEST(CoarseAlignment, RefusesShortWindowsAndPoles) {
  const UnitModel unit = default_unit();
  const AlignRun r = table_run(unit, false);
  auto message = [&](size_t b, size_t e, Site site) {
    try {
      coarse_align(r.in.imu, b, e, site, ParamSet{}, 0.0);
    } catch (const std::invalid_argument& ex) {
      return std::string(ex.what());
    }
    return std::string();
  };
  EXPECT_NE(message(r.first.begin, r.first.begin + 500, factory_site()).find("at least 10 s"),
            std::string::npos);
  Site pole = factory_site();
  pole.lat_rad = 89.5 * kDegToRad;
  EXPECT_NE(message(r.first.begin, r.first.end, pole).find("pole"), std::string::npos);
  EXPECT_NE(message(5, 5, factory_site()).find("window"), std::string::npos);
}

}  // namespace
}  // namespace imucal::calib
