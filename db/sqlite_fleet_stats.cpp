#include "db/sqlite_fleet_stats.hpp"

#include <sqlite3.h>
#include <sys/stat.h>

#include <map>
#include <mutex>

#include "calib/core/param_set.hpp"
#include "db/schema.hpp"
#include "db/sqlite_repository.hpp"

namespace imucal::db {

namespace {

// ----- SQL: constant fragments only; every value is a bound named parameter
// -----------------------

/// The UTC day of r.started_at_ms, floor division also before 1970 (utc_day()).
const char* const kDayExpr =
    "CASE WHEN r.started_at_ms >= 0 THEN r.started_at_ms / 86400000 "
    "ELSE -((86399999 - r.started_at_ms) / 86400000) END";
const char* const kWhereSerial = "r.unit_id = (SELECT id FROM units WHERE serial = :serial)";
const char* const kWhereSince = "r.started_at_ms >= :since";
const char* const kWhereUntil = "r.started_at_ms < :until";
const char* const kWhereStation = "r.station = :station";

/// " WHERE a AND b ..." for the filters given ("" for none).
std::string where_clause(const FleetFilter& f) {
  std::string w;
  auto add = [&w](const char* cond) { w += (w.empty() ? " WHERE " : " AND ") + std::string(cond); };
  if (f.serial) add(kWhereSerial);
  if (f.since_ms) add(kWhereSince);
  if (f.until_ms) add(kWhereUntil);
  if (f.station) add(kWhereStation);
  return w;
}

}  // namespace

struct SqliteFleetStats::Impl {
  std::string path;
  sqlite3* db = nullptr;
  mutable std::mutex mutex;

  ~Impl() {
    if (db) sqlite3_close_v2(db);
  }

  /// A prepared statement for one call, finalised on destruction.
  class Query {
   public:
    Query(const Impl& impl, const std::string& sql, const char* op) : impl_(impl), op_(op) {
      const int rc = sqlite3_prepare_v2(impl.db, sql.c_str(), -1, &st_, nullptr);
      if (rc != SQLITE_OK)
        schema::throw_sqlite(impl.db, rc, impl.path, std::string(op) + ": prepare");
    }
    ~Query() { sqlite3_finalize(st_); }
    Query(const Query&) = delete;
    Query& operator=(const Query&) = delete;

    /// Binds `name` if the statement has it (its WHERE clause may not).
    void bind_text(const char* name, const std::string& v) {
      if (const int i = sqlite3_bind_parameter_index(st_, name))
        check(sqlite3_bind_text(st_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT));
    }
    void bind_int(const char* name, std::int64_t v) {
      if (const int i = sqlite3_bind_parameter_index(st_, name))
        check(sqlite3_bind_int64(st_, i, v));
    }
    void bind_filter(const FleetFilter& f) {
      if (f.serial) bind_text(":serial", *f.serial);
      if (f.since_ms) bind_int(":since", *f.since_ms);
      if (f.until_ms) bind_int(":until", *f.until_ms);
      if (f.station) bind_text(":station", *f.station);
    }
    bool step() {
      const int rc = sqlite3_step(st_);
      if (rc == SQLITE_ROW) return true;
      if (rc == SQLITE_DONE) return false;
      schema::throw_sqlite(impl_.db, rc, impl_.path, op_);
    }
    std::int64_t i64(int c) const { return sqlite3_column_int64(st_, c); }
    int type(int c) const { return sqlite3_column_type(st_, c); }
    double f64(int c) const { return sqlite3_column_double(st_, c); }
    std::string text(int c) const { return schema::column_text(st_, c); }

   private:
    void check(int rc) {
      if (rc != SQLITE_OK)
        schema::throw_sqlite(impl_.db, rc, impl_.path, std::string(op_) + ": bind");
    }
    const Impl& impl_;
    const char* op_;
    sqlite3_stmt* st_ = nullptr;
  };

  /// Reads in one snapshot: BEGIN now, ROLLBACK (nothing to keep) when done.
  class Snapshot {
   public:
    Snapshot(const Impl& impl, const char* op) : impl_(impl) {
      schema::exec(impl.db, "BEGIN", impl.path, std::string(op) + ": begin");
    }
    ~Snapshot() { sqlite3_exec(impl_.db, "ROLLBACK", nullptr, nullptr, nullptr); }
    Snapshot(const Snapshot&) = delete;
    Snapshot& operator=(const Snapshot&) = delete;

   private:
    const Impl& impl_;
  };
};

SqliteFleetStats::SqliteFleetStats(const std::string& path) : impl_(std::make_unique<Impl>()) {
  Impl& d = *impl_;
  d.path = path;
  struct stat sb;
  if (::stat(path.c_str(), &sb) != 0)
    throw NotFound(path + ": no such database file (read-only mode never creates one)");
  const int rc =
      sqlite3_open_v2(path.c_str(), &d.db, SQLITE_OPEN_READONLY | SQLITE_OPEN_NOMUTEX, nullptr);
  if (rc != SQLITE_OK) schema::throw_sqlite(d.db, rc, path, "open read-only");
  sqlite3_extended_result_codes(d.db, 1);
  sqlite3_busy_timeout(d.db, 5000);
  // The memory bound of every history connection (db/sqlite_repository.hpp); our own constant.
  const std::string cache_size = "PRAGMA cache_size = -" + std::to_string(kSqlitePageCacheKiB);
  schema::exec(d.db, cache_size.c_str(), path, "open: cache_size");
  schema::exec(d.db, "PRAGMA mmap_size = 0", path, "open: mmap_size");
  schema::check_version_readable(d.db, path);
}

SqliteFleetStats::~SqliteFleetStats() = default;

std::vector<StationDayCount> SqliteFleetStats::runs_per_station_day(const FleetFilter& f) const {
  validate_filter(f);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const char* op = "runs per station and day";
  Impl::Snapshot snapshot(*impl_, op);
  Impl::Query q(*impl_,
                std::string("SELECT r.station, ") + kDayExpr + " AS day, count(*) FROM runs r" +
                    where_clause(f) + " GROUP BY r.station, day ORDER BY r.station, day",
                op);
  q.bind_filter(f);
  std::vector<StationDayCount> out;
  while (q.step()) out.push_back({q.text(0), q.i64(1), q.i64(2)});
  return out;
}

std::vector<StationVerdictCounts> SqliteFleetStats::verdict_counts_per_station(
    const FleetFilter& f) const {
  validate_filter(f);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const char* op = "verdict counts per station";
  Impl::Snapshot snapshot(*impl_, op);
  Impl::Query q(*impl_,
                "SELECT r.station, r.verdict, count(*) FROM runs r" + where_clause(f) +
                    " GROUP BY r.station, r.verdict ORDER BY r.station",
                op);
  q.bind_filter(f);
  std::vector<StationVerdictCounts> out;
  while (q.step()) {
    const std::string station = q.text(0);
    if (out.empty() || out.back().station != station) out.push_back({station});
    StationVerdictCounts& c = out.back();
    const std::string verdict = q.type(1) == SQLITE_NULL ? "" : q.text(1);
    const std::int64_t n = q.i64(2);
    if (verdict == "PASS")
      c.pass += n;
    else if (verdict == "REVIEW")
      c.review += n;
    else if (verdict == "FAILED")
      c.failed += n;
    else if (verdict.empty())
      c.live += n;
    else
      throw Corrupt(impl_->path + ": " + op + ": stored verdict \"" + verdict + "\" is unknown");
  }
  return out;
}

std::vector<ParamSummary> SqliteFleetStats::param_distribution(int param_index,
                                                               const FleetFilter& f) const {
  if (param_index < 0 || param_index >= calib::ParamSet::kSize)
    throw InvalidInput("parameter index " + std::to_string(param_index) + " is not in 0..26");
  validate_filter(f);
  const std::string name = calib::param_info(param_index).name;
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const char* op = "parameter distribution";
  Impl::Snapshot snapshot(*impl_, op);
  Impl::Query q(*impl_,
                "SELECT r.station, json_extract(c.params_json, :path) FROM runs r "
                "JOIN calibrations c ON c.run_id = r.id AND c.method = 'ains' "
                "AND (c.unobservable_json = '[]' OR NOT EXISTS "
                "(SELECT 1 FROM json_each(c.unobservable_json) WHERE value = :name))" +
                    where_clause(f),
                op);
  q.bind_filter(f);
  q.bind_text(":path", "$." + name);
  q.bind_text(":name", name);
  std::map<std::string, std::vector<double>> by_station;
  while (q.step()) {
    const int t = q.type(1);
    if (t != SQLITE_FLOAT && t != SQLITE_INTEGER)
      throw Corrupt(impl_->path + ": " + op + ": an AINS parameter set has no number at " + name);
    by_station[q.text(0)].push_back(q.f64(1));
  }
  std::vector<ParamSummary> out;
  for (auto& [station, values] : by_station) {
    ParamSummary s = summarize(values);
    s.station = station;
    out.push_back(s);
  }
  return out;
}

std::vector<RunId> SqliteFleetStats::table_run_members(RunId table_run_id) const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const char* op = "table run members";
  Impl::Snapshot snapshot(*impl_, op);
  Impl::Query q(*impl_,
                "SELECT id FROM runs WHERE id = :id UNION "
                "SELECT id FROM runs WHERE table_run_id = :id ORDER BY 1",
                op);
  q.bind_int(":id", table_run_id);
  std::vector<RunId> out;
  while (q.step()) out.push_back(q.i64(0));
  return out;
}

}  // namespace imucal::db
