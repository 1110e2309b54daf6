#pragma once
// The SQLite schema of the calibration history and its migrations (db/history/SCHEMA.md describes
// the tables). The schema version lives in `PRAGMA user_version`; `PRAGMA application_id` marks the
// file as ours. Migration N turns a version N-1 database into version N inside one write
// transaction together with the user_version bump, so a crash leaves either the old or the new
// version, never a half-migrated file. Software refuses a database whose version is newer than it
// knows (it cannot know what the newer schema means), and a file with tables but no version (not
// ours).
//
// Also the low-level SQLite error mapping shared with db/history/sqlite_repository.cpp.
#include <sqlite3.h>

#include <string>
#include <vector>

namespace imucal::db::history::schema {

/// The version this software writes and reads.
constexpr int kSchemaVersion = 10;
/// PRAGMA application_id of a calibration-history database: ASCII "IMUC".
constexpr int kApplicationId = 0x494D5543;

struct Migration {
  int version;  ///< the user_version after applying it (1, 2, ... consecutive)
  const char* description;
  const char* sql;  ///< DDL only: no values, so no binding is needed
};

/// The migrations of this software, in order (migration 1 = the initial schema).
const std::vector<Migration>& migrations();

/// Bring the database to the last version of `list` (normally migrations()), atomically.
/// Throws IncompatibleSchema if the database is newer than the list knows, has another
/// application_id, or has tables but user_version 0; any SQL error rolls the whole upgrade back.
/// `path` names the file in messages. Returns the version found before.
int migrate(sqlite3* db, const std::string& path,
            const std::vector<Migration>& list = migrations());

/// The refusals of migrate() without writing: returns the user_version found if a migration to
/// `latest` may proceed, otherwise throws IncompatibleSchema.
int check_compatible(sqlite3* db, const std::string& path, int latest);

/// For read-only connections (no migration possible): the version must be exactly
/// kSchemaVersion; otherwise IncompatibleSchema saying what to do.
void check_version_readable(sqlite3* db, const std::string& path);

/// PRAGMA user_version.
int user_version(sqlite3* db, const std::string& path);

/// Throw the DbError subclass that matches an SQLite result code: BUSY/LOCKED -> Busy,
/// CORRUPT/NOTADB -> Corrupt, READONLY -> ReadOnly, CONSTRAINT -> Conflict, CANTOPEN -> IoError
/// or NotFound, FULL/IOERR/other -> IoError. Message: "<path>: <context>: <sqlite message>".
[[noreturn]] void throw_sqlite(sqlite3* db, int rc, const std::string& path,
                               const std::string& context);

/// Column `c` of the current row as text ("" for NULL), with its exact length (embedded NULs kept).
inline std::string column_text(sqlite3_stmt* st, int c) {
  const unsigned char* p = sqlite3_column_text(st, c);
  return p ? std::string(reinterpret_cast<const char*>(p),
                         static_cast<std::size_t>(sqlite3_column_bytes(st, c)))
           : std::string();
}

/// sqlite3_exec of constant SQL (no values); throws via throw_sqlite.
void exec(sqlite3* db, const char* sql, const std::string& path, const std::string& context);

}  // namespace imucal::db::history::schema
