#pragma once
// `imucal validate-diagnosis [--runs N] [--nulls N] [--pairs N] [--triples N] [--seed S]
// [--sequence S] [--effects a,b] [--false-alarm P] [--threads N] [--setting factory|land] [--grade
// G]
// [--json]`: the blind validation of the gap diagnosis (calib/diagnosis/diagnosis_validation.hpp)
// — confusion matrix, top-1 accuracy, false alarms on null runs with their 95 % interval, median
// held-out shrinkage, pairs and triples named — with a progress line on stderr.
#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>

namespace imucal::tools::imucal {

struct ValidateArgs {
  int runs = 10, nulls = -1, pairs = -1, threads = 0;  ///< nulls/pairs -1: same as runs
  int triples = 0;                                     ///< runs with three effects
  /// The diagnosis' false-alarm rate per run (imucal diagnose's default: 2e-3, alpha 1e-3).
  double false_alarm = 2e-3;
  uint64_t seed = 1;
  std::string sequence = "factory-std";
  std::string effects;
  std::string setting = "factory";  ///< factory: table runs; land: table-free hand-placed runs
  std::string grade;                ///< land: a unit drawn from this grade's envelope (--seed)
  /// factory: the world the runs come from, "truth" (calib/sim) or "alt" (tools/altsim, the
  /// independent simulator of issue #22).
  std::string simulator = "truth";
  bool json = false;
};

CLI::App* add_validate_command(CLI::App& app, ValidateArgs& args);
/// Exit 0 when the figures meet the bar (top-1 >= 90 %, false alarms <= 10 % — 5 % on
/// land, issue #21 — median shrinkage >= 70 %; issue #22: with several effects the first named one
/// injected >= 90 %, pairs all named >= 80 %, triples >= 60 %, no noise candidate ahead of an
/// injected effect), 3 otherwise.
int cmd_validate(const ValidateArgs& args);

}  // namespace imucal::tools::imucal
