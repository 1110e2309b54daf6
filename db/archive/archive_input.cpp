#include "db/archive/archive_input.hpp"

#include <string>
#include <utility>
#include <vector>

#include "calib/input/run_input.hpp"
#include "db/archive/archive_error.hpp"
#include "db/archive/csv.hpp"
#include "db/archive/io_util.hpp"

namespace imucal::db::archive {

namespace {

/// A file of the archive directory `dir`, as the reader names it.
std::string file_in(const std::string& dir, const char* name) {
  if (dir.empty()) return name;
  return dir.back() == '/' ? dir + name : dir + "/" + name;
}

/// The run's description as calib/input takes it, from run.toml.
calib::input::RunDescription run_description(const RunInfo& info) {
  calib::input::RunDescription run;
  run.setting = info.setting;
  run.site = info.site;
  run.imu_rate_hz = info.imu_rate_hz;
  run.noise = calib::core::NoiseModel{};
  run.noise.arw_rad_per_sqrt_s = info.arw_rad_per_sqrt_s;
  run.noise.vrw_mps_per_sqrt_s = info.vrw_mps_per_sqrt_s;
  run.noise.dtheta_lsb_rad = info.dtheta_lsb_rad;
  run.noise.dv_lsb_mps = info.dv_lsb_mps;
  run.noise.lsb_rounding = info.lsb_rounding;
  run.grade = info.grade;
  run.prior_overrides = info.prior_overrides;
  run.min_rest_s = info.min_rest_s;
  run.first_rest_s = info.first_rest_s;
  run.reference = info.reference;
  run.table = info.table.geometry();
  run.lever_arm_p_m = info.table.lever_arm_m;
  return run;
}

/// The archive's files and columns, for calib/input's errors.
calib::input::SeriesNames series_names(const RunArchive& a) {
  calib::input::SeriesNames names;
  names.imu = "imu.csv";
  names.reference = a.info.reference == ReferenceKind::kAttitude ? "attitude.csv" : "table.csv";
  names.rate = "run.toml [imu] rate_hz";
  names.rate_key = "rate_hz";
  names.time = "t_s";
  names.dv = "dv_*_mps";
  names.dtheta = "dtheta_*_rad";
  names.at_rest = "at_rest";
  names.reference_choice = "table.csv or attitude.csv";
  names.imu_sample = [](std::size_t k) {
    return "imu.csv line " + std::to_string(CsvTable::line_of_row(k));
  };
  return names;
}

/// calib/input's error as the file (and line) a user must fix.
[[noreturn]] void rethrow_as_archive_error(const calib::input::InputError& e, const RunArchive& a,
                                           const calib::input::SeriesNames& names) {
  using Where = calib::input::InputError::Where;
  const bool at_sample = e.sample() != calib::input::InputError::kNoSample;
  const size_t line = at_sample ? CsvTable::line_of_row(e.sample()) : 0;
  switch (e.where()) {
    case Where::kImu:
      throw ArchiveError(file_in(a.origin, "imu.csv"), line, e.what());
    case Where::kReference:
      throw ArchiveError(file_in(a.origin, names.reference.c_str()), line, e.what());
    case Where::kRate:
      throw ArchiveError::field_error(file_in(a.origin, "run.toml"), "imu.rate_hz", e.what());
    case Where::kRun:
      break;
  }
  throw ArchiveError(a.origin, e.what());
}

/// Both overloads: `owned` is the archive itself when the caller gave it up (a factory run's IMU
/// series then moves into the input and its reference samples are freed once the input is built).
calib::core::CalibrationInput convert(const RunArchive& a, RunArchive* owned) {
  const calib::input::SeriesNames names = series_names(a);
  const calib::input::ReferenceLogs logs{&a.table, &a.attitude};
  try {
    if (owned && a.info.setting == calib::core::Setting::kFactory) {
      calib::core::CalibrationInput in = calib::input::build_calibration_input(
          run_description(a.info), std::move(owned->imu), logs, a.gnss, names);
      std::vector<calib::core::TableSample>().swap(owned->table);
      std::vector<AttitudeSample>().swap(owned->attitude);
      return in;
    }
    return calib::input::build_calibration_input(run_description(a.info), a.imu, logs, a.gnss,
                                                 names);
  } catch (const calib::input::InputError& e) {
    rethrow_as_archive_error(e, a, names);
  }
}

}  // namespace

calib::core::CalibrationInput to_calibration_input(const RunArchive& a) {
  return convert(a, nullptr);
}

calib::core::CalibrationInput to_calibration_input(RunArchive&& a) { return convert(a, &a); }

}  // namespace imucal::db::archive
