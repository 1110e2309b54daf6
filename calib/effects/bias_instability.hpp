#pragma once
// bias_instability (ARCHITECTURE §7) and the noise model's own Gauss-Markov terms: a first-order
// Gauss-Markov bias per axis (paper eq. 16-17), exact discretisation x_k = φ x_{k-1} + w_k,
// φ = exp(-dt/τ), var(w) = σ² (1 - φ²), x_0 ~ N(0, σ²) (stationary from the start).
#include <cmath>
#include <random>

#include "calib/core/rotation.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

struct GaussMarkov3 {
  double sigma = 0.0, phi = 0.0, drive = 0.0;
  Vec3<double> x = Vec3<double>::Zero();

  void init(double sigma_, double tau_s, double dt_s, std::mt19937_64& rng) {
    sigma = sigma_;
    if (sigma <= 0.0) return;
    phi = std::exp(-dt_s / tau_s);
    drive = sigma * std::sqrt(1.0 - phi * phi);
    std::normal_distribution<double> n(0.0, 1.0);
    for (int i = 0; i < 3; ++i) x(i) = sigma * n(rng);
  }
  void step(std::mt19937_64& rng) {
    if (sigma <= 0.0) return;
    std::normal_distribution<double> n(0.0, 1.0);
    for (int i = 0; i < 3; ++i) x(i) = phi * x(i) + drive * n(rng);
  }
  /// Correlation of the process between two instants |Δt| apart.
  static double correlation(double dt_s, double tau_s) { return std::exp(-std::abs(dt_s) / tau_s); }
};

}  // namespace imucal::calib::effects
