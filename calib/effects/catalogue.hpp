#pragma once
// The effects catalogue (ARCHITECTURE §7): unmodelled physics that the truth simulator injects and
// the gap diagnosis hypothesises. One name per effect, used everywhere (unit files, truth.json,
// command lines, reports, JSON). Every effect has a flat parameter vector in SI units (EffectInfo
// lists its parameters with their human units and a typical navigation-grade magnitude); `Effects`
// holds the values of all of them in typed fields, and effect_vector()/set_effect_vector() convert
// between the two, so generic code (CLI parsing, truth.json, the diagnosis) and the physics (the
// forward models in calib/effects/*.hpp, shared by the simulator and the diagnosis) see the same
// numbers.
//
// Every field defaults to "off" (zero). An effect is active when any of its parameters is non-zero
// (shape parameters such as time constants do not count).
#include <Eigen/Core>
#include <array>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "calib/core/conventions.hpp"

namespace imucal::calib::effects {

enum class EffectId {
  kAccelQuadraticK2,
  kAccelAsymmetry,
  kSizeEffect,
  kGyroGSensitivity,
  kGyroAccelSkew,
  kTableTimeOffset,
  kThermalDrift,
  kBiasInstability,
  kTableNonorthogonality,
  kTableWobble,
  kGravityError,
  kLatitudeError,
  kQuantisation,
  kOutputFilter,
  kRestTremor,
};
constexpr int kNumEffects = 15;

/// Where an effect acts, which decides how the diagnosis can see it.
enum class EffectKind {
  kSensor,      ///< on the unit's increments, given its kinematics (deterministic)
  kTable,       ///< on the table's attitude or its encoder log
  kSite,        ///< on the Earth model the station assumes (gravity, latitude)
  kStochastic,  ///< a random process (estimated through its statistics, not a deterministic fit)
};

struct EffectParamInfo {
  std::string name;        ///< e.g. "k2_x" (unique within the effect)
  std::string si_unit;     ///< e.g. "1/(m/s^2)"
  std::string human_unit;  ///< e.g. "ug/g^2"
  double si_to_human;      ///< human = SI * si_to_human
  /// A shape parameter (a time constant) is not an amplitude: it does not make the effect active,
  /// is not fitted linearly (the diagnosis searches it on a grid) and does not enter the magnitude.
  bool shape = false;
};

struct EffectInfo {
  EffectId id;
  std::string name;  ///< the catalogue name, e.g. "accel_quadratic_k2"
  EffectKind kind;
  std::string model;      ///< the formula, one line
  std::string signature;  ///< how it shows in the data (ARCHITECTURE §7)
  std::vector<EffectParamInfo> params;
  /// A typical navigation-grade value of every parameter (SI, same order): the magnitude the
  /// catalogue quotes and the pattern (direction) used for detection thresholds.
  std::vector<double> typical;
  /// Parameters sharing the magnitude's unit: magnitude = Euclidean norm of these (human units).
  std::vector<int> magnitude_params;
  /// The largest magnitude (in magnitude_unit()) a unit of each grade — navigation, tactical, MEMS,
  /// calib/core/unit_grade.hpp's order — may physically have (issue #49): a lever arm is at most
  /// the unit's size and a gyro/accelerometer skew a few sample periods whatever the grade, a
  /// navigation unit's bias instability is its datasheet's. Infinity: no bound beyond the
  /// diagnosis' general rule (DiagnosisOptions::max_plausible_typical × the grade's effect scale).
  std::array<double, 3> plausible_max{kNoPlausibleBound, kNoPlausibleBound, kNoPlausibleBound};
  static constexpr double kNoPlausibleBound = std::numeric_limits<double>::infinity();
  int size() const { return static_cast<int>(params.size()); }
  /// The unit of magnitude() (the human unit of the magnitude parameters).
  const std::string& magnitude_unit() const;
  /// Norm of the magnitude parameters of an SI parameter vector, in magnitude_unit().
  double magnitude(const Eigen::VectorXd& si) const;
};

/// All 15 effects, in EffectId order.
const std::vector<EffectInfo>& effect_catalogue();
const EffectInfo& effect_info(EffectId id);
/// nullptr if the name is not in the catalogue.
const EffectInfo* find_effect(const std::string& name);
/// "accel_quadratic_k2, accel_asymmetry, ..." for error messages.
std::string effect_names_list();
/// "NAME,NAME,..." (as `--candidates` and `--effects` take it) to ids; empty text -> empty list.
/// Throws std::invalid_argument "unknown effect 'x' (known: ...)" or "no effect named".
std::vector<EffectId> parse_effect_list(const std::string& comma_separated);

/// The values of every effect, SI. Defaults: all off.
struct Effects {
  // --- sensor effects (calib/effects/*.hpp) ---
  /// accel_quadratic_k2: δf_i = K2_i f_i², in 1/(m/s²) (10 µg/g² ≈ 1.02e-6).
  Eigen::Vector3d accel_k2_per_mps2 = Eigen::Vector3d::Zero();
  /// accel_asymmetry: δf_i = Kap_i |f_i| (dimensionless).
  Eigen::Vector3d accel_asym = Eigen::Vector3d::Zero();
  /// size_effect: lever arm of accelerometer i from the rotation centre, body frame, m.
  std::array<Eigen::Vector3d, 3> accel_lever_arm_m{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
                                                   Eigen::Vector3d::Zero()};
  /// gyro_g_sensitivity: δω = G f, in (rad/s)/(m/s²).
  Eigen::Matrix3d gyro_g_sens = Eigen::Matrix3d::Zero();
  /// gyro_accel_skew: the accelerometers sample t_GA later than the gyros: δf = t_GA (ω × f), s.
  double gyro_accel_skew_s = 0.0;
  /// thermal_drift: warm-up of the biases, b(t) = b + A exp(-t/τ), t from the run's first sample.
  Eigen::Vector3d thermal_accel_mps2 = Eigen::Vector3d::Zero();
  Eigen::Vector3d thermal_gyro_radps = Eigen::Vector3d::Zero();
  double thermal_tau_s = 900.0;
  // --- stochastic ---
  /// bias_instability: first-order Gauss-Markov bias per axis (paper eq. 16-17), undeclared in
  /// the noise model. σ of the process and its correlation time.
  double instability_gyro_radps = 0.0;
  double instability_accel_mps2 = 0.0;
  double instability_tau_s = 1000.0;
  /// quantisation: the unit's real output LSBs (coarser than the noise model declares); 0 = off.
  double quant_dtheta_rad = 0.0;
  double quant_dv_mps = 0.0;
  /// output_filter: the first-order output filter's coefficient per sensor, y_k = a y_{k-1} +
  /// (1 - a) x_k, 0 <= a < 1 (calib/effects/output_filter.hpp); 0 = off.
  double output_filter_gyro = 0.0;
  double output_filter_accel = 0.0;
  /// rest_tremor: a hand holds the unit in its rests (calib/effects/rest_tremor.hpp): the RMS rate
  /// per axis of its tremor (6-11 Hz), the RMS angle per axis of its sway (0.3-1.2 Hz), and the
  /// distance from the unit to the pivot it turns the unit about (a shape parameter); 0 = off.
  double tremor_rate_rms_radps = 0.0;
  double tremor_tilt_rms_rad = 0.0;
  double tremor_pivot_m = 0.1;
  // --- table ---
  /// table_time_offset: the encoder log lags the IMU clock by this much, s.
  double table_time_offset_s = 0.0;
  /// table_nonorthogonality: the inner axis leans towards the outer axis by this angle (rad):
  /// inner axis in the outer-gimbal frame = Ry(δ) e_z, i.e. 90° - δ from the outer axis.
  double table_nonorthogonality_rad = 0.0;
  /// table_wobble: once-per-revolution tilt of the platform against the outer gimbal, rotation
  /// vector δ_o(inner) = Rz(-inner) (w_x, w_y, 0), rad (the part of a first-harmonic wobble that
  /// does not turn with the platform; the part that does is a fixed mounting rotation, absorbed by
  /// the misalignments).
  Eigen::Vector2d table_wobble_rad = Eigen::Vector2d::Zero();
  // --- site ---
  /// gravity_error: true local gravity minus the station's configured value, m/s².
  double gravity_error_mps2 = 0.0;
  /// latitude_error: true latitude minus the station's configured latitude, rad.
  double latitude_error_rad = 0.0;

  bool any() const;
  bool active(EffectId id) const;
  /// Names of the active effects, in catalogue order.
  std::vector<std::string> active_names() const;
  friend bool operator==(const Effects& a, const Effects& b);
};

/// The SI parameter vector of one effect (EffectInfo::params order).
Eigen::VectorXd effect_vector(const Effects& fx, EffectId id);
/// Set one effect from its SI parameter vector; throws std::invalid_argument naming the effect and
/// its parameters when the size is wrong, a value is not finite, or a shape parameter is not > 0.
void set_effect_vector(Effects& fx, EffectId id, const Eigen::VectorXd& si);

/// Parse "NAME=V[,V...]" (SI values in EffectInfo::params order), as given to `--effect`, and set
/// it in fx. A shape parameter may be left out at the end (it keeps its default). Throws
/// std::invalid_argument with a message naming the effect and listing its parameters and units, or
/// listing the catalogue names for an unknown effect.
void apply_effect_spec(Effects& fx, const std::string& spec);

}  // namespace imucal::calib::effects
