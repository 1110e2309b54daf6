#pragma once
// What stationd does when a capture ends, for tests that calibrate an archive as the station
// does: a run created calibrating in the history, then the calibration worker's job on its archive
// (station/run/calibration_worker.hpp), in this thread.
#include <string>

#include "db/history/repository.hpp"
#include "station/run/calibration_worker.hpp"

namespace imucal::test_support {

/// The outcome of the station's calibration job on the archive at `dir`, for a factory-std run of
/// `serial` at `station` that `repo` records.
inline station::run::CalibrationOutcome calibrate_as_the_station(db::history::Repository& repo,
                                                                 const std::string& serial,
                                                                 const std::string& station,
                                                                 const std::string& dir) {
  db::history::NewRun nr;
  nr.serial = serial;
  nr.operator_name = "test";
  nr.station = station;
  nr.sequence_name = "factory-std";
  nr.software_version = "test";
  nr.started_at_ms = 1714560000000;
  nr.archive_path = dir;
  nr.state = db::history::RunState::kCalibrating;
  station::run::CalibrationJob job;
  job.run_id = repo.create_run(nr);
  job.archive_dir = dir;
  return station::run::run_calibration_job(repo, job);
}

}  // namespace imucal::test_support
