#include "calib/diagnosis/rest_tremor_candidate.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>

#include "calib/core/chi2.hpp"
#include "calib/core/imu_error_model.hpp"
#include "calib/effects/rest_tremor.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::core;
using namespace calib::effects;

namespace {

// Blocks of 0.2 s average the tremor (6–11 Hz: 1.2–2.2 cycles) and a pivot's shake out of the
// tilt and keep the sway (0.3–1.2 Hz); windows of at most 4 s keep a slow bias wander (and the
// spurious regression of one slow random walk on another) out of the slope.
constexpr double kBlock_s = 0.2;
constexpr double kWindow_s = 4.0;
constexpr size_t kMinBlocks = 5;
constexpr int kBandPoints = 24;
constexpr double kRateSystematic = 0.03, kTiltSystematic = 0.05;  // see score_rest_tremor

/// A stretch of one rest: `blocks` blocks of `block` samples from sample `begin`.
struct TremorWindow {
  size_t rest = 0, begin = 0, block = 0, blocks = 0;
};

std::vector<TremorWindow> tremor_windows(const CalibrationInput& in,
                                         const std::vector<RestPeriod>& rests) {
  std::vector<TremorWindow> out;
  for (size_t r = 0; r < rests.size(); ++r) {
    const RestPeriod& p = rests[r];
    const double dt = in.imu[p.begin].dt_s;
    const size_t block = std::max<size_t>(3, static_cast<size_t>(std::lround(kBlock_s / dt)));
    const size_t windows = static_cast<size_t>(std::ceil(p.size() * dt / kWindow_s - 1e-9));
    const size_t per_window = p.size() / std::max<size_t>(1, windows);
    for (size_t w = 0; w < windows; ++w) {
      const size_t blocks = per_window / block;
      if (blocks >= kMinBlocks) out.push_back({r, p.begin + w * per_window, block, blocks});
    }
  }
  return out;
}

/// v less its least-squares line over the index.
void detrend(std::vector<double>& v) {
  const double n = static_cast<double>(v.size()), c = 0.5 * (n - 1.0);
  double mean = 0.0, sxt = 0.0, stt = 0.0;
  for (double x : v) mean += x / n;
  for (size_t j = 0; j < v.size(); ++j) {
    const double t = static_cast<double>(j) - c;
    sxt += t * (v[j] - mean);
    stt += t * t;
  }
  const double b = stt > 0.0 ? sxt / stt : 0.0;
  for (size_t j = 0; j < v.size(); ++j) v[j] -= mean + b * (static_cast<double>(j) - c);
}

double sinc(double x) { return std::abs(x) < 1e-9 ? 1.0 : std::sin(x) / x; }

/// The fraction of a sinusoid's mean square (f uniform over [f0, f1], any phase) that survives:
/// n values spaced `step` apart, each the mean over `span` around its point (sinc), less their
/// line. The cosine and sine parts of a random phase each carry half.
double band_retention(double f0, double f1, size_t n, double step, double span) {
  double sum = 0.0;
  for (int i = 0; i < kBandPoints; ++i) {
    const double f = f0 + (f1 - f0) * (i + 0.5) / kBandPoints, w = 2.0 * kPi * f;
    std::vector<double> c(n), s(n);
    for (size_t j = 0; j < n; ++j) {
      c[j] = std::cos(w * step * static_cast<double>(j));
      s[j] = std::sin(w * step * static_cast<double>(j));
    }
    detrend(c);
    detrend(s);
    double ss = 0.0;
    for (size_t j = 0; j < n; ++j) ss += c[j] * c[j] + s[j] * s[j];
    sum += std::pow(sinc(kPi * f * span), 2) * ss / static_cast<double>(n);
  }
  return sum / kBandPoints;
}

/// Per-axis regression sums of the slope and the size's sums, over one window or several.
struct TremorSums {
  Eigen::Array3d sxx = Eigen::Array3d::Zero(), sxy = Eigen::Array3d::Zero(),
                 syy = Eigen::Array3d::Zero();
  double dof = 0.0, blocks = 0.0;
  double tilt2 = 0.0, tilt_noise = 0.0, tilt_weight = 0.0;  ///< Σ θ², its noise, Σ retention
  double rate2 = 0.0, rate_noise = 0.0, rate_weight = 0.0;  ///< Σ rate², its noise, Σ retention
  void add(const TremorSums& o) {
    sxx += o.sxx;
    sxy += o.sxy;
    syy += o.syy;
    dof += o.dof;
    blocks += o.blocks;
    tilt2 += o.tilt2;
    tilt_noise += o.tilt_noise;
    tilt_weight += o.tilt_weight;
    rate2 += o.rate2;
    rate_noise += o.rate_noise;
    rate_weight += o.rate_weight;
  }
  double rate_ms() const { return rate_weight > 0.0 ? (rate2 - rate_noise) / rate_weight : 0.0; }
  double tilt_ms() const { return tilt_weight > 0.0 ? (tilt2 - tilt_noise) / tilt_weight : 0.0; }
};

/// The declared noise as the sums need it, summed over the axes of the compensated rate (the noise
/// is the raw output's: compensating by (I + M_g)⁻¹ scales it by that matrix's rows).
struct DeclaredNoise {
  double rate_var = 0.0;  ///< (rad/s)²: ARW²/dt and the rounding's variance (LSB²/6 carried,
                          ///< LSB²/12 per sample) over dt²
  double arw2 = 0.0;      ///< rad²/s: ARW² and a per-sample rounding's white density
};

/// Sums of one window: the blocks' tilt and specific force (the slope), the blocks' rates about
/// their lines (rate_rms) and the detrended tilt (tilt_rms).
TremorSums window_sums(const CalibrationInput& in, const ImuCompensator& comp,
                       const TremorWindow& w, const DeclaredNoise& noise,
                       std::map<size_t, double>& sway_retention_by_blocks, double tremor_ret) {
  const size_t n = w.block * w.blocks;
  std::vector<Eigen::Vector3d> rate(n), force(n);
  Eigen::Vector3d rate_mean = Eigen::Vector3d::Zero(), f_mean = Eigen::Vector3d::Zero();
  double T = 0.0;
  for (size_t k = 0; k < n; ++k) {
    const ImuIncrement& x = in.imu[w.begin + k];
    rate[k] = comp.dtheta(x.dtheta_rad, x.dt_s) / x.dt_s;
    force[k] = comp.dv(x.dv_mps, x.dt_s) / x.dt_s;
    rate_mean += rate[k] / static_cast<double>(n);
    f_mean += force[k] / static_cast<double>(n);
    T += x.dt_s;
  }
  TremorSums s;
  std::array<std::vector<double>, 3> theta_b, f_b;
  Eigen::Vector3d theta = Eigen::Vector3d::Zero();
  for (size_t j = 0; j < w.blocks; ++j) {
    Eigen::Vector3d th_sum = Eigen::Vector3d::Zero(), f_sum = Eigen::Vector3d::Zero();
    std::vector<double> axis_rate[3];
    for (size_t k = j * w.block; k < (j + 1) * w.block; ++k) {
      theta += (rate[k] - rate_mean) * in.imu[w.begin + k].dt_s;
      th_sum += theta;
      f_sum += force[k];
      for (int a = 0; a < 3; ++a) axis_rate[a].push_back(rate[k](a));
    }
    for (int a = 0; a < 3; ++a) {
      theta_b[static_cast<size_t>(a)].push_back(th_sum(a) / static_cast<double>(w.block));
      f_b[static_cast<size_t>(a)].push_back(f_sum(a) / static_cast<double>(w.block));
      detrend(axis_rate[a]);
      for (double r : axis_rate[a]) s.rate2 += r * r;
    }
  }
  const double m = static_cast<double>(w.block), nb = static_cast<double>(w.blocks);
  s.rate_noise = nb * (m - 2.0) * noise.rate_var;
  s.rate_weight = 3.0 * nb * m * tremor_ret;
  // x = f̄ × θ per block, then every series less its window's line.
  std::array<std::vector<double>, 3> x;
  for (size_t j = 0; j < w.blocks; ++j) {
    const Eigen::Vector3d th(theta_b[0][j], theta_b[1][j], theta_b[2][j]);
    const Eigen::Vector3d xj = f_mean.cross(th);
    for (int a = 0; a < 3; ++a) x[static_cast<size_t>(a)].push_back(xj(a));
  }
  for (int a = 0; a < 3; ++a) {
    const auto i = static_cast<size_t>(a);
    detrend(x[i]);
    detrend(f_b[i]);
    detrend(theta_b[i]);
    for (size_t j = 0; j < w.blocks; ++j) {
      s.sxx(a) += x[i][j] * x[i][j];
      s.sxy(a) += x[i][j] * f_b[i][j];
      s.syy(a) += f_b[i][j] * f_b[i][j];
      s.tilt2 += theta_b[i][j] * theta_b[i][j];
    }
  }
  s.dof = nb - 2.0;
  s.blocks = nb;
  double& ret = sway_retention_by_blocks[w.blocks];
  if (ret == 0.0) ret = band_retention(kSwayMinHz, kSwayMaxHz, w.blocks, T / nb, T / nb);
  s.tilt_weight = 3.0 * nb * ret;
  // The gyro's white noise integrates into a random walk: less its line over the window, its mean
  // square is ARW² T / 15 per axis.
  s.tilt_noise = nb * noise.arw2 * T / 15.0;
  return s;
}

/// The slope pooled over the axes by their precision, each axis' σ from its own residuals.
struct Slope {
  double beta = 0.0, sigma = std::numeric_limits<double>::infinity();
  double z() const { return std::isfinite(sigma) && sigma > 0.0 ? beta / sigma : 0.0; }
};

Slope slope_of(const TremorSums& s) {
  double info = 0.0, num = 0.0;
  for (int a = 0; a < 3; ++a) {
    if (!(s.sxx(a) > 0.0) || s.dof <= 1.0) continue;
    const double resid = std::max(0.0, s.syy(a) - s.sxy(a) * s.sxy(a) / s.sxx(a));
    const double var = resid / std::max(1.0, s.dof - 1.0);
    if (!(var > 0.0)) continue;
    info += s.sxx(a) / var;
    num += s.sxy(a) / var;
  }
  Slope out;
  if (info > 0.0) {
    out.beta = num / info;
    out.sigma = 1.0 / std::sqrt(info);
  }
  return out;
}

DeclaredNoise declared_noise(const CalibrationInput& in, const ImuCompensator& comp) {
  const double dt = in.imu.front().dt_s, q = in.noise.dtheta_lsb_rad;
  const double gain = comp.A_g_inv.squaredNorm();  // Σ over the axes of each row's squared norm
  DeclaredNoise n;
  const double arw2 = gain * in.noise.arw_rad_per_sqrt_s * in.noise.arw_rad_per_sqrt_s;
  // A sample's rate carries the rounding's whole variance; the tilt integrates a per-sample
  // rounding into a random walk as it does ARW, a carried one not (noise_model.hpp).
  n.rate_var = arw2 / dt + gain * rounding_variance(q, in.noise.lsb_rounding) / (dt * dt);
  n.arw2 = arw2 + gain * rounding_white_density(q, in.noise.lsb_rounding, dt);
  return n;
}

/// The windows' sums, per rest (index = the rest's).
std::vector<TremorSums> rest_sums(const CalibrationInput& in, const std::vector<RestPeriod>& rests,
                                  const ParamSet& base, const std::vector<TremorWindow>& windows) {
  const ImuCompensator comp(base);
  const DeclaredNoise noise = declared_noise(in, comp);
  std::map<size_t, double> sway_ret;
  std::map<size_t, double> tremor_ret;  // by block length
  std::vector<TremorSums> out(rests.size());
  for (const TremorWindow& w : windows) {
    double& rt = tremor_ret[w.block];
    const double dt = in.imu[w.begin].dt_s;
    if (rt == 0.0) rt = band_retention(kTremorMinHz, kTremorMaxHz, w.block, dt, dt);
    out[w.rest].add(window_sums(in, comp, w, noise, sway_ret, rt));
  }
  return out;
}

/// A mean square pooled over rests (weights: their retention weights) and its σ from the scatter
/// between rests; as an RMS with σ by the delta method (or √σ when it is not above 0).
void pooled_rms(const std::vector<TremorSums>& per_rest, bool rate, double& rms, double& sigma) {
  double w_sum = 0.0, ms = 0.0;
  std::vector<std::pair<double, double>> v;  // (weight, mean square)
  for (const TremorSums& s : per_rest) {
    const double w = rate ? s.rate_weight : s.tilt_weight;
    if (!(w > 0.0)) continue;
    v.emplace_back(w, rate ? s.rate_ms() : s.tilt_ms());
    w_sum += w;
  }
  for (const auto& [w, x] : v) ms += w * x / std::max(w_sum, 1e-300);
  double var = 0.0;
  for (const auto& [w, x] : v) var += w * w * (x - ms) * (x - ms);
  const double n = static_cast<double>(v.size());
  const double sigma_ms = n > 1.0 ? std::sqrt(var * n / (n - 1.0)) / w_sum : std::abs(ms);
  rms = std::sqrt(std::max(0.0, ms));
  // Near 0 the delta method fails: the σ of an RMS is at most the root of its mean square's.
  sigma = rms > 0.0 ? std::min(sigma_ms / (2.0 * rms), std::sqrt(sigma_ms)) : std::sqrt(sigma_ms);
}

}  // namespace

CandidateResult score_rest_tremor(const CalibrationInput& in, const std::vector<RestPeriod>& rests,
                                  const ParamSet& base, int folds) {
  const EffectInfo& e = effect_info(EffectId::kRestTremor);
  CandidateResult r;
  r.id = e.id;
  r.name = e.name;
  r.unit = e.magnitude_unit();
  r.separable = true;  // a statistic of its own, not a direction among the segment residuals
  r.k = 1;
  r.value_si = Eigen::VectorXd::Zero(e.size());
  r.value_si(2) = e.typical[2];  // the pivot is not estimated
  const std::vector<TremorWindow> windows = tremor_windows(in, rests);
  const std::vector<TremorSums> per_rest = rest_sums(in, rests, base, windows);
  const int K = std::max(2, std::min<int>(folds, static_cast<int>(rests.size())));
  std::vector<TremorSums> fold(static_cast<size_t>(K));
  TremorSums all;
  for (size_t i = 0; i < per_rest.size(); ++i) {
    fold[i % static_cast<size_t>(K)].add(per_rest[i]);
    all.add(per_rest[i]);
  }
  const Slope s = slope_of(all);
  if (s.z() > 0.0) r.lr = s.z() * s.z();  // a turned body senses gravity turned the same way
  r.p_value = chi2_survival(r.lr, r.k);
  r.bic_gain = r.lr - r.k * std::log(std::max(2.0, all.blocks));
  double before = 0.0, after = 0.0;
  for (int f = 0; f < K; ++f) {
    TremorSums train;
    for (int g = 0; g < K; ++g)
      if (g != f) train.add(fold[static_cast<size_t>(g)]);
    const Slope held = slope_of(fold[static_cast<size_t>(f)]), fit = slope_of(train);
    if (!std::isfinite(held.sigma)) continue;
    before += held.z() * held.z();
    after += std::pow((held.beta - fit.beta) / held.sigma, 2);
  }
  r.held_out_gap_before = before / K;
  r.held_out_gap = after / K;
  double rate = 0.0, rate_sigma = 0.0, tilt = 0.0, tilt_sigma = 0.0;
  pooled_rms(per_rest, true, rate, rate_sigma);
  pooled_rms(per_rest, false, tilt, tilt_sigma);
  // The scatter between rests does not see what moves every rest alike: the band the blocks'
  // loss is put back for (the catalogue's; a real hand's differs) and the rests the detector
  // keeps (it cuts where a hand moves most). On simulated hand runs these moved the sizes by
  // -2.4…+1.7 % (rate) and -4.5…+2 % (tilt) against a scatter of 0.3-0.6 %: a floor of 3 % and 5 %.
  rate_sigma = std::hypot(rate_sigma, kRateSystematic * rate);
  tilt_sigma = std::hypot(tilt_sigma, kTiltSystematic * tilt);
  r.value_si(0) = rate;
  r.value_si(1) = tilt;
  r.magnitude = e.magnitude(r.value_si);
  r.magnitude_sigma = rate_sigma * e.params[0].si_to_human;
  const double sig[2] = {rate_sigma, tilt_sigma};
  for (int j = 0; j < 2; ++j) {
    const EffectParamInfo& pi = e.params[static_cast<size_t>(j)];
    r.params.push_back(
        {pi.name, pi.human_unit, r.value_si(j) * pi.si_to_human, sig[j] * pi.si_to_human});
  }
  char note[320];
  std::snprintf(note, sizeof note,
                "the accelerometers follow the gyro-integrated tilt with slope %.3g +- %.2g (0 "
                "under sensor noise, 1 under motion) over %.0f blocks of 0.2 s in %zu windows; "
                "sizes are the gyros' beyond the declared noise (a noise declared too low reads "
                "as rate); the pivot is not estimated",
                s.beta, std::isfinite(s.sigma) ? s.sigma : 0.0, all.blocks, windows.size());
  r.note = note;
  return r;
}

std::vector<RestPeriod> still_rests(const CalibrationInput& in,
                                    const std::vector<RestPeriod>& rests) {
  std::vector<double> var(rests.size(), 0.0);
  for (size_t r = 0; r < rests.size(); ++r) {
    const RestPeriod& p = rests[r];
    for (int a = 0; a < 3; ++a) {
      std::vector<double> w;
      for (size_t k = p.begin; k < p.end; ++k)
        w.push_back(in.imu[k].dtheta_rad(a) / in.imu[k].dt_s);
      detrend(w);
      for (double x : w) var[r] += x * x / (3.0 * static_cast<double>(w.size()));
    }
  }
  const double quietest = var.empty() ? 0.0 : *std::min_element(var.begin(), var.end());
  std::vector<RestPeriod> out;
  for (size_t r = 0; r < rests.size(); ++r)
    if (var[r] <= kStillRatio * quietest) out.push_back(rests[r]);
  return out;
}

double rest_tremor_noncentrality(const GapModel& model, double m) {
  const CalibrationInput& in = model.input();
  const EffectInfo& e = effect_info(EffectId::kRestTremor);
  const double vrw2 = in.noise.vrw_mps_per_sqrt_s * in.noise.vrw_mps_per_sqrt_s;
  const double gS = kStandardGravity_mps2 * m * e.typical[1];
  double lambda = 0.0;
  std::map<size_t, double> ret;
  for (const TremorWindow& w : tremor_windows(in, model.rests())) {
    const double block_s = static_cast<double>(w.block) * in.imu[w.begin].dt_s;
    double& r = ret[w.blocks];
    if (r == 0.0) r = band_retention(kSwayMinHz, kSwayMaxHz, w.blocks, block_s, block_s);
    // Two horizontal axes of sway, each block's mean force with variance VRW² / block.
    lambda += static_cast<double>(w.blocks) * 2.0 * gS * gS * r * block_s / vrw2;
  }
  return lambda;
}

}  // namespace imucal::calib::diagnosis
