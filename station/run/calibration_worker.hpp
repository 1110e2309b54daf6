#pragma once
// The daemon's calibration worker: threads that turn finished run archives into stored results, so
// the control socket and the table stay responsive while Ceres and the smoother run.
//
// A job does exactly what `imucal calibrate` and `reprocess` do (one code path, calib/
// calibration_pipeline.hpp): db::archive::read_archive -> db::archive::to_calibration_input ->
// calib::pipeline::run_calibration (AINS and NLSQ, each evaluated, then the cross-check at k_sigma)
// -> calib::diagnosis::diagnose (the sim-to-real gap of the run against its NLSQ calibration) ->
// db::history::calibration_record / db::history::crosscheck_record -> Repository::finish_run in one
// transaction:
//   cross-check PASS, limits kept, gap consistent, archive complete -> done (verdict PASS)
//   otherwise -> review (verdict REVIEW) with one reason per source (db::history::RunReason): the
//     cross-check's failures, the limits', "sim-to-real gap: " + the diagnosis summary, a
//     partial archive, a field setting no second method checks
//   the archive unreadable (missing, I/O error, corrupt: the station wrote or copied it) -> failed
//     (verdict STATION-FAULT), reason "archive: cannot read the run's archive: ..."
//   any other error -> failed (verdict FAILED), reason = the error (the data checks, ...)
// with the archive's SHA-256, the capture counters (capture_json) and the diagnosis summary
// (diagnosis_json) stored with the run.
//
// A run that became terminal while its job waited or ran (aborted by the operator, or by SIGTERM)
// is left as it is: the job's result is dropped and reported as such.
#include <condition_variable>
#include <deque>
#include <functional>
#include <mutex>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "calib/diagnosis/false_alarm.hpp"
#include "db/history/repository.hpp"

namespace imucal::station::run {

struct CalibrationJob {
  db::history::RunId run_id = 0;
  std::string archive_dir;
  std::string archive_sha256;  ///< stored with the result (checked by the caller for reprocess)
  std::string capture_json;    ///< capture counters (capture_stats.hpp) as JSON text, or ""
  double k_sigma = 4.0;
  /// The gap check's false-alarm rate per run ([calibration] gap_false_alarm).
  double gap_false_alarm = calib::diagnosis::kDefaultGapFalseAlarm;
  /// The product's known effects ([calibration] known_effects): a gap they alone explain is no
  /// REVIEW.
  std::vector<std::string> known_effects;
  /// Why the archive is incomplete ("" = complete): the result is then REVIEW at best.
  std::string partial_reason;
  /// The run's end as recorded (an import keeps its archive's times); none: when the job ends.
  std::optional<db::history::TimestampMs> ended_at_ms;
  /// Calibrate with this surveyed gravity instead of the archive's (a reprocess with a corrected
  /// station setting, issue #25), m/s².
  std::optional<double> site_gravity_mps2;
};

struct CalibrationOutcome {
  db::history::RunId run_id = 0;
  db::history::RunState state =
      db::history::RunState::kFailed;              ///< done, review or failed (as stored)
  std::optional<db::history::RunVerdict> verdict;  ///< the run's (db::history::run_verdict(state))
  std::optional<db::history::Verdict>
      crosscheck_verdict;  ///< the cross-check's own, if one was made
  std::string reason;      ///< review: every reason ("; "-joined); failed: the error
  bool stored = true;      ///< false: the run was already terminal, nothing was written
  double runtime_s = 0.0;  ///< wall time of the job
};

/// Runs one job synchronously in the calling thread (what the worker thread does per job).
/// `on_phase` gets the pipeline's phase texts ("reading the archive", "AINS", ...). Never throws
/// for job errors (they become a failed run); throws only if the repository itself fails.
CalibrationOutcome run_calibration_job(
    db::history::Repository& repository, const CalibrationJob& job,
    const std::function<void(const std::string&)>& on_phase = {});

class CalibrationWorker {
 public:
  using Done = std::function<void(const CalibrationOutcome&)>;
  using Phase = std::function<void(db::history::RunId, const std::string&)>;

  /// `threads` jobs run at once (the units of one table run calibrate in parallel; each job is
  /// itself two threads, AINS beside NLSQ): 1 for a one-unit station, at most the machine's
  /// cores otherwise (memory: `imucal bench` of an hour's run at 100 Hz peaks at 88 MB; the
  /// daemon with four units on factory-std at 188 MiB, README "Several units per table run").
  explicit CalibrationWorker(db::history::Repository& repository, Phase on_phase = {},
                             unsigned threads = 1);
  ~CalibrationWorker();  ///< stop()
  CalibrationWorker(const CalibrationWorker&) = delete;
  CalibrationWorker& operator=(const CalibrationWorker&) = delete;

  /// Queues a job; `done` is called from the worker thread when it has been stored (or dropped).
  void submit(CalibrationJob job, Done done);
  /// True while a job is queued or running.
  bool busy() const;
  /// Blocks until no job is queued or running.
  void wait_idle();
  /// Lets the running jobs finish (the pipeline cannot be interrupted), drops queued ones (their
  /// runs stay live and start-up recovery marks them interrupted), joins the threads. Idempotent.
  void stop();

 private:
  void loop();

  db::history::Repository& repo_;
  Phase on_phase_;
  mutable std::mutex mu_;
  std::condition_variable cv_;
  std::deque<std::pair<CalibrationJob, Done>> queue_;
  unsigned running_jobs_ = 0;
  bool stopping_ = false;
  std::vector<std::thread> threads_;
};

}  // namespace imucal::station::run
