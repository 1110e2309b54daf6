#include "station/daemon/daemon.hpp"

#include <fcntl.h>
#include <signal.h>
#include <spdlog/spdlog.h>
#include <sys/file.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <thread>

#include "sequences/library.hpp"
#include "station/control/control_server.hpp"

namespace imucal::station::daemon {
using namespace station::config;
using namespace station::control;
using namespace station::run;

namespace fs = std::filesystem;

Daemon::Daemon(StationConfig config, DaemonOptions options)
    : cfg_(std::move(config)), opt_(std::move(options)) {}

Daemon::~Daemon() {
  try {
    stop("daemon shutting down");
  } catch (const std::exception& e) {
    spdlog::error("shutdown: {}", e.what());
  }
  release_lock();
}

namespace {

void make_dir(const fs::path& p, const char* what) {
  if (p.empty()) return;
  std::error_code ec;
  fs::create_directories(p, ec);
  if (ec)
    throw std::runtime_error("cannot create the " + std::string(what) + " " + p.string() + ": " +
                             ec.message());
}

std::string duration_text(double s) {
  const long total = std::lround(std::max(0.0, s));
  if (total < 60) return std::to_string(total) + " s";
  if (total < 3600) return std::to_string(total / 60) + " min " + std::to_string(total % 60) + " s";
  return std::to_string(total / 3600) + " h " + std::to_string((total % 3600) / 60) + " min";
}

}  // namespace

void Daemon::start() {
  std::lock_guard<std::mutex> lk(lifecycle_mu_);
  if (started_ok_) return;
  spdlog::info("stationd {} starting: station {}, config {}", opt_.version, cfg_.station_name,
               cfg_.source_path);
  if (!cfg_.sequence_dir.empty()) sequences::set_sequence_dir(cfg_.sequence_dir);
  spdlog::info("sequence library {}", sequences::sequence_dir());
  make_dir(cfg_.data_dir, "data directory");
  make_dir(fs::path(cfg_.data_dir) / "runs", "run archive directory");
  make_dir(fs::path(cfg_.database).parent_path(), "database directory");
  make_dir(fs::path(cfg_.control_socket).parent_path(), "control socket directory");

  // One daemon per data directory: a second one (started by mistake on the same config) must not
  // run start-up recovery, which would stop the first one's table and mark its run interrupted.
  // flock is released by the kernel when the holder dies, even by SIGKILL.
  const std::string lock_path = (fs::path(cfg_.data_dir) / "stationd.lock").string();
  lock_fd_ = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
  if (lock_fd_ < 0)
    throw std::runtime_error("cannot open " + lock_path + ": " + std::strerror(errno));
  if (::flock(lock_fd_, LOCK_EX | LOCK_NB) != 0) {
    const int err = errno;
    char buf[32] = {};
    const ssize_t n = ::pread(lock_fd_, buf, sizeof buf - 1, 0);
    ::close(lock_fd_);
    lock_fd_ = -1;
    std::string holder = n > 0 ? std::string(buf, static_cast<size_t>(n)) : std::string("?");
    while (!holder.empty() && (holder.back() == '\n' || holder.back() == ' ')) holder.pop_back();
    throw std::runtime_error(err == EWOULDBLOCK
                                 ? "another stationd (pid " + holder + ") is running on " +
                                       cfg_.data_dir + " (lock " + lock_path + ")"
                                 : "cannot lock " + lock_path + ": " + std::strerror(err));
  }
  const std::string pid_text = std::to_string(getpid()) + "\n";
  if (::ftruncate(lock_fd_, 0) != 0 ||
      ::pwrite(lock_fd_, pid_text.data(), pid_text.size(), 0) < 0) {
    spdlog::warn("cannot write the pid into {}: {}", lock_path, std::strerror(errno));
  }

  repo_ = std::make_unique<db::history::SqliteRepository>(cfg_.database);
  spdlog::info("history database {}", cfg_.database);
  recovery_ = recover_at_startup(cfg_, *repo_, opt_.stop_table_at_start);
  continue_run_ids_after_archives(cfg_, *repo_);
  if (!recovery_.runs.empty()) {
    spdlog::warn("recovery: {} run(s) ended at start-up", recovery_.runs.size());
  }

  if (cfg_.fleet) {
    // The line never waits for the fleet store: the sender only reads what SQLite committed.
    fleet_ = std::make_unique<FleetSender>(cfg_.database, *cfg_.fleet);
    spdlog::info("fleet store {} as station {}: outbox {} entries", fleet_->status().url,
                 cfg_.fleet->station_id, fleet_->status().outbox_length);
  } else {
    repo_->set_outbox_enabled(false);
  }

  // The units of one table run calibrate in parallel, as many at once as there are cores.
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  worker_ = std::make_unique<CalibrationWorker>(
      *repo_, CalibrationWorker::Phase{}, std::min(cores, static_cast<unsigned>(cfg_.imus.size())));
  controller_ = std::make_unique<RunController>(cfg_, *repo_, *worker_, opt_.version);
  ControlServerOptions so;
  so.socket_path = cfg_.control_socket;
  so.database_path = cfg_.database;  // streamed exports read it on connections of their own
  so.group = cfg_.control_group;
  so.socket_mode = cfg_.control_socket_mode;
  so.idle_timeout =
      std::chrono::milliseconds(static_cast<int64_t>(cfg_.control_idle_timeout_s * 1000));
  so.max_clients_per_user = cfg_.control_max_connections_per_user;
  so.version = opt_.version;
  server_ = std::make_unique<ControlServer>(*this, so);
  try {
    server_->start();
  } catch (...) {
    server_.reset();
    controller_.reset();
    worker_.reset();
    fleet_.reset();
    repo_.reset();
    release_lock();
    throw;
  }
  started_ok_ = true;
  opt_.notifier.ready(status_line());
}

void Daemon::stop(const std::string& reason) {
  std::lock_guard<std::mutex> lk(lifecycle_mu_);
  if (!started_ok_ || stopped_) return;
  stopped_ = true;
  opt_.notifier.stopping();
  spdlog::info("stationd stopping: {}", reason);
  // The control socket stays up while the run is being aborted, so clients see it end.
  if (controller_) controller_->shutdown(reason);
  if (server_) server_->stop();
  if (worker_) worker_->stop();
  controller_.reset();
  server_.reset();
  worker_.reset();
  if (fleet_) {
    // A moment for the last run to reach the fleet store; whatever is left waits in the outbox
    // for the next start.
    if (!fleet_->wait_until_drained(std::chrono::seconds(2)))
      spdlog::info("fleet store: {} outbox entries wait for the next start",
                   fleet_->status().outbox_length);
    fleet_.reset();
  }
  repo_.reset();
  release_lock();
  spdlog::info("stationd stopped");
}

void Daemon::release_lock() {
  if (lock_fd_ >= 0) {
    ::close(lock_fd_);  // releases the flock; the file stays (harmless, reused next time)
    lock_fd_ = -1;
  }
}

void Daemon::request_stop() { stop_requested_.store(true); }

int Daemon::run() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGINT);
  // Blocked here, inherited by every thread started below: the signals are only ever taken by
  // sigtimedwait in this loop, never delivered to a thread in the middle of a Modbus transaction.
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
  start();

  const auto wd = opt_.notifier.watchdog_interval();
  const auto tick = std::chrono::milliseconds(
      wd ? std::clamp<long long>(std::chrono::duration_cast<std::chrono::milliseconds>(*wd).count(),
                                 10, 1000)
         : 1000);
  auto next_watchdog = std::chrono::steady_clock::now();
  std::string last_status;
  // The words db::history::stopped_by_daemon() reads back (a run this stop aborts is not an
  // operator's abort: issue #52).
  std::string stop_reason = db::history::kDaemonStopReasons[2];
  while (!stop_requested_.load()) {
    if (wd && std::chrono::steady_clock::now() >= next_watchdog) {
      // The loop is alive and the run controller answers (status_line takes its lock).
      opt_.notifier.watchdog();
      next_watchdog = std::chrono::steady_clock::now() + *wd;
    }
    const std::string line = status_line();
    if (line != last_status) {
      opt_.notifier.status(line);
      last_status = line;
    }
    timespec ts{};
    const auto wait = std::min<long long>(tick.count(), 250);
    ts.tv_sec = wait / 1000;
    ts.tv_nsec = (wait % 1000) * 1000000L;
    const int sig = sigtimedwait(&set, nullptr, &ts);
    if (sig == SIGTERM || sig == SIGINT) {
      stop_reason = db::history::kDaemonStopReasons[sig == SIGTERM ? 0 : 1];
      spdlog::info("{} received", sig == SIGTERM ? "SIGTERM" : "SIGINT");
      break;
    }
    if (sig < 0 && errno != EAGAIN && errno != EINTR) {
      spdlog::error("sigtimedwait: {}", std::strerror(errno));
    }
  }
  stop(stop_reason);
  return 0;
}

std::string Daemon::status_line() const {
  if (!controller_) return "starting";
  const auto a = controller_->active();
  if (!a) return "idle";
  std::string s = "run " + std::to_string(a->run_id) + " " + a->serial;
  if (!a->siblings.empty())  // a table run of several units: the others by serial
    for (const RunSnapshot& sib : a->siblings) s += ", " + sib.serial;
  s += ": ";
  if (a->state == db::history::RunState::kRunning && a->steps > 0) {
    s += "step " + std::to_string(a->step) + "/" + std::to_string(a->steps) + " ";
  }
  s += a->phase != RunPhase::kNone ? to_string(a->phase) : db::history::to_string(a->state);
  if (a->time_left_s) s += ", " + duration_text(*a->time_left_s) + " left";
  return s;
}

nlohmann::json Daemon::start_run(const StartRunRequest& request) {
  if (!controller_) throw ControlError(error_code::kUnavailable, "the daemon is not running");
  return controller_->start(request);
}

nlohmann::json Daemon::status(std::optional<db::history::RunId> run_id) {
  using nlohmann::json;
  if (!controller_) throw ControlError(error_code::kUnavailable, "the daemon is not running");
  const auto active = controller_->active();
  if (run_id) {
    if (active && active->run_id == *run_id) return {{"run", to_json(*active)}};
    if (active)  // a sibling unit of the live table run: its live snapshot
      for (const RunSnapshot& sib : active->siblings)
        if (sib.run_id == *run_id) return {{"run", to_json(sib)}};
    try {
      return {{"run", to_json(snapshot_from_record(repo_->show(*run_id).run))}};
    } catch (const db::history::NotFound& e) {
      throw ControlError(error_code::kNotFound, e.what());
    }
  }
  const auto last = controller_->last_finished();
  json daemon = {
      {"version", opt_.version},
      {"pid", static_cast<long long>(getpid())},
      {"station", cfg_.station_name},
      {"uptime_s",
       std::chrono::duration<double>(std::chrono::steady_clock::now() - started_).count()}};
  return {{"daemon", daemon},
          {"state", active ? "busy" : "idle"},
          {"run", active ? to_json(*active) : json(nullptr)},
          {"last_run", last ? to_json(*last) : json(nullptr)},
          {"fleet", fleet_ ? fleet_->status().to_json() : json(nullptr)}};
}

nlohmann::json Daemon::abort_run(const std::string& reason) {
  if (!controller_) throw ControlError(error_code::kUnavailable, "the daemon is not running");
  const auto active = controller_->active();
  if (!active || !controller_->abort(reason.empty() ? "aborted by the operator" : reason)) {
    throw ControlError(error_code::kNotFound, "no run is active");
  }
  return {{"run_id", active->run_id}, {"serial", active->serial}, {"aborting", true}};
}

nlohmann::json Daemon::reprocess(const ReprocessRequest& request) {
  if (!controller_) throw ControlError(error_code::kUnavailable, "the daemon is not running");
  return controller_->reprocess(request);
}

nlohmann::json Daemon::diagnose(db::history::RunId run_id) {
  if (!controller_) throw ControlError(error_code::kUnavailable, "the daemon is not running");
  return controller_->diagnose(run_id);
}

nlohmann::json Daemon::import_archive(const std::string& dir, const std::string& user) {
  if (!controller_) throw ControlError(error_code::kUnavailable, "the daemon is not running");
  return controller_->import_archive(dir, user);
}

nlohmann::json Daemon::promote(db::history::RunId run_id, const std::string& user,
                               const std::string& reason) {
  if (!controller_) throw ControlError(error_code::kUnavailable, "the daemon is not running");
  return controller_->promote(run_id, user, reason);
}

const db::history::Repository& Daemon::repository() const {
  if (!repo_) throw ControlError(error_code::kUnavailable, "the daemon is not running");
  return *repo_;
}

}  // namespace imucal::station::daemon
