#pragma once
// A run's recorded series -> the methods' input (ARCHITECTURE §2.1, step 6): the reference attitude
// on the IMU time axis from the table model or an attitude log, the plausibility checks of the
// increments and of gravity at rest, the rest periods (the table's flags, or found in the IMU data
// for field runs, where the first must open the run), and a fixture slot's lever arm taken out of
// the accelerometers. Plain series in, CalibrationInput out: whoever read the series (the run
// archive, db/archive; a test; a simulator) names them in the errors through SeriesNames.
#include <Eigen/Core>
#include <cstddef>
#include <functional>
#include <stdexcept>
#include <string>
#include <vector>

#include "calib/core/calibration_input.hpp"
#include "calib/core/earth.hpp"
#include "calib/core/imu_increment.hpp"
#include "calib/core/noise_model.hpp"
#include "calib/core/table_model.hpp"
#include "calib/core/unit_grade.hpp"

namespace imucal::calib::input {
using namespace calib::core;

/// The attitude reference the series carry: the table's encoder log, an attitude log, or none
/// (land and sea runs).
enum class ReferenceKind { kTable, kAttitude, kNone };

/// One sample of an attitude log: body w.r.t. NED, ZYX Euler angles in rad.
struct AttitudeSample {
  double t_s = 0.0;
  double roll_rad = 0.0;
  double pitch_rad = 0.0;
  double yaw_rad = 0.0;
  bool at_rest = false;
};

/// Everything about a run but its series.
struct RunDescription {
  Setting setting = Setting::kFactory;
  Site site;
  double imu_rate_hz = 0.0;  ///< the declared sample rate, checked against the series' intervals
  NoiseModel noise;
  Grade grade = Grade::kNavigation;
  EnvelopeOverrides prior_overrides;
  double min_rest_s = 0.0;  ///< field runs: the shortest rest kept (0: the detector's default)
  /// Field runs: the first rest must last this long (0: the grade's rule, first_rest_rule).
  double first_rest_s = 0.0;
  ReferenceKind reference = ReferenceKind::kTable;
  TableGeometry table;  ///< factory runs with an encoder log: the model that turns angles into C_bn
  /// A unit mounted off the table's rotation centre (platform axes, m): taken out of the
  /// accelerometer increments while the table turns.
  Eigen::Vector3d lever_arm_p_m = Eigen::Vector3d::Zero();
};

/// The reference logs, read where they are (not copied): the one ReferenceKind names is used, on
/// the IMU time axis (one sample per IMU sample).
struct ReferenceLogs {
  const std::vector<TableSample>* table = nullptr;
  const std::vector<AttitudeSample>* attitude = nullptr;
};

/// How the caller's source calls what it handed over, so that an error says what to fix. The
/// defaults are generic; the run archive passes its file and column names (db/archive).
struct SeriesNames {
  std::string imu = "the IMU series";
  std::string reference = "the reference";
  std::string rate = "the declared IMU rate";  ///< where the rate was declared
  std::string rate_key = "the rate";           ///< the same, short
  std::string time = "the time";               ///< the series' time column
  std::string dv = "dv";                       ///< the velocity increments' columns
  std::string dtheta = "dtheta";               ///< the angle increments' columns
  std::string at_rest = "at_rest";             ///< the reference's rest flag
  std::string reference_choice = "a table log or an attitude log";
  /// IMU sample k (0-based), as the source numbers it (the archive: its line in imu.csv).
  std::function<std::string(std::size_t)> imu_sample = [](std::size_t k) {
    return "sample " + std::to_string(k);
  };
};

/// An input that cannot be built: what to fix, in which series, and at which sample.
class InputError : public std::runtime_error {
 public:
  /// kImu / kReference: the IMU series or the reference log (at `sample`, or as a whole);
  /// kRun: the run as a whole; kRate: the declared IMU rate.
  enum class Where { kImu, kReference, kRun, kRate };
  static constexpr std::size_t kNoSample = static_cast<std::size_t>(-1);
  InputError(Where where, std::string message, std::size_t sample = kNoSample)
      : std::runtime_error(message), where_(where), sample_(sample) {}
  Where where() const { return where_; }
  std::size_t sample() const { return sample_; }  ///< 0-based index into the series, or kNoSample

 private:
  Where where_;
  std::size_t sample_;
};

/// Field runs: what the first rest found in the IMU data must be (issue #48 item 2). A
/// navigation-grade unit levels and gyrocompasses on it: at least 20 s, beginning within 10 s of
/// the first sample (handling before the recording settles). A tactical or MEMS unit cannot find
/// north and only levels: its first still position of any length serves, wherever it begins (the
/// samples before it are not used). RunDescription::first_rest_s > 0 asks for a longer one.
struct FirstRestRule {
  double min_s = 0.0;           ///< the shortest first rest
  double latest_start_s = 0.0;  ///< how long after the first sample it may begin
};
FirstRestRule first_rest_rule(const RunDescription& run);
/// How far a reference sample's time may lie from its IMU sample's.
constexpr double kTimeMatchTolerance_s = 1e-6;

/// Build the calibration input. Land and sea (run.setting): no attitude reference is used, rest
/// periods come from the IMU data (calib/core/rest_detector.hpp) and the first must start the run;
/// at sea the GNSS fixes are passed on. Factory: the reference attitude on the IMU time axis (same
/// sample count, times within kTimeMatchTolerance_s — no interpolation), at least one rest sample,
/// a sample interval consistent with run.imu_rate_hz, plausible increment magnitudes (|dv|/dt <
/// 20 g, |dθ|/dt < 1000 °/s, mean |dv|/dt at rest within 10 % of local gravity, or the grade's
/// own tolerance), then the lever arm removed. Throws InputError.
CalibrationInput build_calibration_input(const RunDescription& run, const ImuSeries& imu,
                                         const ReferenceLogs& reference,
                                         const std::vector<GnssFix>& gnss,
                                         const SeriesNames& names = {});
/// The same input, bit for bit, taking the IMU series into the input instead of copying it (a
/// factory run; a field run copies it either way, so pass it as const there).
CalibrationInput build_calibration_input(const RunDescription& run, ImuSeries&& imu,
                                         const ReferenceLogs& reference,
                                         const std::vector<GnssFix>& gnss,
                                         const SeriesNames& names = {});

}  // namespace imucal::calib::input
