#pragma once
// What the control socket (control_server.hpp) asks of the daemon. The server owns the transport
// (Unix socket, JSON lines, peer credentials, permission check, request validation); the daemon
// (daemon.hpp) implements this interface. Reads (history, show, params, export) are answered by the
// server straight from the repository, the same way stationctl answers them from a read-only
// database when the daemon is down (record_json.hpp), so both paths print the same thing.
//
// Every method either returns the JSON "result" object of the reply or throws ControlError, whose
// code is one of the protocol's error codes (control_protocol.hpp) and whose message is the
// one-line text shown to the operator.
#include <cstdint>
#include <nlohmann/json.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "db/history/repository.hpp"

namespace imucal::station::control {

/// Protocol error codes (the "code" of an error reply).
namespace error_code {
inline constexpr const char* kBadRequest = "bad_request";              ///< malformed line / fields
inline constexpr const char* kPermissionDenied = "permission_denied";  ///< not in the control group
inline constexpr const char* kBusy = "busy";                           ///< a run is already active
inline constexpr const char* kNotFound = "not_found";          ///< unknown run / serial / sequence
inline constexpr const char* kInvalidInput = "invalid_input";  ///< e.g. serial breaks the rules
inline constexpr const char* kUnavailable = "unavailable";     ///< hardware not reachable etc.
inline constexpr const char* kInternal = "internal";           ///< a bug: logged with details
}  // namespace error_code

class ControlError : public std::runtime_error {
 public:
  ControlError(std::string code, const std::string& message)
      : std::runtime_error(message), code_(std::move(code)) {}
  const std::string& code() const { return code_; }

 private:
  std::string code_;
};

struct ReprocessRequest {
  db::history::RunId run_id = 0;
  std::string user;            ///< who asked (recorded as the new run's operator)
  bool allow_partial = false;  ///< calibrate an incomplete archive anyway (REVIEW at best)
  /// The site's surveyed gravity to calibrate with instead of the archive's (issue #25: a station
  /// whose signature showed a wrong gravity, corrected), m/s²; the new run's origin says so.
  std::optional<double> gravity_mps2;
};

/// One unit of a table run: the fixture slot it sits in ("" = the next free slot in the
/// configuration's order) and its serial number.
struct UnitRequest {
  std::string slot;
  std::string serial;
};

struct StartRunRequest {
  std::string serial;  ///< one unit, in the first slot (when `units` is empty)
  /// Several units on one table run (issue #23), each its own run, archive and result.
  std::vector<UnitRequest> units;
  std::optional<std::string> sequence;  ///< library name or path; default: the config's
  std::string operator_name;            ///< default: the peer's user name
};

class ControlHandler {
 public:
  virtual ~ControlHandler() = default;
  /// Starts a run; returns {"run_id": N, "serial": ..., "sequence": ..., "steps": N}.
  /// kBusy if a run is active, kInvalidInput for a bad serial, kNotFound for an unknown sequence.
  virtual nlohmann::json start_run(const StartRunRequest& request) = 0;
  /// The daemon's state (see the contract for the fields). With run_id: that run's state, live if
  /// it is the active one, else from the repository (kNotFound if there is no such run).
  virtual nlohmann::json status(std::optional<db::history::RunId> run_id) = 0;
  /// Aborts the active run (table to safe stop, run -> aborted); kNotFound if none is active.
  virtual nlohmann::json abort_run(const std::string& reason) = 0;
  /// Recalibrates a stored run from its archive into a new run; returns {"run_id": new id,
  /// "reprocessed_from": id}. kBusy if a run is active, kNotFound for an unknown run,
  /// kInvalidInput for an incomplete archive (aborted, interrupted, failed capture) unless
  /// allow_partial — then the result is REVIEW at best, never the unit's active parameters.
  virtual nlohmann::json reprocess(const ReprocessRequest& request) = 0;
  /// The sim-to-real gap diagnosis of a finished run (station/run/gap_check.hpp), its summary
  /// stored with the run; returns the full diagnosis JSON plus "run_id". kBusy while a run is
  /// active.
  virtual nlohmann::json diagnose(db::history::RunId run_id) = 0;
  /// Imports a field (or another station's) run archive into the history for its serial and
  /// calibrates it with the setting run.toml names; returns {"run_id", "serial", "setting"}.
  /// kInvalidInput naming the file for a bad archive (nothing stored), kBusy while a run is
  /// active. `user` is recorded as the run's operator.
  virtual nlohmann::json import_archive(const std::string& dir, const std::string& user) {
    (void)dir;
    (void)user;
    throw ControlError(error_code::kInternal, "import is not supported by this handler");
  }
  /// QA's promotion of a field run to the unit's active parameters
  /// (db::history::Repository::promote), recorded with `user`; returns {"run_id", "promoted_by",
  /// "promoted_at"}.
  virtual nlohmann::json promote(db::history::RunId run_id, const std::string& user,
                                 const std::string& reason) {
    (void)run_id;
    (void)user;
    (void)reason;
    throw ControlError(error_code::kInternal, "promote is not supported by this handler");
  }
  /// The repository reads are served from.
  virtual const db::history::Repository& repository() const = 0;
};

}  // namespace imucal::station::control
