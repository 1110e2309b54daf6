#include "db/fleet/pg_connection.hpp"

#include <cmath>
#include <cstdio>
#include <cstring>

namespace imucal::db::fleet {
using namespace db::history;

namespace {

std::string trimmed(const char* text) {
  std::string s = text ? text : "";
  while (!s.empty() && (s.back() == '\n' || s.back() == ' ')) s.pop_back();
  return s;
}

}  // namespace

PgParam pg_value(std::int64_t v) { return std::to_string(v); }
PgParam pg_value(double v) {
  char buf[40];
  std::snprintf(buf, sizeof buf, "%.17g", v);  // round-trips a double exactly
  return std::string(buf);
}
PgParam pg_value(bool v) { return std::string(v ? "t" : "f"); }
PgParam pg_value(const std::string& v) { return v; }
PgParam pg_value(const char* v) { return std::string(v); }
PgParam pg_text_array(const std::vector<std::string>& items) {
  std::string out = "{";
  for (std::size_t i = 0; i < items.size(); ++i) {
    if (i) out += ',';
    out += '"';
    for (char ch : items[i]) {
      if (ch == '"' || ch == '\\') out += '\\';
      out += ch;
    }
    out += '"';
  }
  return out + "}";
}

std::string PgResult::text(int row, int col) const {
  return std::string(PQgetvalue(r_.get(), row, col),
                     static_cast<std::size_t>(PQgetlength(r_.get(), row, col)));
}
std::int64_t PgResult::i64(int row, int col) const {
  return std::strtoll(PQgetvalue(r_.get(), row, col), nullptr, 10);
}
double PgResult::f64(int row, int col) const {
  return std::strtod(PQgetvalue(r_.get(), row, col), nullptr);
}
std::optional<std::int64_t> PgResult::opt_i64(int row, int col) const {
  if (is_null(row, col)) return std::nullopt;
  return i64(row, col);
}

PgConnection::PgConnection(const FleetTarget& target, const std::string& server_options)
    : target_(target) {
  // Defaults first, then the URL as libpq's dbname (expanded): libpq lets a keyword override
  // those before it, so the URL's own parameters (?connect_timeout=…, ?application_name=…) win.
  // A network that silently drops packets (no reset) must end a statement too, or the sender
  // would wait on it forever: TCP keepalives and a 30 s limit on unacknowledged data. The password
  // as its own keyword after the URL: it never has to be written into one, and libpq's other
  // sources (PGPASSWORD, ~/.pgpass) still apply when it is empty.
  const char* keys[] = {"connect_timeout",
                        "application_name",
                        "keepalives",
                        "keepalives_idle",
                        "keepalives_interval",
                        "keepalives_count",
                        "tcp_user_timeout",
                        "dbname",
                        "password",
                        server_options.empty() ? nullptr : "options",
                        nullptr};
  const char* values[] = {"5",
                          "imucal",
                          "1",
                          "10",
                          "5",
                          "3",
                          "30000",
                          target.url.c_str(),
                          target.password.empty() ? nullptr : target.password.c_str(),
                          server_options.c_str(),
                          nullptr};
  conn_ = PQconnectdbParams(keys, values, /*expand_dbname=*/1);
  if (!conn_ || PQstatus(conn_) != CONNECTION_OK) {
    const std::string why = trimmed(conn_ ? PQerrorMessage(conn_) : "out of memory");
    if (conn_) PQfinish(conn_);
    conn_ = nullptr;
    throw IoError("fleet store " + target.redacted() + ": cannot connect: " + target.redact(why));
  }
}

PgConnection::~PgConnection() {
  if (conn_) PQfinish(conn_);
}

bool PgConnection::ok() const { return conn_ && PQstatus(conn_) == CONNECTION_OK; }

void PgConnection::fail(PGresult* r, const char* op) {
  const char* state = r ? PQresultErrorField(r, PG_DIAG_SQLSTATE) : nullptr;
  const std::string code = state ? state : "";
  const std::string why =
      target_.redact(trimmed(r ? PQresultErrorMessage(r) : PQerrorMessage(conn_)));
  if (r) PQclear(r);
  const std::string msg = "fleet store " + target_.redacted() + ": " + op + ": " +
                          (why.empty() ? target_.redact(trimmed(PQerrorMessage(conn_))) : why);
  if (code == "42501" || code == "25006") throw ReadOnly(msg);
  if (code.rfind("23", 0) == 0) throw Conflict(msg);
  if (code.rfind("22", 0) == 0) throw InvalidInput(msg);
  throw IoError(msg);
}

PGresult* PgConnection::send(const std::string& sql, const std::vector<PgParam>* params) {
  auto once = [&]() -> PGresult* {
    if (!params) return PQexec(conn_, sql.c_str());
    std::vector<const char*> values;
    values.reserve(params->size());
    for (const PgParam& p : *params) values.push_back(p ? p->c_str() : nullptr);
    return PQexecParams(conn_, sql.c_str(), static_cast<int>(values.size()), nullptr, values.data(),
                        nullptr, nullptr, 0);
  };
  if (tx_depth_ == 0 && lost()) PQreset(conn_);
  PGresult* r = once();
  const ExecStatusType s = r ? PQresultStatus(r) : PGRES_FATAL_ERROR;
  if (s != PGRES_FATAL_ERROR || tx_depth_ != 0 || !lost()) return r;
  // The connection went away under this statement, outside any transaction: once more anew.
  if (r) PQclear(r);
  PQreset(conn_);
  return once();
}

PgResult PgConnection::exec(const std::string& sql, const std::vector<PgParam>& params,
                            const char* op) {
  PGresult* r = send(sql, &params);
  const ExecStatusType s = r ? PQresultStatus(r) : PGRES_FATAL_ERROR;
  if (s != PGRES_COMMAND_OK && s != PGRES_TUPLES_OK) fail(r, op);
  return PgResult(r);
}

void PgConnection::exec_plain(const std::string& sql, const char* op) {
  PGresult* r = send(sql, nullptr);
  const ExecStatusType s = r ? PQresultStatus(r) : PGRES_FATAL_ERROR;
  if (s != PGRES_COMMAND_OK && s != PGRES_TUPLES_OK) fail(r, op);
  PQclear(r);
}

PgTransaction::PgTransaction(PgConnection& c, const char* op, bool read_only) : c_(c), op_(op) {
  c_.exec_plain(read_only ? "BEGIN ISOLATION LEVEL REPEATABLE READ READ ONLY" : "BEGIN", op);
  ++c_.tx_depth_;
}

PgTransaction::~PgTransaction() {
  --c_.tx_depth_;
  if (done_ || !c_.ok()) return;
  try {
    c_.exec_plain("ROLLBACK", op_);
  } catch (const DbError&) {
    // the connection is gone: the server rolled back already
  }
}

void PgTransaction::commit() {
  c_.exec_plain("COMMIT", op_);
  done_ = true;
}

}  // namespace imucal::db::fleet
