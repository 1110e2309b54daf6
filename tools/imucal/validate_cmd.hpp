#pragma once
// `imucal validate-diagnosis [--runs N] [--nulls N] [--pairs N] [--seed S] [--sequence S]
// [--effects a,b] [--threads N] [--setting factory|land] [--grade G] [--json]`: the blind
// validation of the gap diagnosis (calib/diagnosis/diagnosis_validation.hpp) — confusion matrix,
// top-1 accuracy, false alarms on null runs, median held-out shrinkage, pairs named — with a
// progress line on stderr.
#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>

namespace imucal::tools {

struct ValidateArgs {
  int runs = 10, nulls = -1, pairs = -1, threads = 0;  ///< nulls/pairs -1: same as runs
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
/// land, issue #21 — median shrinkage >= 70 %, pairs >= 70 %), 3 otherwise.
int cmd_validate(const ValidateArgs& args);

}  // namespace imucal::tools
