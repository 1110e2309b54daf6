#include "station/run_controller.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "db/archive/run_archive.hpp"
#include "db/serial_number.hpp"
#include "drivers/imu/can_channel.hpp"
#include "drivers/turntable/turntable_client.hpp"
#include "sequences/library.hpp"
#include "sequences/parser.hpp"
#include "sequences/validator.hpp"
#include "station/archive_writer.hpp"
#include "station/capture.hpp"
#include "station/end_note.hpp"
#include "station/gap_check.hpp"
#include "station/import_staging.hpp"
#include "station/time_left.hpp"

namespace imucal::station {

namespace fs = std::filesystem;
using std::chrono::milliseconds;
using Clock = std::chrono::steady_clock;

const char* to_string(RunPhase p) {
  switch (p) {
    case RunPhase::kNone:
      return "";
    case RunPhase::kConnecting:
      return "connecting";
    case RunPhase::kHoming:
      return "homing";
    case RunPhase::kMoving:
      return "moving";
    case RunPhase::kSettling:
      return "settling";
    case RunPhase::kResting:
      return "resting";
    case RunPhase::kCalibrating:
      return "calibrating";
    case RunPhase::kStopping:
      return "stopping";
  }
  return "";
}

nlohmann::json to_json(const RunSnapshot& r) {
  using nlohmann::json;
  const bool live = !db::is_terminal(r.state);
  json o;
  o["run_id"] = r.run_id;
  o["serial"] = r.serial;
  o["sequence"] = r.sequence;
  o["operator"] = r.operator_name;
  o["state"] = db::to_string(r.state);
  o["phase"] = r.phase == RunPhase::kNone ? json(nullptr) : json(to_string(r.phase));
  o["step"] =
      live && r.steps > 0 && r.step > 0 ? json(r.step) : json(nullptr);  // null while preparing
  o["steps"] = r.steps > 0 ? json(r.steps) : json(nullptr);
  o["time_left_s"] = live && r.time_left_s ? json(*r.time_left_s) : json(nullptr);
  o["verdict"] = r.verdict ? json(db::to_string(*r.verdict)) : json(nullptr);
  o["crosscheck_verdict"] =
      r.crosscheck_verdict ? json(db::to_string(*r.crosscheck_verdict)) : json(nullptr);
  o["reason"] = r.reason;
  o["started_at"] = r.started_at_ms ? json(db::format_time_utc(r.started_at_ms)) : json(nullptr);
  o["ended_at"] = r.ended_at_ms ? json(db::format_time_utc(*r.ended_at_ms)) : json(nullptr);
  o["capture"] = r.capture ? to_json(*r.capture) : json(nullptr);
  o["archive"] = r.archive_path;
  o["reprocessed_from"] = r.reprocessed_from ? json(*r.reprocessed_from) : json(nullptr);
  return o;
}

RunSnapshot snapshot_from_record(const db::RunRecord& rec) {
  RunSnapshot s;
  s.run_id = rec.run_id;
  s.serial = rec.serial;
  s.sequence = rec.sequence_name;
  s.operator_name = rec.operator_name;
  s.state = rec.state;
  s.phase = rec.state == db::RunState::kCalibrating ? RunPhase::kCalibrating : RunPhase::kNone;
  s.verdict = rec.verdict;
  s.crosscheck_verdict = rec.crosscheck_verdict;
  s.reason = rec.failure_reason;
  s.started_at_ms = rec.started_at_ms;
  s.ended_at_ms = rec.ended_at_ms;
  s.archive_path = rec.archive_path;
  s.reprocessed_from = rec.reprocessed_from;
  if (!rec.capture_json.empty()) {
    try {
      s.capture = capture_stats_from_json(nlohmann::json::parse(rec.capture_json));
    } catch (const std::exception& e) {
      spdlog::warn("run {}: stored capture counters unreadable: {}", rec.run_id, e.what());
    }
  }
  return s;
}

namespace {

/// Moves longer than this are seen by the IMU (above rest_rate_threshold_dps at any realistic
/// table acceleration), so the rest after them waits for the motion in the IMU stream.
constexpr double kVisibleMoveDeg = 0.01;
/// How long (in IMU samples, as seconds at the configured rate) after a rest begins a commanded
/// move may still be invisible in the IMU stream before the run fails: a unit that does not turn
/// with the table never shows it.
constexpr double kMoveVisibleWithin_s = 5.0;

/// Rest-to-rest time of a trapezoidal (or triangular) move, s.
double move_time_s(double distance_deg, double rate_dps, double accel_dps2) {
  const double d = std::abs(distance_deg);
  if (rate_dps <= 0 || accel_dps2 <= 0) return 0.0;
  if (d >= rate_dps * rate_dps / accel_dps2) return d / rate_dps + rate_dps / accel_dps2;
  return 2.0 * std::sqrt(d / accel_dps2);
}

/// The operator (or SIGTERM) asked to stop; carries no text (the reason is in Live).
struct AbortRequested {};

/// The IMU side failed: run -> failed.
class CaptureFailure : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace

RunPlan plan_run(const std::string& sequence, const StationConfig& cfg) {
  RunPlan plan;
  plan.sequence_path = sequences::resolve_sequence(sequence);
  const sequences::Sequence seq = sequences::parse_sequence_file(plan.sequence_path);
  sequences::TableLimits limits;
  limits.max_rate_dps = cfg.max_rate_dps;
  sequences::validate_or_throw(seq, sequences::effective_limits(limits, seq.limits));
  plan.sequence_name = seq.name;
  plan.sequence_sha256 = sequences::sequence_hash(plan.sequence_path);
  plan.start_outer_deg = seq.start.outer_deg;
  plan.start_inner_deg = seq.start.inner_deg;

  const double guard_s = static_cast<double>(cfg.settle_guard_samples) / cfg.rate_hz;
  auto rest = [&](double rest_s, double outer, double inner, int line) {
    PlannedStep p;
    p.kind = PlannedStep::Kind::kRest;
    p.outer_deg = outer;
    p.inner_deg = inner;
    p.rest_samples = static_cast<uint64_t>(std::llround(rest_s * cfg.rate_hz));
    p.expected_s = rest_s + guard_s;
    p.source_line = line;
    return p;
  };
  double outer = seq.start.outer_deg, inner = seq.start.inner_deg;
  plan.steps.push_back(rest(seq.start.rest_s, outer, inner, seq.start.rest_line));
  for (const auto& st : seq.steps) {
    if (st.kind == sequences::StepKind::kRest) {
      plan.steps.push_back(rest(st.duration_s, outer, inner, st.line));
      continue;
    }
    double& axis = st.axis == sequences::Axis::kOuter ? outer : inner;
    const double from = axis;
    axis = st.to_deg ? *st.to_deg : axis + st.by_deg.value_or(0.0);
    PlannedStep p;
    p.kind = PlannedStep::Kind::kMove;
    p.outer_deg = outer;
    p.inner_deg = inner;
    p.rate_dps = std::min(st.rate_dps, cfg.max_rate_dps);
    p.expected_s = move_time_s(axis - from, p.rate_dps, st.accel_dps2);
    p.source_line = st.line;
    plan.steps.push_back(p);
  }
  return plan;
}

struct RunController::Live {
  RunSnapshot snap;  // everything below: guarded by the controller's mutex
  RunPlan plan;
  bool reprocess = false;
  bool abort = false;
  std::string abort_reason;
  turntable::TurntableClient* client = nullptr;
  Capture* capture = nullptr;
  int step_index = -1;  // into plan.steps; -1 while preparing
  Clock::time_point step_started{};
  bool handed_to_worker = false;
  Clock::time_point stream_started{};  // when the first IMU samples arrived
  uint64_t rows_at_stream_start = 0;
  mutable TimeLeftEstimator time_left;  // active() is const; the estimate only ever shrinks
};

RunController::RunController(const StationConfig& config, db::Repository& repository,
                             CalibrationWorker& worker, std::string software_version)
    : cfg_(config),
      repo_(repository),
      worker_(worker),
      software_version_(std::move(software_version)) {}

RunController::~RunController() { shutdown("daemon shutting down"); }

std::string run_archive_dir(const std::string& data_dir, db::RunId id, const std::string& serial) {
  return (fs::path(data_dir) / "runs" / (std::to_string(id) + "-" + serial)).string();
}

std::string RunController::archive_dir_for(db::RunId id, const std::string& serial) const {
  return run_archive_dir(cfg_.data_dir, id, serial);
}

nlohmann::json RunController::start(const StartRunRequest& request) {
  if (auto problem = db::serial_problem(request.serial)) {
    throw ControlError(error_code::kInvalidInput, *problem);
  }
  const std::string seq_name = request.sequence.value_or(cfg_.default_sequence);
  std::string seq_path;
  try {
    seq_path = sequences::resolve_sequence(seq_name);
  } catch (const sequences::SequenceError& e) {
    throw ControlError(error_code::kNotFound,
                       e.what());  // names the sequence (and the library's, for a bare name)
  }
  RunPlan plan;
  try {
    plan = plan_run(seq_path, cfg_);
  } catch (const sequences::SequenceError& e) {
    // The file exists but is malformed or asks more than the station's limits allow.
    throw ControlError(error_code::kInvalidInput, e.what());
  }

  std::unique_lock<std::mutex> lk(mu_);
  if (shut_down_) throw ControlError(error_code::kUnavailable, "the daemon is shutting down");
  if (live_) {
    throw ControlError(error_code::kBusy, "run " + std::to_string(live_->snap.run_id) + " (" +
                                              live_->snap.serial + ") is " +
                                              db::to_string(live_->snap.state) +
                                              "; one run at a time (abort it or wait)");
  }
  if (thread_.joinable()) thread_.join();  // the previous run's control thread has ended
  try {
    fs::create_directories(fs::path(cfg_.data_dir) / "runs");
  } catch (const std::exception& e) {
    throw ControlError(
        error_code::kUnavailable,
        "cannot create " + (fs::path(cfg_.data_dir) / "runs").string() + ": " + e.what());
  }

  const db::NewRun nr = new_run(request.serial, request.operator_name, plan.sequence_name,
                                plan.sequence_sha256, db::RunState::kPreparing);
  const db::RunId id = repo_.create_run(nr);

  auto live = std::make_shared<Live>();
  live->plan = std::move(plan);
  live->snap.run_id = id;
  live->snap.serial = nr.serial;
  live->snap.sequence = nr.sequence_name;
  live->snap.operator_name = nr.operator_name;
  live->snap.state = db::RunState::kPreparing;
  live->snap.phase = RunPhase::kConnecting;
  live->snap.steps = static_cast<int>(live->plan.steps.size());
  live->snap.started_at_ms = nr.started_at_ms;
  live->snap.archive_path = archive_dir_for(id, nr.serial);
  if (const std::string err = reserve_end_note(end_note_path(cfg_.data_dir, id)); !err.empty())
    spdlog::warn(
        "run {}: no end note reserved ({}); if the disk fills up, a restart before "
        "space returns will not know why the run ended",
        id, err);
  live_ = live;
  spdlog::info("run {}: serial {}, sequence {} ({} steps), operator {}", id, nr.serial,
               nr.sequence_name, live->snap.steps, nr.operator_name);
  thread_ = std::thread([this, live] { control_thread(live); });
  return {{"run_id", id},
          {"serial", nr.serial},
          {"sequence", nr.sequence_name},
          {"steps", live->snap.steps}};
}

db::RunDetails RunController::stored_run_with_archive(db::RunId run_id, const char* what,
                                                      std::string& digest) const {
  if (shut_down_) throw ControlError(error_code::kUnavailable, "the daemon is shutting down");
  if (live_) {
    throw ControlError(error_code::kBusy, "run " + std::to_string(live_->snap.run_id) + " is " +
                                              db::to_string(live_->snap.state) +
                                              "; one run at a time");
  }
  db::RunDetails d;
  try {
    d = repo_.show(run_id);
  } catch (const db::NotFound& e) {
    throw ControlError(error_code::kNotFound, e.what());
  }
  const db::RunRecord& orig = d.run;
  if (!db::is_terminal(orig.state)) {
    throw ControlError(error_code::kBusy,
                       "run " + std::to_string(run_id) + " is still " + db::to_string(orig.state));
  }
  if (orig.archive_path.empty() || !fs::is_directory(orig.archive_path)) {
    throw ControlError(
        error_code::kNotFound,
        "run " + std::to_string(run_id) + " has no archive" +
            (orig.archive_path.empty() ? "" : " (" + orig.archive_path + " is missing)"));
  }
  if (orig.archive_sha256.empty()) {
    throw ControlError(error_code::kInvalidInput, "run " + std::to_string(run_id) +
                                                      " has no recorded archive SHA-256 to check " +
                                                      orig.archive_path + " against");
  }
  try {
    digest = archive_digest(orig.archive_path);
  } catch (const std::exception& e) {
    throw ControlError(error_code::kUnavailable, e.what());
  }
  if (digest != orig.archive_sha256) {
    throw ControlError(error_code::kInvalidInput,
                       "archive " + orig.archive_path + " of run " + std::to_string(run_id) +
                           " has changed since it was recorded (SHA-256 now " + digest +
                           ", recorded " + orig.archive_sha256 + "); not " + what);
  }
  return d;
}

nlohmann::json RunController::diagnose(db::RunId run_id) {
  // Held throughout: no run starts while the diagnosis takes the CPU (about a second).
  std::lock_guard<std::mutex> lk(mu_);
  std::string digest;
  const db::RunDetails d = stored_run_with_archive(run_id, "diagnosing", digest);
  nlohmann::json full;
  try {
    full = diagnose_archive(d.run.archive_path);
  } catch (const std::exception& e) {
    throw ControlError(error_code::kInvalidInput,
                       "run " + std::to_string(run_id) + ": diagnosis failed: " + e.what());
  }
  repo_.set_diagnosis(run_id, full.at("stored_summary").dump());
  full.erase("stored_summary");
  full["run_id"] = run_id;
  spdlog::info("run {}: diagnosed: {}", run_id, full.value("summary", std::string()));
  return full;
}

namespace {

/// Why a stored run's archive is incomplete, "" if it is complete: its run.toml says the capture
/// did not complete, or the run ended before its capture did (aborted, or failed for anything but
/// the calibration itself — archives written before run.toml said so claim complete).
std::string partial_archive_reason(const db::RunRecord& run) {
  const std::string path = (fs::path(run.archive_path) / "run.toml").string();
  try {
    std::ifstream in(path);
    std::ostringstream ss;
    ss << in.rdbuf();
    const archive::RunInfo info = archive::parse_run_info(ss.str(), path);
    if (info.capture && !info.capture->complete)
      return "its archive is incomplete (run.toml [capture] complete = false)";
  } catch (const std::exception& e) {
    return std::string("its run.toml cannot be read: ") + e.what();
  }
  // Interrupted runs: recovery marked a cut archive incomplete above and left a finished one
  // (killed while calibrating) complete.
  const bool calibration_failure = run.failure_reason.rfind("calibration failed", 0) == 0;
  if (run.state == db::RunState::kAborted ||
      (run.state == db::RunState::kFailed && !calibration_failure))
    return std::string("the run ended ") + db::to_string(run.state) +
           " before its capture completed (" + run.failure_reason + ")";
  return "";
}

/// Whether the archive's imu.csv has a data row after its header (a run killed or stopped
/// before its first sample keeps an archive without any: nothing to calibrate).
bool archive_has_data(const std::string& dir) {
  std::ifstream in((fs::path(dir) / "imu.csv").string());
  std::string line;
  if (!std::getline(in, line)) return false;  // not even a header
  while (std::getline(in, line))
    if (!line.empty() && line != "\r") return true;
  return false;
}

}  // namespace

nlohmann::json RunController::reprocess(const ReprocessRequest& request) {
  const db::RunId run_id = request.run_id;
  std::unique_lock<std::mutex> lk(mu_);
  std::string digest;
  const db::RunDetails d = stored_run_with_archive(run_id, "reprocessing", digest);
  const db::RunRecord& orig = d.run;
  const std::string partial = partial_archive_reason(orig);
  if (!partial.empty() && !request.allow_partial)
    throw ControlError(error_code::kInvalidInput,
                       "run " + std::to_string(run_id) + ": " + partial +
                           "; not reprocessed (reprocess --partial calibrates it anyway, stored "
                           "REVIEW at best and never active)");
  if (!archive_has_data(orig.archive_path))
    throw ControlError(error_code::kInvalidInput,
                       "run " + std::to_string(run_id) + ": its archive " + orig.archive_path +
                           " holds no data rows (the run stopped before its first sample); "
                           "nothing to reprocess");
  if (thread_.joinable()) thread_.join();

  // The new run is recorded as the requester's, not the original operator's.
  const std::string by = request.user.empty() ? orig.operator_name : request.user;
  db::NewRun nr = new_run(orig.serial, by, orig.sequence_name, orig.sequence_sha256,
                          db::RunState::kCalibrating);
  nr.archive_path = orig.archive_path;
  nr.reprocessed_from = run_id;
  const db::RunId id = repo_.create_run(nr);

  auto live = std::make_shared<Live>();
  live->reprocess = true;
  live->handed_to_worker = true;
  live->snap = snapshot_from_record(orig);
  live->snap.run_id = id;
  live->snap.state = db::RunState::kCalibrating;
  live->snap.phase = RunPhase::kCalibrating;
  live->snap.verdict.reset();
  live->snap.crosscheck_verdict.reset();
  live->snap.reason.clear();
  live->snap.started_at_ms = nr.started_at_ms;
  live->snap.ended_at_ms.reset();
  live->snap.reprocessed_from = run_id;
  live->snap.operator_name = by;
  live_ = live;
  spdlog::info("run {}: reprocessing run {} from {} for {}{}", id, run_id, orig.archive_path, by,
               partial.empty() ? "" : " (partial archive: " + partial + ")");

  CalibrationJob job;
  job.run_id = id;
  job.archive_dir = orig.archive_path;
  job.archive_sha256 = digest;
  job.capture_json = orig.capture_json;
  job.k_sigma = cfg_.k_sigma;
  job.gap_false_alarm = cfg_.gap_false_alarm;
  job.partial_reason = partial;
  lk.unlock();
  worker_.submit(job, [this, live](const CalibrationOutcome& out) { on_calibrated(live, out); });
  return {{"run_id", id}, {"reprocessed_from", run_id}};
}

namespace {

/// The archive to import, read and checked as the calibration will read it; any problem is the
/// caller's (kInvalidInput, naming the file), and nothing is stored.
archive::RunArchive checked_import(const std::string& dir) {
  if (dir.empty() || !fs::path(dir).is_absolute())
    throw ControlError(error_code::kInvalidInput,
                       "import: '" + dir + "' is not an absolute path (stationctl sends one)");
  try {
    archive::RunArchive ar = archive::read_archive(dir);
    (void)archive::to_calibration_input(ar);
    return ar;
  } catch (const std::exception& e) {
    throw ControlError(error_code::kInvalidInput, std::string("import: ") + e.what());
  }
}

}  // namespace

nlohmann::json RunController::import_archive(const std::string& dir, const std::string& user) {
  std::unique_lock<std::mutex> lk(mu_);
  if (shut_down_) throw ControlError(error_code::kUnavailable, "the daemon is shutting down");
  if (live_)
    throw ControlError(error_code::kBusy, "run " + std::to_string(live_->snap.run_id) + " is " +
                                              db::to_string(live_->snap.state) +
                                              "; one run at a time");
  archive::RunArchive ar = checked_import(dir);
  if (thread_.joinable()) thread_.join();

  // The station keeps its own copy (staged, then renamed into place once the run exists), so the
  // record stays reproducible whatever happens to the medium it came from; an archive the history
  // already holds is refused before anything is stored.
  std::optional<StagedImport> staged;
  try {
    staged.emplace(dir, ar, (fs::path(cfg_.data_dir) / "runs").string());
  } catch (const std::exception& e) {
    throw ControlError(error_code::kUnavailable,
                       std::string("import: cannot store the archive: ") + e.what());
  }
  if (const auto dup = duplicate_import(repo_, *staged))
    throw ControlError(error_code::kInvalidInput, "import: " + *dup);

  const db::TimestampMs now = db::now_ms();
  const RecordedTimes times = recorded_times(ar, now);
  db::NewRun nr = new_run(ar.info.serial, user, ar.info.sequence_name, ar.info.sequence_sha256,
                          db::RunState::kCalibrating);
  nr.setting = ar.info.setting;
  nr.started_at_ms = times.started_at_ms;
  nr.origin = import_origin(dir, now, times);
  db::RunId id = 0;
  try {
    id = repo_.create_run(nr);
  } catch (const db::InvalidInput& e) {
    throw ControlError(error_code::kInvalidInput, std::string("import: ") + e.what());
  }
  const std::string dest = archive_dir_for(id, ar.info.serial);
  try {
    staged->move_to(dest);
  } catch (const std::exception& e) {
    db::RunCompletion c;
    c.state = db::RunState::kFailed;
    c.ended_at_ms = db::now_ms();
    c.reason = std::string("import: cannot store the archive: ") + e.what();
    repo_.finish_run(id, c);
    throw ControlError(error_code::kUnavailable, c.reason);
  }

  auto live = std::make_shared<Live>();
  live->reprocess = true;
  live->handed_to_worker = true;
  live->snap.run_id = id;
  live->snap.serial = ar.info.serial;
  live->snap.sequence = ar.info.sequence_name;
  live->snap.operator_name = user;
  live->snap.archive_path = dest;
  live->snap.state = db::RunState::kCalibrating;
  live->snap.phase = RunPhase::kCalibrating;
  live->snap.started_at_ms = nr.started_at_ms;
  live_ = live;
  spdlog::info("run {}: imported {} ({} run of {}, recorded {}) into {}", id, dir,
               calib::setting_name(ar.info.setting), ar.info.serial,
               db::format_time_utc(times.started_at_ms), dest);

  CalibrationJob job;
  job.run_id = id;
  job.archive_dir = dest;
  job.archive_sha256 = staged->copy_sha256();
  job.k_sigma = cfg_.k_sigma;
  job.gap_false_alarm = cfg_.gap_false_alarm;
  job.ended_at_ms = times.ended_at_ms;
  lk.unlock();
  worker_.submit(job, [this, live](const CalibrationOutcome& out) { on_calibrated(live, out); });
  return {{"run_id", id},
          {"serial", ar.info.serial},
          {"setting", calib::setting_name(ar.info.setting)},
          {"archive", dest}};
}

nlohmann::json RunController::promote(db::RunId run_id, const std::string& user,
                                      const std::string& reason) {
  const db::TimestampMs now = db::now_ms();
  try {
    repo_.promote(run_id, user, reason, now);
  } catch (const db::NotFound& e) {
    throw ControlError(error_code::kNotFound, e.what());
  } catch (const db::Conflict& e) {
    throw ControlError(error_code::kInvalidInput, e.what());
  } catch (const db::InvalidInput& e) {
    throw ControlError(error_code::kInvalidInput, e.what());
  }
  spdlog::info("run {}: promoted to the active parameters by {}: {}", run_id, user, reason);
  return {{"run_id", run_id}, {"promoted_by", user}, {"promoted_at", db::format_time_utc(now)}};
}

bool RunController::abort(const std::string& reason) {
  std::shared_ptr<Live> live;
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (!live_) return false;
    live = live_;
    if (!live->handed_to_worker) {
      if (!live->abort) {
        live->abort = true;
        live->abort_reason = reason;
        spdlog::warn("run {}: abort requested: {}", live->snap.run_id, reason);
      }
      if (live->client) live->client->request_abort();
      cv_.notify_all();  // wakes record_end's retry wait
      return true;
    }
  }
  // Calibrating: the table is idle; the run ends now and the worker's result will be dropped.
  db::RunCompletion c;
  c.state = db::RunState::kAborted;
  c.ended_at_ms = db::now_ms();
  c.reason = reason;
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (live_ != live) return true;  // finished meanwhile
    if (live->snap.capture) c.capture_json = to_json(*live->snap.capture).dump();
    c.archive_path = live->snap.archive_path;
    try {
      c.archive_sha256 = archive_digest(live->snap.archive_path);
    } catch (const std::exception& e) {
      spdlog::warn("run {}: {}", live->snap.run_id, e.what());
    }
    try {
      repo_.finish_run(live->snap.run_id, c);
    } catch (const db::Conflict&) {
      // The worker stored its result a moment earlier: that outcome stands (its callback follows).
      return true;
    }
    live->snap.state = db::RunState::kAborted;
    live->snap.reason = reason;
    spdlog::warn("run {}: aborted while calibrating: {}", live->snap.run_id, reason);
  }
  end_live(live);
  return true;
}

std::optional<RunSnapshot> RunController::active() const {
  std::lock_guard<std::mutex> lk(mu_);
  if (!live_) return std::nullopt;
  const Live& L = *live_;
  RunSnapshot s = L.snap;
  if (L.capture) s.capture = L.capture->stats();
  // Time left: the plan's remaining table time, scaled by how fast the IMU samples really arrive
  // (a simulator may run faster than real time).
  if (!L.handed_to_worker && !L.plan.steps.empty() && L.capture) {
    const double table_done_s =
        static_cast<double>(L.capture->rows() - L.rows_at_stream_start) / cfg_.rate_hz;
    const double wall_s = std::chrono::duration<double>(Clock::now() - L.stream_started).count();
    const double speed = wall_s > 0 && table_done_s > 0 ? table_done_s / wall_s : 1.0;
    double left_s = 0.0;
    const int n = static_cast<int>(L.plan.steps.size());
    for (int j = std::max(0, L.step_index + 1); j < n; ++j) left_s += L.plan.steps[j].expected_s;
    if (L.step_index >= 0 && L.step_index < n) {
      const PlannedStep& cur = L.plan.steps[L.step_index];
      if (cur.kind == PlannedStep::Kind::kRest && L.capture) {
        const uint64_t done = L.capture->rest_rows_done();
        left_s +=
            static_cast<double>(cur.rest_samples - std::min(done, cur.rest_samples)) / cfg_.rate_hz;
        if (done == 0) left_s += static_cast<double>(cfg_.settle_guard_samples) / cfg_.rate_hz;
      } else {
        const double elapsed =
            std::chrono::duration<double>(Clock::now() - L.step_started).count() * speed;
        left_s += std::max(0.0, cur.expected_s - elapsed);
      }
    }
    s.time_left_s = L.time_left.update(left_s, table_done_s, wall_s);
  }
  return s;
}

std::optional<RunSnapshot> RunController::last_finished() const {
  std::lock_guard<std::mutex> lk(mu_);
  return last_;
}

bool RunController::busy() const {
  std::lock_guard<std::mutex> lk(mu_);
  return live_ != nullptr;
}

bool RunController::wait_idle(milliseconds timeout) {
  std::unique_lock<std::mutex> lk(mu_);
  return cv_.wait_for(lk, timeout, [&] { return live_ == nullptr; });
}

void RunController::shutdown(const std::string& reason) {
  {
    std::lock_guard<std::mutex> lk(mu_);
    shut_down_ = true;
  }
  abort(reason);
  {
    std::unique_lock<std::mutex> lk(mu_);
    cv_.wait(lk, [&] { return live_ == nullptr; });
  }
  if (thread_.joinable()) thread_.join();
}

db::NewRun RunController::new_run(const std::string& serial, const std::string& operator_name,
                                  const std::string& sequence_name,
                                  const std::string& sequence_sha256, db::RunState state) const {
  db::NewRun nr;
  nr.serial = serial;
  nr.operator_name = operator_name;
  nr.station = cfg_.station_name;
  nr.sequence_name = sequence_name;
  nr.sequence_sha256 = sequence_sha256;
  nr.software_version = software_version_;
  nr.started_at_ms = db::now_ms();
  nr.state = state;
  return nr;
}

void RunController::set_phase(Live& live, RunPhase phase) {
  std::lock_guard<std::mutex> lk(mu_);
  live.snap.phase = phase;
}

void RunController::end_live(const std::shared_ptr<Live>& live) {
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (live_ != live) return;
    live->snap.phase = RunPhase::kNone;
    live->snap.time_left_s.reset();
    if (!live->snap.ended_at_ms) live->snap.ended_at_ms = db::now_ms();
    last_ = live->snap;
    live_.reset();
    // Notified under the lock: the calibration worker's thread ends runs too, and shutdown() (the
    // destructor) may return and destroy cv_ as soon as it sees live_ empty — a notify after the
    // unlock could touch a destroyed condition variable (found by ThreadSanitizer).
    cv_.notify_all();
  }
}

void RunController::on_calibrated(const std::shared_ptr<Live>& live,
                                  const CalibrationOutcome& out) {
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (live_ != live) return;  // aborted while calibrating: already ended
    if (out.stored) {
      live->snap.state = out.state;
      live->snap.verdict = out.verdict;
      live->snap.crosscheck_verdict = out.crosscheck_verdict;
      live->snap.reason = out.reason;
    } else {
      // Not stored: either already terminal in the database (take that) or the database failed
      // (the run stays live there; recovery will mark it interrupted).
      try {
        const db::RunRecord rec = repo_.show(live->snap.run_id).run;
        live->snap.state = rec.state;
        live->snap.verdict = rec.verdict;
        live->snap.crosscheck_verdict = rec.crosscheck_verdict;
        live->snap.reason = rec.failure_reason;
        live->snap.ended_at_ms = rec.ended_at_ms;
      } catch (const std::exception&) {
        live->snap.reason = out.reason;
      }
    }
  }
  end_live(live);
}

void RunController::control_thread(std::shared_ptr<Live> live) {
  try {
    capture_run(live);
  } catch (const std::exception& e) {
    // capture_run handles every run error itself; this is the database failing at the end.
    spdlog::error("run {}: {}", live->snap.run_id, e.what());
  }
  if (!live->handed_to_worker) end_live(live);
}

void RunController::finish_early(Live& live, db::RunState state, const std::string& reason) {
  std::lock_guard<std::mutex> lk(mu_);
  live.snap.state = state;
  live.snap.reason = reason;
  live.snap.ended_at_ms = db::now_ms();
}

void RunController::capture_run(const std::shared_ptr<Live>& self) {
  Live& L = *self;
  const db::RunId id = L.snap.run_id;
  const RunPlan& plan = L.plan;
  std::unique_ptr<turntable::TurntableClient> client;
  std::unique_ptr<Capture> cap;
  std::unique_ptr<ArchiveWriter> writer;
  archive::RunInfo info;
  bool captured = false;
  db::RunState end_state = db::RunState::kFailed;
  std::string reason;

  auto check_abort = [&] {
    std::lock_guard<std::mutex> lk(mu_);
    if (L.abort) throw AbortRequested{};
  };
  auto check_capture = [&] {
    if (cap) {
      if (auto f = cap->fault()) throw CaptureFailure(*f);
    }
  };
  const milliseconds poll = std::max(milliseconds(1), cfg_.turntable.poll_period);
  const auto move_timeout = milliseconds(static_cast<int64_t>(cfg_.move_timeout_s * 1000.0));

  // Commands a move and polls the table until it is in position, handing every reading to the
  // capture (sample-and-hold angles while moving); the final check is the client's own
  // wait_in_position (fault, e-stop, heartbeat, target reached).
  double at_outer = 0.0, at_inner = 0.0;  // where the table stands (last in-position reading)
  auto move = [&](double outer, double inner, double rate) {
    // The next rest may only count IMU samples that show this move happened (the IMU stream can
    // lag the Modbus readings); a move too short to be seen is not waited for.
    if (cap && (std::abs(outer - at_outer) > kVisibleMoveDeg ||
                std::abs(inner - at_inner) > kVisibleMoveDeg))
      cap->move_commanded();
    client->move_to(outer, inner, rate);
    const auto deadline = Clock::now() + move_timeout;
    set_phase(L, RunPhase::kMoving);
    for (;;) {
      check_abort();
      const turntable::TableStatus st = client->status();
      if (cap) cap->table_moving(st.outer_deg, st.inner_deg);
      check_capture();
      if (st.fault || st.estop || st.heartbeat_stale) break;
      if (st.in_position && !st.moving) break;
      set_phase(L, st.moving ? RunPhase::kMoving : RunPhase::kSettling);
      if (Clock::now() >= deadline) break;
      std::this_thread::sleep_for(poll);
    }
    const auto left = std::chrono::duration_cast<milliseconds>(deadline - Clock::now());
    return client->wait_in_position(std::max(milliseconds(1), left));
  };

  // A counted rest: the capture marks rest_samples rows at_rest once the unit is still; meanwhile
  // the table is watched for faults (it must hold its position).
  auto rest = [&](double outer, double inner, uint64_t samples) {
    cap->begin_rest(outer, inner, samples);
    set_phase(L, RunPhase::kSettling);
    // A unit that never comes to rest: give it the rest's real-time length plus a move timeout.
    const double budget_s =
        static_cast<double>(samples + cfg_.settle_guard_samples) / cfg_.rate_hz +
        cfg_.move_timeout_s;
    const auto deadline = Clock::now() + milliseconds(static_cast<int64_t>(budget_s * 1000.0));
    for (;;) {
      if (cap->wait_rest_done(poll)) return;
      check_capture();
      check_abort();
      const turntable::TableStatus st = client->status();
      const std::string where = "turntable " + cfg_.turntable.endpoint.to_string() +
                                " during a rest at outer " + std::to_string(st.outer_deg) +
                                " deg, inner " + std::to_string(st.inner_deg) + " deg";
      if (st.estop) throw turntable::EstopError(where + ": e-stop open");
      if (st.fault)
        throw turntable::TableFaultError(
            where + ": table fault, code " + std::to_string(st.fault_code), st.fault_code);
      if (st.heartbeat_stale) throw turntable::HeartbeatError(where + ": PLC heartbeat stuck");
      if (st.moving) throw turntable::MoveTimeoutError(where + ": the table moved during a rest");
      if (cap->rest_rows_done() > 0) set_phase(L, RunPhase::kResting);
      // The table has arrived; the IMU must have seen the move within a few seconds of samples.
      if (cap->unseen_move_samples() > static_cast<uint64_t>(kMoveVisibleWithin_s * cfg_.rate_hz))
        throw CaptureFailure(
            "the IMU did not show the table's move to outer " + std::to_string(outer) +
            " deg, inner " + std::to_string(inner) + " deg (" +
            std::to_string(static_cast<int>(kMoveVisibleWithin_s)) +
            " s of samples after the table stopped): the unit did not move with the table "
            "(loose, or not on it), or its gyro axis of that rotation is dead");
      if (Clock::now() >= deadline) {
        throw CaptureFailure("the unit did not come to rest within " + std::to_string(budget_s) +
                             " s (rest rate threshold " +
                             std::to_string(cfg_.rest_rate_threshold_dps) + " deg/s)");
      }
    }
  };

  try {
    // --- preparing: table ---
    set_phase(L, RunPhase::kConnecting);
    client = std::make_unique<turntable::TurntableClient>(cfg_.turntable);
    {
      std::lock_guard<std::mutex> lk(mu_);
      L.client = client.get();
      if (L.abort) client->request_abort();
    }
    check_abort();
    client->connect();
    check_abort();
    turntable::TableStatus st = client->status();
    if (st.estop)
      throw turntable::EstopError("turntable " + cfg_.turntable.endpoint.to_string() +
                                  ": e-stop open");
    if (st.fault) {
      spdlog::warn("run {}: table reports fault code {}; clearing it", id, st.fault_code);
      client->clear_fault();
    }
    client->enable();
    set_phase(L, RunPhase::kHoming);
    st = client->home(milliseconds(static_cast<int64_t>(cfg_.home_timeout_s * 1000.0)));
    check_abort();
    if (std::abs(st.outer_deg - plan.start_outer_deg) > cfg_.turntable.position_tolerance_deg ||
        std::abs(st.inner_deg - plan.start_inner_deg) > cfg_.turntable.position_tolerance_deg) {
      st = move(plan.start_outer_deg, plan.start_inner_deg, cfg_.max_rate_dps);
    }

    // --- preparing: IMU ---
    set_phase(L, RunPhase::kConnecting);
    CaptureOptions co;
    co.decoder = decoder_options(cfg_);
    co.max_gap_samples = cfg_.max_gap_samples;
    co.settle_guard_samples = cfg_.settle_guard_samples;
    co.rest_rate_threshold_dps = cfg_.rest_rate_threshold_dps;
    co.stream_timeout = milliseconds(cfg_.stream_timeout_ms);
    cap = std::make_unique<Capture>(imu::CanChannel::open(cfg_.can_uri), co);
    cap->start();
    {
      std::lock_guard<std::mutex> lk(mu_);
      L.capture = cap.get();
    }
    if (!cap->wait_for_stream(co.stream_timeout)) {
      check_capture();
      throw CaptureFailure("no IMU samples on " + cfg_.can_uri + " within " +
                           std::to_string(cfg_.stream_timeout_ms) + " ms");
    }
    {
      std::lock_guard<std::mutex> lk(mu_);
      L.stream_started = Clock::now();
      L.rows_at_stream_start = cap->rows();
    }
    check_abort();

    // --- archive + running ---
    info.serial = L.snap.serial;
    info.station_name = cfg_.station_name;
    info.site = cfg_.site;
    info.imu_rate_hz = cfg_.rate_hz;
    info.sequence_name = plan.sequence_name;
    info.sequence_sha256 = plan.sequence_sha256;
    info.software_version = software_version_;
    info.start_time = db::format_time_utc(L.snap.started_at_ms);
    info.reference = archive::ReferenceKind::kTable;
    info.arw_rad_per_sqrt_s = cfg_.arw_rad_per_sqrt_s();
    info.vrw_mps_per_sqrt_s = cfg_.vrw_mps_per_sqrt_s();
    writer = std::make_unique<ArchiveWriter>(L.snap.archive_path, info);
    cap->table_moving(st.outer_deg, st.inner_deg);
    cap->attach(writer.get());
    repo_.update_run_state(id, db::RunState::kRunning);
    {
      std::lock_guard<std::mutex> lk(mu_);
      L.snap.state = db::RunState::kRunning;
    }
    spdlog::info("run {}: running, archive {}", id, L.snap.archive_path);

    at_outer = st.outer_deg;
    at_inner = st.inner_deg;
    for (size_t i = 0; i < plan.steps.size(); ++i) {
      const PlannedStep& p = plan.steps[i];
      {
        std::lock_guard<std::mutex> lk(mu_);
        L.step_index = static_cast<int>(i);
        L.snap.step = static_cast<int>(i) + 1;
        L.step_started = Clock::now();
      }
      check_abort();
      if (p.kind == PlannedStep::Kind::kMove) {
        spdlog::debug("run {}: step {}/{}: move to outer {} deg, inner {} deg at {} deg/s", id,
                      i + 1, plan.steps.size(), p.outer_deg, p.inner_deg, p.rate_dps);
        st = move(p.outer_deg, p.inner_deg, p.rate_dps);
        at_outer = st.outer_deg;
        at_inner = st.inner_deg;
      } else {
        spdlog::debug("run {}: step {}/{}: rest {} samples", id, i + 1, plan.steps.size(),
                      p.rest_samples);
        rest(at_outer, at_inner, p.rest_samples);
      }
      check_capture();
    }
    check_abort();
    cap->detach();
    check_capture();
    captured = true;
  } catch (const AbortRequested&) {
    end_state = db::RunState::kAborted;
  } catch (const turntable::AbortedError&) {
    end_state = db::RunState::kAborted;
  } catch (const turntable::TurntableError& e) {
    end_state = db::RunState::kAborted;
    reason = std::string("table: ") + e.what();
  } catch (const CaptureFailure& e) {
    end_state = db::RunState::kFailed;
    reason = std::string("capture: ") + e.what();
  } catch (const imu::CanChannelError& e) {
    end_state = db::RunState::kFailed;
    reason = std::string("capture: ") + e.what();
  } catch (const std::exception& e) {
    end_state = db::RunState::kFailed;
    reason = e.what();
  }
  {
    std::lock_guard<std::mutex> lk(mu_);
    // The operator's reason wins over whatever the abort made the table or capture report (a
    // table link that was down, say): it is what the run ended for.
    if (L.abort && !captured) {
      const std::string consequence = reason;
      end_state = db::RunState::kAborted;
      reason = L.abort_reason;
      if (!consequence.empty() && consequence != reason) reason += " (then: " + consequence + ")";
    }
    if (end_state == db::RunState::kAborted && reason.empty()) reason = L.abort_reason;
    // An abort that arrived after the last step still wins over calibrating.
    if (captured && L.abort) {
      captured = false;
      end_state = db::RunState::kAborted;
      reason = L.abort_reason;
    }
  }
  if (reason.empty()) reason = "aborted";

  if (!captured) {
    spdlog::warn("run {}: {}: {}", id, db::to_string(end_state), reason);
    set_phase(L, RunPhase::kStopping);
    if (client && client->connected()) client->safe_stop();
  }

  // Capture and archive end on every path: counters, run.toml with end time and [capture].
  std::optional<CaptureStats> stats;
  if (cap) {
    cap->detach();
    cap->stop();  // no more frames counted after the archive's last one
    stats = cap->stats();
    {
      std::lock_guard<std::mutex> lk(mu_);
      L.capture = nullptr;
      L.snap.capture = stats;
    }
    cap.reset();
  }
  std::string sha;
  if (writer) {
    try {
      info.end_time = db::format_time_utc(db::now_ms());
      // complete only when every step ran: an aborted or failed run's archive says so, and its
      // reprocess is refused unless asked for (REVIEW at best then).
      info.capture = to_capture_info(stats.value_or(CaptureStats{}), captured);
      writer->finish(info);
    } catch (const std::exception& e) {
      spdlog::error("run {}: finishing the archive: {}", id, e.what());
      if (captured) {
        captured = false;
        end_state = db::RunState::kFailed;
        reason = std::string("archive: ") + e.what();
      }
    }
    writer.reset();
    try {
      sha = archive_digest(L.snap.archive_path);
    } catch (const std::exception& e) {
      spdlog::error("run {}: {}", id, e.what());
    }
  }
  {
    std::lock_guard<std::mutex> lk(mu_);
    L.client = nullptr;
  }
  if (client) {
    client->close();
    client.reset();
  }
  const std::string capture_json = stats ? to_json(*stats).dump() : std::string();
  const bool have_archive = fs::exists(fs::path(L.snap.archive_path) / "run.toml");

  if (captured) {
    repo_.update_run_state(id, db::RunState::kCalibrating);
    CalibrationJob job;
    job.run_id = id;
    job.archive_dir = L.snap.archive_path;
    job.archive_sha256 = sha;
    job.capture_json = capture_json;
    job.k_sigma = cfg_.k_sigma;
    job.gap_false_alarm = cfg_.gap_false_alarm;
    {
      std::lock_guard<std::mutex> lk(mu_);
      L.snap.state = db::RunState::kCalibrating;
      L.snap.phase = RunPhase::kCalibrating;
      L.handed_to_worker = true;
    }
    spdlog::info("run {}: capture complete ({} rows, {} at rest); calibrating", id,
                 stats ? stats->rows_written : 0, stats ? stats->rest_samples : 0);
    try {
      worker_.submit(job,
                     [this, self](const CalibrationOutcome& out) { on_calibrated(self, out); });
      return;
    } catch (const std::exception& e) {
      // The worker is stopped (daemon shutting down): the archive is complete, reprocess it later.
      std::lock_guard<std::mutex> lk(mu_);
      L.handed_to_worker = false;
      end_state = db::RunState::kInterrupted;
      reason =
          std::string("capture complete but not calibrated: ") + e.what() + "; reprocess the run";
    }
  }

  db::RunCompletion c;
  c.state = end_state;
  c.ended_at_ms = db::now_ms();
  c.reason = reason;
  if (have_archive) c.archive_path = L.snap.archive_path;
  c.archive_sha256 = sha;
  c.capture_json = capture_json;
  finish_early(L, end_state, reason);
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (!have_archive) L.snap.archive_path.clear();
  }
  record_end(L, c);
}

void RunController::record_end(Live& L, const db::RunCompletion& c) {
  const db::RunId id = L.snap.run_id;
  const std::string note = end_note_path(cfg_.data_dir, id);
  bool noted = false;
  for (int attempt = 0;; ++attempt) {
    try {
      repo_.finish_run(id, c);
      remove_end_note(note);
      if (attempt > 0) spdlog::info("run {}: end recorded in the database at last", id);
      return;
    } catch (const std::exception& e) {
      // Typically the disk is full (the database shares it with the archives). The run has ended
      // (status says so, `--wait` returns); its end is kept in the reserved note so that a restart
      // finds the real reason, and recording is retried until space returns or the daemon stops.
      if (!noted) {
        const std::string err = record_end_note(note, c.state, c.reason);
        spdlog::error("run {}: the database cannot record its end ({}); {}; retrying every {} s",
                      id, e.what(),
                      err.empty() ? "kept in " + note : "and no end note either: " + err,
                      kRecordRetry.count() / 1000.0);
        noted = true;
      }
    }
    std::unique_lock<std::mutex> lk(mu_);
    if (cv_.wait_for(lk, kRecordRetry, [&] { return L.abort || shut_down_; })) {
      spdlog::warn("run {}: stopping with its end unrecorded; start-up recovery takes it from {}",
                   id, note);
      return;
    }
  }
}

}  // namespace imucal::station
