#include "db/history/sqlite_fleet_stats.hpp"

#include <sqlite3.h>
#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <cstdio>
#include <map>
#include <mutex>
#include <string_view>
#include <unordered_map>
#include <unordered_set>

#include "calib/core/param_set.hpp"
#include "db/history/compact_param_text.hpp"
#include "db/history/schema.hpp"
#include "db/history/sqlite_repository.hpp"

namespace imucal::db::history {

namespace {

// ----- SQL: constant fragments only; every value is a bound named parameter
// -----------------------

const char* const kWhereSerial = "r.unit_id = (SELECT id FROM units WHERE serial = :serial)";
const char* const kWhereSince = "r.started_at_ms >= :since";
const char* const kWhereUntil = "r.started_at_ms < :until";
const char* const kWhereStation = "r.station = :station";
// :verdicts is ",PASS,REVIEW,": the filter's verdicts between commas ("live": none yet).
const char* const kWhereVerdict = "instr(:verdicts, ',' || coalesce(r.verdict, 'live') || ',') > 0";

/// " WHERE a AND b ..." for the filters given and `also` ("" for none).
std::string where_clause(const FleetFilter& f, const std::string& also = "") {
  std::string w;
  auto add = [&w](const std::string& cond) { w += (w.empty() ? " WHERE " : " AND ") + cond; };
  if (!also.empty()) add(also);
  if (f.serial) add(kWhereSerial);
  if (f.since_ms) add(kWhereSince);
  if (f.until_ms) add(kWhereUntil);
  if (f.station) add(kWhereStation);
  if (f.verdict) add(kWhereVerdict);
  return w;
}

/// The station texts of a scan as small numbers, without a copy per row: a history has few
/// stations, and a scan in time order sees them interleaved.
class StationNames {
 public:
  std::size_t index_of(std::string_view text) {
    if (last_ < names_.size() && names_[last_] == text) return last_;
    for (last_ = 0; last_ < names_.size(); ++last_)
      if (names_[last_] == text) return last_;
    names_.emplace_back(text);
    return last_;
  }
  const std::string& name(std::size_t i) const { return names_[i]; }
  std::size_t size() const { return names_.size(); }
  /// The indexes in byte order of their names (the order results come in).
  std::vector<std::size_t> sorted() const {
    std::vector<std::size_t> order(names_.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = i;
    std::sort(order.begin(), order.end(),
              [this](std::size_t a, std::size_t b) { return names_[a] < names_[b]; });
    return order;
  }

 private:
  std::vector<std::string> names_;
  std::size_t last_ = 0;
};

}  // namespace

namespace {
/// The AINS result ains_results() takes (runs r and calibrations c joined): every term
/// determined, and a verdict that is the unit's own (or none yet).
constexpr const char* kUsableAinsResult =
    "c.unobservable_json = '[]' AND "
    "(r.verdict IS NULL OR r.verdict IN ('PASS', 'REVIEW', 'FAILED'))";
}  // namespace

struct SqliteFleetStats::Impl {
  std::string path;
  sqlite3* db = nullptr;
  mutable std::mutex mutex;

  /// The few runs the counts must look at one by one: those a reprocess supersedes, and the field
  /// runs (setting land or sea), with the field runs whose AINS result is not in the housing frame
  /// (a factory AINS result always is: calib/ains/ains.cpp). Read by a scan of the run rows, which
  /// the counts themselves never read (they use the covering index runs_by_time_station); kept
  /// until another connection commits (PRAGMA data_version changes).
  struct Exceptions {
    std::int64_t data_version = -1;
    std::unordered_set<RunId> superseded;
    std::unordered_map<RunId, std::string> field_setting;
    std::unordered_set<RunId> other_frame;
    std::vector<ReprocessLink> links;  ///< ascending run
  };
  mutable Exceptions exceptions;

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
      if (f.verdict) {
        std::string list = ",";
        for (const std::string& v : verdict_list(*f.verdict)) list += v + ",";
        bind_text(":verdicts", list);
      }
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
    std::string_view view(int c) const {
      const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(st_, c));
      return p ? std::string_view(p, static_cast<std::size_t>(sqlite3_column_bytes(st_, c)))
               : std::string_view();
    }

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

  /// The exceptions as of the current snapshot (call inside one), re-read after a commit.
  const Exceptions& current_exceptions(const char* op) const {
    std::int64_t version = 0;
    {
      Query v(*this, "PRAGMA data_version", op);
      if (v.step()) version = v.i64(0);
    }
    if (version == exceptions.data_version) return exceptions;
    Exceptions e;
    e.data_version = version;
    Query q(*this,
            "SELECT r.id, r.reprocessed_from, r.setting, (SELECT c.body_frame FROM calibrations c "
            "WHERE c.run_id = r.id AND c.method = 'ains') FROM runs r "
            "WHERE r.reprocessed_from IS NOT NULL OR r.setting <> 'factory'",
            op);
    std::vector<ReprocessLink> links;
    while (q.step()) {
      const RunId id = q.i64(0);
      if (q.type(1) != SQLITE_NULL) links.push_back({id, q.i64(1), id, q.i64(1)});
      std::string setting = q.text(2);
      if (setting != "factory") e.field_setting.emplace(id, std::move(setting));
      if (q.type(3) != SQLITE_NULL && q.text(3) != "housing") e.other_frame.insert(id);
    }
    for (const RunId r : superseded_runs(links)) e.superseded.insert(r);
    std::sort(links.begin(), links.end(),
              [](const ReprocessLink& a, const ReprocessLink& b) { return a.run < b.run; });
    e.links = std::move(links);
    exceptions = std::move(e);
    return exceptions;
  }

  /// Whether run `id` has the filter's setting (factory unless listed as a field run).
  static bool setting_matches(const Exceptions& e, RunId id, const FleetFilter& f) {
    if (!f.setting) return true;
    const auto it = e.field_setting.find(id);
    return (it == e.field_setting.end() ? std::string("factory") : it->second) == *f.setting;
  }
  /// Whether run `id` counts in the aggregates: it stands for its capture and has the setting.
  static bool counts(const Exceptions& e, RunId id, const FleetFilter& f) {
    return e.superseded.count(id) == 0 && setting_matches(e, id, f);
  }

  /// The runs of a reprocess chain (a reprocess or a run reprocessed) with a result
  /// ains_results() takes, not calibrated from a partial archive: signature_stand_ins()'s
  /// `usable`. Call inside a snapshot.
  std::vector<RunId> usable_reprocess_results(const char* op) const {
    Query q(*this,
            std::string("SELECT r.id FROM runs r JOIN calibrations c ON c.run_id = r.id AND "
                        "c.method = 'ains' WHERE r.setting = 'factory' AND ") +
                kUsableAinsResult +
                " AND (r.reprocessed_from IS NOT NULL OR r.id IN (SELECT reprocessed_from FROM "
                "runs WHERE reprocessed_from IS NOT NULL)) AND NOT EXISTS (SELECT 1 FROM "
                "json_each(r.reasons_json) j WHERE json_extract(j.value, '$.source') = "
                "'partial archive')",
            op);
    std::vector<RunId> out;
    while (q.step()) out.push_back(q.i64(0));
    return out;
  }
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
  // The memory bound of every history connection (db/history/sqlite_repository.hpp); our own
  // constant.
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
  // Counted here, not by GROUP BY: the rows come from runs_by_time_station alone (schema v8), and
  // SQLite's GROUP BY would sort them all (in a temporary file beyond the bounded page cache).
  const Impl::Exceptions& ex = impl_->current_exceptions(op);
  Impl::Query q(*impl_, "SELECT r.station, r.started_at_ms, r.id FROM runs r" + where_clause(f),
                op);
  q.bind_filter(f);
  StationNames stations;
  std::vector<std::map<std::int64_t, std::int64_t>> per_day;
  while (q.step()) {
    if (!Impl::counts(ex, q.i64(2), f)) continue;
    const std::size_t s = stations.index_of(q.view(0));
    if (s == per_day.size()) per_day.emplace_back();
    ++per_day[s][utc_day(q.i64(1))];
  }
  std::vector<StationDayCount> out;
  for (const std::size_t s : stations.sorted())
    for (const auto& [day, runs] : per_day[s]) out.push_back({stations.name(s), day, runs});
  return out;
}

std::vector<StationVerdictCounts> SqliteFleetStats::verdict_counts_per_station(
    const FleetFilter& f) const {
  validate_filter(f);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const char* op = "verdict counts per station";
  Impl::Snapshot snapshot(*impl_, op);
  // Counted here, not by GROUP BY: runs_by_time_station covers the stored verdict (schema v10), so
  // the count reads no run row and sorts nothing.
  const Impl::Exceptions& ex = impl_->current_exceptions(op);
  Impl::Query q(*impl_, "SELECT r.station, r.verdict, r.id FROM runs r" + where_clause(f), op);
  q.bind_filter(f);
  StationNames stations;
  // Per station: the runs per verdict, indexed by RunVerdict, and the live ones (NULL) last.
  constexpr std::size_t kLiveSlot = 6;
  std::vector<std::array<std::int64_t, kLiveSlot + 1>> per_verdict;
  while (q.step()) {
    if (!Impl::counts(ex, q.i64(2), f)) continue;
    const std::size_t s = stations.index_of(q.view(0));
    if (s == per_verdict.size()) per_verdict.push_back({});
    if (q.type(1) == SQLITE_NULL) {
      ++per_verdict[s][kLiveSlot];
      continue;
    }
    const std::string_view text = q.view(1);
    RunVerdict v{};
    try {
      v = run_verdict_from_string(std::string(text));
    } catch (const InvalidInput&) {
      throw Corrupt(impl_->path + ": " + op + ": stored run verdict \"" + std::string(text) +
                    "\" is unknown");
    }
    ++per_verdict[s][static_cast<std::size_t>(v)];
  }
  std::vector<StationVerdictCounts> out;
  for (const std::size_t s : stations.sorted()) {
    const auto& n = per_verdict[s];
    StationVerdictCounts c{stations.name(s)};
    c.pass = n[static_cast<std::size_t>(RunVerdict::kPass)];
    c.review = n[static_cast<std::size_t>(RunVerdict::kReview)];
    c.failed = n[static_cast<std::size_t>(RunVerdict::kFailed)];
    c.station_fault = n[static_cast<std::size_t>(RunVerdict::kStationFault)];
    c.aborted = n[static_cast<std::size_t>(RunVerdict::kAborted)];
    c.interrupted = n[static_cast<std::size_t>(RunVerdict::kInterrupted)];
    c.live = n[kLiveSlot];
    out.push_back(c);
  }
  return out;
}

std::vector<ParamSummary> SqliteFleetStats::param_distribution(int param_index,
                                                               const FleetFilter& f) const {
  if (param_index < 0 || param_index >= calib::core::ParamSet::kSize)
    throw InvalidInput("parameter index " + std::to_string(param_index) + " is not in 0..26");
  validate_filter(f);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const char* op = "parameter distribution";
  Impl::Snapshot snapshot(*impl_, op);
  // ains_values (schema v8): the AINS result's values as numbers, NULL where the result does not
  // determine the parameter. The column name is ours (p00..p26 from the checked index), not input.
  char column[8];
  std::snprintf(column, sizeof column, "a.p%02d", param_index);
  const Impl::Exceptions& ex = impl_->current_exceptions(op);
  Impl::Query q(*impl_,
                std::string("SELECT r.station, ") + column + ", r.id" +
                    " FROM runs r JOIN ains_values a ON a.run_id = r.id" +
                    where_clause(f, std::string(column) + " IS NOT NULL"),
                op);
  q.bind_filter(f);
  const bool by_frame = frame_dependent(param_index);
  StationNames stations;
  std::vector<std::vector<double>> values;
  std::vector<std::int64_t> other_frame;
  while (q.step()) {
    if (!Impl::counts(ex, q.i64(2), f)) continue;
    const std::size_t s = stations.index_of(q.view(0));
    if (s == values.size()) values.emplace_back(), other_frame.push_back(0);
    if (by_frame && ex.other_frame.count(q.i64(2)))
      ++other_frame[s];
    else
      values[s].push_back(q.f64(1));
  }
  std::vector<ParamSummary> out;
  for (const std::size_t s : stations.sorted()) {
    ParamSummary summary = summarize(values[s]);
    summary.station = stations.name(s);
    summary.other_frame = other_frame[s];
    out.push_back(summary);
  }
  return out;
}

std::vector<ReprocessLink> SqliteFleetStats::reprocess_links() const {
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const char* op = "reprocess links";
  Impl::Snapshot snapshot(*impl_, op);
  return impl_->current_exceptions(op).links;
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

std::vector<AinsResultRow> SqliteFleetStats::ains_results(const FleetFilter& f) const {
  validate_filter(f);
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const char* op = "AINS results";
  Impl::Snapshot snapshot(*impl_, op);
  std::string sql =
      "SELECT r.id, r.station, u.serial, r.sequence_name, r.started_at_ms, c.sigma_json";
  char column[8];
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
    std::snprintf(column, sizeof column, ", a.p%02d", i);
    sql += column;
  }
  const Impl::Exceptions& ex = impl_->current_exceptions(op);
  std::string captures = "r.reprocessed_from IS NULL";
  for (const RunId id : signature_stand_ins(ex.links, impl_->usable_reprocess_results(op)))
    captures += " OR r.id = " + std::to_string(id);
  sql +=
      " FROM runs r JOIN units u ON u.id = r.unit_id JOIN ains_values a ON a.run_id = r.id "
      "JOIN calibrations c ON c.run_id = r.id AND c.method = 'ains'" +
      where_clause(
          f, std::string("r.setting = 'factory' AND (") + captures + ") AND " + kUsableAinsResult) +
      " ORDER BY r.id";
  Impl::Query q(*impl_, sql, op);
  q.bind_filter(f);
  std::vector<AinsResultRow> out;
  while (q.step()) {
    if (!Impl::setting_matches(ex, q.i64(0), f)) continue;
    AinsResultRow row;
    row.run_id = q.i64(0);
    row.local_run_id = row.run_id;  // a station's own database
    row.station = q.text(1);
    row.serial = q.text(2);
    row.sequence_name = q.text(3);
    row.started_at_ms = q.i64(4);
    if (!read_compact_param_set(q.view(5), /*non_negative=*/true, row.sigma))
      throw Corrupt(impl_->path + ": " + op + ": run " + std::to_string(row.run_id) +
                    ": its AINS sigma_json is not a parameter set of non-negative numbers");
    calib::core::ParamVector x;
    for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
      if (q.type(6 + i) == SQLITE_NULL)
        throw Corrupt(impl_->path + ": " + op + ": run " + std::to_string(row.run_id) +
                      ": ains_values misses " + calib::core::param_info(i).name);
      x(i) = q.f64(6 + i);
    }
    row.value = calib::core::ParamSet::from_vector(x);
    out.push_back(std::move(row));
  }
  return out;
}

}  // namespace imucal::db::history
