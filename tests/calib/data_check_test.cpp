// Sanity checks of the raw data (calib/checks/data_check.hpp): clean simulated runs of every
// setting pass; each corruption an operator meets (stuck, clipped, swapped, sign-flipped axes, a
// unit that did not move, a wrong fixture orientation, a clock jump) is found and named — and the
// pipeline refuses to calibrate it.
#include "calib/checks/data_check.hpp"

#include <gtest/gtest.h>

#include <functional>

#include "ains_test_support.hpp"
#include "calib/pipeline/calibration_pipeline.hpp"
#include "calib/sim/field_sim.hpp"
#include "calib/sim/sim_input.hpp"

namespace imucal::calib {
using namespace imucal::calib::checks;
using namespace imucal::calib::core;
using namespace imucal::calib::effects;
using namespace imucal::calib::pipeline;
using namespace imucal::calib::sim;
namespace {

const CalibrationInput& clean_factory() {
  static const CalibrationInput in = [] {
    const UnitModel unit = default_unit();
    const SimResult sim =
        testing::simulate_run(testing::short_profile(), TableGeometry{}, unit, 3, true);
    return input_from_simulation(sim, TableGeometry{}, testing::factory_site(), unit.noise);
  }();
  return in;
}

CalibrationInput field(Setting setting) {
  FieldSimOptions o;
  o.setting = setting;
  o.seed = 4;
  const UnitModel unit = default_unit();
  const FieldSimResult r =
      simulate_field(testing::short_profile(), testing::factory_site(), unit, o);
  return input_from_field_data(setting, r.imu, r.gnss, testing::factory_site(), unit.noise);
}

std::string symptoms(const std::vector<DataProblem>& p) {
  std::string s;
  for (const auto& x : p) s += "[" + x.symptom + "] " + x.detail + "\n";
  return s;
}

bool has(const std::vector<DataProblem>& p, const std::string& symptom) {
  for (const auto& x : p)
    if (x.symptom == symptom) return true;
  return false;
}

CalibrationInput corrupted(const std::function<void(ImuIncrement&, size_t)>& edit) {
  CalibrationInput in = clean_factory();
  for (size_t i = 0; i < in.imu.size(); ++i) edit(in.imu[i], i);
  return in;
}

TEST(DataCheck, CleanRunsOfEverySettingPass) {
  EXPECT_TRUE(check_data(clean_factory()).empty()) << symptoms(check_data(clean_factory()));
  for (Setting s : {Setting::kLand, Setting::kSea}) {
    const CalibrationInput in = field(s);
    EXPECT_TRUE(check_data(in).empty()) << setting_name(s) << "\n" << symptoms(check_data(in));
  }
}

TEST(DataCheck, StuckAxis) {
  const auto p = check_data(corrupted([](ImuIncrement& s, size_t) { s.dtheta_rad(1) = 0.0; }));
  EXPECT_TRUE(has(p, "stuck channel")) << symptoms(p);
  EXPECT_NE(symptoms(p).find("gyro y holds 0"), std::string::npos) << symptoms(p);
}

TEST(DataCheck, SwappedGyroAxes) {
  const auto p = check_data(
      corrupted([](ImuIncrement& s, size_t) { std::swap(s.dtheta_rad(0), s.dtheta_rad(1)); }));
  EXPECT_TRUE(has(p, "table vs IMU rotation")) << symptoms(p);
  EXPECT_TRUE(has(p, "gyro vs gravity")) << symptoms(p);
}

TEST(DataCheck, SignFlippedAxis) {
  const auto p = check_data(corrupted([](ImuIncrement& s, size_t) { s.dtheta_rad(2) *= -1; }));
  EXPECT_TRUE(has(p, "table vs IMU rotation")) << symptoms(p);
  const auto a = check_data(corrupted([](ImuIncrement& s, size_t) { s.dv_mps(0) *= -1; }));
  EXPECT_TRUE(has(a, "gravity direction")) << symptoms(a);
}

TEST(DataCheck, TableMovedButTheUnitDidNot) {
  const CalibrationInput& clean = clean_factory();
  const auto p = check_data(corrupted([&](ImuIncrement& s, size_t i) {
    const ImuIncrement& still = clean.imu[i % 500];
    s.dtheta_rad = still.dtheta_rad;
    s.dv_mps = still.dv_mps;
  }));
  EXPECT_TRUE(has(p, "table vs IMU rotation")) << symptoms(p);
  EXPECT_NE(symptoms(p).find("did not move with the table"), std::string::npos) << symptoms(p);
  EXPECT_FALSE(has(p, "saturation")) << "replayed noise is not clipping\n" << symptoms(p);
}

TEST(DataCheck, WrongFixtureOrientation) {
  // The unit turned 90° about its z axis in the fixture: x reads y, y reads -x.
  const auto p = check_data(corrupted([](ImuIncrement& s, size_t) {
    s.dtheta_rad = Eigen::Vector3d(s.dtheta_rad(1), -s.dtheta_rad(0), s.dtheta_rad(2));
    s.dv_mps = Eigen::Vector3d(s.dv_mps(1), -s.dv_mps(0), s.dv_mps(2));
  }));
  EXPECT_TRUE(has(p, "gravity direction")) << symptoms(p);
  EXPECT_NE(symptoms(p).find("wrong fixture orientation"), std::string::npos);
}

TEST(DataCheck, SaturatedSamples) {
  const double lim = 5.0 * kDegToRad * 0.01;  // a ±5 deg/s gyro on 10 deg/s rotations
  const auto p = check_data(corrupted(
      [&](ImuIncrement& s, size_t) { s.dtheta_rad = s.dtheta_rad.cwiseMax(-lim).cwiseMin(lim); }));
  EXPECT_TRUE(has(p, "saturation")) << symptoms(p);
}

TEST(DataCheck, ClockJump) {
  const auto p = check_data(corrupted([](ImuIncrement& s, size_t i) {
    if (i >= 20000) s.t_s += 5.0;
  }));
  EXPECT_TRUE(has(p, "clock jump")) << symptoms(p);
}

TEST(DataCheck, GravityMagnitudeOfAScaleFarOff) {
  const auto p = check_data(corrupted([](ImuIncrement& s, size_t) { s.dv_mps *= 1.2; }));
  EXPECT_TRUE(has(p, "gravity magnitude")) << symptoms(p);
}

TEST(DataCheck, ThePipelineRefusesWithTheSymptomsBeforeAnyMethod) {
  const CalibrationInput in = corrupted([](ImuIncrement& s, size_t) { s.dtheta_rad(0) = 0.0; });
  // Concurrent (the default) the checks run beside AINS: the refusal must be the same.
  for (const bool concurrent : {true, false}) {
    PipelineOptions o;
    o.concurrent = concurrent;
    try {
      (void)run_calibration(in, o);
      ADD_FAILURE() << "a stuck gyro was calibrated, concurrent " << concurrent;
    } catch (const DataCheckError& e) {
      EXPECT_TRUE(has(e.problems(), "stuck channel"));
      EXPECT_NE(std::string(e.what()).find("not a calibration matter"), std::string::npos);
    }
  }
  PipelineOptions off;
  off.check_data = false;
  off.methods = MethodSelection::kAins;
  EXPECT_NO_THROW((void)run_calibration(clean_factory(), off));
}

}  // namespace
}  // namespace imucal::calib
