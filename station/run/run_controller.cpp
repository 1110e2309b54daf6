#include "station/run/run_controller.hpp"

#include <spdlog/spdlog.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "db/archive/archive_input.hpp"
#include "db/archive/run_archive.hpp"
#include "db/history/serial_number.hpp"
#include "drivers/imu/can_channel.hpp"
#include "drivers/turntable/turntable_client.hpp"
#include "sequences/library.hpp"
#include "sequences/parser.hpp"
#include "sequences/validator.hpp"
#include "station/control/control_protocol.hpp"
#include "station/run/archive_writer.hpp"
#include "station/run/capture.hpp"
#include "station/run/end_note.hpp"
#include "station/run/gap_check.hpp"
#include "station/run/import_staging.hpp"
#include "station/run/run_live.hpp"
#include "station/run/time_left.hpp"

namespace imucal::station::run {
using namespace station::config;
using namespace station::control;

namespace fs = std::filesystem;
using nlohmann::json;
using std::chrono::milliseconds;

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
  const bool live = !db::history::is_terminal(r.state);
  json o;
  o["run_id"] = r.run_id;
  o["serial"] = r.serial;
  o["sequence"] = r.sequence;
  o["operator"] = r.operator_name;
  o["state"] = db::history::to_string(r.state);
  o["phase"] = r.phase == RunPhase::kNone ? json(nullptr) : json(to_string(r.phase));
  o["step"] =
      live && r.steps > 0 && r.step > 0 ? json(r.step) : json(nullptr);  // null while preparing
  o["steps"] = r.steps > 0 ? json(r.steps) : json(nullptr);
  o["time_left_s"] = live && r.time_left_s ? json(*r.time_left_s) : json(nullptr);
  o["verdict"] = r.verdict ? json(db::history::to_string(*r.verdict)) : json(nullptr);
  o["crosscheck_verdict"] =
      r.crosscheck_verdict ? json(db::history::to_string(*r.crosscheck_verdict)) : json(nullptr);
  o["reason"] = r.reason;
  o["started_at"] =
      r.started_at_ms ? json(db::history::format_time_utc(r.started_at_ms)) : json(nullptr);
  o["ended_at"] =
      r.ended_at_ms ? json(db::history::format_time_utc(*r.ended_at_ms)) : json(nullptr);
  o["capture"] = r.capture ? to_json(*r.capture) : json(nullptr);
  o["archive"] = r.archive_path;
  o["reprocessed_from"] = r.reprocessed_from ? json(*r.reprocessed_from) : json(nullptr);
  o["slot"] = r.slot;
  o["table_run"] = r.table_run_id ? json(*r.table_run_id) : json(nullptr);
  if (!r.siblings.empty()) {
    RunSnapshot self = r;
    self.siblings.clear();
    json units = json::array({to_json(self)});
    for (const RunSnapshot& sib : r.siblings) units.push_back(to_json(sib));
    o["units"] = std::move(units);
  }
  return o;
}

RunSnapshot snapshot_from_record(const db::history::RunRecord& rec) {
  RunSnapshot s;
  s.run_id = rec.run_id;
  s.serial = rec.serial;
  s.sequence = rec.sequence_name;
  s.operator_name = rec.operator_name;
  s.state = rec.state;
  s.phase =
      rec.state == db::history::RunState::kCalibrating ? RunPhase::kCalibrating : RunPhase::kNone;
  s.verdict = rec.verdict;
  s.crosscheck_verdict = rec.crosscheck_verdict;
  s.reason = rec.failure_reason;
  s.started_at_ms = rec.started_at_ms;
  s.ended_at_ms = rec.ended_at_ms;
  s.archive_path = rec.archive_path;
  s.reprocessed_from = rec.reprocessed_from;
  s.slot = rec.slot;
  s.table_run_id = rec.table_run_id;
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

/// Rest-to-rest time of a trapezoidal (or triangular) move, s.
double move_time_s(double distance_deg, double rate_dps, double accel_dps2) {
  const double d = std::abs(distance_deg);
  if (rate_dps <= 0 || accel_dps2 <= 0) return 0.0;
  if (d >= rate_dps * rate_dps / accel_dps2) return d / rate_dps + rate_dps / accel_dps2;
  return 2.0 * std::sqrt(d / accel_dps2);
}

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

  const ImuSlotConfig& imu = cfg.imu();  // the time estimate counts the first slot's samples
  const double guard_s = static_cast<double>(imu.settle_guard_samples) / imu.rate_hz;
  auto rest = [&](double rest_s, double outer, double inner, int line) {
    PlannedStep p;
    p.kind = PlannedStep::Kind::kRest;
    p.outer_deg = outer;
    p.inner_deg = inner;
    p.rest_s = rest_s;
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

RunController::RunController(const StationConfig& config, db::history::Repository& repository,
                             CalibrationWorker& worker, std::string software_version)
    : cfg_(config),
      repo_(repository),
      worker_(worker),
      software_version_(std::move(software_version)) {}

RunController::~RunController() { shutdown("daemon shutting down"); }

std::string run_archive_dir(const std::string& data_dir, db::history::RunId id,
                            const std::string& serial) {
  return (fs::path(data_dir) / "runs" / (std::to_string(id) + "-" + serial)).string();
}

std::string RunController::archive_dir_for(db::history::RunId id, const std::string& serial) const {
  return run_archive_dir(cfg_.data_dir, id, serial);
}

std::vector<std::pair<const ImuSlotConfig*, std::string>> RunController::units_of(
    const StartRunRequest& request) const {
  std::vector<UnitRequest> asked = request.units;
  if (asked.empty()) asked.push_back({"", request.serial});
  if (asked.size() > cfg_.imus.size())
    throw ControlError(error_code::kInvalidInput,
                       std::to_string(asked.size()) + " units, but the fixture has " +
                           std::to_string(cfg_.imus.size()) + " slot(s)");
  std::vector<std::pair<const ImuSlotConfig*, std::string>> out;
  auto taken = [&](const ImuSlotConfig* slot) {
    return std::any_of(out.begin(), out.end(), [&](const auto& u) { return u.first == slot; });
  };
  for (const UnitRequest& u : asked) {
    if (auto problem = db::history::serial_problem(u.serial))
      throw ControlError(error_code::kInvalidInput, *problem);
    for (const auto& other : out)
      if (other.second == u.serial)
        throw ControlError(error_code::kInvalidInput,
                           "serial " + u.serial + " is given twice (one unit per slot)");
    const ImuSlotConfig* slot = nullptr;
    for (const ImuSlotConfig& c : cfg_.imus) {
      if (u.slot.empty() ? !taken(&c) : c.name == u.slot) {
        slot = &c;
        break;
      }
    }
    if (!slot) {
      std::string names;
      for (const ImuSlotConfig& c : cfg_.imus) names += (names.empty() ? "" : ", ") + c.name;
      throw ControlError(error_code::kInvalidInput,
                         "no slot \"" + u.slot + "\" on this fixture (slots: " + names + ")");
    }
    if (taken(slot))
      throw ControlError(error_code::kInvalidInput, "slot " + slot->name + " is given twice");
    out.emplace_back(slot, u.serial);
  }
  return out;
}

json RunController::create_unit_runs(
    Live& live, const std::vector<std::pair<const ImuSlotConfig*, std::string>>& units,
    const std::string& operator_name) {
  const bool several_slots = cfg_.imus.size() > 1;
  json started_units = json::array();
  for (const auto& [slot, serial] : units) {
    db::history::NewRun nr = new_run(serial, operator_name, live.plan.sequence_name,
                                     live.plan.sequence_sha256, db::history::RunState::kPreparing);
    if (several_slots) nr.slot = slot->name;
    if (!live.units.empty()) nr.table_run_id = live.units.front().snap.run_id;
    const db::history::RunId id = repo_.create_run(nr);
    Unit u;
    u.slot = slot;
    RunSnapshot& snap = u.snap;
    snap.run_id = id;
    snap.serial = nr.serial;
    snap.slot = nr.slot;
    snap.table_run_id = nr.table_run_id;
    snap.sequence = nr.sequence_name;
    snap.operator_name = nr.operator_name;
    snap.state = db::history::RunState::kPreparing;
    snap.phase = RunPhase::kConnecting;
    snap.steps = static_cast<int>(live.plan.steps.size());
    snap.started_at_ms = nr.started_at_ms;
    snap.archive_path = archive_dir_for(id, nr.serial);
    if (const std::string err = reserve_end_note(end_note_path(cfg_.data_dir, id)); !err.empty())
      spdlog::warn(
          "run {}: no end note reserved ({}); if the disk fills up, a restart before "
          "space returns will not know why the run ended",
          id, err);
    spdlog::info("run {}: serial {}{}, sequence {} ({} steps), operator {}", id, nr.serial,
                 nr.slot.empty() ? "" : " in slot " + nr.slot, nr.sequence_name, snap.steps,
                 nr.operator_name);
    started_units.push_back({{"run_id", id}, {"serial", nr.serial}, {"slot", nr.slot}});
    live.units.push_back(std::move(u));
  }
  return started_units;
}

nlohmann::json RunController::start(const StartRunRequest& request) {
  const auto units = units_of(request);
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
  if (diagnosing_)
    throw ControlError(error_code::kBusy, "run " + std::to_string(*diagnosing_) +
                                              " is being diagnosed; start when it is done");
  if (live_) {
    const RunSnapshot& a = live_->units.front().snap;
    throw ControlError(error_code::kBusy, "run " + std::to_string(a.run_id) + " (" + a.serial +
                                              ") is " + db::history::to_string(a.state) +
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

  auto live = std::make_shared<Live>();
  live->plan = std::move(plan);
  json started_units = create_unit_runs(*live, units, request.operator_name);
  live_ = live;
  thread_ = std::thread([this, live] { control_thread(live); });
  const RunSnapshot& first = live->units.front().snap;
  json reply = {{"run_id", first.run_id},
                {"serial", first.serial},
                {"sequence", first.sequence},
                {"steps", first.steps}};
  if (units.size() > 1) reply["units"] = std::move(started_units);
  return reply;
}

db::history::RunDetails RunController::stored_run_with_archive(db::history::RunId run_id,
                                                               const char* what,
                                                               std::string& digest,
                                                               bool check_digest) const {
  if (shut_down_) throw ControlError(error_code::kUnavailable, "the daemon is shutting down");
  if (live_) {
    throw ControlError(error_code::kBusy,
                       "run " + std::to_string(live_->units.front().snap.run_id) + " is " +
                           db::history::to_string(live_->units.front().snap.state) +
                           "; one run at a time");
  }
  db::history::RunDetails d;
  try {
    d = repo_.show(run_id);
  } catch (const db::history::NotFound& e) {
    throw ControlError(error_code::kNotFound, e.what());
  }
  const db::history::RunRecord& orig = d.run;
  if (!db::history::is_terminal(orig.state)) {
    throw ControlError(error_code::kBusy, "run " + std::to_string(run_id) + " is still " +
                                              db::history::to_string(orig.state));
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
  if (check_digest) digest = unchanged_archive_digest(d.run, what);
  return d;
}

std::string RunController::unchanged_archive_digest(const db::history::RunRecord& run,
                                                    const char* what) {
  std::string digest;
  try {
    digest = archive_digest(run.archive_path);
  } catch (const std::exception& e) {
    throw ControlError(error_code::kUnavailable, e.what());
  }
  if (digest != run.archive_sha256) {
    throw ControlError(error_code::kInvalidInput,
                       "archive " + run.archive_path + " of run " + std::to_string(run.run_id) +
                           " has changed since it was recorded (SHA-256 now " + digest +
                           ", recorded " + run.archive_sha256 + "); not " + what);
  }
  return digest;
}

nlohmann::json RunController::diagnose(db::history::RunId run_id) {
  // The lock is held to check and to store, not while the diagnosis takes the CPU (seconds for an
  // hour's run; status answers meanwhile, issue #22); no run starts until it is done.
  db::history::RunDetails d;
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (diagnosing_)
      throw ControlError(error_code::kBusy, "run " + std::to_string(*diagnosing_) +
                                                " is being diagnosed; one diagnosis at a time");
    std::string unchecked;
    d = stored_run_with_archive(run_id, "diagnosing", unchecked, /*check_digest=*/false);
    diagnosing_ = run_id;
  }
  struct Done {
    RunController& rc;
    ~Done() {
      std::lock_guard<std::mutex> lk(rc.mu_);
      rc.diagnosing_.reset();
    }
  } done{*this};
  unchanged_archive_digest(d.run, "diagnosing");  // hashing an hour's archive: off the lock too
  nlohmann::json full;
  try {
    full = diagnose_archive(d.run.archive_path);
  } catch (const std::exception& e) {
    throw ControlError(error_code::kInvalidInput,
                       "run " + std::to_string(run_id) + ": diagnosis failed: " + e.what());
  }
  {
    std::lock_guard<std::mutex> lk(mu_);
    repo_.set_diagnosis(run_id, full.at("stored_summary").dump());
  }
  full.erase("stored_summary");
  full["run_id"] = run_id;
  spdlog::info("run {}: diagnosed: {}", run_id, full.value("summary", std::string()));
  return full;
}

namespace {

/// Why a stored run's archive is incomplete, "" if it is complete: its run.toml says the capture
/// did not complete, or the run ended before its capture did (aborted, or failed for anything but
/// the calibration itself — archives written before run.toml said so claim complete).
std::string partial_archive_reason(const db::history::RunRecord& run) {
  const std::string path = (fs::path(run.archive_path) / "run.toml").string();
  try {
    std::ifstream in(path);
    std::ostringstream ss;
    ss << in.rdbuf();
    const db::archive::RunInfo info = db::archive::parse_run_info(ss.str(), path);
    if (info.capture && !info.capture->complete)
      return "its archive is incomplete (run.toml [capture] complete = false)";
  } catch (const std::exception& e) {
    return std::string("its run.toml cannot be read: ") + e.what();
  }
  // Interrupted runs: recovery marked a cut archive incomplete above and left a finished one
  // (killed while calibrating) complete.
  const bool calibration_failure = run.failure_reason.rfind("calibration failed", 0) == 0;
  if (run.state == db::history::RunState::kAborted ||
      (run.state == db::history::RunState::kFailed && !calibration_failure))
    return std::string("the run ended ") + db::history::to_string(run.state) +
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
  const db::history::RunId run_id = request.run_id;
  if (request.gravity_mps2 && !plausible_surveyed_gravity(*request.gravity_mps2))
    throw ControlError(error_code::kInvalidInput,
                       "reprocess: gravity_mps2 " + std::to_string(*request.gravity_mps2) +
                           " is no surveyed gravity (m/s², between 9.7 and 9.9)");
  std::unique_lock<std::mutex> lk(mu_);
  std::string digest;
  const db::history::RunDetails d = stored_run_with_archive(run_id, "reprocessing", digest);
  const db::history::RunRecord& orig = d.run;
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
  db::history::NewRun nr = new_run(orig.serial, by, orig.sequence_name, orig.sequence_sha256,
                                   db::history::RunState::kCalibrating);
  nr.archive_path = orig.archive_path;
  nr.reprocessed_from = run_id;
  if (request.gravity_mps2) {
    char corrected[160];
    std::snprintf(corrected, sizeof corrected,
                  "reprocessed with the site's surveyed gravity corrected to %.7f m/s^2",
                  *request.gravity_mps2);
    nr.origin = corrected;
  }
  const db::history::RunId id = repo_.create_run(nr);

  auto live = std::make_shared<Live>();
  live->reprocess = true;
  live->capture_over = true;
  Unit u;
  u.handed_to_worker = true;
  RunSnapshot& snap = u.snap;
  snap = snapshot_from_record(orig);
  snap.run_id = id;
  snap.state = db::history::RunState::kCalibrating;
  snap.phase = RunPhase::kCalibrating;
  snap.verdict.reset();
  snap.crosscheck_verdict.reset();
  snap.reason.clear();
  snap.started_at_ms = nr.started_at_ms;
  snap.ended_at_ms.reset();
  snap.reprocessed_from = run_id;
  snap.operator_name = by;
  snap.slot.clear();
  snap.table_run_id.reset();
  live->units.push_back(std::move(u));
  live_ = live;
  spdlog::info("run {}: reprocessing run {} from {} for {}{}", id, run_id, orig.archive_path, by,
               partial.empty() ? "" : " (partial archive: " + partial + ")");

  CalibrationJob job;
  job.run_id = id;
  job.archive_dir = orig.archive_path;
  job.archive_sha256 = digest;
  job.capture_json = orig.capture_json;
  apply_calibration_settings(job);
  job.partial_reason = partial;
  job.site_gravity_mps2 = request.gravity_mps2;
  lk.unlock();
  worker_.submit(job, [this, live](const CalibrationOutcome& out) { on_calibrated(live, 0, out); });
  return {{"run_id", id}, {"reprocessed_from", run_id}};
}

namespace {

/// The archive to import, read and checked as the calibration will read it; any problem is the
/// caller's (kInvalidInput, naming the file), and nothing is stored.
db::archive::RunArchive checked_import(const std::string& dir) {
  if (dir.empty() || !fs::path(dir).is_absolute())
    throw ControlError(error_code::kInvalidInput,
                       "import: '" + dir + "' is not an absolute path (stationctl sends one)");
  try {
    db::archive::RunArchive ar = db::archive::read_archive(dir);
    (void)db::archive::to_calibration_input(ar);
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
    throw ControlError(error_code::kBusy,
                       "run " + std::to_string(live_->units.front().snap.run_id) + " is " +
                           db::history::to_string(live_->units.front().snap.state) +
                           "; one run at a time");
  db::archive::RunArchive ar = checked_import(dir);
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

  const db::history::TimestampMs now = db::history::now_ms();
  const RecordedTimes times = recorded_times(ar, now);
  db::history::NewRun nr = new_run(ar.info.serial, user, ar.info.sequence_name,
                                   ar.info.sequence_sha256, db::history::RunState::kCalibrating);
  nr.setting = ar.info.setting;
  nr.started_at_ms = times.started_at_ms;
  nr.origin = import_origin(dir, now, times);
  db::history::RunId id = 0;
  try {
    id = repo_.create_run(nr);
  } catch (const db::history::InvalidInput& e) {
    throw ControlError(error_code::kInvalidInput, std::string("import: ") + e.what());
  }
  const std::string dest = archive_dir_for(id, ar.info.serial);
  try {
    staged->move_to(dest);
  } catch (const std::exception& e) {
    db::history::RunCompletion c;
    c.state = db::history::RunState::kFailed;
    c.verdict = db::history::RunVerdict::kStationFault;  // the station's disk, not the unit
    c.ended_at_ms = db::history::now_ms();
    c.reason = std::string("import: cannot store the archive: ") + e.what();
    repo_.finish_run(id, c);
    throw ControlError(error_code::kUnavailable, c.reason);
  }

  auto live = std::make_shared<Live>();
  live->reprocess = true;
  live->capture_over = true;
  Unit u;
  u.handed_to_worker = true;
  u.snap.run_id = id;
  u.snap.serial = ar.info.serial;
  u.snap.sequence = ar.info.sequence_name;
  u.snap.operator_name = user;
  u.snap.archive_path = dest;
  u.snap.state = db::history::RunState::kCalibrating;
  u.snap.phase = RunPhase::kCalibrating;
  u.snap.started_at_ms = nr.started_at_ms;
  live->units.push_back(std::move(u));
  live_ = live;
  spdlog::info("run {}: imported {} ({} run of {}, recorded {}) into {}", id, dir,
               calib::core::setting_name(ar.info.setting), ar.info.serial,
               db::history::format_time_utc(times.started_at_ms), dest);

  CalibrationJob job;
  job.run_id = id;
  job.archive_dir = dest;
  job.archive_sha256 = staged->copy_sha256();
  apply_calibration_settings(job);
  job.ended_at_ms = times.ended_at_ms;
  lk.unlock();
  worker_.submit(job, [this, live](const CalibrationOutcome& out) { on_calibrated(live, 0, out); });
  return {{"run_id", id},
          {"serial", ar.info.serial},
          {"setting", calib::core::setting_name(ar.info.setting)},
          {"archive", dest}};
}

nlohmann::json RunController::promote(db::history::RunId run_id, const std::string& user,
                                      const std::string& reason) {
  const db::history::TimestampMs now = db::history::now_ms();
  try {
    repo_.promote(run_id, user, reason, now);
  } catch (const db::history::NotFound& e) {
    throw ControlError(error_code::kNotFound, e.what());
  } catch (const db::history::Conflict& e) {
    throw ControlError(error_code::kInvalidInput, e.what());
  } catch (const db::history::InvalidInput& e) {
    throw ControlError(error_code::kInvalidInput, e.what());
  }
  spdlog::info("run {}: promoted to the active parameters by {}: {}", run_id, user, reason);
  return {{"run_id", run_id},
          {"promoted_by", user},
          {"promoted_at", db::history::format_time_utc(now)}};
}

bool RunController::abort(const std::string& reason) {
  std::shared_ptr<Live> live;
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (!live_) return false;
    live = live_;
    if (!live->capture_over) {
      if (!live->abort) {
        live->abort = true;
        live->abort_reason = reason;
        spdlog::warn("run {}: abort requested: {}", live->units.front().snap.run_id, reason);
      }
      if (live->client) live->client->request_abort();
      cv_.notify_all();  // wakes record_end's retry wait
      return true;
    }
  }
  // Calibrating: the table is idle; every unit still calibrating ends now and the worker's
  // result for it will be dropped.
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (live_ != live) return true;  // finished meanwhile
    for (Unit& u : live->units) {
      if (u.ended) continue;
      db::history::RunCompletion c;
      c.state = db::history::RunState::kAborted;
      c.verdict = db::history::RunVerdict::kAborted;
      c.ended_at_ms = db::history::now_ms();
      c.reason = reason;
      if (u.snap.capture) c.capture_json = to_json(*u.snap.capture).dump();
      c.archive_path = u.snap.archive_path;
      try {
        c.archive_sha256 = archive_digest(u.snap.archive_path);
      } catch (const std::exception& e) {
        spdlog::warn("run {}: {}", u.snap.run_id, e.what());
      }
      try {
        repo_.finish_run(u.snap.run_id, c);
      } catch (const db::history::Conflict&) {
        // The worker stored its result a moment earlier: that outcome stands (its callback
        // follows).
        continue;
      }
      u.ended = true;
      u.snap.state = db::history::RunState::kAborted;
      u.snap.verdict = db::history::RunVerdict::kAborted;
      u.snap.reason = reason;
      u.snap.ended_at_ms = c.ended_at_ms;
      spdlog::warn("run {}: aborted while calibrating: {}", u.snap.run_id, reason);
    }
    if (!live->all_ended()) return true;  // the rest end with their callbacks
  }
  end_live(live);
  return true;
}

RunSnapshot RunController::snapshot_of(const Live& L) const {
  std::vector<RunSnapshot> units;
  for (const Unit& u : L.units) {
    units.push_back(u.snap);
    if (u.capture) units.back().capture = u.capture->stats();
  }
  RunSnapshot s = units.front();
  s.siblings.assign(units.begin() + 1, units.end());
  return s;
}

std::optional<RunSnapshot> RunController::active() const {
  std::lock_guard<std::mutex> lk(mu_);
  if (!live_) return std::nullopt;
  const Live& L = *live_;
  RunSnapshot s = snapshot_of(L);
  // Time left: the plan's remaining table time, scaled by how fast the IMU samples really arrive
  // (a simulator may run faster than real time); counted on the first unit still capturing.
  const Unit* u = L.capturing_unit();
  if (!L.capture_over && !L.plan.steps.empty() && u && u->slot) {
    const double rate_hz = u->slot->rate_hz;
    const double table_done_s =
        static_cast<double>(u->capture->rows() - u->rows_at_stream_start) / rate_hz;
    const double wall_s = std::chrono::duration<double>(Clock::now() - L.stream_started).count();
    const double speed = wall_s > 0 && table_done_s > 0 ? table_done_s / wall_s : 1.0;
    double left_s = 0.0;
    const int n = static_cast<int>(L.plan.steps.size());
    for (int j = std::max(0, L.step_index + 1); j < n; ++j) left_s += L.plan.steps[j].expected_s;
    if (L.step_index >= 0 && L.step_index < n) {
      const PlannedStep& cur = L.plan.steps[L.step_index];
      if (cur.kind == PlannedStep::Kind::kRest) {
        const uint64_t samples = cur.rest_samples(rate_hz);
        const uint64_t done = u->capture->rest_rows_done();
        left_s += static_cast<double>(samples - std::min(done, samples)) / rate_hz;
        if (done == 0) left_s += static_cast<double>(u->slot->settle_guard_samples) / rate_hz;
      } else {
        const double elapsed =
            std::chrono::duration<double>(Clock::now() - L.step_started).count() * speed;
        left_s += std::max(0.0, cur.expected_s - elapsed);
      }
    }
    s.time_left_s = L.time_left.update(left_s, table_done_s, wall_s);
    for (RunSnapshot& sib : s.siblings) sib.time_left_s = s.time_left_s;
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

db::history::NewRun RunController::new_run(const std::string& serial,
                                           const std::string& operator_name,
                                           const std::string& sequence_name,
                                           const std::string& sequence_sha256,
                                           db::history::RunState state) const {
  db::history::NewRun nr;
  nr.serial = serial;
  nr.operator_name = operator_name;
  nr.station = cfg_.station_name;
  nr.sequence_name = sequence_name;
  nr.sequence_sha256 = sequence_sha256;
  nr.software_version = software_version_;
  nr.started_at_ms = db::history::now_ms();
  nr.state = state;
  return nr;
}

void RunController::set_phase(Live& live, RunPhase phase) {
  std::lock_guard<std::mutex> lk(mu_);
  for (Unit& u : live.units)
    if (!u.ended && !u.handed_to_worker) u.snap.phase = phase;
}

void RunController::end_live(const std::shared_ptr<Live>& live) {
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (live_ != live) return;
    for (Unit& u : live->units) {
      u.snap.phase = RunPhase::kNone;
      u.snap.time_left_s.reset();
      if (!u.snap.ended_at_ms) u.snap.ended_at_ms = db::history::now_ms();
    }
    last_ = snapshot_of(*live);
    live_.reset();
    // Notified under the lock: the calibration worker's thread ends runs too, and shutdown() (the
    // destructor) may return and destroy cv_ as soon as it sees live_ empty — a notify after the
    // unlock could touch a destroyed condition variable (found by ThreadSanitizer).
    cv_.notify_all();
  }
}

void RunController::apply_calibration_settings(CalibrationJob& job) const {
  job.k_sigma = cfg_.k_sigma;
  job.gap_false_alarm = cfg_.gap_false_alarm;
  job.known_effects = cfg_.known_effects;
}

void RunController::on_calibrated(const std::shared_ptr<Live>& live, size_t unit,
                                  const CalibrationOutcome& out) {
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (live_ != live) return;  // aborted while calibrating: already ended
    Unit& u = live->units.at(unit);
    if (u.ended) return;  // aborted while calibrating, its siblings still running
    RunSnapshot& snap = u.snap;
    u.ended = true;
    snap.phase = RunPhase::kNone;
    if (out.stored) {
      snap.state = out.state;
      snap.verdict = out.verdict;
      snap.crosscheck_verdict = out.crosscheck_verdict;
      snap.reason = out.reason;
      snap.ended_at_ms = db::history::now_ms();
    } else {
      // Not stored: either already terminal in the database (take that) or the database failed
      // (the run stays live there; recovery will mark it interrupted).
      try {
        const db::history::RunRecord rec = repo_.show(snap.run_id).run;
        snap.state = rec.state;
        snap.verdict = rec.verdict;
        snap.crosscheck_verdict = rec.crosscheck_verdict;
        snap.reason = rec.failure_reason;
        snap.ended_at_ms = rec.ended_at_ms;
      } catch (const std::exception&) {
        snap.reason = out.reason;
      }
    }
    if (!live->all_ended()) return;  // its siblings are still capturing or calibrating
  }
  end_live(live);
}

void RunController::control_thread(std::shared_ptr<Live> live) {
  try {
    capture_run(live);
  } catch (const std::exception& e) {
    // capture_run handles every run error itself; this is the database failing at the end.
    spdlog::error("run {}: {}", live->units.front().snap.run_id, e.what());
  }
  bool done = false, aborted = false;
  std::string abort_reason;
  {
    std::lock_guard<std::mutex> lk(mu_);
    live->capture_over = true;
    // A unit the worker did not take (the database failed at its end) ends with the table run.
    for (Unit& u : live->units)
      if (!u.handed_to_worker) u.ended = true;
    done = live->all_ended();
    aborted = live->abort;  // asked for while the last units were handed over
    abort_reason = live->abort_reason;
  }
  if (done)
    end_live(live);
  else if (aborted)
    abort(abort_reason);
}

void RunController::finish_early(Unit& unit, db::history::RunState state,
                                 db::history::RunVerdict verdict, const std::string& reason) {
  std::lock_guard<std::mutex> lk(mu_);
  unit.snap.state = state;
  unit.snap.verdict = verdict;
  unit.snap.reason = reason;
  unit.snap.ended_at_ms = db::history::now_ms();
  unit.snap.phase = RunPhase::kNone;
  unit.ended = true;
}

void RunController::record_end(Live& L, Unit& unit, const db::history::RunCompletion& c) {
  const db::history::RunId id = unit.snap.run_id;
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
        const std::string err = record_end_note(
            note, c.state, c.verdict.value_or(*db::history::run_verdict(c.state)), c.reason);
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

}  // namespace imucal::station::run
