// Backend-neutral parts of the repository interface: enum texts, conversions from the calibration
// core's result types, and UTC time text.
#include "db/history/repository.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>

namespace imucal::db::history {

const char* to_string(DbErrorKind kind) {
  switch (kind) {
    case DbErrorKind::kNotFound:
      return "not found";
    case DbErrorKind::kConflict:
      return "conflict";
    case DbErrorKind::kCorrupt:
      return "corrupt";
    case DbErrorKind::kBusy:
      return "busy";
    case DbErrorKind::kReadOnly:
      return "read-only";
    case DbErrorKind::kInvalidInput:
      return "invalid input";
    case DbErrorKind::kIncompatibleSchema:
      return "incompatible schema";
    case DbErrorKind::kIo:
      return "I/O error";
  }
  return "?";
}

namespace {
constexpr RunState kAllStates[] = {
    RunState::kPreparing, RunState::kRunning, RunState::kCalibrating, RunState::kDone,
    RunState::kReview,    RunState::kFailed,  RunState::kAborted,     RunState::kInterrupted};
}  // namespace

const char* to_string(RunState s) {
  switch (s) {
    case RunState::kPreparing:
      return "preparing";
    case RunState::kRunning:
      return "running";
    case RunState::kCalibrating:
      return "calibrating";
    case RunState::kDone:
      return "done";
    case RunState::kReview:
      return "review";
    case RunState::kFailed:
      return "failed";
    case RunState::kAborted:
      return "aborted";
    case RunState::kInterrupted:
      return "interrupted";
  }
  return "?";
}

RunState run_state_from_string(const std::string& s) {
  for (RunState st : kAllStates)
    if (s == to_string(st)) return st;
  throw InvalidInput("unknown run state \"" + s +
                     "\" (expected preparing, running, calibrating, done, review, failed, "
                     "aborted or interrupted)");
}

bool is_terminal(RunState s) {
  return s != RunState::kPreparing && s != RunState::kRunning && s != RunState::kCalibrating;
}

const std::vector<RunState>& live_states() {
  static const std::vector<RunState> states = {RunState::kPreparing, RunState::kRunning,
                                               RunState::kCalibrating};
  return states;
}

const char* to_string(Method m) {
  switch (m) {
    case Method::kAins:
      return "ains";
    case Method::kNlsq:
      return "nlsq";
    case Method::kLegacy:
      return "legacy";
  }
  return "ains";
}

Method method_from_string(const std::string& s) {
  if (s == "ains") return Method::kAins;
  if (s == "nlsq") return Method::kNlsq;
  if (s == "legacy") return Method::kLegacy;
  throw InvalidInput("unknown calibration method \"" + s + "\" (expected ains, nlsq or legacy)");
}

const char* to_string(calib::core::BodyFrame f) {
  return f == calib::core::BodyFrame::kHousing ? "housing" : "accel_symmetric";
}

calib::core::BodyFrame body_frame_from_string(const std::string& s) {
  if (s == "housing") return calib::core::BodyFrame::kHousing;
  if (s == "accel_symmetric") return calib::core::BodyFrame::kAccelSymmetric;
  throw InvalidInput("unknown body frame \"" + s + "\" (expected housing or accel_symmetric)");
}

const char* to_string(Verdict v) { return v == Verdict::kPass ? "PASS" : "REVIEW"; }

Verdict verdict_from_string(const std::string& s) {
  if (s == "PASS") return Verdict::kPass;
  if (s == "REVIEW") return Verdict::kReview;
  throw InvalidInput("unknown cross-check verdict \"" + s + "\" (expected PASS or REVIEW)");
}

const char* to_string(RunVerdict v) {
  switch (v) {
    case RunVerdict::kPass:
      return "PASS";
    case RunVerdict::kReview:
      return "REVIEW";
    case RunVerdict::kFailed:
      return "FAILED";
    case RunVerdict::kStationFault:
      return "STATION-FAULT";
    case RunVerdict::kAborted:
      return "ABORTED";
    case RunVerdict::kInterrupted:
      return "INTERRUPTED";
  }
  return "FAILED";
}

RunVerdict run_verdict_from_string(const std::string& s) {
  for (RunVerdict v : {RunVerdict::kPass, RunVerdict::kReview, RunVerdict::kFailed,
                       RunVerdict::kStationFault, RunVerdict::kAborted, RunVerdict::kInterrupted})
    if (s == to_string(v)) return v;
  throw InvalidInput("unknown run verdict \"" + s +
                     "\" (expected PASS, REVIEW, FAILED, STATION-FAULT, ABORTED or INTERRUPTED)");
}

std::optional<RunVerdict> run_verdict(RunState s) {
  switch (s) {
    case RunState::kDone:
      return RunVerdict::kPass;
    case RunState::kReview:
      return RunVerdict::kReview;
    case RunState::kFailed:
      return RunVerdict::kFailed;
    case RunState::kAborted:
      return RunVerdict::kAborted;
    case RunState::kInterrupted:
      return RunVerdict::kInterrupted;
    default:
      return std::nullopt;
  }
}

bool verdict_fits_state(RunVerdict v, RunState s) {
  const std::optional<RunVerdict> own = run_verdict(s);
  if (!own) return false;
  if (v == *own) return true;
  return v == RunVerdict::kStationFault &&
         (s == RunState::kFailed || s == RunState::kAborted || s == RunState::kInterrupted);
}

bool is_unit_outcome(RunVerdict v) {
  return v == RunVerdict::kPass || v == RunVerdict::kReview || v == RunVerdict::kFailed;
}

const char* outcome_of(RunVerdict v) {
  switch (v) {
    case RunVerdict::kStationFault:
      return "station";
    case RunVerdict::kAborted:
      return "operator";
    case RunVerdict::kInterrupted:
      return "daemon";
    default:
      return "unit";
  }
}

bool stopped_by_daemon(const RunRecord& run) {
  if (run.verdict != RunVerdict::kAborted) return false;
  for (const char* p : kDaemonStopReasons)
    if (run.failure_reason.rfind(p, 0) == 0) return true;
  return false;
}

const char* outcome_of(const RunRecord& run) {
  if (!run.verdict) return "";
  return stopped_by_daemon(run) ? "daemon" : outcome_of(*run.verdict);
}

std::string join_reasons(const std::vector<RunReason>& reasons) {
  std::string s;
  for (const RunReason& r : reasons) s += (s.empty() ? "" : "; ") + r.text;
  return s;
}

CalibrationRecord calibration_record(const calib::core::CalibrationResult& result,
                                     const calib::checks::EvaluationMetrics* metrics) {
  CalibrationRecord r;
  r.method = method_from_string(result.method);
  r.params = result.params;
  r.sigma = result.sigma;
  r.converged = result.converged;
  r.iterations = result.iterations;
  r.runtime_s = result.runtime_s;
  r.warnings = result.warnings;
  r.body_frame = result.body_frame;
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i)
    if (!result.observable[static_cast<size_t>(i)])
      r.unobservable.push_back(calib::core::param_info(i).name);
  r.notes = result.unobservable_notes;
  if (metrics) {
    StoredMetrics m;
    m.orientation_rmse_mdeg = metrics->orientation_rmse_mdeg;
    m.accel_rmse_ug = metrics->accel_rmse_ug;
    m.heading_offset_gamma_np_rad = metrics->heading_offset_gamma_np_rad;
    m.body_misalignment_theta_bp_rad = metrics->body_misalignment_theta_bp_rad;
    r.metrics = m;
  }
  return r;
}

CrosscheckRecord crosscheck_record(const calib::checks::CrossCheckResult& result, double k_sigma) {
  CrosscheckRecord r;
  r.verdict = result.pass ? Verdict::kPass : Verdict::kReview;
  r.k_sigma = k_sigma;
  r.failures = result.failures;
  r.not_compared = result.skipped;
  return r;
}

RunReason crosscheck_reason(const CrosscheckRecord& x) {
  std::string s;
  for (const auto& f : x.failures)
    s += (s.empty() ? "" : "; ") + (f.detail.empty() ? f.term : f.detail);
  return {"cross-check", s.empty() ? "cross-check REVIEW" : "cross-check REVIEW: " + s};
}

CalibrationRecord active_calibration(const ActiveCalibration& active, const std::string& where) {
  for (const CalibrationRecord& c : active.all)
    if (c.method == active.run.holding_method) return c;
  throw Corrupt(where + ": run " + std::to_string(active.run.run_id) + " is active but has no " +
                to_string(active.run.holding_method) + " calibration");
}

// ----- time ------------------------------------------------------------------------------------
// Proleptic Gregorian calendar <-> days since 1970-01-01 (H. Hinnant's civil algorithms), so no
// dependence on the process time zone (timegm/gmtime are not needed).
namespace {

std::int64_t days_from_civil(std::int64_t y, unsigned m, unsigned d) {
  y -= m <= 2;
  const std::int64_t era = (y >= 0 ? y : y - 399) / 400;
  const unsigned yoe = static_cast<unsigned>(y - era * 400);
  const unsigned doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + static_cast<std::int64_t>(doe) - 719468;
}

void civil_from_days(std::int64_t z, std::int64_t& y, unsigned& m, unsigned& d) {
  z += 719468;
  const std::int64_t era = (z >= 0 ? z : z - 146096) / 146097;
  const unsigned doe = static_cast<unsigned>(z - era * 146097);
  const unsigned yoe = (doe - doe / 1460 + doe / 36524 - doe / 146096) / 365;
  y = static_cast<std::int64_t>(yoe) + era * 400;
  const unsigned doy = doe - (365 * yoe + yoe / 4 - yoe / 100);
  const unsigned mp = (5 * doy + 2) / 153;
  d = doy - (153 * mp + 2) / 5 + 1;
  m = mp < 10 ? mp + 3 : mp - 9;
  y += m <= 2;
}

bool leap(std::int64_t y) { return (y % 4 == 0 && y % 100 != 0) || y % 400 == 0; }

unsigned days_in_month(std::int64_t y, unsigned m) {
  static const unsigned kDays[] = {31, 28, 31, 30, 31, 30, 31, 31, 30, 31, 30, 31};
  return m == 2 && leap(y) ? 29 : kDays[m - 1];
}

[[noreturn]] void bad_time(const std::string& text, const std::string& why) {
  throw InvalidInput("time \"" + text + "\": " + why +
                     " (expected YYYY-MM-DD or YYYY-MM-DDTHH:MM[:SS[.fff]] with optional Z or "
                     "+HH:MM offset; UTC if no offset)");
}

}  // namespace

std::string format_time_utc(TimestampMs t_ms) {
  std::int64_t days = t_ms / 86400000, rem = t_ms % 86400000;
  if (rem < 0) {
    rem += 86400000;
    --days;
  }
  std::int64_t y;
  unsigned mo, d;
  civil_from_days(days, y, mo, d);
  const int h = static_cast<int>(rem / 3600000), mi = static_cast<int>(rem / 60000 % 60);
  const int s = static_cast<int>(rem / 1000 % 60), ms = static_cast<int>(rem % 1000);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%04lld-%02u-%02uT%02d:%02d:%02d.%03dZ", static_cast<long long>(y),
                mo, d, h, mi, s, ms);
  return buf;
}

TimestampMs parse_time_utc(const std::string& text) {
  std::size_t pos = 0;
  auto digits = [&](std::size_t n, const char* what) -> int {
    if (pos + n > text.size()) bad_time(text, std::string("missing ") + what);
    int v = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const char c = text[pos + i];
      if (c < '0' || c > '9') bad_time(text, std::string("expected digits for ") + what);
      v = v * 10 + (c - '0');
    }
    pos += n;
    return v;
  };
  auto expect = [&](char c, const char* what) {
    if (pos >= text.size() || text[pos] != c) bad_time(text, std::string("expected ") + what);
    ++pos;
  };
  const int year = digits(4, "the year");
  expect('-', "'-' after the year");
  const int month = digits(2, "the month");
  expect('-', "'-' after the month");
  const int day = digits(2, "the day");
  if (month < 1 || month > 12) bad_time(text, "month out of range");
  if (day < 1 || static_cast<unsigned>(day) > days_in_month(year, static_cast<unsigned>(month)))
    bad_time(text, "no such day in that month");
  int hour = 0, minute = 0, second = 0, millis = 0, offset_min = 0;
  if (pos < text.size()) {
    if (text[pos] != 'T' && text[pos] != ' ') bad_time(text, "expected 'T' after the date");
    ++pos;
    hour = digits(2, "the hour");
    expect(':', "':' after the hour");
    minute = digits(2, "the minutes");
    if (pos < text.size() && text[pos] == ':') {
      ++pos;
      second = digits(2, "the seconds");
      if (pos < text.size() && text[pos] == '.') {
        ++pos;
        int n = 0, scale = 100;
        while (pos < text.size() && text[pos] >= '0' && text[pos] <= '9') {
          millis += (text[pos] - '0') * scale;  // digits beyond milliseconds are truncated
          scale /= 10;
          ++pos;
          ++n;
        }
        if (n == 0) bad_time(text, "expected digits after '.'");
      }
    }
    if (hour > 23 || minute > 59 || second > 59) bad_time(text, "time of day out of range");
    if (pos < text.size()) {
      const char c = text[pos];
      if (c == 'Z') {
        ++pos;
      } else if (c == '+' || c == '-') {
        ++pos;
        const int oh = digits(2, "the offset hours");
        expect(':', "':' in the offset");
        const int om = digits(2, "the offset minutes");
        if (oh > 23 || om > 59) bad_time(text, "offset out of range");
        offset_min = (c == '+' ? 1 : -1) * (oh * 60 + om);
      } else {
        bad_time(text, "unexpected text after the time");
      }
    }
  }
  if (pos != text.size()) bad_time(text, "unexpected text at the end");
  const std::int64_t days =
      days_from_civil(year, static_cast<unsigned>(month), static_cast<unsigned>(day));
  const std::int64_t local_ms = ((days * 24 + hour) * 60 + minute) * 60000 +
                                static_cast<std::int64_t>(second) * 1000 + millis;
  return local_ms - static_cast<std::int64_t>(offset_min) * 60000;
}

TimestampMs now_ms() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::vector<RunRecord> Repository::station_runs(const std::string& station,
                                                const std::optional<std::string>& serial,
                                                std::size_t limit) const {
  std::vector<RunRecord> all = serial ? history(*serial) : recent_runs(0);
  std::vector<RunRecord> out;
  for (RunRecord& r : all) {
    if (r.station != station) continue;
    out.push_back(std::move(r));
    if (limit != 0 && out.size() == limit) break;
  }
  return out;
}

std::size_t Repository::station_run_count(const std::string& station,
                                          const std::optional<std::string>& serial) const {
  return station_runs(station, serial, 0).size();
}

}  // namespace imucal::db::history
