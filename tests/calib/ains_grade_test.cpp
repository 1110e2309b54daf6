// Land AINS on a unit far from nominal (issue #21): MEMS-grade hand-placed land runs
// (tests/support/mems_runs.hpp), calibrated through the pipeline as `imucal calibrate` does — the
// legacy method first, the filter linearised about its result, the prior the grade's.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "calib/ains/ains.hpp"
#include "calib/core/body_frame.hpp"
#include "calib/legacy/legacy.hpp"
#include "calib/pipeline/calibration_pipeline.hpp"
#include "tests/support/mems_runs.hpp"
#include "tests/support/sigma_honesty.hpp"

namespace imucal::calib {
using namespace imucal::calib::ains;
using namespace imucal::calib::core;
using namespace imucal::calib::legacy;
using namespace imucal::calib::pipeline;
using namespace imucal::calib::sim;
namespace {

using testing::mems_input;

/// Errors against truth in the accel-symmetric frame both field methods report in.
ParamVector errors(const CalibrationResult& r, const FieldSimResult& sim) {
  return r.params.to_vector() - to_accel_symmetric_frame(sim.truth).params.to_vector();
}

PipelineResult land_all(const CalibrationInput& in) {
  PipelineOptions o;
  o.methods = MethodSelection::kAll;
  return run_calibration(in, o);
}

// Every observable parameter within 4σ of truth, converged, within the MEMS limits, and the two
// methods agree (the cross-check passes): the run is PASS at its grade.
TEST(AinsGrade, LandMemsRunsFromTheLegacyStartWithin4Sigma) {
  for (uint64_t seed = 1; seed <= 3; ++seed) {
    const FieldSimResult sim = testing::simulate_mems(seed);
    const PipelineResult p = land_all(mems_input(sim));
    ASSERT_TRUE(p.ains && p.legacy) << seed;
    const CalibrationResult& r = p.ains->result;
    EXPECT_TRUE(r.converged) << "seed " << seed << ", " << r.iterations << " passes";
    const ParamVector e = errors(r, sim), s = r.sigma.to_vector();
    for (int i = 0; i < ParamSet::kSize; ++i) {
      if (r.observable[static_cast<size_t>(i)]) {
        EXPECT_LT(std::abs(e(i) / s(i)), 4.0) << param_info(i).name << " seed " << seed;
      }
    }
    EXPECT_TRUE(p.pass()) << "seed " << seed << ": "
                          << (p.limits.failures.empty() ? "" : p.limits.failures.front().detail)
                          << (p.crosscheck && !p.crosscheck->pass ? " cross-check fails" : "");
  }
}

// The start is a linearisation point, not information: from the legacy result and from the
// truth itself, with the same initial attitude, AINS lands on the same parameters (within 0.1σ),
// so the cross-check still compares two independent estimates. (The initial heading is searched
// by likelihood from each start and may land a few degrees apart — on seed 8 that moves the
// vertical gyro bias by 1σ; the Monte Carlo below holds the σ honest with that search.)
TEST(AinsGrade, TheStartDoesNotDecideTheAnswer) {
  for (uint64_t seed : {7u, 8u}) {
    const FieldSimResult sim = testing::simulate_mems(seed);
    const CalibrationInput in = mems_input(sim);
    AinsOptions o;
    o.initial_heading_sigma_rad = 1.0;
    o.start = calibrate_legacy(in).params;
    const AinsResult from_legacy = calibrate_ains_detailed(in, o);
    o.start = to_accel_symmetric_frame(sim.truth).params;
    o.initial_C_bn = from_legacy.coarse_C_bn;
    const CalibrationResult from_truth = calibrate_ains(in, o);
    ASSERT_TRUE(from_legacy.calibration.converged && from_truth.converged) << seed;
    const ParamVector d =
        from_legacy.calibration.params.to_vector() - from_truth.params.to_vector();
    const ParamVector s = from_truth.sigma.to_vector();
    for (int i = 0; i < 24; ++i)
      EXPECT_LT(std::abs(d(i) / s(i)), 0.1) << param_info(i).name << " seed " << seed;
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

// Honest σ (issue #21's Monte Carlo bar): RMS(error/σ) per group within [0.7, 1.4], through the
// pipeline as `imucal calibrate --method ains` runs it (legacy start, heading search).
TEST(AinsGrade, MemsSigmaIsHonestMonteCarlo) {
  constexpr int kRuns = 24;
  testing::GroupSigmaCheck check;
  int converged = 0;
  for (uint64_t seed = 100; seed < 100 + kRuns; ++seed) {
    const FieldSimResult sim = testing::simulate_mems(seed);
    PipelineOptions o;
    o.methods = MethodSelection::kAins;
    const PipelineResult p = run_calibration(mems_input(sim), o);
    ASSERT_TRUE(p.ains) << seed;
    const CalibrationResult& r = p.ains->result;
    converged += r.converged;
    check.add(errors(r, sim), r.sigma.to_vector());
  }
  EXPECT_EQ(converged, kRuns);
  check.expect_within("land AINS on " + std::to_string(kRuns) + " MEMS hand-placed runs (" +
                      std::to_string(converged) + " converged)");
}

}  // namespace
}  // namespace imucal::calib
