#pragma once
// rest_tremor (ARCHITECTURE §7): the unit is held by a hand during its rests, not set down. A hand
// holding a unit "still" turns it by small angles θ_b(t) and carries it along:
//  * tremor: physiological tremor (4–12 Hz), per axis three sinusoids of 6–11 Hz drawn per rest
//    whose rate has the RMS rate_rms — the corpus' hand-held rests show 0.3–1.4 °/s of gyro
//    scatter against 0.1–0.2 °/s on the bench (docs/validation/corpus.md);
//  * sway: the hand leans the unit out and back, per axis two sinusoids of 0.3–1.2 Hz drawn per
//    rest whose angle has the RMS tilt_rms — the MPU-6050 recording's 0.2 s windows' mean rate
//    strays 1–2 °/s from the gyro offset;
//  * both turn the unit about the hand's pivot (the wrist), pivot_m from the unit in a direction
//    drawn per rest: the unit's origin moves with the rotation, so the accelerometers sense
//    ω̇ × ρ + ω × (ω × ρ) (ρ: the pivot to the accelerometer) besides gravity turned by θ.
// The motion fades in and out over the first and last quarter second of each rest (angle and rate
// zero at its ends, where the move takes over); the attitude is C_bn = C_bn_nominal exp([θ×]).
//
// What shows: the gyros see the rate; the accelerometers see gravity turned by the tilt,
// f_b = f̄_b + f̄_b × θ (horizontal components only), plus the pivot's acceleration. Unlike any
// sensor noise, the accelerometers' excursions within a rest follow the gyro-integrated tilt — the
// diagnosis' statistic (calib/diagnosis/rest_tremor_candidate.hpp). A rest's mean rate carries
// whatever net turn the hand made in it, and its mean specific force the mean tilt.
#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>
#include <vector>

#include "calib/core/conventions.hpp"
#include "calib/core/rotation.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

/// The catalogue's draw: tremor frequencies and sway frequencies (Hz), the fade at a rest's ends.
constexpr double kTremorMinHz = 6.0, kTremorMaxHz = 11.0;
constexpr double kSwayMinHz = 0.3, kSwayMaxHz = 1.2;
constexpr double kTremorFade_s = 0.25;

/// The right Jacobian of SO(3): the body rate of C exp([θ×]) is J_r(θ) θ̇ (C constant).
inline Eigen::Matrix3d so3_right_jacobian(const Eigen::Vector3d& theta) {
  const double a = theta.norm();
  const Eigen::Matrix3d K = skew<double>(theta);
  if (a < 1e-5) return Eigen::Matrix3d::Identity() - 0.5 * K + K * K / 6.0;
  return Eigen::Matrix3d::Identity() - (1.0 - std::cos(a)) / (a * a) * K +
         (a - std::sin(a)) / (a * a * a) * K * K;
}

/// One rest's hand motion (drawn once per rest, for a rest of duration_s). Default: no motion.
class RestTremorMotion {
 public:
  RestTremorMotion() = default;
  RestTremorMotion(double rate_rms_radps, double tilt_rms_rad, double pivot_m, double duration_s,
                   std::mt19937_64& rng)
      : T_s_(duration_s), fade_s_(std::min(kTremorFade_s, 0.25 * duration_s)) {
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    std::normal_distribution<double> n01(0.0, 1.0);
    for (int i = 0; i < 3; ++i) {
      // Three tremor sinusoids of rate amplitude R √(2/3): a mean-square rate R² per axis.
      for (Wave& w : tremor_[static_cast<size_t>(i)]) {
        w.w = 2.0 * kPi * (kTremorMinHz + (kTremorMaxHz - kTremorMinHz) * u01(rng));
        w.phase = 2.0 * kPi * u01(rng);
        w.amp = rate_rms_radps * std::sqrt(2.0 / 3.0) / w.w;
      }
      // Two sway sinusoids of angle amplitude S: a mean-square angle S² per axis.
      for (Wave& w : sway_[static_cast<size_t>(i)]) {
        w.w = 2.0 * kPi * (kSwayMinHz + (kSwayMaxHz - kSwayMinHz) * u01(rng));
        w.phase = 2.0 * kPi * u01(rng);
        w.amp = tilt_rms_rad;
      }
    }
    const Eigen::Vector3d u(n01(rng), n01(rng), n01(rng));
    rho_b_m_ = pivot_m * u.normalized();
  }

  double duration_s() const { return T_s_; }
  /// The unit's origin from the hand's pivot, body axes (fixed in the body), m.
  const Eigen::Vector3d& pivot_to_unit_b_m() const { return rho_b_m_; }

  /// The body's rotation against its nominal attitude τ after the rest began (0 outside it).
  Eigen::Vector3d angle_rad(double tau_s) const {
    Eigen::Vector3d th, dth;
    evaluate(tau_s, th, dth);
    return th;
  }
  /// The body rate of the motion (against the nominal attitude), rad/s: J_r(θ) θ̇.
  Eigen::Vector3d rate_b_radps(double tau_s) const {
    Eigen::Vector3d th, dth;
    evaluate(tau_s, th, dth);
    return so3_right_jacobian(th) * dth;
  }
  /// Its derivative by central differences over ±10 µs (exact to ~1e-9 of it at 11 Hz).
  Eigen::Vector3d rate_dot_b_radps2(double tau_s) const {
    constexpr double h = 1e-5;
    return (rate_b_radps(tau_s + h) - rate_b_radps(tau_s - h)) / (2.0 * h);
  }
  /// The hand's specific force on accelerometer i at lever arm r_i from the unit's origin
  /// (calib/effects/size_effect.hpp), component i of ω̇ × ρ_i + ω × (ω × ρ_i), ρ_i = ρ + r_i.
  Eigen::Vector3d specific_force_b_mps2(double tau_s,
                                        const std::array<Eigen::Vector3d, 3>& lever_m) const {
    const Eigen::Vector3d w = rate_b_radps(tau_s), wdot = rate_dot_b_radps2(tau_s);
    Eigen::Vector3d f;
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector3d rho = rho_b_m_ + lever_m[static_cast<size_t>(i)];
      f(i) = (wdot.cross(rho) + w.cross(w.cross(rho)))(i);
    }
    return f;
  }

 private:
  struct Wave {
    double amp = 0.0, w = 0.0, phase = 0.0;
  };
  /// The fade in and out: sin² over fade_s_ at each end, 1 between (zero slope at both ends).
  void fade(double tau_s, double& g, double& dg) const {
    g = 1.0;
    dg = 0.0;
    const double x = std::min(tau_s, T_s_ - tau_s);
    if (x >= fade_s_) return;
    const double a = 0.5 * kPi * x / fade_s_;
    g = std::sin(a) * std::sin(a);
    dg = (tau_s < T_s_ - tau_s ? 1.0 : -1.0) * std::sin(2.0 * a) * 0.5 * kPi / fade_s_;
  }
  void evaluate(double tau_s, Eigen::Vector3d& th, Eigen::Vector3d& dth) const {
    th.setZero();
    dth.setZero();
    if (!(tau_s > 0.0 && tau_s < T_s_)) return;
    double g, dg;
    fade(tau_s, g, dg);
    for (int i = 0; i < 3; ++i) {
      double a = 0.0, da = 0.0;
      auto add = [&](const Wave& w) {
        a += w.amp * std::sin(w.w * tau_s + w.phase);
        da += w.amp * w.w * std::cos(w.w * tau_s + w.phase);
      };
      for (const Wave& w : tremor_[static_cast<size_t>(i)]) add(w);
      for (const Wave& w : sway_[static_cast<size_t>(i)]) add(w);
      th(i) = g * a;
      dth(i) = dg * a + g * da;
    }
  }

  double T_s_ = 0.0, fade_s_ = kTremorFade_s;
  std::array<std::array<Wave, 3>, 3> tremor_{};
  std::array<std::array<Wave, 2>, 3> sway_{};
  Eigen::Vector3d rho_b_m_ = Eigen::Vector3d::Zero();
};

/// The hand's motion in each segment of a run: one per entry of `rest_durations_s` (a rest's
/// duration, or 0 for a segment that is no rest: no motion). Drawn from a generator of its own,
/// seeded by the run's seed, so a run with the effect draws the same sensor noise as without it.
inline std::vector<RestTremorMotion> draw_rest_tremor(double rate_rms_radps, double tilt_rms_rad,
                                                      double pivot_m,
                                                      const std::vector<double>& rest_durations_s,
                                                      uint64_t seed) {
  std::vector<RestTremorMotion> out(rest_durations_s.size());
  if (rate_rms_radps == 0.0 && tilt_rms_rad == 0.0) return out;
  std::mt19937_64 rng(seed * 0xD1B54A32D192ED03ULL + 0x7E30);
  for (size_t i = 0; i < out.size(); ++i)
    if (rest_durations_s[i] > 0.0)
      out[i] = RestTremorMotion(rate_rms_radps, tilt_rms_rad, pivot_m, rest_durations_s[i], rng);
  return out;
}

}  // namespace imucal::calib::effects
