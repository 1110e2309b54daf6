// End to end (issue #26 item 3): the gap budget's paper-like unit
// (db/archive/units/paper-like.toml, written by `imucal gap-budget --write-unit`) on the station —
// stationsim --unit, stationd and stationctl as real processes on loopback.
//  * The paper's methods work on it: AINS and NLSQ agree (the cross-check PASSes) and every
//    limit holds.
//  * The station still sees what no single model of it explains: the gap diagnosis names the
//    budget's sources — the gyro/accelerometer skew first (the budget's largest that biases a
//    calibration), the table's wobble, the accelerometer warm-up, the site's latitude (2 runs in 3)
//    and the accelerometer bias instability — so by default the run is REVIEW.
//  * A product whose effects are known ([calibration] known_effects, the budget's list) ends
//    PASS, the diagnosis kept with the run.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <string>
#include <vector>

#include "tests/e2e/station_harness.hpp"

namespace imucal::e2e {
namespace {

const std::string kPaperLikeUnit =
    std::string(IMUCAL_SOURCE_DIR) + "/db/archive/units/paper-like.toml";

// The sources the budget fits into the paper's units that also bias a calibration (README, "The
// paper's figures: a gap budget"), by their catalogue names.
const std::vector<std::string> kBudgetSources = {
    "gyro_accel_skew", "thermal_drift", "bias_instability",      "size_effect",
    "latitude_error",  "table_wobble",  "table_nonorthogonality"};

// Of them, those a `short` run separates and the diagnosis must name.
const std::vector<std::string> kMustName = {"gyro_accel_skew", "table_wobble"};
// The site's latitude error is not among them: its 5 arcmin is about 5 sigma on `short` (sigma
// 0.99 arcmin), and at the station's level (false alarm 1e-4 per run: alpha 5e-5 over 15
// candidates, |z| > 4.65) that is a coin weighted 2:1 — named in 41 of 60 runs on 2026-11-30 (the
// CI run of 3c62f8d failed on one of the other 7). Where it is named its size must be the
// budget's (below); where it is not, the slow drift it leaves is named instead (kSlowBiasDrift).
// And the accelerometer's slow bias drift, as its warm-up or its bias instability: a `short` run
// names both in most runs, and at least one always. Under a busy CPU (two busy loops beside the
// test, 2026-11-28) 28 of 29 runs named both; one named the instability alone, its held-out gap
// already consistent after four steps (1.2) — the two drifts are alike over a short run.
const std::vector<std::string> kSlowBiasDrift = {"thermal_drift", "bias_instability"};

bool contains(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

/// One `short` run of the paper-like unit; returns its history record.
json run_paper_like(Station& st, const std::string& serial, int expected_exit) {
  const CmdResult run = st.ctl(
      {"run", "start", "--serial", serial, "--sequence", "short", "--operator", "e2e", "--wait"},
      240s);
  EXPECT_EQ(run.exit_code, expected_exit) << run.describe() << "\ndaemon log:\n" << st.daemon_log();
  const CmdResult hist = st.ctl({"history", serial, "--json"});
  EXPECT_EQ(hist.exit_code, 0) << hist.describe();
  const json runs = hist.json_out()["runs"];
  EXPECT_EQ(runs.size(), 1u) << runs.dump(2);
  return runs.empty() ? json::object() : runs[0];
}

std::vector<std::string> explained_by(const json& rec) {
  std::vector<std::string> out;
  if (rec.contains("diagnosis") && rec["diagnosis"].contains("explained_by"))
    for (const json& e : rec["diagnosis"]["explained_by"]) out.push_back(e.get<std::string>());
  return out;
}

TEST(StationPaperLike, TheMethodsAgreeAndTheDiagnosisNamesTheBudgetsSourcesSoTheRunIsReview) {
  Station st;
  SimOptions o;
  o.extra = {"--unit", kPaperLikeUnit};
  ASSERT_TRUE(st.start(o));
  const json truth = json::parse(read_text(st.truth_path()));
  ASSERT_TRUE(truth["effects"].contains("gyro_accel_skew")) << truth.dump(2);

  const json rec = run_paper_like(st, "PAPER-0001", 1);
  EXPECT_EQ(rec.value("crosscheck_verdict", ""), "PASS") << rec.dump(2);
  EXPECT_EQ(rec.value("state", ""), "review") << rec.dump(2);
  const std::string reason = rec.value("failure_reason", "");
  EXPECT_NE(reason.find("sim-to-real gap"), std::string::npos) << rec.dump(2);
  // The gap is the only reason: no limit, no cross-check.
  EXPECT_EQ(reason.find("limit"), std::string::npos) << reason;
  EXPECT_EQ(reason.find("cross-check"), std::string::npos) << reason;

  ASSERT_TRUE(rec["diagnosis"].is_object()) << rec.dump(2);
  EXPECT_EQ(rec["diagnosis"].value("verdict", ""), "explained") << rec["diagnosis"].dump(2);
  const std::vector<std::string> named = explained_by(rec);
  ASSERT_FALSE(named.empty()) << rec["diagnosis"].dump(2);
  std::printf("explained by:");
  for (const std::string& e : named) std::printf(" %s", e.c_str());
  std::printf("\n");
  EXPECT_EQ(named.front(), "gyro_accel_skew") << rec["diagnosis"].dump(2);
  for (const std::string& e : kMustName)
    EXPECT_TRUE(contains(named, e)) << e << " not named: " << rec["diagnosis"].dump(2);
  EXPECT_TRUE(contains(named, kSlowBiasDrift[0]) || contains(named, kSlowBiasDrift[1]))
      << "no slow accelerometer drift named: " << rec["diagnosis"].dump(2);
  // Of the budget's sources, at least those it must name.
  int budget_named = 0;
  for (const std::string& e : named) {
    budget_named += contains(kBudgetSources, e) ? 1 : 0;
    // Nothing the unit does not carry (issue #49: a named effect is earned).
    EXPECT_TRUE(contains(kBudgetSources, e)) << e << " is no source of this unit";
  }
  EXPECT_GE(budget_named, static_cast<int>(kMustName.size()) + 1) << rec["diagnosis"].dump(2);
  // The sizes the budget fitted, within the diagnosis' own ±4σ (skew 2.5 ms; latitude 5 arcmin).
  for (const json& step : rec["diagnosis"]["steps"]) {
    const std::string effect = step.value("effect", "");
    // at(): a key renamed in the record fails here instead of reading 0 (the σ was read from
    // "magnitude_sigma", a key the record does not have, so every bound was the bare margin).
    const double m = step.at("magnitude").get<double>(), s = step.at("sigma").get<double>();
    if (effect == "gyro_accel_skew") {
      EXPECT_NEAR(m, 2.5, 4.0 * s + 0.05) << step.dump();
    }
    if (effect == "latitude_error") {
      EXPECT_NEAR(m, 5.0, 4.0 * s + 0.5) << step.dump();
    }
  }
}

TEST(StationPaperLike, AProductWhoseEffectsAreKnownEndsPassWithTheDiagnosisKept) {
  Station st;
  SimOptions o;
  o.extra = {"--unit", kPaperLikeUnit};
  ASSERT_TRUE(st.start_sim(o));
  std::string cfg = st.config_text();
  std::string known = "known_effects = [";
  for (size_t i = 0; i < kBudgetSources.size(); ++i)
    known += (i ? ", \"" : "\"") + kBudgetSources[i] + "\"";
  known += "]\n";
  const size_t at = cfg.find("k_sigma = 4.0\n");
  ASSERT_NE(at, std::string::npos) << cfg;
  cfg.insert(at, known);
  st.write_config(cfg);
  ASSERT_TRUE(st.start_daemon());

  const json rec = run_paper_like(st, "PAPER-0002", 0);
  EXPECT_EQ(rec.value("state", ""), "done") << rec.dump(2);
  EXPECT_EQ(rec.value("verdict", ""), "PASS") << rec.dump(2);
  EXPECT_EQ(rec.value("crosscheck_verdict", ""), "PASS") << rec.dump(2);
  ASSERT_TRUE(rec["diagnosis"].is_object()) << rec.dump(2);
  EXPECT_EQ(rec["diagnosis"].value("verdict", ""), "explained") << rec["diagnosis"].dump(2);
  EXPECT_EQ(rec["diagnosis"].value("known_effects_only", false), true) << rec["diagnosis"].dump(2);
  // QA reading the record sees why a run with a named gap passed.
  const CmdResult show = st.ctl({"show", std::to_string(rec.value("run_id", -1LL))});
  EXPECT_NE(show.out.find("known effects alone"), std::string::npos) << show.describe();
}

}  // namespace
}  // namespace imucal::e2e
