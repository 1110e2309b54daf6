// A station whose history database was replaced (a new, empty one) or restored from an older copy
// while its data directory kept the run archives: new runs are numbered after every archive, so
// that a run never fails on an old archive directory of the same id and serial, and the fleet
// store never meets an old local id again (station/run/recovery.hpp,
// continue_run_ids_after_archives).
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "db/history/sqlite_repository.hpp"
#include "station/run/recovery.hpp"
#include "tests/db/history_fixtures.hpp"

namespace imucal::station {
using namespace imucal::station::config;
using namespace imucal::station::run;
namespace {

namespace fs = std::filesystem;
constexpr db::history::TimestampMs kT0 = 1714560000000;

void make_archive(const std::string& data_dir, const std::string& name) {
  fs::create_directories(fs::path(data_dir) / "runs" / name);
  std::ofstream(fs::path(data_dir) / "runs" / name / "run.toml") << "# kept\n";
}

TEST(RunNumbering, TheHighestArchiveIsFoundAmongRunDirectoriesOnly) {
  db::test::TempDir dir;
  const std::string data = dir.file("data");
  EXPECT_EQ(highest_archived_run_id(data), 0) << "no runs directory yet";
  make_archive(data, "7-SN-A");
  make_archive(data, "12-SN-B");
  make_archive(data, "abc-1");                                     // not a run id
  make_archive(data, "-5");                                        // no id before the dash
  make_archive(data, "99999999999999999999999-SN-C");              // more digits than an id has
  std::ofstream(fs::path(data) / "runs" / "99-SN-D") << "a file";  // not a directory
  std::ofstream(fs::path(data) / "runs" / ".3.end") << "";         // an end note
  EXPECT_EQ(highest_archived_run_id(data), 12);
}

TEST(RunNumbering, AReplacedDatabaseNumbersItsRunsAfterTheArchivesItFinds) {
  db::test::TempDir dir;
  StationConfig cfg;
  cfg.data_dir = dir.file("data");
  cfg.database = dir.file("data/history.sqlite");
  make_archive(cfg.data_dir, "1-SN-A");
  make_archive(cfg.data_dir, "12-SN-A");
  {
    db::history::SqliteRepository repo(cfg.database);  // the new, empty database
    EXPECT_EQ(repo.highest_run_id_issued(), 0);
    EXPECT_EQ(continue_run_ids_after_archives(cfg, repo), 12);
    EXPECT_EQ(continue_run_ids_after_archives(cfg, repo), 0) << "once is enough";
    EXPECT_EQ(repo.create_run(db::test::new_run("SN-A", kT0)), 13);
  }
  {
    // Reopened (the next start): the numbering held, and runs beyond the archives go on.
    db::history::SqliteRepository repo(cfg.database);
    EXPECT_EQ(repo.highest_run_id_issued(), 13);
    EXPECT_EQ(continue_run_ids_after_archives(cfg, repo), 0);
    EXPECT_EQ(repo.create_run(db::test::new_run("SN-A", kT0 + 1000)), 14);
    EXPECT_FALSE(repo.continue_run_ids_after(3)) << "numbering never moves back";
    EXPECT_EQ(repo.create_run(db::test::new_run("SN-A", kT0 + 2000)), 15);
  }
  db::history::SqliteOptions ro;
  ro.read_only = true;
  db::history::SqliteRepository reader(cfg.database, ro);
  EXPECT_THROW(reader.continue_run_ids_after(100), db::history::ReadOnly);
}

}  // namespace
}  // namespace imucal::station
