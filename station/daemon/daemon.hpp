#pragma once
// stationd as an object: everything the process owns, in start-up order, and the ControlHandler the
// control socket calls (station/control/control_handler.hpp).
//
//   start():  data directories -> lock <data_dir>/stationd.lock (one daemon per data directory)
//             -> history database (db::history::SqliteRepository) -> start-up recovery
//             (recovery.hpp: table safe stop, live runs -> interrupted) -> calibration worker ->
//             run controller -> control socket listening -> sd_notify READY=1 + STATUS=
//   run():    start(), then the main loop: SIGTERM/SIGINT (blocked in every thread, taken with
//             sigtimedwait here), WATCHDOG=1 every half $WATCHDOG_USEC, STATUS= on every change of
//             the run's progress; on a signal or request_stop(): stop(), return 0
//   stop():   STOPPING=1 -> the active run is aborted (table safe stop, run aborted, archive
//             finished) and waited for -> control socket closed -> worker joined
//
// Status JSON (status()): {"daemon": {"version", "pid", "station", "uptime_s"}, "state": "idle" |
// "busy", "run": RunSnapshot JSON | null, "last_run": the last run this daemon ended | null,
// "fleet": FleetSenderStatus JSON (outbox length, last error, ...) | null without [fleet]}.
#include <atomic>
#include <chrono>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>

#include "db/history/sqlite_repository.hpp"
#include "station/config/config.hpp"
#include "station/control/control_handler.hpp"
#include "station/daemon/fleet_sender.hpp"
#include "station/daemon/sd_notify.hpp"
#include "station/run/calibration_worker.hpp"
#include "station/run/recovery.hpp"
#include "station/run/run_controller.hpp"

namespace imucal::station::control {
class ControlServer;
}

namespace imucal::station::daemon {
using namespace station::config;
using namespace station::control;
using namespace station::run;

struct DaemonOptions {
  SdNotifier notifier;              ///< systemd notifications (default: none)
  bool stop_table_at_start = true;  ///< recovery's safe stop (tests without a table turn it off)
  std::string version = IMUCAL_VERSION;
};

class Daemon final : public ControlHandler {
 public:
  Daemon(StationConfig config, DaemonOptions options);
  ~Daemon() override;  ///< stop("daemon shutting down")
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;

  /// Everything up to READY=1. Throws std::runtime_error (database, socket, directories) naming
  /// the path; what was started is stopped again.
  void start();
  /// Orderly shutdown (see the file comment). Idempotent.
  void stop(const std::string& reason);
  /// start() + main loop until SIGTERM/SIGINT or request_stop(); returns the exit code (0). Blocks
  /// SIGTERM and SIGINT in the calling thread before any other thread exists, so call it from the
  /// main thread before creating threads.
  int run();
  /// Thread-safe: makes run() return (after stop()).
  void request_stop();

  // ControlHandler
  nlohmann::json start_run(const StartRunRequest& request) override;
  nlohmann::json status(std::optional<db::history::RunId> run_id) override;
  nlohmann::json abort_run(const std::string& reason) override;
  nlohmann::json reprocess(const ReprocessRequest& request) override;
  nlohmann::json diagnose(db::history::RunId run_id) override;
  nlohmann::json import_archive(const std::string& dir, const std::string& user) override;
  nlohmann::json promote(db::history::RunId run_id, const std::string& user,
                         const std::string& reason) override;
  const db::history::Repository& repository() const override;

  const RecoveryReport& recovery() const { return recovery_; }
  const StationConfig& config() const { return cfg_; }
  RunController& controller() { return *controller_; }
  /// One-line STATUS= text ("idle", "run 3 SIM-0001: step 4/27 resting, 1 min 10 s left", ...).
  std::string status_line() const;

 private:
  StationConfig cfg_;
  DaemonOptions opt_;
  std::chrono::steady_clock::time_point started_ = std::chrono::steady_clock::now();
  std::unique_ptr<db::history::SqliteRepository> repo_;
  std::unique_ptr<FleetSender> fleet_;  ///< [fleet] named: the outbox sender; otherwise none
  std::unique_ptr<CalibrationWorker> worker_;
  std::unique_ptr<RunController> controller_;
  std::unique_ptr<ControlServer> server_;
  RecoveryReport recovery_;
  int lock_fd_ = -1;  ///< flock'd <data_dir>/stationd.lock: one daemon per data directory
  void release_lock();
  std::mutex lifecycle_mu_;
  bool started_ok_ = false;
  bool stopped_ = false;
  std::atomic<bool> stop_requested_{false};
};

}  // namespace imucal::station::daemon
