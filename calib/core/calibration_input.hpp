#pragma once
// What every calibration method and the evaluation consume, and what the methods return.
// Built from a run archive (db/archive) or directly from the truth simulator; calib/ never reads
// files itself.
#include <Eigen/Core>
#include <array>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "calib/core/earth.hpp"
#include "calib/core/imu_increment.hpp"
#include "calib/core/noise_model.hpp"
#include "calib/core/param_set.hpp"
#include "calib/core/unit_grade.hpp"
#include "calib/core/unusable_span.hpp"

namespace imucal::calib::core {

/// Where a run was recorded, which decides the observations that exist (paper §IV-B/C/D):
///  * kFactory — a turntable: reference attitude (table.csv/attitude.csv), zero velocity at rest,
///    surveyed gravity;
///  * kLand — a customer site: no reference attitude, zero velocity and mean depth at rest
///    (rest found from the IMU data), normal gravity unless surveyed;
///  * kSea — a vessel: no reference attitude, no zero velocity, GNSS horizontal position and mean
///    depth (rest periods still found from the IMU data, for the initial alignment).
enum class Setting { kFactory, kLand, kSea };
/// "factory", "land", "sea".
const char* setting_name(Setting s);
/// The inverse of setting_name; nullopt for anything else.
std::optional<Setting> parse_setting(const std::string& name);

/// One GNSS position fix (gnss.csv): WGS-84 latitude/longitude of the unit and its 1-σ horizontal
/// noise (per axis, metres).
struct GnssFix {
  double t_s = 0.0;
  double lat_rad = 0.0;
  double lon_rad = 0.0;
  double sigma_m = 0.3;
};

/// Reference attitude for sample k (same time axis as the IMU): the table's C_bn (without ς) or
/// the attitude log's, and whether the unit is at rest.
struct ReferenceSample {
  double t_s = 0.0;
  Eigen::Matrix3d C_bn_ref = Eigen::Matrix3d::Identity();
  bool at_rest = false;
  /// The table's encoder angles behind C_bn_ref (NaN when the reference is an attitude log): the
  /// gap diagnosis needs them for the table effects (non-orthogonality, wobble).
  double outer_rad = std::numeric_limits<double>::quiet_NaN();
  double inner_rad = std::numeric_limits<double>::quiet_NaN();
};

struct CalibrationInput {
  Setting setting = Setting::kFactory;
  Site site;      ///< factory: surveyed; land: approximately known; sea: approximate (GNSS aids)
  ImuSeries imu;  ///< raw (uncompensated) increments
  /// Same length and times as imu. Factory: the reference attitude and the table's at_rest flag.
  /// Land/sea: at_rest only (from calib/core/rest_detector.hpp); C_bn_ref is identity and unused.
  std::vector<ReferenceSample> reference;
  std::vector<GnssFix> gnss;         ///< sea: position fixes inside the IMU's time span; else empty
  NoiseModel noise;                  ///< sensor noise spec (datasheet or unit file)
  Grade grade = Grade::kNavigation;  ///< the unit's grade: what may be assumed before its data
  EnvelopeOverrides prior_overrides;  ///< run.toml [prior] overrides of the grade's envelopes
  /// Field runs: clipped or dropped samples (calib/core/unusable_span.hpp), never inside a rest
  /// (at_rest is false there); each method leaves out the move that holds one and says so.
  /// Factory runs: empty (the data checks refuse a clipped or gapped table run as a whole).
  std::vector<UnusableSpan> unusable;

  /// The grade with its overrides: what the data checks, limits and the filter's prior assume.
  UnitPrior unit_prior() const { return {grade, prior_overrides}; }

  /// True when reference[].C_bn_ref is a real attitude reference (the factory setting).
  bool has_reference_attitude() const { return setting == Setting::kFactory; }
};

/// Half-open index range [begin, end) of one rest period in imu/reference.
struct RestPeriod {
  size_t begin = 0;
  size_t end = 0;
  size_t size() const { return end - begin; }
};

/// Maximal runs of at_rest samples with at least min_samples samples.
std::vector<RestPeriod> find_rest_periods(const CalibrationInput& in, size_t min_samples);

/// A rest as the multi-position methods average it: [begin, end) after trimming, and its middle.
struct TrimmedRest {
  size_t begin = 0, end = 0, mid = 0;
};

/// The rest periods of at least min_samples samples, each trimmed at both ends by trim_s or a
/// quarter of its length, whichever is less (the unit settling after a move, starting the next:
/// a hand-held position of 2 s keeps its middle second, a table's long rest loses trim_s), kept
/// when at least min_samples / 2 samples remain: the legacy fit's rests and the held-out check's.
std::vector<TrimmedRest> trimmed_rests(const CalibrationInput& in, size_t min_samples,
                                       double trim_s);

/// The raw mean angular rate over a rest period (rad/s): the gyro bias plus Earth rate there.
Eigen::Vector3d mean_rate_radps(const ImuSeries& imu, const RestPeriod& rest);

/// The gyros' common offset before any calibration: per axis the median of the rests' mean rates
/// (what a MEMS gyro's few °/s of bias make of every rest; zero when there is no rest).
Eigen::Vector3d median_rest_rate_radps(const ImuSeries& imu, const std::vector<RestPeriod>& rests);

/// The body frame a result's misalignments refer to.
///  * kHousing — the IMU housing (mounting fixture) frame: needs an orientation reference
///  (factory);
///  * kAccelSymmetric — the frame in which I + dM_a is symmetric (the accelerometer triad's own
///    orthogonal frame, polar decomposition; calib/core/body_frame.hpp). Used where the housing
///    orientation is not observable (land, sea, the legacy method): a common rotation of both
///    triads is then indistinguishable from a rotation of the unit.
enum class BodyFrame { kHousing, kAccelSymmetric };

struct CalibrationResult {
  std::string method;  ///< "ains", "nlsq" or "legacy"
  Setting setting = Setting::kFactory;
  BodyFrame body_frame = BodyFrame::kHousing;
  /// Parameters this result determines. false: not observable here (the table misalignment ς
  /// without a table; ...): the value is a placeholder (0) and must not be compared or stored as
  /// a finding. Default: all true.
  std::array<bool, ParamSet::kSize> observable = all_observable();
  /// Human-readable statements of what could not be determined and why (printed with the result).
  std::vector<std::string> unobservable_notes;
  ParamSet params;
  ParamSet sigma;  ///< 1-σ of each parameter (sqrt of cov diagonal)
  ParamCovariance cov = ParamCovariance::Zero();
  bool converged = false;
  int iterations = 0;
  double runtime_s = 0.0;
  std::vector<std::string> warnings;

  static std::array<bool, ParamSet::kSize> all_observable() {
    std::array<bool, ParamSet::kSize> a;
    a.fill(true);
    return a;
  }
};

/// The per-sample validity every method needs before it reads a sample: imu and reference of the
/// same length on the same time axis (within half a sample), each increment finite with dt_s > 0
/// and times increasing, and — where the setting has an attitude reference — each C_bn_ref a
/// finite rotation. Throws std::invalid_argument naming the first bad sample, prefixed with `who`
/// (the method's name as operators read it: "AINS: imu[12].dt_s must be finite and > 0").
void check_input_samples(const CalibrationInput& in, const std::string& who);

/// sigma from a covariance (sqrt of the diagonal, in ParamSet shape).
ParamSet sigma_from_covariance(const ParamCovariance& cov);

/// A land or sea run's input: no attitude reference, rest periods from the IMU data alone
/// (calib/core/rest_detector.hpp: `at_rest` per sample, C_bn_ref identity), GNSS fixes at sea.
/// `grade` chooses the rest detector: navigation grade the magnitude detector
/// (calib/core/rest_detector.hpp, as before the grades existed), the others the variation detector
/// that needs no calibration (calib/core/variation_rest_detector.hpp) with the grade's floors;
/// `min_rest_s` > 0 overrides the detector's shortest rest. Clipped and dropped samples are found
/// (`unusable`) and no rest holds one: a rest with one in it ends there and goes on after it.
CalibrationInput input_from_field_data(Setting setting, const ImuSeries& imu,
                                       const std::vector<GnssFix>& gnss, const Site& site,
                                       const NoiseModel& noise, Grade grade = Grade::kNavigation,
                                       double min_rest_s = 0.0);

}  // namespace imucal::calib::core
