#include "db/fleet/pg_fleet_stats.hpp"

#include <cstdlib>
#include <mutex>

#include "calib/core/param_set.hpp"
#include "db/fleet/fleet_codec.hpp"
#include "db/fleet/fleet_schema.hpp"
#include "db/fleet/pg_connection.hpp"

namespace imucal::db::fleet {
using namespace db::history;

namespace {

// $3 since, $4 until, $5 station, $6 serial, $7 setting, $8 verdicts (comma-separated, 'live': none
// yet), $9 the
// runs a reprocess supersedes (db/history/fleet_stats.hpp: one capture counted once): unset ones
// fold away when the server plans the statement with its values (an unnamed statement is planned
// per call), so the indexes serve.
const char* const kWhere =
    " ($3::bigint IS NULL OR r.started_at_ms >= $3) AND ($4::bigint IS NULL OR r.started_at_ms < "
    "$4)"
    " AND ($5::text IS NULL OR r.station_id = $5) AND ($6::text IS NULL OR r.serial = $6) "
    " AND ($7::text IS NULL OR r.setting = $7)"
    " AND ($8::text IS NULL OR coalesce(r.verdict, 'live') = ANY(string_to_array($8, ',')))"
    " AND NOT (r.id = ANY($9::bigint[])) ";

// The AINS result ains_results() takes (runs r and calibrations c joined): every term determined,
// and a verdict that is the unit's own (or none yet).
const char* const kUsableAinsResult =
    "c.unobservable = '[]'::jsonb AND r.ains_values IS NOT NULL AND "
    "(r.verdict IS NULL OR r.verdict IN ('PASS', 'REVIEW', 'FAILED'))";

/// "{1,2,3}": a bigint[] parameter's text.
std::string id_array(const std::vector<RunId>& ids) {
  std::string s = "{";
  for (const RunId id : ids) s += (s.size() > 1 ? "," : "") + std::to_string(id);
  return s + "}";
}

// The UTC day (utc_day()) in integer arithmetic: floor() of a numeric quotient cost 20 ms more
// over a year of 10^5 runs.
const char* const kDayExpr =
    "CASE WHEN r.started_at_ms >= 0 THEN r.started_at_ms / 86400000 "
    "ELSE -((86399999 - r.started_at_ms) / 86400000) END";

// OFFSET 0 keeps the subquery whole: only (station, value, frame) reach the sort, not each run's
// array. $2: the parameter depends on the body frame (frame_dependent()); then a field run's result
// in another frame than the housing's (a factory AINS result is always in the housing frame:
// calib/ains/ains.cpp) is left out of the statistics and counted apart (o).
const std::string kDistribution =
    "SELECT station_id, count(*) FILTER (WHERE NOT o), avg(v) FILTER (WHERE NOT o), "
    "coalesce(stddev_samp(v) FILTER (WHERE NOT o), 0), min(v) FILTER (WHERE NOT o), "
    "percentile_cont(ARRAY[0.25, 0.5, 0.75]) WITHIN GROUP (ORDER BY v) FILTER (WHERE NOT o), "
    "max(v) FILTER (WHERE NOT o), count(*) FILTER (WHERE o) "
    "FROM (SELECT r.station_id, r.ains_values[$1::int] AS v, (coalesce($2::boolean, false) AND "
    "r.setting <> "
    "'factory' AND EXISTS (SELECT 1 FROM calibrations c WHERE c.run_id = r.id AND c.method = "
    "'ains' AND c.body_frame <> 'housing')) AS o FROM runs r "
    "      WHERE r.ains_values IS NOT NULL AND" +
    std::string(kWhere) +
    " OFFSET 0) s WHERE v IS NOT NULL GROUP BY station_id "
    "ORDER BY station_id COLLATE \"C\"";

}  // namespace

struct PgFleetStats::Impl {
  // No parallel plans for these aggregates: measured on the 2-core reference machine at 10^5
  // runs, a year's verdict counts took 18 ms serially and 64-125 ms with two workers (their start
  // costs more than the scan they share). A site with a large server can set it back in the URL.
  explicit Impl(const FleetTarget& t) : conn(t, "-c max_parallel_workers_per_gather=0") {
    check_fleet_version(conn);
  }
  mutable PgConnection conn;
  mutable std::mutex mutex;

  /// The runs of a reprocess chain with a result ains_results() takes, not calibrated from a
  /// partial archive (signature_stand_ins()'s `usable`; the SQLite backend's rule). Call with the
  /// mutex held.
  std::vector<RunId> usable_reprocess_results() const {
    const PgResult q = conn.exec(
        "SELECT r.id FROM runs r JOIN calibrations c ON c.run_id = r.id AND c.method = 'ains' "
        "WHERE $1::text IS NULL AND r.setting = 'factory' AND " +
            std::string(kUsableAinsResult) +
            " AND (r.reprocessed_from_local IS NOT NULL OR EXISTS (SELECT 1 FROM runs x WHERE "
            "x.station_id = r.station_id AND x.reprocessed_from_local = r.local_run_id)) AND NOT "
            "r.reasons @> '[{\"source\": \"partial archive\"}]'::jsonb",
        {std::nullopt}, "reprocess results");
    std::vector<RunId> out;
    for (int i = 0; i < q.rows(); ++i) out.push_back(q.i64(i, 0));
    return out;
  }

  /// The filter's values ($3..$9); with `one_per_capture`, $9 lists the runs a reprocess
  /// supersedes, read now (every reprocess of the store: a capture's newest run may lie outside
  /// the window). Call with the mutex held.
  std::vector<PgParam> filter_values(const FleetFilter& f, PgParam a, PgParam b,
                                     bool one_per_capture = true) const {
    validate_filter(f);
    std::vector<RunId> superseded;
    if (one_per_capture) superseded = superseded_runs(read_links());
    PgParam verdicts;
    if (f.verdict) {
      std::string list;
      for (const std::string& v : verdict_list(*f.verdict)) list += (list.empty() ? "" : ",") + v;
      verdicts = list;
    }
    return {std::move(a),         std::move(b),        pg_value(f.since_ms),
            pg_value(f.until_ms), pg_value(f.station), pg_value(f.serial),
            pg_value(f.setting),  std::move(verdicts), PgParam(id_array(superseded))};
  }
  /// Every reprocess of the store, ascending run. Call with the mutex held.
  std::vector<ReprocessLink> read_links() const {
    const PgResult q = conn.exec(
        "SELECT r.id, o.id, r.local_run_id, o.local_run_id FROM runs r JOIN runs o ON "
        "o.station_id = r.station_id AND o.local_run_id = r.reprocessed_from_local "
        "WHERE $1::text IS NULL AND r.reprocessed_from_local IS NOT NULL ORDER BY r.id",
        {std::nullopt}, "reprocesses");
    std::vector<ReprocessLink> links;
    for (int i = 0; i < q.rows(); ++i)
      links.push_back({q.i64(i, 0), q.i64(i, 1), q.i64(i, 2), q.i64(i, 3)});
    return links;
  }
};

PgFleetStats::PgFleetStats(const FleetTarget& target) : impl_(std::make_unique<Impl>(target)) {}
PgFleetStats::~PgFleetStats() = default;

std::string PgFleetStats::param_distribution_sql() { return kDistribution; }

std::vector<StationDayCount> PgFleetStats::runs_per_station_day(const FleetFilter& f) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const auto values = impl_->filter_values(f, std::nullopt, std::nullopt);
  const PgResult q = impl_->conn.exec(
      "SELECT r.station_id, " + std::string(kDayExpr) +
          " AS day, count(*) "
          "FROM runs r WHERE $1::text IS NULL AND $2::text IS NULL AND" +
          std::string(kWhere) + "GROUP BY 1, 2 ORDER BY r.station_id COLLATE \"C\", 2",
      values, "runs per station and day");
  std::vector<StationDayCount> out;
  for (int i = 0; i < q.rows(); ++i) out.push_back({q.text(i, 0), q.i64(i, 1), q.i64(i, 2)});
  return out;
}

std::vector<StationVerdictCounts> PgFleetStats::verdict_counts_per_station(
    const FleetFilter& f) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const auto values = impl_->filter_values(f, std::nullopt, std::nullopt);
  const PgResult q = impl_->conn.exec(
      "SELECT r.station_id, count(*) FILTER (WHERE r.verdict = 'PASS'), "
      "count(*) FILTER (WHERE r.verdict = 'REVIEW'), count(*) FILTER (WHERE r.verdict = 'FAILED'), "
      "count(*) FILTER (WHERE r.verdict = 'STATION-FAULT'), "
      "count(*) FILTER (WHERE r.verdict = 'ABORTED'), "
      "count(*) FILTER (WHERE r.verdict = 'INTERRUPTED'), "
      "count(*) FILTER (WHERE r.verdict IS NULL) FROM runs r "
      "WHERE $1::text IS NULL AND $2::text IS NULL AND" +
          std::string(kWhere) + "GROUP BY 1 ORDER BY r.station_id COLLATE \"C\"",
      values, "verdicts per station");
  std::vector<StationVerdictCounts> out;
  for (int i = 0; i < q.rows(); ++i) {
    StationVerdictCounts c{q.text(i, 0)};
    c.pass = q.i64(i, 1);
    c.review = q.i64(i, 2);
    c.failed = q.i64(i, 3);
    c.station_fault = q.i64(i, 4);
    c.aborted = q.i64(i, 5);
    c.interrupted = q.i64(i, 6);
    c.live = q.i64(i, 7);
    out.push_back(c);
  }
  return out;
}

std::vector<ParamSummary> PgFleetStats::param_distribution(int param_index,
                                                           const FleetFilter& f) const {
  if (param_index < 0 || param_index >= calib::core::ParamSet::kSize)
    throw InvalidInput("parameter index " + std::to_string(param_index) + " is not in 0..26");
  // ains_values is 1-based in SQL and in calib::core::param_info order (db/fleet/fleet_schema.cpp).
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const auto values = impl_->filter_values(f, pg_value(std::int64_t{param_index + 1}),
                                           pg_value(frame_dependent(param_index)));
  const PgResult q = impl_->conn.exec(kDistribution, values, "parameter distribution");
  std::vector<ParamSummary> out;
  for (int i = 0; i < q.rows(); ++i) {
    ParamSummary s;
    s.station = q.text(i, 0);
    s.count = q.i64(i, 1);
    s.other_frame = q.i64(i, 7);
    if (s.count == 0) {  // every result in another frame: no statistics (NULLs)
      out.push_back(s);
      continue;
    }
    s.mean = q.f64(i, 2);
    s.std_dev = q.f64(i, 3);
    s.min = q.f64(i, 4);
    // The three quartiles from one sort: "{q1,median,q3}".
    std::string quartiles = q.text(i, 5);
    char* at = quartiles.data() + 1;
    s.q1 = std::strtod(at, &at);
    s.median = std::strtod(at + 1, &at);
    s.q3 = std::strtod(at + 1, &at);
    s.max = q.f64(i, 6);
    out.push_back(s);
  }
  return out;
}

std::vector<ReprocessLink> PgFleetStats::reprocess_links() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->read_links();
}

std::vector<RunId> PgFleetStats::table_run_members(RunId table_run_id) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const PgResult q = impl_->conn.exec(
      "SELECT id FROM runs WHERE id = $1 UNION SELECT f.id FROM runs f JOIN runs r ON r.id = $1 "
      "WHERE f.station_id = r.station_id AND f.table_run_local = r.local_run_id ORDER BY 1",
      {pg_value(table_run_id)}, "table run members");
  std::vector<RunId> out;
  for (int i = 0; i < q.rows(); ++i) out.push_back(q.i64(i, 0));
  return out;
}

std::vector<AinsResultRow> PgFleetStats::ains_results(const FleetFilter& f) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  // Its own rule for reprocesses (the originals stand for them, or the first reprocess with a
  // result where the original has none: signature_stand_ins): no list of superseded runs.
  auto values = impl_->filter_values(f, std::nullopt, std::nullopt, false);
  values.push_back(PgParam(
      id_array(signature_stand_ins(impl_->read_links(), impl_->usable_reprocess_results()))));
  const PgResult q = impl_->conn.exec(
      "SELECT r.id, r.station_id, r.serial, r.sequence_name, r.started_at_ms, c.sigma::text, "
      "r.ains_values::text, r.local_run_id FROM runs r JOIN calibrations c ON c.run_id = r.id AND "
      "c.method = 'ains' WHERE $1::text IS NULL AND $2::text IS NULL AND r.setting = 'factory' "
      "AND (r.reprocessed_from_local IS NULL OR r.id = ANY($10::bigint[])) AND " +
          std::string(kUsableAinsResult) + " AND" + std::string(kWhere) + "ORDER BY r.id",
      values, "AINS results");
  std::vector<AinsResultRow> out;
  for (int i = 0; i < q.rows(); ++i) {
    AinsResultRow row;
    row.run_id = q.i64(i, 0);
    row.station = q.text(i, 1);
    row.serial = q.text(i, 2);
    row.sequence_name = q.text(i, 3);
    row.started_at_ms = q.i64(i, 4);
    row.local_run_id = q.i64(i, 7);
    const std::string origin =
        impl_->conn.target().redacted() + ": run " + std::to_string(row.run_id) + " ains";
    row.sigma = params_from_json(q.text(i, 5), origin + " sigma");
    // "{v1,v2,...}": the 27 values in calib::core::param_info order (db/fleet/fleet_schema.cpp).
    const std::string array = q.text(i, 6);
    calib::core::ParamVector x;
    const char* at = array.c_str() + 1;
    for (int k = 0; k < calib::core::ParamSet::kSize; ++k) {
      char* end = nullptr;
      x(k) = std::strtod(at, &end);
      if (end == at)
        throw Corrupt(origin + ": ains_values has no number for " +
                      calib::core::param_info(k).name);
      at = end + 1;
    }
    row.value = calib::core::ParamSet::from_vector(x);
    out.push_back(std::move(row));
  }
  return out;
}

}  // namespace imucal::db::fleet
