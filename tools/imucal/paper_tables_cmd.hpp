#pragma once
// `imucal paper-tables [--units 6] [--seed S] [--sequence factory-std] [--effects
// none|typical|LIST]
// [--threads N] [--json]`:
// the paper's Tables I–IV (calib/studies/paper/paper_tables.hpp) on simulated units, in the paper's
// layout and beside its published figures, with a progress line on stderr. Exit 0 when the paper's
// findings hold in kind (AINS within 25 % across the three settings on both metrics; the legacy
// method worse on orientation than the factory AINS), 3 otherwise.
#include <CLI/CLI.hpp>
#include <cstdint>
#include <string>

namespace imucal::tools::imucal {

struct PaperTablesArgs {
  int units = 6;
  int threads = 0;  ///< 0: hardware concurrency
  uint64_t seed = 1;
  std::string sequence = "factory-std";
  bool json = false;
  std::string effects = "none";  ///< "none" | "typical" | e.g. "thermal,k2": units' unmodelled effects
};

CLI::App* add_paper_tables_command(CLI::App& app, PaperTablesArgs& args);
int cmd_paper_tables(const PaperTablesArgs& args);

}  // namespace imucal::tools::imucal
