// Land AINS on a unit far from nominal (issue #21): MEMS-grade hand-placed land runs
// (tests/support/mems_runs.hpp), calibrated through the pipeline as `imucal calibrate` does — the
// legacy method first, the filter linearised about its result, the prior the grade's.
#include <gtest/gtest.h>

#include <cmath>

#include "calib/ains/ains.hpp"
#include "calib/core/body_frame.hpp"
#include "calib/legacy/legacy.hpp"
#include "calib/pipeline/calibration_pipeline.hpp"
#include "tests/support/mems_runs.hpp"

namespace imucal::calib {
namespace {

CalibrationInput mems_input(const FieldSimResult& sim) {
  NoiseModel noise;
  const GradePrior mems = grade_prior(Grade::kMems);
  noise.arw_rad_per_sqrt_s = mems.arw_rad_per_sqrt_s;
  noise.vrw_mps_per_sqrt_s = mems.vrw_mps_per_sqrt_s;
  return input_from_field_data(Setting::kLand, sim.imu, {}, demo_factory_site(), noise,
                               Grade::kMems);
}

/// Errors against truth in the accel-symmetric frame both field methods report in.
ParamVector errors(const CalibrationResult& r, const FieldSimResult& sim) {
  return r.params.to_vector() - to_accel_symmetric_frame(sim.truth).params.to_vector();
}

PipelineResult land_all(const CalibrationInput& in) {
  PipelineOptions o;
  o.methods = MethodSelection::kAll;
  return run_calibration(in, o);
}

// Started from the legacy result, every observable parameter lands within 4σ of truth on these
// seeds. Not yet the bar (issue #21 stays open): over 24 runs RMS(error/σ) of the
// accelerometer scales is 2.1 (accel_M[2][2] 3.1, errors mostly positive), the answer moves by up
// to 0.3σ with the start (legacy vs truth), and on one run in three the passes creep along the
// heading / vertical gyro bias valley (0.03–0.05σ per pass) and do not converge in 8 — so the
// run is REVIEW, as it should be while that holds.
TEST(AinsGrade, LandMemsRunsFromTheLegacyStartWithin4Sigma) {
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    const FieldSimResult sim = testing::simulate_mems(seed);
    const PipelineResult p = land_all(mems_input(sim));
    ASSERT_TRUE(p.ains && p.legacy) << seed;
    const CalibrationResult& r = p.ains->result;
    const ParamVector e = errors(r, sim), s = r.sigma.to_vector();
    for (int i = 0; i < ParamSet::kSize; ++i) {
      if (r.observable[static_cast<size_t>(i)]) {
        EXPECT_LT(std::abs(e(i) / s(i)), 4.0) << param_info(i).name << " seed " << seed;
      }
    }
    if (!r.converged) {
      EXPECT_FALSE(p.pass()) << "an unconverged AINS must not PASS, seed " << seed;
    }
  }
}

// Without the start the filter cannot calibrate such a unit at all: what the start is for.
TEST(AinsGrade, FromZeroAMemsUnitIsOutOfReach) {
  const FieldSimResult sim = testing::simulate_mems(1);
  const CalibrationInput in = mems_input(sim);
  bool reached = false;
  try {
    const CalibrationResult r = calibrate_ains(in);
    const ParamVector e = errors(r, sim), s = r.sigma.to_vector();
    reached = r.converged && (e.head(24).cwiseQuotient(s.head(24))).cwiseAbs().maxCoeff() < 4.0;
  } catch (const std::exception&) {
    reached = false;
  }
  EXPECT_FALSE(reached);
}

}  // namespace
}  // namespace imucal::calib
