#include "tools/stationctl/connection.hpp"

#include <chrono>
#include <filesystem>
#include <iostream>

#include "db/history/serial_number.hpp"
#include "db/history/sqlite_repository.hpp"
#include "station/control/record_json.hpp"

namespace imucal::tools::stationctl {

namespace {

using station::control::ControlClientError;

constexpr auto kReplyTimeout = std::chrono::seconds(60);
/// A read the daemon does not answer in this time is read from the database instead.
constexpr auto kReadTimeout = std::chrono::seconds(10);

int exit_for_error_code(const std::string& code) {
  namespace ec = station::control::error_code;
  if (code == ec::kBadRequest || code == ec::kInvalidInput || code == ec::kNotFound)
    return kBadInput;
  if (code == ec::kBusy || code == ec::kPermissionDenied) return kRefused;
  return kUnavailable;
}

/// A read request as the daemon's control server validates it.
station::control::Request validated_read(const std::string& command, const json& args) {
  return station::control::validate_request(json{{"id", 0}, {"cmd", command}, {"args", args}});
}

/// A read of the fleet store (--fleet URL): the same validation and the same answer as the
/// daemon's, over every station's runs.
json fleet_read(const Target& t, const std::string& command, const json& args) {
  if (command == station::control::cmd::kRunStatus)
    throw Failure{kBadInput, "run status needs a station's daemon, not the fleet store"};
  const auto repo = open_fleet(t);
  try {
    return station::control::answer_repository_read(*repo, validated_read(command, args));
  } catch (const station::control::BadRequest& e) {
    throw Failure{kBadInput, e.what()};
  } catch (const db::history::DbError& e) {
    throw Failure{exit_for_db_error(e.kind()), e.what()};
  }
}

/// Why a read goes to the database instead of the daemon.
struct Fallback {
  std::string why;
  /// The daemon is not there or does not answer (not: it refused this user, or is merely busy):
  /// a run the database holds live has nobody running it now.
  bool daemon_silent = false;
};

/// A read answered by the daemon; nullopt (with why it was not) when it is not there or does not
/// answer and there is a database to read instead.
std::optional<json> read_from_daemon(const Target& t, const std::string& command, const json& args,
                                     Fallback& fallback) {
  using Kind = ControlClientError::Kind;
  std::optional<ControlClient> client;
  try {
    client.emplace(t.socket);
  } catch (const ControlClientError& e) {
    if (e.kind() != Kind::kUnreachable && e.kind() != Kind::kNoPermission)
      throw Failure{kUnavailable, e.what()};
    fallback = {e.what(), e.kind() == Kind::kUnreachable};
    return std::nullopt;
  }
  // A daemon that does not answer (busy, or its connections exhausted) is no reason not to read:
  // the database is there.
  try {
    const station::control::Reply r = client->call(command, args, kReadTimeout);
    if (r.ok || r.error_code != station::control::error_code::kUnavailable || t.db.empty())
      return result_or_fail(r);
    fallback = {"stationd: " + r.error_message, false};  // e.g. its connections are exhausted
  } catch (const ControlClientError& e) {
    if (t.db.empty() || (e.kind() != Kind::kTimeout && e.kind() != Kind::kClosed))
      throw Failure{kUnavailable, e.what()};
    fallback = {e.what(), true};
  }
  return std::nullopt;
}

bool is_live_state(const std::string& state) {
  for (const db::history::RunState s : db::history::live_states())
    if (state == db::history::to_string(s)) return true;
  return false;
}

/// Issue #50 item 2: with the daemon gone, the database still says `running` of the run it was
/// running; the note tells a reader that nobody is.
void mark_live_runs_of_silent_daemon(json& result) {
  const auto mark = [](json& run) {
    if (run.is_object() && is_live_state(text(run, "state")))
      run["state_note"] = "daemon not answering";
  };
  if (result.contains("run")) mark(result["run"]);
  if (result.contains("runs") && result["runs"].is_array())
    for (json& run : result["runs"]) mark(run);
}

/// The history database opened read-only; no database (or not a usable one) is a database error,
/// not bad input.
std::unique_ptr<db::history::SqliteRepository> open_read_only(const std::string& path) {
  try {
    db::history::SqliteOptions options;
    options.read_only = true;
    return std::make_unique<db::history::SqliteRepository>(path, options);
  } catch (const db::history::DbError& e) {
    throw Failure{kUnavailable, e.what()};
  }
}

/// `run status --run ID` from the database: the run's state as the daemon would give it.
json run_status_from(const db::history::SqliteRepository& repo,
                     const station::control::Request& request, const std::string& why) {
  if (!request.args.contains("run_id"))
    throw Failure{kUnavailable, why +
                                    " (the status of the daemon needs the daemon; "
                                    "`run status --run ID` reads a run's state from the "
                                    "database)"};
  json run = station::control::run_record_json(
      repo.show(request.args["run_id"].get<db::history::RunId>()).run);
  run["reason"] = run["failure_reason"];
  return json{{"run", run}};
}

/// A read from the database read-only, when and why the daemon did not answer it.
json read_from_database(const Target& t, const std::string& command, const json& args,
                        const Fallback& fallback) {
  announce_database_fallback(t, fallback.why);
  const std::unique_ptr<db::history::SqliteRepository> opened = open_read_only(t.db);
  const db::history::SqliteRepository& repo = *opened;
  try {
    // The same validation and the same answer as the daemon's control server.
    const station::control::Request request = validated_read(command, args);
    json result = command == station::control::cmd::kRunStatus
                      ? run_status_from(repo, request, fallback.why)
                      : station::control::answer_repository_read(repo, request);
    if (fallback.daemon_silent) mark_live_runs_of_silent_daemon(result);
    return result;
  } catch (const station::control::BadRequest& e) {
    throw Failure{kBadInput, e.what()};
  } catch (const db::history::DbError& e) {
    throw Failure{exit_for_db_error(e.kind()), e.what()};
  }
}

}  // namespace

int exit_for_db_error(db::history::DbErrorKind kind) {
  if (kind == db::history::DbErrorKind::kNotFound ||
      kind == db::history::DbErrorKind::kInvalidInput)
    return kBadInput;
  return kUnavailable;
}

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

ControlClient connect_or_fail(const Target& t) {
  try {
    return ControlClient(t.socket);
  } catch (const ControlClientError& e) {
    if (e.kind() == ControlClientError::Kind::kNoPermission) throw Failure{kRefused, e.what()};
    throw Failure{kUnavailable, std::string(e.what()) + " (is stationd running?)"};
  }
}

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

void announce_database_fallback(const Target& t, const std::string& why) {
  if (t.db.empty())
    throw Failure{kUnavailable, why + "; no database to read instead (give --db or --config)"};
  std::cerr << "stationctl: note: " << why << "; reading the database " << t.db
            << " read-only instead\n";
}

std::unique_ptr<db::fleet::FleetRepository> open_fleet(const Target& t) {
  try {
    return std::make_unique<db::fleet::FleetRepository>(
        db::fleet::parse_fleet_target(t.fleet_url, t.fleet_password));
  } catch (const db::history::DbError& e) {
    throw Failure{exit_for_db_error(e.kind()), e.what()};
  }
}

json read_request(const Target& t, const std::string& command, const json& args) {
  if (!t.fleet_url.empty()) return fleet_read(t, command, args);
  Fallback fallback;
  if (std::optional<json> answer = read_from_daemon(t, command, args, fallback)) return *answer;
  return read_from_database(t, command, args, fallback);
}

std::optional<json> run_from_database(const Target& t, db::history::RunId run_id) {
  if (t.db.empty()) return std::nullopt;
  try {
    db::history::SqliteOptions options;
    options.read_only = true;
    const db::history::SqliteRepository repo(t.db, options);
    return station::control::run_record_json(repo.show(run_id).run);
  } catch (const db::history::DbError&) {
    return std::nullopt;  // locked, being recovered, or gone: the caller asks again later
  }
}

std::function<std::string(const std::string&)> text_check(std::size_t max_chars) {
  return [max_chars](const std::string& v) {
    return station::control::text_field_error(v, max_chars);
  };
}

void check_serial(const std::string& serial) {
  if (const auto problem = db::history::serial_problem(serial)) throw Failure{kBadInput, *problem};
}

std::string text(const json& o, const char* key, const std::string& fallback) {
  const auto it = o.find(key);
  if (it == o.end() || it->is_null()) return fallback;
  return it->is_string() ? it->get<std::string>() : it->dump();
}

void print_json(const json& j) {
  std::cout << j.dump(2, ' ', false, json::error_handler_t::replace) << "\n";
}

int print_result(const json& r, bool as_json, std::string (*render)(const json&)) {
  if (as_json)
    print_json(r);
  else
    std::cout << render(r);
  return kOk;
}

}  // namespace imucal::tools::stationctl
