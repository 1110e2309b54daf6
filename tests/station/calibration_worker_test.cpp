// Whose a failed calibration job was (issue #50: "a station fault (table, bus, disk, daemon)"): the
// run's archive is the station's own — written by its capture or copied in after an import read
// it whole — so an archive the worker cannot read back is the station's disk or writer, and the
// run ends STATION-FAULT; an archive that reads but whose data the calibration refuses is the
// unit's FAILED. A real SQLite file and a real run archive (tests/data/soak-null-run).
#include "station/run/calibration_worker.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "db/history/sqlite_repository.hpp"
#include "tests/support/calibration_job.hpp"
#include "tests/support/data_archive.hpp"
#include "tests/support/temp_dir.hpp"

namespace imucal {
namespace {

namespace fs = std::filesystem;

/// One calibration job on the archive at `dir`, as the station runs it; the stored record.
db::history::RunRecord calibrate_stored(db::history::SqliteRepository& repo,
                                        const std::string& dir) {
  const station::run::CalibrationOutcome out =
      test_support::calibrate_as_the_station(repo, "SN-WORKER", "worker-test", dir);
  EXPECT_TRUE(out.stored);
  EXPECT_EQ(out.state, db::history::RunState::kFailed) << out.reason;
  const std::vector<db::history::RunRecord> runs = repo.recent_runs(1);
  EXPECT_EQ(runs.size(), 1u);
  if (runs.empty()) return {};
  EXPECT_EQ(runs[0].verdict, out.verdict) << "the outcome reported is the one stored";
  return runs[0];
}

/// Keeps the first `lines` lines of `path`.
void truncate_lines(const std::string& path, int lines) {
  std::ifstream in(path);
  std::string text, line;
  for (int i = 0; i < lines && std::getline(in, line); ++i) text += line + "\n";
  in.close();
  std::ofstream(path, std::ios::trunc) << text;
}

class CalibrationWorkerOutcome : public ::testing::Test {
 protected:
  test_support::ScopedTempDir tmp_{"worker-outcome"};
  db::history::SqliteRepository repo_{tmp_.sub("history.sqlite")};
  std::string archive_ = test_support::unpack_data_archive("soak-null-run", tmp_.path());
};

TEST_F(CalibrationWorkerOutcome, AnArchiveGoneFromTheDiskIsAStationFault) {
  fs::remove_all(archive_);
  const db::history::RunRecord r = calibrate_stored(repo_, archive_);
  EXPECT_EQ(r.verdict, db::history::RunVerdict::kStationFault) << r.failure_reason;
  EXPECT_EQ(r.failure_reason.rfind("archive: cannot read the run's archive: ", 0), 0u)
      << r.failure_reason;
  EXPECT_NE(r.failure_reason.find(archive_), std::string::npos) << "names the archive";
}

TEST_F(CalibrationWorkerOutcome, ACorruptArchiveIsAStationFault) {
  std::ofstream(archive_ + "/imu.csv", std::ios::app) << "0.5,not-a-number,1,2,3,4,5\n";
  const db::history::RunRecord r = calibrate_stored(repo_, archive_);
  EXPECT_EQ(r.verdict, db::history::RunVerdict::kStationFault) << r.failure_reason;
  EXPECT_NE(r.failure_reason.find("imu.csv"), std::string::npos) << r.failure_reason;
}

TEST_F(CalibrationWorkerOutcome, DataTheCalibrationRefusesAreTheUnitsFailure) {
  // A readable archive with 2 s of samples: no calibration can use it, and nothing of the
  // station's failed.
  truncate_lines(archive_ + "/imu.csv", 200);
  const db::history::RunRecord r = calibrate_stored(repo_, archive_);
  EXPECT_EQ(r.verdict, db::history::RunVerdict::kFailed) << r.failure_reason;
  EXPECT_EQ(r.failure_reason.rfind("calibration failed: ", 0), 0u) << r.failure_reason;
}

}  // namespace
}  // namespace imucal
