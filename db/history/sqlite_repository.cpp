#include "db/history/sqlite_repository.hpp"

#include <sqlite3.h>
#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <mutex>
#include <nlohmann/json.hpp>
#include <unordered_map>

#include "db/archive/archive_error.hpp"
#include "db/archive/param_json.hpp"
#include "db/history/compact_param_text.hpp"
#include "db/history/export.hpp"
#include "db/history/schema.hpp"
#include "db/history/serial_number.hpp"

namespace imucal::db::history {

namespace {

using nlohmann::json;

// ----- SQL (constant text only; every value is bound) -------------------------------------------

const std::string kRunColumns =
    "r.id, u.serial, r.operator, r.station, r.sequence_name, r.sequence_sha256, "
    "r.software_version, r.started_at_ms, r.ended_at_ms, r.state, r.failure_reason, "
    "r.archive_path, r.archive_sha256, r.reprocessed_from, x.verdict, r.capture_json, "
    "r.diagnosis_json, r.setting, r.origin, r.promoted_at_ms, r.promoted_by, r.promote_reason, "
    "r.verdict, r.reasons_json, r.slot, r.table_run_id, r.uuid, r.revision, r.holding_method, "
    "r.holding_reason";
constexpr int kNumRunColumns = 30;
constexpr int kExportVerdictColumn = 14;  ///< x.verdict among kRunColumns
const std::string kRunFrom =
    " FROM runs r JOIN units u ON u.id = r.unit_id LEFT JOIN crosschecks x ON x.run_id = r.id ";
const std::string kCalColumns =
    "c.method, c.params_json, c.sigma_json, c.converged, c.iterations, c.runtime_s, "
    "c.warnings_json, c.orientation_rmse_mdeg, c.accel_rmse_ug, c.heading_offset_gamma_np_rad, "
    "c.theta_bp_x_rad, c.theta_bp_y_rad, c.theta_bp_z_rad, c.body_frame, c.unobservable_json, "
    "c.notes_json";

const std::string kSqlRunById = "SELECT " + kRunColumns + kRunFrom + "WHERE r.id = ?1";
const std::string kSqlHistory = "SELECT " + kRunColumns + kRunFrom +
                                "WHERE r.unit_id = ?1 ORDER BY r.started_at_ms DESC, r.id DESC "
                                "LIMIT ?2";
const std::string kSqlRecent =
    "SELECT " + kRunColumns + kRunFrom + "ORDER BY r.started_at_ms DESC, r.id DESC LIMIT ?1";
const char* const kSqlCountRuns = "SELECT count(*) FROM runs";
const std::string kSqlActive = "SELECT " + kRunColumns + kRunFrom +
                               "WHERE r.unit_id = ?1 AND r.verdict = 'PASS' "
                               "AND r.setting = 'factory' AND r.origin = '' "
                               "ORDER BY r.started_at_ms DESC, r.id DESC LIMIT 1";
const std::string kSqlLatestPromoted = "SELECT " + kRunColumns + kRunFrom +
                                       "WHERE r.unit_id = ?1 AND r.promoted_at_ms IS NOT NULL "
                                       "ORDER BY r.promoted_at_ms DESC, r.id DESC LIMIT 1";
constexpr const char* kSqlHighestRunIdIssued =
    "SELECT coalesce((SELECT max(seq) FROM sqlite_sequence WHERE name = 'runs'), 0)";
const std::string kSqlRunsWithArchiveSha =
    "SELECT " + kRunColumns + kRunFrom + "WHERE r.archive_sha256 = ?1 ORDER BY r.id";
const std::string kSqlRunsInState =
    "SELECT " + kRunColumns + kRunFrom + "WHERE r.state = ?1 ORDER BY r.id";
const std::string kSqlCalsOfRun =
    "SELECT " + kCalColumns + " FROM calibrations c WHERE c.run_id = ?1 ORDER BY c.method";

// Export: one statement per filter combination so that each uses its index (an "?1 IS NULL OR"
// disjunction would defeat the planner). Runs without calibrations appear once (LEFT JOIN).
const std::string kExportHead = "SELECT " + kRunColumns + ", " + kCalColumns +
                                ", x.k_sigma, x.failures_json, x.not_compared_json" + kRunFrom +
                                "LEFT JOIN calibrations c ON c.run_id = r.id ";
constexpr int kNumCalColumns = 16;
constexpr int kExportCrosscheckColumn = kNumRunColumns + kNumCalColumns;  ///< x.k_sigma
const std::string kExportTail = " ORDER BY r.started_at_ms, r.id, c.method";
const std::string kSqlExportAll = kExportHead + kExportTail;
const std::string kSqlExportSerial = kExportHead + "WHERE u.serial = ?1" + kExportTail;
const std::string kSqlExportSince = kExportHead + "WHERE r.started_at_ms >= ?2" + kExportTail;
const std::string kSqlExportBoth =
    kExportHead + "WHERE u.serial = ?1 AND r.started_at_ms >= ?2" + kExportTail;

const char* const kSqlUnitId = "SELECT id FROM units WHERE serial = ?1";
/// Units whose serial differs from ?1 only in case (NOCASE folds ASCII: the serial alphabet).
const char* const kSqlSerialsIgnoringCase =
    "SELECT serial FROM units WHERE serial = ?1 COLLATE NOCASE ORDER BY serial LIMIT 4";
const char* const kSqlInsertUnit =
    "INSERT INTO units (serial, first_seen_ms) VALUES (?1, ?2) ON CONFLICT (serial) DO NOTHING";
const char* const kSqlRunExists = "SELECT 1 FROM runs WHERE id = ?1";
const char* const kSqlInsertRun =
    "INSERT INTO runs (unit_id, operator, station, sequence_name, sequence_sha256, "
    "software_version, started_at_ms, state, archive_path, reprocessed_from, setting, origin, "
    "slot, table_run_id, uuid) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, "
    "?14, lower(hex(randomblob(16))))";
const char* const kSqlPromote =
    "UPDATE runs SET promoted_at_ms = ?2, promoted_by = ?3, promote_reason = ?4 WHERE id = ?1";
const char* const kSqlRunState = "SELECT state FROM runs WHERE id = ?1";
const char* const kSqlSetLiveState = "UPDATE runs SET state = ?2 WHERE id = ?1";
const char* const kSqlFinishRun =
    "UPDATE runs SET state = ?2, ended_at_ms = ?3, failure_reason = ?4, "
    "archive_path = coalesce(?5, archive_path), archive_sha256 = ?6, capture_json = ?7, "
    "diagnosis_json = ?8, reasons_json = ?9, holding_method = coalesce(?10, holding_method), "
    "holding_reason = coalesce(?11, holding_reason), verdict = ?12 WHERE id = ?1";
const char* const kSqlSetDiagnosis = "UPDATE runs SET diagnosis_json = ?2 WHERE id = ?1";
const char* const kSqlHasMethod = "SELECT 1 FROM calibrations WHERE run_id = ?1 AND method = ?2";
const char* const kSqlInsertCal =
    "INSERT INTO calibrations (run_id, method, params_json, sigma_json, converged, iterations, "
    "runtime_s, warnings_json, orientation_rmse_mdeg, accel_rmse_ug, "
    "heading_offset_gamma_np_rad, theta_bp_x_rad, theta_bp_y_rad, theta_bp_z_rad, body_frame, "
    "unobservable_json, notes_json) "
    "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17)";
const char* const kSqlVerdict = "SELECT verdict FROM crosschecks WHERE run_id = ?1";
const char* const kSqlCrosscheck =
    "SELECT verdict, k_sigma, failures_json, not_compared_json FROM crosschecks WHERE run_id = ?1";
const char* const kSqlInsertCrosscheck =
    "INSERT INTO crosschecks (run_id, verdict, k_sigma, failures_json, not_compared_json) "
    "VALUES (?1, ?2, ?3, ?4, ?5)";
const char* const kSqlLiveRuns =
    "SELECT id, state FROM runs WHERE state IN ('preparing', 'running', 'calibrating') "
    "ORDER BY id";
const char* const kSqlCountRunsOfUnit = "SELECT count(*) FROM runs WHERE unit_id = ?1";
const char* const kSqlOutboxEnabled = "SELECT enabled FROM outbox_state WHERE id = 1";
const char* const kSqlSetOutboxEnabled = "UPDATE outbox_state SET enabled = ?1 WHERE id = 1";
const char* const kSqlOutboxResync =
    "INSERT INTO outbox (run_id, change, at_ms) SELECT id, 'resync', ?1 FROM runs ORDER BY id";
const char* const kSqlOutboxClear = "DELETE FROM outbox";
const char* const kSqlOutboxBatch =
    "SELECT seq, run_id, change, at_ms FROM outbox ORDER BY seq LIMIT ?1";
const char* const kSqlOutboxRemove = "DELETE FROM outbox WHERE seq <= ?1";
const char* const kSqlOutboxLength = "SELECT count(*) FROM outbox";

int live_rank(RunState s) {
  switch (s) {
    case RunState::kPreparing:
      return 0;
    case RunState::kRunning:
      return 1;
    case RunState::kCalibrating:
      return 2;
    default:
      return 3;
  }
}

bool is_sha256_hex(const std::string& s) {
  if (s.size() != 64) return false;
  return std::all_of(s.begin(), s.end(),
                     [](char c) { return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f'); });
}

void check_sha(const std::string& value, const char* field) {
  if (!value.empty() && !is_sha256_hex(value))
    throw InvalidInput(std::string(field) + " \"" + value.substr(0, 80) +
                       "\" is not a SHA-256 (expected 64 lowercase hex digits, or empty)");
}

std::string run_label(RunId id) { return "run " + std::to_string(id); }

/// The stored reasons_json text: the same array run_json prints (db/history/export.hpp).
std::string reasons_to_json(const std::vector<RunReason>& reasons) {
  return reasons_json(reasons).dump();
}

/// The stored reasons_json (an array of {source, text}); InvalidInput naming what is wrong.
std::vector<RunReason> reasons_from_json(const std::string& text) {
  const json a = json::parse(text, nullptr, false);
  if (!a.is_array()) throw InvalidInput("not a JSON array");
  std::vector<RunReason> out;
  for (const json& e : a) {
    if (!e.is_object() || !e.contains("source") || !e["source"].is_string() ||
        !e.contains("text") || !e["text"].is_string())
      throw InvalidInput("an entry is not {\"source\": text, \"text\": text}: " + e.dump());
    out.push_back({e["source"].get<std::string>(), e["text"].get<std::string>()});
  }
  return out;
}

/// The source of a single reason given as text, by the state it ends (RunReason sources).
const char* default_reason_source(RunState s) {
  switch (s) {
    case RunState::kAborted:
      return "aborted";
    case RunState::kInterrupted:
      return "interrupted";
    case RunState::kFailed:
      return "error";
    default:
      return "review";
  }
}

/// Validated JSON text of one calibration's parameters and sigma.
void check_calibration(const CalibrationRecord& c, RunId run_id, std::string& params_json,
                       std::string& sigma_json, std::string& warnings_json) {
  const std::string what = run_label(run_id) + " " + to_string(c.method) + " calibration";
  try {
    // param_set_to_json with sigma validates finiteness and non-negative sigma.
    json both = db::archive::param_set_to_json(c.params, &c.sigma);
    json sigma = both["sigma"];
    both.erase("sigma");
    params_json = both.dump();
    sigma_json = sigma.dump();
  } catch (const db::archive::ArchiveError& e) {
    throw InvalidInput(what + ": " + e.what());
  }
  if (!std::isfinite(c.runtime_s) || c.runtime_s < 0)
    throw InvalidInput(what + ": runtime_s must be finite and >= 0");
  if (c.iterations < 0) throw InvalidInput(what + ": iterations must be >= 0");
  if (c.metrics) {
    const StoredMetrics& m = *c.metrics;
    const bool finite = std::isfinite(m.orientation_rmse_mdeg) && std::isfinite(m.accel_rmse_ug) &&
                        std::isfinite(m.heading_offset_gamma_np_rad) &&
                        m.body_misalignment_theta_bp_rad.allFinite();
    if (!finite) throw InvalidInput(what + ": evaluation metrics must be finite");
  }
  warnings_json = json(c.warnings).dump();
}

void check_crosscheck(const CrosscheckRecord& x, RunId run_id) {
  if (!std::isfinite(x.k_sigma) || x.k_sigma <= 0)
    throw InvalidInput(run_label(run_id) + " cross-check: k_sigma must be positive and finite");
  if (x.verdict == Verdict::kPass && !x.failures.empty())
    throw InvalidInput(run_label(run_id) + " cross-check: a PASS verdict cannot list failures");
  if (x.verdict == Verdict::kReview && x.failures.empty())
    throw InvalidInput(run_label(run_id) +
                       " cross-check: a REVIEW verdict must list the failing terms");
}

}  // namespace

// =================================================================================================

struct SqliteRepository::Impl {
  std::string path;
  SqliteOptions options;
  sqlite3* db = nullptr;
  mutable std::recursive_mutex mutex;
  mutable std::unordered_map<const char*, sqlite3_stmt*> cache;  // keyed by the SQL text's address
  mutable int depth = 0;                                         // transaction nesting depth

  ~Impl() {
    for (auto& kv : cache) sqlite3_finalize(kv.second);
    if (db) sqlite3_close_v2(db);
  }

  [[noreturn]] void fail(int rc, const std::string& context) const {
    schema::throw_sqlite(db, rc, path, context);
  }

  // ----- statements ------------------------------------------------------------------------------
  /// A cached prepared statement, reset (bindings cleared) when the handle goes out of scope.
  class Stmt {
   public:
    Stmt(const Impl& impl, const char* sql, const char* op) : impl_(impl), op_(op) {
      auto it = impl.cache.find(sql);
      if (it != impl.cache.end()) {
        st_ = it->second;
      } else {
        const int rc =
            sqlite3_prepare_v3(impl.db, sql, -1, SQLITE_PREPARE_PERSISTENT, &st_, nullptr);
        if (rc != SQLITE_OK) impl.fail(rc, std::string(op) + ": prepare");
        impl.cache.emplace(sql, st_);
      }
    }
    ~Stmt() {
      sqlite3_reset(st_);
      sqlite3_clear_bindings(st_);
    }
    Stmt(const Stmt&) = delete;
    Stmt& operator=(const Stmt&) = delete;

    Stmt& bind(int i, std::int64_t v) { return check(sqlite3_bind_int64(st_, i, v)); }
    Stmt& bind(int i, int v) { return check(sqlite3_bind_int64(st_, i, v)); }
    Stmt& bind(int i, double v) { return check(sqlite3_bind_double(st_, i, v)); }
    Stmt& bind(int i, const std::string& v) {
      return check(
          sqlite3_bind_text(st_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT));
    }
    Stmt& bind(int i, const char* v) {
      return check(sqlite3_bind_text(st_, i, v, -1, SQLITE_TRANSIENT));
    }
    Stmt& bind_null(int i) { return check(sqlite3_bind_null(st_, i)); }
    template <typename T>
    Stmt& bind(int i, const std::optional<T>& v) {
      return v ? bind(i, *v) : bind_null(i);
    }

    /// true: a row is available; false: done.
    bool step() {
      const int rc = sqlite3_step(st_);
      if (rc == SQLITE_ROW) return true;
      if (rc == SQLITE_DONE) return false;
      impl_.fail(rc, op_);
    }
    void run() {
      while (step()) {
      }
    }

    bool is_null(int c) const { return sqlite3_column_type(st_, c) == SQLITE_NULL; }
    std::int64_t i64(int c) const { return sqlite3_column_int64(st_, c); }
    double f64(int c) const { return sqlite3_column_double(st_, c); }
    std::string text(int c) const { return schema::column_text(st_, c); }

   private:
    Stmt& check(int rc) {
      if (rc != SQLITE_OK) impl_.fail(rc, std::string(op_) + ": bind");
      return *this;
    }
    const Impl& impl_;
    const char* op_;
    sqlite3_stmt* st_ = nullptr;
  };

  // ----- transactions ----------------------------------------------------------------------------
  /// Write transaction (BEGIN IMMEDIATE) at depth 0, savepoint inside another transaction.
  /// Read transactions (deferred BEGIN) give read methods one snapshot.
  class Tx {
   public:
    Tx(const Impl& impl, const char* op, bool write) : impl_(impl), op_(op) {
      outer_ = impl.depth == 0;
      const char* sql = outer_ ? (write ? "BEGIN IMMEDIATE" : "BEGIN") : "SAVEPOINT imucal_nested";
      schema::exec(impl.db, sql, impl.path, std::string(op) + ": begin transaction");
      ++impl.depth;
    }
    void commit() {
      const char* sql = outer_ ? "COMMIT" : "RELEASE imucal_nested";
      const int rc = sqlite3_exec(impl_.db, sql, nullptr, nullptr, nullptr);
      if (rc != SQLITE_OK) {
        // The destructor rolls back; report the commit failure (e.g. disk full, I/O error).
        impl_.fail(rc, std::string(op_) + ": commit");
      }
      --impl_.depth;
      done_ = true;
    }
    ~Tx() {
      if (done_) return;
      if (outer_) {
        sqlite3_exec(impl_.db, "ROLLBACK", nullptr, nullptr, nullptr);
      } else {
        sqlite3_exec(impl_.db, "ROLLBACK TO imucal_nested; RELEASE imucal_nested", nullptr, nullptr,
                     nullptr);
      }
      --impl_.depth;
    }
    Tx(const Tx&) = delete;
    Tx& operator=(const Tx&) = delete;

   private:
    const Impl& impl_;
    const char* op_;
    bool outer_ = true;
    bool done_ = false;
  };

  void require_writable(const char* op) const {
    if (options.read_only)
      throw ReadOnly(path + ": " + op +
                     ": the database was opened read-only (QA mode); writes "
                     "are made by the station daemon");
  }

  // ----- row decoding ----------------------------------------------------------------------------
  RunRecord read_run(const Stmt& q) const {
    RunRecord r;
    r.run_id = q.i64(0);
    r.serial = q.text(1);
    r.operator_name = q.text(2);
    r.station = q.text(3);
    r.sequence_name = q.text(4);
    r.sequence_sha256 = q.text(5);
    r.software_version = q.text(6);
    r.started_at_ms = q.i64(7);
    if (!q.is_null(8)) r.ended_at_ms = q.i64(8);
    r.state = decode([&] { return run_label(r.run_id) + " state"; },
                     [&] { return run_state_from_string(q.text(9)); });
    r.failure_reason = q.text(10);
    r.archive_path = q.text(11);
    r.archive_sha256 = q.text(12);
    if (!q.is_null(13)) r.reprocessed_from = q.i64(13);
    if (!q.is_null(14))
      r.crosscheck_verdict = decode([&] { return run_label(r.run_id) + " cross-check verdict"; },
                                    [&] { return verdict_from_string(q.text(14)); });
    r.capture_json = q.text(15);
    r.diagnosis_json = q.text(16);
    const std::string setting = q.text(17);
    r.setting = decode([&] { return run_label(r.run_id) + " setting"; },
                       [&] {
                         const auto v = calib::core::parse_setting(setting);
                         if (!v) throw InvalidInput("unknown setting \"" + setting + "\"");
                         return *v;
                       });
    r.origin = q.text(18);
    if (!q.is_null(19)) r.promoted_at_ms = q.i64(19);
    r.promoted_by = q.text(20);
    r.promote_reason = q.text(21);
    if (!q.is_null(22))
      r.verdict = decode([&] { return run_label(r.run_id) + " verdict"; },
                         [&] { return run_verdict_from_string(q.text(22)); });
    if (is_terminal(r.state) != r.verdict.has_value() ||
        (r.verdict && !verdict_fits_state(*r.verdict, r.state)))
      throw Corrupt(path + ": " + run_label(r.run_id) + " verdict \"" + q.text(22) +
                    "\" contradicts its state " + to_string(r.state));
    r.reasons = decode([&] { return run_label(r.run_id) + " reasons_json"; },
                       [&] { return reasons_from_json(q.text(23)); });
    r.slot = q.text(24);
    if (!q.is_null(25)) r.table_run_id = q.i64(25);
    r.uuid = q.text(26);
    r.revision = q.i64(27);
    r.holding_method = decode([&] { return run_label(r.run_id) + " holding_method"; },
                              [&] { return method_from_string(q.text(28)); });
    r.holding_reason = q.text(29);
    return r;
  }

  /// A stored parameter-set JSON text (five keys, ARCHITECTURE §3). The fast path checks the exact
  /// shape without building any message; anything unexpected is handed to the strict archive
  /// reader for its field-named error (export reads 200 000 of these for 100 000 runs).
  calib::core::ParamSet decode_params(const std::string& text, bool is_sigma,
                                      const std::function<std::string()>& origin) const {
    calib::core::ParamSet p;
    if (read_compact_param_set(text, is_sigma, p)) return p;  // the text as stored
    json j;
    try {
      j = json::parse(text);
    } catch (const json::exception& e) {
      throw Corrupt(origin() + ": stored JSON is invalid: " + e.what());
    }
    bool ok = j.is_object() && j.size() == 5;
    auto vec = [&](const char* key, Eigen::Ref<Eigen::Vector3d> out) {
      if (!ok) return;
      auto it = j.find(key);
      if (it == j.end() || !it->is_array() || it->size() != 3) {
        ok = false;
        return;
      }
      for (int i = 0; i < 3; ++i) {
        const json& e = (*it)[static_cast<std::size_t>(i)];
        if (!e.is_number()) {
          ok = false;
          return;
        }
        out(i) = e.get<double>();
        ok = ok && std::isfinite(out(i)) && (!is_sigma || out(i) >= 0.0);
      }
    };
    auto mat = [&](const char* key, Eigen::Matrix3d& out) {
      if (!ok) return;
      auto it = j.find(key);
      if (it == j.end() || !it->is_array() || it->size() != 3) {
        ok = false;
        return;
      }
      for (int r = 0; r < 3 && ok; ++r) {
        const json& row = (*it)[static_cast<std::size_t>(r)];
        if (!row.is_array() || row.size() != 3) {
          ok = false;
          return;
        }
        for (int c = 0; c < 3; ++c) {
          const json& e = row[static_cast<std::size_t>(c)];
          if (!e.is_number()) {
            ok = false;
            return;
          }
          out(r, c) = e.get<double>();
          ok = ok && std::isfinite(out(r, c)) && (!is_sigma || out(r, c) >= 0.0);
        }
      }
    };
    vec("accel_bias_mps2", p.accel_bias_mps2);
    mat("accel_M", p.accel_M);
    vec("gyro_bias_radps", p.gyro_bias_radps);
    mat("gyro_M", p.gyro_M);
    vec("table_misalignment_rad", p.table_misalignment_rad);
    if (ok) return p;
    try {
      // Same five-key shape for values and sigmas: the strict reader names the bad field.
      db::archive::param_set_from_json(j, origin());
    } catch (const db::archive::ArchiveError& e) {
      throw Corrupt(std::string("stored value is invalid: ") + e.what());
    }
    if (is_sigma) throw Corrupt(origin() + ": stored 1-sigma set has a negative entry");
    throw Corrupt(origin() + ": stored parameter set is invalid");
  }

  /// Calibration columns starting at column c0 (method at c0); nullopt if method is NULL.
  std::optional<CalibrationRecord> read_calibration(const Stmt& q, int c0, RunId run_id) const {
    if (q.is_null(c0)) return std::nullopt;
    CalibrationRecord c;
    const std::string method = q.text(c0);
    auto where = [&] { return run_label(run_id) + " calibration"; };
    c.method = method == "ains"   ? Method::kAins
               : method == "nlsq" ? Method::kNlsq
                                  : decode([&] { return where() + " method"; },
                                           [&] { return method_from_string(method); });
    auto origin = [&] { return path + ": " + where() + " " + to_string(c.method); };
    c.params = decode_params(q.text(c0 + 1), false, [&] { return origin() + " params_json"; });
    c.sigma = decode_params(q.text(c0 + 2), true, [&] { return origin() + " sigma_json"; });
    c.converged = q.i64(c0 + 3) != 0;
    c.iterations = static_cast<int>(q.i64(c0 + 4));
    c.runtime_s = q.f64(c0 + 5);
    const std::string warnings = q.text(c0 + 6);
    if (warnings != "[]")
      c.warnings = decode_json(origin() + " warnings_json", warnings,
                               [&](const json& j) { return j.get<std::vector<std::string>>(); });
    if (!q.is_null(c0 + 7)) {
      StoredMetrics m;
      m.orientation_rmse_mdeg = q.f64(c0 + 7);
      m.accel_rmse_ug = q.f64(c0 + 8);
      m.heading_offset_gamma_np_rad = q.f64(c0 + 9);
      m.body_misalignment_theta_bp_rad = {q.f64(c0 + 10), q.f64(c0 + 11), q.f64(c0 + 12)};
      c.metrics = m;
    }
    c.body_frame = decode([&] { return origin() + " body_frame"; },
                          [&] { return body_frame_from_string(q.text(c0 + 13)); });
    c.unobservable = string_list(q.text(c0 + 14), [&] { return origin() + " unobservable_json"; });
    c.notes = string_list(q.text(c0 + 15), [&] { return origin() + " notes_json"; });
    return c;
  }

  /// f() decodes a stored enum text; its InvalidInput becomes Corrupt naming what(), which is
  /// only evaluated on failure (rows are decoded by the hundred thousand).
  template <typename W, typename F>
  auto decode(W what, F f) const -> decltype(f()) {
    try {
      return f();
    } catch (const InvalidInput& e) {
      throw Corrupt(path + ": " + what() + ": stored value is invalid: " + e.what());
    }
  }

  /// A stored JSON array of strings ("[]" without parsing: the common case by far).
  template <typename W>
  std::vector<std::string> string_list(const std::string& text, W what) const {
    if (text == "[]") return {};
    return decode_json(what(), text,
                       [](const json& j) { return j.get<std::vector<std::string>>(); });
  }

  template <typename F>
  auto decode_json(const std::string& origin, const std::string& text, F f) const
      -> decltype(f(json())) {
    try {
      return f(json::parse(text));
    } catch (const db::archive::ArchiveError& e) {
      throw Corrupt(std::string("stored value is invalid: ") + e.what());
    } catch (const json::exception& e) {
      throw Corrupt(origin + ": stored JSON is invalid: " + e.what());
    }
  }

  std::vector<CalibrationRecord> calibrations_of(RunId run_id) const {
    std::vector<CalibrationRecord> out;
    Stmt q(*this, kSqlCalsOfRun.c_str(), "read calibrations");
    q.bind(1, run_id);
    while (q.step()) out.push_back(*read_calibration(q, 0, run_id));
    return out;
  }

  std::optional<CrosscheckRecord> crosscheck_of(RunId run_id) const {
    Stmt q(*this, kSqlCrosscheck, "read cross-check");
    q.bind(1, run_id);
    if (!q.step()) return std::nullopt;
    return read_crosscheck(q, 0, 1, run_id);
  }

  /// A cross-check from a result row: verdict, k_sigma and failures_json at k_col + 1.
  CrosscheckRecord read_crosscheck(const Stmt& q, int verdict_col, int k_col, RunId run_id) const {
    CrosscheckRecord x;
    const auto what = [&] { return run_label(run_id) + " cross-check"; };  // for errors only
    x.verdict = decode([&] { return what() + " verdict"; },
                       [&] { return verdict_from_string(q.text(verdict_col)); });
    x.k_sigma = q.f64(k_col);
    x.not_compared =
        string_list(q.text(k_col + 2), [&] { return path + ": " + what() + " not_compared_json"; });
    const std::string failures = q.text(k_col + 1);
    if (failures == "[]") return x;  // a PASS: no JSON to parse
    x.failures = decode_json(path + ": " + what() + " failures_json", failures, [](const json& j) {
      std::vector<calib::checks::CrossCheckFailure> v;
      for (const json& f : j)
        v.push_back({f.at("term").get<std::string>(), f.at("detail").get<std::string>()});
      return v;
    });
    return x;
  }

  std::optional<std::int64_t> unit_id(const std::string& serial) const {
    Stmt q(*this, kSqlUnitId, "find unit");
    q.bind(1, serial);
    if (!q.step()) return std::nullopt;
    return q.i64(0);
  }

  std::int64_t require_unit(const std::string& serial) const {
    validate_serial(serial);
    auto id = unit_id(serial);
    if (!id)
      throw NotFound(path + ": no unit with serial number \"" + serial + "\" on record" +
                     did_you_mean(serials_ignoring_case(serial)));
    return *id;
  }

  std::vector<std::string> serials_ignoring_case(const std::string& serial) const {
    Stmt q(*this, kSqlSerialsIgnoringCase, "find unit ignoring case");
    q.bind(1, serial);
    std::vector<std::string> near;
    while (q.step()) near.push_back(q.text(0));
    return near;
  }

  RunState state_of(RunId run_id, const char* op) const {
    Stmt q(*this, kSqlRunState, op);
    q.bind(1, run_id);
    if (!q.step())
      throw NotFound("no " + run_label(run_id) + " in " + path);  // op: internal, not for users
    return decode([&] { return run_label(run_id) + " state"; },
                  [&] { return run_state_from_string(q.text(0)); });
  }

  /// Empty, or a JSON object text (what the *_json columns hold).
  static void check_json_object(const std::string& text, const std::string& who,
                                const char* field) {
    if (text.empty()) return;
    const json parsed = json::parse(text, nullptr, /*allow_exceptions=*/false);
    if (!parsed.is_object())
      throw InvalidInput(who + ": " + field +
                         " must be a JSON object (or empty), got: " + text.substr(0, 80));
  }

  RunState require_live(RunId run_id, const char* op) const {
    const RunState s = state_of(run_id, op);
    if (is_terminal(s))
      throw Conflict(path + ": " + op + ": " + run_label(run_id) + " is already " + to_string(s) +
                     " (terminal); a finished run cannot change — reprocess it as a new run");
    return s;
  }

  void insert_calibration(RunId run_id, const CalibrationRecord& c, const char* op) {
    std::string params_json, sigma_json, warnings_json;
    check_calibration(c, run_id, params_json, sigma_json, warnings_json);
    {
      Stmt q(*this, kSqlHasMethod, op);
      q.bind(1, run_id).bind(2, to_string(c.method));
      if (q.step())
        throw Conflict(path + ": " + op + ": " + run_label(run_id) + " already has an " +
                       to_string(c.method) + " calibration");
    }
    Stmt q(*this, kSqlInsertCal, op);
    q.bind(1, run_id).bind(2, to_string(c.method)).bind(3, params_json).bind(4, sigma_json);
    q.bind(5, c.converged ? 1 : 0)
        .bind(6, c.iterations)
        .bind(7, c.runtime_s)
        .bind(8, warnings_json);
    if (c.metrics) {
      const StoredMetrics& m = *c.metrics;
      q.bind(9, m.orientation_rmse_mdeg).bind(10, m.accel_rmse_ug);
      q.bind(11, m.heading_offset_gamma_np_rad);
      q.bind(12, m.body_misalignment_theta_bp_rad.x())
          .bind(13, m.body_misalignment_theta_bp_rad.y());
      q.bind(14, m.body_misalignment_theta_bp_rad.z());
    } else {
      for (int i = 9; i <= 14; ++i) q.bind_null(i);
    }
    q.bind(15, to_string(c.body_frame));
    q.bind(16, json(c.unobservable).dump()).bind(17, json(c.notes).dump());
    q.run();
  }

  void insert_crosscheck(RunId run_id, const CrosscheckRecord& x, const char* op) {
    check_crosscheck(x, run_id);
    {
      Stmt q(*this, kSqlVerdict, op);
      q.bind(1, run_id);
      if (q.step())
        throw Conflict(path + ": " + op + ": " + run_label(run_id) +
                       " already has a cross-check verdict (" + q.text(0) + ")");
    }
    json failures = json::array();
    for (const auto& f : x.failures) failures.push_back({{"term", f.term}, {"detail", f.detail}});
    Stmt q(*this, kSqlInsertCrosscheck, op);
    q.bind(1, run_id).bind(2, to_string(x.verdict)).bind(3, x.k_sigma).bind(4, failures.dump());
    q.bind(5, json(x.not_compared).dump());
    q.run();
  }

  calib::core::Setting setting_of(RunId run_id, const char* op) const {
    Stmt q(*this, "SELECT setting FROM runs WHERE id = ?1", op);
    q.bind(1, run_id);
    if (!q.step())
      throw NotFound("no " + run_label(run_id) + " in " + path);  // op: internal, not for users
    const auto v = calib::core::parse_setting(q.text(0));
    if (!v) throw Corrupt(path + ": " + run_label(run_id) + " has an unknown setting");
    return *v;
  }

  /// The verdict a completion stores: its own if given (InvalidInput if the state cannot end so),
  /// else the state's.
  static RunVerdict end_verdict(const RunCompletion& c, const std::string& who) {
    const RunVerdict v = c.verdict.value_or(*run_verdict(c.state));
    if (!verdict_fits_state(v, c.state))
      throw InvalidInput(who + ": a " + to_string(c.state) + " run cannot have the verdict " +
                         to_string(v) + " (failed, aborted and interrupted runs may be " +
                         to_string(RunVerdict::kStationFault) + ")");
    return v;
  }

  void finish(RunId run_id, const RunCompletion& c) {
    const char* op = "finish_run";
    const std::string who = path + ": " + op + ": " + run_label(run_id);
    if (!is_terminal(c.state))
      throw InvalidInput(
          who + ": state " + to_string(c.state) +
          " is not terminal (expected done, review, failed, aborted or interrupted)");
    const RunVerdict verdict_of_end = end_verdict(c, who);
    check_sha(c.archive_sha256, "archive SHA-256");
    check_json_object(c.capture_json, who, "capture_json");
    check_json_object(c.diagnosis_json, who, "diagnosis_json");
    std::string reason = !c.reason.empty() ? c.reason : join_reasons(c.reasons);
    std::vector<RunReason> reasons = c.reasons;
    if (reasons.empty() && !reason.empty())
      reasons.push_back({default_reason_source(c.state), reason});
    for (const RunReason& r : reasons)
      if (r.source.empty() || r.text.empty())
        throw InvalidInput(who + ": a reason needs a source and a text");
    for (std::size_t i = 0; i < c.calibrations.size(); ++i)
      for (std::size_t k = 0; k < i; ++k)
        if (c.calibrations[i].method == c.calibrations[k].method)
          throw InvalidInput(who + ": two " + std::string(to_string(c.calibrations[i].method)) +
                             " calibrations in one completion");
    Tx tx(*this, op, true);
    require_live(run_id, op);
    for (const auto& cal : c.calibrations) insert_calibration(run_id, cal, op);
    if (c.crosscheck) insert_crosscheck(run_id, *c.crosscheck, op);

    // Life-cycle rules against everything stored for the run (including earlier store_* calls).
    // The second method is the setting's: NLSQ in the factory, legacy on land; a sea run has
    // AINS alone and so is never done (QA may promote it).
    const calib::core::Setting setting = setting_of(run_id, op);
    auto has = [&](const char* method) {
      Stmt q(*this, kSqlHasMethod, op);
      q.bind(1, run_id).bind(2, method);
      return q.step();
    };
    const bool has_ains = has("ains");
    const char* second = setting == calib::core::Setting::kLand ? "legacy" : "nlsq";
    const bool has_second = has(second);
    std::optional<Verdict> verdict;
    {
      Stmt q(*this, kSqlVerdict, op);
      q.bind(1, run_id);
      if (q.step()) verdict = verdict_from_string(q.text(0));
    }
    // Legacy holds only a land run's rests, and only with its legacy set stored: then the
    // cross-check's disagreement is AINS's and does not decide the run (holding_method.hpp).
    const bool legacy_holds = c.holding_method == Method::kLegacy;
    if (legacy_holds && (setting != calib::core::Setting::kLand || !has("legacy")))
      throw Conflict(who + ": legacy can hold only a land run that stores a legacy calibration");
    if (c.holding_method == Method::kNlsq)
      throw InvalidInput(who + ": the holding method is ains or legacy, not nlsq");
    if (reasons.empty() && c.state == RunState::kReview && verdict == Verdict::kReview &&
        !legacy_holds) {
      // In review by the cross-check alone: its failures are the reason every view lists.
      reasons.push_back(crosscheck_reason(*crosscheck_of(run_id)));
      reason = reasons.back().text;
    }
    if (c.state == RunState::kDone) {
      std::string missing;
      if (setting == calib::core::Setting::kSea)
        missing += " a second method (a sea run has AINS alone: review, or promote explicitly);";
      if (!has_ains) missing += " ains calibration;";
      if (setting != calib::core::Setting::kSea && !has_second)
        missing += std::string(" ") + second + " calibration;";
      if (!verdict)
        missing += " a cross-check verdict;";
      else if (verdict != Verdict::kPass && !legacy_holds)
        missing += " a PASS cross-check (it is REVIEW);";
      if (!missing.empty()) {
        missing.pop_back();
        throw Conflict(who + " cannot be done without:" + missing);
      }
    }
    // A PASS cross-check goes to review only with a reason of its own (a significant sim-to-real
    // gap).
    if (verdict == Verdict::kPass && c.state == RunState::kReview && reason.empty())
      throw Conflict(who +
                     ": cross-check is PASS, so the run cannot go to review without a reason");
    if (verdict == Verdict::kReview && c.state == RunState::kDone && !legacy_holds)
      throw Conflict(who + ": cross-check is REVIEW, so the run cannot be done");
    const bool needs_reason =
        c.state == RunState::kFailed || c.state == RunState::kAborted ||
        c.state == RunState::kInterrupted ||
        (c.state == RunState::kReview && (verdict != Verdict::kReview || legacy_holds));
    if (needs_reason && reason.empty())
      throw InvalidInput(who + ": state " + to_string(c.state) + " needs a reason");
    if (c.state == RunState::kDone && !reasons.empty())
      throw InvalidInput(who +
                         ": a done (PASS) run has no reasons against it: " + join_reasons(reasons));

    Stmt q(*this, kSqlFinishRun, op);
    q.bind(1, run_id).bind(2, to_string(c.state)).bind(3, c.ended_at_ms).bind(4, reason);
    q.bind(5, c.archive_path).bind(6, c.archive_sha256).bind(7, c.capture_json);
    q.bind(8, c.diagnosis_json).bind(9, reasons_to_json(reasons));
    q.bind(10, to_string(c.holding_method)).bind(11, c.holding_reason);
    q.bind(12, std::string(to_string(verdict_of_end)));
    q.run();
    tx.commit();
  }
};

// =================================================================================================

void limit_sqlite_process_memory() { sqlite3_soft_heap_limit64(kSqliteSoftHeapLimitBytes); }

SqliteRepository::SqliteRepository(const std::string& path, const SqliteOptions& options)
    : impl_(std::make_unique<Impl>()) {
  Impl& d = *impl_;
  d.path = path;
  d.options = options;
  if (options.busy_timeout_ms < 0) throw InvalidInput(path + ": busy_timeout_ms must be >= 0");
  struct stat sb;
  const bool exists = ::stat(path.c_str(), &sb) == 0;
  if (!exists && (options.read_only || !options.create))
    throw NotFound(path + ": no such database file" +
                   (options.read_only ? " (read-only mode never creates one)" : ""));
  int flags = SQLITE_OPEN_FULLMUTEX;
  flags |= options.read_only ? SQLITE_OPEN_READONLY
                             : (SQLITE_OPEN_READWRITE | (options.create ? SQLITE_OPEN_CREATE : 0));
  const int rc = sqlite3_open_v2(path.c_str(), &d.db, flags, nullptr);
  if (rc != SQLITE_OK) d.fail(rc, options.read_only ? "open read-only" : "open");
  sqlite3_extended_result_codes(d.db, 1);
  // Connection settings (no values: constant pragmas; busy_timeout through the C API).
  sqlite3_busy_timeout(d.db, options.busy_timeout_ms);
  // The memory bounds (sqlite_repository.hpp). PRAGMA arguments cannot be bound; the number is our
  // own constant, not input.
  const std::string cache_size = "PRAGMA cache_size = -" + std::to_string(kSqlitePageCacheKiB);
  schema::exec(d.db, cache_size.c_str(), path, "open: cache_size");
  schema::exec(d.db, "PRAGMA mmap_size = 0", path, "open: mmap_size");
  schema::exec(d.db, "PRAGMA foreign_keys = ON", path, "open: foreign_keys");
  if (!options.read_only) {
    schema::exec(d.db, "PRAGMA synchronous = FULL", path, "open: synchronous=FULL");
    // Migrate (or refuse a foreign/newer file) before switching the journal mode, so a refused
    // file is left exactly as it was.
    schema::migrate(d.db, path);
    schema::exec(d.db, "PRAGMA journal_mode = WAL", path, "open: journal_mode=WAL");
    // Keep the -wal and -shm files when the last connection closes: a reader that may not create
    // files beside the database (QA and operators reading the daemon's data directory while it is
    // stopped) can open a WAL database read-only only where they exist ("attempt to write a
    // readonly database" otherwise; SQLite's wal.html, "Read-Only Databases").
    // With a journal size limit, the last close truncates the checkpointed -wal to zero bytes, so
    // no stale frame is left beside the file (a restored backup, a copied history); while running,
    // a reset -wal is cut back to 4 MiB.
    int persist_wal = 1;
    sqlite3_file_control(d.db, "main", SQLITE_FCNTL_PERSIST_WAL, &persist_wal);
    schema::exec(d.db, "PRAGMA journal_size_limit = 4194304", path, "open: journal_size_limit");
  } else {
    schema::exec(d.db, "PRAGMA synchronous = FULL", path, "open: synchronous=FULL");
    schema::check_version_readable(d.db, path);
  }
}

SqliteRepository::~SqliteRepository() = default;

const std::string& SqliteRepository::path() const { return impl_->path; }
bool SqliteRepository::read_only() const { return impl_->options.read_only; }

int SqliteRepository::schema_version() const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  return schema::user_version(impl_->db, impl_->path);
}

std::string SqliteRepository::integrity_check() const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  Impl::Stmt q(*impl_, "PRAGMA integrity_check", "integrity_check");
  std::string out;
  while (q.step()) {
    if (!out.empty()) out += "\n";
    out += q.text(0);
  }
  return out;
}

void SqliteRepository::transaction(const std::function<void()>& body) {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  impl_->require_writable("transaction");
  Impl::Tx tx(*impl_, "transaction", true);
  body();
  tx.commit();
}

RunId SqliteRepository::create_run(const NewRun& run) {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  Impl& d = *impl_;
  const char* op = "create_run";
  d.require_writable(op);
  validate_serial(run.serial);
  check_sha(run.sequence_sha256, "sequence SHA-256");
  if (is_terminal(run.state))
    throw InvalidInput(d.path + ": " + op +
                       ": a new run starts in a live state (preparing, "
                       "running or calibrating), not " +
                       to_string(run.state));
  Impl::Tx tx(d, op, true);
  if (run.reprocessed_from) {
    Impl::Stmt q(d, kSqlRunExists, op);
    q.bind(1, *run.reprocessed_from);
    if (!q.step())
      throw NotFound(d.path + ": " + op + ": reprocessed_from names no run (" +
                     run_label(*run.reprocessed_from) + ")");
  }
  {
    Impl::Stmt q(d, kSqlInsertUnit, op);
    q.bind(1, run.serial).bind(2, run.started_at_ms);
    q.run();
  }
  const std::int64_t unit = *d.unit_id(run.serial);
  {
    Impl::Stmt q(d, kSqlInsertRun, op);
    q.bind(1, unit).bind(2, run.operator_name).bind(3, run.station).bind(4, run.sequence_name);
    q.bind(5, run.sequence_sha256).bind(6, run.software_version).bind(7, run.started_at_ms);
    q.bind(8, to_string(run.state)).bind(9, run.archive_path).bind(10, run.reprocessed_from);
    q.bind(11, calib::core::setting_name(run.setting)).bind(12, run.origin);
    q.bind(13, run.slot).bind(14, run.table_run_id);
    q.run();
  }
  const RunId id = sqlite3_last_insert_rowid(d.db);
  tx.commit();
  return id;
}

void SqliteRepository::update_run_state(RunId run_id, RunState state, const std::string& reason) {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  Impl& d = *impl_;
  const char* op = "update_run_state";
  d.require_writable(op);
  if (is_terminal(state)) {
    RunCompletion c;
    c.state = state;
    c.ended_at_ms = now_ms();
    c.reason = reason;
    d.finish(run_id, c);
    return;
  }
  Impl::Tx tx(d, op, true);
  const RunState cur = d.require_live(run_id, op);
  if (live_rank(state) < live_rank(cur))
    throw Conflict(d.path + ": " + op + ": " + run_label(run_id) + " is " + to_string(cur) +
                   "; it cannot go back to " + to_string(state));
  if (state != cur) {
    Impl::Stmt q(d, kSqlSetLiveState, op);
    q.bind(1, run_id).bind(2, to_string(state));
    q.run();
  }
  tx.commit();
}

void SqliteRepository::finish_run(RunId run_id, const RunCompletion& completion) {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  impl_->require_writable("finish_run");
  impl_->finish(run_id, completion);
}

void SqliteRepository::store_calibration(RunId run_id, const CalibrationRecord& calibration) {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  Impl& d = *impl_;
  const char* op = "store_calibration";
  d.require_writable(op);
  Impl::Tx tx(d, op, true);
  d.require_live(run_id, op);
  d.insert_calibration(run_id, calibration, op);
  tx.commit();
}

void SqliteRepository::store_crosscheck(RunId run_id, const CrosscheckRecord& crosscheck) {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  Impl& d = *impl_;
  const char* op = "store_crosscheck";
  d.require_writable(op);
  Impl::Tx tx(d, op, true);
  d.require_live(run_id, op);
  d.insert_crosscheck(run_id, crosscheck, op);
  tx.commit();
}

void SqliteRepository::set_diagnosis(RunId run_id, const std::string& diagnosis_json) {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  Impl& d = *impl_;
  const char* op = "set_diagnosis";
  d.require_writable(op);
  const std::string who = d.path + ": " + op + ": " + run_label(run_id);
  Impl::check_json_object(diagnosis_json, who, "diagnosis_json");
  Impl::Tx tx(d, op, true);
  const RunState s = d.state_of(run_id, op);
  if (!is_terminal(s))
    throw Conflict(who + " is still " + to_string(s) + "; diagnose it when it has finished");
  Impl::Stmt q(d, kSqlSetDiagnosis, op);
  q.bind(1, run_id).bind(2, diagnosis_json);
  q.run();
  tx.commit();
}

std::vector<RunId> SqliteRepository::mark_interrupted_runs(TimestampMs now) {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  Impl& d = *impl_;
  const char* op = "mark_interrupted_runs";
  d.require_writable(op);
  Impl::Tx tx(d, op, true);
  std::vector<std::pair<RunId, std::string>> live;
  {
    Impl::Stmt q(d, kSqlLiveRuns, op);
    while (q.step()) live.emplace_back(q.i64(0), q.text(1));
  }
  std::vector<RunId> ids;
  for (const auto& [id, state] : live) {
    Impl::Stmt q(d, kSqlFinishRun, op);
    const std::string reason = "the station daemon stopped while the run was " + state +
                               " (found at start-up); not resumed — the archive can be reprocessed";
    q.bind(1, id).bind(2, to_string(RunState::kInterrupted)).bind(3, now).bind(4, reason);
    // Keep whatever capture summary was stored (none: runs get it at finish).
    q.bind_null(5).bind(6, std::string()).bind(7, std::string()).bind(8, std::string());
    q.bind(9, reasons_to_json({{default_reason_source(RunState::kInterrupted), reason}}));
    q.bind_null(10).bind_null(11);  // no calibration judged: the holding method stays as stored
    q.bind(12, std::string(to_string(RunVerdict::kInterrupted)));
    q.run();
    ids.push_back(id);
  }
  tx.commit();
  return ids;
}

std::vector<RunRecord> SqliteRepository::history(const std::string& serial,
                                                 std::size_t limit) const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  const Impl& d = *impl_;
  validate_serial(serial);
  Impl::Tx tx(d, "history", false);
  const std::int64_t unit = d.require_unit(serial);
  std::vector<RunRecord> out;
  Impl::Stmt q(d, kSqlHistory.c_str(), "history");
  q.bind(1, unit).bind(2, limit == 0 ? std::int64_t{-1} : static_cast<std::int64_t>(limit));
  while (q.step()) out.push_back(d.read_run(q));
  return out;  // the read transaction ends (rolls back: nothing was written) with tx
}

std::size_t SqliteRepository::run_count(const std::string& serial) const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  const Impl& d = *impl_;
  validate_serial(serial);
  Impl::Tx tx(d, "run_count", false);
  const std::int64_t unit = d.require_unit(serial);
  Impl::Stmt q(d, "SELECT COUNT(*) FROM runs WHERE unit_id = ?1", "run_count");
  q.bind(1, unit);
  return q.step() ? static_cast<std::size_t>(q.i64(0)) : 0;
}

RunDetails SqliteRepository::show(RunId run_id) const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  const Impl& d = *impl_;
  Impl::Tx tx(d, "show", false);
  RunDetails out;
  {
    Impl::Stmt q(d, kSqlRunById.c_str(), "show");
    q.bind(1, run_id);
    if (!q.step()) throw NotFound("no " + run_label(run_id) + " in " + d.path);
    out.run = d.read_run(q);
  }
  out.calibrations = d.calibrations_of(run_id);
  out.crosscheck = d.crosscheck_of(run_id);
  return out;
}

ActiveCalibration SqliteRepository::active_params(const std::string& serial) const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  const Impl& d = *impl_;
  validate_serial(serial);
  Impl::Tx tx(d, "active_params", false);
  const std::int64_t unit = d.require_unit(serial);
  ActiveCalibration out;
  bool have_factory = false;
  {
    Impl::Stmt q(d, kSqlActive.c_str(), "active_params");
    q.bind(1, unit);
    have_factory = q.step();
    if (have_factory) out.run = d.read_run(q);
  }
  if (!have_factory) {
    Impl::Stmt p(d, kSqlLatestPromoted.c_str(), "active_params");
    p.bind(1, unit);
    if (!p.step()) {
      Impl::Stmt n(d, kSqlCountRunsOfUnit, "active_params");
      n.bind(1, unit);
      n.step();
      throw NotFound(d.path + ": serial number \"" + serial + "\" has no active calibration (" +
                     std::to_string(n.i64(0)) +
                     " run(s) on record: none a station factory run with verdict PASS, none "
                     "promoted)");
    }
  }
  {
    // A promotion made after the latest factory PASS ended wins (QA's explicit choice).
    Impl::Stmt q(d, kSqlLatestPromoted.c_str(), "active_params");
    q.bind(1, unit);
    if (q.step()) {
      RunRecord promoted = d.read_run(q);
      if (!have_factory || *promoted.promoted_at_ms > out.run.ended_at_ms.value_or(0))
        out.run = std::move(promoted);
    }
  }
  out.all = d.calibrations_of(out.run.run_id);
  out.active = active_calibration(out, d.path);
  return out;
}

std::vector<RunRecord> SqliteRepository::recent_runs(std::size_t limit) const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  const Impl& d = *impl_;
  Impl::Tx tx(d, "recent_runs", false);
  Impl::Stmt q(d, kSqlRecent.c_str(), "recent_runs");
  q.bind(1, limit == 0 ? static_cast<std::int64_t>(-1) : static_cast<std::int64_t>(limit));
  std::vector<RunRecord> out;
  while (q.step()) out.push_back(d.read_run(q));
  return out;
}

std::size_t SqliteRepository::total_run_count() const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  const Impl& d = *impl_;
  Impl::Tx tx(d, "total_run_count", false);
  Impl::Stmt q(d, kSqlCountRuns, "total_run_count");
  q.step();
  return static_cast<std::size_t>(q.i64(0));
}

RunId SqliteRepository::highest_run_id_issued() const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  const Impl& d = *impl_;
  Impl::Tx tx(d, "highest_run_id_issued", false);
  Impl::Stmt q(d, kSqlHighestRunIdIssued, "highest_run_id_issued");
  q.step();
  return q.i64(0);
}

bool SqliteRepository::continue_run_ids_after(RunId id) {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  Impl& d = *impl_;
  const char* op = "continue_run_ids_after";
  d.require_writable(op);
  Impl::Tx tx(d, op, true);
  if (highest_run_id_issued() >= id) return false;
  // AUTOINCREMENT numbers after sqlite_sequence's row (absent before the first run).
  Impl::Stmt(d, "DELETE FROM sqlite_sequence WHERE name = 'runs'", op).run();
  Impl::Stmt q(d, "INSERT INTO sqlite_sequence (name, seq) VALUES ('runs', ?1)", op);
  q.bind(1, id);
  q.run();
  tx.commit();
  return true;
}

std::vector<RunRecord> SqliteRepository::runs_with_archive_sha256(const std::string& sha256) const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  const Impl& d = *impl_;
  if (!is_sha256_hex(sha256))
    throw InvalidInput(d.path + ": runs_with_archive_sha256: \"" + sha256.substr(0, 80) +
                       "\" is not a SHA-256 (64 lowercase hex digits)");
  Impl::Tx tx(d, "runs_with_archive_sha256", false);
  Impl::Stmt q(d, kSqlRunsWithArchiveSha.c_str(), "runs_with_archive_sha256");
  q.bind(1, sha256);
  std::vector<RunRecord> out;
  while (q.step()) out.push_back(d.read_run(q));
  return out;
}

void SqliteRepository::promote(RunId run_id, const std::string& by, const std::string& reason,
                               TimestampMs at_ms) {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  Impl& d = *impl_;
  const char* op = "promote";
  d.require_writable(op);
  const std::string who = d.path + ": " + op + ": " + run_label(run_id);
  if (reason.empty()) throw InvalidInput(who + ": a promotion needs a reason (QA record)");
  if (by.empty()) throw InvalidInput(who + ": a promotion needs the name of who promotes");
  Impl::Tx tx(d, op, true);
  RunRecord r;
  {
    Impl::Stmt q(d, kSqlRunById.c_str(), op);
    q.bind(1, run_id);
    if (!q.step()) throw NotFound("no " + run_label(run_id) + " in " + d.path);
    r = d.read_run(q);
  }
  if (r.setting == calib::core::Setting::kFactory && r.origin.empty())
    throw Conflict(who +
                   " is a factory run of this station: its PASS is active by itself; only runs "
                   "that are not are promoted: field (land/sea) runs, imported runs and runs "
                   "reprocessed with a corrected gravity");
  if (!is_terminal(r.state)) throw Conflict(who + " is still " + to_string(r.state));
  const bool sea_alone = r.setting == calib::core::Setting::kSea && r.state == RunState::kReview &&
                         !r.crosscheck_verdict;
  if (r.state != RunState::kDone && !sea_alone)
    throw Conflict(who + " is " + to_string(r.state) +
                   (r.failure_reason.empty() ? "" : " (" + r.failure_reason + ")") +
                   "; only a done (PASS) field run, or a sea run reviewed only for having AINS "
                   "alone, can be promoted");
  Impl::Stmt q(d, kSqlPromote, op);
  q.bind(1, run_id).bind(2, at_ms).bind(3, by).bind(4, reason);
  q.run();
  tx.commit();
}

void SqliteRepository::export_rows(const ExportFilter& filter,
                                   const std::function<void(const ExportRow&)>& sink) const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  const Impl& d = *impl_;
  if (filter.serial) validate_serial(*filter.serial);
  const std::string& sql = filter.serial ? (filter.since_ms ? kSqlExportBoth : kSqlExportSerial)
                                         : (filter.since_ms ? kSqlExportSince : kSqlExportAll);
  Impl::Tx tx(d, "export", false);
  Impl::Stmt q(d, sql.c_str(), "export");
  if (filter.serial) q.bind(1, *filter.serial);
  if (filter.since_ms) q.bind(2, *filter.since_ms);
  ExportRow row;
  while (q.step()) {
    row.run = d.read_run(q);
    if (filter.station && row.run.station != *filter.station)
      continue;  // rare: scanned, not indexed
    row.calibration = d.read_calibration(q, kNumRunColumns, row.run.run_id);
    row.crosscheck.reset();
    if (!q.is_null(kExportCrosscheckColumn))
      row.crosscheck =
          d.read_crosscheck(q, kExportVerdictColumn, kExportCrosscheckColumn, row.run.run_id);
    sink(row);
  }
}

std::vector<RunRecord> SqliteRepository::runs_in_state(const std::vector<RunState>& states) const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  const Impl& d = *impl_;
  Impl::Tx tx(d, "runs_in_state", false);
  std::vector<RunRecord> out;
  std::vector<RunState> uniq = states;
  std::sort(uniq.begin(), uniq.end());
  uniq.erase(std::unique(uniq.begin(), uniq.end()), uniq.end());
  for (RunState s : uniq) {
    Impl::Stmt q(d, kSqlRunsInState.c_str(), "runs_in_state");
    q.bind(1, to_string(s));
    while (q.step()) out.push_back(d.read_run(q));
  }
  std::sort(out.begin(), out.end(),
            [](const RunRecord& a, const RunRecord& b) { return a.run_id < b.run_id; });
  return out;
}

// ----- the replication outbox ------------------------------------------------------------------

void SqliteRepository::set_outbox_enabled(bool enabled) {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  Impl& d = *impl_;
  const char* op = "set_outbox_enabled";
  d.require_writable(op);
  Impl::Tx tx(d, op, true);
  {
    Impl::Stmt q(d, kSqlOutboxEnabled, op);
    if (q.step() && (q.i64(0) != 0) == enabled) return;  // unchanged: nothing to enqueue
  }
  Impl::Stmt(d, kSqlSetOutboxEnabled, op).bind(1, enabled ? 1 : 0).run();
  if (enabled)
    Impl::Stmt(d, kSqlOutboxResync, op).bind(1, now_ms()).run();
  else
    Impl::Stmt(d, kSqlOutboxClear, op).run();
  tx.commit();
}

bool SqliteRepository::outbox_enabled() const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  Impl::Stmt q(*impl_, kSqlOutboxEnabled, "outbox_enabled");
  return q.step() && q.i64(0) != 0;
}

std::vector<OutboxEntry> SqliteRepository::outbox_batch(std::size_t limit) const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  std::vector<OutboxEntry> out;
  Impl::Stmt q(*impl_, kSqlOutboxBatch, "outbox_batch");
  q.bind(1, static_cast<std::int64_t>(limit));
  while (q.step()) out.push_back({q.i64(0), q.i64(1), q.text(2), q.i64(3)});
  return out;
}

void SqliteRepository::outbox_remove_through(std::int64_t seq) {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  Impl& d = *impl_;
  const char* op = "outbox_remove_through";
  d.require_writable(op);
  Impl::Tx tx(d, op, true);
  Impl::Stmt(d, kSqlOutboxRemove, op).bind(1, seq).run();
  tx.commit();
}

std::size_t SqliteRepository::outbox_length() const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  Impl::Stmt q(*impl_, kSqlOutboxLength, "outbox_length");
  return q.step() ? static_cast<std::size_t>(q.i64(0)) : 0;
}

std::vector<RunDetails> SqliteRepository::details_of(const std::vector<RunId>& ids) const {
  std::lock_guard<std::recursive_mutex> lock(impl_->mutex);
  Impl& d = *impl_;
  Impl::Tx tx(d, "details_of", false);
  std::vector<RunId> sorted = ids;
  std::sort(sorted.begin(), sorted.end());
  sorted.erase(std::unique(sorted.begin(), sorted.end()), sorted.end());
  std::vector<RunDetails> out;
  for (RunId id : sorted) {
    try {
      out.push_back(show(id));
    } catch (const NotFound&) {
      // a run the outbox names but the file no longer holds (a restored backup): nothing to send
    }
  }
  tx.commit();
  return out;
}

}  // namespace imucal::db::history
