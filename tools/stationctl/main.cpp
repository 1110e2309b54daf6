// stationctl: the operator's and QA engineer's tool for the calibration station (docs/operator.md,
// docs/qa.md). It talks to stationd over the control socket (JSON lines,
// station/control/control_protocol.hpp); the read commands (history, show, params, export, run
// status --run ID) fall back to reading the history database read-only when the daemon cannot be
// reached, through the same functions the daemon uses (station/control/record_json.hpp), so the
// output is the same either way.
//
// Exit codes: 0 ok (with --wait: the run is done with verdict PASS); 1 the run ended review,
// failed or aborted; 2 bad input (usage, invalid serial, unknown sequence or run); 3 refused (busy,
// permission); 4 daemon unreachable for a control command, database or I/O error (--wait: no
// answer for 10 minutes, or --give-up-after S); 5 with --wait, the run was interrupted (its daemon
// stopped during it); 130 when Ctrl-C stops --wait from following a run (the run itself goes on).
// `diagnose` exits as `imucal diagnose` does: 0 consistent or explained, 3 unexplained (a refusal,
// also 3, says so on stderr).
//
// This file is the program's wiring: the global options, each command's registration (one file
// pair per command or group, *_cmd.{hpp,cpp}; what they share in connection.{hpp,cpp}), dispatch
// and the top-level error handling.
#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>
#include <string>

#include "tools/stationctl/connection.hpp"
#include "tools/stationctl/diagnose_cmd.hpp"
#include "tools/stationctl/export_cmd.hpp"
#include "tools/stationctl/fleet_cmd.hpp"
#include "tools/stationctl/history_cmd.hpp"
#include "tools/stationctl/import_cmd.hpp"
#include "tools/stationctl/params_cmd.hpp"
#include "tools/stationctl/promote_cmd.hpp"
#include "tools/stationctl/reprocess_cmd.hpp"
#include "tools/stationctl/run_cmd.hpp"
#include "tools/stationctl/show_cmd.hpp"
#include "tools/stationctl/stations_cmd.hpp"

namespace {

using namespace imucal::tools::stationctl;

/// A command's options (CLI11 binds to these) and its subcommand, to find the one given.
template <class Args>
struct Command {
  Args args;
  CLI::App* app = nullptr;
};

/// Every command (one runs per call).
struct Commands {
  RunArgs run;
  RunCommands run_cmds{};
  Command<HistoryArgs> history;
  Command<ShowArgs> show;
  Command<ParamsArgs> params;
  Command<ExportArgs> exp;
  Command<ReprocessArgs> reprocess;
  Command<DiagnoseArgs> diagnose;
  Command<ImportArgs> import;
  Command<PromoteArgs> promote;
  Command<StationsArgs> stations;
  Command<FleetArgs> resync;
};

void add_global_options(CLI::App& app, Globals& g) {
  app.add_option("--config", g.config,
                 std::string("stationd's config file: [control] socket and [station] database "
                             "(default ") +
                     kDefaultConfig + " if it exists)");
  app.add_option("--socket", g.socket,
                 std::string("control socket of stationd (default: the config's, else ") +
                     kDefaultSocket + ")");
  app.add_option("--db", g.db,
                 "history database for reads when stationd is down (default: the config's)");
  app.add_option("--fleet", g.fleet,
                 "read history, show, params, export and stations from the factory's fleet store "
                 "(postgresql://USER@HOST:PORT/DB) instead of this station");
  app.add_option("--fleet-password-file", g.fleet_password_file,
                 "the fleet store password's file (first line); default: PGPASSWORD or ~/.pgpass");
  app.add_flag("--json", g.json, "print the raw JSON result instead of text");
}

/// The subcommands, in the order --help lists them.
void add_commands(CLI::App& app, Commands& c) {
  c.run_cmds = add_run_commands(app, c.run);
  c.history.app = add_history_command(app, c.history.args);
  c.show.app = add_show_command(app, c.show.args);
  c.params.app = add_params_command(app, c.params.args);
  c.exp.app = add_export_command(app, c.exp.args);
  c.reprocess.app = add_reprocess_command(app, c.reprocess.args);
  c.diagnose.app = add_diagnose_command(app, c.diagnose.args);
  c.import.app = add_import_command(app, c.import.args);
  c.promote.app = add_promote_command(app, c.promote.args);
  c.stations.app = add_stations_command(app, c.stations.args);
  c.resync.app = add_fleet_commands(app, c.resync.args);
}

/// The command given, run.
int dispatch(const Target& t, const Commands& c, bool as_json) {
  if (*c.run_cmds.start) return cmd_run_start(t, c.run, as_json);
  if (*c.run_cmds.status) return cmd_run_status(t, c.run, as_json);
  if (*c.run_cmds.abort) return cmd_run_abort(t, c.run, as_json);
  if (*c.history.app) return cmd_history(t, c.history.args, as_json);
  if (*c.show.app) return cmd_show(t, c.show.args, as_json);
  if (*c.params.app) return cmd_params(t, c.params.args, as_json);
  if (*c.exp.app) return cmd_export(t, c.exp.args, as_json);
  if (*c.reprocess.app) return cmd_reprocess(t, c.reprocess.args, as_json);
  if (*c.diagnose.app) return cmd_diagnose(t, c.diagnose.args, as_json);
  if (*c.import.app) return cmd_import(t, c.import.args, as_json);
  if (*c.promote.app) return cmd_promote(t, c.promote.args, as_json);
  if (*c.stations.app) return cmd_stations(t, c.stations.args, as_json);
  if (*c.resync.app) return cmd_fleet_resync(t, c.resync.args, as_json);
  throw Failure{kBadInput, "no command given (see --help)"};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"stationctl: start and follow calibration runs; query the calibration history"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string(IMUCAL_VERSION));
  Globals g;
  Commands c;
  add_global_options(app, g);
  add_commands(app, c);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForVersion& e) {
    return app.exit(e);  // prints the version, exit 0 (it was caught below as bad input, exit 2)
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return kBadInput;
  }
  try {
    return dispatch(resolve_target(g), c, g.json);
  } catch (const Failure& f) {
    std::cout.flush();
    std::cerr << "stationctl: " << f.message << "\n";
    return f.code;
  } catch (const std::exception& e) {
    std::cout.flush();
    std::cerr << "stationctl: " << e.what() << "\n";
    return kUnavailable;
  }
}
