#pragma once
// `imucal design-sequence --like SEQ --time-s T [--out F]` and
// `imucal design-sequence [--like SEQ] --target-from SEQ --factor K [--out F]` (issue #23 item 2):
// the sequence designer (calib/studies/design/sequence_design.hpp) on the station's limits
// tightened by the reference's [limits], the default unit (or --unit's) and the demo factory site;
// prints what the design traded against the reference (per parameter group and per catalogue
// effect) and writes the sequence file atomically, its header naming the command that made it.
#include <CLI/CLI.hpp>
#include <string>

namespace imucal::tools::imucal {

struct DesignSequenceArgs {
  std::string like = "factory-std";
  double time_s = 0.0;  ///< --time-s (0: not given)
  std::string target_from;
  double factor = 1.0;
  std::string out;
  std::string name;  ///< the design's name (default: --out's stem, else LIKE-design)
  std::string unit;
  double rate_hz = 100.0;
  double search_rate_hz = 20.0;
  bool no_effects = false;
  std::string command_line;  ///< as typed, for the file's header
};

CLI::App* add_design_sequence_command(CLI::App& app, DesignSequenceArgs& args);

/// Exit 0: designed and written, every target met; 3: written, but a target is not met (said
/// which); 1: bad input (the option or file named), nothing written.
int cmd_design_sequence(const DesignSequenceArgs& args);

}  // namespace imucal::tools::imucal
