#pragma once
// output_filter (ARCHITECTURE §7): the sensor low-pass filters its output before the register
// (an anti-alias or smoothing stage), modelled as a first-order recursive filter per axis,
//   y_k = a y_{k-1} + (1 - a) x_k,   0 <= a < 1,
// whose DC gain is 1 (a long sum of outputs equals the sum of inputs: no scale factor, only a lag
// of a/(1-a) samples). On white input of variance σ² the output is AR(1):
//   var(y) = σ² (1-a)/(1+a),   lag-1 autocorrelation ρ1 = a,
// so the samples look quieter than the input while a mean of N ≫ 1/(1-a) samples keeps the input's
// variance σ²/N: against the per-sample scatter, a mean's variance is inflated by (1+a)/(1-a)
// (the AR(1) variance of the mean, e.g. Box & Jenkins §2.1.5). A positive lag-1 autocorrelation is
// the signature; quantisation with a carried remainder makes it negative (quantisation.hpp).
// The corner (-3 dB) frequency of the filter at sample interval dt is f_c ≈ -ln(a) / (2π dt).
#include <cmath>

#include "calib/core/rotation.hpp"

namespace imucal::calib::effects {
using namespace calib::core;

/// One sensor's output filter (three axes, one coefficient). a = 0 passes the input unchanged.
struct OutputFilter {
  double a = 0.0;
  Vec3<double> state = Vec3<double>::Zero();
  bool primed = false;

  Vec3<double> apply(const Vec3<double>& x) {
    if (a <= 0.0) return x;
    // Start from the first input, as a filter that has run since power-on: no start-up transient.
    state = primed ? Vec3<double>(a * state + (1.0 - a) * x) : x;
    primed = true;
    return state;
  }
};

/// Lag-1 autocorrelation of the filter's output on white input (the AR(1) coefficient).
inline double output_filter_lag1_autocorr(double a) { return a; }

/// Variance of one output sample per unit input variance: (1-a)/(1+a).
inline double output_filter_sample_variance_ratio(double a) { return (1.0 - a) / (1.0 + a); }

/// Variance of a long mean of outputs against the per-sample variance over N: (1+a)/(1-a).
inline double output_filter_mean_variance_inflation(double a) { return (1.0 + a) / (1.0 - a); }

/// Corner (-3 dB) frequency of the coefficient a at sample interval dt_s, Hz (0 for a = 0: none).
inline double output_filter_corner_hz(double a, double dt_s) {
  return a > 0.0 ? -std::log(a) / (2.0 * M_PI * dt_s) : 0.0;
}

/// The coefficient of a corner frequency f_c at sample interval dt_s: a = exp(-2π f_c dt).
inline double output_filter_coefficient(double corner_hz, double dt_s) {
  return std::exp(-2.0 * M_PI * corner_hz * dt_s);
}

}  // namespace imucal::calib::effects
