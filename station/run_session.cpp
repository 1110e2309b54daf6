// One run's capture as named stages (issue #20 item 2): connect the table, home it, connect the
// IMU, open the archive (running), then per planned step a move (moving, settling) or a counted
// rest (settling, resting), the end of the capture, and the hand-over to the calibration worker
// (calibrating) — or, on any failure or abort, the safe stop and the run's terminal record.
//
// The run's life-cycle transitions are in one place, the "transitions" block below: the database
// and the live snapshot change together there and nowhere else in this file.
#include <spdlog/spdlog.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>

#include "db/archive/run_archive.hpp"
#include "drivers/imu/can_channel.hpp"
#include "drivers/turntable/turntable_client.hpp"
#include "station/archive_writer.hpp"
#include "station/capture.hpp"
#include "station/run_controller.hpp"
#include "station/run_live.hpp"

namespace imucal::station {

namespace fs = std::filesystem;
using std::chrono::milliseconds;

struct RunController::Session {
  Session(RunController& controller, const std::shared_ptr<Live>& live)
      : rc(controller), self(live), L(*live), id(live->snap.run_id), plan(live->plan) {}

  /// The stages in order; ends with the run handed to the worker or recorded as ended.
  void run();

 private:
  RunController& rc;
  const std::shared_ptr<Live>& self;
  Live& L;
  const db::RunId id;
  const RunPlan& plan;

  std::unique_ptr<turntable::TurntableClient> client;
  std::unique_ptr<Capture> cap;
  std::unique_ptr<ArchiveWriter> writer;
  archive::RunInfo info;
  double at_outer = 0.0, at_inner = 0.0;  // where the table stands (last in-position reading)

  // How the capture ended.
  bool captured = false;
  db::RunState end_state = db::RunState::kFailed;
  std::string reason;
  std::optional<CaptureStats> stats;
  std::string sha;

  // --- stages ---
  turntable::TableStatus connect_table();
  turntable::TableStatus home(turntable::TableStatus st);
  void connect_imu();
  void open_archive(const turntable::TableStatus& st);
  void run_steps();
  turntable::TableStatus move(double outer, double inner, double rate);
  void rest(double outer, double inner, uint64_t samples);
  void check_rest_table(double outer, double inner, double budget_s, Clock::time_point deadline);
  // --- the end ---
  void ended(db::RunState state, std::string why);
  void resolve_abort();
  void end_capture();
  void close_archive();
  void close_table();
  bool hand_over();
  void record_failure();
  // --- transitions ---
  void enter_running();
  void enter_calibrating();

  void check_abort() {
    std::lock_guard<std::mutex> lk(rc.mu_);
    if (L.abort) throw AbortRequested{};
  }
  void check_capture() {
    if (cap)
      if (auto f = cap->fault()) throw CaptureFailure(*f);
  }
  milliseconds poll() const { return std::max(milliseconds(1), rc.cfg_.turntable.poll_period); }
};

void RunController::capture_run(const std::shared_ptr<Live>& self) { Session(*this, self).run(); }

void RunController::Session::run() {
  try {
    turntable::TableStatus st = home(connect_table());
    connect_imu();
    open_archive(st);
    run_steps();
    check_abort();
    cap->detach();
    check_capture();
    captured = true;
  } catch (const AbortRequested&) {
    ended(db::RunState::kAborted, "");
  } catch (const turntable::AbortedError&) {
    ended(db::RunState::kAborted, "");
  } catch (const turntable::TurntableError& e) {
    ended(db::RunState::kAborted, std::string("table: ") + e.what());
  } catch (const CaptureFailure& e) {
    ended(db::RunState::kFailed, std::string("capture: ") + e.what());
  } catch (const imu::CanChannelError& e) {
    ended(db::RunState::kFailed, std::string("capture: ") + e.what());
  } catch (const std::exception& e) {
    ended(db::RunState::kFailed, e.what());
  }
  resolve_abort();
  if (!captured) {
    spdlog::warn("run {}: {}: {}", id, db::to_string(end_state), reason);
    rc.set_phase(L, RunPhase::kStopping);
    if (client && client->connected()) client->safe_stop();
  }
  end_capture();
  close_archive();
  close_table();
  if (captured && hand_over()) return;
  record_failure();
}

// ----- stages ------------------------------------------------------------------------------------

/// Connects, refuses an open e-stop, clears a standing fault and enables the drives.
turntable::TableStatus RunController::Session::connect_table() {
  rc.set_phase(L, RunPhase::kConnecting);
  client = std::make_unique<turntable::TurntableClient>(rc.cfg_.turntable);
  {
    std::lock_guard<std::mutex> lk(rc.mu_);
    L.client = client.get();
    if (L.abort) client->request_abort();
  }
  check_abort();
  client->connect();
  check_abort();
  const turntable::TableStatus st = client->status();
  if (st.estop)
    throw turntable::EstopError("turntable " + rc.cfg_.turntable.endpoint.to_string() +
                                ": e-stop open");
  if (st.fault) {
    spdlog::warn("run {}: table reports fault code {}; clearing it", id, st.fault_code);
    client->clear_fault();
  }
  client->enable();
  return st;
}

/// Homes the table and brings it to the plan's start attitude.
turntable::TableStatus RunController::Session::home(turntable::TableStatus st) {
  rc.set_phase(L, RunPhase::kHoming);
  st = client->home(milliseconds(static_cast<int64_t>(rc.cfg_.home_timeout_s * 1000.0)));
  check_abort();
  const double tol = rc.cfg_.turntable.position_tolerance_deg;
  if (std::abs(st.outer_deg - plan.start_outer_deg) > tol ||
      std::abs(st.inner_deg - plan.start_inner_deg) > tol)
    st = move(plan.start_outer_deg, plan.start_inner_deg, rc.cfg_.max_rate_dps);
  return st;
}

/// Opens the CAN channel and waits for the IMU's stream.
void RunController::Session::connect_imu() {
  rc.set_phase(L, RunPhase::kConnecting);
  CaptureOptions co;
  co.decoder = decoder_options(rc.cfg_);
  co.max_gap_samples = rc.cfg_.max_gap_samples;
  co.settle_guard_samples = rc.cfg_.settle_guard_samples;
  co.rest_rate_threshold_dps = rc.cfg_.rest_rate_threshold_dps;
  co.stream_timeout = milliseconds(rc.cfg_.stream_timeout_ms);
  cap = std::make_unique<Capture>(imu::CanChannel::open(rc.cfg_.can_uri), co);
  cap->start();
  {
    std::lock_guard<std::mutex> lk(rc.mu_);
    L.capture = cap.get();
  }
  if (!cap->wait_for_stream(co.stream_timeout)) {
    check_capture();
    throw CaptureFailure("no IMU samples on " + rc.cfg_.can_uri + " within " +
                         std::to_string(rc.cfg_.stream_timeout_ms) + " ms");
  }
  {
    std::lock_guard<std::mutex> lk(rc.mu_);
    L.stream_started = Clock::now();
    L.rows_at_stream_start = cap->rows();
  }
  check_abort();
}

/// The run archive opens and the capture starts writing into it: the run is running.
void RunController::Session::open_archive(const turntable::TableStatus& st) {
  const StationConfig& cfg = rc.cfg_;
  info.serial = L.snap.serial;
  info.station_name = cfg.station_name;
  info.site = cfg.site;
  info.imu_rate_hz = cfg.rate_hz;
  info.sequence_name = plan.sequence_name;
  info.sequence_sha256 = plan.sequence_sha256;
  info.software_version = rc.software_version_;
  info.start_time = db::format_time_utc(L.snap.started_at_ms);
  info.reference = archive::ReferenceKind::kTable;
  info.arw_rad_per_sqrt_s = cfg.arw_rad_per_sqrt_s();
  info.vrw_mps_per_sqrt_s = cfg.vrw_mps_per_sqrt_s();
  if (cfg.protocol) {  // the protocol's resolution: the gap diagnosis models its quantisation
    const imu::IncrementResolution q = imu::increment_resolution(*cfg.protocol, 1.0 / cfg.rate_hz);
    info.dtheta_lsb_rad = q.dtheta_rad;
    info.dv_lsb_mps = q.dv_mps;
    info.imu_protocol = cfg.protocol->name;
  }
  info.grade = cfg.grade;
  writer = std::make_unique<ArchiveWriter>(L.snap.archive_path, info);
  cap->table_moving(st.outer_deg, st.inner_deg);
  cap->attach(writer.get());
  enter_running();
  at_outer = st.outer_deg;
  at_inner = st.inner_deg;
}

/// Every planned step: a move, or a counted rest where the table stands.
void RunController::Session::run_steps() {
  for (size_t i = 0; i < plan.steps.size(); ++i) {
    const PlannedStep& p = plan.steps[i];
    {
      std::lock_guard<std::mutex> lk(rc.mu_);
      L.step_index = static_cast<int>(i);
      L.snap.step = static_cast<int>(i) + 1;
      L.step_started = Clock::now();
    }
    check_abort();
    if (p.kind == PlannedStep::Kind::kMove) {
      spdlog::debug("run {}: step {}/{}: move to outer {} deg, inner {} deg at {} deg/s", id, i + 1,
                    plan.steps.size(), p.outer_deg, p.inner_deg, p.rate_dps);
      const turntable::TableStatus st = move(p.outer_deg, p.inner_deg, p.rate_dps);
      at_outer = st.outer_deg;
      at_inner = st.inner_deg;
    } else {
      spdlog::debug("run {}: step {}/{}: rest {} samples", id, i + 1, plan.steps.size(),
                    p.rest_samples);
      rest(at_outer, at_inner, p.rest_samples);
    }
    check_capture();
  }
}

/// Commands a move and polls the table until it is in position, handing every reading to the
/// capture (sample-and-hold angles while moving); the final check is the client's own
/// wait_in_position (fault, e-stop, heartbeat, target reached).
turntable::TableStatus RunController::Session::move(double outer, double inner, double rate) {
  // The next rest may only count IMU samples that show this move happened (the IMU stream can lag
  // the Modbus readings); a move too short to be seen is not waited for.
  if (cap && (std::abs(outer - at_outer) > kVisibleMoveDeg ||
              std::abs(inner - at_inner) > kVisibleMoveDeg))
    cap->move_commanded();
  client->move_to(outer, inner, rate);
  const auto deadline =
      Clock::now() + milliseconds(static_cast<int64_t>(rc.cfg_.move_timeout_s * 1000.0));
  rc.set_phase(L, RunPhase::kMoving);
  for (;;) {
    check_abort();
    const turntable::TableStatus st = client->status();
    if (cap) cap->table_moving(st.outer_deg, st.inner_deg);
    check_capture();
    if (st.fault || st.estop || st.heartbeat_stale) break;
    if (st.in_position && !st.moving) break;
    rc.set_phase(L, st.moving ? RunPhase::kMoving : RunPhase::kSettling);
    if (Clock::now() >= deadline) break;
    std::this_thread::sleep_for(poll());
  }
  const auto left = std::chrono::duration_cast<milliseconds>(deadline - Clock::now());
  return client->wait_in_position(std::max(milliseconds(1), left));
}

/// A counted rest: the capture marks `samples` rows at rest once the unit is still; meanwhile the
/// table is watched (it must hold its position).
void RunController::Session::rest(double outer, double inner, uint64_t samples) {
  cap->begin_rest(outer, inner, samples);
  rc.set_phase(L, RunPhase::kSettling);
  // A unit that never comes to rest: give it the rest's real-time length plus a move timeout.
  const double budget_s =
      static_cast<double>(samples + rc.cfg_.settle_guard_samples) / rc.cfg_.rate_hz +
      rc.cfg_.move_timeout_s;
  const auto deadline = Clock::now() + milliseconds(static_cast<int64_t>(budget_s * 1000.0));
  while (!cap->wait_rest_done(poll())) {
    check_capture();
    check_abort();
    check_rest_table(outer, inner, budget_s, deadline);
  }
}

/// During a rest: the table holds still and fault-free, the IMU has shown the move before it, and
/// the unit comes to rest in time.
void RunController::Session::check_rest_table(double outer, double inner, double budget_s,
                                              Clock::time_point deadline) {
  const turntable::TableStatus st = client->status();
  const std::string where = "turntable " + rc.cfg_.turntable.endpoint.to_string() +
                            " during a rest at outer " + std::to_string(st.outer_deg) +
                            " deg, inner " + std::to_string(st.inner_deg) + " deg";
  if (st.estop) throw turntable::EstopError(where + ": e-stop open");
  if (st.fault)
    throw turntable::TableFaultError(where + ": table fault, code " + std::to_string(st.fault_code),
                                     st.fault_code);
  if (st.heartbeat_stale) throw turntable::HeartbeatError(where + ": PLC heartbeat stuck");
  if (st.moving) throw turntable::MoveTimeoutError(where + ": the table moved during a rest");
  if (cap->rest_rows_done() > 0) rc.set_phase(L, RunPhase::kResting);
  // The table has arrived; the IMU must have seen the move within a few seconds of samples.
  if (cap->unseen_move_samples() > static_cast<uint64_t>(kMoveVisibleWithin_s * rc.cfg_.rate_hz))
    throw CaptureFailure(
        "the IMU did not show the table's move to outer " + std::to_string(outer) + " deg, inner " +
        std::to_string(inner) + " deg (" + std::to_string(static_cast<int>(kMoveVisibleWithin_s)) +
        " s of samples after the table stopped): the unit did not move with the table (loose, or "
        "not on it), or its gyro axis of that rotation is dead");
  if (Clock::now() >= deadline)
    throw CaptureFailure("the unit did not come to rest within " + std::to_string(budget_s) +
                         " s (rest rate threshold " +
                         std::to_string(rc.cfg_.rest_rate_threshold_dps) + " deg/s)");
}

// ----- the end -----------------------------------------------------------------------------------

void RunController::Session::ended(db::RunState state, std::string why) {
  end_state = state;
  reason = std::move(why);
}

/// The operator's reason wins over whatever the abort made the table or capture report (a table
/// link that was down, say): it is what the run ended for. An abort after the last step still wins
/// over calibrating.
void RunController::Session::resolve_abort() {
  {
    std::lock_guard<std::mutex> lk(rc.mu_);
    if (L.abort && !captured) {
      const std::string consequence = reason;
      end_state = db::RunState::kAborted;
      reason = L.abort_reason;
      if (!consequence.empty() && consequence != reason) reason += " (then: " + consequence + ")";
    }
    if (end_state == db::RunState::kAborted && reason.empty()) reason = L.abort_reason;
    if (captured && L.abort) {
      captured = false;
      end_state = db::RunState::kAborted;
      reason = L.abort_reason;
    }
  }
  if (reason.empty()) reason = "aborted";
}

/// The capture ends on every path: no frame is counted after the archive's last one.
void RunController::Session::end_capture() {
  if (!cap) return;
  cap->detach();
  cap->stop();
  stats = cap->stats();
  {
    std::lock_guard<std::mutex> lk(rc.mu_);
    L.capture = nullptr;
    L.snap.capture = stats;
  }
  cap.reset();
}

/// run.toml with the end time and [capture] (complete only when every step ran: an aborted or
/// failed run's archive says so, and its reprocess is refused unless asked for), and the digest.
void RunController::Session::close_archive() {
  if (!writer) return;
  try {
    info.end_time = db::format_time_utc(db::now_ms());
    info.capture = to_capture_info(stats.value_or(CaptureStats{}), captured);
    writer->finish(info);
  } catch (const std::exception& e) {
    spdlog::error("run {}: finishing the archive: {}", id, e.what());
    if (captured) {
      captured = false;
      ended(db::RunState::kFailed, std::string("archive: ") + e.what());
    }
  }
  writer.reset();
  try {
    sha = archive_digest(L.snap.archive_path);
  } catch (const std::exception& e) {
    spdlog::error("run {}: {}", id, e.what());
  }
}

void RunController::Session::close_table() {
  {
    std::lock_guard<std::mutex> lk(rc.mu_);
    L.client = nullptr;
  }
  if (!client) return;
  client->close();
  client.reset();
}

/// The complete archive to the calibration worker; false when the worker refuses it (the daemon
/// is shutting down: the archive is complete, reprocess it later).
bool RunController::Session::hand_over() {
  CalibrationJob job;
  job.run_id = id;
  job.archive_dir = L.snap.archive_path;
  job.archive_sha256 = sha;
  job.capture_json = stats ? to_json(*stats).dump() : std::string();
  rc.apply_calibration_settings(job);
  enter_calibrating();
  spdlog::info("run {}: capture complete ({} rows, {} at rest); calibrating", id,
               stats ? stats->rows_written : 0, stats ? stats->rest_samples : 0);
  try {
    RunController& controller = rc;
    std::shared_ptr<Live> live = self;
    rc.worker_.submit(job, [&controller, live](const CalibrationOutcome& out) {
      controller.on_calibrated(live, out);
    });
    return true;
  } catch (const std::exception& e) {
    std::lock_guard<std::mutex> lk(rc.mu_);
    L.handed_to_worker = false;
    ended(db::RunState::kInterrupted,
          std::string("capture complete but not calibrated: ") + e.what() + "; reprocess the run");
    return false;
  }
}

/// A run that ended before calibrating: its terminal state with the reason, the archive (if one
/// was written), its digest and the capture counters.
void RunController::Session::record_failure() {
  const bool have_archive = fs::exists(fs::path(L.snap.archive_path) / "run.toml");
  db::RunCompletion c;
  c.state = end_state;
  c.ended_at_ms = db::now_ms();
  c.reason = reason;
  if (have_archive) c.archive_path = L.snap.archive_path;
  c.archive_sha256 = sha;
  c.capture_json = stats ? to_json(*stats).dump() : std::string();
  rc.finish_early(L, end_state, reason);
  {
    std::lock_guard<std::mutex> lk(rc.mu_);
    if (!have_archive) L.snap.archive_path.clear();
  }
  rc.record_end(L, c);
}

// ----- transitions (database and live snapshot together) -----------------------------------------

/// preparing -> running: the archive is open and the capture writes into it.
void RunController::Session::enter_running() {
  rc.repo_.update_run_state(id, db::RunState::kRunning);
  {
    std::lock_guard<std::mutex> lk(rc.mu_);
    L.snap.state = db::RunState::kRunning;
  }
  spdlog::info("run {}: running, archive {}", id, L.snap.archive_path);
}

/// running -> calibrating: the capture is complete and the worker takes the run over.
void RunController::Session::enter_calibrating() {
  rc.repo_.update_run_state(id, db::RunState::kCalibrating);
  std::lock_guard<std::mutex> lk(rc.mu_);
  L.snap.state = db::RunState::kCalibrating;
  L.snap.phase = RunPhase::kCalibrating;
  L.handed_to_worker = true;
}

}  // namespace imucal::station
