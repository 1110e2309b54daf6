#pragma once
// `imucal gap-budget --against paper` (issue #26): which error sources, at which sizes, turn the
// simulated Tables I–IV into the paper's (calib/studies/paper/gap_budget.hpp for the method).
#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>

namespace imucal::tools::imucal {

struct GapBudgetArgs {
  std::string against = "paper";
  int units = 6;
  int threads = 0;  ///< 0: hardware concurrency
  uint64_t seed = 1;
  std::string sequence = "factory-std";
  std::string candidates;  ///< comma-separated names; empty: every default candidate
  int replicates = 8;
  int probe_units = 4;   ///< units per probe (each source alone)
  int search_units = 8;  ///< units per simulation of the whole-model search
  int check_units = 16;  ///< units of the fitted model's check on new seeds
  /// "NAME=SIZE,...": no fit — simulate this model (candidates' sizes in their human units) and
  /// print its means and per-IMU values beside the paper's.
  std::string model;
  std::string write_unit;  ///< --write-unit FILE: the model as a unit file
  std::string plot;        ///< --plot FILE.svg: the paper's IMUs beside the simulated units
  bool json = false;
};

CLI::App* add_gap_budget_command(CLI::App& app, GapBudgetArgs& args);
int cmd_gap_budget(const GapBudgetArgs& args);

}  // namespace imucal::tools::imucal
