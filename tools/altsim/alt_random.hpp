#pragma once
// altsim's own noise source, deliberately unlike the truth simulator's (std::mt19937_64 with
// std::normal_distribution): xoshiro256** seeded through splitmix64, normal deviates by the
// Marsaglia polar method, and a first-order Gauss-Markov process on top of them. Written here
// from the published algorithms so that a defect in one generator cannot hide in both simulators.
#include <array>
#include <cmath>
#include <cstdint>

namespace imucal::tools::altsim {

/// splitmix64: turns one 64-bit seed into a well-mixed sequence (used only to fill xoshiro's
/// state, which must not be all zero and should not be correlated between nearby seeds).
inline uint64_t splitmix64_next(uint64_t& state) {
  uint64_t z = (state += 0x9e3779b97f4a7c15ULL);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

/// xoshiro256** (Blackman & Vigna): 256-bit state, period 2^256 - 1.
class Xoshiro256ss {
 public:
  explicit Xoshiro256ss(uint64_t seed) {
    uint64_t sm = seed;
    for (uint64_t& w : s_) w = splitmix64_next(sm);
  }
  uint64_t next() {
    const uint64_t result = rotl(s_[1] * 5, 7) * 9;
    const uint64_t t = s_[1] << 17;
    s_[2] ^= s_[0];
    s_[3] ^= s_[1];
    s_[1] ^= s_[2];
    s_[0] ^= s_[3];
    s_[2] ^= t;
    s_[3] = rotl(s_[3], 45);
    return result;
  }
  /// Uniform on [0, 1) with 53 random bits (the top bits: xoshiro's low bits are its weakest).
  double uniform01() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }

 private:
  static uint64_t rotl(uint64_t x, int k) { return (x << k) | (x >> (64 - k)); }
  std::array<uint64_t, 4> s_{};
};

/// Standard normal deviates by the Marsaglia polar method: each accepted pair of uniforms in the
/// unit disc yields two independent normals; the second is kept for the next call.
class PolarNormal {
 public:
  explicit PolarNormal(uint64_t seed) : rng_(seed) {}
  double operator()() {
    if (has_spare_) {
      has_spare_ = false;
      return spare_;
    }
    double u, v, s;
    do {
      u = 2.0 * rng_.uniform01() - 1.0;
      v = 2.0 * rng_.uniform01() - 1.0;
      s = u * u + v * v;
    } while (s >= 1.0 || s == 0.0);
    const double m = std::sqrt(-2.0 * std::log(s) / s);
    spare_ = v * m;
    has_spare_ = true;
    return u * m;
  }

 private:
  Xoshiro256ss rng_;
  double spare_ = 0.0;
  bool has_spare_ = false;
};

/// First-order Gauss-Markov process per axis, σ (stationary standard deviation) and τ
/// (correlation time), discretised exactly at the sample interval: x_k = φ x_{k-1} + q w_k with
/// φ = exp(-dt/τ), q = σ sqrt(1 - φ²); started in its stationary distribution x_0 ~ N(0, σ²) so
/// that its variance does not depend on where in the run one looks.
class GaussMarkov3 {
 public:
  GaussMarkov3() = default;
  GaussMarkov3(double sigma, double tau_s, double dt_s, PolarNormal& normal) : sigma_(sigma) {
    if (sigma_ <= 0.0) return;  // off: draws nothing, so other streams keep their values
    phi_ = std::exp(-dt_s / tau_s);
    drive_ = sigma_ * std::sqrt(1.0 - phi_ * phi_);
    for (double& xi : x_) xi = sigma_ * normal();
  }
  bool on() const { return sigma_ > 0.0; }
  /// Advances one sample and returns the new state's component i through x(i).
  void step(PolarNormal& normal) {
    if (!on()) return;
    for (double& xi : x_) xi = phi_ * xi + drive_ * normal();
  }
  double x(int i) const { return x_[static_cast<size_t>(i)]; }

 private:
  double sigma_ = 0.0, phi_ = 0.0, drive_ = 0.0;
  std::array<double, 3> x_{0.0, 0.0, 0.0};
};

}  // namespace imucal::tools::altsim
