// What follows a unit's grade (issue #21): the data checks widen to what an uncalibrated unit of
// the grade may be yet still catch a swapped, sign-flipped or dead axis; the legacy method
// calibrates a MEMS unit far from nominal from scratch; the limits accept it. Runs: MEMS-grade
// hand-placed land runs (tests/support/mems_runs.hpp).
#include <gtest/gtest.h>

#include <cmath>

#include "calib/checks/data_check.hpp"
#include "calib/checks/limit_check.hpp"
#include "calib/core/body_frame.hpp"
#include "calib/legacy/legacy.hpp"
#include "tests/support/mems_runs.hpp"
#include "tests/support/sigma_honesty.hpp"

namespace imucal::calib {
using namespace imucal::calib::checks;
using namespace imucal::calib::core;
using namespace imucal::calib::legacy;
using namespace imucal::calib::sim;
namespace {

using testing::mems_input;

std::string symptoms_grade(const std::vector<DataProblem>& problems) {
  std::string s;
  for (const auto& p : problems) s += "[" + p.symptom + "] " + p.detail + " ";
  return s;
}

bool has_grade(const std::vector<DataProblem>& problems, const std::string& symptom) {
  for (const auto& p : problems)
    if (p.symptom == symptom) return true;
  return false;
}

TEST(GradeDataChecks, AMemsUnitFarFromNominalIsSaneAtItsGradeOnly) {
  const CalibrationInput in = mems_input(testing::simulate_mems(1));
  EXPECT_EQ(in.grade, Grade::kMems);
  const auto at_grade = check_data(in, data_check_options(Grade::kMems));
  EXPECT_TRUE(at_grade.empty()) << symptoms_grade(at_grade);
  // Held to navigation grade the same unit looks broken (what issue #21 met on a real unit).
  const auto at_navigation = check_data(in, data_check_options(Grade::kNavigation));
  EXPECT_TRUE(has_grade(at_navigation, "gyro vs gravity") || has_grade(at_navigation, "gravity magnitude"))
      << symptoms_grade(at_navigation);
}

TEST(GradeDataChecks, SwappedFlippedAndDeadAxesAreStillCaughtAtMemsGrade) {
  const CalibrationInput good = mems_input(testing::simulate_mems(2));
  const DataCheckOptions o = data_check_options(Grade::kMems);
  CalibrationInput in = good;
  for (auto& s : in.imu) std::swap(s.dtheta_rad(0), s.dtheta_rad(1));
  EXPECT_TRUE(has_grade(check_data(in, o), "gyro vs gravity")) << "gyro x/y swapped";
  in = good;
  for (auto& s : in.imu) s.dtheta_rad(2) = -s.dtheta_rad(2);
  EXPECT_TRUE(has_grade(check_data(in, o), "gyro vs gravity")) << "gyro z sign-flipped";
  in = good;
  for (auto& s : in.imu) std::swap(s.dv_mps(1), s.dv_mps(2));
  EXPECT_TRUE(has_grade(check_data(in, o), "gyro vs gravity")) << "accelerometer y/z swapped";
  in = good;
  for (auto& s : in.imu) s.dv_mps(0) = 0.0;  // a dead accelerometer
  const auto dead = check_data(in, o);
  EXPECT_TRUE(has_grade(dead, "gravity magnitude") || has_grade(dead, "stuck channel")) << symptoms_grade(dead);
}

/// Errors against truth, in the accel-symmetric frame legacy reports in.
ParamVector legacy_errors(const CalibrationResult& r, const FieldSimResult& sim) {
  return r.params.to_vector() - to_accel_symmetric_frame(sim.truth).params.to_vector();
}

// From scratch (T = I, b = 0) on units with gyro offsets of 2.5–5 °/s, scales ±25 % and 50 mrad:
// converged, within the MEMS limits, every term within 4σ of truth, and accurate to what makes a
// MEMS calibration worth having (1 mg, 1000 ppm, 0.02 °/s, 2000 ppm — against envelopes of 200 mg,
// 30 %, 5 °/s, 30 %).
TEST(GradeLegacy, MemsUnitsFarFromNominalFromScratch) {
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    const FieldSimResult sim = testing::simulate_mems(seed);
    const CalibrationResult r = calibrate_legacy(mems_input(sim));
    EXPECT_TRUE(r.converged) << "seed " << seed << ", " << r.iterations << " rounds";
    const ParamVector e = legacy_errors(r, sim), s = r.sigma.to_vector();
    const ParamSet pe = ParamSet::from_vector(e);
    EXPECT_LT(pe.accel_bias_mps2.cwiseAbs().maxCoeff(), 1e-3 * kStandardGravity_mps2) << seed;
    EXPECT_LT(pe.accel_M.cwiseAbs().maxCoeff(), 1000e-6) << seed;
    EXPECT_LT(pe.gyro_bias_radps.cwiseAbs().maxCoeff(), 0.02 * kDegToRad) << seed;
    EXPECT_LT(pe.gyro_M.cwiseAbs().maxCoeff(), 2000e-6) << seed;
    for (int i = 0; i < 24; ++i)
      EXPECT_LT(std::abs(e(i) / s(i)), 4.0) << param_info(i).name << " seed " << seed;
    LimitCheckOptions lo;
    lo.datasheet = limits_for_grade(lo.datasheet, Grade::kMems);
    LimitCheckResult lr;
    check_limits(r, EvaluationMetrics{}, false, lo, lr);
    EXPECT_TRUE(lr.pass) << "seed " << seed << ": "
                         << (lr.failures.empty() ? "" : lr.failures.front().detail);
  }
}

// Honest σ (issue #21's Monte Carlo bar): over 40 drawn units and hand-placed runs, RMS(error/σ)
// per group within [0.7, 1.4]. Each rest's noise follows its own length (3–11 s here) and each
// move's the ARW over its duration; weighting every rest as 60 s long made the accelerometer
// groups' σ 2.2× too small and the gyro scale's 10× too large.
TEST(GradeLegacy, MemsSigmaIsHonestMonteCarlo) {
  constexpr int kRuns = 40;
  testing::GroupSigmaCheck check;
  for (uint64_t seed = 100; seed < 100 + kRuns; ++seed) {
    const FieldSimResult sim = testing::simulate_mems(seed);
    const CalibrationResult r = calibrate_legacy(mems_input(sim));
    check.add(legacy_errors(r, sim), r.sigma.to_vector());
  }
  check.expect_within("legacy on " + std::to_string(kRuns) + " MEMS hand-placed runs");
}

TEST(GradeLimits, NavigationKeepsTheStationsDatasheetAndMemsWidensIt) {
  const DatasheetLimits station;
  const DatasheetLimits nav = limits_for_grade(station, Grade::kNavigation);
  EXPECT_EQ(nav.gyro_bias_radps, station.gyro_bias_radps);
  EXPECT_EQ(nav.accel_scale, station.accel_scale);
  const DatasheetLimits mems = limits_for_grade(station, Grade::kMems);
  EXPECT_GE(mems.gyro_bias_radps, 5.0 * kDegToRad);
  EXPECT_GE(mems.gyro_scale, 0.25);
  EXPECT_EQ(mems.table_misalignment_rad, station.table_misalignment_rad);
}

// run.toml's [prior] overrides (issue #21): a MEMS product whose datasheet promises gyro scales
// within 10 % — the drawn unit's 24 % then fails its limits, naming the gyro scale, where the
// class's 30 % envelope let it pass; the data checks and the filter's prior follow the same
// envelope.
TEST(GradeLimits, EnvelopeOverridesNarrowTheLimitsChecksAndPrior) {
  EnvelopeOverrides tight;
  tight.scale = 0.10;
  const UnitPrior product(Grade::kMems, tight);
  const DatasheetLimits station;
  EXPECT_DOUBLE_EQ(limits_for_grade(station, product).gyro_scale,
                   std::max(station.gyro_scale, 0.10));
  EXPECT_LT(data_check_options(product).rotation_tol_fraction,
            data_check_options(Grade::kMems).rotation_tol_fraction);
  const FieldSimResult sim = testing::simulate_mems(1);
  ASSERT_GT(sim.truth.gyro_M.diagonal().cwiseAbs().maxCoeff(), 0.12);
  const CalibrationResult r = calibrate_legacy(mems_input(sim));
  for (const UnitPrior& p : {UnitPrior(Grade::kMems), product}) {
    LimitCheckOptions lo;
    lo.datasheet = limits_for_grade(lo.datasheet, p);
    LimitCheckResult lr;
    check_limits(r, EvaluationMetrics{}, false, lo, lr);
    EXPECT_EQ(lr.pass, !p.overrides.any());
    if (p.overrides.any()) {
      ASSERT_FALSE(lr.failures.empty());
      EXPECT_NE(lr.failures.front().detail.find("gyro_M"), std::string::npos)
          << lr.failures.front().detail;
    }
  }
  // Navigation with an override is no longer "as before": the override is what counts.
  EnvelopeOverrides wide;
  wide.accel_bias_mps2 = 0.1;
  EXPECT_FALSE(UnitPrior(Grade::kNavigation, wide).plain_navigation());
  EXPECT_DOUBLE_EQ(limits_for_grade(station, UnitPrior(Grade::kNavigation, wide)).accel_bias_mps2,
                   std::max(station.accel_bias_mps2, 0.1));
}

}  // namespace
}  // namespace imucal::calib
