// The run state machine against the in-process simulated station (drivers::simulated::StationSim: a
// Modbus PLC table and the IMU CAN node on it, one physics clock, accelerated): a run executes
// every step of its sequence with rests counted in IMU samples, is calibrated by the worker and
// stored; an abort stops the table and marks the run aborted; a table fault mid-move aborts the run
// with the fault in the reason. Expectations come from the sequence (poses, rest lengths × rate)
// and the simulator's truth.
#include "station/run/run_controller.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <thread>

#include "calib/core/param_set.hpp"
#include "db/archive/run_archive.hpp"
#include "db/history/sqlite_repository.hpp"
#include "drivers/simulated/station_sim.hpp"
#include "sequences/sequence_error.hpp"
#include "station/run/archive_writer.hpp"

namespace imucal::station {
using namespace imucal::station::config;
using namespace imucal::station::control;
using namespace imucal::station::run;
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

/// 5 steps: rest 10 s at (0,0); outer +90; rest 10 s at (90,0); inner +90; rest 12 s at (90,90).
const char* const kTinySequence = R"(name = "tiny"
[start]
outer_deg = 0.0
inner_deg = 0.0
rest_s = 10.0
[defaults]
rate_dps = 10.0
accel_dps2 = 10.0
[[step]]
rotate = "outer"
by_deg = 90.0
[[step]]
rest_s = 10.0
[[step]]
rotate = "inner"
by_deg = 90.0
[[step]]
rest_s = 12.0
)";

std::string make_temp_dir_run_controller() {
  std::string tmpl = (fs::temp_directory_path() / "imucal-runctl-XXXXXX").string();
  if (!mkdtemp(tmpl.data())) throw std::runtime_error("mkdtemp failed");
  return tmpl;
}

/// Temp dir + simulator + config + repository + worker + controller.
class Station {
 public:
  explicit Station(
      double speed,
      std::optional<drivers::simulated::StationSimFaults::TableFault> fault = std::nullopt) {
    dir_ = make_temp_dir_run_controller();
    drivers::simulated::StationSimConfig sc;
    sc.can_path = dir_ + "/bus.sock";
    sc.speed = speed;
    sc.seed = 7;
    sc.faults.table_fault = fault;
    sim_ = std::make_unique<drivers::simulated::StationSim>(sc);
    sim_->start();
    std::ofstream(dir_ + "/tiny.toml") << kTinySequence;
    const std::string text = "[station]\nname = \"test-station\"\nlat_deg = 55.7856\nlon_deg = 12.5213\n"
                             "height_m = 30.0\ndata_dir = \"data\"\n"
                             "[control]\nsocket = \"ctl.sock\"\n"
                             "[turntable]\nendpoint = \"" + sim_->modbus_endpoint() + "\"\n"
                             "move_timeout_s = 30\nhome_timeout_s = 30\nreconnect_give_up_ms = 1000\n"
                             "[imu]\ncan = \"" + sim_->can_uri() + "\"\n"
                             "[calibration]\ndefault_sequence = \"" + dir_ + "/tiny.toml\"\n";
    cfg_ = parse_config(text, dir_ + "/stationd.toml", dir_);
    fs::create_directories(cfg_.data_dir);
    repo_ = std::make_unique<db::history::SqliteRepository>(cfg_.database);
    worker_ = std::make_unique<CalibrationWorker>(*repo_);
    ctl_ = std::make_unique<RunController>(cfg_, *repo_, *worker_, "test");
  }
  ~Station() {
    ctl_.reset();
    worker_.reset();
    repo_.reset();
    sim_.reset();
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }

  db::history::RunId start(const std::string& serial,
                           std::optional<std::string> sequence = std::nullopt) {
    StartRunRequest r;
    r.serial = serial;
    r.sequence = std::move(sequence);
    r.operator_name = "tester";
    return ctl_->start(r).at("run_id").get<db::history::RunId>();
  }
  /// Polls the live snapshot until pred holds (true) or timeout (false).
  template <class P>
  bool wait_for(P pred, std::chrono::milliseconds timeout) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < end) {
      if (auto a = ctl_->active(); a && pred(*a)) return true;
      std::this_thread::sleep_for(2ms);
    }
    return false;
  }
  bool table_moving() {
    return sim_->table_server().with_plc(
        [](drivers::simulated::TablePlc& plc) { return plc.moving(); });
  }

  std::string dir_;
  std::unique_ptr<drivers::simulated::StationSim> sim_;
  StationConfig cfg_;
  std::unique_ptr<db::history::SqliteRepository> repo_;
  std::unique_ptr<CalibrationWorker> worker_;
  std::unique_ptr<RunController> ctl_;
};

TEST(RunPlan, TinySequenceFlattensToRestsAndMovesWithSampleCounts) {
  const std::string dir = make_temp_dir_run_controller();
  std::ofstream(dir + "/tiny.toml") << kTinySequence;
  const std::string base = "[station]\nname=\"s\"\nlat_deg=0\nlon_deg=0\nheight_m=0\ndata_dir=\"d\"\n"
                           "[imu]\ncan=\"unixcan:x\"\nrate_hz=200\n"
                           "[turntable]\nendpoint=\"tcp:127.0.0.1:1\"\n";
  const RunPlan p = plan_run(dir + "/tiny.toml", parse_config(base, "cfg", dir));
  // A station slower than the file's 10 deg/s refuses the sequence (it is not silently slowed).
  EXPECT_THROW(plan_run(dir + "/tiny.toml", parse_config(base + "max_rate_dps = 5\n", "cfg", dir)),
               sequences::SequenceError);
  fs::remove_all(dir);
  EXPECT_EQ(p.sequence_name, "tiny");
  EXPECT_EQ(p.sequence_sha256.size(), 64u);
  ASSERT_EQ(p.steps.size(), 5u);  // initial rest + 4 [[step]]s
  EXPECT_EQ(p.steps[0].kind, PlannedStep::Kind::kRest);
  EXPECT_EQ(p.steps[0].rest_samples(200.0), 2000u);  // 10 s × 200 Hz
  EXPECT_EQ(p.steps[1].kind, PlannedStep::Kind::kMove);
  EXPECT_DOUBLE_EQ(p.steps[1].outer_deg, 90.0);
  EXPECT_DOUBLE_EQ(p.steps[1].inner_deg, 0.0);
  EXPECT_DOUBLE_EQ(p.steps[1].rate_dps, 10.0);
  EXPECT_EQ(p.steps[2].rest_samples(200.0), 2000u);
  EXPECT_DOUBLE_EQ(p.steps[3].outer_deg, 90.0);
  EXPECT_DOUBLE_EQ(p.steps[3].inner_deg, 90.0);
  EXPECT_EQ(p.steps[4].rest_samples(200.0), 2400u);
  // 90 deg at 10 deg/s with 10 deg/s²: 90/10 + 10/10 = 10 s; rests add the settle guard (50/200 s).
  EXPECT_NEAR(p.steps[1].expected_s, 10.0, 1e-9);
  EXPECT_NEAR(p.steps[0].expected_s, 10.25, 1e-9);
}

TEST(RunController, TinyRunExecutesEveryStepAndCountsRestsInSamples) {
  Station st(100.0);
  const db::history::RunId id = st.start("TINY-1");
  // Observed live: preparing/running states with step i/5 and a phase word.
  EXPECT_TRUE(st.wait_for(
      [](const RunSnapshot& s) {
        return s.state == db::history::RunState::kRunning && s.step >= 1;
      },
      20s));
  ASSERT_TRUE(st.ctl_->wait_idle(60s));
  const auto last = st.ctl_->last_finished();
  ASSERT_TRUE(last.has_value());
  EXPECT_EQ(last->run_id, id);
  EXPECT_EQ(last->steps, 5);
  EXPECT_EQ(last->step, 5);
  // Four rests' worth of motion cannot calibrate 27 parameters: the worker must say so (failed),
  // not abort, and the capture itself must be complete.
  const db::history::RunRecord rec = st.repo_->show(id).run;
  EXPECT_TRUE(rec.state == db::history::RunState::kFailed ||
              rec.state == db::history::RunState::kReview)
      << db::history::to_string(rec.state);
  if (rec.state == db::history::RunState::kFailed) {
    EXPECT_NE(rec.failure_reason.find("calibration failed"), std::string::npos) << rec.failure_reason;
  }
  EXPECT_EQ(rec.archive_path, run_archive_dir(st.cfg_.data_dir, id, "TINY-1"));
  EXPECT_EQ(rec.archive_sha256, archive_digest(rec.archive_path));
  ASSERT_FALSE(rec.capture_json.empty());

  const db::archive::RunArchive ar = db::archive::read_archive(rec.archive_path);
  ASSERT_TRUE(ar.info.capture.has_value());
  EXPECT_TRUE(ar.info.capture->complete);
  EXPECT_EQ(ar.info.serial, "TINY-1");
  EXPECT_EQ(ar.info.sequence_name, "tiny");
  EXPECT_FALSE(ar.info.end_time.empty());
  // The rests, in order: 1000, 1000, 1200 consecutive at_rest rows (10 s, 10 s, 12 s at 100 Hz), at
  // the sequence's poses.
  struct Block { size_t n = 0; double outer_deg = 0, inner_deg = 0; };
  std::vector<Block> blocks;
  bool prev = false;
  for (const auto& row : ar.table) {
    if (row.at_rest) {
      if (!prev) blocks.push_back({0, row.outer_rad * 180.0 / M_PI, row.inner_rad * 180.0 / M_PI});
      ++blocks.back().n;
    }
    prev = row.at_rest;
  }
  ASSERT_EQ(blocks.size(), 3u);
  EXPECT_EQ(blocks[0].n, 1000u);
  EXPECT_EQ(blocks[1].n, 1000u);
  EXPECT_EQ(blocks[2].n, 1200u);
  const double tol = st.cfg_.turntable.position_tolerance_deg;
  EXPECT_NEAR(blocks[0].outer_deg, 0.0, tol);
  EXPECT_NEAR(blocks[0].inner_deg, 0.0, tol);
  EXPECT_NEAR(blocks[1].outer_deg, 90.0, tol);
  EXPECT_NEAR(blocks[1].inner_deg, 0.0, tol);
  EXPECT_NEAR(blocks[2].outer_deg, 90.0, tol);
  EXPECT_NEAR(blocks[2].inner_deg, 90.0, tol);
  // Rows: one per sample slot, t = (row + 1) / rate; more rows than the rests (settling + moves:
  // two 10 s moves = 2000 rows at least).
  ASSERT_GT(ar.imu.size(), 3200u + 2000u);
  EXPECT_NEAR(ar.imu.back().t_s, static_cast<double>(ar.imu.size()) / 100.0, 1e-9);
  const CaptureStats cs = capture_stats_from_json(nlohmann::json::parse(rec.capture_json));
  EXPECT_EQ(cs.rows_written, ar.imu.size());
  EXPECT_EQ(cs.rest_samples, 3200u);
  EXPECT_EQ(cs.samples_lost, 0u);
  EXPECT_FALSE(st.table_moving());
}

TEST(RunController, ShortSequenceEndsDonePassWithParametersNearTheTruth) {
  Station st(100.0);
  const db::history::RunId id = st.start("SIM-0001", "short");
  ASSERT_TRUE(st.ctl_->wait_idle(60s));
  const db::history::RunDetails d = st.repo_->show(id);
  ASSERT_EQ(d.run.state, db::history::RunState::kDone) << d.run.failure_reason;
  ASSERT_TRUE(d.run.verdict.has_value());
  EXPECT_EQ(*d.run.verdict, db::history::RunVerdict::kPass);
  ASSERT_EQ(d.calibrations.size(), 2u);
  // The AINS estimate against the simulator's true unit, parameter by parameter within 4σ.
  const calib::core::ParamSet truth = st.sim_->config().unit.params;
  const auto& ains = d.calibrations[0];
  ASSERT_EQ(ains.method, db::history::Method::kAins);
  const auto est = ains.params.to_vector(), sig = ains.sigma.to_vector(), tru = truth.to_vector();
  for (int i = 0; i < static_cast<int>(est.size()); ++i) {
    EXPECT_LE(std::abs(est[i] - tru[i]), 4.0 * sig[i] + 1e-12)
        << "parameter " << calib::core::param_info(i).name;
  }
  // Steps of "short": initial rest + 26 [[step]]s.
  EXPECT_EQ(st.ctl_->last_finished()->steps, 27);
  EXPECT_EQ(*st.ctl_->last_finished()->verdict, db::history::RunVerdict::kPass);
}

TEST(RunController, AbortMidRunStopsTheTableAndMarksTheRunAborted) {
  Station st(20.0);  // slow enough to catch the table mid-move
  const db::history::RunId id = st.start("ABORT-1");
  ASSERT_TRUE(st.wait_for([](const RunSnapshot& s) { return s.step == 2 && s.phase == RunPhase::kMoving; }, 30s));
  std::this_thread::sleep_for(50ms);
  EXPECT_TRUE(st.table_moving());
  EXPECT_TRUE(st.ctl_->abort("operator pressed abort"));
  ASSERT_TRUE(st.ctl_->wait_idle(30s));
  const db::history::RunRecord rec = st.repo_->show(id).run;
  EXPECT_EQ(rec.state, db::history::RunState::kAborted);
  EXPECT_EQ(rec.failure_reason, "operator pressed abort");
  // Safe stop: the table decelerates to a standstill short of the 90 deg target.
  bool stopped = false;
  for (int i = 0; i < 200 && !stopped; ++i) {
    stopped = !st.table_moving();
    std::this_thread::sleep_for(10ms);
  }
  EXPECT_TRUE(stopped);
  const double outer = st.sim_->table_server().with_plc(
      [](drivers::simulated::TablePlc& p) { return p.outer_deg(); });
  EXPECT_LT(outer, 89.0);
  // The archive holds what was captured and is finished and readable.
  const db::archive::RunArchive ar = db::archive::read_archive(rec.archive_path);
  EXPECT_EQ(rec.archive_sha256, archive_digest(rec.archive_path));
  EXPECT_FALSE(ar.info.end_time.empty());
  EXPECT_GE(ar.imu.size(), 1000u);  // the whole first rest at least
  EXPECT_FALSE(st.ctl_->abort("again"));  // nothing live any more
}

TEST(RunController, TableFaultMidMoveAbortsWithTheFaultInTheReason) {
  Station st(100.0, drivers::simulated::StationSimFaults::TableFault{
                        2, 1.0, 17});  // 1 s into the second move
  const db::history::RunId id = st.start("FAULT-1");
  ASSERT_TRUE(st.ctl_->wait_idle(30s));
  const db::history::RunRecord rec = st.repo_->show(id).run;
  EXPECT_EQ(rec.state, db::history::RunState::kAborted);
  EXPECT_NE(rec.failure_reason.find("fault"), std::string::npos) << rec.failure_reason;
  EXPECT_NE(rec.failure_reason.find("17"), std::string::npos) << rec.failure_reason;
  EXPECT_FALSE(st.table_moving());
  EXPECT_EQ(st.ctl_->last_finished()->step, 4);  // the second move is step 4 of 5
  const db::archive::RunArchive ar = db::archive::read_archive(rec.archive_path);
  size_t rest_rows = 0;
  for (const auto& r : ar.table) rest_rows += r.at_rest ? 1 : 0;
  EXPECT_EQ(rest_rows, 2000u);  // the two rests before the faulted move
}

TEST(RunController, RefusesBadRequestsWithoutWritingAnything) {
  Station st(100.0);
  auto code_of = [&](const StartRunRequest& r) {
    try {
      st.ctl_->start(r);
    } catch (const ControlError& e) {
      return e.code();
    }
    return std::string("accepted");
  };
  StartRunRequest bad_serial;
  bad_serial.serial = "AB CD";
  EXPECT_EQ(code_of(bad_serial), error_code::kInvalidInput);
  StartRunRequest unknown;
  unknown.serial = "OK-1";
  unknown.sequence = "no-such-sequence";
  EXPECT_EQ(code_of(unknown), error_code::kNotFound);
  // A sequence faster than the station allows (max_rate_dps 20).
  std::ofstream(st.dir_ + "/fast.toml") << std::string(kTinySequence).replace(
      std::string(kTinySequence).find("rate_dps = 10.0"), 15, "rate_dps = 50.0");
  StartRunRequest fast;
  fast.serial = "OK-1";
  fast.sequence = st.dir_ + "/fast.toml";
  EXPECT_EQ(code_of(fast), error_code::kInvalidInput);
  EXPECT_TRUE(
      st.repo_
          ->runs_in_state({db::history::RunState::kPreparing, db::history::RunState::kRunning,
                           db::history::RunState::kCalibrating, db::history::RunState::kFailed,
                           db::history::RunState::kAborted})
          .empty());
  // One at a time.
  st.start("OK-1");
  fast.sequence.reset();
  EXPECT_EQ(code_of(fast), error_code::kBusy);
  st.ctl_->abort("test over");
  EXPECT_TRUE(st.ctl_->wait_idle(30s));
}

}  // namespace
}  // namespace imucal::station
