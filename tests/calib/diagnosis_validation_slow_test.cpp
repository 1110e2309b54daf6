// Blind validation of the gap diagnosis on factory-std (issue #8 item 4, "What it must show"): runs
// with one withheld effect (every effect the sequence separates) at 3-10x its detection threshold,
// pairs, and null runs. The issue's bar — top-1 >= 90 %, false alarms <= 10 %, median held-out
// shrinkage >= 70 %, both of a pair named >= 70 % — is measured at the whole count
// (IMUCAL_WHOLE_COUNTS=1: 10 runs per effect, 30 nulls, 20 pairs; `imucal validate-diagnosis
// --runs 10`, docs/validation/diagnosis.md) and held to it there. The CI count (2 runs per effect:
// 18 single-effect runs, 6 nulls, 4 pairs) holds it with margins for the sampling noise of so few
// runs (top-1 >= 80 %, at most one null of 6, both named in 2 of 4 pairs): it proves every effect
// is named nearly always and nulls are rarely flagged. IMUCAL_VALIDATION_RUNS overrides.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>

#include "calib/core/site_presets.hpp"
#include "calib/diagnosis/diagnosis_validation.hpp"
#include "calib/sim/sim_input.hpp"
#include "sequences/library.hpp"
#include "tests/support/ci_count.hpp"
#include "tests/support/validation_report.hpp"

using namespace imucal;
using namespace imucal::calib;
using namespace imucal::calib::core;
using namespace imucal::calib::diagnosis;
using namespace imucal::calib::effects;
using namespace imucal::calib::sim;

TEST(DiagnosisValidation, FactoryStdMeetsTheBarWithMargins) {
  constexpr int kRunsWhole = 10;
  const int runs = test_support::test_count("IMUCAL_VALIDATION_RUNS", 2, kRunsWhole);
  const bool issue_bar = runs >= kRunsWhole;  // enough runs to hold the rates to the bar itself
  ValidationOptions opt;
  opt.runs_per_effect = runs;
  opt.null_runs = 3 * runs;
  opt.pair_runs = 2 * runs;
  opt.seed = 7;
  const ValidationReport r =
      validate_diagnosis(truth_run_source(sequences::load_profile("factory-std"), TableGeometry{},
                                          demo_factory_site(), default_unit(), 100.0),
                         TableGeometry{}, default_unit().params, "factory-std", opt);
  calib::testing::print_validation(r);
  // Every effect factory-std separates is validated: the dynamic, table, site and stochastic ones.
  EXPECT_GE(r.effects.size(), 9u);
  EXPECT_GE(r.top1, issue_bar ? 0.9 : 0.8);
  EXPECT_LE(r.false_alarm, issue_bar ? 0.1 : 0.2);
  EXPECT_GE(r.median_shrinkage, issue_bar ? 0.7 : 0.6);
  EXPECT_GE(r.pair_both, issue_bar ? 0.7 : 0.5);
}
