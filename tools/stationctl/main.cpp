// stationctl: the operator's and QA engineer's tool for the calibration station (station contract
// §C). It talks to stationd over the control socket (JSON lines, station/control/control_protocol.hpp);
// the read commands (history, show, params, export, run status --run ID) fall back to reading the
// history database read-only when the daemon cannot be reached, through the same functions the
// daemon uses (station/control/record_json.hpp), so the output is the same either way.
//
// Exit codes: 0 ok (with --wait: the run is done with verdict PASS); 1 the run ended review,
// failed, aborted or interrupted; 2 bad input (usage, invalid serial, unknown sequence or run);
// 3 refused (busy, permission); 4 daemon unreachable for a control command, database or I/O error;
// 130 when Ctrl-C stops --wait from following a run (the run itself goes on). `diagnose` exits as
// `imucal diagnose` does: 0 consistent or explained, 3 unexplained (a refusal, also 3, says so on
// stderr).
#include <signal.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <string>
#include <thread>

#include "db/archive/io_util.hpp"
#include "db/history/export.hpp"
#include "db/fleet/fleet_repository.hpp"
#include "db/fleet/fleet_schema.hpp"
#include "db/fleet/fleet_writer.hpp"
#include "db/fleet/pg_fleet_stats.hpp"
#include "db/history/serial_number.hpp"
#include "db/history/sqlite_fleet_stats.hpp"
#include "db/history/sqlite_repository.hpp"
#include "station/config/config.hpp"
#include "station/control/control_client.hpp"
#include "station/control/control_protocol.hpp"
#include "station/daemon/fleet_sender.hpp"
#include "station/control/record_json.hpp"
#include "tools/report/station_signatures.hpp"
#include "tools/report/diagnosis_report.hpp"
#include "tools/stationctl/export_output.hpp"

namespace {

using nlohmann::json;
using namespace imucal;
using station::control::ControlClient;
using station::control::ControlClientError;
using tools::stationctl::ExportOutput;
using tools::stationctl::ExportOutputError;

enum Exit : int { kOk = 0, kRunNotPassed = 1, kBadInput = 2, kRefused = 3, kUnavailable = 4 };
/// `diagnose` of a run whose gap no candidate explains: the exit code of imucal diagnose.
constexpr int kGapUnexplained = 3;

/// Where stationd looks when no config is given (the systemd unit, station/daemon/stationd.service.in, passes this file).
constexpr const char* kDefaultConfig = "/etc/imucal/stationd.toml";
constexpr const char* kDefaultSocket = "/run/imucal/stationd.sock";
constexpr auto kPollPeriod = std::chrono::milliseconds(200);
/// The daemon's own rule for names and reasons (station/control/control_protocol.hpp), checked before
/// connecting so that the operator sees the problem at once.
std::function<std::string(const std::string&)> text_check(std::size_t max_chars) {
  return [max_chars](const std::string& v) { return station::control::text_field_error(v, max_chars); };
}

/// Exit code when the operator stops following a run with Ctrl-C (128 + SIGINT, the shell's).
constexpr int kInterrupted = 130;

/// Set by SIGINT/SIGTERM while --wait follows a run: stop following (the run itself goes on).
std::atomic<bool> g_stop_following{false};
extern "C" void on_stop_signal(int) { g_stop_following = true; }
constexpr auto kReplyTimeout = std::chrono::seconds(60);
/// A read the daemon does not answer in this time is read from the database instead.
constexpr auto kReadTimeout = std::chrono::seconds(10);
/// How long --wait looks in the database for the outcome of a run whose daemon went away.
constexpr auto kOutcomeGrace = std::chrono::seconds(10);
/// A streamed export: the longest wait for its next frame (the daemon sends one per 64 KiB).
constexpr auto kExportFrameTimeout = std::chrono::seconds(30);

/// A failure with its exit code; main prints "stationctl: <message>" and exits with the code.
struct Failure {
  int code;
  std::string message;
};

int exit_for_error_code(const std::string& code) {
  namespace ec = station::control::error_code;
  if (code == ec::kBadRequest || code == ec::kInvalidInput || code == ec::kNotFound)
    return kBadInput;
  if (code == ec::kBusy || code == ec::kPermissionDenied) return kRefused;
  return kUnavailable;
}

int exit_for_db_error(db::history::DbErrorKind kind) {
  if (kind == db::history::DbErrorKind::kNotFound || kind == db::history::DbErrorKind::kInvalidInput)
    return kBadInput;
  return kUnavailable;
}

struct Globals {
  std::string config;
  std::string socket;
  std::string db;
  std::string fleet;                ///< --fleet URL: read the fleet store instead
  std::string fleet_password_file;  ///< its password (else libpq's PGPASSWORD / ~/.pgpass)
  bool json = false;
};

struct Target {
  std::string socket;
  std::string db;  ///< "" = none known
  std::string config_used;
  std::string fleet_url;  ///< --fleet: reads go to the fleet store (no daemon, no SQLite)
  std::string fleet_password;
  std::optional<station::config::FleetConfig> fleet_config;  ///< the config's [fleet], for `fleet resync`
};

Target resolve_target(const Globals& g) {
  Target t;
  std::string config = g.config;
  if (config.empty() && (g.socket.empty() || g.db.empty()) &&
      std::filesystem::exists(kDefaultConfig))
    config = kDefaultConfig;
  if (!config.empty()) {
    try {
      // The daemon's own loader: a config stationd accepts is one stationctl reads the same way
      // (relative paths against the file's directory). Only the socket and database are used.
      const station::config::StationConfig c = station::config::load_config(config);
      t.socket = c.control_socket;
      t.db = c.database;
      t.config_used = config;
      t.fleet_config = c.fleet;
    } catch (const station::config::ConfigError& e) {
      throw Failure{kBadInput, e.what()};
    }
  }
  if (!g.socket.empty()) t.socket = g.socket;
  if (!g.db.empty()) t.db = g.db;
  t.fleet_url = g.fleet;
  try {
    if (!g.fleet_password_file.empty())
      t.fleet_password = db::fleet::read_password_file(g.fleet_password_file);
    if (!t.fleet_url.empty()) (void)db::fleet::parse_fleet_target(t.fleet_url, t.fleet_password);
  } catch (const db::history::DbError& e) {
    throw Failure{kBadInput, std::string("--fleet: ") + e.what()};
  }
  if (t.socket.empty()) t.socket = kDefaultSocket;
  return t;
}

/// The result of an ok reply; an error reply becomes a Failure with the reply's message.
json result_or_fail(const station::control::Reply& r) {
  if (!r.ok) throw Failure{exit_for_error_code(r.error_code), r.error_message};
  return r.result;
}

json call(ControlClient& client, const std::string& command, const json& args) {
  try {
    return result_or_fail(client.call(command, args, kReplyTimeout));
  } catch (const ControlClientError& e) {
    throw Failure{kUnavailable, e.what()};
  }
}

/// For control commands: the daemon must be there.
ControlClient connect_or_fail(const Target& t) {
  try {
    return ControlClient(t.socket);
  } catch (const ControlClientError& e) {
    if (e.kind() == ControlClientError::Kind::kNoPermission) throw Failure{kRefused, e.what()};
    throw Failure{kUnavailable, std::string(e.what()) + " (is stationd running?)"};
  }
}

/// For reads: a connection to the daemon, or none (with `why`) when it is not there or the socket
/// admits only the control group, so that the database is read instead.
std::optional<ControlClient> connect_for_read(const Target& t, std::string& why) {
  using Kind = ControlClientError::Kind;
  try {
    return std::optional<ControlClient>(std::in_place, t.socket);
  } catch (const ControlClientError& e) {
    if (e.kind() != Kind::kUnreachable && e.kind() != Kind::kNoPermission)
      throw Failure{kUnavailable, e.what()};
    why = e.what();
    return std::nullopt;
  }
}

/// The fleet store's read side (db/fleet/fleet_repository.hpp); its errors as stationctl's.
std::unique_ptr<db::fleet::FleetRepository> open_fleet(const Target& t) {
  try {
    return std::make_unique<db::fleet::FleetRepository>(
        db::fleet::parse_fleet_target(t.fleet_url, t.fleet_password));
  } catch (const db::history::DbError& e) {
    throw Failure{exit_for_db_error(e.kind()), e.what()};
  }
}

/// A read of the fleet store (--fleet URL): the same validation and the same answer as the
/// daemon's, over every station's runs.
json fleet_read(const Target& t, const std::string& command, const json& args) {
  if (command == station::control::cmd::kRunStatus)
    throw Failure{kBadInput, "run status needs a station's daemon, not the fleet store"};
  const auto repo = open_fleet(t);
  try {
    const station::control::Request request =
        station::control::validate_request(json{{"id", 0}, {"cmd", command}, {"args", args}});
    return station::control::answer_repository_read(*repo, request);
  } catch (const station::control::BadRequest& e) {
    throw Failure{kBadInput, e.what()};
  } catch (const db::history::DbError& e) {
    throw Failure{exit_for_db_error(e.kind()), e.what()};
  }
}

/// A read: over the socket, or from the database read-only when the daemon is unreachable.
json read_request(const Target& t, const std::string& command, const json& args) {
  if (!t.fleet_url.empty()) return fleet_read(t, command, args);
  std::string why;
  using Kind = ControlClientError::Kind;
  std::optional<ControlClient> client = connect_for_read(t, why);
  // A daemon that does not answer (busy, or its connections exhausted) is no reason not to read:
  // the database is there.
  if (client) {
    try {
      const station::control::Reply r = client->call(command, args, kReadTimeout);
      if (r.ok || r.error_code != station::control::error_code::kUnavailable || t.db.empty())
        return result_or_fail(r);
      why = "stationd: " + r.error_message;  // e.g. its connections are exhausted
    } catch (const ControlClientError& e) {
      if (t.db.empty() || (e.kind() != Kind::kTimeout && e.kind() != Kind::kClosed))
        throw Failure{kUnavailable, e.what()};
      why = e.what();
    }
  }

  if (t.db.empty())
    throw Failure{kUnavailable, why + "; no database to read instead (give --db or --config)"};
  std::cerr << "stationctl: note: " << why << "; reading the database " << t.db
            << " read-only instead\n";
  std::unique_ptr<db::history::SqliteRepository> opened;
  try {
    db::history::SqliteOptions options;
    options.read_only = true;
    opened = std::make_unique<db::history::SqliteRepository>(t.db, options);
  } catch (const db::history::DbError& e) {
    // No database (or not a usable one) is a database error, not bad input.
    throw Failure{kUnavailable, e.what()};
  }
  const db::history::SqliteRepository& repo = *opened;
  try {
    // The same validation and the same answer as the daemon's control server.
    const station::control::Request request =
        station::control::validate_request(json{{"id", 0}, {"cmd", command}, {"args", args}});
    if (command == station::control::cmd::kRunStatus) {
      if (!request.args.contains("run_id"))
        throw Failure{kUnavailable, why +
                                        " (the status of the daemon needs the daemon; "
                                        "`run status --run ID` reads a run's state from the "
                                        "database)"};
      json run = station::control::run_record_json(repo.show(request.args["run_id"].get<db::history::RunId>()).run);
      run["reason"] = run["failure_reason"];
      return json{{"run", run}};
    }
    return station::control::answer_repository_read(repo, request);
  } catch (const station::control::BadRequest& e) {
    throw Failure{kBadInput, e.what()};
  } catch (const db::history::DbError& e) {
    throw Failure{exit_for_db_error(e.kind()), e.what()};
  }
}

/// A member as text: strings as they are, other values as JSON, absent or null as `fallback`.
std::string text(const json& o, const char* key, const std::string& fallback = "") {
  const auto it = o.find(key);
  if (it == o.end() || it->is_null()) return fallback;
  return it->is_string() ? it->get<std::string>() : it->dump();
}

void print_json(const json& j) {
  std::cout << j.dump(2, ' ', false, json::error_handler_t::replace) << "\n";
}

bool state_done_pass(const json& run) {
  return text(run, "state") == "done" && text(run, "verdict") == "PASS";
}

bool is_terminal_state(const std::string& state) {
  return state == "done" || state == "review" || state == "failed" || state == "aborted" ||
         state == "interrupted";
}

/// Polls run.status every ~200 ms until the run is terminal, showing a progress line on stderr
/// (a TTY: rewritten in place; otherwise a new line only when step, phase or state changes).
int wait_for_run(const Target& target, ControlClient& client, db::history::RunId run_id, bool json_out,
                 json* outcome = nullptr);
int wait_for_runs(const Target& target, ControlClient& client, const std::vector<db::history::RunId>& ids,
                  bool json_out);

/// `stationctl import DIR [--wait]`: the daemon reads the archive itself, so the path is made
/// absolute here (the daemon's working directory is not the user's).
int cmd_import(const Target& target, const std::string& dir, bool wait, bool json_out) {
  std::error_code ec;
  const std::string abs = std::filesystem::absolute(dir, ec).lexically_normal().string();
  if (ec || !std::filesystem::is_directory(abs))
    throw Failure{kBadInput, dir + ": no such run archive directory"};
  ControlClient client = connect_or_fail(target);
  const json r = call(client, station::control::cmd::kImport, {{"dir", abs}});
  const std::string head = "run " + text(r, "run_id", "?") + ": imported " + text(r, "setting") +
                           " run of " + text(r, "serial") + " from " + abs;
  if (!wait) {
    if (json_out)
      print_json(r);
    else
      std::cout << head << "\n";
    return kOk;
  }
  if (!json_out) std::cerr << head << "\n";
  return wait_for_run(target, client, r.at("run_id").get<db::history::RunId>(), json_out);
}

/// `stationctl promote RUN_ID --reason TEXT`: recorded with the caller's user name.
int cmd_promote(const Target& target, db::history::RunId run_id, const std::string& reason, bool json_out) {
  ControlClient client = connect_or_fail(target);
  const json r = call(client, station::control::cmd::kPromote, {{"run_id", run_id}, {"reason", reason}});
  if (json_out)
    print_json(r);
  else
    std::cout << "run " << run_id << " promoted to the active parameters by "
              << text(r, "promoted_by") << " at " << text(r, "promoted_at") << "\n";
  return kOk;
}

/// The daemon went away while a run was followed (SIGTERM, a crash): what the database says of
/// the run once it is terminal — the daemon records an abort as it stops, recovery a crash when
/// it starts again. Waits up to kOutcomeGrace for that; nullopt if there is still no outcome.
std::optional<json> outcome_after_daemon_left(const Target& target, db::history::RunId run_id) {
  const auto deadline = std::chrono::steady_clock::now() + kOutcomeGrace;
  for (;;) {
    try {
      const json status = read_request(target, station::control::cmd::kRunStatus, {{"run_id", run_id}});
      if (status.contains("run") && is_terminal_state(text(status["run"], "state")))
        return status["run"];
    } catch (const Failure&) {
      // The database is not readable either (yet): try again until the deadline.
    }
    if (std::chrono::steady_clock::now() >= deadline) return std::nullopt;
    std::this_thread::sleep_for(std::chrono::milliseconds(200));
  }
}

/// Follows one run to its end with the progress line; prints its outcome (or, with `outcome`,
/// hands it back unprinted). Exit code: 0 only for done + PASS.
int wait_for_run(const Target& target, ControlClient& client, db::history::RunId run_id, bool json_out,
                 json* outcome) {
  const bool tty = ::isatty(STDERR_FILENO) != 0;
  std::string last_key, last_line;
  std::size_t shown_width = 0;
  json run;
  struct sigaction sa {};
  sa.sa_handler = on_stop_signal;
  sigemptyset(&sa.sa_mask);
  ::sigaction(SIGINT, &sa, nullptr);
  ::sigaction(SIGTERM, &sa, nullptr);
  for (;;) {
    if (g_stop_following) {
      if (tty && shown_width) std::cerr << "\n";
      std::cerr << "stationctl: stopped following run " << run_id
                << "; the run goes on (`stationctl run status --run " << run_id << "`)\n";
      return kInterrupted;
    }
    json status;
    try {
      status = call(client, station::control::cmd::kRunStatus, {{"run_id", run_id}});
    } catch (Failure& f) {
      if (tty && shown_width) std::cerr << "\n";  // keep the last progress shown
      shown_width = 0;
      if (f.code == kUnavailable) {
        if (auto outcome = outcome_after_daemon_left(target, run_id)) {
          run = *outcome;
          break;
        }
      }
      f.message = "while waiting for run " + std::to_string(run_id) + ": " + f.message +
                  " (the run's outcome: `stationctl run status --run " + std::to_string(run_id) +
                  "`)";
      throw;
    }
    if (!status.contains("run") || !status["run"].is_object())
      throw Failure{kUnavailable, "run.status reply without a run object: " + status.dump()};
    run = status["run"];
    const std::string state = text(run, "state");
    if (is_terminal_state(state)) break;  // the outcome line below says it once
    const std::string line = station::control::progress_line(run);
    if (tty) {
      if (line != last_line) {
        std::string out = "\r" + line;
        if (line.size() < shown_width) out += std::string(shown_width - line.size(), ' ');
        std::cerr << out << std::flush;
        shown_width = line.size();
        last_line = line;
      }
    } else {
      // Time left changes every poll; a log gets a line per step, phase or state only.
      const std::string key =
          state + "|" + text(run, "phase") + "|" + (run.contains("step") ? run["step"].dump() : "");
      if (key != last_key) {
        std::cerr << line << "\n" << std::flush;
        last_key = key;
      }
    }
    for (auto slept = std::chrono::milliseconds(0); slept < kPollPeriod && !g_stop_following;
         slept += std::chrono::milliseconds(20))
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  // On a TTY the progress line is wiped: the outcome replaces it.
  if (tty && shown_width) std::cerr << "\r" << std::string(shown_width, ' ') << "\r" << std::flush;
  if (outcome)
    *outcome = run;
  else if (json_out)
    print_json(json{{"run", run}});
  else
    std::cout << station::control::outcome_line(run) << "\n";
  const bool pass = state_done_pass(run);
  return pass ? kOk : kRunNotPassed;
}

/// The units of one table run followed to their ends (the first one's progress line names the
/// others); one outcome line per unit, or {"runs": [...]}. 0 only if every unit is done + PASS.
int wait_for_runs(const Target& target, ControlClient& client, const std::vector<db::history::RunId>& ids,
                  bool json_out) {
  json runs = json::array();
  int code = kOk;
  for (const db::history::RunId id : ids) {
    json run;
    const int c = wait_for_run(target, client, id, json_out, &run);
    if (c == kInterrupted) return c;
    if (c != kOk) code = c;
    runs.push_back(run);
  }
  if (json_out)
    print_json(json{{"runs", runs}});
  else
    for (const json& run : runs) std::cout << station::control::outcome_line(run) << "\n";
  return code;
}

void check_serial(const std::string& serial) {
  if (const auto problem = db::history::serial_problem(serial)) throw Failure{kBadInput, *problem};
}

/// The export streamed from the daemon into `out`; the rows, or nullopt (with `why`) when the
/// daemon cannot serve it and nothing has been written yet, so the database can be read instead.
std::optional<std::size_t> export_from_daemon(const Target& t, const json& args, ExportOutput& out,
                                              std::string& why) {
  using Kind = ControlClientError::Kind;
  std::optional<ControlClient> client = connect_for_read(t, why);
  if (!client) return std::nullopt;
  bool wrote = false;
  try {
    json streamed = args;
    streamed["stream"] = true;
    const station::control::Reply r = client->call_streamed(
        station::control::cmd::kExport, streamed,
        [&](std::string_view bytes) {
          wrote = true;
          out.write(bytes);
        },
        kExportFrameTimeout);
    if (r.ok) return r.result.at("rows").get<std::size_t>();
    if (r.error_code != station::control::error_code::kUnavailable || t.db.empty() || wrote)
      result_or_fail(r);
    why = "stationd: " + r.error_message;
  } catch (const ControlClientError& e) {
    if (wrote || t.db.empty() || (e.kind() != Kind::kTimeout && e.kind() != Kind::kClosed))
      throw Failure{kUnavailable, e.what()};
    why = e.what();
  }
  return std::nullopt;
}

/// `stationctl export`: streamed from the daemon as it reads the rows, or straight from the
/// database when the daemon is down; memory stays flat either way (issue #11). Where the bytes go:
/// tools/stationctl/export_output.hpp.
int export_to(const Target& t, const json& args, const std::string& output, bool json_out) {
  ExportOutput out(output);
  std::string why;
  std::optional<std::size_t> rows;
  if (!t.fleet_url.empty()) {
    const auto repo = open_fleet(t);
    try {
      rows = db::history::export_history(*repo, station::control::export_filter(*repo, args),
                                args.at("format").get<std::string>(), out.stream());
    } catch (const db::history::DbError& e) {
      out.check();
      throw Failure{exit_for_db_error(e.kind()), e.what()};
    }
  } else {
    rows = export_from_daemon(t, args, out, why);
  }
  if (!rows) {
    if (t.db.empty())
      throw Failure{kUnavailable, why + "; no database to read instead (give --db or --config)"};
    std::cerr << "stationctl: note: " << why << "; reading the database " << t.db
              << " read-only instead\n";
    try {
      db::history::SqliteOptions options;
      options.read_only = true;
      const db::history::SqliteRepository repo(t.db, options);
      rows = db::history::export_history(repo, station::control::export_filter(repo, args),
                                args.at("format").get<std::string>(), out.stream());
    } catch (const db::history::DbError& e) {
      out.check();  // the output's own failure, with the system's reason, before the export's words
      throw Failure{exit_for_db_error(e.kind()), e.what()};
    }
  }
  out.commit();
  if (output.empty()) return kOk;
  if (json_out)
    print_json({{"format", args.at("format")}, {"rows", *rows}, {"output", output}});
  else
    std::cerr << "stationctl: " << *rows << " rows written to " << output << "\n";
  return kOk;
}

int cmd_export(const Target& t, const json& args, const std::string& output, bool json_out) {
  try {
    return export_to(t, args, output, json_out);
  } catch (const ExportOutputError& e) {
    throw Failure{kUnavailable, e.what()};
  }
}

/// Every option value of every command (CLI11 binds to these; one command runs per call).
struct Args {
  std::vector<std::string> serials, slots;  ///< run start: the units, by order or by slot
  std::string serial, sequence, operator_name, reason, since, format, output, import_dir,
      report_dir, station;
  std::string until;  ///< stations --signatures: the window's end
  bool wait = false, partial = false, bare = false, signatures = false, trend = false;
  int period_days = 7;  ///< stations --signatures --trend
  double false_alarm = 1e-3;
  std::optional<double> gravity_mps2;  ///< reprocess: the corrected surveyed gravity
  db::history::RunId run_id = 0;
  std::vector<db::history::RunId> run_ids;  ///< reprocess: one or several
  std::size_t limit = 0;
};

/// The subcommands, to find the one given.
struct Commands {
  CLI::App *start, *status, *abort, *history, *show, *params, *exp, *reprocess, *diagnose, *import,
      *promote, *stations, *resync;
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

void add_run_commands(CLI::App& app, Args& a, Commands& c) {
  auto* run = app.add_subcommand("run", "start, follow or abort a calibration run");
  run->require_subcommand(1);
  run->fallthrough();
  c.start = run->add_subcommand("start", "start a run of a unit (needs the control group)");
  c.start
      ->add_option("--serial", a.serials,
                   std::string("serial number: ") + db::history::kSerialRule +
                       "; repeat it for several units on the fixture (slots in the "
                       "configuration's order)")
      ->take_all();
  c.start->add_option("--slot", a.slots,
                      "SLOT=SERIAL: a unit in a named fixture slot (repeatable; instead of "
                      "--serial)");
  c.start->add_option("--sequence", a.sequence, "sequence name or file (default: the station's)");
  c.start->add_option("--operator", a.operator_name, "operator name (default: your user name)")
      ->check(text_check(station::control::kMaxNameChars));
  c.start->add_flag("--wait", a.wait, "follow the run to its end; exit 0 only for done + PASS");
  c.start->fallthrough();
  c.status = run->add_subcommand("status", "the daemon's state, or one run's (--run)");
  c.status->add_option("--run", a.run_id, "run id")->check(CLI::PositiveNumber);
  c.status->fallthrough();
  c.abort = run->add_subcommand("abort", "abort the active run (needs the control group)");
  c.abort->add_option("--reason", a.reason, "why (stored with the run)")
      ->check(text_check(station::control::kMaxReasonChars));
  c.abort->fallthrough();
}

void add_read_commands(CLI::App& app, Args& a, Commands& c) {
  c.history = app.add_subcommand(
      "history", "the runs of a unit, newest first; without SN the newest runs of every unit");
  c.history->add_option("SN", a.serial, "serial number (default: every unit)");
  c.history->add_option("--limit", a.limit,
                        "at most N runs (default: all of a unit, the newest 20 of every unit)");
  c.history->add_option("--station", a.station, "only this station's runs");
  c.history->fallthrough();
  c.show = app.add_subcommand("show", "everything stored about a run");
  c.show->add_option("RUN_ID", a.run_id, "run id")->required()->check(CLI::PositiveNumber);
  c.show->fallthrough();
  c.params = app.add_subcommand(
      "params",
      "the unit's active parameter set with 1-sigma (JSON for the INS) and, under \"source\", the "
      "run it comes from");
  c.params->add_option("SN", a.serial, "serial number")->required();
  c.params->add_flag("--bare", a.bare,
                     "leave \"source\" out: only the five schema keys and sigma, for a loader that "
                     "accepts nothing else");
  c.params->fallthrough();
  c.exp = app.add_subcommand(
      "export",
      "the history as CSV, JSON or NDJSON, streamed (with --json and --output: a JSON "
      "summary of what was written)");
  c.exp->add_option("--serial", a.serial, "only this unit");
  c.exp->add_option("--since", a.since,
                    "only runs started at or after (YYYY-MM-DD[THH:MM[:SS]][Z])");
  c.exp->add_option("--format", a.format, "csv, json (one array) or ndjson (one object per line)")
      ->required()
      ->check(CLI::IsMember({"csv", "json", "ndjson"}));
  c.exp->add_option("--output", a.output, "write to FILE instead of stdout");
  c.exp->add_option("--station", a.station, "only this station's runs");
  c.exp->fallthrough();
}

void add_history_commands(CLI::App& app, Args& a, Commands& c) {
  c.reprocess = app.add_subcommand(
      "reprocess",
      "recalibrate stored runs from their archives into new runs (needs the group); several "
      "RUN_IDs (a station signature's runs) are reprocessed one after another, each followed to "
      "its end");
  c.reprocess->add_option("RUN_ID", a.run_ids, "run id(s)")->required()->check(CLI::PositiveNumber);
  c.reprocess->add_flag("--wait", a.wait, "follow the new run to its end (always, for several)");
  c.reprocess->add_flag("--partial", a.partial,
                        "calibrate an incomplete archive (aborted, interrupted or failed capture) "
                        "anyway: stored REVIEW at best, never the unit's active parameters");
  c.reprocess->add_option("--gravity-mps2", a.gravity_mps2,
                          "calibrate with this surveyed gravity (m/s², 9.7-9.9) instead of the "
                          "archive's: a station whose signature showed a wrong gravity, corrected "
                          "(issue #25); the new run says so and, like an import, becomes the "
                          "unit's active parameters only when QA promotes it");
  c.reprocess->fallthrough();
  c.diagnose = app.add_subcommand(
      "diagnose", "sim-to-real gap diagnosis of a stored run, kept with the run (needs the group)");
  c.diagnose->add_option("RUN_ID", a.run_id, "run id")->required()->check(CLI::PositiveNumber);
  c.diagnose->add_option("--report", a.report_dir,
                         "also write OUTDIR/report.html and OUTDIR/diagnosis.json (as imucal "
                         "diagnose --report)");
  c.diagnose->fallthrough();
  c.import = app.add_subcommand(
      "import",
      "add a field (land/sea) or other station's run archive to its unit's history and calibrate "
      "it with its setting (needs the group); it keeps the archive's recorded start and end, never "
      "becomes active unless promoted, and an archive already stored is refused");
  c.import
      ->add_option("DIR", a.import_dir, "run archive directory (imucal simulate/calibrate format)")
      ->required();
  c.import->add_flag("--wait", a.wait, "follow the calibration to its end");
  c.import->fallthrough();
  c.promote = app.add_subcommand(
      "promote", "QA: make a field run the unit's active parameters (needs the group)");
  c.promote->add_option("RUN_ID", a.run_id, "run id")->required()->check(CLI::PositiveNumber);
  c.promote->add_option("--reason", a.reason, "why (stored with the run, required)")
      ->required()
      ->check(text_check(station::control::kMaxReasonChars));
  c.promote->fallthrough();
  c.stations = app.add_subcommand(
      "stations", "the stations in the fleet store (--fleet URL), or their signatures");
  c.stations->add_flag("--signatures", a.signatures,
                       "each station's departure from the fleet and the station errors it fits "
                       "(issue #25), from the fleet store or --db; exit 1 if one is flagged");
  c.stations->add_option("--since", a.since,
                         "signatures: runs started at or after (UTC date or time; default: 7 "
                         "days before --until)");
  c.stations->add_option("--until", a.until,
                         "signatures: runs started before (UTC date: up to the end of that day; "
                         "default: the end of the newest run's day)");
  c.stations->add_flag("--trend", a.trend,
                       "signatures period by period (default window: the 12 periods up to the "
                       "newest run's day); exit 1 if one is flagged in the newest period");
  c.stations->add_option("--period-days", a.period_days, "trend: the length of a period in days")
      ->check(CLI::Range(1, 366))
      ->default_val(7);
  c.stations
      ->add_option("--false-alarm", a.false_alarm,
                   "signatures: false-alarm rate per station and period")
      ->check(CLI::Range(1e-6, 0.2))
      ->default_val(1e-3);
  c.stations->fallthrough();
  auto* fleet = app.add_subcommand("fleet", "this station's share of the factory's fleet store");
  fleet->require_subcommand(1);
  fleet->fallthrough();
  c.resync = fleet->add_subcommand(
      "resync",
      "rebuild this station's share of the fleet store from its SQLite history (the config's "
      "[fleet], or --fleet URL with --station-id): every run stored; runs the store holds and "
      "this database does not (a replaced or restored database) are kept, set apart as station "
      "ID.previous-TIME, never deleted; safe while stationd runs");
  c.resync->add_option("--station-id", a.station,
                       "the station's id in the store (default: the config's)");
  c.resync->fallthrough();
}

/// A result as JSON, or as the text `render` makes of it.
int print_result(const json& r, bool as_json, std::string (*render)(const json&)) {
  if (as_json)
    print_json(r);
  else
    std::cout << render(r);
  return kOk;
}

/// A run started (or a reprocessing): its id printed, or followed to its end with --wait.
int started(const Target& t, ControlClient& client, const json& r, const std::string& what,
            bool wait, bool as_json) {
  if (!wait) {
    if (as_json)
      print_json(r);
    else
      std::cout << "run " << text(r, "run_id", "?") << " " << what << "\n";
    return kOk;
  }
  if (!as_json) std::cerr << "run " << text(r, "run_id", "?") << " " << what << "\n";
  return wait_for_run(t, client, r.at("run_id").get<db::history::RunId>(), as_json);
}

/// run start's units: --serial SN (repeatable: slots in order) or --slot SLOT=SN, not both.
json start_units(const Args& a) {
  if (a.serials.empty() == a.slots.empty())
    throw Failure{kBadInput,
                  "run start: give the unit(s) with --serial SN (repeatable) or "
                  "--slot SLOT=SN (repeatable), not both"};
  json units = json::array();
  for (const std::string& sn : a.serials) {
    check_serial(sn);
    units.push_back({{"serial", sn}});
  }
  for (const std::string& spec : a.slots) {
    const auto eq = spec.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == spec.size())
      throw Failure{kBadInput, "--slot " + spec + ": expected SLOT=SERIAL (e.g. --slot B=SN-0042)"};
    check_serial(spec.substr(eq + 1));
    units.push_back({{"slot", spec.substr(0, eq)}, {"serial", spec.substr(eq + 1)}});
  }
  return units;
}

int cmd_run_start(const Target& t, const Args& a, bool as_json) {
  const json units = start_units(a);
  json args = json::object();
  if (units.size() == 1 && !units[0].contains("slot"))
    args["serial"] = units[0]["serial"];  // one unit: the request every daemon understands
  else
    args["units"] = units;
  if (!a.sequence.empty()) args["sequence"] = a.sequence;
  if (!a.operator_name.empty()) args["operator"] = a.operator_name;
  ControlClient client = connect_or_fail(t);
  const json r = call(client, station::control::cmd::kRunStart, args);
  std::string what = "started: ";
  std::vector<db::history::RunId> ids;
  if (r.contains("units") && r["units"].is_array()) {
    for (const json& u : r["units"]) {
      what += (ids.empty() ? "" : ", ") + text(u, "serial") + " (slot " + text(u, "slot") +
              ", run " + text(u, "run_id") + ")";
      ids.push_back(u.at("run_id").get<db::history::RunId>());
    }
  } else {
    what += text(r, "serial");
    ids.push_back(r.at("run_id").get<db::history::RunId>());
  }
  if (a.wait && ids.size() > 1) {
    if (!as_json) std::cerr << "table run " << ids.front() << " " << what << "\n";
    return wait_for_runs(t, client, ids, as_json);
  }
  if (a.wait || as_json) return started(t, client, r, what, a.wait, as_json);
  std::cout << "run " << text(r, "run_id", "?") << " " << what << ", sequence "
            << text(r, "sequence", a.sequence)
            << (r.contains("steps") ? ", " + r["steps"].dump() + " steps" : "") << "\n";
  return kOk;
}

int cmd_run_abort(const Target& t, const Args& a, bool as_json) {
  json args = json::object();
  if (!a.reason.empty()) args["reason"] = a.reason;
  ControlClient client = connect_or_fail(t);
  const json r = call(client, station::control::cmd::kRunAbort, args);
  if (as_json)
    print_json(r);
  else if (r.contains("run") && r["run"].is_object())
    std::cout << station::control::outcome_line(r["run"]) << "\n";
  else
    std::cout << "abort requested"
              << (r.contains("run_id") ? " for run " + r["run_id"].dump() : std::string()) << "\n";
  return kOk;
}

int cmd_export_history(const Target& t, const Args& a, bool as_json) {
  json args = {{"format", a.format}};
  if (!a.station.empty()) args["station"] = a.station;
  if (!a.serial.empty()) {
    check_serial(a.serial);
    args["serial"] = a.serial;
  }
  if (!a.since.empty()) {
    try {
      (void)db::history::parse_time_utc(a.since);
    } catch (const db::history::DbError& e) {
      throw Failure{kBadInput, std::string("--since: ") + e.what()};
    }
    args["since"] = a.since;
  }
  return cmd_export(t, args, a.output, as_json);
}

json reprocess_args(db::history::RunId run_id, const Args& a) {
  json args = {{"run_id", run_id}};
  if (a.partial) args["partial"] = true;
  if (a.gravity_mps2) args["gravity_mps2"] = *a.gravity_mps2;
  return args;
}

/// The command that reprocesses `rest` with the same options: what a stopped batch leaves to do.
std::string reprocess_command(const std::vector<db::history::RunId>& rest, const Args& a) {
  std::string cmd = "stationctl reprocess";
  for (const db::history::RunId id : rest) cmd += " " + std::to_string(id);
  if (a.partial) cmd += " --partial";
  if (a.gravity_mps2) {
    char g[32];
    std::snprintf(g, sizeof g, "%.10g", *a.gravity_mps2);
    cmd += std::string(" --gravity-mps2 ") + g;
  }
  return cmd;
}

/// Several runs (a flagged station's, issue #25): the daemon calibrates one at a time, so each is
/// started once the one before has ended. One line per run, old -> new and its outcome; a refusal
/// or an interruption stops the batch and says which runs are left, with the command that goes on.
/// Exit code: 0 only when every new run is done + PASS.
int reprocess_batch(const Target& t, const Args& a, bool as_json) {
  std::set<db::history::RunId> seen;
  for (const db::history::RunId id : a.run_ids)
    if (!seen.insert(id).second)
      throw Failure{kBadInput, "reprocess: run " + std::to_string(id) + " is given twice"};
  ControlClient client = connect_or_fail(t);
  json done = json::array();
  int code = kOk;
  for (std::size_t i = 0; i < a.run_ids.size(); ++i) {
    const db::history::RunId old_id = a.run_ids[i];
    const std::vector<db::history::RunId> rest(a.run_ids.begin() + static_cast<std::ptrdiff_t>(i),
                                      a.run_ids.end());
    const std::string left = " (reprocessed " + std::to_string(i) + " of " +
                             std::to_string(a.run_ids.size()) +
                             "; to go on: " + reprocess_command(rest, a) + ")";
    json r;
    try {
      r = call(client, station::control::cmd::kReprocess, reprocess_args(old_id, a));
    } catch (Failure& f) {
      f.message = "run " + std::to_string(old_id) + ": " + f.message + left;
      throw;
    }
    if (!as_json)
      std::cerr << "[" << i + 1 << "/" << a.run_ids.size() << "] run " << old_id
                << " reprocessing as run " << text(r, "run_id", "?") << "\n";
    json run;
    const int c = wait_for_run(t, client, r.at("run_id").get<db::history::RunId>(), as_json, &run);
    if (c == kInterrupted) {
      std::cerr << "stationctl: the batch stopped" << left << "\n";
      return c;
    }
    if (c != kOk) code = c;
    done.push_back({{"reprocessed", old_id}, {"run", run}});
    if (!as_json)
      std::cout << "run " << old_id << " -> " << station::control::outcome_line(run) << "\n" << std::flush;
  }
  if (as_json)
    print_json(json{{"runs", done}});
  else if (a.gravity_mps2)
    std::cerr << "the new runs become their units' active parameters only once QA promotes them "
                 "(stationctl promote RUN_ID --reason TEXT)\n";
  return code;
}

int cmd_reprocess(const Target& t, const Args& a, bool as_json) {
  if (a.run_ids.size() > 1) return reprocess_batch(t, a, as_json);
  const db::history::RunId run_id = a.run_ids.at(0);
  ControlClient client = connect_or_fail(t);
  const json r = call(client, station::control::cmd::kReprocess, reprocess_args(run_id, a));
  return started(t, client, r, "reprocesses run " + std::to_string(run_id), a.wait, as_json);
}

/// --report OUTDIR must be a directory or not exist yet (checked before the daemon works).
void check_report_dir(const std::string& dir) {
  std::error_code ec;
  if (!dir.empty() && std::filesystem::exists(dir, ec) && !std::filesystem::is_directory(dir, ec))
    throw Failure{kBadInput, "--report " + dir + ": exists and is not a directory"};
}

/// `stationctl diagnose RUN_ID [--report OUTDIR]`: the daemon diagnoses (and stores the summary);
/// the report is written here, the same page as imucal diagnose's; exit 3 when unexplained.
int cmd_diagnose(const Target& t, const Args& a, bool as_json) {
  check_report_dir(a.report_dir);
  ControlClient client = connect_or_fail(t);
  const json d = call(client, station::control::cmd::kDiagnose, {{"run_id", a.run_id}});
  if (!a.report_dir.empty()) {
    std::error_code ec;
    std::filesystem::create_directories(a.report_dir, ec);
    if (ec) throw Failure{kUnavailable, "--report " + a.report_dir + ": " + ec.message()};
    try {
      db::archive::write_file_atomic(a.report_dir + "/diagnosis.json", d.dump(2) + "\n");
      db::archive::write_file_atomic(a.report_dir + "/report.html", tools::report::diagnosis_report_html(d));
    } catch (const std::exception& e) {
      throw Failure{kUnavailable, std::string("--report: ") + e.what()};
    }
  }
  print_result(d, as_json, station::control::render_diagnosis_text);
  return d.value("verdict", "") == "unexplained" ? kGapUnexplained : kOk;
}

/// `stationctl --fleet URL stations`: the stations with runs in the fleet store.
int cmd_stations(const Target& t, bool as_json) {
  if (t.fleet_url.empty())
    throw Failure{kBadInput, "stations: give the fleet store with --fleet URL"};
  const auto repo = open_fleet(t);
  json list = json::array();
  try {
    for (const auto& [id, runs] : repo->stations())
      list.push_back({{"station", id}, {"runs", runs}});
  } catch (const db::history::DbError& e) {
    throw Failure{exit_for_db_error(e.kind()), e.what()};
  }
  if (as_json) {
    print_json({{"stations", list}});
  } else {
    for (const json& s : list)
      std::cout << text(s, "station") << "  " << text(s, "runs") << " runs\n";
    if (list.empty()) std::cout << "no station has stored runs in the fleet store\n";
  }
  return kOk;
}

/// `stations --signatures --trend`: the signatures period by period; exit 1 if a station is
/// flagged in the newest period (an old flag is history).
int signature_trend(const db::history::Repository& repo, const db::history::FleetStats& stats, const Args& a,
                    const calib::studies::fleet::SignatureOptions& options, bool as_json) {
  const db::history::FleetFilter window =
      tools::report::signature_window(repo, a.since, a.until, 12 * a.period_days);
  json trend = tools::report::station_signature_trend(
      stats, window, a.period_days, options,
      [](const std::string& line) { std::cerr << line << "...\n"; });
  bool flagged_now = false;
  if (!trend["periods"].empty())
    for (const json& st : trend["periods"].back()["stations"])
      flagged_now = flagged_now || st.value("flagged", false);
  if (as_json)
    print_json(trend);
  else
    std::cout << tools::report::render_signature_trend_text(trend);
  return flagged_now ? kRunNotPassed : kOk;
}

/// `stationctl [--fleet URL | --db FILE] stations --signatures`: station signatures (issue #25).
int cmd_station_signatures(const Target& t, const Args& a, bool as_json) {
  if (t.fleet_url.empty() && t.db.empty())
    throw Failure{kBadInput, "stations --signatures: give the fleet store (--fleet URL) or --db"};
  try {
    std::unique_ptr<db::history::Repository> repo;
    std::unique_ptr<db::history::FleetStats> stats;
    if (!t.fleet_url.empty()) {
      const auto target = db::fleet::parse_fleet_target(t.fleet_url, t.fleet_password);
      repo = std::make_unique<db::fleet::FleetRepository>(target);
      stats = std::make_unique<db::fleet::PgFleetStats>(target);
    } else {
      db::history::SqliteOptions ro;
      ro.read_only = true;
      repo = std::make_unique<db::history::SqliteRepository>(t.db, ro);
      stats = std::make_unique<db::history::SqliteFleetStats>(t.db);
    }
    calib::studies::fleet::SignatureOptions options;
    options.false_alarm = a.false_alarm;
    if (a.trend) return signature_trend(*repo, *stats, a, options, as_json);
    const db::history::FleetFilter window = tools::report::signature_window(*repo, a.since, a.until);
    json report = tools::report::station_signature_report(
        *stats, window, options, [](const std::string& line) { std::cerr << line << "...\n"; });
    report["since"] = window.since_ms ? db::history::format_time_utc(*window.since_ms) : "";
    report["until"] = window.until_ms ? db::history::format_time_utc(*window.until_ms) : "";
    bool flagged = false;
    for (const json& st : report["stations"]) flagged = flagged || st.value("flagged", false);
    if (as_json)
      print_json(report);
    else
      std::cout << "runs started " << text(report, "since") << " until " << text(report, "until")
                << "\n"
                << tools::report::render_signatures_text(report);
    return flagged ? kRunNotPassed : kOk;
  } catch (const tools::report::WindowError& e) {
    throw Failure{kBadInput, std::string("stations --signatures: ") + e.what()};
  } catch (const db::history::DbError& e) {
    throw Failure{exit_for_db_error(e.kind()), e.what()};
  }
}

/// `stationctl fleet resync`: the station's share of the fleet store made equal to its SQLite.
int cmd_fleet_resync(const Target& t, const std::string& station_id_option, bool as_json) {
  if (t.db.empty()) throw Failure{kBadInput, "fleet resync: no database (give --config or --db)"};
  if (t.fleet_url.empty() && !t.fleet_config)
    throw Failure{kBadInput,
                  "fleet resync: the config names no [fleet] store (or give --fleet URL)"};
  const std::string station_id = !station_id_option.empty() ? station_id_option
                                 : t.fleet_config
                                     ? t.fleet_config->station_id
                                     : throw Failure{kBadInput, "fleet resync: give --station-id"};
  try {
    const db::fleet::FleetTarget target =
        t.fleet_url.empty() ? station::daemon::fleet_target(*t.fleet_config)
                            : db::fleet::parse_fleet_target(t.fleet_url, t.fleet_password);
    db::history::SqliteOptions ro;
    ro.read_only = true;
    const db::history::SqliteRepository local(t.db, ro);
    db::fleet::PgConnection conn(target);
    db::fleet::migrate_fleet(conn);
    // The mark before the read: a run the sender delivers meanwhile is never set apart.
    const db::fleet::ResyncMark mark = db::fleet::begin_resync(conn, station_id);
    std::vector<db::history::RunId> ids;
    std::vector<std::string> uuids;
    for (const db::history::RunRecord& r : local.recent_runs(0)) {
      ids.push_back(r.run_id);
      uuids.push_back(r.uuid);
    }
    std::sort(ids.begin(), ids.end());
    // First set apart what the store holds and this database does not (a replaced database
    // reuses their local ids), then store every run of this one.
    const std::size_t apart = db::fleet::set_apart_runs_not_in(conn, station_id, uuids, mark);
    db::fleet::UpsertCount n;
    constexpr std::size_t kChunk = 500;
    for (std::size_t i = 0; i < ids.size(); i += kChunk) {
      const std::vector<db::history::RunId> chunk(ids.begin() + i,
                                         ids.begin() + std::min(ids.size(), i + kChunk));
      const auto runs = local.details_of(chunk);
      const auto c = db::fleet::upsert_runs(conn, station_id, runs);
      n.written += c.written;
      n.unchanged += c.unchanged;
      if (!as_json && isatty(STDERR_FILENO))
        std::cerr << "\rresync " << std::min(ids.size(), i + kChunk) << "/" << ids.size() << " runs"
                  << std::flush;
    }
    if (!as_json && isatty(STDERR_FILENO)) std::cerr << "\n";
    const json r = {{"station_id", station_id},
                    {"fleet", target.redacted()},
                    {"runs", ids.size()},
                    {"written", n.written},
                    {"unchanged", n.unchanged},
                    {"set_apart", apart},
                    {"set_apart_as", apart > 0 ? mark.apart_id : std::string()}};
    if (as_json) {
      print_json(r);
    } else {
      std::cout << "fleet store " << target.redacted() << ": station " << station_id
                << " resynced: " << ids.size() << " runs (" << n.written << " written, "
                << n.unchanged << " already there)\n";
      if (apart > 0)
        std::cout << apart << " runs the store held and this database does not (a replaced or "
                  << "restored database) were set apart, kept, as station " << mark.apart_id
                  << "\n";
    }
    return kOk;
  } catch (const db::history::DbError& e) {
    throw Failure{exit_for_db_error(e.kind()), e.what()};
  }
}

/// The command given, run.
int dispatch(const Target& t, const Args& a, const Commands& c, bool as_json) {
  if (*c.start) return cmd_run_start(t, a, as_json);
  if (*c.status) {
    json args = json::object();
    if (a.run_id > 0) args["run_id"] = a.run_id;
    return print_result(read_request(t, station::control::cmd::kRunStatus, args), as_json,
                        station::control::render_status_text);
  }
  if (*c.abort) return cmd_run_abort(t, a, as_json);
  if (*c.history) {
    json args = json::object();
    if (!a.serial.empty()) {
      check_serial(a.serial);
      args["serial"] = a.serial;
    }
    if (a.limit > 0) args["limit"] = a.limit;
    if (!a.station.empty()) args["station"] = a.station;
    return print_result(read_request(t, station::control::cmd::kHistory, args), as_json,
                        station::control::render_history_text);
  }
  if (*c.show)
    return print_result(read_request(t, station::control::cmd::kShow, {{"run_id", a.run_id}}), as_json,
                        station::control::render_show_text);
  if (*c.params) {
    check_serial(a.serial);
    json params = read_request(t, station::control::cmd::kParams, {{"serial", a.serial}});
    if (a.bare) params.erase("source");
    return print_result(params, as_json, station::control::render_params_text);
  }
  if (*c.exp) return cmd_export_history(t, a, as_json);
  if (*c.reprocess) return cmd_reprocess(t, a, as_json);
  if (*c.diagnose) return cmd_diagnose(t, a, as_json);
  if (*c.import) return cmd_import(t, a.import_dir, a.wait, as_json);
  if (*c.promote) return cmd_promote(t, a.run_id, a.reason, as_json);
  if (*c.stations)
    return a.signatures || a.trend ? cmd_station_signatures(t, a, as_json)
                                   : cmd_stations(t, as_json);
  if (*c.resync) return cmd_fleet_resync(t, a.station, as_json);
  throw Failure{kBadInput, "no command given (see --help)"};
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"stationctl: start and follow calibration runs; query the calibration history"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string(IMUCAL_VERSION));
  Globals g;
  Args a;
  Commands c{};
  add_global_options(app, g);
  add_run_commands(app, a, c);
  add_read_commands(app, a, c);
  add_history_commands(app, a, c);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    app.exit(e);
    return kBadInput;
  }
  try {
    return dispatch(resolve_target(g), a, c, g.json);
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
