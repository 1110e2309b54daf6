// The station's gap check (station/run/gap_check.hpp) on the run that made CI fail at random (issue
// #28, tests/data/README.md): a null run from the station simulator whose noise stretch is unlucky.
// Two rules hold on it: an effect that removes only a small part of a significant gap is no finding
// (the run is "unexplained" and the REVIEW reason names no effect), and at the station's
// false-alarm rate per run the run is consistent.
#include "station/run/gap_check.hpp"

#include <gtest/gtest.h>

#include <cstdlib>
#include <stdexcept>
#include <string>

#include "calib/diagnosis/diagnosis.hpp"
#include "calib/effects/catalogue.hpp"
#include "calib/nlsq/nlsq.hpp"
#include "db/archive/archive_input.hpp"
#include "db/archive/run_archive.hpp"
#include "station/config/config.hpp"
#include "tests/support/data_archive.hpp"
#include "tests/support/temp_dir.hpp"

namespace imucal::station {
using namespace imucal::station::config;
using namespace imucal::station::run;
namespace {

/// The archive of tests/data/soak-null-run.tar.xz, unpacked into `dir`.
std::string unpack_soak_run(const test_support::ScopedTempDir& dir) {
  return test_support::unpack_data_archive("soak-null-run", dir.path());
}

GapCheck check_at(const std::string& run_dir, double false_alarm_per_run) {
  db::archive::RunArchive ar = db::archive::read_archive(run_dir);
  // The samples move into the input; ar keeps its info, all check_gap reads of it.
  calib::core::CalibrationInput in = db::archive::to_calibration_input(std::move(ar));
  const calib::core::CalibrationResult nlsq = calib::nlsq::calibrate_nlsq(in);
  return check_gap(std::move(in), ar, nlsq.params, false_alarm_per_run);
}

TEST(GapCheck, AnEffectThatRemovesLittleOfTheHeldOutGapIsNoFindingAndTheReasonNamesNone) {
  test_support::ScopedTempDir dir("gap_check_test");
  const std::string run = unpack_soak_run(dir);
  // The overall test at 1e-3 and each candidate at 1e-3 / 12, the rule the station used before
  // issue #28 — at which this run was "explained by latitude_error = 3.76 +- 0.95 arcmin; held-out
  // gap 1.29 -> 1.28". The candidates share alpha (Bonferroni), so the rate that keeps each at
  // 1e-3 / 12 grows with the catalogue: with the output filter (14 candidates) 2e-3 per run put
  // latitude_error's p 7.4e-5 just above 1e-3 / 14 and left no weak candidate to show.
  const double per_candidate = 1e-3 / 12.0;
  const double n_candidates = static_cast<double>(calib::effects::effect_catalogue().size());
  const GapCheck g = check_at(run, 2.0 * per_candidate * n_candidates);
  EXPECT_TRUE(g.significant) << g.text;  // the gap is real at that rate: p 0.00046
  EXPECT_EQ(g.summary.value("verdict", ""), "unexplained") << g.summary.dump();
  EXPECT_TRUE(g.summary["best"].is_null()) << g.summary.dump();
  // The REVIEW reason is "sim-to-real gap: " + text: it must suggest no cause.
  EXPECT_EQ(g.text.find("latitude"), std::string::npos) << g.text;
  EXPECT_EQ(g.text.find("explained by"), std::string::npos) << g.text;
  EXPECT_NE(g.text.find("no candidate effect explains it"), std::string::npos) << g.text;
  // The engineer still sees which candidate came closest, and by how little.
  ASSERT_TRUE(g.summary["weak_candidate"].is_object()) << g.summary.dump();
  EXPECT_EQ(g.summary["weak_candidate"].value("effect", ""), "latitude_error");
  EXPECT_LT(g.summary["weak_candidate"].value("shrinkage", 1.0),
            calib::diagnosis::DiagnosisOptions{}.min_shrinkage);
}

// Issue #26: the product's known effects excuse a gap only when they explain it; an unexplained
// gap stays a REVIEW whatever the station knows.
TEST(GapCheck, KnownEffectsDoNotExcuseAnUnexplainedGap) {
  test_support::ScopedTempDir dir("gap_check_test");
  const std::string run = unpack_soak_run(dir);
  db::archive::RunArchive ar = db::archive::read_archive(run);
  calib::core::CalibrationInput in = db::archive::to_calibration_input(std::move(ar));
  const calib::core::CalibrationResult nlsq = calib::nlsq::calibrate_nlsq(in);
  const GapCheck g = check_gap(std::move(in), ar, nlsq.params, 2e-3, {"latitude_error"});
  EXPECT_TRUE(g.significant) << g.text;
  EXPECT_FALSE(g.known) << g.summary.dump();
  EXPECT_EQ(g.summary.value("known_effects_only", true), false) << g.summary.dump();
}

TEST(GapCheck, AtTheStationsFalseAlarmRateTheUnluckyNullRunIsConsistent) {
  test_support::ScopedTempDir dir("gap_check_test");
  const std::string run = unpack_soak_run(dir);
  const GapCheck g = check_at(run, StationConfig{}.gap_false_alarm);
  EXPECT_FALSE(g.significant) << g.text;
  EXPECT_EQ(g.summary.value("verdict", ""), "consistent") << g.summary.dump();
  // The overall χ² is what it was; only the level it is held to changed (p 0.00046 > 5e-5).
  EXPECT_NEAR(g.summary["overall"].value("p_value", 0.0), 4.6e-4, 0.5e-4);
}

TEST(GapCheck, FalseAlarmRateOutsideZeroToOneIsRefused) {
  EXPECT_THROW(calib::diagnosis::diagnosis_options_for_false_alarm(0.0), std::invalid_argument);
  EXPECT_THROW(calib::diagnosis::diagnosis_options_for_false_alarm(1.0), std::invalid_argument);
  EXPECT_DOUBLE_EQ(calib::diagnosis::diagnosis_options_for_false_alarm(1e-4).alpha, 5e-5);
}

}  // namespace
}  // namespace imucal::station
