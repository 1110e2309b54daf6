// Blind validation of the gap diagnosis without a table (issue #21 "What it must show": table-free
// simulated runs with one withheld effect each — K2, g-sensitivity, thermal drift, size effect,
// where the setting can separate them — top-1 >= 90 %, nulls <= 5 %). factory-std's positions taken
// by hand on land (calib/sim/field_sim.hpp: placement errors, rest and move times jittered, no
// table log), calibrated by the multi-position method and diagnosed with each rest's attitude
// unknown. The whole count (IMUCAL_WHOLE_COUNTS=1; `imucal validate-diagnosis --setting land
// --runs 10 --nulls 40`, docs/validation/field.md): 10 runs per effect and 40 nulls, held to the
// issue's bar: it measures the rates. The CI count: 3 runs per effect and 12 nulls, held to the bar
// with margins (top-1 >= 85 %, at most one null of 12 flagged): every separable effect named in
// nearly every run. Not cut below 3: at 2 runs no null could be flagged (10 % of 8 is 0), which a
// process at the issue's 5 % would fail one time in three. IMUCAL_VALIDATION_RUNS overrides.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>

#include "calib/core/site_presets.hpp"
#include "calib/diagnosis/diagnosis_validation.hpp"
#include "calib/legacy/legacy.hpp"
#include "calib/sim/hand_placement.hpp"
#include "calib/sim/sim_input.hpp"
#include "calib/sim/unit_draw.hpp"
#include "sequences/library.hpp"
#include "tests/support/ci_count.hpp"
#include "tests/support/field_unit.hpp"
#include "tests/support/validation_report.hpp"

using namespace imucal;
using namespace imucal::calib;
using namespace imucal::calib::core;
using namespace imucal::calib::diagnosis;
using namespace imucal::calib::effects;
using namespace imucal::calib::legacy;
using namespace imucal::calib::sim;

namespace {

RunSource land_source() {
  FieldSimOptions o;
  o.setting = Setting::kLand;
  return field_run_source(sequences::load_profile("factory-std"), demo_factory_site(),
                          test_support::field_unit(), o);
}

bool validated(const ValidationReport& r, const char* name) {
  return std::find(r.effects.begin(), r.effects.end(), name) != r.effects.end();
}

}  // namespace

TEST(LandDiagnosisValidation, FactoryStdByHandMeetsTheBarWithMargins) {
  constexpr int kRunsWhole = 10;
  const int runs = test_support::test_count("IMUCAL_VALIDATION_RUNS", 3, kRunsWhole);
  const bool issue_bar = runs >= kRunsWhole;  // enough runs to hold the rates to the bar itself
  ValidationOptions opt;
  opt.runs_per_effect = runs;
  opt.null_runs = 4 * runs;
  opt.pair_runs = 0;
  opt.seed = 5;
  const ValidationReport r = validate_diagnosis(
      land_source(), TableGeometry{}, test_support::field_unit().params, "factory-std", opt);
  calib::testing::print_validation(r);
  for (const auto& d : r.detectability)
    if (!d.separable()) std::printf("  not validated: %s (%s)\n", d.name.c_str(), d.reason.c_str());
  // The issue's effects that a hand-placed land run separates on its own (K2 is confounded with
  // the asymmetry here as on the table: see the next test).
  EXPECT_TRUE(validated(r, "gyro_g_sensitivity"));
  EXPECT_TRUE(validated(r, "thermal_drift"));
  EXPECT_TRUE(validated(r, "size_effect"));
  EXPECT_GE(r.effects.size(), 6u);
  EXPECT_GE(r.top1, issue_bar ? 0.9 : 0.85);
  EXPECT_LE(r.false_alarm, issue_bar ? 0.05 : 0.1);
  EXPECT_GE(r.median_shrinkage, 0.7);
}

// K2 and the accelerometer asymmetry tell the same story on factory-std's positions (at ±1 g and
// at tilts |f| and f² differ too little): a K2 run is explained by the set, with K2's own values.
TEST(LandDiagnosisValidation, K2ByHandIsExplainedAsTheSetItCannotBeToldFrom) {
  const RunSource world = land_source();
  Effects fx;
  fx.accel_k2_per_mps2 = Eigen::Vector3d(2e-6, -2e-6, 2e-6);  // ±20 µg/g², ~5x its threshold
  for (uint64_t seed : {8u, 9u}) {
    DiagnosisInput in;
    in.cal = world(fx, seed, true);
    const DiagnosisResult d = diagnose(in, calibrate_legacy(in.cal).params);
    std::printf("seed %llu: %s\n", static_cast<unsigned long long>(seed), d.summary.c_str());
    EXPECT_EQ(d.verdict, "explained");
    EXPECT_NE(std::find(d.explained_by.begin(), d.explained_by.end(), "accel_quadratic_k2"),
              d.explained_by.end());
    for (const auto& c : d.candidates) {
      if (c.name != "accel_quadratic_k2") continue;
      for (int i = 0; i < 3; ++i)
        EXPECT_LT(std::abs(c.value_si(i) - fx.accel_k2_per_mps2(i)),
                  4.0 * c.params[static_cast<size_t>(i)].sigma /
                      effect_info(c.id).params[static_cast<size_t>(i)].si_to_human)
            << c.params[static_cast<size_t>(i)].name;
    }
  }
}

// A MEMS unit's K2 on 38 hand-placed positions (issue #21): its z direction correlates 0.97 with
// the calibration's terms there (z mostly vertical), above the 0.95 separability limit. Left out of
// the fit, its remainder was taken by a wandering bias, which was named first in every run; fitted
// with the separable directions as a nuisance direction (DiagnosisOptions::fit_limit), K2 alone
// explains the run and its size comes out within 4σ of the injected one.
TEST(LandDiagnosisValidation, K2OfAMemsUnitOnHandPlacedPositionsIsNamedAlone) {
  const uint64_t seed = 5;
  UnitModel unit = draw_unit(Grade::kMems, seed);
  unit.params.table_misalignment_rad.setZero();
  FieldSimOptions o;
  o.setting = Setting::kLand;
  const RunSource world =
      field_run_source(hand_placed_profile(seed), demo_factory_site(), unit, o, Grade::kMems);
  const EffectInfo& e = effect_info(EffectId::kAccelQuadraticK2);
  Effects fx;
  set_effect_vector(fx, e.id, scaled_typical(e, 4800.0, 1.0));  // µg/g², ~6x its threshold (796)
  for (uint64_t run_seed : {5000011u, 5000012u}) {
    DiagnosisInput in;
    in.cal = world(fx, run_seed, true);
    const DiagnosisResult d = diagnose(in, calibrate_legacy(in.cal).params);
    std::printf("seed %llu: %s\n", static_cast<unsigned long long>(run_seed), d.summary.c_str());
    ASSERT_TRUE(d.best) << d.summary;
    const CandidateResult& k2 = d.candidates[*d.best];
    EXPECT_EQ(k2.name, e.name);
    EXPECT_FALSE(d.second) << d.candidates[*d.second].name;
    EXPECT_NE(k2.note.find("1 more fitted with them, not resolved"), std::string::npos) << k2.note;
    EXPECT_LT(std::abs(k2.magnitude - 4800.0), 4.0 * k2.magnitude_sigma)
        << k2.magnitude << " +- " << k2.magnitude_sigma;
    EXPECT_GT(d.held_out.shrinkage, 0.7);
  }
}
