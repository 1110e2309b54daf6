#pragma once
// The project's conventions, written down once (ARCHITECTURE §3). Every other header relies on
// them.
//
// Frames
//   n  navigation frame, North-East-Down (NED), attached to the station on the WGS-84 ellipsoid.
//   b  body frame = IMU housing frame as fixed by the mounting fixture on the table platform.
//   p  table platform frame (moves with both table axes); t table base frame; i inertial frame.
//   C_bn means "b to n": y_n = C_bn * y_b. The inverse is C_nb = C_bn^T.
//
// Attitude errors (paper eq. 30, 33): an estimate Ĉ_bn relates to truth by Ĉ_bn = (I - [psi x])
// C_bn. Table misalignment ς (paper eq. 30-31): C_bn_true = exp([ς x]) * C_bn_table, where
// C_bn_table is what the table's encoder angles (or attitude.csv) say.
//
// IMU data are increments per sample, after coning/sculling compensation:
//   dtheta_k  rotation vector of the body attitude change w.r.t. inertial space over [t_{k-1}, t_k]
//   dv_k      = integral of C_{b(t)}^{b(t_{k-1})} f_b(t) dt, expressed in the body frame at the
//   *start*
//             of the interval (rotation and sculling compensated).
//   so the velocity update is  Δv_n = (I - ½[ω_in dt x]) C_bn(t_{k-1}) dv_k + (g_n - coriolis) dt.
//   A source delivering the raw integral ∫ f_b dt must be converted on import
//   (dv ≈ v_raw + ½ dθ × v_raw).
//
// Error model (paper eq. 18, 23), applied to increments exactly as to rates:
//   f~ = f + b_a + dM_a f        w~ = w + b_g + dM_g w
//   dv~ = dv + b_a dt + dM_a dv  dθ~ = dθ + b_g dt + dM_g dθ
//   dM are full 3x3: diagonal = scale-factor error, off-diagonal = misalignment.
//   Compensation: f = (I + dM_a)^-1 (f~ - b_a).
//
// Units: SI everywhere inside the code (rad, m/s, m/s^2, rad/s, s, m). Human-facing output converts
// (µg, deg/h, ppm, arcsec) and always carries the unit in the label.
// Names carry frame and unit: f_b, w_ib_b, C_bn, lat_rad, dt_s, g_mps2.

namespace imucal {

/// Standard gravity used only for unit conversions (µg, g), never as the local gravity.
constexpr double kStandardGravity_mps2 = 9.80665;
constexpr double kPi = 3.14159265358979323846;
constexpr double kDegToRad = kPi / 180.0;
constexpr double kRadToDeg = 180.0 / kPi;
constexpr double kArcsecToRad = kDegToRad / 3600.0;
constexpr double kDegPerHourToRadPerSec = kDegToRad / 3600.0;
constexpr double kMicroG_mps2 = 1e-6 * kStandardGravity_mps2;

}  // namespace imucal
