// The station's consistency test on factory-length runs (issue #8, "What it must show"): through
// the daemon's own calibration job (station/run/calibration_worker.hpp: AINS, NLSQ, cross-check,
// gap diagnosis, SQLite), on simulated factory-std runs of the default unit:
//  * every catalogue effect that the factory sequence can detect (imucal crlb --effects: a finite
//    detection threshold), injected at 3x its threshold, no longer ends a run PASS — it ends REVIEW
//    and the reason names the gap;
//  * null runs (no effect) still PASS: at most 5 % REVIEW. The whole count (IMUCAL_WHOLE_COUNTS=1,
//    the issue's) is 40 seeds with at most 2 REVIEW, the figure as it stands: it measures
//    the rate to about ±5 %. The CI count is 10 seeds with at most 2 REVIEW: a station exactly at
//    the 5 % fails it with probability P(Bin(10, 0.05) > 2) = 1.2 %, one at the gap check's
//    design rate (1e-4 per run) never in practice (2e-10); a station whose null runs end REVIEW
//    one time in three fails it 70 % of the time, one that reviews every run always. It proves that
//    the null runs are not commonly flagged; the whole count that they are flagged at most 5 %.
//    IMUCAL_GAP_NULL_SEEDS overrides both counts (the bound then as at the CI count).
// Before issue #8 a 30 µg/g² K2, a warm-up, a Gauss-Markov bias or a 10" table non-orthogonality
// ended PASS with parameters 7-180 σ off.
#include <gtest/gtest.h>

#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <thread>

#include "calib/core/site_presets.hpp"
#include "calib/diagnosis/diagnosis_validation.hpp"
#include "calib/diagnosis/effect_detectability.hpp"
#include "calib/sim/sim_input.hpp"
#include "db/archive/run_archive.hpp"
#include "db/history/sqlite_repository.hpp"
#include "sequences/library.hpp"
#include "station/run/calibration_worker.hpp"
#include "tests/support/calibration_job.hpp"
#include "tests/support/ci_count.hpp"
#include "tests/support/temp_dir.hpp"

using namespace imucal;

namespace {

constexpr int kNullSeedsCi = 10, kNullSeedsWhole = 40;
/// The ceiling on the rate of null runs that do not PASS.
constexpr double kNullReviewRate = 0.05;
/// The false-fail probability the CI count's bound is chosen for (at exactly kNullReviewRate).
constexpr double kNullFalseFail = 0.02;

struct Case {
  std::string name;  ///< "null" or the effect
  calib::effects::Effects effects;
  uint64_t seed = 0;
};

struct Outcome {
  db::history::RunState state = db::history::RunState::kFailed;
  std::string reason;
};

const sequences::MotionProfile& factory_std() {
  static const sequences::MotionProfile p = sequences::load_profile("factory-std");
  return p;
}

/// Simulate the case into an archive and run the daemon's calibration job on it.
Outcome run_case(const Case& c, const std::string& dir, db::history::Repository& repo) {
  calib::effects::UnitModel unit = calib::effects::default_unit();
  unit.effects = c.effects;
  calib::sim::SimOptions so;
  so.seed = c.seed;
  const calib::core::TableGeometry geom;
  calib::sim::SimResult sim =
      calib::sim::simulate(factory_std(), geom, calib::core::demo_factory_site(), unit, so);
  db::archive::RunArchive ar;
  ar.info.serial = "GAP-" + std::to_string(c.seed);
  ar.info.site = calib::core::demo_factory_site();
  ar.info.imu_rate_hz = so.rate_hz;
  ar.info.table = db::archive::TableSetup::from_geometry(geom);
  ar.info.sequence_name = "factory-std";
  ar.info.arw_rad_per_sqrt_s = unit.noise.arw_rad_per_sqrt_s;
  ar.info.vrw_mps_per_sqrt_s = unit.noise.vrw_mps_per_sqrt_s;
  ar.imu = std::move(sim.imu);
  ar.table = std::move(sim.table);
  db::archive::write_archive(dir, ar);
  const station::run::CalibrationOutcome out =
      test_support::calibrate_as_the_station(repo, ar.info.serial, "gap-test", dir);
  return {out.state, out.reason};
}

std::vector<Outcome> run_all(const std::vector<Case>& cases) {
  const test_support::ScopedTempDir tmp("gap-review");
  db::history::SqliteRepository repo(tmp.sub("history.sqlite"));
  std::vector<Outcome> out(cases.size());
  std::atomic<size_t> next{0};
  auto worker = [&] {
    for (size_t i = next++; i < cases.size(); i = next++)
      out[i] = run_case(cases[i], tmp.sub("run-" + std::to_string(i)), repo);
  };
  std::vector<std::thread> pool;
  for (unsigned t = 0; t < std::max(1u, std::thread::hardware_concurrency()); ++t)
    pool.emplace_back(worker);
  for (auto& t : pool) t.join();
  return out;
}

}  // namespace

TEST(GapReview, EveryDetectableEffectAtThreeTimesItsThresholdIsNeverPass) {
  const auto det = calib::diagnosis::effect_detectability(
      calib::sim::truth_run_source(factory_std(), calib::core::TableGeometry{},
                                   calib::core::demo_factory_site(), calib::effects::default_unit(),
                                   100.0)(calib::effects::Effects{}, 1, /*noise=*/false),
      calib::core::TableGeometry{}, calib::effects::default_unit().params);
  std::vector<Case> cases;
  for (const auto& d : det) {
    if (!std::isfinite(d.threshold))
      continue;  // not detectable on factory-std (named in crlb --effects)
    Case c;
    c.name = d.name;
    c.seed = 500 + cases.size();
    calib::effects::set_effect_vector(
        c.effects, d.id,
        calib::diagnosis::scaled_typical(calib::effects::effect_info(d.id), 3.0 * d.threshold,
                                         1.0));
    cases.push_back(c);
  }
  ASSERT_GE(cases.size(), 11u) << "K2, asymmetry, size, g-sensitivity, skew, thermal, instability, "
                                  "non-orthogonality, wobble, latitude, quantisation";
  const auto out = run_all(cases);
  for (size_t i = 0; i < cases.size(); ++i) {
    std::printf("  %-24s 3x threshold -> %s: %s\n", cases[i].name.c_str(),
                db::history::to_string(out[i].state), out[i].reason.substr(0, 160).c_str());
    EXPECT_EQ(out[i].state, db::history::RunState::kReview)
        << cases[i].name << ": " << out[i].reason;
    EXPECT_NE(out[i].reason.find("sim-to-real gap"), std::string::npos) << cases[i].name;
  }
}

TEST(GapReview, NullRunsStillPass) {
  const int n = test_support::test_count("IMUCAL_GAP_NULL_SEEDS", kNullSeedsCi, kNullSeedsWhole);
  std::vector<Case> cases;
  for (int i = 0; i < n; ++i)
    cases.push_back({"null", calib::effects::Effects{}, 1000u + static_cast<uint64_t>(i)});
  const auto out = run_all(cases);
  int review = 0;
  for (size_t i = 0; i < out.size(); ++i) {
    if (out[i].state != db::history::RunState::kDone)
      std::printf("  null seed %llu -> %s: %s\n", static_cast<unsigned long long>(cases[i].seed),
                  db::history::to_string(out[i].state), out[i].reason.c_str());
    review += out[i].state == db::history::RunState::kDone ? 0 : 1;
  }
  // At the whole count the figure (5 % of 40: 2); at any other count the fewest allowed
  // whose false-fail probability at the rate is at most kNullFalseFail (2 of 10: 1.2 %).
  const int allowed = n == kNullSeedsWhole
                          ? static_cast<int>(kNullReviewRate * n)
                          : test_support::allowed_events(n, kNullReviewRate, kNullFalseFail);
  std::printf(
      "  %d of %d null runs not PASS (at most %d allowed: false-fail probability %.4f at a %.0f "
      "%% rate)\n",
      review, n, allowed, test_support::binomial_tail_above(allowed, n, kNullReviewRate),
      100 * kNullReviewRate);
  EXPECT_LE(review, allowed) << review << " of " << n << " null runs not PASS";
}
