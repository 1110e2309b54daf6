#pragma once
// The run state machine of stationd (issue #3 item 4; ARCHITECTURE §2.1, docs/operator.md).
//
// One run at a time. A run's life, with the db::history::RunState stored at each stage and the
// "phase" word the status shows:
//
//   start()  -> create_run                                  preparing
//     control thread:  connect the table                       phase connecting
//                      clear a latched fault, enable, home      phase homing
//                      move to the sequence's start pose        phase moving / settling
//                      IMU stream check (samples decode)        (still connecting)
//                      archive <data_dir>/runs/<id>-<serial>/ created, capture attached
//                                                             running, step i/N
//                      per step: rest   -> Capture::begin_rest(round(rest_s * rate_hz) samples),
//                                          wait_rest_done       phase settling, then resting
//                                rotate -> move_to(target, min(rate, max_rate_dps)), own status
//                                          polling feeding Capture::table_moving, wait_in_position
//                                                               phase moving / settling
//                      capture detached, archive finished (run.toml [capture] complete = true),
//                      SHA-256 of the archive             calibrating
//     worker thread (calibration_worker.hpp): read_archive -> run_calibration -> finish_run
//                                                             done | review | failed
//
// Steps: step 1 is the sequence's initial rest ([start] rest_s), steps 2..N its [[step]]s in file
// order, so N = 1 + number of [[step]] entries. Rests are counted in IMU samples (Capture), never
// in wall time, so an accelerated simulator produces the same archive as real time.
//
// Ending early (every path commands the table to a safe stop, detaches the capture, finishes the
// archive with what it has and stores its SHA-256 and the capture counters):
//   abort(reason) (operator or SIGTERM)            -> aborted, reason as given
//   table fault, e-stop, stale heartbeat, link lost (reconnect gave up), move timeout, command
//   rejected                                        -> aborted, reason "table: ..." (fault code)
//   capture fault (IMU reset, gap, stream timeout, moved during a rest), no IMU stream
//                                                   -> failed, reason "capture: ..."
//   anything else (archive I/O, ...)               -> failed, reason = the error
// An abort during calibrating marks the run aborted at once; the worker's result is dropped.
//
// reprocess(run): checks the stored archive's SHA-256 against the archive on disk, creates a new
// run (reprocessed_from, state calibrating, archive reused) and hands it to the same worker.
//
// Threading: the public methods may be called from any thread (the control server's, the signal
// handler thread); the control thread and the worker's completion callback update the run snapshot
// under one mutex.
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "db/history/repository.hpp"
#include "station/config/config.hpp"
#include "station/control/control_handler.hpp"
#include "station/run/calibration_worker.hpp"
#include "station/run/capture_stats.hpp"

namespace imucal::drivers::turntable {
class TurntableClient;
}

namespace imucal::station::run {
using namespace station::config;
using namespace station::control;

class Capture;

/// What the run is doing right now (the status "phase" word); kNone once it is terminal.
enum class RunPhase {
  kNone,
  kConnecting,
  kHoming,
  kMoving,
  kSettling,
  kResting,
  kCalibrating,
  kStopping
};
/// "connecting", "homing", "moving", "settling", "resting", "calibrating", "stopping"; "" for
/// kNone.
const char* to_string(RunPhase p);

/// A run as the status shows it (live, or rebuilt from the database).
struct RunSnapshot {
  db::history::RunId run_id = 0;
  std::string serial, sequence, operator_name;
  db::history::RunState state = db::history::RunState::kPreparing;
  RunPhase phase = RunPhase::kNone;
  int step = 0, steps = 0;            ///< 0 / 0 when not applicable (reprocess, from the DB)
  std::optional<double> time_left_s;  ///< estimate while capturing
  std::optional<db::history::RunVerdict> verdict;  ///< the run's: PASS / REVIEW / FAILED /
                                                   ///< STATION-FAULT / ABORTED / INTERRUPTED
  std::optional<db::history::Verdict>
      crosscheck_verdict;  ///< the cross-check's own, if one was made
  std::string reason;
  db::history::TimestampMs started_at_ms = 0;
  std::optional<db::history::TimestampMs> ended_at_ms;
  std::optional<CaptureStats> capture;
  std::string archive_path;
  std::optional<db::history::RunId> reprocessed_from;
  std::string slot;                                ///< fixture slot ("" on a one-unit station)
  std::optional<db::history::RunId> table_run_id;  ///< the first unit's run, for its siblings
  /// The other units of the same table run (live: their snapshots; empty for a one-unit run).
  std::vector<RunSnapshot> siblings;
};

/// The contract's "run" object: run_id, serial, sequence, operator, state, phase, step, steps,
/// time_left_s, verdict (the run's), crosscheck_verdict, reason, started_at, capture (null where
/// not applicable), plus ended_at, archive, reprocessed_from, slot and table_run; with siblings,
/// "units": every unit of the table run (this one first) in the same shape.
nlohmann::json to_json(const RunSnapshot& run);
/// A stored run in the same shape (phase/step/time left null; capture from capture_json).
RunSnapshot snapshot_from_record(const db::history::RunRecord& record);

/// One step of the executed plan (the sequence flattened to table commands).
struct PlannedStep {
  enum class Kind { kRest, kMove } kind = Kind::kRest;
  double outer_deg = 0.0, inner_deg = 0.0;  ///< rest pose / move target
  double rate_dps = 0.0;                    ///< move: commanded rate (clipped to max_rate_dps)
  double rest_s = 0.0;                      ///< rest: its length in table seconds
  /// A rest's length in samples of a unit at `rate_hz` (each unit counts its rest at its own rate).
  uint64_t rest_samples(double rate_hz) const {
    return static_cast<uint64_t>(std::llround(rest_s * rate_hz));
  }
  double expected_s = 0.0;  ///< expected duration in table (sim) seconds
  int source_line = 0;      ///< line in the sequence file
};

struct RunPlan {
  std::string sequence_name;  ///< the file's name = "..."
  std::string sequence_path;
  std::string sequence_sha256;
  double start_outer_deg = 0.0, start_inner_deg = 0.0;
  std::vector<PlannedStep> steps;  ///< steps[0] = the initial rest
};

/// Resolves (library name or path), parses and validates a sequence against the station's limits
/// (max_rate_dps) and flattens it. Throws sequences::SequenceError.
RunPlan plan_run(const std::string& sequence, const StationConfig& config);

/// The archive directory of run `id`: <data_dir>/runs/<id>-<serial>.
std::string run_archive_dir(const std::string& data_dir, db::history::RunId id,
                            const std::string& serial);

class RunController {
 public:
  /// `repository` and `worker` must outlive the controller.
  RunController(const StationConfig& config, db::history::Repository& repository,
                CalibrationWorker& worker, std::string software_version = IMUCAL_VERSION);
  ~RunController();  ///< shutdown("daemon shutting down")
  RunController(const RunController&) = delete;
  RunController& operator=(const RunController&) = delete;

  /// Starts a run (returns once it is created, preparing). ControlError: kBusy (a run is live),
  /// kInvalidInput (serial rule, a sequence the station's limits refuse), kNotFound (unknown
  /// sequence), kUnavailable (data directory not writable). Returns the handler's JSON shape.
  nlohmann::json start(const StartRunRequest& request);
  /// ControlError kBusy, kNotFound (no such run / no archive), kInvalidInput (archive changed
  /// since it was recorded), kUnavailable (archive unreadable).
  nlohmann::json reprocess(const ReprocessRequest& request);
  /// `stationctl import DIR`: a field (or other station's) archive into the history, copied into
  /// the station's store and calibrated with its own setting (ControlHandler::import_archive).
  nlohmann::json import_archive(const std::string& dir, const std::string& user);
  /// `stationctl promote RUN --reason`: QA makes a field run the unit's active parameters.
  nlohmann::json promote(db::history::RunId run_id, const std::string& user,
                         const std::string& reason);
  /// The full gap diagnosis of a finished run's archive (checked against its recorded SHA-256; the
  /// run's NLSQ calibration recomputed as the model), its summary stored with the run
  /// (Repository::set_diagnosis). kBusy while a run is active or another diagnosis runs,
  /// kNotFound for an unknown run or a missing archive, kInvalidInput for a changed archive or
  /// one the diagnosis cannot use. Thread-safe; holds no lock while it computes, and no run
  /// starts meanwhile.
  nlohmann::json diagnose(db::history::RunId run_id);
  /// Aborts the live run; false if there is none.
  bool abort(const std::string& reason);

  std::optional<RunSnapshot> active() const;
  std::optional<RunSnapshot> last_finished() const;
  bool busy() const;
  /// Waits until no run is live (true) or the timeout passed (false).
  bool wait_idle(std::chrono::milliseconds timeout);
  /// Aborts the live run with `reason`, waits for it to end (the worker's running job included)
  /// and refuses new runs from then on. Idempotent.
  void shutdown(const std::string& reason);

 private:
  struct Live;
  struct Unit;
  /// One run's capture as named stages (station/run/run_session.cpp).
  struct Session;
  friend struct Session;
  void control_thread(std::shared_ptr<Live> live);
  void capture_run(const std::shared_ptr<Live>& live);
  void finish_early(Unit& unit, db::history::RunState state, db::history::RunVerdict verdict,
                    const std::string& reason);
  /// Stores the run's end; when the database cannot (disk full), keeps it in the run's end note
  /// and retries every kRecordRetry until it can or the run is aborted / the daemon stops.
  void record_end(Live& live, Unit& unit, const db::history::RunCompletion& completion);
  static constexpr std::chrono::milliseconds kRecordRetry{2000};
  void on_calibrated(const std::shared_ptr<Live>& live, size_t unit, const CalibrationOutcome& out);
  /// The fixture slots and serials of a start request, checked (ControlError kInvalidInput).
  std::vector<std::pair<const ImuSlotConfig*, std::string>> units_of(
      const StartRunRequest& request) const;
  /// One preparing run per unit (the siblings naming the first as their table run), added to
  /// `live`; returns [{run_id, serial, slot}]. Needs mu_.
  nlohmann::json create_unit_runs(
      Live& live, const std::vector<std::pair<const ImuSlotConfig*, std::string>>& units,
      const std::string& operator_name);
  /// The live runs' snapshot as the status shows it: the first unit's, with its siblings.
  RunSnapshot snapshot_of(const Live& live) const;
  /// The station's calibration settings into a job (k_sigma, gap_false_alarm, known_effects):
  /// a run's, a reprocess's and an import's alike.
  void apply_calibration_settings(CalibrationJob& job) const;
  void set_phase(Live& live, RunPhase phase);
  /// A finished run whose archive is present and unchanged (what reprocess() and diagnose() check);
  /// `digest` gets the archive's SHA-256 (with check_digest; otherwise the caller checks it with
  /// unchanged_archive_digest, which needs no lock). Throws ControlError. Needs mu_.
  db::history::RunDetails stored_run_with_archive(db::history::RunId run_id, const char* what,
                                                  std::string& digest,
                                                  bool check_digest = true) const;
  /// The archive's SHA-256, refused (ControlError) unless it is the recorded one.
  static std::string unchanged_archive_digest(const db::history::RunRecord& run, const char* what);
  /// A new run of this station and software, started now (what start() and reprocess() share).
  db::history::NewRun new_run(const std::string& serial, const std::string& operator_name,
                              const std::string& sequence_name, const std::string& sequence_sha256,
                              db::history::RunState state) const;
  void end_live(const std::shared_ptr<Live>& live);
  std::string archive_dir_for(db::history::RunId id, const std::string& serial) const;

  StationConfig cfg_;
  db::history::Repository& repo_;
  CalibrationWorker& worker_;
  std::string software_version_;

  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::shared_ptr<Live> live_;
  std::optional<RunSnapshot> last_;
  std::thread thread_;
  bool shut_down_ = false;
  std::optional<db::history::RunId>
      diagnosing_;  ///< a diagnosis runs (off the lock): no run starts
};

}  // namespace imucal::station::run
