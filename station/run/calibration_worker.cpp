#include "station/run/calibration_worker.hpp"

#include <malloc.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <chrono>
#include <exception>
#include <stdexcept>
#include <string>

#include "calib/pipeline/calibration_pipeline.hpp"
#include "db/archive/archive_error.hpp"
#include "db/archive/archive_input.hpp"
#include "db/archive/run_archive.hpp"
#include "station/run/gap_check.hpp"

namespace imucal::station::run {

namespace {

bool already_terminal(db::history::Repository& repo, db::history::RunId id) {
  return db::history::is_terminal(repo.show(id).run.state);
}

db::history::RunReason limits_reason(const calib::checks::LimitCheckResult& limits) {
  std::string s;
  for (const auto& f : limits.failures) s += (s.empty() ? "" : "; ") + f.detail;
  return {"limits", "limits: " + s};
}

/// Why a pipeline result is not PASS (none when it is): cross-check failures, then limits — or,
/// where the legacy fit holds the rests and AINS does not, its own limits alone (the pipeline's
/// PipelineResult::pass(), calib/pipeline/holding_method.hpp).
std::vector<db::history::RunReason> review_reasons(const calib::pipeline::PipelineResult& r) {
  std::vector<db::history::RunReason> reasons;
  if (r.rests_on_legacy()) {
    calib::checks::LimitCheckResult legacy;
    for (const auto& f : r.limits.failures)
      if (f.method == calib::pipeline::method_name(calib::pipeline::Method::kLegacy))
        legacy.failures.push_back(f);
    if (!legacy.failures.empty()) reasons.push_back(limits_reason(legacy));
    return reasons;
  }
  if (r.crosscheck && !r.crosscheck->pass)
    reasons.push_back(
        db::history::crosscheck_reason(db::history::crosscheck_record(*r.crosscheck, 0.0)));
  if (!r.limits.pass) reasons.push_back(limits_reason(r.limits));
  return reasons;
}

/// What the capture filled in or lost (the archive's run.toml [capture]), for a gap reason: "" for
/// a clean capture or an archive without counters. A gap on a run with interpolated samples may be
/// the interpolation's, not the unit's.
std::string capture_note(const db::archive::RunArchive& ar) {
  if (!ar.info.capture) return "";
  const db::archive::CaptureInfo& c = *ar.info.capture;
  if (c.samples_lost + c.samples_filled + c.samples_late + c.samples_corrupt == 0) return "";
  return " (capture: " + std::to_string(c.samples_lost) + " samples lost, " +
         std::to_string(c.samples_filled) + " filled by interpolation, " +
         std::to_string(c.samples_late) + " late, " + std::to_string(c.samples_corrupt) +
         " corrupt)";
}

/// Factory: AINS + NLSQ, cross-check, and the gap check (a significant sim-to-real gap means an
/// unmodelled effect that biases the calibration, so the run is never PASS then — unless the
/// product's known effects alone explain it, [calibration] known_effects).
void store_factory_result(const calib::pipeline::PipelineResult& r,
                          calib::core::CalibrationInput in, const db::archive::RunArchive& ar,
                          const CalibrationJob& job,
                          const std::function<void(const std::string&)>& phase,
                          db::history::RunCompletion& completion) {
  if (!r.ains || !r.nlsq || !r.crosscheck)
    throw std::runtime_error("the calibration pipeline returned without both methods");
  completion.calibrations.push_back(
      db::history::calibration_record(r.ains->result, &r.ains->metrics));
  completion.calibrations.push_back(
      db::history::calibration_record(r.nlsq->result, &r.nlsq->metrics));
  completion.crosscheck = db::history::crosscheck_record(*r.crosscheck, job.k_sigma);
  phase("gap diagnosis");
  const GapCheck gap =
      check_gap(std::move(in), ar, r.nlsq->result.params, job.gap_false_alarm, job.known_effects);
  completion.diagnosis_json = gap.summary.dump();
  completion.reasons = review_reasons(r);
  if (gap.significant && !gap.known)
    completion.reasons.push_back({"gap", "sim-to-real gap: " + gap.text + capture_note(ar)});
  completion.state =
      completion.reasons.empty() ? db::history::RunState::kDone : db::history::RunState::kReview;
}

/// Land: AINS + legacy and their cross-check (no metrics: no attitude reference; no gap check:
/// it models a table run), and which of the two holds the rests: the run's active set should QA
/// promote it. Sea: AINS alone, which no second method can check — review, for QA to
/// promote explicitly.
void store_field_result(const calib::pipeline::PipelineResult& r, calib::core::Setting setting,
                        double k_sigma, db::history::RunCompletion& completion) {
  if (!r.ains) throw std::runtime_error("the calibration pipeline returned without AINS");
  completion.calibrations.push_back(db::history::calibration_record(r.ains->result, nullptr));
  const std::string frame_note =
      "housing orientation not observable " +
      std::string(setting == calib::core::Setting::kSea ? "at sea" : "on land") +
      " (misalignments in the accelerometer triad's frame)";
  if (setting == calib::core::Setting::kSea || !r.legacy || !r.crosscheck) {
    completion.state = db::history::RunState::kReview;
    if (!r.limits.pass) completion.reasons.push_back(limits_reason(r.limits));
    const std::string unchecked = r.unchecked_reason.empty()
                                      ? "AINS alone, no second method to cross-check it"
                                      : r.unchecked_reason;
    completion.reasons.push_back({"field", unchecked + "; " + frame_note + "; promote explicitly"});
    return;
  }
  completion.calibrations.push_back(db::history::calibration_record(r.legacy->result, nullptr));
  completion.crosscheck = db::history::crosscheck_record(*r.crosscheck, k_sigma);
  if (r.holding) {
    completion.holding_method =
        r.rests_on_legacy() ? db::history::Method::kLegacy : db::history::Method::kAins;
    completion.holding_reason = r.holding->reason;
  }
  completion.reasons = review_reasons(r);
  completion.state =
      completion.reasons.empty() ? db::history::RunState::kDone : db::history::RunState::kReview;
}

/// An incomplete archive (the reprocess of an aborted or interrupted run, asked for explicitly, or
/// any archive whose run.toml says its capture did not complete) is REVIEW at best: the rest of
/// the sequence is missing, and it must never become the unit's active parameters.
void cap_partial_archive(const CalibrationJob& job, const db::archive::RunArchive& ar,
                         db::history::RunCompletion& completion) {
  std::string why = job.partial_reason;
  if (why.empty() && ar.info.capture && !ar.info.capture->complete)
    why = "its archive is incomplete (run.toml [capture] complete = false)";
  if (why.empty() || completion.state == db::history::RunState::kFailed) return;
  completion.state = db::history::RunState::kReview;
  completion.reasons.insert(completion.reasons.begin(),
                            {"partial archive", "partial archive: " + why + " — REVIEW at best"});
}

/// The run's archive could not be read back: the station wrote it (a capture) or copied it in
/// after reading it whole (an import), so a missing, unreadable or corrupt archive is the station's
/// disk or writer, never the unit (issue #50: "a station fault (table, bus, disk, daemon)").
struct StationArchiveFault : std::runtime_error {
  using std::runtime_error::runtime_error;
};

db::archive::RunArchive read_own_archive(const std::string& dir) {
  try {
    return db::archive::read_archive(dir);
  } catch (const db::archive::ArchiveError& e) {
    throw StationArchiveFault(e.what());
  }
}

/// The completion of a run that failed with `reason`, its archive and capture kept.
void failed(const CalibrationJob& job, db::history::RunCompletion& completion,
            const std::string& reason) {
  completion = db::history::RunCompletion{};
  completion.state = db::history::RunState::kFailed;
  completion.reasons = {{"error", reason}};
  completion.archive_path = job.archive_dir;
  completion.archive_sha256 = job.archive_sha256;
  completion.capture_json = job.capture_json;
}

}  // namespace

CalibrationOutcome run_calibration_job(db::history::Repository& repo, const CalibrationJob& job,
                                       const std::function<void(const std::string&)>& on_phase) {
  const auto t0 = std::chrono::steady_clock::now();
  auto phase = [&](const std::string& p) {
    if (on_phase) on_phase(p);
  };
  CalibrationOutcome out;
  out.run_id = job.run_id;

  db::history::RunCompletion completion;
  completion.archive_path = job.archive_dir;
  completion.archive_sha256 = job.archive_sha256;
  completion.capture_json = job.capture_json;
  try {
    phase("reading the archive");
    db::archive::RunArchive ar = read_own_archive(job.archive_dir);
    phase("checking the archive");
    // The samples move into the input (no copy held through the calibration); ar keeps its info,
    // all that is used below.
    calib::core::CalibrationInput in = db::archive::to_calibration_input(std::move(ar));
    if (job.site_gravity_mps2) in.site.gravity_mps2 = *job.site_gravity_mps2;
    calib::pipeline::PipelineOptions opt;
    opt.methods = calib::pipeline::MethodSelection::kAll;
    opt.crosscheck.k_sigma = job.k_sigma;
    opt.on_phase = phase;
    const calib::pipeline::PipelineResult r = calib::pipeline::run_calibration(in, opt);
    if (in.setting == calib::core::Setting::kFactory)
      store_factory_result(r, std::move(in), ar, job, phase, completion);
    else
      store_field_result(r, in.setting, job.k_sigma, completion);
    cap_partial_archive(job, ar, completion);
  } catch (const StationArchiveFault& e) {
    failed(job, completion, "archive: cannot read the run's archive: " + std::string(e.what()));
    completion.verdict =
        db::history::RunVerdict::kStationFault;  // the station's disk, not the unit
  } catch (const std::exception& e) {
    failed(job, completion, std::string("calibration failed: ") + e.what());
  }
  completion.reason = db::history::join_reasons(completion.reasons);
  out.state = completion.state;
  out.verdict =
      completion.verdict ? completion.verdict : db::history::run_verdict(completion.state);
  if (completion.crosscheck) out.crosscheck_verdict = completion.crosscheck->verdict;
  out.reason = completion.reason;
  completion.ended_at_ms = job.ended_at_ms.value_or(db::history::now_ms());
  // The calibration's sample arrays (tens of MB) are freed now; glibc keeps freed heap memory
  // mapped, so give it back: between runs the daemon returns to its idle size (the soak test:
  // 16 MB flat instead of 39 MB).
  malloc_trim(0);

  phase("storing the results");
  if (already_terminal(repo, job.run_id)) {
    out.stored = false;
  } else {
    try {
      repo.finish_run(job.run_id, completion);
    } catch (const db::history::Conflict&) {
      // Became terminal between the check and the write (an abort): that state stands.
      out.stored = false;
    }
  }
  out.runtime_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

CalibrationWorker::CalibrationWorker(db::history::Repository& repository, Phase on_phase,
                                     unsigned threads)
    : repo_(repository), on_phase_(std::move(on_phase)) {
  for (unsigned i = 0; i < std::max(1u, threads); ++i) threads_.emplace_back([this] { loop(); });
}

CalibrationWorker::~CalibrationWorker() { stop(); }

void CalibrationWorker::submit(CalibrationJob job, Done done) {
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (stopping_) throw std::logic_error("calibration worker is stopped");
    queue_.emplace_back(std::move(job), std::move(done));
  }
  cv_.notify_all();
}

bool CalibrationWorker::busy() const {
  std::lock_guard<std::mutex> lk(mu_);
  return running_jobs_ > 0 || !queue_.empty();
}

void CalibrationWorker::wait_idle() {
  std::unique_lock<std::mutex> lk(mu_);
  cv_.wait(lk, [&] { return running_jobs_ == 0 && (queue_.empty() || stopping_); });
}

void CalibrationWorker::stop() {
  {
    std::lock_guard<std::mutex> lk(mu_);
    if (stopping_ && threads_.empty()) return;
    stopping_ = true;
    if (!queue_.empty()) {
      spdlog::warn(
          "calibration worker stopping: {} queued job(s) dropped (their runs are marked "
          "interrupted at the next start)",
          queue_.size());
    }
    queue_.clear();
  }
  cv_.notify_all();
  for (std::thread& t : threads_)
    if (t.joinable()) t.join();
  threads_.clear();
}

void CalibrationWorker::loop() {
  for (;;) {
    std::pair<CalibrationJob, Done> item;
    {
      std::unique_lock<std::mutex> lk(mu_);
      cv_.wait(lk, [&] { return stopping_ || !queue_.empty(); });
      if (queue_.empty()) return;  // stopping
      item = std::move(queue_.front());
      queue_.pop_front();
      ++running_jobs_;
    }
    const CalibrationJob& job = item.first;
    spdlog::info("run {}: calibrating from {}", job.run_id, job.archive_dir);
    CalibrationOutcome out;
    try {
      out = run_calibration_job(repo_, job, [&](const std::string& p) {
        spdlog::debug("run {}: {}", job.run_id, p);
        if (on_phase_) on_phase_(job.run_id, p);
      });
      if (!out.stored) {
        spdlog::info("run {}: calibration result dropped (the run ended meanwhile)", job.run_id);
      } else {
        spdlog::info("run {}: {} in {:.1f} s{}{}", job.run_id, db::history::to_string(out.state),
                     out.runtime_s, out.reason.empty() ? "" : ": ", out.reason);
      }
    } catch (const std::exception& e) {
      // The repository failed (disk full, database locked away): the run stays live and start-up
      // recovery will mark it interrupted with its archive kept.
      out.run_id = job.run_id;
      out.state = db::history::RunState::kFailed;
      out.reason = std::string("storing the results failed: ") + e.what();
      out.stored = false;
      spdlog::error("run {}: {}", job.run_id, out.reason);
    }
    if (item.second) {
      try {
        item.second(out);
      } catch (const std::exception& e) {
        spdlog::error("run {}: completion handler: {}", job.run_id, e.what());
      }
    }
    {
      std::lock_guard<std::mutex> lk(mu_);
      --running_jobs_;
    }
    cv_.notify_all();
  }
}

}  // namespace imucal::station::run
