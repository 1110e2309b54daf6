#pragma once
// One libpq connection to the fleet store (issue #24), with every statement sent as text plus bound
// values (PQexecParams: no value ever becomes SQL text) and every failure a db::history::DbError
// that names the server by its redacted address (db/fleet/fleet_url.hpp) — never the password.
//
// SQLSTATE → DbError: 42501 insufficient privilege / 25006 read-only transaction → ReadOnly;
// 23xxx integrity → Conflict; 22xxx data → InvalidInput; 28xxx authentication (wrong or expired
// password) and 3D000 unknown database → IoError with the server's words; a lost connection →
// IoError. Not thread-safe: one connection per thread.
#include <libpq-fe.h>

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "db/fleet/fleet_url.hpp"
#include "db/history/repository.hpp"

namespace imucal::db::fleet {

/// A bound value: text, or SQL NULL.
using PgParam = std::optional<std::string>;
PgParam pg_value(std::int64_t v);
PgParam pg_value(double v);
PgParam pg_value(bool v);
PgParam pg_value(const std::string& v);
PgParam pg_value(const char* v);
/// A PostgreSQL array literal of texts, bound as one value ($n::text[]): {"a","b"}, " and
/// \ escaped.
PgParam pg_text_array(const std::vector<std::string>& items);
template <typename T>
PgParam pg_value(const std::optional<T>& v) {
  return v ? pg_value(*v) : std::nullopt;
}

/// A query's rows; values are libpq's text forms.
class PgResult {
 public:
  explicit PgResult(PGresult* r) : r_(r, &PQclear) {}
  int rows() const { return PQntuples(r_.get()); }
  bool is_null(int row, int col) const { return PQgetisnull(r_.get(), row, col) != 0; }
  std::string text(int row, int col) const;
  std::int64_t i64(int row, int col) const;
  double f64(int row, int col) const;
  bool boolean(int row, int col) const { return text(row, col) == "t"; }
  std::optional<std::int64_t> opt_i64(int row, int col) const;

 private:
  std::unique_ptr<PGresult, void (*)(PGresult*)> r_;
};

class PgConnection {
 public:
  /// Connects (connect_timeout from the URL, default 5 s). Throws IoError naming the redacted
  /// address and the server's reason.
  /// `server_options`: libpq's `options` (e.g. "-c work_mem=64MB"), the session settings of
  /// every connection it opens, also after a reconnect; empty for the server's own.
  explicit PgConnection(const FleetTarget& target, const std::string& server_options = "");
  ~PgConnection();
  PgConnection(const PgConnection&) = delete;
  PgConnection& operator=(const PgConnection&) = delete;

  /// One statement with bound values ($1, $2, ...). `op` names the operation in errors.
  PgResult exec(const std::string& sql, const std::vector<PgParam>& params, const char* op);
  /// Constant SQL (DDL, BEGIN/COMMIT): no values.
  void exec_plain(const std::string& sql, const char* op);
  /// True while the socket is still good (after an error it may not be).
  bool ok() const;
  /// Outside a transaction, a connection found lost (the server restarted, the network reset) is
  /// opened again and the statement sent once more: a reader (stationweb, stationctl) outlives a
  /// server restart. Inside one it never is (the rest of a transaction must not run without its
  /// beginning): the caller sees the error.
  const FleetTarget& target() const { return target_; }

 private:
  [[noreturn]] void fail(PGresult* r, const char* op);
  PGresult* send(const std::string& sql, const std::vector<PgParam>* params);
  bool lost() const { return PQstatus(conn_) != CONNECTION_OK; }
  friend class PgTransaction;
  FleetTarget target_;
  PGconn* conn_ = nullptr;
  int tx_depth_ = 0;
};

/// One transaction on a connection: BEGIN at construction, COMMIT by commit(), ROLLBACK otherwise.
class PgTransaction {
 public:
  PgTransaction(PgConnection& c, const char* op, bool read_only = false);
  ~PgTransaction();
  void commit();
  PgTransaction(const PgTransaction&) = delete;
  PgTransaction& operator=(const PgTransaction&) = delete;

 private:
  PgConnection& c_;
  const char* op_;
  bool done_ = false;
};

}  // namespace imucal::db::fleet
