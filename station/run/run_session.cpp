// One run's capture as named stages (issue #20 item 2): connect the table, home it, connect the
// IMU, open the archive (running), then per planned step a move (moving, settling) or a counted
// rest (settling, resting), the end of the capture, and the hand-over to the calibration worker
// (calibrating) — or, on any failure or abort, the safe stop and the run's terminal record.
//
// The run's life-cycle transitions are in one place, the "transitions" block below: the database
// and the live snapshot change together there and nowhere else in this file.
#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "calib/core/conventions.hpp"
#include "calib/core/readable_number.hpp"
#include "db/archive/run_archive.hpp"
#include "drivers/imu/can_channel.hpp"
#include "drivers/turntable/turntable_client.hpp"
#include "station/run/archive_writer.hpp"
#include "station/run/capture.hpp"
#include "station/run/run_controller.hpp"
#include "station/run/run_live.hpp"

namespace imucal::station::run {
using namespace station::config;

namespace fs = std::filesystem;
using std::chrono::milliseconds;

namespace {
/// An angle or rate in a message a person reads: six significant digits, no trailing zeros
/// (std::to_string printed "90.000000"; issue #50 item 5).
std::string angle_text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.6g", v);
  return buf;
}
}  // namespace

struct RunController::Session {
  Session(RunController& controller, const std::shared_ptr<Live>& live)
      : rc(controller),
        self(live),
        L(*live),
        id(live->units.front().snap.run_id),
        plan(live->plan) {
    units.resize(live->units.size());
    for (size_t i = 0; i < units.size(); ++i) units[i].index = i;
  }

  /// The stages in order; ends with every unit handed to the worker or recorded as ended.
  void run();

 private:
  /// One unit's capture: its link, archive and how it ended.
  struct UnitCapture {
    size_t index = 0;  // into L.units
    std::unique_ptr<Capture> cap;
    std::unique_ptr<ArchiveWriter> writer;
    db::archive::RunInfo info;
    bool live = true;  // still capturing (not dropped alone)
    std::optional<CaptureStats> stats;
    std::string sha;
    std::string archive_error;  // finishing its archive failed: the unit fails
  };

  RunController& rc;
  const std::shared_ptr<Live>& self;
  Live& L;
  const db::history::RunId id;  // the table run's (its first unit's) run id, for the log
  const RunPlan& plan;

  std::unique_ptr<drivers::turntable::TurntableClient> client;
  std::vector<UnitCapture> units;
  double at_outer = 0.0, at_inner = 0.0;  // where the table stands (last in-position reading)

  // How the capture of the units still live ended.
  bool captured = false;
  db::history::RunState end_state = db::history::RunState::kFailed;
  db::history::RunVerdict end_verdict = db::history::RunVerdict::kFailed;  // whose the end was
  std::string reason;

  Unit& unit(const UnitCapture& u) { return L.units[u.index]; }
  const ImuSlotConfig& slot(const UnitCapture& u) { return *L.units[u.index].slot; }
  db::history::RunId run_id(const UnitCapture& u) { return L.units[u.index].snap.run_id; }
  size_t live_units() const {
    return static_cast<size_t>(
        std::count_if(units.begin(), units.end(), [](const UnitCapture& u) { return u.live; }));
  }

  // --- stages ---
  drivers::turntable::TableStatus connect_table();
  drivers::turntable::TableStatus home(drivers::turntable::TableStatus st);
  void connect_imus();
  void open_imu(UnitCapture& u);
  void wait_for_stream(UnitCapture& u);
  void open_archives(const drivers::turntable::TableStatus& st);
  void run_steps();
  drivers::turntable::TableStatus move(double outer, double inner, double rate);
  void rest(double outer, double inner, const PlannedStep& step);
  void check_rest_table(double outer, double inner, double budget_s, Clock::time_point deadline);
  // --- one unit failing while the others go on ---
  void unit_failed(UnitCapture& u, const std::string& why,
                   db::history::RunVerdict verdict = db::history::RunVerdict::kFailed);
  void drop_unit(UnitCapture& u, const std::string& why, db::history::RunVerdict verdict);
  // --- the end ---
  void ended(db::history::RunState state, db::history::RunVerdict verdict, std::string why);
  void resolve_abort();
  void end_capture(UnitCapture& u);
  void close_archive(UnitCapture& u, bool complete);
  void close_table();
  void hand_over(UnitCapture& u);
  void record_failure(UnitCapture& u, db::history::RunState state, db::history::RunVerdict verdict,
                      const std::string& why);
  // --- transitions ---
  void enter_running();
  void enter_calibrating(UnitCapture& u);

  void check_abort() {
    std::lock_guard<std::mutex> lk(rc.mu_);
    if (L.abort) throw AbortRequested{};
  }
  /// A unit whose stream failed ends FAILED alone while others capture; the last one ends the run.
  void check_capture() {
    for (UnitCapture& u : units)
      if (u.live && u.cap)
        if (auto f = u.cap->fault())
          unit_failed(u, *f,
                      u.cap->fault_is_station() ? db::history::RunVerdict::kStationFault
                                                : db::history::RunVerdict::kFailed);
  }
  milliseconds poll() const { return std::max(milliseconds(1), rc.cfg_.turntable.poll_period); }
};

void RunController::capture_run(const std::shared_ptr<Live>& self) { Session(*this, self).run(); }

void RunController::Session::run() {
  try {
    drivers::turntable::TableStatus st = home(connect_table());
    connect_imus();
    open_archives(st);
    run_steps();
    check_abort();
    for (UnitCapture& u : units)
      if (u.live) u.cap->detach();
    check_capture();
    captured = true;
  } catch (const AbortRequested&) {
    ended(db::history::RunState::kAborted, db::history::RunVerdict::kAborted, "");
  } catch (const drivers::turntable::AbortedError&) {
    ended(db::history::RunState::kAborted, db::history::RunVerdict::kAborted, "");
  } catch (const drivers::turntable::TurntableError& e) {
    // The table (its link, drives, e-stop, PLC) ended the capture: the station's, not the unit's.
    ended(db::history::RunState::kAborted, db::history::RunVerdict::kStationFault,
          std::string("table: ") + e.what());
  } catch (const CaptureFailure& e) {
    ended(db::history::RunState::kFailed, e.verdict(), std::string("capture: ") + e.what());
  } catch (const drivers::imu::CanChannelError& e) {
    ended(db::history::RunState::kFailed, db::history::RunVerdict::kStationFault,
          std::string("capture: ") + e.what());
  } catch (const std::exception& e) {
    // Anything else (the archive directory, the disk) is the station's: the unit's own failures
    // arrive as CaptureFailure.
    ended(db::history::RunState::kFailed, db::history::RunVerdict::kStationFault, e.what());
  }
  resolve_abort();
  if (!captured) {
    spdlog::warn("run {}: {}: {}", id, db::history::to_string(end_state), reason);
    rc.set_phase(L, RunPhase::kStopping);
    if (client && client->connected()) client->safe_stop();
  }
  for (UnitCapture& u : units)
    if (u.live) {
      end_capture(u);
      close_archive(u, captured);
    }
  close_table();
  for (UnitCapture& u : units) {
    if (!u.live) continue;
    if (!u.archive_error.empty())
      record_failure(u, db::history::RunState::kFailed, db::history::RunVerdict::kStationFault,
                     "archive: " + u.archive_error);
    else if (captured)
      hand_over(u);
    else
      record_failure(u, end_state, end_verdict, reason);
  }
}

// ----- stages ------------------------------------------------------------------------------------

/// Connects, refuses an open e-stop, clears a standing fault and enables the drives.
drivers::turntable::TableStatus RunController::Session::connect_table() {
  rc.set_phase(L, RunPhase::kConnecting);
  client = std::make_unique<drivers::turntable::TurntableClient>(rc.cfg_.turntable);
  {
    std::lock_guard<std::mutex> lk(rc.mu_);
    L.client = client.get();
    if (L.abort) client->request_abort();
  }
  check_abort();
  client->connect();
  check_abort();
  const drivers::turntable::TableStatus st = client->status();
  if (st.estop)
    throw drivers::turntable::EstopError("turntable " + rc.cfg_.turntable.endpoint.to_string() +
                                         ": e-stop open");
  if (st.fault) {
    spdlog::warn("run {}: table reports fault code {}; clearing it", id, st.fault_code);
    client->clear_fault();
  }
  client->enable();
  return st;
}

/// Homes the table and brings it to the plan's start attitude.
drivers::turntable::TableStatus RunController::Session::home(drivers::turntable::TableStatus st) {
  rc.set_phase(L, RunPhase::kHoming);
  st = client->home(milliseconds(static_cast<int64_t>(rc.cfg_.home_timeout_s * 1000.0)));
  check_abort();
  const double tol = rc.cfg_.turntable.position_tolerance_deg;
  if (std::abs(st.outer_deg - plan.start_outer_deg) > tol ||
      std::abs(st.inner_deg - plan.start_inner_deg) > tol)
    st = move(plan.start_outer_deg, plan.start_inner_deg, rc.cfg_.max_rate_dps);
  return st;
}

/// Opens every unit's CAN channel, then waits for each stream (the units were powered on together);
/// a unit without one fails alone (the run goes on with the others) unless it is the last.
void RunController::Session::connect_imus() {
  rc.set_phase(L, RunPhase::kConnecting);
  for (bool waiting : {false, true}) {
    for (UnitCapture& u : units) {
      if (!u.live) continue;
      try {
        waiting ? wait_for_stream(u) : open_imu(u);
      } catch (const CaptureFailure& e) {
        unit_failed(u, e.what(), e.verdict());
      } catch (const drivers::imu::CanChannelError& e) {
        unit_failed(u, e.what(), db::history::RunVerdict::kStationFault);
      }
    }
  }
  {
    std::lock_guard<std::mutex> lk(rc.mu_);
    L.stream_started = Clock::now();
    for (UnitCapture& u : units)
      if (u.live) unit(u).rows_at_stream_start = u.cap->rows();
  }
  check_abort();
}

void RunController::Session::open_imu(UnitCapture& u) {
  const ImuSlotConfig& s = slot(u);
  CaptureOptions co;
  co.decoder = decoder_options(s);
  co.max_gap_samples = s.max_gap_samples;
  co.settle_guard_samples = s.settle_guard_samples;
  co.rest_rate_threshold_dps = s.rest_rate_threshold_dps;
  co.stream_timeout = milliseconds(s.stream_timeout_ms);
  u.cap = std::make_unique<Capture>(drivers::imu::CanChannel::open(s.can_uri), co);
  u.cap->start();
  std::lock_guard<std::mutex> lk(rc.mu_);
  unit(u).capture = u.cap.get();
}

void RunController::Session::wait_for_stream(UnitCapture& u) {
  const ImuSlotConfig& s = slot(u);
  if (!u.cap->wait_for_stream(milliseconds(s.stream_timeout_ms))) {
    if (auto f = u.cap->fault())
      throw CaptureFailure(*f, u.cap->fault_is_station() ? db::history::RunVerdict::kStationFault
                                                         : db::history::RunVerdict::kFailed);
    throw CaptureFailure("no IMU samples on " + s.can_uri + " within " +
                         std::to_string(s.stream_timeout_ms) + " ms");
  }
}

/// Every unit's run archive opens and its capture starts writing into it: the run is running.
void RunController::Session::open_archives(const drivers::turntable::TableStatus& st) {
  const StationConfig& cfg = rc.cfg_;
  for (UnitCapture& u : units) {
    if (!u.live) continue;
    const ImuSlotConfig& s = slot(u);
    db::archive::RunInfo& info = u.info;
    info.serial = unit(u).snap.serial;
    info.station_name = cfg.station_name;
    info.site = cfg.site;
    info.imu_rate_hz = s.rate_hz;
    info.sequence_name = plan.sequence_name;
    info.sequence_sha256 = plan.sequence_sha256;
    info.software_version = rc.software_version_;
    info.start_time = db::history::format_time_utc(unit(u).snap.started_at_ms);
    info.reference = db::archive::ReferenceKind::kTable;
    info.arw_rad_per_sqrt_s = s.arw_rad_per_sqrt_s();
    info.vrw_mps_per_sqrt_s = s.vrw_mps_per_sqrt_s();
    if (s.protocol) {  // the protocol's resolution: the gap diagnosis models its quantisation
      const drivers::imu::IncrementResolution q =
          drivers::imu::increment_resolution(*s.protocol, 1.0 / s.rate_hz);
      info.dtheta_lsb_rad = q.dtheta_rad;
      info.dv_lsb_mps = q.dv_mps;
      info.imu_protocol = s.protocol->name;
    }
    info.grade = s.grade;
    info.table.slot = unit(u).snap.slot;
    for (int k = 0; k < 3; ++k) {
      info.table.mount_rpy_rad(k) = s.mount_rpy_deg[static_cast<size_t>(k)] * kDegToRad;
      info.table.lever_arm_m(k) = s.lever_arm_m[static_cast<size_t>(k)];
    }
    u.writer = std::make_unique<ArchiveWriter>(unit(u).snap.archive_path, info);
    u.cap->table_moving(st.outer_deg, st.inner_deg);
    u.cap->attach(u.writer.get());
  }
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
      L.step_started = Clock::now();
      for (Unit& u : L.units)
        if (!u.ended) u.snap.step = static_cast<int>(i) + 1;
    }
    check_abort();
    if (p.kind == PlannedStep::Kind::kMove) {
      spdlog::debug("run {}: step {}/{}: move to outer {} deg, inner {} deg at {} deg/s", id, i + 1,
                    plan.steps.size(), p.outer_deg, p.inner_deg, p.rate_dps);
      const drivers::turntable::TableStatus st = move(p.outer_deg, p.inner_deg, p.rate_dps);
      at_outer = st.outer_deg;
      at_inner = st.inner_deg;
    } else {
      spdlog::debug("run {}: step {}/{}: rest {} s", id, i + 1, plan.steps.size(), p.rest_s);
      rest(at_outer, at_inner, p);
    }
    check_capture();
  }
}

/// Commands a move and polls the table until it is in position, handing every reading to the
/// captures (sample-and-hold angles while moving); the final check is the client's own
/// wait_in_position (fault, e-stop, heartbeat, target reached).
drivers::turntable::TableStatus RunController::Session::move(double outer, double inner,
                                                             double rate) {
  // The next rest may only count IMU samples that show this move happened (the IMU stream can lag
  // the Modbus readings); a move too short to be seen is not waited for.
  if (std::abs(outer - at_outer) > kVisibleMoveDeg || std::abs(inner - at_inner) > kVisibleMoveDeg)
    for (UnitCapture& u : units)
      if (u.live && u.cap) u.cap->move_commanded();
  client->move_to(outer, inner, rate);
  const auto deadline =
      Clock::now() + milliseconds(static_cast<int64_t>(rc.cfg_.move_timeout_s * 1000.0));
  rc.set_phase(L, RunPhase::kMoving);
  for (;;) {
    check_abort();
    const drivers::turntable::TableStatus st = client->status();
    for (UnitCapture& u : units)
      if (u.live && u.cap) u.cap->table_moving(st.outer_deg, st.inner_deg);
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

/// A counted rest: each capture marks its rest's samples (rest_s at its unit's rate) at rest once
/// its unit is still; meanwhile the table is watched (it must hold its position).
void RunController::Session::rest(double outer, double inner, const PlannedStep& step) {
  double budget_s = 0.0;
  for (UnitCapture& u : units) {
    if (!u.live) continue;
    const ImuSlotConfig& s = slot(u);
    const uint64_t samples = step.rest_samples(s.rate_hz);
    u.cap->begin_rest(outer, inner, samples);
    // A unit that never comes to rest: give it the rest's real-time length plus a move timeout.
    budget_s =
        std::max(budget_s, static_cast<double>(samples + s.settle_guard_samples) / s.rate_hz +
                               rc.cfg_.move_timeout_s);
  }
  rc.set_phase(L, RunPhase::kSettling);
  const auto deadline = Clock::now() + milliseconds(static_cast<int64_t>(budget_s * 1000.0));
  for (;;) {
    bool done = true;
    for (UnitCapture& u : units)
      if (u.live && !u.cap->wait_rest_done(done ? poll() : milliseconds(0))) done = false;
    if (done) return;
    check_capture();
    check_abort();
    check_rest_table(outer, inner, budget_s, deadline);
  }
}

/// During a rest: the table holds still and fault-free, each unit has shown the move before it,
/// and comes to rest in time.
void RunController::Session::check_rest_table(double outer, double inner, double budget_s,
                                              Clock::time_point deadline) {
  const drivers::turntable::TableStatus st = client->status();
  const std::string where = "turntable " + rc.cfg_.turntable.endpoint.to_string() +
                            " during a rest at outer " + std::to_string(st.outer_deg) +
                            " deg, inner " + std::to_string(st.inner_deg) + " deg";
  if (st.estop) throw drivers::turntable::EstopError(where + ": e-stop open");
  if (st.fault)
    throw drivers::turntable::TableFaultError(
        where + ": table fault, code " + std::to_string(st.fault_code), st.fault_code);
  if (st.heartbeat_stale) throw drivers::turntable::HeartbeatError(where + ": PLC heartbeat stuck");
  if (st.moving)
    throw drivers::turntable::MoveTimeoutError(where + ": the table moved during a rest");
  if (std::any_of(units.begin(), units.end(),
                  [](const UnitCapture& u) { return u.live && u.cap->rest_rows_done() > 0; }))
    rc.set_phase(L, RunPhase::kResting);
  for (UnitCapture& u : units) {
    if (!u.live) continue;
    const ImuSlotConfig& s = slot(u);
    // The table has arrived; the IMU must have seen the move within a few seconds of samples.
    if (u.cap->unseen_move_samples() > static_cast<uint64_t>(kMoveVisibleWithin_s * s.rate_hz))
      unit_failed(u, "the IMU did not show the table's move to outer " + angle_text(outer) +
                         " deg, inner " + angle_text(inner) + " deg (" +
                         std::to_string(static_cast<int>(kMoveVisibleWithin_s)) +
                         " s of samples after the table stopped): the unit did not move with the "
                         "table (loose, or not on it), or its gyro axis of that rotation is dead");
    else if (Clock::now() >= deadline && !u.cap->wait_rest_done(milliseconds(0)))
      unit_failed(u, "the unit did not come to rest within " + calib::core::seconds_text(budget_s) +
                         " (rest rate threshold " + angle_text(s.rest_rate_threshold_dps) +
                         " deg/s)");
  }
}

// ----- one unit failing while the others go on ---------------------------------------------------

/// A unit's capture failed: alone it ends the run (CaptureFailure); beside others it ends FAILED
/// on its own and the table goes on for them.
void RunController::Session::unit_failed(UnitCapture& u, const std::string& why,
                                         db::history::RunVerdict verdict) {
  if (live_units() <= 1) throw CaptureFailure(why, verdict);
  drop_unit(u, "capture: " + why, verdict);
}

void RunController::Session::drop_unit(UnitCapture& u, const std::string& why,
                                       db::history::RunVerdict verdict) {
  spdlog::warn("run {} (slot {}): failed alone, the table run goes on: {}", run_id(u), slot(u).name,
               why);
  u.live = false;
  end_capture(u);
  close_archive(u, false);
  record_failure(u, db::history::RunState::kFailed, verdict, why);
}

// ----- the end -----------------------------------------------------------------------------------

void RunController::Session::ended(db::history::RunState state, db::history::RunVerdict verdict,
                                   std::string why) {
  end_state = state;
  end_verdict = verdict;
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
      end_state = db::history::RunState::kAborted;
      end_verdict = db::history::RunVerdict::kAborted;
      reason = L.abort_reason;
      if (!consequence.empty() && consequence != reason) reason += " (then: " + consequence + ")";
    }
    if (end_state == db::history::RunState::kAborted && reason.empty()) reason = L.abort_reason;
    if (captured && L.abort) {
      captured = false;
      end_state = db::history::RunState::kAborted;
      end_verdict = db::history::RunVerdict::kAborted;
      reason = L.abort_reason;
    }
  }
  if (reason.empty()) reason = "aborted";
}

/// The capture ends on every path: no frame is counted after the archive's last one.
void RunController::Session::end_capture(UnitCapture& u) {
  if (!u.cap) return;
  u.cap->detach();
  u.cap->stop();
  u.stats = u.cap->stats();
  {
    std::lock_guard<std::mutex> lk(rc.mu_);
    unit(u).capture = nullptr;
    unit(u).snap.capture = u.stats;
  }
  u.cap.reset();
}

/// run.toml with the end time and [capture] (complete only when every step ran: an aborted or
/// failed run's archive says so, and its reprocess is refused unless asked for), and the digest.
void RunController::Session::close_archive(UnitCapture& u, bool complete) {
  if (!u.writer) return;
  try {
    u.info.end_time = db::history::format_time_utc(db::history::now_ms());
    u.info.capture = to_capture_info(u.stats.value_or(CaptureStats{}), complete);
    u.writer->finish(u.info);
  } catch (const std::exception& e) {
    spdlog::error("run {}: finishing the archive: {}", run_id(u), e.what());
    if (complete) u.archive_error = e.what();
  }
  u.writer.reset();
  try {
    u.sha = archive_digest(unit(u).snap.archive_path);
  } catch (const std::exception& e) {
    spdlog::error("run {}: {}", run_id(u), e.what());
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

/// The complete archive to the calibration worker; when the worker refuses it (the daemon is
/// shutting down) the unit ends interrupted: the archive is complete, reprocess it later.
void RunController::Session::hand_over(UnitCapture& u) {
  const db::history::RunId rid = run_id(u);
  CalibrationJob job;
  job.run_id = rid;
  job.archive_dir = unit(u).snap.archive_path;
  job.archive_sha256 = u.sha;
  job.capture_json = u.stats ? to_json(*u.stats).dump() : std::string();
  rc.apply_calibration_settings(job);
  enter_calibrating(u);
  spdlog::info("run {}: capture complete ({} rows, {} at rest); calibrating", rid,
               u.stats ? u.stats->rows_written : 0, u.stats ? u.stats->rest_samples : 0);
  try {
    RunController& controller = rc;
    std::shared_ptr<Live> live = self;
    const size_t index = u.index;
    rc.worker_.submit(job, [&controller, live, index](const CalibrationOutcome& out) {
      controller.on_calibrated(live, index, out);
    });
  } catch (const std::exception& e) {
    {
      std::lock_guard<std::mutex> lk(rc.mu_);
      unit(u).handed_to_worker = false;
    }
    record_failure(
        u, db::history::RunState::kInterrupted, db::history::RunVerdict::kInterrupted,
        std::string("capture complete but not calibrated: ") + e.what() + "; reprocess the run");
  }
}

/// A unit that ended before calibrating: its terminal state with the reason, the archive (if one
/// was written), its digest and the capture counters.
void RunController::Session::record_failure(UnitCapture& u, db::history::RunState state,
                                            db::history::RunVerdict verdict,
                                            const std::string& why) {
  Unit& un = unit(u);
  const bool have_archive = fs::exists(fs::path(un.snap.archive_path) / "run.toml");
  db::history::RunCompletion c;
  c.state = state;
  c.verdict = verdict;
  c.ended_at_ms = db::history::now_ms();
  c.reason = why;
  if (have_archive) c.archive_path = un.snap.archive_path;
  c.archive_sha256 = u.sha;
  c.capture_json = u.stats ? to_json(*u.stats).dump() : std::string();
  rc.finish_early(un, state, verdict, why);
  {
    std::lock_guard<std::mutex> lk(rc.mu_);
    if (!have_archive) un.snap.archive_path.clear();
  }
  rc.record_end(L, un, c);
}

// ----- transitions (database and live snapshot together) -----------------------------------------

/// preparing -> running: the archives are open and the captures write into them.
void RunController::Session::enter_running() {
  for (UnitCapture& u : units) {
    if (!u.live) continue;
    rc.repo_.update_run_state(run_id(u), db::history::RunState::kRunning);
    {
      std::lock_guard<std::mutex> lk(rc.mu_);
      unit(u).snap.state = db::history::RunState::kRunning;
    }
    spdlog::info("run {}: running, archive {}", run_id(u), unit(u).snap.archive_path);
  }
}

/// running -> calibrating: the capture is complete and the worker takes the unit over.
void RunController::Session::enter_calibrating(UnitCapture& u) {
  rc.repo_.update_run_state(run_id(u), db::history::RunState::kCalibrating);
  std::lock_guard<std::mutex> lk(rc.mu_);
  Unit& un = unit(u);
  un.snap.state = db::history::RunState::kCalibrating;
  un.snap.phase = RunPhase::kCalibrating;
  un.handed_to_worker = true;
}

}  // namespace imucal::station::run
