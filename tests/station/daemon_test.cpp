// The Daemon in process: start-up recovery marks live runs interrupted and keeps their archives
// intact and reprocessable; the status JSON carries the contract's fields before, during and after
// a run (through the real control socket); run() notifies systemd (READY=1, WATCHDOG=1, STOPPING=1)
// and shuts down cleanly.
#include "station/daemon/daemon.hpp"

#include <gtest/gtest.h>
#include <poll.h>
#include <spdlog/spdlog.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <unistd.h>

#include <chrono>
#include <cstddef>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <thread>

#include "calib/core/site_presets.hpp"
#include "calib/sim/truth_sim.hpp"
#include "db/archive/run_archive.hpp"
#include "drivers/simulated/station_sim.hpp"
#include "sequences/library.hpp"
#include "station/control/control_client.hpp"
#include "station/daemon/logging.hpp"
#include "station/run/archive_writer.hpp"

namespace imucal::station {
using namespace imucal::station::config;
using namespace imucal::station::control;
using namespace imucal::station::daemon;
using namespace imucal::station::run;
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using nlohmann::json;

std::string make_temp_dir() {
  std::string tmpl = (fs::temp_directory_path() / "imucal-daemon-XXXXXX").string();
  if (!mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
  return tmpl;
}

StationConfig config_for(const std::string& dir, const std::string& endpoint,
                         const std::string& can) {
  const std::string text =
      "[station]\nname = \"daemon-test\"\nlat_deg = 55.7856\nlon_deg = 12.5213\n"
      "height_m = 30.0\ndata_dir = \"data\"\n"
      "[control]\nsocket = \"ctl.sock\"\n"
      "[turntable]\nendpoint = \"" +
      endpoint +
      "\"\nreconnect_give_up_ms = 300\n"
      "move_timeout_s = 30\nhome_timeout_s = 30\n"
      "[imu]\ncan = \"" +
      can +
      "\"\n"
      "[calibration]\ndefault_sequence = \"short\"\n";
  return parse_config(text, dir + "/stationd.toml", dir);
}

class TempDirDaemon {
 public:
  TempDirDaemon() : path(make_temp_dir()) {}
  ~TempDirDaemon() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  std::string path;
};

/// Writes the simulated "short" run into `dir` as a killed daemon leaves it: rows flushed, run.toml
/// without end time, no [capture], and half a line at the end of imu.csv. Returns the rows written.
size_t write_killed_archive(const std::string& dir, const std::string& serial) {
  const auto profile = sequences::load_profile("short");
  calib::sim::SimOptions so;
  so.seed = 3;
  const calib::sim::SimResult sim =
      calib::sim::simulate(profile, calib::core::TableGeometry{}, calib::core::demo_factory_site(),
                           calib::effects::default_unit(), so);
  db::archive::RunInfo info;
  info.serial = serial;
  info.station_name = "daemon-test";
  info.site = calib::core::demo_factory_site();
  info.imu_rate_hz = so.rate_hz;
  info.sequence_name = "short";
  info.start_time = "2024-05-01T10:00:00.000Z";
  {
    ArchiveWriter w(dir, info);
    for (size_t i = 0; i < sim.imu.size(); ++i) w.append_row(sim.imu[i], sim.table[i]);
    w.flush();
  }  // destroyed without finish(): what SIGKILL leaves behind
  std::ofstream(dir + "/imu.csv", std::ios::app) << "530.01,1.2e-06,3.";  // torn last line
  return sim.imu.size();
}

TEST(Daemon, RecoveryMarksLiveRunsInterruptedKeepsTheArchiveAndReprocessWorks) {
  TempDirDaemon tmp;
  StationConfig cfg = config_for(tmp.path, "tcp:127.0.0.1:1", "unixcan:" + tmp.path + "/none.sock");
  fs::create_directories(cfg.data_dir);
  db::history::RunId running_id = 0, preparing_id = 0;
  size_t rows = 0;
  {
    db::history::SqliteRepository repo(cfg.database);
    db::history::NewRun nr;
    nr.serial = "REC-1";
    nr.operator_name = "op";
    nr.station = "daemon-test";
    nr.sequence_name = "short";
    nr.software_version = "test";
    nr.started_at_ms = db::history::now_ms();
    nr.state = db::history::RunState::kRunning;
    running_id = repo.create_run(nr);
    rows = write_killed_archive(run_archive_dir(cfg.data_dir, running_id, "REC-1"), "REC-1");
    nr.serial = "REC-2";
    nr.state = db::history::RunState::kPreparing;
    preparing_id = repo.create_run(nr);
  }

  DaemonOptions opt;
  opt.stop_table_at_start = false;
  Daemon d(cfg, opt);
  d.start();
  ASSERT_EQ(d.recovery().runs.size(), 2u);

  const db::history::RunRecord rec = d.repository().show(running_id).run;
  EXPECT_EQ(rec.state, db::history::RunState::kInterrupted);
  EXPECT_NE(rec.failure_reason.find("running"), std::string::npos) << rec.failure_reason;
  EXPECT_NE(rec.failure_reason.find(std::to_string(rows) + " rows"), std::string::npos)
      << rec.failure_reason;
  // Intact: every complete row kept, the torn line gone, readable, hash recorded.
  const db::archive::RunArchive ar = db::archive::read_archive(rec.archive_path);
  EXPECT_EQ(ar.imu.size(), rows);
  EXPECT_EQ(ar.table.size(), rows);
  ASSERT_TRUE(ar.info.capture.has_value());
  EXPECT_FALSE(ar.info.capture->complete);
  EXPECT_FALSE(ar.info.end_time.empty());
  EXPECT_EQ(rec.archive_sha256, archive_digest(rec.archive_path));
  ASSERT_FALSE(rec.capture_json.empty());
  EXPECT_EQ(json::parse(rec.capture_json).at("rows_written").get<uint64_t>(), rows);

  const db::history::RunRecord prep = d.repository().show(preparing_id).run;
  EXPECT_EQ(prep.state, db::history::RunState::kInterrupted);
  EXPECT_NE(prep.failure_reason.find("no archive"), std::string::npos) << prep.failure_reason;
  // Nothing is resumed: the daemon is idle.
  EXPECT_EQ(d.status(std::nullopt).at("state"), "idle");

  // reprocess of the cut archive: refused unless asked for explicitly, naming why.
  try {
    d.reprocess({running_id, "qa-anna", false, std::nullopt});
    FAIL() << "a partial archive was reprocessed without being asked for";
  } catch (const ControlError& e) {
    EXPECT_EQ(e.code(), error_code::kInvalidInput);
    EXPECT_NE(std::string(e.what()).find("incomplete"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("--partial"), std::string::npos) << e.what();
  }
  // Asked for: a new run from the kept archive, calibrated by the worker, REVIEW at best and
  // recorded as the requester's.
  const json r = d.reprocess({running_id, "qa-anna", true, std::nullopt});
  const db::history::RunId new_id = r.at("run_id").get<db::history::RunId>();
  EXPECT_EQ(r.at("reprocessed_from").get<db::history::RunId>(), running_id);
  EXPECT_THROW(d.reprocess({running_id, "qa-anna", true, std::nullopt}),
               ControlError);  // busy meanwhile
  ASSERT_TRUE(d.controller().wait_idle(60s));
  const json s = d.status(new_id).at("run");
  EXPECT_EQ(s.at("state"), "review") << s.dump();
  // (The verdict is the cross-check's: the two methods may well agree on the prefix.)
  EXPECT_NE(s.at("reason").get<std::string>().find("partial archive"), std::string::npos)
      << s.dump();
  EXPECT_EQ(s.at("reprocessed_from").get<db::history::RunId>(), running_id);
  EXPECT_EQ(d.repository().show(new_id).run.operator_name, "qa-anna");
  EXPECT_EQ(d.repository().show(new_id).run.archive_sha256, rec.archive_sha256);
  EXPECT_THROW(d.repository().active_params("REC-1"), db::history::NotFound)
      << "a partial archive became the unit's active parameters";

  // Reprocessed with a corrected surveyed gravity (issue #25: a station's signature showed its
  // gravity wrong): 50 µg more than the archive's moves every accelerometer scale by -50 ppm
  // against the same archive calibrated as it was, and the new run says what was corrected.
  const double archive_g = *calib::core::demo_factory_site().gravity_mps2;
  const double corrected_g = archive_g + 50.0 * kMicroG_mps2;
  const json r2 = d.reprocess({running_id, "qa-anna", true, corrected_g});
  const db::history::RunId corrected_id = r2.at("run_id").get<db::history::RunId>();
  ASSERT_TRUE(d.controller().wait_idle(60s));
  const db::history::RunDetails as_was = d.repository().show(new_id);
  const db::history::RunDetails corrected = d.repository().show(corrected_id);
  EXPECT_NE(corrected.run.origin.find("surveyed gravity corrected to"), std::string::npos)
      << corrected.run.origin;
  EXPECT_EQ(as_was.run.origin, "");
  ASSERT_FALSE(as_was.calibrations.empty());
  ASSERT_FALSE(corrected.calibrations.empty());
  ASSERT_EQ(as_was.calibrations[0].method, db::history::Method::kAins);
  ASSERT_EQ(corrected.calibrations[0].method, db::history::Method::kAins);
  for (int i = 0; i < 3; ++i)
    EXPECT_NEAR(corrected.calibrations[0].params.accel_M(i, i) -
                    as_was.calibrations[0].params.accel_M(i, i),
                -50e-6, 1e-6)
        << "axis " << i;
  try {
    d.reprocess({running_id, "qa-anna", true, 98.1});
    FAIL() << "a gravity ten times Earth's was taken";
  } catch (const ControlError& e) {
    EXPECT_EQ(e.code(), error_code::kInvalidInput);
  }

  // A changed archive is refused before anything is written.
  std::ofstream(rec.archive_path + "/capture.log", std::ios::app) << "x";
  try {
    d.reprocess({running_id, "qa-anna", true, std::nullopt});
    FAIL() << "a changed archive was reprocessed";
  } catch (const ControlError& e) {
    EXPECT_EQ(e.code(), error_code::kInvalidInput);
    EXPECT_NE(std::string(e.what()).find("changed"), std::string::npos) << e.what();
  }
  try {
    d.status(db::history::RunId{999});
    FAIL() << "unknown run answered";
  } catch (const ControlError& e) {
    EXPECT_EQ(e.code(), error_code::kNotFound);
  }
  d.stop("test over");
}

TEST(Daemon, StatusJsonThroughTheControlSocketBeforeDuringAndAfterARun) {
  TempDirDaemon tmp;
  drivers::simulated::StationSimConfig sc;
  sc.can_path = tmp.path + "/bus.sock";
  sc.speed = 50.0;
  drivers::simulated::StationSim sim(sc);
  sim.start();
  std::ofstream(tmp.path + "/tiny.toml") << "name = \"tiny\"\n[start]\nrest_s = 10.0\n"
                                            "[[step]]\nrotate = \"inner\"\nby_deg = 90.0\n"
                                            "[[step]]\nrest_s = 10.0\n";
  StationConfig cfg = config_for(tmp.path, sim.modbus_endpoint(), sim.can_uri());
  Daemon d(cfg, DaemonOptions{});
  d.start();
  EXPECT_TRUE(d.recovery().table_reached);  // the start-up safe stop reached the table
  ControlClient c(cfg.control_socket);

  Reply r = c.call("run.status");
  ASSERT_TRUE(r.ok) << r.error_message;
  const json& daemon = r.result.at("daemon");
  EXPECT_EQ(daemon.at("version"), IMUCAL_VERSION);
  EXPECT_EQ(daemon.at("pid").get<long long>(), static_cast<long long>(getpid()));
  EXPECT_EQ(daemon.at("station"), "daemon-test");
  EXPECT_GE(daemon.at("uptime_s").get<double>(), 0.0);
  EXPECT_EQ(r.result.at("state"), "idle");
  EXPECT_TRUE(r.result.at("run").is_null());
  EXPECT_TRUE(r.result.at("last_run").is_null());

  r = c.call("run.start",
             {{"serial", "STAT-1"}, {"sequence", tmp.path + "/tiny.toml"}, {"operator", "alice"}});
  ASSERT_TRUE(r.ok) << r.error_message;
  const db::history::RunId id = r.result.at("run_id").get<db::history::RunId>();
  EXPECT_EQ(r.result.at("steps"), 3);
  // A second start is refused while the first is live.
  Reply busy = c.call("run.start", {{"serial", "STAT-2"}});
  EXPECT_FALSE(busy.ok);
  EXPECT_EQ(busy.error_code, error_code::kBusy);

  // During the capture, once the table works (before it, while the links come up, the phase is
  // "connecting" and no step has begun): every field of the contract's run object.
  const auto on_the_table = [](const json& run) {
    if (!run.is_object() || run.at("state") != "running" || !run.at("capture").is_object())
      return false;
    const json& phase = run.at("phase");
    // time_left_s is null until a second of IMU data has measured the stream's speed (issue #19
    // item 10: before that it printed the plan's real-time length on a fast simulator).
    return (phase == "moving" || phase == "settling" || phase == "resting") &&
           run.at("time_left_s").is_number();
  };
  json live;
  for (int i = 0; i < 3000; ++i) {
    r = c.call("run.status");
    ASSERT_TRUE(r.ok);
    if (on_the_table(r.result.at("run"))) {
      live = r.result;
      break;
    }
    std::this_thread::sleep_for(2ms);
  }
  ASSERT_TRUE(live.is_object()) << "never saw the run on the table";
  EXPECT_EQ(live.at("state"), "busy");
  const json& run = live.at("run");
  EXPECT_EQ(run.at("run_id").get<db::history::RunId>(), id);
  EXPECT_EQ(run.at("serial"), "STAT-1");
  EXPECT_EQ(run.at("sequence"), "tiny");
  EXPECT_EQ(run.at("operator"), "alice");
  EXPECT_GE(run.at("step").get<int>(), 1);
  EXPECT_EQ(run.at("steps"), 3);
  ASSERT_TRUE(run.at("time_left_s").is_number());
  // At most the whole plan in table time (10 + 9 + 1 + 10 s + guards), at least 0.
  EXPECT_GE(run.at("time_left_s").get<double>(), 0.0);
  EXPECT_LE(run.at("time_left_s").get<double>(), 32.0);
  EXPECT_TRUE(run.at("verdict").is_null());
  EXPECT_EQ(run.at("reason"), "");
  EXPECT_TRUE(run.at("started_at").is_string());
  EXPECT_TRUE(run.at("capture").contains("rows_written"));
  EXPECT_TRUE(run.at("capture").contains("samples_lost"));

  ASSERT_TRUE(d.controller().wait_idle(60s));
  r = c.call("run.status");
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.result.at("state"), "idle");
  EXPECT_TRUE(r.result.at("run").is_null());
  const json& last = r.result.at("last_run");
  ASSERT_TRUE(last.is_object());
  EXPECT_EQ(last.at("run_id").get<db::history::RunId>(), id);
  const std::string state = last.at("state");
  EXPECT_TRUE(state == "failed" || state == "review") << last.dump();  // 2 poses cannot calibrate
  EXPECT_TRUE(last.at("phase").is_null());
  EXPECT_TRUE(last.at("time_left_s").is_null());
  EXPECT_NE(last.at("reason").get<std::string>(), "");
  EXPECT_EQ(last.at("capture").at("rest_samples").get<uint64_t>(), 2000u);  // 2 × 10 s at 100 Hz

  // The same run from the database by id.
  r = c.call("run.status", {{"run_id", id}});
  ASSERT_TRUE(r.ok) << r.error_message;
  EXPECT_EQ(r.result.at("run").at("state"), state);
  EXPECT_EQ(r.result.at("run").at("capture").at("rest_samples").get<uint64_t>(), 2000u);
  // Nothing to abort now.
  r = c.call("run.abort", json::object());
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.error_code, error_code::kNotFound);
  d.stop("test over");
  EXPECT_FALSE(fs::exists(cfg.control_socket));
}

TEST(Daemon, SecondDaemonOnTheSameDataDirectoryIsRefusedBeforeTouchingAnything) {
  TempDirDaemon tmp;
  StationConfig cfg = config_for(tmp.path, "tcp:127.0.0.1:1", "unixcan:" + tmp.path + "/none.sock");
  DaemonOptions opt;
  opt.stop_table_at_start = false;
  Daemon first(cfg, opt);
  first.start();
  // A live run of the first daemon (as if it were running one).
  db::history::RunId id = 0;
  {
    db::history::SqliteRepository repo(cfg.database);
    db::history::NewRun nr;
    nr.serial = "LOCK-1";
    nr.started_at_ms = db::history::now_ms();
    nr.state = db::history::RunState::kRunning;
    id = repo.create_run(nr);
  }
  // A second daemon (another socket, same data directory) must not run recovery on it.
  StationConfig cfg2 = cfg;
  cfg2.control_socket = tmp.path + "/ctl2.sock";
  Daemon second(cfg2, opt);
  try {
    second.start();
    FAIL() << "second daemon started";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("another stationd (pid " + std::to_string(getpid()) + ")"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(first.repository().show(id).run.state, db::history::RunState::kRunning);
  EXPECT_FALSE(fs::exists(cfg2.control_socket));
  first.stop("test over");
  // Once the first is gone, a new daemon starts and recovers the run.
  Daemon third(cfg2, opt);
  third.start();
  EXPECT_EQ(third.repository().show(id).run.state, db::history::RunState::kInterrupted);
  third.stop("test over");
}

TEST(Logging, JournalOnlyWhenStderrIsTheJournalStream) {
  struct stat st {};
  ASSERT_EQ(fstat(STDERR_FILENO, &st), 0);
  const std::string mine = std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino);
  ::unsetenv("JOURNAL_STREAM");
  EXPECT_FALSE(stderr_is_journal());
  // Inherited from a service but stderr is something else now: not the journal.
  ::setenv("JOURNAL_STREAM",
           (std::to_string(st.st_dev) + ":" + std::to_string(st.st_ino + 1)).c_str(), 1);
  EXPECT_FALSE(stderr_is_journal());
  ::setenv("JOURNAL_STREAM", "garbage", 1);
  EXPECT_FALSE(stderr_is_journal());
  ::setenv("JOURNAL_STREAM", mine.c_str(), 1);
  EXPECT_TRUE(stderr_is_journal());
  ::unsetenv("JOURNAL_STREAM");
  EXPECT_EQ(setup_logging("warn"), LogTarget::kConsole);
  EXPECT_EQ(spdlog::default_logger()->level(), spdlog::level::warn);
  EXPECT_THROW(setup_logging("loud"), std::invalid_argument);
  setup_logging("info");
}

/// A datagram socket standing in for systemd's notify socket.
class FakeSystemd {
 public:
  explicit FakeSystemd(const std::string& path) : path_(path) {
    fd_ = ::socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
    sockaddr_un a{};
    a.sun_family = AF_UNIX;
    std::memcpy(a.sun_path, path.data(), path.size());
    ::bind(fd_, reinterpret_cast<sockaddr*>(&a),
           static_cast<socklen_t>(offsetof(sockaddr_un, sun_path) + path.size()));
  }
  ~FakeSystemd() { ::close(fd_); }
  /// Waits for a datagram containing `what`; all datagrams seen are appended to log.
  bool wait_for(const std::string& what, std::chrono::milliseconds timeout) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < end) {
      pollfd p{fd_, POLLIN, 0};
      if (::poll(&p, 1, 50) != 1) continue;
      char buf[4096];
      const ssize_t n = ::recv(fd_, buf, sizeof buf, 0);
      if (n <= 0) continue;
      const std::string msg(buf, static_cast<size_t>(n));
      log += msg + "|";
      if (msg.find(what) != std::string::npos) return true;
    }
    return false;
  }
  std::string log;

 private:
  std::string path_;
  int fd_ = -1;
};

TEST(Daemon, RunNotifiesSystemdAndStopsCleanly) {
  TempDirDaemon tmp;
  StationConfig cfg = config_for(tmp.path, "tcp:127.0.0.1:1", "unixcan:" + tmp.path + "/none.sock");
  FakeSystemd systemd(tmp.path + "/notify.sock");
  DaemonOptions opt;
  opt.stop_table_at_start = false;
  opt.notifier = SdNotifier(tmp.path + "/notify.sock", std::chrono::microseconds(200000));
  Daemon d(cfg, opt);
  int rc = -1;
  std::thread t([&] { rc = d.run(); });
  EXPECT_TRUE(systemd.wait_for("READY=1", 10s)) << systemd.log;
  EXPECT_TRUE(fs::exists(cfg.control_socket));  // READY only once the socket listens
  EXPECT_NE(systemd.log.find("STATUS=idle"), std::string::npos) << systemd.log;
  EXPECT_TRUE(systemd.wait_for("WATCHDOG=1", 2s)) << systemd.log;  // every 100 ms
  EXPECT_TRUE(systemd.wait_for("WATCHDOG=1", 2s)) << systemd.log;
  d.request_stop();
  t.join();
  EXPECT_EQ(rc, 0);
  EXPECT_TRUE(systemd.wait_for("STOPPING=1", 2s)) << systemd.log;
  EXPECT_FALSE(fs::exists(cfg.control_socket));
}

}  // namespace
}  // namespace imucal::station
