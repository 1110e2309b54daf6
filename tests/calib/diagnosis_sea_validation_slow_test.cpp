// Blind validation of the gap diagnosis at sea (issue #21 "What it must show": table-free
// simulated runs with one withheld effect each, where the setting can separate them — top-1
// >= 90 %, nulls <= 5 %). factory-std's positions taken by hand on a rocking, heaving, drifting
// deck with GNSS fixes (calib/sim/field_sim.hpp), calibrated by AINS and diagnosed on the filter's
// GNSS innovations. The whole count (IMUCAL_WHOLE_COUNTS=1; `imucal validate-diagnosis --setting
// sea --runs 10 --nulls 40`, docs/validation/field.md): 10 runs per effect and 40 nulls, held to
// the issue's bar (top-1 >= 90 %, nulls <= 5 %): it measures the rates. The CI count: 1 run per
// effect and 4 nulls, held to the bar with margins (top-1 >= 85 %: every effect named; no null
// flagged): it proves that each effect a sea run separates is named and null runs pass.
// IMUCAL_VALIDATION_RUNS overrides the runs per effect.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>

#include "calib/core/site_presets.hpp"
#include "calib/diagnosis/diagnosis_validation.hpp"
#include "calib/sim/sim_input.hpp"
#include "sequences/library.hpp"
#include "tests/support/ci_count.hpp"
#include "tests/support/field_unit.hpp"
#include "tests/support/validation_report.hpp"

using namespace imucal;
using namespace imucal::calib;
using namespace imucal::calib::core;
using namespace imucal::calib::diagnosis;
using namespace imucal::calib::effects;
using namespace imucal::calib::sim;

TEST(SeaDiagnosisValidation, FactoryStdAtSeaMeetsTheBarWithMargins) {
  constexpr int kRunsWhole = 10;
  const int runs = test_support::test_count("IMUCAL_VALIDATION_RUNS", 1, kRunsWhole);
  const bool issue_bar = runs >= kRunsWhole;  // enough runs to hold the rates to the bar itself
  const UnitModel unit = test_support::field_unit();
  FieldSimOptions o;
  o.setting = Setting::kSea;
  const RunSource world =
      field_run_source(sequences::load_profile("factory-std"), demo_factory_site(), unit, o);
  ValidationOptions opt;
  opt.runs_per_effect = runs;
  opt.null_runs = 4 * runs;
  opt.pair_runs = 0;
  opt.seed = 7;
  const ValidationReport r =
      validate_diagnosis(world, TableGeometry{}, unit.params, "factory-std", opt);
  calib::testing::print_validation(r);
  for (const auto& d : r.detectability)
    if (!d.separable()) std::printf("  not validated: %s (%s)\n", d.name.c_str(), d.reason.c_str());
  // What a sea run separates on factory-std: the unit's g-sensitivity, lever arms, skew and
  // warm-up (K2 only as the set with the asymmetry, as on land and on the table).
  for (const char* name : {"gyro_g_sensitivity", "size_effect", "gyro_accel_skew", "thermal_drift"})
    EXPECT_NE(std::find(r.effects.begin(), r.effects.end(), name), r.effects.end()) << name;
  EXPECT_GE(r.top1, issue_bar ? 0.9 : 0.85);
  EXPECT_LE(r.false_alarm, issue_bar ? 0.05 : 0.1);
  EXPECT_GE(r.median_shrinkage, 0.7);
}
