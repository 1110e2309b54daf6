#pragma once
// What stationctl's commands share: the exit codes and the Failure that carries one to main; where
// the station is (the global options resolved into a Target); the control socket to stationd and,
// for reads, the history database read-only when the daemon cannot be reached or the fleet store
// with --fleet (the same answers either way, station/control/record_json.hpp); the checks made
// before connecting; printing a result as text or JSON.
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "db/fleet/fleet_repository.hpp"
#include "db/history/repository.hpp"
#include "station/config/config.hpp"
#include "station/control/control_client.hpp"
#include "station/control/control_protocol.hpp"

namespace imucal::tools::stationctl {

using nlohmann::json;
using station::control::ControlClient;

/// stationctl's exit codes (main.cpp's header says what each means). kRunInterrupted: a run
/// followed with --wait ended interrupted — its daemon stopped during it and start-up recovery
/// (station/run/recovery.hpp) marked it so; the unit is not to blame, the run may be reprocessed.
enum Exit : int {
  kOk = 0,
  kRunNotPassed = 1,
  kBadInput = 2,
  kRefused = 3,
  kUnavailable = 4,
  kRunInterrupted = 5
};
/// Exit code when the operator stops following a run with Ctrl-C (128 + SIGINT, the shell's).
constexpr int kStoppedFollowing = 130;

/// A failure with its exit code; main prints "stationctl: <message>" and exits with the code.
struct Failure {
  int code;
  std::string message;
};

/// The exit code of a database error: not found or invalid input is bad input.
int exit_for_db_error(db::history::DbErrorKind kind);

/// Where stationd looks when no config is given (the systemd unit,
/// station/daemon/stationd.service.in, passes this file).
constexpr const char* kDefaultConfig = "/etc/imucal/stationd.toml";
constexpr const char* kDefaultSocket = "/run/imucal/stationd.sock";

/// The global options, as given.
struct Globals {
  std::string config;
  std::string socket;
  std::string db;
  std::string fleet;                ///< --fleet URL: read the fleet store instead
  std::string fleet_password_file;  ///< its password (else libpq's PGPASSWORD / ~/.pgpass)
  bool json = false;
};

/// The station the commands talk to, from the global options and the config.
struct Target {
  std::string socket;
  std::string db;  ///< "" = none known
  std::string config_used;
  std::string fleet_url;  ///< --fleet: reads go to the fleet store (no daemon, no SQLite)
  std::string fleet_password;
  std::optional<station::config::FleetConfig>
      fleet_config;  ///< the config's [fleet], for `fleet resync`
};

/// The target of the global options: the config's socket and database unless given, the fleet
/// store's URL checked. Throws Failure.
Target resolve_target(const Globals& g);

/// The result of an ok reply; an error reply becomes a Failure with the reply's message.
json result_or_fail(const station::control::Reply& r);

/// A control command's reply (its result); any failure as a Failure.
json call(ControlClient& client, const std::string& command, const json& args);

/// For control commands: the daemon must be there.
ControlClient connect_or_fail(const Target& t);

/// For reads: a connection to the daemon, or none (with `why`) when it is not there or the socket
/// admits only the control group, so that the database is read instead.
std::optional<ControlClient> connect_for_read(const Target& t, std::string& why);

/// Before the database is read instead of the daemon (`why` it is): a Failure if there is none,
/// else the note on stderr that says so.
void announce_database_fallback(const Target& t, const std::string& why);

/// The fleet store's read side (db/fleet/fleet_repository.hpp); its errors as stationctl's.
std::unique_ptr<db::fleet::FleetRepository> open_fleet(const Target& t);

/// A read: over the socket, or from the database read-only when the daemon is unreachable, or
/// from the fleet store with --fleet. Read from the database because the daemon does not answer,
/// a run the database still holds live (preparing, running, calibrating) carries
/// "state_note": "daemon not answering": nobody is running it now.
json read_request(const Target& t, const std::string& command, const json& args);

/// One run as the database holds it (run_record_json), read quietly (no fallback note): nullopt
/// when there is no database or it cannot be read now. For a follower whose daemon went away.
std::optional<json> run_from_database(const Target& t, db::history::RunId run_id);

/// The daemon's own rule for names and reasons (station/control/control_protocol.hpp), checked
/// before connecting so that the operator sees the problem at once.
std::function<std::string(const std::string&)> text_check(std::size_t max_chars);

/// A serial number the history would refuse, refused here (bad input).
void check_serial(const std::string& serial);

/// A member as text: strings as they are, other values as JSON, absent or null as `fallback`.
std::string text(const json& o, const char* key, const std::string& fallback = "");

void print_json(const json& j);

/// A result as JSON, or as the text `render` makes of it.
int print_result(const json& r, bool as_json, std::string (*render)(const json&));

}  // namespace imucal::tools::stationctl
