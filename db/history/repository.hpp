#pragma once
// The calibration-history repository (ARCHITECTURE §2, station issue item 5): what the daemon
// stores per serial number and what QA reads back. This header is the backend-neutral interface
// plus its plain record structs; db/history/sqlite_repository.hpp is the embedded default, and a
// fleet-wide PostgreSQL backend can implement the same interface without touching the daemon.
//
// Model (db/history/SCHEMA.md has the tables):
//   unit (serial) 1──n run ──1 crosscheck (PASS | REVIEW)
//                        └──n calibration (one per method: ains, nlsq)
// Run states (station issue item 4): preparing → running → calibrating → done | review | failed |
// aborted | interrupted. The first three are "live"; the last five are terminal and final — a run
// never leaves a terminal state (reprocessing creates a new run that names its origin).
//
// The *active* calibration of a serial is the AINS parameter set of its latest FACTORY run
// recorded by this station (by start time, then run id) whose verdict is PASS — unless QA promoted
// a field run (land/sea) or an imported run (`stationctl promote`) after that run ended: then the
// latest promoted run. A field or imported run never becomes active on its own, even with PASS.
// AINS is "the" set because it estimates the full model (paper §IV, 27 parameters incl. table
// misalignment ς, with smoothed covariance) and is the paper's primary method; NLSQ is the
// independent check that made the verdict PASS. The one exception (schema v9): a land run below
// navigation grade on which AINS cannot hold the rests the legacy fit holds
// (calib/pipeline/holding_method.hpp) names legacy as its holding method, and its legacy set is the
// one that becomes active (RunRecord::holding_method). Every set of that run stays retrievable
// (ActiveCalibration::all). A later REVIEW, failed, aborted or interrupted run never replaces the
// active set.
//
// Times are UTC milliseconds since the Unix epoch (TimestampMs); format_time_utc/parse_time_utc
// convert to/from ISO 8601 for people and files.
#include <cstdint>
#include <ctime>
#include <functional>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "calib/checks/crosscheck.hpp"
#include "calib/checks/evaluation.hpp"
#include "calib/core/calibration_input.hpp"
#include "calib/core/param_set.hpp"

namespace imucal::db::history {

using RunId = std::int64_t;
using TimestampMs = std::int64_t;  ///< UTC, milliseconds since 1970-01-01T00:00:00Z

// ---------------------------------------------------------------------------------------------
// Errors. Every repository failure is a DbError whose kind() says what the caller can do about it
// and whose what() names the database file, the operation and the record.
// ---------------------------------------------------------------------------------------------
enum class DbErrorKind {
  kNotFound,            ///< no such run / serial / active calibration, or no database file
  kConflict,            ///< violates the run life cycle or uniqueness (e.g. second nlsq result)
  kCorrupt,             ///< the file is not a sound history database, or a stored value is bad
  kBusy,                ///< another connection held the write lock past busy_timeout
  kReadOnly,            ///< a write through a read-only repository
  kInvalidInput,        ///< a caller-supplied value breaks a documented rule (e.g. serial)
  kIncompatibleSchema,  ///< schema version newer than this software, or not our database
  kIo,                  ///< disk full, I/O error, cannot open
};
const char* to_string(DbErrorKind kind);

class DbError : public std::runtime_error {
 public:
  DbError(DbErrorKind kind, const std::string& message)
      : std::runtime_error(message), kind_(kind) {}
  DbErrorKind kind() const { return kind_; }

 private:
  DbErrorKind kind_;
};

// Typed subclasses so callers can catch exactly what they handle.
struct NotFound : DbError {
  explicit NotFound(const std::string& m) : DbError(DbErrorKind::kNotFound, m) {}
};
struct Conflict : DbError {
  explicit Conflict(const std::string& m) : DbError(DbErrorKind::kConflict, m) {}
};
struct Corrupt : DbError {
  explicit Corrupt(const std::string& m) : DbError(DbErrorKind::kCorrupt, m) {}
};
struct Busy : DbError {
  explicit Busy(const std::string& m) : DbError(DbErrorKind::kBusy, m) {}
};
struct ReadOnly : DbError {
  explicit ReadOnly(const std::string& m) : DbError(DbErrorKind::kReadOnly, m) {}
};
struct InvalidInput : DbError {
  explicit InvalidInput(const std::string& m) : DbError(DbErrorKind::kInvalidInput, m) {}
};
struct IncompatibleSchema : DbError {
  explicit IncompatibleSchema(const std::string& m)
      : DbError(DbErrorKind::kIncompatibleSchema, m) {}
};
struct IoError : DbError {
  explicit IoError(const std::string& m) : DbError(DbErrorKind::kIo, m) {}
};

// ---------------------------------------------------------------------------------------------
// Enumerations with their stored text.
// ---------------------------------------------------------------------------------------------
enum class RunState {
  kPreparing,
  kRunning,
  kCalibrating,
  kDone,
  kReview,
  kFailed,
  kAborted,
  kInterrupted
};
/// "preparing", "running", "calibrating", "done", "review", "failed", "aborted", "interrupted".
const char* to_string(RunState s);
/// Inverse of to_string; InvalidInput naming the accepted words otherwise.
RunState run_state_from_string(const std::string& s);
/// done, review, failed, aborted, interrupted.
bool is_terminal(RunState s);
/// The live states in life-cycle order (preparing, running, calibrating).
const std::vector<RunState>& live_states();

enum class Method { kAins, kNlsq, kLegacy };
const char* to_string(Method m);                  ///< "ains", "nlsq", "legacy"
const char* to_string(calib::core::BodyFrame f);  ///< "housing", "accel_symmetric"
calib::core::BodyFrame body_frame_from_string(const std::string& s);  ///< InvalidInput otherwise
Method method_from_string(const std::string& s);                      ///< InvalidInput otherwise

/// The cross-check's own verdict (AINS against the second method), one input of the run verdict.
enum class Verdict { kPass, kReview };
const char* to_string(Verdict v);                   ///< "PASS", "REVIEW"
Verdict verdict_from_string(const std::string& s);  ///< InvalidInput otherwise

/// The run's verdict (issue #19 item 2, issue #50): the one answer every view shows, and whose
/// the end was. done → PASS, review → REVIEW (the unit's own outcomes, what its yield counts); a
/// run that ended without a result says whose it was — FAILED (the unit's: its data or its
/// calibration failed), STATION-FAULT (the station's: table, CAN bus, disk, daemon), ABORTED (an
/// operator's `run abort`), INTERRUPTED (the daemon stopped or died mid-run). A live run has none.
/// A PASS cross-check does not make a run PASS: the limits, the gap check, a partial archive or a
/// field setting can still send it to review (its reasons say which).
enum class RunVerdict { kPass, kReview, kFailed, kStationFault, kAborted, kInterrupted };
/// "PASS", "REVIEW", "FAILED", "STATION-FAULT", "ABORTED", "INTERRUPTED".
const char* to_string(RunVerdict v);
/// Inverse of to_string; InvalidInput naming the accepted words otherwise.
RunVerdict run_verdict_from_string(const std::string& s);
/// The verdict a terminal state has when nothing else is known of whose its end was: done → PASS,
/// review → REVIEW, failed → FAILED, aborted → ABORTED, interrupted → INTERRUPTED; none while live.
std::optional<RunVerdict> run_verdict(RunState s);
/// Whether a terminal state may end with this verdict: done only PASS, review only REVIEW;
/// failed, aborted and interrupted their default verdict or STATION-FAULT (a table fault ends a
/// capture as aborted, a CAN bus or disk fault as failed, a daemon that could not calibrate as
/// interrupted).
bool verdict_fits_state(RunVerdict v, RunState s);
/// Whether the verdict is the unit's own outcome (PASS, REVIEW, FAILED): what a unit's yield
/// counts. STATION-FAULT, ABORTED and INTERRUPTED say nothing about the unit.
bool is_unit_outcome(RunVerdict v);
/// Whose the outcome is, one word for exports and pages: "unit" (PASS, REVIEW, FAILED), "station"
/// (STATION-FAULT), "operator" (ABORTED), "daemon" (INTERRUPTED). A run's own: outcome_of(run).
const char* outcome_of(RunVerdict v);

/// One reason a run is not PASS, with what raised it. Sources: "cross-check", "limits", "gap",
/// "partial archive", "field" (a setting no second method can check), "error" (the calibration
/// failed: data checks, archive format, ...), "aborted", "interrupted", or "migrated" (a run
/// stored before schema v5, whose single reason text is kept whole).
struct RunReason {
  std::string source;
  std::string text;  ///< as people read it, e.g. "limits: gyro bias z 0.31 deg/h > 0.2 deg/h"
  bool operator==(const RunReason& o) const { return source == o.source && text == o.text; }
};
/// The reasons' texts joined by "; " (RunRecord::failure_reason).
std::string join_reasons(const std::vector<RunReason>& reasons);

// ---------------------------------------------------------------------------------------------
// Records.
// ---------------------------------------------------------------------------------------------

/// What the daemon knows when a run starts.
struct NewRun {
  std::string serial;  ///< db/history/serial_number.hpp rules
  std::string operator_name;
  std::string station;
  std::string sequence_name;
  std::string sequence_sha256;  ///< 64 lowercase hex digits, or empty if unknown
  std::string software_version;
  TimestampMs started_at_ms = 0;
  std::string
      archive_path;  ///< run archive directory (ARCHITECTURE §5); may be set now or at finish
  RunState state = RunState::kPreparing;  ///< must be a live state
  std::optional<RunId>
      reprocessed_from;  ///< for `reprocess RUN_ID`: the run whose archive is reused
  calib::core::Setting setting =
      calib::core::Setting::kFactory;  ///< where the data were recorded (v4)
  std::string origin;  ///< e.g. "imported from /path" for `stationctl import`; empty for runs
  /// The fixture slot the unit sat in (schema v6; "" on a one-unit station), and the table run it
  /// shared with its siblings: the first unit's run id (unset for a run of its own and for the
  /// first unit itself, whose own id it is).
  std::string slot;
  std::optional<RunId> table_run_id;
};

struct RunRecord {
  RunId run_id = 0;
  std::string serial;
  std::string operator_name;
  std::string station;
  std::string sequence_name;
  std::string sequence_sha256;
  std::string software_version;
  TimestampMs started_at_ms = 0;
  std::optional<TimestampMs> ended_at_ms;  ///< set exactly when the state is terminal
  RunState state = RunState::kPreparing;
  std::string failure_reason;      ///< why failed/aborted/interrupted/review (the reasons joined)
  std::vector<RunReason> reasons;  ///< the same, one per source (schema v5); empty for PASS
  std::string archive_path;
  std::string archive_sha256;  ///< 64 lowercase hex digits, or empty
  std::optional<RunId> reprocessed_from;
  std::optional<RunVerdict> verdict;  ///< the run's verdict, stored at its end (schema v10); none
                                      ///< while live
  std::optional<Verdict> crosscheck_verdict;  ///< the cross-check's own, if one is stored
  std::string capture_json;    ///< capture counters (station/run/capture_stats.hpp) as a JSON
                               ///< object text; empty if the run stored none (schema v2)
  std::string diagnosis_json;  ///< gap diagnosis summary (db::archive::diagnosis_summary_json) as a
                               ///< JSON object text; empty if none was made (schema v3)
  calib::core::Setting setting = calib::core::Setting::kFactory;  ///< schema v4
  std::string origin;                                             ///< "imported from DIR", or empty
  std::optional<TimestampMs> promoted_at_ms;  ///< set when QA promoted this run (field runs)
  std::string promoted_by;                    ///< who promoted it (user name or uid)
  std::string promote_reason;
  std::string slot;                   ///< fixture slot (schema v6), "" on a one-unit station
  std::optional<RunId> table_run_id;  ///< the table run shared with siblings (see NewRun)
  /// Schema v7: the run's UUID (32 lowercase hex digits, random, set when the run is created; with
  /// the station id it keys the run in the fleet store) and its revision (how many changes it has
  /// seen; the fleet store keeps the highest).
  std::string uuid;
  std::int64_t revision = 0;
  /// Schema v9: the method whose set is the run's active one when the run is active — AINS, or
  /// legacy where AINS could not hold a land run's rests the legacy fit holds — and why, with both
  /// figures (calib/pipeline/holding_method.hpp; "" for runs that were not judged so).
  Method holding_method = Method::kAins;
  std::string holding_reason;
};

/// Whether an ABORTED run was ended by stationd's own stop (SIGTERM, SIGINT, a stop request),
/// not by an operator's `run abort`: its reason starts with the daemon's wording
/// (station/daemon/daemon.cpp Daemon::run, kDaemonStopReasons). The record holds no structured
/// cause, so the daemon's words are the contract.
bool stopped_by_daemon(const RunRecord& run);
/// outcome_of(verdict), but "daemon" for an ABORTED run stationd's stop ended (issue #52: it
/// was shown as an operator's abort).
const char* outcome_of(const RunRecord& run);
/// The beginnings of the reasons stationd gives a run it stopped (stopped_by_daemon()).
inline constexpr const char* kDaemonStopReasons[] = {"daemon stopped by SIGTERM",
                                                     "daemon stopped by SIGINT", "stop requested"};

/// Headline evaluation metrics of one method (paper §VII, calib/checks/evaluation.hpp), per-period
/// details excluded (they are reproducible from the archive).
struct StoredMetrics {
  double orientation_rmse_mdeg = 0.0;
  double accel_rmse_ug = 0.0;
  double heading_offset_gamma_np_rad = 0.0;
  Eigen::Vector3d body_misalignment_theta_bp_rad = Eigen::Vector3d::Zero();
};

struct CalibrationRecord {
  Method method = Method::kAins;
  calib::core::ParamSet params;  ///< stored as parameter-set JSON (ARCHITECTURE §3)
  calib::core::ParamSet sigma;   ///< 1-σ, same shape, non-negative
  bool converged = false;
  int iterations = 0;
  double runtime_s = 0.0;
  std::vector<std::string> warnings;
  std::optional<StoredMetrics> metrics;
  /// The frame its misalignments refer to (schema v5): housing, or the accelerometer triad's own
  /// (field runs: the housing orientation is not observable without an attitude reference).
  calib::core::BodyFrame body_frame = calib::core::BodyFrame::kHousing;
  std::vector<std::string> unobservable;  ///< parameter names it does not determine (v5)
  std::vector<std::string> notes;         ///< what it cannot say, for people (v5)
};

struct CrosscheckRecord {
  Verdict verdict = Verdict::kReview;
  double k_sigma = 4.0;
  std::vector<calib::checks::CrossCheckFailure> failures;  ///< empty for PASS
  std::vector<std::string> not_compared;  ///< parameters one method cannot observe (v5)
};

/// What finish_run stores, all in one transaction (a run is never "done" without its results).
struct RunCompletion {
  RunState state = RunState::kDone;  ///< must be terminal
  TimestampMs ended_at_ms = 0;
  std::string reason;              ///< required for failed/aborted/interrupted, and
                                   ///< for review without a REVIEW cross-check;
                                   ///< empty: join_reasons(reasons)
  std::vector<RunReason> reasons;  ///< every reason by source; empty: `reason` as one reason
  /// Whose end it was (issue #50): unset → run_verdict(state); STATION-FAULT for a failed,
  /// aborted or interrupted run the station caused (verdict_fits_state, else InvalidInput).
  std::optional<RunVerdict> verdict;
  std::optional<std::string> archive_path;  ///< replaces the stored path if given
  std::string archive_sha256;               ///< 64 lowercase hex digits, or empty
  std::vector<CalibrationRecord>
      calibrations;  ///< stored with the run (may be empty if stored before)
  std::optional<CrosscheckRecord> crosscheck;
  std::string capture_json;    ///< capture counters as a JSON object text, or empty
  std::string diagnosis_json;  ///< gap diagnosis summary as a JSON object text, or empty
  /// The run's holding method and why (RunRecord::holding_method). Legacy only on a land run that
  /// stores a legacy calibration; then a REVIEW cross-check (AINS's disagreement) may end done.
  Method holding_method = Method::kAins;
  std::string holding_reason;
};

struct RunDetails {
  RunRecord run;
  std::vector<CalibrationRecord> calibrations;  ///< ains first, then nlsq
  std::optional<CrosscheckRecord> crosscheck;
};

struct ActiveCalibration {
  RunRecord run;             ///< the latest done+PASS run of the serial
  CalibrationRecord active;  ///< its holding method's result (AINS but where legacy holds): the set
  std::vector<CalibrationRecord> all;  ///< every method of that run (ains, nlsq)
};

struct ExportFilter {
  std::optional<std::string> serial;
  std::optional<TimestampMs> since_ms;  ///< runs with started_at_ms >= since_ms
  /// Runs of this station only (RunRecord::station; in the fleet store, the station id).
  std::optional<std::string> station;
};

/// One exported row: a run with one of its calibrations (no calibration → calibration empty,
/// e.g. failed or aborted runs, so every run appears at least once).
struct ExportRow {
  RunRecord run;
  std::optional<CalibrationRecord> calibration;
  std::optional<CrosscheckRecord> crosscheck;  ///< the run's cross-check, if one is stored
};

// ---------------------------------------------------------------------------------------------
// The interface.
// ---------------------------------------------------------------------------------------------
class Repository {
 public:
  virtual ~Repository() = default;

  /// New run for new.serial (the unit is created on first use). Returns its id, which is larger
  /// than every id issued before (ids are never reused). InvalidInput on a bad serial, SHA-256
  /// text or a non-live state; NotFound if reprocessed_from names no run.
  virtual RunId create_run(const NewRun& run) = 0;

  /// Move a run forward in its life cycle. Live states may only advance (preparing → running →
  /// calibrating; repeating the current state is a no-op); Conflict if the run is terminal or the
  /// move goes backwards. A terminal state is a finish_run with ended_at = now and this reason.
  virtual void update_run_state(RunId run_id, RunState state, const std::string& reason = {}) = 0;

  /// Terminal state, end time, archive hash and (optionally) the results, atomically. Rules:
  /// done needs the setting's two calibrations and a PASS cross-check (stored now or before) —
  /// or, where the completion names legacy as the holding method, a cross-check of either verdict;
  /// a PASS cross-check needs state done and a REVIEW one state review (but where legacy holds);
  /// failed, aborted, interrupted need a reason. Conflict if the run is already terminal, a result
  /// exists twice, or legacy is named holding on a run that is not land or stores no legacy set.
  virtual void finish_run(RunId run_id, const RunCompletion& completion) = 0;

  /// Store one method's result for a live run. Conflict if the run is terminal or this method
  /// is already stored for it.
  virtual void store_calibration(RunId run_id, const CalibrationRecord& calibration) = 0;
  /// Store the cross-check verdict for a live run. Conflict if terminal or already stored.
  virtual void store_crosscheck(RunId run_id, const CrosscheckRecord& crosscheck) = 0;
  /// Replace the gap diagnosis summary of a terminal run (`stationctl diagnose`): a JSON object
  /// text. The run's state and results are untouched. Throws NotFound, InvalidInput (not an
  /// object), Conflict (the run is still live).
  virtual void set_diagnosis(RunId run_id, const std::string& diagnosis_json) = 0;

  /// Start-up recovery: every run in a live state becomes interrupted (ended_at = now_ms, reason
  /// names the state it was found in). Returns their ids, ascending. Results stored so far stay.
  virtual std::vector<RunId> mark_interrupted_runs(TimestampMs now_ms) = 0;

  /// Runs of a serial, newest first (start time descending, then run id descending). limit 0 =
  /// all. InvalidInput for a malformed serial; NotFound if no unit has this serial.
  virtual std::vector<RunRecord> history(const std::string& serial,
                                         std::size_t limit = 0) const = 0;
  /// How many runs the serial has in all (what `history --limit N` shows N of). NotFound as
  /// history().
  virtual std::size_t run_count(const std::string& serial) const = 0;
  /// The newest runs of every unit (start time descending, then run id descending); limit 0 = all.
  virtual std::vector<RunRecord> recent_runs(std::size_t limit) const = 0;
  /// How many runs the database holds in all.
  virtual std::size_t total_run_count() const = 0;
  /// The runs of one station (RunRecord::station; in the fleet store its station id), of one
  /// serial or of every unit, newest first; limit 0 = all. InvalidInput for a malformed serial.
  /// The default filters history()/recent_runs(); the fleet store answers from its index.
  virtual std::vector<RunRecord> station_runs(const std::string& station,
                                              const std::optional<std::string>& serial,
                                              std::size_t limit) const;
  /// How many runs station_runs(station, serial, 0) returns (what `history --station` shows N
  /// of). The default counts them; the fleet store counts in its index.
  virtual std::size_t station_run_count(const std::string& station,
                                        const std::optional<std::string>& serial) const;

  /// Everything stored about a run. NotFound if there is no such run.
  virtual RunDetails show(RunId run_id) const = 0;

  /// The active calibration (see the file comment). NotFound if the serial is unknown or has no
  /// done+PASS run; the message says which.
  virtual ActiveCalibration active_params(const std::string& serial) const = 0;

  /// Stream matching runs, oldest first (start time, run id), one row per run and method (ains
  /// before nlsq). `sink` must not call back into the repository.
  virtual void export_rows(const ExportFilter& filter,
                           const std::function<void(const ExportRow&)>& sink) const = 0;

  /// Runs whose stored archive SHA-256 is `sha256` (64 lowercase hex digits; InvalidInput
  /// otherwise), ascending id: `stationctl import` refuses an archive the history already holds.
  virtual std::vector<RunRecord> runs_with_archive_sha256(const std::string& sha256) const = 0;

  /// Runs currently in any of `states`, ascending id.
  virtual std::vector<RunRecord> runs_in_state(const std::vector<RunState>& states) const = 0;

  /// QA's explicit promotion of a field run (land or sea) or an imported run to the unit's active
  /// parameters, with who, when and why. InvalidInput for an empty reason or `by`; NotFound for
  /// an unknown run; Conflict for a factory run of this station (its PASS makes it active by
  /// itself), a live run, or a run that is neither done (PASS) nor a sea run reviewed only for
  /// want of a second method.
  virtual void promote(RunId run_id, const std::string& by, const std::string& reason,
                       TimestampMs at_ms) = 0;
};

/// The active set among an active run's calibrations (`active.all`): its holding method's
/// (RunRecord::holding_method). Corrupt naming `where` and the run if it stores none.
CalibrationRecord active_calibration(const ActiveCalibration& active, const std::string& where);

// ---------------------------------------------------------------------------------------------
// Conversions from the calibration core's result types.
// ---------------------------------------------------------------------------------------------

/// Method from CalibrationResult::method ("ains" / "nlsq"); InvalidInput otherwise.
CalibrationRecord calibration_record(const calib::core::CalibrationResult& result,
                                     const calib::checks::EvaluationMetrics* metrics);
CrosscheckRecord crosscheck_record(const calib::checks::CrossCheckResult& result, double k_sigma);
/// The reason a REVIEW cross-check gives: {"cross-check", "cross-check REVIEW: " + the failures'
/// details joined by "; "}.
RunReason crosscheck_reason(const CrosscheckRecord& crosscheck);

// ---------------------------------------------------------------------------------------------
// Time.
// ---------------------------------------------------------------------------------------------

/// "2024-05-01T12:34:56.789Z" (always UTC, always milliseconds).
std::string format_time_utc(TimestampMs t_ms);
/// Accepts "YYYY-MM-DD" (midnight UTC), "YYYY-MM-DDTHH:MM[:SS[.fff]]" with optional trailing
/// "Z" (UTC) or "+HH:MM"/"-HH:MM" offset; a space may replace 'T'. Throws InvalidInput naming
/// the accepted forms for anything else (including impossible dates like 2024-02-30).
TimestampMs parse_time_utc(const std::string& text);
/// The system clock now, in TimestampMs.
TimestampMs now_ms();

}  // namespace imucal::db::history
