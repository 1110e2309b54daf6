// Several unmodelled effects at once (issue #22 item 2, "What it must show"): runs of factory-std
// with 2 and 3 withheld effects (3-10x each one's detection threshold at the station's false-alarm
// rate) from the project's simulator and from the independent one (tools/altsim: its own
// integration scheme and noise generator), calibrated and diagnosed blind by `imucal
// validate-diagnosis`. The issue's bar — the first named effect injected in >= 90 % of runs, every
// injected effect named in >= 80 % of pairs and >= 60 % of triples, no noise candidate named ahead
// of an injected effect — is held at the whole count (IMUCAL_WHOLE_COUNTS=1: 20 pairs, 20 triples
// and 20 nulls per simulator, docs/validation/diagnosis.md). The CI count (8 of each per simulator)
// holds it with margins for the sampling noise of so few runs (first named injected >= 80 %, both
// of a pair >= 65 %: 6 of 8, all of a triple >= 45 %: 4 of 8), and the null runs beside them at
// the station's rate (none flagged). IMUCAL_VALIDATION_RUNS x 4 overrides the count.
#include <gtest/gtest.h>

#include <cstdio>
#include <cstdlib>
#include <nlohmann/json.hpp>
#include <string>

#include "tests/support/ci_count.hpp"
#include "tests/support/imucal_cli.hpp"

namespace {

constexpr int kRunsWhole = 5;  // x 4: the 20 pairs, triples and nulls of the whole count

int multi_runs() {
  return 4 * imucal::test_support::test_count("IMUCAL_VALIDATION_RUNS", 2, kRunsWhole);
}

nlohmann::json validate(const std::string& simulator, int n, int seed) {
  const auto r = imucal::test_support::run_imucal(
      "validate-diagnosis --simulator " + simulator + " --sequence factory-std --runs 1 --nulls " +
          std::to_string(n) + " --pairs " + std::to_string(n) + " --triples " + std::to_string(n) +
          " --false-alarm 1e-4 --seed " + std::to_string(seed) + " --json",
      /*merge_stderr=*/false);
  EXPECT_TRUE(r.code == 0 || r.code == 3) << r.out.substr(0, 2000);
  return nlohmann::json::parse(r.out);
}

void expect_the_bar(const nlohmann::json& j, const std::string& simulator) {
  std::printf(
      "%s: pairs all named %.2f (%d), triples all named %.2f (%d), first named injected "
      "%.2f, noise ahead %d, null false alarms %.3f of %d\n",
      simulator.c_str(), j["pair_both"].get<double>(), j["pair_runs"].get<int>(),
      j["triple_all"].get<double>(), j["triple_runs"].get<int>(),
      j["multi_first_injected"].get<double>(), j["multi_noise_ahead"].get<int>(),
      j["false_alarm"].get<double>(), j["null_runs"].get<int>());
  for (const auto& r : j["runs"])
    if (r["injected"].size() >= 2)
      std::printf("  %-70s -> %s\n", r["injected"].dump().c_str(), r["explained"].dump().c_str());
  EXPECT_GE(j["pair_runs"].get<int>(), 4);
  EXPECT_GE(j["triple_runs"].get<int>(), 4);
  // Enough runs to hold the rates to the bar itself.
  const bool issue_bar = j["pair_runs"].get<int>() >= 4 * kRunsWhole;
  EXPECT_GE(j["multi_first_injected"].get<double>(), issue_bar ? 0.9 : 0.8) << simulator;
  EXPECT_GE(j["pair_both"].get<double>(), issue_bar ? 0.8 : 0.65) << simulator;
  EXPECT_GE(j["triple_all"].get<double>(), issue_bar ? 0.6 : 0.45) << simulator;
  EXPECT_EQ(j["multi_noise_ahead"].get<int>(), 0) << simulator;
  // At 1e-4 per run, one false alarm in 8 to 20 null runs would be a 0.1-0.2 % event.
  EXPECT_EQ(j["false_alarm"].get<double>(), 0.0) << simulator;
}

}  // namespace

TEST(DiagnosisSeveralEffects, TheProjectsSimulatorMeetsTheBarWithMargins) {
  expect_the_bar(validate("truth", multi_runs(), 11), "truth");
}

TEST(DiagnosisSeveralEffects, TheIndependentSimulatorMeetsTheBarWithMargins) {
  expect_the_bar(validate("alt", multi_runs(), 12), "alt");
}
