#pragma once
// quantisation (ARCHITECTURE §7) and the noise model's declared LSBs: the output register rounds
// each axis to its LSB and carries the remainder into the next sample (an accumulating register),
// so quantisation never accumulates into a drift. The error of one output is e_k - e_{k-1} with e
// uniform on ±LSB/2: white over long spans (Allan slope -1), variance LSB²/6 per sample and lag-1
// autocovariance -LSB²/12 — which is how the diagnosis tells it from a larger white noise.
// A declared LSB may instead be rounded per sample (LsbRounding::kPerSample, noise_model.hpp: a
// logger of counts), white with variance LSB²/12; the quantisation *effect* is always carried.
#include <cmath>

#include "calib/core/noise_model.hpp"
#include "calib/core/rotation.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

struct Quantiser {
  double lsb = 0.0;
  LsbRounding rounding = LsbRounding::kCarried;
  Vec3<double> carry = Vec3<double>::Zero();

  Vec3<double> apply(const Vec3<double>& x) {
    if (lsb <= 0.0) return x;
    const Vec3<double> total = x + carry;
    Vec3<double> q;
    for (int i = 0; i < 3; ++i) q(i) = std::round(total(i) / lsb) * lsb;
    if (rounding == LsbRounding::kCarried) carry = total - q;
    return q;
  }
};

/// Lag-1 autocovariance of the carried quantisation error for a given LSB.
inline double quantisation_lag1_autocov(double lsb) {
  return rounding_lag1_autocov(lsb, LsbRounding::kCarried);
}

}  // namespace imucal::calib::effects
