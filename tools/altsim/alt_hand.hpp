#pragma once
// altsim's rest_tremor: a hand holds the unit during the table's rests (the project's ARCHITECTURE
// §7, reproduced, not included). Per rest segment altsim draws its own hand from its own generator:
// per axis three tremor sinusoids of 6–11 Hz whose rate has the RMS rate_rms, two sway sinusoids of
// 0.3–1.2 Hz whose angle has the RMS tilt_rms, faded in and out by sin² over the rest's first and
// last quarter second, and a pivot pivot_m from the unit in a uniformly drawn direction. The hand
// turns the body by the rotation vector θ(t) (C_bn = C_bn_table exp([θ×])); altsim takes the
// hand's body rate from the quaternion's derivative, ω = 2 vec(q* ⊗ q̇), and its angular
// acceleration by differences of that rate, and moves the accelerometers about the pivot as a
// rigid body turning at the true body's rate w.r.t. inertial space (alt_sim.cpp).
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <vector>

#include "sequences/motion_profile.hpp"
#include "tools/altsim/alt_sim.hpp"

namespace imucal::tools::altsim {

/// The hand's rotation of the body at an instant: θ (nominal body -> true body, body axes), the
/// rate ω of the true body against the nominal one and its derivative, both in the true body.
struct HandPose {
  Eigen::Vector3d theta_rad = Eigen::Vector3d::Zero();
  Eigen::Vector3d w_b = Eigen::Vector3d::Zero(), wdot_b = Eigen::Vector3d::Zero();
};

class AltHand {
 public:
  /// No hand when the effect is off; `seed` the run's (a generator of its own is derived from it).
  AltHand(const sequences::MotionProfile& profile, const AltEffects& fx, uint64_t seed);
  bool active() const { return !rests_.empty(); }
  /// The hand at t in profile segment `segment` (no motion outside rests).
  HandPose at(size_t segment, double t_s) const;
  /// The accelerometers' position from the pivot in segment `segment`, body axes, m.
  Eigen::Vector3d pivot_to_unit_b(size_t segment) const;

 private:
  struct Sinusoid {
    double amp_rad = 0.0, w_radps = 0.0, phase_rad = 0.0;
  };
  struct Rest {
    double t0_s = 0.0, t1_s = 0.0;
    std::array<std::array<Sinusoid, 5>, 3> waves{};  ///< per axis: 3 tremor, 2 sway
    Eigen::Vector3d rho_b_m = Eigen::Vector3d::Zero();
  };
  /// θ and θ̇ at t of a rest.
  void angle(const Rest& r, double t_s, Eigen::Vector3d& th, Eigen::Vector3d& thdot) const;
  Eigen::Vector3d rate(const Rest& r, double t_s) const;
  std::vector<int> index_;  ///< per profile segment: its entry in rests_, or -1
  std::vector<Rest> rests_;
};

}  // namespace imucal::tools::altsim
