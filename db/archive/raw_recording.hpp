#pragma once
// A raw IMU recording as it comes (issue #21 item 5): text columns of time and three gyro and
// three accelerometer channels — one file, or one per sensor (time + x, y, z each) — separated by
// commas, semicolons, tabs or spaces, in counts or in SI, as rates or as increments. What
// `imucal import` turns into a run archive.
//
// Reading, as loggers write (issue #48 item 4): lines starting with '#' or '%' and blank lines are
// skipped, and the first `skip_lines` lines whatever they hold. Before the first data row (every
// cell a finite decimal number) may stand a preamble — lines of another cell count, such as a
// logger's "key,value" lines — and header lines whose cells are all text; they are skipped and
// counted. A line with the data's cell count and some but not all cells numbers is a bad data row,
// wherever it stands: an ArchiveError naming the file, line and column. Cells are separated by
// commas, semicolons, tabs or spaces; a line with semicolons is split at them alone, and its cells
// may carry a decimal comma ("9,81").
//
// Columns: given (`columns`), or else read from a header whose names are recognisable (t, time,
// timestamp; gx, gyro_x, wx, ...; ax, acc_x, accel_x, ...; a unit suffix such as "_dps" or
// " [g]" is ignored; other names are columns to ignore), or else t,gx,gy,gz,ax,ay,az. A
// recognisable header that contradicts the given columns is an error naming both: header names
// are never silently overruled. A recording without a time column takes its sample rate
// (`rate_hz`): sample k at k / rate_hz.
//
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
  /// or "-" for a column to ignore; each sensor name exactly once, "t" at most once (without it,
  /// rate_hz). Empty: from a recognisable header, else t,gx,gy,gz,ax,ay,az.
  std::vector<std::string> columns;
  double seconds_per_time_unit = 1.0;
  /// The sensor's sample rate, Hz: required without a time column; with one, the stamps' rate
  /// must agree within 2 %.
  double rate_hz = 0.0;
  std::size_t skip_lines = 0;  ///< lines skipped at the top of each file, whatever they hold
  RawQuantity quantity = RawQuantity::kRates;  ///< rad/s, m/s² (or rad, m/s) after scaling
  RawAxisScale gyro, accel;
  /// Refuse any irregular time stamp (as the daemon's own captures must be). Without it a logger's
  /// habits are taken as they come: a row repeated verbatim (same stamp, same values) is dropped,
  /// and a dropped-sample gap (a step over 1.5 × the typical one) is kept as a gap on the grid —
  /// the calibration leaves out the move or the part of a rest it falls in
  /// (calib/core/unusable_span.hpp). One file per sensor: repeated stamps are always refused.
  bool strict_time = false;
};

struct RawRecording {
  calib::core::ImuSeries imu;  ///< on the uniform grid, t from 0 at the first sample
  double rate_hz = 0.0;
  double jitter_rms_s = 0.0;  ///< host stamps about the grid
  double jitter_max_s = 0.0;
  std::size_t header_lines = 0;  ///< lines before the data skipped (preamble, header), all files
  std::vector<std::string> columns;  ///< one file: the columns used
  std::string columns_from;          ///< "given", "header" or "default" (one file)
  bool decimal_comma = false;        ///< some cell was read with a decimal comma
  std::size_t repeated_rows = 0;     ///< rows dropped as verbatim repeats of the one before
  std::size_t gaps = 0;              ///< dropped-sample gaps kept on the grid
  std::size_t samples_missing = 0;   ///< samples those gaps lack, in all
  /// One raw unit as an increment where every raw value of a sensor's three columns is a whole
  /// number (counts): |scale| × the grid's period for rates (the factor they were integrated
  /// with), |scale| for increments, the coarsest axis's. 0 where a value has a fraction: a decimal
  /// reading's resolution is not known.
  double dtheta_count_rad = 0.0, dv_count_mps = 0.0;
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
