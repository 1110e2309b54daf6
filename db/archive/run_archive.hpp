#pragma once
// The run archive (ARCHITECTURE §5): the interchange format every tool reads and through which data
// from other stations and simulators enter. A run is a directory:
//   run.toml                  RunInfo (below)
//   imu.csv t_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps[,temp_c]
//   table.csv                 t_s,outer_deg,inner_deg,at_rest              (encoder log)
//   or attitude.csv           t_s,roll_deg,pitch_deg,yaw_deg,at_rest       (NED, ZYX, body w.r.t.
//   n) gnss.csv              t_s,lat_deg,lon_deg,sigma_m   (GNSS position fixes; required at sea)
//   truth.json                (simulated runs only) injected parameters, effect names, noise
//   capture.log               (daemon runs only) raw CAN frames; not interpreted here
// Full rules (columns, keys, units, checks): db/archive/FORMAT.md.
#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "calib/core/calibration_input.hpp"
#include "calib/core/earth.hpp"
#include "calib/core/imu_increment.hpp"
#include "calib/core/table_model.hpp"
#include "calib/input/run_input.hpp"
#include "db/archive/unit_file.hpp"

namespace imucal::db::archive {

/// Table geometry as run.toml states it ([table] section). Kept in the file's own terms (axes,
/// heading, fixture Euler angles) so that write-then-read is exact; geometry() builds the
/// calib::core::TableGeometry.
struct TableSetup {
  /// Defaults follow calib::core::TableGeometry{} (the station's table).
  Eigen::Vector3d outer_axis_t =
      calib::core::TableGeometry{}.outer_axis_t;  ///< in the base frame, unit
  Eigen::Vector3d inner_axis_o =
      calib::core::TableGeometry{}.inner_axis_o;                  ///< in the outer-gimbal frame
  double heading_rad = calib::core::TableGeometry{}.heading_rad;  ///< C_tn = Rz(heading)
  Eigen::Vector3d mount_rpy_rad =
      Eigen::Vector3d::Zero();  ///< fixture C_bp = euler_to_C_bn(r, p, y)
  /// slot (optional): the fixture position of a station that holds several units (issue #23).
  std::string slot;
  /// lever_arm_m (optional, platform axes, m): the unit's centre from the table's rotation centre.
  /// A rigid offset senses ω×(ω×r) + ω̇×r while the table turns; calib/input takes it out
  /// of the accelerometer increments before any method sees them.
  Eigen::Vector3d lever_arm_m = Eigen::Vector3d::Zero();

  calib::core::TableGeometry geometry() const;
  /// From a geometry (C_bp decomposed into ZYX Euler angles; exact to round-off).
  static TableSetup from_geometry(const calib::core::TableGeometry& g);
};

/// The attitude reference file of a run: table.csv (kTable), attitude.csv (kAttitude), or none
/// (kNone: land and sea runs) — calib/input's reference kinds.
using ReferenceKind = calib::input::ReferenceKind;

/// run.toml [capture] (daemon runs only): how the live capture went. The counters have the names
/// and meanings of station::run::CaptureStats (station/run/capture_stats.hpp); this copy keeps the
/// archive library independent of the daemon.
struct CaptureInfo {
  /// true: the capture ended normally (the daemon finished the archive). false: the archive was
  /// cut short (aborted, failed) or recovered after the daemon died; a recovered archive's counters
  /// are recounted from its files (FORMAT.md), samples_filled and rx_overflow then 0 (unknown).
  bool complete = false;
  uint64_t frames_received = 0, frames_logged = 0;
  uint64_t frames_foreign = 0, frames_error = 0, frames_malformed = 0, frames_duplicate = 0,
           frames_out_of_order = 0, frames_discarded = 0, rx_overflow = 0;
  uint64_t samples_decoded = 0, samples_lost = 0, samples_corrupt = 0, samples_incomplete = 0,
           samples_late = 0;
  uint64_t samples_filled = 0;
  uint64_t max_gap_samples = 0;
  uint64_t imu_resets = 0;
  uint64_t rows_written = 0;
  uint64_t rest_samples = 0;

  /// Every counter's run.toml key and member, in file order (the one list the reader, the writer
  /// and station/capture_stats use).
  static const std::vector<std::pair<const char*, uint64_t CaptureInfo::*>>& counters();
  friend bool operator==(const CaptureInfo& a, const CaptureInfo& b);
  friend bool operator!=(const CaptureInfo& a, const CaptureInfo& b) { return !(a == b); }
};

/// run.toml.
struct RunInfo {
  std::string serial;  ///< required
  /// setting: factory (default), land or sea — which observations the run has (FORMAT.md).
  calib::core::Setting setting = calib::core::Setting::kFactory;
  std::string station_name;
  calib::core::Site site;  ///< [station] lat_deg, lon_deg, height_m required; gravity_mps2 optional
  double imu_rate_hz = 0.0;  ///< [imu] rate_hz, required
  /// [imu] protocol, optional: the name of the unit's CAN protocol the station read it through
  /// (drivers/imu/PROTOCOL.md; "imucal-imu-1" is the built-in one).
  std::string imu_protocol;
  TableSetup table;             ///< [table], all keys optional (defaults above)
  std::string sequence_name;    ///< [sequence] name
  std::string sequence_sha256;  ///< [sequence] sha256: 64 hex digits or empty
  std::string software_version;
  std::string start_time;  ///< ISO 8601, empty if unknown
  std::string end_time;
  ReferenceKind reference = ReferenceKind::kTable;  ///< must match the reference file present
  /// [noise] used to weight the estimators; defaults = calib::core::NoiseModel{} (ARCHITECTURE §7).
  double arw_rad_per_sqrt_s = calib::core::NoiseModel{}.arw_rad_per_sqrt_s;
  double vrw_mps_per_sqrt_s = calib::core::NoiseModel{}.vrw_mps_per_sqrt_s;
  /// [noise] dtheta_lsb_rad, dv_lsb_mps: the resolution of one sample's increments as the unit's
  /// protocol carries them (written by the daemon when they differ from the built-in protocol's
  /// 1e-9 rad and 1e-7 m/s); the gap diagnosis models the quantisation with them.
  double dtheta_lsb_rad = calib::core::NoiseModel{}.dtheta_lsb_rad;
  double dv_lsb_mps = calib::core::NoiseModel{}.dv_lsb_mps;
  /// [noise] lsb_rounding: "carried" (default: an output register's, the station's protocol) or
  /// "per_sample" (a logger of counts, written by `imucal import`); calib/core/noise_model.hpp.
  calib::core::LsbRounding lsb_rounding = calib::core::LsbRounding::kCarried;
  /// [prior] grade: what the unit is expected to be (calib/core/unit_grade.hpp); navigation by
  /// default. Chooses the field runs' rest detector so far (issue #21).
  calib::core::Grade grade = calib::core::Grade::kNavigation;
  /// [prior] min_rest_s: the shortest rest the field runs' detector keeps (0: its default).
  double min_rest_s = 0.0;
  /// [prior] first_rest_s: field runs' first rest must last this long (0: the grade's rule —
  /// navigation 20 s within the first 10 s, tactical and MEMS any length anywhere).
  double first_rest_s = 0.0;
  /// [prior] gyro_bias_deg_per_s, accel_bias_mg, scale_ppm, misalignment_mrad: overrides of the
  /// grade's envelopes (a product whose datasheet differs from its class's).
  calib::core::EnvelopeOverrides prior_overrides;
  /// [capture], optional: written by the daemon when it finishes (or recovers) the archive.
  std::optional<CaptureInfo> capture;
};

/// attitude.csv row (angles converted to rad): calib/input's attitude-log sample.
using AttitudeSample = calib::input::AttitudeSample;

struct RunArchive {
  RunInfo info;
  calib::core::ImuSeries imu;                   ///< temp_c = NaN when imu.csv has no temp_c column
  std::vector<calib::core::TableSample> table;  ///< non-empty iff info.reference == kTable
  std::vector<AttitudeSample> attitude;         ///< non-empty iff info.reference == kAttitude
  std::vector<calib::core::GnssFix> gnss;       ///< gnss.csv (required at sea), angles in rad
  std::optional<Truth> truth;
  std::string
      origin;  ///< directory it was read from (names files in later errors); "" if in memory
};

/// The IMU data's span, s: from the start of the first sample's interval to the last sample (0
/// without samples). What an archive's recording lasted.
double data_span_s(const RunArchive& archive);

/// Read and validate an archive directory. Every format error is an ArchiveError naming the file
/// and line/field. With run.toml [imu] dv_convention = "raw_integral" the dv columns are converted
/// on reading (dv = v_raw + ½ dθ × v_raw); in memory dv always follows conventions.hpp.
RunArchive read_archive(const std::string& dir);

/// Write an archive atomically: everything goes to "<dir>.tmp-XXXXXX" (fsync'd), then one rename
/// makes it appear. An existing non-empty `dir` is refused unless overwrite (then swapped out
/// atomically and removed). On any error the temporary directory is removed and `dir` is untouched.
void write_archive(const std::string& dir, const RunArchive& archive, bool overwrite = false);

/// What write_archive refuses as the archive's place, checked on its own so that a tool can refuse
/// before any work: a non-directory, or a non-empty directory unless `overwrite`. The message ends
/// with `how_to_replace`.
void check_archive_target(const std::string& dir, bool overwrite,
                          const std::string& how_to_replace = "remove it first");

/// Parse / produce run.toml text.
RunInfo parse_run_info(const std::string& text, const std::string& origin);
std::string run_info_text(const RunInfo& info);

/// IMU time axis tolerance between imu.csv and the reference file (calib/input's).
using calib::input::kTimeMatchTolerance_s;

}  // namespace imucal::db::archive
