#pragma once
// A run archive's series handed to calib/input (calib/input/run_input.hpp), which builds the
// methods' input from them: the reference, the checks, the rest periods, the lever arm. Here only
// what the archive knows: which run.toml fields describe the run, what its files and columns are
// called, and which file and line an input error points at.
#include "calib/core/calibration_input.hpp"
#include "db/archive/run_archive.hpp"

namespace imucal::db::archive {

/// The calibration input of a run (calib/input/run_input.hpp builds it from the archive's series:
/// reference, checks, rest periods, lever arm). Its errors become ArchiveErrors naming the file
/// and line under archive.origin (imu.csv, table.csv or attitude.csv, run.toml's [imu] rate_hz).
calib::core::CalibrationInput to_calibration_input(const RunArchive& archive);
/// The same input, bit for bit, from an archive the caller no longer needs whole: a factory run's
/// IMU series is moved into the input (not copied) and its table/attitude samples are freed once
/// the reference is built, which saves a copy of the series and lowers the peak memory by about
/// a quarter. Afterwards `archive` keeps info, gnss, truth and origin; imu, table and attitude are
/// empty (land and sea runs: left as they were, the field input copies the series).
/// After an error the samples may be gone as well.
calib::core::CalibrationInput to_calibration_input(RunArchive&& archive);

}  // namespace imucal::db::archive
