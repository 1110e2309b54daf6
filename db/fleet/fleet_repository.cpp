#include "db/fleet/fleet_repository.hpp"

#include <algorithm>

#include "db/fleet/fleet_codec.hpp"
#include "db/fleet/fleet_schema.hpp"
#include "db/history/serial_number.hpp"

namespace imucal::db::fleet {
using namespace db::history;

namespace {

// The run columns, in RunRecord order; the store's ids for the station-local references.
const std::string kRunColumns =
    "r.id, r.serial, r.operator, r.station, r.sequence_name, r.sequence_sha256, "
    "r.software_version, r.started_at_ms, r.ended_at_ms, r.state, r.failure_reason, "
    "r.archive_path, r.archive_sha256, "
    "(SELECT f.id FROM runs f WHERE f.station_id = r.station_id "
    "   AND f.local_run_id = r.reprocessed_from_local), "
    "x.verdict, r.capture_json, r.diagnosis_json, r.setting, r.origin, r.promoted_at_ms, "
    "r.promoted_by, r.promote_reason, r.reasons::text, r.slot, "
    "(SELECT f.id FROM runs f WHERE f.station_id = r.station_id "
    "   AND f.local_run_id = r.table_run_local), "
    "r.run_uuid, r.revision, r.holding_method, r.holding_reason, r.verdict";
constexpr int kNumRunColumns = 30;
const std::string kRunFrom = " FROM runs r LEFT JOIN crosschecks x ON x.run_id = r.id ";
const std::string kCalColumns =
    "c.method, c.params::text, c.sigma::text, c.converged, c.iterations, c.runtime_s, "
    "c.warnings::text, c.metrics::text, c.body_frame, c.unobservable::text, c.notes::text";
const std::string kActiveFactory = "SELECT " + kRunColumns + kRunFrom +
                                   "WHERE r.serial = $1 AND r.verdict = 'PASS' AND "
                                   "r.setting = 'factory' AND r.origin = '' "
                                   "ORDER BY r.started_at_ms DESC, r.id DESC LIMIT 1";
const std::string kLatestPromoted = "SELECT " + kRunColumns + kRunFrom +
                                    "WHERE r.serial = $1 AND r.promoted_at_ms IS NOT NULL "
                                    "ORDER BY r.promoted_at_ms DESC, r.id DESC LIMIT 1";
constexpr int kExportFetchRows = 2000;

std::string run_label(RunId id) { return "run " + std::to_string(id); }

}  // namespace

struct FleetRepository::Impl {
  explicit Impl(const FleetTarget& t) : conn(t) { check_fleet_version(conn); }
  mutable PgConnection conn;
  mutable std::mutex mutex;

  std::string where() const { return "fleet store " + conn.target().redacted(); }

  RunRecord read_run(const PgResult& q, int row) const {
    RunRecord r;
    r.run_id = q.i64(row, 0);
    const std::string origin = where() + " " + run_label(r.run_id);
    r.serial = q.text(row, 1);
    r.operator_name = q.text(row, 2);
    r.station = q.text(row, 3);
    r.sequence_name = q.text(row, 4);
    r.sequence_sha256 = q.text(row, 5);
    r.software_version = q.text(row, 6);
    r.started_at_ms = q.i64(row, 7);
    r.ended_at_ms = q.opt_i64(row, 8);
    r.state = decode(origin + " state", [&] { return run_state_from_string(q.text(row, 9)); });
    r.failure_reason = q.text(row, 10);
    r.archive_path = q.text(row, 11);
    r.archive_sha256 = q.text(row, 12);
    r.reprocessed_from = q.opt_i64(row, 13);
    if (!q.is_null(row, 14))
      r.crosscheck_verdict = decode(origin + " cross-check verdict",
                                    [&] { return verdict_from_string(q.text(row, 14)); });
    r.capture_json = q.text(row, 15);
    r.diagnosis_json = q.text(row, 16);
    const auto setting = calib::core::parse_setting(q.text(row, 17));
    if (!setting) throw Corrupt(origin + ": unknown setting \"" + q.text(row, 17) + "\"");
    r.setting = *setting;
    r.origin = q.text(row, 18);
    r.promoted_at_ms = q.opt_i64(row, 19);
    r.promoted_by = q.text(row, 20);
    r.promote_reason = q.text(row, 21);
    r.reasons = reasons_from_json(q.text(row, 22), origin + " reasons");
    r.slot = q.text(row, 23);
    r.table_run_id = q.opt_i64(row, 24);
    r.uuid = q.text(row, 25);
    r.revision = q.i64(row, 26);
    r.holding_method =
        decode(origin + " holding_method", [&] { return method_from_string(q.text(row, 27)); });
    r.holding_reason = q.text(row, 28);
    if (!q.is_null(row, 29))
      r.verdict =
          decode(origin + " verdict", [&] { return run_verdict_from_string(q.text(row, 29)); });
    if (is_terminal(r.state) != r.verdict.has_value() ||
        (r.verdict && !verdict_fits_state(*r.verdict, r.state)))
      throw Corrupt(origin + ": verdict \"" + q.text(row, 29) + "\" contradicts its state " +
                    to_string(r.state));
    return r;
  }

  /// Calibration columns from c0 (the method); nullopt if the method is NULL (LEFT JOIN).
  std::optional<CalibrationRecord> read_calibration(const PgResult& q, int row, int c0,
                                                    RunId run_id) const {
    if (q.is_null(row, c0)) return std::nullopt;
    CalibrationRecord c;
    const std::string origin = where() + " " + run_label(run_id) + " " + q.text(row, c0);
    c.method = decode(origin + " method", [&] { return method_from_string(q.text(row, c0)); });
    c.params = params_from_json(q.text(row, c0 + 1), origin + " params");
    c.sigma = params_from_json(q.text(row, c0 + 2), origin + " sigma");
    c.converged = q.boolean(row, c0 + 3);
    c.iterations = static_cast<int>(q.i64(row, c0 + 4));
    c.runtime_s = q.f64(row, c0 + 5);
    c.warnings = strings_from_json(q.text(row, c0 + 6), origin + " warnings");
    if (!q.is_null(row, c0 + 7)) c.metrics = metrics_from_json(q.text(row, c0 + 7), origin);
    c.body_frame =
        decode(origin + " body_frame", [&] { return body_frame_from_string(q.text(row, c0 + 8)); });
    c.unobservable = strings_from_json(q.text(row, c0 + 9), origin + " unobservable");
    c.notes = strings_from_json(q.text(row, c0 + 10), origin + " notes");
    return c;
  }

  template <typename F>
  static auto decode(const std::string& what, F f) -> decltype(f()) {
    try {
      return f();
    } catch (const InvalidInput& e) {
      throw Corrupt(what + ": stored value is invalid: " + e.what());
    }
  }

  std::vector<RunRecord> runs(const std::string& sql, const std::vector<PgParam>& params,
                              const char* op) const {
    const PgResult q = conn.exec(sql, params, op);
    std::vector<RunRecord> out;
    for (int i = 0; i < q.rows(); ++i) out.push_back(read_run(q, i));
    return out;
  }

  std::vector<CalibrationRecord> calibrations_of(RunId id) const {
    const PgResult q = conn.exec(
        "SELECT " + kCalColumns + " FROM calibrations c WHERE c.run_id = $1 ORDER BY c.method",
        {pg_value(id)}, "read calibrations");
    std::vector<CalibrationRecord> out;
    for (int i = 0; i < q.rows(); ++i) out.push_back(*read_calibration(q, i, 0, id));
    return out;
  }

  std::optional<CrosscheckRecord> crosscheck_of(RunId id) const {
    const PgResult q = conn.exec(
        "SELECT verdict, k_sigma, failures::text, not_compared::text FROM crosschecks "
        "WHERE run_id = $1",
        {pg_value(id)}, "read the cross-check");
    if (q.rows() == 0) return std::nullopt;
    const std::string origin = where() + " " + run_label(id) + " cross-check";
    CrosscheckRecord x;
    x.verdict = decode(origin, [&] { return verdict_from_string(q.text(0, 0)); });
    x.k_sigma = q.f64(0, 1);
    x.failures = failures_from_json(q.text(0, 2), origin);
    x.not_compared = strings_from_json(q.text(0, 3), origin);
    return x;
  }

  std::size_t count_of(const std::string& serial) const {
    return static_cast<std::size_t>(
        conn.exec("SELECT count(*) FROM runs WHERE serial = $1", {pg_value(serial)}, "count runs")
            .i64(0, 0));
  }

  [[noreturn]] void refuse_write(const char* op) const {
    throw ReadOnly(where() + ": " + op +
                   ": the fleet store is written only by the stations' outbox senders "
                   "(write at the station; it replicates)");
  }
};

FleetRepository::FleetRepository(const FleetTarget& target)
    : impl_(std::make_unique<Impl>(target)) {}
FleetRepository::~FleetRepository() = default;
const FleetTarget& FleetRepository::target() const { return impl_->conn.target(); }

RunId FleetRepository::create_run(const NewRun&) { impl_->refuse_write("create_run"); }
void FleetRepository::update_run_state(RunId, RunState, const std::string&) {
  impl_->refuse_write("update_run_state");
}
void FleetRepository::finish_run(RunId, const RunCompletion&) { impl_->refuse_write("finish_run"); }
void FleetRepository::store_calibration(RunId, const CalibrationRecord&) {
  impl_->refuse_write("store_calibration");
}
void FleetRepository::store_crosscheck(RunId, const CrosscheckRecord&) {
  impl_->refuse_write("store_crosscheck");
}
void FleetRepository::set_diagnosis(RunId, const std::string&) {
  impl_->refuse_write("set_diagnosis");
}
std::vector<RunId> FleetRepository::mark_interrupted_runs(TimestampMs) {
  impl_->refuse_write("mark_interrupted_runs");
}
void FleetRepository::promote(RunId, const std::string&, const std::string&, TimestampMs) {
  impl_->refuse_write("promote");
}

std::vector<RunRecord> FleetRepository::history(const std::string& serial,
                                                std::size_t limit) const {
  validate_serial(serial);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  PgTransaction tx(impl_->conn, "history", true);
  if (impl_->count_of(serial) == 0)
    throw NotFound(impl_->where() + ": no unit with serial number \"" + serial + "\" on record");
  auto out =
      impl_->runs("SELECT " + kRunColumns + kRunFrom +
                      "WHERE r.serial = $1 ORDER BY r.started_at_ms DESC, r.id DESC "
                      "LIMIT $2",
                  {pg_value(serial),
                   limit == 0 ? PgParam(std::nullopt) : pg_value(static_cast<std::int64_t>(limit))},
                  "history");
  tx.commit();
  return out;
}

std::size_t FleetRepository::run_count(const std::string& serial) const {
  validate_serial(serial);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const std::size_t n = impl_->count_of(serial);
  if (n == 0)
    throw NotFound(impl_->where() + ": no unit with serial number \"" + serial + "\" on record");
  return n;
}

std::vector<RunRecord> FleetRepository::recent_runs(std::size_t limit) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->runs(
      "SELECT " + kRunColumns + kRunFrom + "ORDER BY r.started_at_ms DESC, r.id DESC LIMIT $1",
      {limit == 0 ? PgParam(std::nullopt) : pg_value(static_cast<std::int64_t>(limit))},
      "recent runs");
}

std::size_t FleetRepository::total_run_count() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return static_cast<std::size_t>(
      impl_->conn.exec("SELECT count(*) FROM runs", {}, "count runs").i64(0, 0));
}

std::vector<RunRecord> FleetRepository::station_runs(const std::string& station,
                                                     const std::optional<std::string>& serial,
                                                     std::size_t limit) const {
  if (serial) validate_serial(*serial);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->runs(
      "SELECT " + kRunColumns + kRunFrom +
          "WHERE r.station_id = $1 AND ($2::text IS NULL OR r.serial = $2) "
          "ORDER BY r.started_at_ms DESC, r.id DESC LIMIT $3",
      {pg_value(station), pg_value(serial),
       limit == 0 ? PgParam(std::nullopt) : pg_value(static_cast<std::int64_t>(limit))},
      "station runs");
}

std::size_t FleetRepository::station_run_count(const std::string& station,
                                               const std::optional<std::string>& serial) const {
  if (serial) validate_serial(*serial);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return static_cast<std::size_t>(
      impl_->conn
          .exec("SELECT count(*) FROM runs r WHERE r.station_id = $1 AND "
                "($2::text IS NULL OR r.serial = $2)",
                {pg_value(station), pg_value(serial)}, "count station runs")
          .i64(0, 0));
}

RunDetails FleetRepository::show(RunId run_id) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  PgTransaction tx(impl_->conn, "show", true);
  auto runs = impl_->runs("SELECT " + kRunColumns + kRunFrom + "WHERE r.id = $1",
                          {pg_value(run_id)}, "show");
  if (runs.empty()) throw NotFound("no " + run_label(run_id) + " in the " + impl_->where());
  RunDetails d;
  d.run = std::move(runs.front());
  d.calibrations = impl_->calibrations_of(run_id);
  d.crosscheck = impl_->crosscheck_of(run_id);
  tx.commit();
  return d;
}

ActiveCalibration FleetRepository::active_params(const std::string& serial) const {
  validate_serial(serial);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const Impl& d = *impl_;
  PgTransaction tx(d.conn, "active_params", true);
  const std::size_t n = d.count_of(serial);
  if (n == 0)
    throw NotFound(d.where() + ": no unit with serial number \"" + serial + "\" on record");
  auto factory = d.runs(kActiveFactory, {pg_value(serial)}, "active_params");
  auto promoted = d.runs(kLatestPromoted, {pg_value(serial)}, "active_params");
  if (factory.empty() && promoted.empty())
    throw NotFound(d.where() + ": serial number \"" + serial + "\" has no active calibration (" +
                   std::to_string(n) +
                   " run(s) on record: none a factory run with verdict PASS, none promoted)");
  ActiveCalibration out;
  // A promotion made after the latest factory PASS ended wins (QA's explicit choice).
  const bool use_promoted =
      factory.empty() || (!promoted.empty() && *promoted.front().promoted_at_ms >
                                                   factory.front().ended_at_ms.value_or(0));
  out.run = use_promoted ? promoted.front() : factory.front();
  out.all = d.calibrations_of(out.run.run_id);
  out.active = active_calibration(out, d.where());
  tx.commit();
  return out;
}

void FleetRepository::export_rows(const ExportFilter& filter,
                                  const std::function<void(const ExportRow&)>& sink) const {
  if (filter.serial) validate_serial(*filter.serial);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl& d = *impl_;
  PgTransaction tx(d.conn, "export", true);
  // A cursor: the rows arrive kExportFetchRows at a time, so memory stays flat at any size.
  d.conn.exec("DECLARE fleet_export NO SCROLL CURSOR FOR SELECT " + kRunColumns + ", " +
                  kCalColumns + ", x.k_sigma, x.failures::text, x.not_compared::text" + kRunFrom +
                  "LEFT JOIN calibrations c ON c.run_id = r.id "
                  "WHERE ($1::text IS NULL OR r.serial = $1) "
                  "AND ($2::bigint IS NULL OR r.started_at_ms >= $2) "
                  "AND ($3::text IS NULL OR r.station_id = $3) "
                  "ORDER BY r.started_at_ms, r.id, c.method",
              {pg_value(filter.serial), pg_value(filter.since_ms), pg_value(filter.station)},
              "export");
  const int x0 = kNumRunColumns + 11;
  for (;;) {
    const PgResult q = d.conn.exec(
        "FETCH " + std::to_string(kExportFetchRows) + " FROM fleet_export", {}, "export");
    for (int i = 0; i < q.rows(); ++i) {
      ExportRow row;
      row.run = d.read_run(q, i);
      row.calibration = d.read_calibration(q, i, kNumRunColumns, row.run.run_id);
      if (!q.is_null(i, x0)) {
        const std::string origin = d.where() + " " + run_label(row.run.run_id) + " cross-check";
        CrosscheckRecord x;
        x.verdict = *row.run.crosscheck_verdict;
        x.k_sigma = q.f64(i, x0);
        x.failures = failures_from_json(q.text(i, x0 + 1), origin);
        x.not_compared = strings_from_json(q.text(i, x0 + 2), origin);
        row.crosscheck = x;
      }
      sink(row);
    }
    if (q.rows() < kExportFetchRows) break;
  }
  tx.commit();
}

std::vector<RunRecord> FleetRepository::runs_with_archive_sha256(const std::string& sha256) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->runs(
      "SELECT " + kRunColumns + kRunFrom + "WHERE r.archive_sha256 = $1 ORDER BY r.id",
      {pg_value(sha256)}, "runs with archive");
}

std::vector<RunRecord> FleetRepository::runs_in_state(const std::vector<RunState>& states) const {
  std::vector<std::string> names;
  for (RunState s : states) names.push_back(to_string(s));
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->runs(
      "SELECT " + kRunColumns + kRunFrom + "WHERE r.state = ANY ($1::text[]) ORDER BY r.id",
      {pg_text_array(names)}, "runs in state");
}

std::vector<std::pair<std::string, std::size_t>> FleetRepository::stations() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const PgResult q = impl_->conn.exec(
      "SELECT station_id, count(*) FROM runs GROUP BY station_id ORDER BY station_id", {},
      "stations");
  std::vector<std::pair<std::string, std::size_t>> out;
  for (int i = 0; i < q.rows(); ++i)
    out.emplace_back(q.text(i, 0), static_cast<std::size_t>(q.i64(i, 1)));
  return out;
}

}  // namespace imucal::db::fleet
