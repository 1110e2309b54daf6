// Station signatures on a simulated fleet (issue #25), the reduced version CI runs: 10 stations,
// 12 units of a production population each plus one golden-unit visit each, the real simulator
// and AINS on `short`; st-03 has a 50 µg gravity error, st-07 a 10″ table non-orthogonality, all
// tables levelled within ±20″. The benchmark (build/bin/fleet_signature_bench) runs ≥ 20 fleets of
// 10 × 50 for the rates in the README.
#include <gtest/gtest.h>

#include <cmath>

#include "calib/core/conventions.hpp"
#include "tools/fleetsim/fleet_sim.hpp"

using namespace imucal;
using namespace imucal::calib;
using namespace imucal::fleetsim;

namespace {

FleetSpec ci_fleet() {
  FleetSpec spec = sound_fleet(10, 20.0 * kArcsecToRad, 2025);
  spec.units_per_station = 12;
  spec.stations[3].gravity_error_mps2 = 50.0 * kMicroG_mps2;
  spec.stations[7].nonorthogonality_rad = 10.0 * kArcsecToRad;
  return spec;
}

}  // namespace

TEST(StationSignatureSim, ResponsesAreWhatPhysicsSays) {
  const auto errors = fleet_station_errors(ci_fleet());
  // A gravity error is exactly a common accelerometer scale: dM_ii = dg / g on every axis.
  const ParamVector& g = errors[0].response;
  for (int i : {3, 7, 11}) EXPECT_NEAR(g(i) * kStandardGravity_mps2, 1.0, 0.01) << i;
  for (int i = 0; i < ParamSet::kSize; ++i) {
    if (i == 3 || i == 7 || i == 11) continue;
    EXPECT_LT(std::abs(g(i)), 0.02 * g(3)) << i;
  }
  // The table's inner axis leaning into the outer turns the gyro triad's x-z and z-y terms.
  const ParamVector& n = errors[1].response;
  EXPECT_NEAR(std::abs(n(17)), 1.0, 0.1);  // gyro_M[0][2]
  EXPECT_NEAR(std::abs(n(22)), 1.0, 0.1);  // gyro_M[2][1]
}

TEST(StationSignatureSim, BothFaultyStationsAreFlaggedWithTheirCauseAndReprocessingRestoresScales) {
  const FleetSpec spec = ci_fleet();
  const std::vector<FleetRun> runs = simulate_fleet(spec);
  ASSERT_EQ(runs.size(), 130u);
  for (const FleetRun& r : runs) ASSERT_TRUE(r.converged) << r.run.serial;
  const auto errors = fleet_station_errors(spec);
  const FleetOutcome o = assess_fleet(spec, runs, errors, {}, /*population_only=*/false);
  EXPECT_EQ(o.faulty, 2);
  EXPECT_EQ(o.detected, 2);
  EXPECT_EQ(o.false_alarms, 0);
  const StationSignature& gs = o.signatures.stations[3];
  ASSERT_TRUE(gs.alarm);
  EXPECT_EQ(gs.alarm->effect, "gravity_error");
  EXPECT_LT(std::abs(gs.alarm->size_si - 50.0 * kMicroG_mps2), 4 * gs.alarm->sigma_si);
  EXPECT_EQ(gs.run_ids.size(), 13u) << "the runs the alarm touches: the station's";
  const StationSignature& ns = o.signatures.stations[7];
  ASSERT_TRUE(ns.alarm);
  EXPECT_EQ(ns.alarm->effect, "table_nonorthogonality");
  EXPECT_LT(std::abs(ns.alarm->size_si - 10.0 * kArcsecToRad), 4 * ns.alarm->sigma_si);

  // Reprocessed with the surveyed gravity corrected by the fitted error, every accelerometer
  // scale of the station's units lies within 4σ of its truth; as stored, none did.
  const std::vector<double> before = reprocess_with_gravity(spec, 3, 0.0);
  const std::vector<double> after = reprocess_with_gravity(spec, 3, gs.alarm->size_si);
  ASSERT_EQ(after.size(), 36u);
  for (std::size_t i = 0; i < after.size(); ++i) {
    EXPECT_GT(before[i], 20.0) << "as stored, the scale carries the station's 50 ppm";
    EXPECT_LT(std::abs(after[i]), 4.0);
  }
}
