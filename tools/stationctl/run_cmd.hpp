#pragma once
// `stationctl run start|status|abort`: start a run of one or several units (needs the control
// group), the daemon's or one run's state (read from the database when the daemon is down), abort
// the active run; and following runs to their end with the live progress line (--wait), which
// `import` and `reprocess` use too.
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "db/history/repository.hpp"
#include "tools/stationctl/connection.hpp"

namespace imucal::tools::stationctl {

/// The options of `run start`, `run status` and `run abort`.
struct RunArgs {
  std::vector<std::string> serials, slots;  ///< start: the units, by order or by slot
  std::string sequence, operator_name;      ///< start
  bool wait = false;                        ///< start
  double give_up_after_s = 600.0;           ///< start --wait: silence before exit 4
  db::history::RunId run_id = 0;            ///< status --run
  std::string reason;                       ///< abort
};

/// The subcommands of `run`, to find the one given.
struct RunCommands {
  CLI::App *start, *status, *abort;
};

RunCommands add_run_commands(CLI::App& app, RunArgs& args);
int cmd_run_start(const Target& t, const RunArgs& a, bool as_json);
int cmd_run_status(const Target& t, const RunArgs& a, bool as_json);
int cmd_run_abort(const Target& t, const RunArgs& a, bool as_json);

/// Follows one run to its end with the progress line on stderr (a TTY: rewritten in place;
/// otherwise a new line only when step, phase or state changes); prints its outcome (or, with
/// `outcome`, hands it back unprinted). Exit code: 0 only for done + PASS; kStoppedFollowing when
/// SIGINT/SIGTERM stops the following (the run itself goes on).
int wait_for_run(const Target& target, ControlClient& client, db::history::RunId run_id,
                 bool json_out, json* outcome = nullptr);

/// A run started (or a reprocessing): its id printed, or followed to its end with --wait.
int started(const Target& t, ControlClient& client, const json& r, const std::string& what,
            bool wait, bool as_json);

}  // namespace imucal::tools::stationctl
