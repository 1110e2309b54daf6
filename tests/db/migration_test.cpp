// Schema versioning (PRAGMA user_version): a fresh file gets version 1 and our application_id; a
// newer, foreign or non-database file is refused untouched; reopening is idempotent; a migration
// is applied atomically with its version bump (a failing one leaves the old version intact).
#include <gtest/gtest.h>
#include <sqlite3.h>

#include <fstream>
#include <iterator>

#include "db/schema.hpp"
#include "db/sqlite_repository.hpp"
#include "tests/db/history_fixtures.hpp"

namespace imucal::db {
namespace {

using test::TempDir;
using test::expect_throw_message;

constexpr TimestampMs kT0 = 1714560000000;

/// A raw connection for inspecting or preparing files around the repository.
class RawDb {
 public:
  explicit RawDb(const std::string& path) {
    if (sqlite3_open(path.c_str(), &db_) != SQLITE_OK) ADD_FAILURE() << "open " << path;
  }
  ~RawDb() { sqlite3_close(db_); }
  sqlite3* get() { return db_; }
  void exec(const std::string& sql) {
    char* err = nullptr;
    if (sqlite3_exec(db_, sql.c_str(), nullptr, nullptr, &err) != SQLITE_OK) {
      ADD_FAILURE() << sql << ": " << (err ? err : "?");
      sqlite3_free(err);
    }
  }
  std::string text(const std::string& sql) {
    sqlite3_stmt* st = nullptr;
    std::string out;
    if (sqlite3_prepare_v2(db_, sql.c_str(), -1, &st, nullptr) != SQLITE_OK) {
      ADD_FAILURE() << sql << ": " << sqlite3_errmsg(db_);
      return out;
    }
    while (sqlite3_step(st) == SQLITE_ROW) {
      if (!out.empty()) out += "\n";
      const unsigned char* p = sqlite3_column_text(st, 0);
      out += p ? reinterpret_cast<const char*>(p) : "NULL";
    }
    sqlite3_finalize(st);
    return out;
  }

 private:
  sqlite3* db_ = nullptr;
};

std::string file_bytes(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>());
}

TEST(Migration, FreshDatabaseGetsVersionOneOurApplicationIdAndWal) {
  TempDir dir;
  const std::string path = dir.file("fresh.db");
  {
    SqliteRepository repo(path);
    EXPECT_EQ(repo.schema_version(), 1);
    EXPECT_EQ(schema::kSchemaVersion, 1);
  }
  RawDb raw(path);
  EXPECT_EQ(raw.text("PRAGMA user_version"), "1");
  EXPECT_EQ(raw.text("PRAGMA application_id"), std::to_string(0x494D5543));
  EXPECT_EQ(raw.text("PRAGMA journal_mode"), "wal") << "WAL is persistent in the file";
  EXPECT_EQ(raw.text("SELECT group_concat(name, ',') FROM (SELECT name FROM sqlite_schema WHERE "
                     "type = 'table' AND name NOT LIKE 'sqlite_%' ORDER BY name)"),
            "calibrations,crosschecks,runs,units");
  EXPECT_EQ(raw.text("PRAGMA integrity_check"), "ok");
  EXPECT_EQ(raw.text("PRAGMA foreign_key_check"), "");
}

TEST(Migration, ReopeningIsIdempotentAndKeepsData) {
  TempDir dir;
  const std::string path = dir.file("reopen.db");
  RunId id = 0;
  {
    SqliteRepository repo(path);
    id = repo.create_run(test::new_run("SIM-0001", kT0));
    repo.finish_run(id, test::pass_completion(3, kT0 + 1000));
  }
  const std::string schema_before = RawDb(path).text("SELECT sql FROM sqlite_schema ORDER BY name");
  for (int i = 0; i < 3; ++i) {
    SqliteRepository repo(path);
    EXPECT_EQ(repo.schema_version(), 1);
    ASSERT_EQ(repo.history("SIM-0001").size(), 1u);
    EXPECT_EQ(repo.history("SIM-0001")[0].run_id, id);
  }
  EXPECT_EQ(RawDb(path).text("SELECT sql FROM sqlite_schema ORDER BY name"), schema_before);
}

TEST(Migration, NewerSchemaVersionIsRefusedAndTheFileLeftUntouched) {
  TempDir dir;
  const std::string path = dir.file("future.db");
  {
    SqliteRepository repo(path);
    repo.create_run(test::new_run("SIM-0001", kT0));
  }
  RawDb(path).exec("PRAGMA user_version = 99");
  const std::string before = file_bytes(path);
  const std::string msg =
      expect_throw_message<IncompatibleSchema>([&] { SqliteRepository r(path); });
  EXPECT_NE(msg.find(path), std::string::npos) << msg;
  EXPECT_NE(msg.find("99"), std::string::npos) << msg;
  EXPECT_NE(msg.find("newer than this software supports (1)"), std::string::npos) << msg;
  SqliteOptions ro;
  ro.read_only = true;
  EXPECT_THROW(SqliteRepository r(path, ro), IncompatibleSchema);
  EXPECT_EQ(file_bytes(path), before) << "a refused file is not modified";
  EXPECT_EQ(RawDb(path).text("PRAGMA user_version"), "99");
}

TEST(Migration, ForeignAndNonDatabaseFilesAreRefused) {
  TempDir dir;
  // Tables but no version: somebody else's database.
  const std::string foreign = dir.file("foreign.db");
  RawDb(foreign).exec("CREATE TABLE stuff (x INTEGER); INSERT INTO stuff VALUES (1);");
  const std::string before = file_bytes(foreign);
  std::string msg = expect_throw_message<IncompatibleSchema>([&] { SqliteRepository r(foreign); });
  EXPECT_NE(msg.find("not created by this software"), std::string::npos) << msg;
  EXPECT_EQ(file_bytes(foreign), before);

  // Another application's id.
  const std::string other = dir.file("other.db");
  RawDb(other).exec("PRAGMA application_id = 1234; PRAGMA user_version = 1;");
  msg = expect_throw_message<IncompatibleSchema>([&] { SqliteRepository r(other); });
  EXPECT_NE(msg.find("not a calibration-history database"), std::string::npos) << msg;

  // Not an SQLite file at all.
  const std::string text = dir.file("notes.db");
  std::ofstream(text) << "this is a text file, long enough to have what looks like a header......"
                         "..................................................................\n";
  msg = expect_throw_message<Corrupt>([&] { SqliteRepository r(text); });
  EXPECT_NE(msg.find(text), std::string::npos) << msg;

  // An empty SQLite file opened read-only: no schema yet, and read-only cannot create it.
  const std::string empty = dir.file("empty.db");
  RawDb(empty).exec("PRAGMA user_version = 0");
  SqliteOptions ro;
  ro.read_only = true;
  msg = expect_throw_message<IncompatibleSchema>([&] { SqliteRepository r(empty, ro); });
  EXPECT_NE(msg.find("no calibration-history schema"), std::string::npos) << msg;
}

TEST(Migration, LaterMigrationsApplyInOrderAndAFailingOneRollsBackCompletely) {
  TempDir dir;
  const std::string path = dir.file("mig.db");
  { SqliteRepository repo(path); }
  RawDb raw(path);

  // A hypothetical version 3 whose second step fails: nothing of 2 or 3 may remain.
  std::vector<schema::Migration> broken = schema::migrations();
  broken.push_back({2, "add a column", "ALTER TABLE units ADD COLUMN model TEXT;"});
  broken.push_back(
      {3, "broken", "CREATE TABLE extra (x INTEGER); INSERT INTO no_such_table VALUES (1);"});
  EXPECT_THROW(schema::migrate(raw.get(), path, broken), IoError);
  EXPECT_EQ(raw.text("PRAGMA user_version"), "1");
  EXPECT_EQ(raw.text("SELECT count(*) FROM sqlite_schema WHERE name = 'extra'"), "0");
  EXPECT_EQ(raw.text("SELECT count(*) FROM pragma_table_info('units') WHERE name = 'model'"), "0");

  // The same list without the broken step: version 2, column present; applying again is a no-op.
  broken.pop_back();
  EXPECT_EQ(schema::migrate(raw.get(), path, broken), 1);
  EXPECT_EQ(raw.text("PRAGMA user_version"), "2");
  EXPECT_EQ(raw.text("SELECT count(*) FROM pragma_table_info('units') WHERE name = 'model'"), "1");
  EXPECT_EQ(schema::migrate(raw.get(), path, broken), 2);

  // This software (version 1) now refuses the version-2 file.
  EXPECT_THROW(SqliteRepository r(path), IncompatibleSchema);

  // Gaps in a migration list are a programming error.
  std::vector<schema::Migration> gap = schema::migrations();
  gap.push_back({5, "gap", "SELECT 1;"});
  EXPECT_THROW(schema::migrate(raw.get(), path, gap), std::logic_error);
}

}  // namespace
}  // namespace imucal::db
