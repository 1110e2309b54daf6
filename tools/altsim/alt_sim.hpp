#pragma once
// altsim: an independent simulator of a factory table run (issue #22). It answers the same
// question as the project's truth simulator (calib/sim/) — what increments does a unit on a
// two-axis table deliver — but shares none of its code and differs in scheme, so that the gap
// diagnosis can be validated on data it was not built alongside:
//  * the body rate comes from the table's gimbal rates (alt_kinematics.hpp), not from the
//    attitude's endpoints;
//  * the attitude change over a sample is integrated numerically: RK4 on a quaternion, at
//    kSubsteps substeps per sample (each piece between profile breakpoints gets its own
//    substeps), dθ = rotation vector of the accumulated relative quaternion;
//  * dv = ∫ C_{b(t)}^{b(k-1)} f_b(t) dt by composite Simpson over the same substeps;
//  * the sensor effects evaluated at every substep node on the force and rate expressed in the
//    sample's start frame (the frame the error model acts in) and Simpson-integrated, where the
//    truth simulator evaluates them once at the interval's mean;
//  * noise from xoshiro256** / Marsaglia polar (alt_random.hpp), not <random>.
//
// Conventions (the project's ARCHITECTURE §3, reproduced, not included): n = NED, b = IMU housing,
// C_bn maps b to n. Increments: dθ_k = rotation vector of the body attitude change w.r.t.
// inertial space over [t_{k-1}, t_k]; dv_k in the body frame at t_{k-1}. Error model on the
// increments: dθ~ = dθ + b_g dt + M_g dθ, dv~ = dv + b_a dt + M_a dv. Table:
//   C_bn_table(outer, inner) = Rz(heading) R(a_outer, outer) R(a_inner, inner) C_bp
// and the true attitude C_bn = exp([ς×]) C_bn_table (ς: the table's reference frame against true
// NED). Everything SI.
//
// May include: Eigen and sequences/motion_profile.hpp only (tools/altsim/README.md).
#include <Eigen/Core>
#include <Eigen/Geometry>  // cross products
#include <array>
#include <cstdint>
#include <vector>

#include "sequences/motion_profile.hpp"

namespace imucal::tools::altsim {

constexpr double kPi = 3.14159265358979323846;
constexpr double kEarthRate_radps = 7.292115e-5;  ///< WGS-84

/// Where the table stands, as the station has it configured (the latitude_error and
/// gravity_error effects say how the truth differs).
struct AltSite {
  double lat_rad = 0.0;
  double gravity_mps2 = 9.81;  ///< local gravity magnitude (the survey value)
  double earth_rate_radps = kEarthRate_radps;
};

/// The two-axis table: the nominal geometry and the station's misalignment ς.
struct AltTable {
  Eigen::Vector3d outer_axis_t{1.0, 0.0, 0.0};         ///< outer axis in the base frame
  Eigen::Vector3d inner_axis_o{0.0, 0.0, 1.0};         ///< inner axis in the outer-gimbal frame
  double heading_rad = 0.0;                            ///< base frame: Rz(heading) from n
  Eigen::Matrix3d C_bp = Eigen::Matrix3d::Identity();  ///< fixture: body to platform
  Eigen::Vector3d misalignment_rad = Eigen::Vector3d::Zero();  ///< ς: C_bn = exp([ς×]) C_bn_table
};

/// The unit's calibration parameters (paper eq. 18, 23): M full 3x3, diagonal = scale-factor
/// error, off-diagonal = misalignment, row i = output axis i.
struct AltErrorModel {
  Eigen::Vector3d b_a_mps2 = Eigen::Vector3d::Zero();
  Eigen::Matrix3d M_a = Eigen::Matrix3d::Zero();
  Eigen::Vector3d b_g_radps = Eigen::Vector3d::Zero();
  Eigen::Matrix3d M_g = Eigen::Matrix3d::Zero();
};

/// The unit's declared stochastic model.
struct AltNoise {
  double arw_rad_per_sqrt_s = 0.0;
  double vrw_mps_per_sqrt_s = 0.0;
  double gyro_gm_sigma_radps = 0.0, gyro_gm_tau_s = 1000.0;   ///< Gauss-Markov bias, declared
  double accel_gm_sigma_mps2 = 0.0, accel_gm_tau_s = 1000.0;  ///< Gauss-Markov bias, declared
  double dtheta_lsb_rad = 0.0, dv_lsb_mps = 0.0;  ///< output resolution, 0 = unquantised
};

/// The effects catalogue's unmodelled physics (the project's ARCHITECTURE §7), SI, all off by
/// default. Each field is defined as the catalogue defines it:
struct AltEffects {
  /// accel_quadratic_k2: δf_i = K2_i f_i², 1/(m/s²).
  Eigen::Vector3d accel_k2_per_mps2 = Eigen::Vector3d::Zero();
  /// accel_asymmetry: δf_i = Kap_i |f_i|.
  Eigen::Vector3d accel_asym = Eigen::Vector3d::Zero();
  /// size_effect: accelerometer i sits at r_i (body axes, m, from the rotation centre) and senses
  /// component i of ω̇×r_i + ω×(ω×r_i) on top of the centre's specific force (ω = ω_ib, ω̇ its
  /// derivative: the point's acceleration w.r.t. inertial space).
  std::array<Eigen::Vector3d, 3> accel_lever_arm_m{Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
                                                   Eigen::Vector3d::Zero()};
  /// gyro_g_sensitivity: δω = G f, (rad/s)/(m/s²), row i = gyro i.
  Eigen::Matrix3d gyro_g_sens = Eigen::Matrix3d::Zero();
  /// gyro_accel_skew: δf = t_GA (ω × f), s.
  double gyro_accel_skew_s = 0.0;
  /// thermal_drift: b(t) = b + A exp(-t/τ), t from the start of the run.
  Eigen::Vector3d thermal_accel_mps2 = Eigen::Vector3d::Zero();
  Eigen::Vector3d thermal_gyro_radps = Eigen::Vector3d::Zero();
  double thermal_tau_s = 900.0;
  /// bias_instability: an undeclared first-order Gauss-Markov bias per axis (σ, τ).
  double instability_gyro_radps = 0.0, instability_accel_mps2 = 0.0;
  double instability_tau_s = 1000.0;
  /// quantisation: the real output LSBs, replacing the declared ones (0 = as declared).
  double quant_dtheta_rad = 0.0, quant_dv_mps = 0.0;
  /// output_filter: a first-order low-pass on the output before the register, per sensor: each
  /// output moves the fraction (1 - a) of the way from the previous output to the new input.
  double output_filter_gyro = 0.0, output_filter_accel = 0.0;
  /// rest_tremor: a hand holds the unit in the table's rests (alt_hand.hpp): the RMS rate per axis
  /// of its tremor, the RMS angle per axis of its sway, the distance from the unit to its pivot.
  double tremor_rate_rms_radps = 0.0, tremor_tilt_rms_rad = 0.0, tremor_pivot_m = 0.1;
  /// table_time_offset: the encoder log at IMU time t shows the angles of t - offset, s.
  double table_time_offset_s = 0.0;
  /// table_nonorthogonality: the inner axis leans by δ towards the outer axis (rotated about
  /// a_inner × a_outer in the outer-gimbal frame), rad.
  double table_nonorthogonality_rad = 0.0;
  /// table_wobble: the platform tilts against the outer gimbal by the rotation vector
  /// δ_o(inner) = R(a_inner, -inner) (w_x u1 + w_y u2), u1 = the outer axis' part perpendicular to
  /// the inner axis, u2 = a_inner × u1; the tilt sits between the outer and inner rotations, rad.
  Eigen::Vector2d table_wobble_rad = Eigen::Vector2d::Zero();
  /// gravity_error: true gravity = configured + dg, m/s².
  double gravity_error_mps2 = 0.0;
  /// latitude_error: true latitude = configured + dlat, rad.
  double latitude_error_rad = 0.0;
};

struct AltUnit {
  AltErrorModel errors;
  AltNoise noise;
  AltEffects effects;
};

struct AltOptions {
  double rate_hz = 100.0;
  uint64_t seed = 1;
  bool noise = true;  ///< false: deterministic (no white noise, Gauss-Markov or quantisation)
  int substeps = 8;   ///< RK4/Simpson substeps per sample piece (even, >= 8)
  /// A sample is flagged at rest only if it lies inside a rest segment this far from its ends
  /// (the station's convention: the estimators use the same epochs).
  double rest_guard_s = 0.5;
};

/// One output sample: the unit's increments over [t_s - dt_s, t_s] and the encoder log.
struct AltSample {
  double t_s = 0.0;
  double dt_s = 0.0;
  Eigen::Vector3d dtheta_rad = Eigen::Vector3d::Zero();
  Eigen::Vector3d dv_mps = Eigen::Vector3d::Zero();
  double outer_deg = 0.0, inner_deg = 0.0;  ///< as the encoder reads them (no table effects)
  bool at_rest = false;
};

/// Simulates the run of `profile` (t = 0 at its start, floor(duration · rate) samples). Pure:
/// safe to call from several threads at once. Throws std::invalid_argument on bad options.
std::vector<AltSample> simulate_alt(const sequences::MotionProfile& profile, const AltTable& table,
                                    const AltSite& site, const AltUnit& unit,
                                    const AltOptions& options);

}  // namespace imucal::tools::altsim
