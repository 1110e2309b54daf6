#pragma once
// End-to-end harness for the station (issue #3, "What it must show"): real processes on loopback.
//
//   stationsim  --modbus 127.P1.P0.N:0 --can <tmp>/bus.sock --ready-file --truth-out --speed 200
//   stationd    --config <tmp>/stationd.toml      (every path of the config inside <tmp>)
//   stationctl  --config <tmp>/stationd.toml ...  (exit code, stdout, stderr captured)
//
// Every test gets its own temporary directory, its own loopback address (so a Modbus port freed by
// one test can never be reached by another test's daemon, see
// tests/drivers/turntable_client_test.cpp) and its own processes. Processes are children of the
// test (fork/exec, stdout/stderr to files in the temporary directory) and are always stopped by the
// destructors (SIGTERM, then SIGKILL), so a failing assertion never leaves a daemon behind. Set
// IMUCAL_E2E_KEEP=1 to keep the directories (their paths are printed) for post-mortems; a failing
// test keeps its own unless IMUCAL_E2E_KEEP=0. IMUCAL_E2E_PROTOCOL=FILE runs the simulator and the
// daemon of every test that does not choose one on that IMU protocol file (issue #27; its
// resolution must suit the default navigation-grade unit: drivers/imu/PROTOCOL.md).
//
// Binaries come from IMUCAL_BIN_DIR (the build tree's bin/). A missing binary is a test failure,
// never a skip.
#include <fcntl.h>
#include <grp.h>
#include <gtest/gtest.h>
#include <sched.h>
#include <signal.h>
#include <sys/prctl.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/types.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <regex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "calib/core/earth.hpp"
#include "calib/core/site_presets.hpp"
#include "db/archive/run_archive.hpp"
#include "db/history/repository.hpp"
#include "db/history/sqlite_repository.hpp"

#ifndef IMUCAL_BIN_DIR
#error "IMUCAL_BIN_DIR must name the build tree's bin directory"
#endif

namespace imucal::e2e {

namespace fs = std::filesystem;
using json = nlohmann::json;
using Clock = std::chrono::steady_clock;
using namespace std::chrono_literals;

inline std::string bin(const std::string& name) { return std::string(IMUCAL_BIN_DIR) + "/" + name; }

inline std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

inline void write_text(const std::string& path, const std::string& text) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  if (!out) throw std::runtime_error("cannot write " + path);
  out << text;
  if (!out) throw std::runtime_error("cannot write " + path);
}

inline std::string shell_quote(const std::vector<std::string>& argv) {
  std::string s;
  for (const auto& a : argv) {
    if (!s.empty()) s += ' ';
    if (a.find_first_of(" \t\"'\\$") == std::string::npos && !a.empty()) {
      s += a;
    } else {
      s += '\'';
      for (char c : a) s += (c == '\'') ? std::string("'\\''") : std::string(1, c);
      s += '\'';
    }
  }
  return s;
}

/// A loopback address (Linux routes all of 127/8 to lo) of this test process alone: 127.P1.P0.N from
/// the pid's low 16 bits and a per-process counter (N never 0 or 255).
inline std::string loopback_address() {
  static int counter = 0;
  const unsigned pid = static_cast<unsigned>(getpid());
  counter = counter % 254 + 1;
  return "127." + std::to_string((pid >> 8) & 0xffu) + "." + std::to_string(pid & 0xffu) + "." +
         std::to_string(counter);
}

/// A fresh directory under $TMPDIR (or /tmp), removed with everything in it unless IMUCAL_E2E_KEEP.
/// Short paths on purpose: Unix socket paths are limited to 107 bytes.
class TempDir {
 public:
  TempDir() {
    const char* base = std::getenv("TMPDIR");
    std::string templ = std::string(base && *base ? base : "/tmp") + "/imucal-e2e-XXXXXX";
    std::vector<char> buf(templ.begin(), templ.end());
    buf.push_back('\0');
    if (!mkdtemp(buf.data())) throw std::runtime_error("mkdtemp " + templ + ": " + std::strerror(errno));
    path_ = buf.data();
    // Other users (the QA-user test runs stationctl as nobody) must reach the config and socket.
    ::chmod(path_.c_str(), 0755);
  }
  ~TempDir() {
    const char* keep = std::getenv("IMUCAL_E2E_KEEP");
    if (keep && *keep && std::string(keep) != "0") {
      std::fprintf(stderr, "[e2e] kept %s\n", path_.c_str());
      return;
    }
    // A failing test keeps its run archives, logs and database for the post-mortem (issue #28);
    // IMUCAL_E2E_KEEP=0 removes them all the same.
    if (!keep && ::testing::Test::HasFailure()) {
      std::fprintf(stderr, "[e2e] the test failed: kept %s (IMUCAL_E2E_KEEP=0 removes it)\n",
                   path_.c_str());
      return;
    }
    std::error_code ec;
    fs::remove_all(path_, ec);
  }
  TempDir(const TempDir&) = delete;
  TempDir& operator=(const TempDir&) = delete;
  const std::string& path() const { return path_; }
  std::string operator/(const std::string& name) const { return path_ + "/" + name; }

 private:
  std::string path_;
};

/// Identity to drop to in the child before exec (QA-user test). Root only.
struct RunAs {
  uid_t uid;
  gid_t gid;
};

struct SpawnOptions {
  std::string stdout_path = "/dev/null";
  std::string stderr_path = "/dev/null";
  std::optional<RunAs> run_as;
  std::vector<std::pair<std::string, std::string>> env;  ///< set in the child
  std::vector<std::string> unset_env;                    ///< removed in the child
  std::optional<int> cpu;                                ///< pin the child to this CPU
};

/// One child process. The destructor stops it (SIGTERM, 5 s, SIGKILL) and reaps it.
class Process {
 public:
  Process() = default;
  Process(const std::vector<std::string>& argv, const SpawnOptions& options) { spawn(argv, options); }
  ~Process() { stop(); }
  Process(const Process&) = delete;
  Process& operator=(const Process&) = delete;
  Process(Process&& o) noexcept { *this = std::move(o); }
  Process& operator=(Process&& o) noexcept {
    if (this != &o) {
      stop();
      pid_ = o.pid_;
      status_ = o.status_;
      argv_ = std::move(o.argv_);
      o.pid_ = -1;
      o.status_.reset();
    }
    return *this;
  }

  void spawn(const std::vector<std::string>& argv, const SpawnOptions& options) {
    stop();
    status_.reset();
    argv_ = argv;
    // Everything the child needs is prepared before fork (only async-signal-safe calls after it).
    std::vector<char*> cargv;
    for (const auto& a : argv) cargv.push_back(const_cast<char*>(a.c_str()));
    cargv.push_back(nullptr);
    const int out_fd = ::open(options.stdout_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    const int err_fd = ::open(options.stderr_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    cpu_set_t cpus;
    CPU_ZERO(&cpus);
    if (options.cpu) CPU_SET(*options.cpu, &cpus);
    if (out_fd < 0 || err_fd < 0) {
      if (out_fd >= 0) ::close(out_fd);
      if (err_fd >= 0) ::close(err_fd);
      throw std::runtime_error("cannot open output files for " + argv.at(0));
    }
    if (options.run_as) {  // the files must be writable by the dropped identity
      (void)::fchown(out_fd, options.run_as->uid, options.run_as->gid);
      (void)::fchown(err_fd, options.run_as->uid, options.run_as->gid);
    }
    const pid_t pid = ::fork();
    if (pid < 0) {
      ::close(out_fd);
      ::close(err_fd);
      throw std::runtime_error("fork: " + std::string(std::strerror(errno)));
    }
    if (pid == 0) {
      ::dup2(out_fd, 1);
      ::dup2(err_fd, 2);
      const int in_fd = ::open("/dev/null", O_RDONLY);
      if (in_fd >= 0) ::dup2(in_fd, 0);
      for (const auto& [k, v] : options.env) ::setenv(k.c_str(), v.c_str(), 1);
      for (const auto& k : options.unset_env) ::unsetenv(k.c_str());
      ::signal(SIGPIPE, SIG_DFL);
      // A test killed by a timeout must not leave its simulator and daemon running (they
      // loaded the machine for the rest of a session once): they die with the test process.
      ::prctl(PR_SET_PDEATHSIG, SIGKILL);
      if (options.cpu && ::sched_setaffinity(0, sizeof cpus, &cpus) != 0) ::_exit(126);
      if (options.run_as) {
        if (::setgroups(0, nullptr) != 0 || ::setgid(options.run_as->gid) != 0 ||
            ::setuid(options.run_as->uid) != 0) {
          ::_exit(125);
        }
      }
      ::execv(cargv[0], cargv.data());
      ::_exit(127);
    }
    ::close(out_fd);
    ::close(err_fd);
    pid_ = pid;
  }

  pid_t pid() const { return pid_; }
  bool spawned() const { return pid_ > 0; }
  const std::vector<std::string>& argv() const { return argv_; }

  /// True while the child has not exited (reaps it if it has).
  bool running() {
    if (pid_ <= 0 || status_) return false;
    int st = 0;
    const pid_t r = ::waitpid(pid_, &st, WNOHANG);
    if (r == pid_) {
      status_ = st;
      return false;
    }
    return r == 0;
  }

  /// Waits up to `timeout` for the child to exit; its raw wait status, or nullopt on timeout.
  std::optional<int> wait_for(std::chrono::milliseconds timeout) {
    if (pid_ <= 0) return status_;
    const auto deadline = Clock::now() + timeout;
    while (running()) {
      if (Clock::now() >= deadline) return std::nullopt;
      std::this_thread::sleep_for(5ms);
    }
    return status_;
  }

  /// Exit code (0-255), 128+signal when killed by a signal, nullopt while running / on timeout.
  std::optional<int> exit_code(std::chrono::milliseconds timeout = 0ms) {
    const auto st = wait_for(timeout);
    if (!st) return std::nullopt;
    if (WIFEXITED(*st)) return WEXITSTATUS(*st);
    if (WIFSIGNALED(*st)) return 128 + WTERMSIG(*st);
    return -1;
  }

  void signal(int sig) {
    if (pid_ > 0 && !status_) ::kill(pid_, sig);
  }

  /// SIGKILL and reap (the `kill -9` of the recovery scenario).
  void kill9() {
    signal(SIGKILL);
    wait_for(10s);
  }

  /// SIGTERM, wait up to `grace`, then SIGKILL; always reaps. Returns the exit code.
  std::optional<int> terminate(std::chrono::milliseconds grace = 5000ms) {
    if (pid_ <= 0) return std::nullopt;
    if (running()) {
      ::kill(pid_, SIGTERM);
      if (!wait_for(grace)) {
        ::kill(pid_, SIGKILL);
        wait_for(10s);
      }
    }
    return exit_code();
  }

  void stop() {
    if (pid_ > 0) terminate();
    pid_ = -1;
  }

 private:
  pid_t pid_ = -1;
  std::optional<int> status_;
  std::vector<std::string> argv_;
};

/// A finished command.
struct CmdResult {
  int exit_code = -1;  ///< 128+signal if killed, -1 if it timed out (then it was killed)
  bool timed_out = false;
  std::string out, err;
  std::string command;  ///< for failure messages

  /// stdout as JSON; a test failure (with the whole output) if it is not JSON.
  json json_out() const {
    try {
      return json::parse(out);
    } catch (const std::exception& e) {
      ADD_FAILURE() << "not JSON (" << e.what() << ") from: " << command << "\nstdout:\n"
                    << out << "\nstderr:\n"
                    << err;
      return json();
    }
  }
  std::string describe() const {
    std::ostringstream s;
    s << "$ " << command << "\nexit " << exit_code << (timed_out ? " (TIMED OUT)" : "") << "\nstdout:\n"
      << out << "\nstderr:\n"
      << err;
    return s.str();
  }
};

/// Runs argv to completion (killed after `timeout`), capturing stdout and stderr through files in `dir`.
inline CmdResult run_command(const std::vector<std::string>& argv, const std::string& dir,
                             std::chrono::milliseconds timeout = 120s,
                             std::optional<RunAs> run_as = std::nullopt) {
  static std::atomic<int> counter{0};
  const int n = ++counter;
  SpawnOptions o;
  o.stdout_path = dir + "/cmd-" + std::to_string(n) + ".out";
  o.stderr_path = dir + "/cmd-" + std::to_string(n) + ".err";
  o.run_as = run_as;
  CmdResult r;
  r.command = shell_quote(argv);
  {
    Process p(argv, o);
    const auto st = p.wait_for(timeout);
    if (!st) {
      r.timed_out = true;
      p.signal(SIGKILL);
      p.wait_for(10s);
    } else {
      r.exit_code = *p.exit_code();
    }
  }
  r.out = read_text(o.stdout_path);
  r.err = read_text(o.stderr_path);
  return r;
}

/// Polls `ready` every `period` until it returns true or `timeout` passes.
inline bool wait_until(const std::function<bool()>& ready, std::chrono::milliseconds timeout,
                       std::chrono::milliseconds period = 20ms) {
  const auto deadline = Clock::now() + timeout;
  for (;;) {
    if (ready()) return true;
    if (Clock::now() >= deadline) return false;
    std::this_thread::sleep_for(period);
  }
}

// ---------------------------------------------------------------------------------------------
// Raw control-socket client (JSON lines): for fast status polling and malformed-request tests,
// independent of stationctl.
// ---------------------------------------------------------------------------------------------
class RawSocket {
 public:
  /// Connects to the Unix stream socket at `path`; throws with errno text on failure.
  explicit RawSocket(const std::string& path) {
    fd_ = ::socket(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0);
    if (fd_ < 0) throw std::runtime_error("socket: " + std::string(std::strerror(errno)));
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    if (path.size() >= sizeof addr.sun_path) throw std::runtime_error("socket path too long: " + path);
    std::memcpy(addr.sun_path, path.c_str(), path.size() + 1);
    if (::connect(fd_, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0) {
      const std::string e = std::strerror(errno);
      ::close(fd_);
      fd_ = -1;
      throw std::runtime_error("connect " + path + ": " + e);
    }
  }
  ~RawSocket() {
    if (fd_ >= 0) ::close(fd_);
  }
  RawSocket(const RawSocket&) = delete;
  RawSocket& operator=(const RawSocket&) = delete;

  /// Writes all bytes; false if the peer closed the connection.
  bool send_raw(const std::string& bytes) {
    size_t off = 0;
    while (off < bytes.size()) {
      const ssize_t n = ::send(fd_, bytes.data() + off, bytes.size() - off, MSG_NOSIGNAL);
      if (n < 0) {
        if (errno == EINTR) continue;
        return false;
      }
      off += static_cast<size_t>(n);
    }
    return true;
  }

  /// Next line (without '\n'), nullopt on EOF / error / timeout.
  std::optional<std::string> read_line(std::chrono::milliseconds timeout = 10s) {
    const auto deadline = Clock::now() + timeout;
    for (;;) {
      const auto nl = buffer_.find('\n');
      if (nl != std::string::npos) {
        std::string line = buffer_.substr(0, nl);
        buffer_.erase(0, nl + 1);
        return line;
      }
      const auto left = std::chrono::duration_cast<std::chrono::milliseconds>(deadline - Clock::now());
      if (left.count() <= 0) return std::nullopt;
      timeval tv{static_cast<time_t>(left.count() / 1000), static_cast<suseconds_t>((left.count() % 1000) * 1000)};
      ::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv);
      char buf[65536];
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n == 0) return std::nullopt;
      if (n < 0) {
        if (errno == EINTR) continue;
        return std::nullopt;
      }
      buffer_.append(buf, static_cast<size_t>(n));
    }
  }

  /// Sends one request line and returns the parsed reply (nullopt if none came).
  std::optional<json> request(const json& req, std::chrono::milliseconds timeout = 10s) {
    if (!send_raw(req.dump() + "\n")) return std::nullopt;
    return reply(timeout);
  }
  /// Reads one reply line as JSON (a non-JSON reply is a test failure).
  std::optional<json> reply(std::chrono::milliseconds timeout = 10s) {
    const auto line = read_line(timeout);
    if (!line) return std::nullopt;
    try {
      return json::parse(*line);
    } catch (const std::exception& e) {
      ADD_FAILURE() << "reply is not JSON: " << *line;
      return json();
    }
  }

 private:
  int fd_ = -1;
  std::string buffer_;
};

// ---------------------------------------------------------------------------------------------
// The station: simulator + daemon + control tool, all in one temporary directory.
// ---------------------------------------------------------------------------------------------
struct SimOptions {
  double speed = 200.0;
  uint64_t seed = 1;
  std::vector<std::string> extra;  ///< fault knobs etc., appended verbatim
};

class Station {
 public:
  Station() : address_(loopback_address()) {}
  ~Station() {
    // Daemon first (it safe-stops the table through the sim), then the sim.
    daemon_.terminate(10s);
    sim_.terminate(5s);
    for (auto& h : hogs_) h->signal(SIGKILL);
    hogs_.clear();
  }

  const TempDir& dir() const { return dir_; }
  /// Run stationsim, stationd and stationctl from `dir` (e.g. an installed package's bin/) instead
  /// of the build tree's.
  void use_programs_from(const std::string& dir) { program_dir_ = dir; }
  std::string program(const std::string& name) const { return program_dir_ + "/" + name; }
  std::string path(const std::string& name) const { return dir_ / name; }
  const std::string& address() const { return address_; }
  std::string config_path() const { return dir_ / "stationd.toml"; }
  std::string socket_path() const { return dir_ / "control.sock"; }
  std::string db_path() const { return dir_ / "history.sqlite"; }
  std::string data_dir() const { return dir_ / "data"; }
  std::string bus_path() const { return dir_ / "bus.sock"; }
  std::string truth_path() const { return dir_ / "truth.json"; }
  std::string sim_stats_path() const { return dir_ / "sim-stats.json"; }
  Process& sim() { return sim_; }
  Process& daemon() { return daemon_; }
  const json& sim_ready() const { return sim_ready_; }
  int modbus_port() const { return modbus_port_; }

  /// Starts stationsim and waits for its ready file. Failure: ADD_FAILURE + false.
  bool start_sim(const SimOptions& o = {}) {
    sim_options_ = o;
    std::ostringstream speed;
    speed << o.speed;
    std::vector<std::string> argv = {program("stationsim"),
                                     "--modbus",
                                     address_ + ":0",
                                     "--can",
                                     bus_path(),
                                     "--ready-file",
                                     dir_ / "sim-ready.json",
                                     "--truth-out",
                                     truth_path(),
                                     "--stats-file",
                                     sim_stats_path(),
                                     "--speed",
                                     speed.str(),
                                     "--seed",
                                     std::to_string(o.seed)};
    argv.insert(argv.end(), o.extra.begin(), o.extra.end());
    const bool chooses = std::find(o.extra.begin(), o.extra.end(), "--protocol") != o.extra.end();
    if (!chooses && !env_protocol().empty())
      argv.insert(argv.end(), {"--protocol", env_protocol()});
    if (access(argv[0].c_str(), X_OK) != 0) {
      ADD_FAILURE() << argv[0] << " is not built";
      return false;
    }
    SpawnOptions so;
    so.stdout_path = dir_ / "sim.out";
    so.stderr_path = dir_ / "sim.err";
    std::error_code ec;
    fs::remove(dir_ / "sim-ready.json", ec);
    sim_.spawn(argv, so);
    const bool ready = wait_until([&] { return fs::exists(dir_ / "sim-ready.json") || !sim_.running(); }, 20s);
    if (!ready || !fs::exists(dir_ / "sim-ready.json")) {
      ADD_FAILURE() << "stationsim did not become ready: " << shell_quote(argv) << "\nstderr:\n"
                    << read_text(dir_ / "sim.err");
      return false;
    }
    sim_ready_at_ = Clock::now();
    try {
      sim_ready_ = json::parse(read_text(dir_ / "sim-ready.json"));
      const std::string modbus = sim_ready_.at("modbus").get<std::string>();  // tcp:ADDR:PORT
      modbus_port_ = std::stoi(modbus.substr(modbus.rfind(':') + 1));
      sim_modbus_ = modbus;
    } catch (const std::exception& e) {
      ADD_FAILURE() << "stationsim ready file is not as the contract says (" << e.what()
                    << "): " << read_text(dir_ / "sim-ready.json");
      return false;
    }
    return true;
  }

  /// The daemon configuration for this station (every path inside the temporary directory).
  /// `extra` is appended (more keys / sections); `imu_extra` goes into [imu].
  std::string config_text(const std::string& extra = "", const std::string& imu_extra = "") const {
    const calib::core::Site site = calib::core::demo_factory_site();
    std::ostringstream c;
    c << std::setprecision(17);
    c << "# e2e test station (tests/e2e/station_harness.hpp)\n"
      << "[station]\n"
      << "name = \"e2e-station\"\n"
      << "lat_deg = " << site.lat_rad * kRadToDeg << "\n"
      << "lon_deg = " << site.lon_rad * kRadToDeg << "\n"
      << "height_m = " << site.height_m << "\n"
      << "gravity_mps2 = " << *site.gravity_mps2 << "\n"
      << "data_dir = \"" << data_dir() << "\"\n"
      << "database = \"" << db_path() << "\"\n"
      << "\n[control]\n"
      << "socket = \"" << socket_path() << "\"\n"
      << "\n[turntable]\n"
      << "endpoint = \"" << (sim_modbus_.empty() ? "tcp:" + address_ + ":1" : sim_modbus_) << "\"\n"
      << "\n[imu]\n"
      << "can = \"unixcan:" << bus_path() << "\"\n"
      << "rate_hz = 100.0\n"
      << (env_protocol().empty() || imu_extra.find("protocol =") != std::string::npos
              ? std::string()
              : "protocol = \"" + env_protocol() + "\"\n")
      << imu_extra << "\n[calibration]\n"
      << "default_sequence = \"short\"\n"
      << "k_sigma = 4.0\n"
      << "\n[log]\n"
      << "level = \"info\"\n"
      << extra;
    return c.str();
  }

  /// IMUCAL_E2E_PROTOCOL: the IMU protocol file of every test that does not choose one.
  static std::string env_protocol() {
    const char* p = std::getenv("IMUCAL_E2E_PROTOCOL");
    return p ? p : "";
  }

  void write_config(const std::string& text) {
    write_text(config_path(), text);
    ::chmod(config_path().c_str(), 0644);
  }

  /// Starts stationd with the current config file (written by write_config, or the default one if
  /// none exists yet) and waits until the control socket answers `ping` and `stationctl run status`
  /// exits 0. Failure: ADD_FAILURE + false.
  bool start_daemon(std::chrono::milliseconds timeout = 30s) {
    if (!fs::exists(config_path())) write_config(config_text());
    const std::vector<std::string> argv = {program("stationd"), "--config", config_path()};
    if (access(argv[0].c_str(), X_OK) != 0) {
      ADD_FAILURE() << argv[0] << " is not built";
      return false;
    }
    ++daemon_starts_;
    SpawnOptions so;
    so.stdout_path = dir_ / ("stationd-" + std::to_string(daemon_starts_) + ".out");
    so.stderr_path = dir_ / ("stationd-" + std::to_string(daemon_starts_) + ".err");
    so.unset_env = {"NOTIFY_SOCKET", "WATCHDOG_USEC", "WATCHDOG_PID", "JOURNAL_STREAM"};
    so.cpu = daemon_cpu_;
    daemon_.spawn(argv, so);
    const bool pinged = wait_until(
        [&] {
          if (!daemon_.running()) return true;
          try {
            RawSocket s(socket_path());
            const auto r = s.request({{"id", 1}, {"cmd", "ping"}, {"args", json::object()}}, 2s);
            return r && r->value("ok", false);
          } catch (const std::exception&) {
            return false;
          }
        },
        timeout, 50ms);
    if (!pinged || !daemon_.running()) {
      ADD_FAILURE() << "stationd did not start serving " << socket_path() << " (running: " << daemon_.running()
                    << ")\nstderr:\n"
                    << daemon_log();
      return false;
    }
    const CmdResult st = ctl({"run", "status"});
    if (st.exit_code != 0) {
      ADD_FAILURE() << "stationctl run status does not answer:\n" << st.describe();
      return false;
    }
    return true;
  }

  /// Pins the daemon (from its next start) to one CPU, e.g. to share it with busy processes.
  void pin_daemon(int cpu) { daemon_cpu_ = cpu; }

  /// Starts `n` busy-looping processes pinned to `cpu` (a loaded station PC); stopped with the
  /// station.
  void start_cpu_hogs(int cpu, int n) {
    for (int i = 0; i < n; ++i) {
      SpawnOptions so;
      so.cpu = cpu;
      hogs_.push_back(std::make_unique<Process>(std::vector<std::string>{"/bin/sh", "-c", "while :; do :; done"}, so));
    }
  }

  /// Both processes with the default config.
  bool start(const SimOptions& o = {}) { return start_sim(o) && start_daemon(); }

  /// Simulated time now, estimated from the wall time since the simulator became ready (the sim
  /// keeps its speed on this machine; its --stats-file reports the speed it reached).
  double sim_seconds(double speed) const {
    return std::chrono::duration<double>(Clock::now() - sim_ready_at_).count() * speed;
  }

  /// The daemon's log of its latest start (stderr).
  std::string daemon_log() const {
    return read_text(dir_ / ("stationd-" + std::to_string(daemon_starts_) + ".err"));
  }

  /// stationctl --config <config> ARGS...
  CmdResult ctl(const std::vector<std::string>& args, std::chrono::milliseconds timeout = 120s,
                std::optional<RunAs> run_as = std::nullopt) const {
    std::vector<std::string> argv = {program("stationctl"), "--config", config_path()};
    argv.insert(argv.end(), args.begin(), args.end());
    return run_command(argv, dir_.path(), timeout, run_as);
  }

  /// One raw request on a fresh connection; nullopt if the daemon cannot be reached.
  std::optional<json> request(const std::string& cmd, const json& args = json::object(),
                              std::chrono::milliseconds timeout = 10s) const {
    try {
      RawSocket s(socket_path());
      return s.request({{"id", 1}, {"cmd", cmd}, {"args", args}}, timeout);
    } catch (const std::exception&) {
      return std::nullopt;
    }
  }

  /// The daemon's live run object ("run" of run.status), null if idle or unreachable.
  json live_run() const {
    const auto r = request("run.status");
    if (!r || !r->value("ok", false)) return json();
    const json& result = (*r)["result"];
    if (!result.contains("run") || result["run"].is_null()) return json();
    return result["run"];
  }

  /// Polls the live run until `pred` holds; the last run object seen (null if never true).
  json wait_live_run(const std::function<bool(const json&)>& pred, std::chrono::milliseconds timeout,
                     std::chrono::milliseconds period = 10ms) const {
    json seen;
    const bool ok = wait_until(
        [&] {
          json run = live_run();
          if (!run.is_null() && pred(run)) {
            seen = run;
            return true;
          }
          return false;
        },
        timeout, period);
    return ok ? seen : json();
  }

  /// stationsim's final stats (after it exited).
  json sim_stats() const {
    try {
      return json::parse(read_text(sim_stats_path()));
    } catch (const std::exception&) {
      return json();
    }
  }

  /// mbpoll against the simulator's Modbus server: options, then the address, then the values to
  /// write (after "--", so negative numbers are not taken for options).
  CmdResult mbpoll(const std::vector<std::string>& args, const std::vector<std::string>& values = {}) const {
    std::vector<std::string> argv = {"/usr/bin/mbpoll", "-m", "tcp", "-a", "1", "-0", "-o", "2",
                                     "-p", std::to_string(modbus_port_)};
    argv.insert(argv.end(), args.begin(), args.end());
    argv.push_back(address_);
    if (!values.empty()) {
      argv.push_back("--");
      argv.insert(argv.end(), values.begin(), values.end());
    }
    return run_command(argv, dir_.path(), 15s);
  }


 private:
  TempDir dir_;
  std::string address_;
  SimOptions sim_options_;
  json sim_ready_;
  Clock::time_point sim_ready_at_ = Clock::now();
  std::string sim_modbus_;
  std::string program_dir_ = IMUCAL_BIN_DIR;
  int modbus_port_ = 0;
  int daemon_starts_ = 0;
  std::optional<int> daemon_cpu_;
  std::vector<std::unique_ptr<Process>> hogs_;
  Process sim_;
  Process daemon_;
};

/// mbpoll prints one "[ADDRESS]: VALUE" line per value.
inline std::map<int, std::string> mbpoll_values(const std::string& output) {
  std::map<int, std::string> v;
  const std::regex line(R"(\[(\d+)\]:\s+(\S+))");
  for (auto it = std::sregex_iterator(output.begin(), output.end(), line); it != std::sregex_iterator(); ++it)
    v[std::stoi((*it)[1])] = (*it)[2];
  return v;
}

/// The table as the simulator's input registers show it (read by mbpoll, a Modbus master nobody
/// here wrote; default register map of drivers/turntable/register_map.example.toml).
struct TableReading {
  bool ok = false;
  double outer_deg = 0, inner_deg = 0, rate_outer_dps = 0, rate_inner_dps = 0;
  int status = 0, fault_code = 0, heartbeat = 0;
  std::string raw;
  bool enabled() const { return status & (1 << 0); }
  bool homed() const { return status & (1 << 1); }
  bool moving() const { return status & (1 << 2); }
  bool in_position() const { return status & (1 << 3); }
  bool fault() const { return status & (1 << 4); }
};

/// float32 from two registers, high word first (the default map's "ABCD"), decoded here
/// independently of drivers/turntable/float_codec.
inline double float_abcd(unsigned hi, unsigned lo) {
  const uint32_t bits = (static_cast<uint32_t>(hi & 0xffffu) << 16) | (lo & 0xffffu);
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

/// All 13 input registers in ONE Modbus request (one consistent snapshot of the PLC).
inline TableReading read_table(const Station& st) {
  TableReading t;
  const CmdResult r = st.mbpoll({"-1", "-t", "3:hex", "-r", "0", "-c", "13"});
  t.raw = r.describe();
  if (r.exit_code != 0) return t;
  auto v = mbpoll_values(r.out);
  unsigned w[13];
  for (int i = 0; i < 13; ++i) {
    if (!v.count(i)) return t;
    w[i] = static_cast<unsigned>(std::stoul(v[i], nullptr, 16));
  }
  t.outer_deg = float_abcd(w[0], w[1]);
  t.inner_deg = float_abcd(w[2], w[3]);
  t.rate_outer_dps = float_abcd(w[4], w[5]);
  t.rate_inner_dps = float_abcd(w[6], w[7]);
  t.status = static_cast<int>(w[8]);
  t.fault_code = static_cast<int>(w[9]);
  t.heartbeat = static_cast<int>(w[10]);
  t.ok = true;
  return t;
}

/// Lower-case copy (message checks are case-insensitive).
inline std::string lower(std::string s) {
  for (auto& c : s) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return s;
}
inline bool contains_ci(const std::string& hay, const std::string& needle) {
  return lower(hay).find(lower(needle)) != std::string::npos;
}

/// Run id from `run start` output (--json: {"run_id": N, ...}).
inline long long run_id_of(const json& j) {
  if (j.is_object() && j.contains("run_id") && j["run_id"].is_number_integer()) return j["run_id"].get<long long>();
  if (j.is_object() && j.contains("run") && j["run"].is_object()) return run_id_of(j["run"]);
  return -1;
}


/// `stationctl --json history SN` -> the "runs" array (a test failure and empty if it fails).
inline json history_runs(const Station& st, const std::string& serial) {
  const CmdResult r = st.ctl({"--json", "history", serial});
  if (r.exit_code != 0) {
    ADD_FAILURE() << r.describe();
    return json::array();
  }
  const json j = r.json_out();
  if (!j.is_object() || !j.contains("runs") || !j["runs"].is_array()) {
    ADD_FAILURE() << "history --json has no \"runs\" array:\n" << r.describe();
    return json::array();
  }
  return j["runs"];
}

/// `stationctl --json show RUN_ID` -> {"run": ..., "calibrations": [...], "crosscheck": ...}.
inline json show_run(const Station& st, long long run_id) {
  const CmdResult r = st.ctl({"--json", "show", std::to_string(run_id)});
  if (r.exit_code != 0) {
    ADD_FAILURE() << r.describe();
    return json();
  }
  const json j = r.json_out();
  if (!j.is_object() || !j.contains("run") || !j["run"].is_object()) {
    ADD_FAILURE() << "show --json has no \"run\" object:\n" << r.describe();
    return json();
  }
  return j;
}

/// The newest run of a serial from `history --json` (null if none).
inline json newest_run(const Station& st, const std::string& serial) {
  const json runs = history_runs(st, serial);
  return runs.empty() ? json() : runs[0];
}

/// Runs of a serial read straight from the database file (read-only, independent of the daemon and
/// stationctl): -1 if there is no database file, else the count (0 if the serial is unknown).
inline long long stored_run_count(const std::string& db_path, const std::string& serial) {
  if (!fs::exists(db_path)) return -1;
  db::history::SqliteOptions o;
  o.read_only = true;
  db::history::SqliteRepository repo(db_path, o);
  try {
    return static_cast<long long>(repo.history(serial).size());
  } catch (const db::history::NotFound&) {
    return 0;
  }
}

/// Every run in the database, any serial (through export), -1 if there is no database file.
inline long long stored_run_total(const std::string& db_path) {
  if (!fs::exists(db_path)) return -1;
  db::history::SqliteOptions o;
  o.read_only = true;
  db::history::SqliteRepository repo(db_path, o);
  std::vector<db::history::RunId> ids;
  repo.export_rows({}, [&](const db::history::ExportRow& row) {
    if (ids.empty() || ids.back() != row.run.run_id) ids.push_back(row.run.run_id);
  });
  return static_cast<long long>(ids.size());
}

/// A number from a JSON object, 0 if absent or not a number (for counter sums).
inline double num(const json& j, const std::string& key) {
  if (!j.is_object() || !j.contains(key) || !j[key].is_number()) return 0.0;
  return j[key].get<double>();
}

/// Rest rows of an archive whose accelerometer does not see gravity where the table says "down" is.
/// Physics, independent of the calibration: at rest the specific force is -g along the body "down"
/// direction, and for the default geometry (calib/core/table_model.hpp; derivation in the comment
/// of sequences/short.toml) down in body = (sin o sin i, sin o cos i, cos o). Biases (µg), scale
/// errors (ppm), misalignments (arcsec) and noise (~1e-3 m/s² per 10 ms sample) are far below the
/// 0.05 m/s² tolerance; a row labelled with the wrong pose is off by ~g·√2.
struct RestCheck {
  size_t rest_rows = 0;
  size_t mislabelled = 0;
  std::string first;  ///< description of the first mislabelled row
};
inline RestCheck check_rest_rows(const db::archive::RunArchive& a, double g_mps2) {
  RestCheck r;
  const size_t n = std::min(a.imu.size(), a.table.size());
  for (size_t k = 0; k < n; ++k) {
    const auto& t = a.table[k];
    if (!t.at_rest) continue;
    ++r.rest_rows;
    const auto& m = a.imu[k];
    const Eigen::Vector3d down(std::sin(t.outer_rad) * std::sin(t.inner_rad),
                               std::sin(t.outer_rad) * std::cos(t.inner_rad), std::cos(t.outer_rad));
    const Eigen::Vector3d f = m.dv_mps / m.dt_s;
    if ((f + g_mps2 * down).norm() > 0.05) {
      if (r.mislabelled++ == 0) {
        std::ostringstream d;
        d << "row " << k + 1 << " (t = " << t.t_s << " s) labelled at rest at outer " << t.outer_rad * kRadToDeg
          << " deg, inner " << t.inner_rad * kRadToDeg << " deg, but f_b = (" << f.transpose()
          << ") m/s^2 while that pose gives (" << (-g_mps2 * down).transpose() << ")";
        r.first = d.str();
      }
    }
  }
  return r;
}

}  // namespace imucal::e2e
