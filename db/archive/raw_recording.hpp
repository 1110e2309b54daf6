#pragma once
// A raw IMU recording as it comes (issue #21 item 5): text columns of time and three gyro and
// three accelerometer channels — one file, or one per sensor (time + x, y, z each) — separated by
// commas, semicolons, tabs or spaces, in counts or in SI, as rates or as increments. What
// `imucal import` turns into a run archive.
//
// Reading: lines starting with '#' or '%' and blank lines are skipped; the first other line may
// be a header (it is, if any of its cells is not a number); every later cell must be a finite
// decimal number, and a bad one is an ArchiveError naming the file, line and column.
//
// Time: a fixed-rate sensor's samples stamped by a host clock with jitter. The period is the
// least-squares slope of the stamps against the sample index, and each sample is re-stamped onto
// that uniform grid (t_k = t_0 + k·T). Nothing is interpolated: the samples are the sensor's, only
// their stamps are the host's. Rates become increments over the grid's period (rate·T); given
// increments are kept. A stamp farther than half a period from the grid is a gap (dropped
// samples) or a clock jump, and is refused naming its line: the importer does not invent data.
// The report says how far the stamps were from the grid (RMS and worst).
#include <Eigen/Core>
#include <string>
#include <vector>

#include "calib/core/imu_increment.hpp"

namespace imucal::db::archive {

/// SI value = (raw - offset) * scale, per axis.
struct RawAxisScale {
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();
  Eigen::Vector3d offset = Eigen::Vector3d::Zero();
};

enum class RawQuantity { kRates, kIncrements };

struct RawImportOptions {
  /// One file: the meaning of each column, in order — "t", "gx", "gy", "gz", "ax", "ay", "az",
  /// or "-" for a column to ignore. Each of the seven names exactly once.
  std::vector<std::string> columns = {"t", "gx", "gy", "gz", "ax", "ay", "az"};
  double seconds_per_time_unit = 1.0;
  RawQuantity quantity = RawQuantity::kRates;  ///< rad/s, m/s² (or rad, m/s) after scaling
  RawAxisScale gyro, accel;
};

struct RawRecording {
  calib::core::ImuSeries imu;  ///< on the uniform grid, t from 0 at the first sample
  double rate_hz = 0.0;
  double jitter_rms_s = 0.0;  ///< host stamps about the grid
  double jitter_max_s = 0.0;
  std::size_t header_lines = 0;  ///< 0 or 1 per file
};

/// One file with every channel (options.columns says which is which).
RawRecording read_raw_recording(const std::string& path, const RawImportOptions& options);

/// As read_raw_recording, from text in memory; `origin` names it in errors (the fuzz target's
/// entry).
RawRecording parse_raw_recording(const std::string& text, const std::string& origin,
                                 const RawImportOptions& options);

/// One file per sensor, each "time x y z"; the two must have the same rows at the same times
/// (within half a period). options.columns is not used.
RawRecording read_raw_recording_pair(const std::string& gyro_path, const std::string& accel_path,
                                     const RawImportOptions& options);

/// Parse a column list "t,gx,gy,gz,ax,ay,az" (commas) and check it; std::invalid_argument naming
/// what is wrong.
std::vector<std::string> parse_raw_columns(const std::string& text);

}  // namespace imucal::db::archive
