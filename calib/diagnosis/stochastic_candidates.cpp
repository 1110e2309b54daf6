#include "calib/diagnosis/stochastic_candidates.hpp"

#include <Eigen/Cholesky>
#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>

#include "calib/core/chi2.hpp"
#include "calib/diagnosis/gap_fit.hpp"
#include "calib/effects/bias_instability.hpp"
#include "calib/effects/output_filter.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::core;
using namespace calib::effects;

namespace {

// ---------------------------------------------------------------------------------------------
// Quantisation: pooled lag-1 autocovariance of the rest samples.

/// Sums for one sensor (3 axes pooled) or one axis over a set of rests.
struct Lag1Sums {
  double s0 = 0.0, s1 = 0.0, n0 = 0.0, n1 = 0.0;
  double s2 = 0.0, n2 = 0.0;  ///< lag 2 (output_filter_p_given_wandering)
  double gamma0() const { return n0 > 0 ? s0 / n0 : 0.0; }
  double gamma1() const { return n1 > 0 ? s1 / n1 : 0.0; }
  double sigma_gamma1() const { return n1 > 0 ? gamma0() / std::sqrt(n1) : 0.0; }
  void add(const Lag1Sums& o) {
    s0 += o.s0;
    s1 += o.s1;
    n0 += o.n0;
    n1 += o.n1;
    s2 += o.s2;
    n2 += o.n2;
  }
  double gamma2() const { return n2 > 0 ? s2 / n2 : 0.0; }
};

/// Lag-1 sums of one axis of one rest (sensor 0 = dv, 1 = dθ), its mean removed. Removing the mean
/// biases the lag-1 sum by about -Σx²/n; that is added back.
Lag1Sums rest_axis_sums(const CalibrationInput& in, const RestPeriod& p, int sensor, int axis) {
  const auto value = [&](size_t k) {
    return sensor == 0 ? in.imu[k].dv_mps(axis) : in.imu[k].dtheta_rad(axis);
  };
  double mean = 0.0;
  for (size_t k = p.begin; k < p.end; ++k) mean += value(k);
  mean /= static_cast<double>(p.size());
  Lag1Sums s;
  double prev = value(p.begin) - mean, prev2 = 0.0;
  s.s0 += prev * prev;
  for (size_t k = p.begin + 1; k < p.end; ++k) {
    const double x = value(k) - mean;
    s.s0 += x * x;
    s.s1 += x * prev;
    if (k >= p.begin + 2) s.s2 += x * prev2;
    prev2 = prev;
    prev = x;
  }
  s.s1 += s.s0 / static_cast<double>(p.size());
  s.s2 += s.s0 / static_cast<double>(p.size());
  s.n0 = static_cast<double>(p.size());
  s.n1 = static_cast<double>(p.size() - 1);
  s.n2 = p.size() > 2 ? static_cast<double>(p.size() - 2) : 0.0;
  return s;
}

/// One sensor's declared rounding as the rest samples' statistics see it (noise_model.hpp):
/// carried, variance LSB²/6 and lag-1 autocovariance -LSB²/12; per sample, LSB²/12 and none.
struct DeclaredRounding {
  double lsb = 0.0;
  double carried_lsb = 0.0;  ///< the LSB when carried, else 0: what the lag-1 statistics see
  double variance = 0.0;     ///< of one sample's error
  double lag1 = 0.0;         ///< autocovariance of neighbouring samples' errors
};

DeclaredRounding declared_rounding(const NoiseModel& nm, int sensor) {
  DeclaredRounding d;
  d.lsb = sensor == 0 ? nm.dv_lsb_mps : nm.dtheta_lsb_rad;
  d.carried_lsb = nm.lsb_rounding == LsbRounding::kCarried ? d.lsb : 0.0;
  d.variance = rounding_variance(d.lsb, nm.lsb_rounding);
  d.lag1 = rounding_lag1_autocov(d.lsb, nm.lsb_rounding);
  return d;
}

/// z of a lag-1 autocovariance against the value the rounding predicts.
double lag1_z(const Lag1Sums& s, double expected_gamma1) {
  const double sg = s.sigma_gamma1();
  return sg > 0.0 ? (s.gamma1() - expected_gamma1) / sg : 0.0;
}

/// The lag-1 autocovariance a carried rounding of `lsb` makes (the quantisation effect's).
double carried_lag1(double lsb) { return rounding_lag1_autocov(lsb, LsbRounding::kCarried); }

/// Allan deviation of one axis' rate residual at cluster size m, pooled over the rests.
double allan_deviation(const CalibrationInput& in, const std::vector<RestPeriod>& rests, int sensor,
                       int axis, size_t m) {
  double sum = 0.0;
  size_t count = 0;
  for (const RestPeriod& p : rests) {
    std::vector<double> c;
    for (size_t k = p.begin; k + m <= p.end; k += m) {
      double s = 0.0, t = 0.0;
      for (size_t j = k; j < k + m; ++j) {
        s += sensor == 0 ? in.imu[j].dv_mps(axis) : in.imu[j].dtheta_rad(axis);
        t += in.imu[j].dt_s;
      }
      c.push_back(s / t);
    }
    for (size_t j = 0; j + 1 < c.size(); ++j) {
      sum += 0.5 * (c[j + 1] - c[j]) * (c[j + 1] - c[j]);
      ++count;
    }
  }
  return count ? std::sqrt(sum / static_cast<double>(count)) : 0.0;
}

}  // namespace

WhitenessStats whiteness_stats(const CalibrationInput& in, const std::vector<RestPeriod>& rests) {
  WhitenessStats w;
  const double dt = in.imu.front().dt_s;
  for (size_t m : {size_t{1}, size_t{10}, size_t{100}, size_t{1000}}) w.tau_s.push_back(m * dt);
  for (int c = 0; c < 6; ++c) {
    const int sensor = c < 3 ? 0 : 1, axis = c % 3;
    Lag1Sums s;
    for (const RestPeriod& p : rests) s.add(rest_axis_sums(in, p, sensor, axis));
    w.lag1_autocorr[static_cast<size_t>(c)] = s.gamma0() > 0 ? s.gamma1() / s.gamma0() : 0.0;
    const DeclaredRounding q = declared_rounding(in.noise, sensor);
    w.lag1_z[static_cast<size_t>(c)] = lag1_z(s, q.lag1);
    const double white = sensor == 0 ? in.noise.vrw_mps_per_sqrt_s : in.noise.arw_rad_per_sqrt_s;
    // Allan variance: white noise (a per-sample rounding's among it) falls as 1/τ, a carried
    // rounding as 3 (LSB²/12)/τ².
    const double white2 = white * white + rounding_white_density(q.lsb, in.noise.lsb_rounding, dt);
    for (double tau : w.tau_s) {
      const size_t m = static_cast<size_t>(std::lround(tau / dt));
      w.adev[static_cast<size_t>(c)].push_back(allan_deviation(in, rests, sensor, axis, m));
      w.adev_expected[static_cast<size_t>(c)].push_back(
          std::sqrt(white2 / tau + q.carried_lsb * q.carried_lsb / (4.0 * tau * tau)));
    }
  }
  return w;
}

namespace {

/// A stochastic candidate's fixed fields: two amplitude parameters, always separable from the
/// deterministic base (it acts on the residuals' statistics, not their mean).
CandidateResult stochastic_candidate(const EffectInfo& e) {
  CandidateResult r;
  r.id = e.id;
  r.name = e.name;
  r.unit = e.magnitude_unit();
  r.separable = true;
  r.k = 2;
  return r;
}

}  // namespace

CandidateResult score_quantisation(const CalibrationInput& in, const std::vector<RestPeriod>& rests,
                                   int folds) {
  const EffectInfo& e = effect_info(EffectId::kQuantisation);
  CandidateResult r = stochastic_candidate(e);
  const int K = std::max(2, std::min<int>(folds, static_cast<int>(rests.size())));
  // Per sensor (param 0 = dθ LSB, 1 = dv LSB; sensor 0 = dv, 1 = dθ) and per fold.
  std::array<std::vector<Lag1Sums>, 2> fold_sums{std::vector<Lag1Sums>(static_cast<size_t>(K)),
                                                 std::vector<Lag1Sums>(static_cast<size_t>(K))};
  for (size_t i = 0; i < rests.size(); ++i)
    for (int sensor = 0; sensor < 2; ++sensor)
      for (int axis = 0; axis < 3; ++axis)
        fold_sums[static_cast<size_t>(sensor)][i % static_cast<size_t>(K)].add(
            rest_axis_sums(in, rests[i], sensor, axis));
  r.value_si = Eigen::VectorXd::Zero(2);
  Eigen::Vector2d sigma = Eigen::Vector2d::Zero();
  double before = 0.0, after = 0.0;
  for (int sensor = 0; sensor < 2; ++sensor) {
    Lag1Sums all;
    for (const auto& f : fold_sums[static_cast<size_t>(sensor)]) all.add(f);
    // The candidate is a carried rounding coarser than the declared one; a per-sample declared
    // rounding has no lag-1 share, so it leaves the candidate's floor at 0.
    const DeclaredRounding d = declared_rounding(in.noise, sensor);
    const double lsb0 = d.carried_lsb;
    const double z = lag1_z(all, d.lag1);
    if (z < 0.0) r.lr += z * z;  // quantisation only makes γ1 more negative
    const double q2 = std::max(lsb0 * lsb0, -12.0 * all.gamma1());
    const int p = sensor == 0 ? 1 : 0;  // catalogue order: dtheta_lsb, dv_lsb
    r.value_si(p) = std::sqrt(q2);
    sigma(p) =
        6.0 * all.sigma_gamma1() / std::max(r.value_si(p), std::sqrt(12.0 * all.sigma_gamma1()));
    for (int f = 0; f < K; ++f) {
      Lag1Sums train;
      for (int g = 0; g < K; ++g)
        if (g != f) train.add(fold_sums[static_cast<size_t>(sensor)][static_cast<size_t>(g)]);
      const double q_train = std::sqrt(std::max(lsb0 * lsb0, -12.0 * train.gamma1()));
      const Lag1Sums& held = fold_sums[static_cast<size_t>(sensor)][static_cast<size_t>(f)];
      before += std::pow(lag1_z(held, d.lag1), 2);
      after += std::pow(lag1_z(held, carried_lag1(q_train)), 2);
    }
  }
  r.p_value = chi2_survival(r.lr, r.k);
  Lag1Sums count;
  for (const auto& f : fold_sums[0]) count.add(f);
  r.bic_gain = r.lr - r.k * std::log(std::max(2.0, count.n1));
  r.held_out_gap = after / (2.0 * K);
  r.held_out_gap_before = before / (2.0 * K);
  r.magnitude = e.magnitude(r.value_si);
  r.magnitude_sigma = e.magnitude(sigma);
  for (int j = 0; j < 2; ++j) {
    const EffectParamInfo& pi = e.params[static_cast<size_t>(j)];
    r.params.push_back(
        {pi.name, pi.human_unit, r.value_si(j) * pi.si_to_human, sigma(j) * pi.si_to_human});
  }
  char note[200];
  std::snprintf(
      note, sizeof note,
      "from the lag-1 autocovariance of the rest samples (declared LSBs %.3g rad, %.3g "
      "m/s, %s)",
      in.noise.dtheta_lsb_rad, in.noise.dv_lsb_mps,
      in.noise.lsb_rounding == LsbRounding::kCarried ? "remainder carried" : "per-sample rounding");
  r.note = note;
  return r;
}

// ---------------------------------------------------------------------------------------------
// Output filter: the pooled lag-1 autocorrelation of the rest samples, one-sided positive.

namespace {

/// The filter coefficient a of one sensor's pooled rest sums, unclamped (a held-out fold may read
/// below 0). Under a filter of coefficient a over white noise plus the declared rounding
/// (noise_model.hpp), γ0 = γ0_f + var_q and γ1 = a γ0_f + lag1_q (carried: q²/6, -q²/12; per
/// sample: q²/12, 0), so a = (γ1 - lag1_q)/(γ0 - var_q).
/// Removing each rest's mean biases the sums by the mean's variance, which the filter inflates by
/// f = (1+a)/(1-a) (output_filter.hpp): E s0 = n0 γ0 - R γ0 f, and rest_axis_sums' white-noise
/// correction (+s0/n per rest) leaves E s1 = n1 γ1 - R γ0 (f - 1), R = n0 - n1 the (rest, axis)
/// pairs; solved by fixed-point iteration from a = 0.
double filter_coefficient(const Lag1Sums& s, const DeclaredRounding& q) {
  const double R = s.n0 - s.n1;
  double a = 0.0;
  for (int it = 0; it < 30; ++it) {
    const double ac = std::clamp(a, 0.0, 0.99);  // the bias terms only for a filter's a
    const double f = (1.0 + ac) / (1.0 - ac);
    const double gamma0 = s.s0 / std::max(1.0, s.n0 - R * f);
    const double gamma1 = (s.s1 + R * gamma0 * (f - 1.0)) / std::max(1.0, s.n1);
    const double denom = gamma0 - q.variance;
    a = denom > 0.0 ? (gamma1 - q.lag1) / denom : 0.0;
  }
  return a;
}

/// σ of the lag-1 autocorrelation estimate of an AR(1) of coefficient a over n1 pairs (Bartlett:
/// var r1 ≈ (1 - a²)/n).
double sigma_filter_coefficient(double a, double n1) {
  return n1 > 0.0 ? std::sqrt(std::max(1e-6, 1.0 - a * a) / n1) : 0.0;
}

}  // namespace

CandidateResult score_output_filter(const CalibrationInput& in,
                                    const std::vector<RestPeriod>& rests, int folds) {
  const EffectInfo& e = effect_info(EffectId::kOutputFilter);
  CandidateResult r = stochastic_candidate(e);
  const int K = std::max(2, std::min<int>(folds, static_cast<int>(rests.size())));
  // Per sensor (sensor 0 = dv, 1 = dθ; param 0 = gyro_a, 1 = accel_a) and per fold.
  std::array<std::vector<Lag1Sums>, 2> fold_sums{std::vector<Lag1Sums>(static_cast<size_t>(K)),
                                                 std::vector<Lag1Sums>(static_cast<size_t>(K))};
  for (size_t i = 0; i < rests.size(); ++i)
    for (int sensor = 0; sensor < 2; ++sensor)
      for (int axis = 0; axis < 3; ++axis)
        fold_sums[static_cast<size_t>(sensor)][i % static_cast<size_t>(K)].add(
            rest_axis_sums(in, rests[i], sensor, axis));
  r.value_si = Eigen::VectorXd::Zero(2);
  Eigen::Vector2d sigma = Eigen::Vector2d::Zero();
  double before = 0.0, after = 0.0;
  for (int sensor = 0; sensor < 2; ++sensor) {
    const auto& fs = fold_sums[static_cast<size_t>(sensor)];
    Lag1Sums all;
    for (const auto& f : fs) all.add(f);
    const DeclaredRounding q = declared_rounding(in.noise, sensor);
    // The same z as the whiteness line's: departure from white noise with the declared rounding.
    const double z = lag1_z(all, q.lag1);
    if (z > 0.0) r.lr += z * z;  // a filter only makes γ1 positive (quantisation: negative)
    const int p = sensor == 0 ? 1 : 0;
    r.value_si(p) = std::clamp(filter_coefficient(all, q), 0.0, 0.99);
    sigma(p) = sigma_filter_coefficient(r.value_si(p), all.n1);
    for (int f = 0; f < K; ++f) {
      Lag1Sums train;
      for (int g = 0; g < K; ++g)
        if (g != f) train.add(fs[static_cast<size_t>(g)]);
      const double a_train = std::clamp(filter_coefficient(train, q), 0.0, 0.99);
      const Lag1Sums& held = fs[static_cast<size_t>(f)];
      const double a_held = filter_coefficient(held, q);
      before += std::pow(lag1_z(held, q.lag1), 2);
      after += std::pow((a_held - a_train) / sigma_filter_coefficient(a_train, held.n1), 2);
    }
  }
  r.p_value = chi2_survival(r.lr, r.k);
  Lag1Sums count;
  for (const auto& f : fold_sums[0]) count.add(f);
  r.bic_gain = r.lr - r.k * std::log(std::max(2.0, count.n1));
  r.held_out_gap = after / (2.0 * K);
  r.held_out_gap_before = before / (2.0 * K);
  r.magnitude = e.magnitude(r.value_si);
  // σ of the norm by the delta method along the fitted direction (the two sensors independent);
  // with nothing fitted, the norm of the σ's.
  const double a_g = r.value_si(0), a_a = r.value_si(1), n2 = a_g * a_g + a_a * a_a;
  r.magnitude_sigma =
      n2 > 0.0 ? std::sqrt((a_g * a_g * sigma(0) * sigma(0) + a_a * a_a * sigma(1) * sigma(1)) / n2)
               : std::hypot(sigma(0), sigma(1));
  for (int j = 0; j < 2; ++j) {
    const EffectParamInfo& pi = e.params[static_cast<size_t>(j)];
    r.params.push_back(
        {pi.name, pi.human_unit, r.value_si(j) * pi.si_to_human, sigma(j) * pi.si_to_human});
  }
  const double dt = in.imu.front().dt_s;
  char note[240];
  std::snprintf(note, sizeof note,
                "from the lag-1 autocorrelation of the rest samples (corner %.3g Hz gyro, %.3g Hz "
                "accel; a rest mean's variance against the per-sample scatter x%.3g, x%.3g)",
                output_filter_corner_hz(r.value_si(0), dt),
                output_filter_corner_hz(r.value_si(1), dt),
                output_filter_mean_variance_inflation(r.value_si(0)),
                output_filter_mean_variance_inflation(r.value_si(1)));
  r.note = note;
  return r;
}

double output_filter_p_given_wandering(const CalibrationInput& in,
                                       const std::vector<RestPeriod>& rests) {
  double lr = 0.0;
  for (int sensor = 0; sensor < 2; ++sensor) {
    Lag1Sums all;
    for (const RestPeriod& p : rests)
      for (int axis = 0; axis < 3; ++axis) all.add(rest_axis_sums(in, p, sensor, axis));
    if (all.n1 <= 0.0 || all.n2 <= 0.0) continue;
    const double d = all.gamma1() - all.gamma2() - declared_rounding(in.noise, sensor).lag1;
    const double sigma = all.gamma0() * std::sqrt(1.0 / all.n1 + 1.0 / all.n2);
    const double z = sigma > 0.0 ? d / sigma : 0.0;
    if (z > 0.0) lr += z * z;
  }
  return chi2_survival(lr, 2);
}

// ---------------------------------------------------------------------------------------------
// Bias instability: REML over the Gauss-Markov σ's.

namespace {

struct GmMatrices {
  Eigen::MatrixXd Ga, Gg;  ///< whitened-residual covariance per unit σ² (accel m/s², gyro rad/s)
};

GmMatrices gm_matrices(const GapLinearisation& lin, double tau_s) {
  const auto& segs = lin.model().segments();
  const int m = lin.model().rows();
  GmMatrices g{Eigen::MatrixXd::Zero(m, m), Eigen::MatrixXd::Zero(m, m)};
  const Eigen::MatrixXd& J = lin.Jb();
  for (size_t s = 0; s < segs.size(); ++s) {
    const int rs = 6 * static_cast<int>(s);
    const double ts = 0.5 * (segs[s].t0_s + segs[s].t1_s);
    for (size_t t = 0; t < segs.size(); ++t) {
      const int rt = 6 * static_cast<int>(t);
      const double rho = GaussMarkov3::correlation(ts - 0.5 * (segs[t].t0_s + segs[t].t1_s), tau_s);
      if (rho < 1e-6) continue;
      g.Ga.block(rs, rt, 6, 6) = rho * J.block(rs, 0, 6, 3) * J.block(rt, 0, 6, 3).transpose();
      g.Gg.block(rs, rt, 6, 6) = rho * J.block(rs, 12, 6, 3) * J.block(rt, 12, 6, 3).transpose();
    }
  }
  return g;
}

/// Restricted log-likelihood of the whitened residuals r0 + J δ with covariance S, δ profiled out
/// (constant terms dropped; J's column scaling is the same for every S, so differences are exact).
double reml(const Eigen::VectorXd& r0, const Eigen::MatrixXd& J, const Eigen::MatrixXd& S,
            double* chi2 = nullptr) {
  const Eigen::LLT<Eigen::MatrixXd> llt(S);
  if (llt.info() != Eigen::Success) return -std::numeric_limits<double>::infinity();
  const Eigen::VectorXd rt = llt.matrixL().solve(r0);
  const Eigen::MatrixXd Jt = llt.matrixL().solve(J);
  const Eigen::VectorXd d = J.colwise().norm().transpose().cwiseMax(1e-300).cwiseInverse();
  const Eigen::MatrixXd Js = Jt * d.asDiagonal();
  const Eigen::LLT<Eigen::MatrixXd> h(Js.transpose() * Js);
  const Eigen::VectorXd x = h.solve(Js.transpose() * rt);
  const Eigen::VectorXd e = rt - Js * x;
  double logdet_S = 0.0, logdet_H = 0.0;
  for (int i = 0; i < S.rows(); ++i) logdet_S += 2.0 * std::log(llt.matrixL()(i, i));
  const Eigen::MatrixXd Lh = h.matrixL();
  for (int i = 0; i < Lh.rows(); ++i) logdet_H += 2.0 * std::log(Lh(i, i));
  if (chi2) *chi2 = e.squaredNorm();
  return -0.5 * (e.squaredNorm() + logdet_S + logdet_H);
}

struct GmFit {
  double sa = 0.0, sg = 0.0, tau = 0.0, ell = -std::numeric_limits<double>::infinity();
};

/// The grid's σ's refined: each in turn by a parabola through log σ and log σ ± log 1.2, its
/// vertex (within a factor 1.5) kept when it is better, twice round. A strong drift's likelihood is
/// sharp (LR ~10⁵ on a factory run at 8× typical): the grid's best σ (its step is 1.4) can be ℓ
/// units from the peak, enough to prefer the wrong τ of the grid (a drift of τ 1000 s at 7.6×
/// typical read 12.6× at τ 3000 s, "implausible").
template <class Ell>
void refine_sigmas(GmFit& f, const Ell& ell) {
  const double h = std::log(1.2), reach = std::log(1.5);
  for (int round = 0; round < 2; ++round)
    for (double GmFit::*sigma : {&GmFit::sa, &GmFit::sg}) {
      if (f.*sigma <= 0.0) continue;
      const double x0 = std::log(f.*sigma);
      const auto at = [&](double log_s) {
        GmFit t = f;
        t.*sigma = std::exp(log_s);
        return ell(t.sa, t.sg);
      };
      const double lm = at(x0 - h), lp = at(x0 + h);
      const double curv = lp - 2.0 * f.ell + lm;
      double x = lp > lm ? x0 + h : x0 - h, l = std::max(lp, lm);
      if (curv < 0.0) {
        const double xv = x0 + std::clamp(-h * (lp - lm) / (2.0 * curv), -reach, reach);
        const double lv = at(xv);
        if (lv > l) x = xv, l = lv;
      }
      if (l > f.ell) f.*sigma = std::exp(x), f.ell = l;
    }
}

GmFit fit_gm(const GapLinearisation& lin, const Eigen::MatrixXd& J, const GmMatrices& g, double tau,
             double typ_a, double typ_g) {
  const int m = lin.model().rows();
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(m, m);
  auto ell = [&](double sa, double sg) {
    return reml(lin.r0(), J, I + sa * sa * g.Ga + sg * sg * g.Gg);
  };
  const std::vector<double> mult = {0.0, 0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0, 32.0, 64.0};
  GmFit best;
  best.tau = tau;
  // Coordinate search: each σ alone, then the neighbourhood of the better combination.
  double sa_best = 0.0, sg_best = 0.0, la = -1e300, lg = -1e300;
  for (double k : mult) {
    const double a = ell(k * typ_a, 0.0), b = ell(0.0, k * typ_g);
    if (a > la) la = a, sa_best = k * typ_a;
    if (b > lg) lg = b, sg_best = k * typ_g;
  }
  for (double fa : {0.0, 0.7, 1.0, 1.4})
    for (double fg : {0.0, 0.7, 1.0, 1.4}) {
      const double l = ell(fa * sa_best, fg * sg_best);
      if (l > best.ell) best = {fa * sa_best, fg * sg_best, tau, l};
    }
  refine_sigmas(best, ell);
  return best;
}

}  // namespace

GaussMarkovFit fit_gauss_markov(const GapLinearisation& lin, const Eigen::MatrixXd& J,
                                const std::vector<double>& tau_grid_s) {
  const EffectInfo& e = effect_info(EffectId::kBiasInstability);
  const int m = lin.model().rows();
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(m, m);
  const double ell0 = reml(lin.r0(), J, I);
  GmFit best;
  GmMatrices gbest;
  GaussMarkovFit out;
  // The σ grid from the unit's grade: a MEMS unit's drift is 10⁴ × the catalogue's (navigation)
  // typical, where a grid of navigation sizes stopped at ~90 × (gnss-ins-sim's IMU381 preset, 3.5
  // °/h: "91 ± 28 × typical", not significant).
  const double scale = effect_scale(EffectId::kBiasInstability, lin.model().input().grade);
  for (double tau : tau_grid_s) {
    GmMatrices g = gm_matrices(lin, tau);
    const GmFit f = fit_gm(lin, J, g, tau, scale * e.typical[1], scale * e.typical[0]);
    out.profile.push_back({tau, f.sa, f.sg, f.ell});
    if (f.ell > best.ell) best = f, gbest = std::move(g);
  }
  out.sigma_accel_mps2 = best.sa;
  out.sigma_gyro_radps = best.sg;
  out.tau_s = best.tau;
  out.lr = std::max(0.0, 2.0 * (best.ell - ell0));
  out.S = I + best.sa * best.sa * gbest.Ga + best.sg * best.sg * gbest.Gg;
  reml(lin.r0(), J, out.S, &out.chi2);
  return out;
}

namespace {

/// The smallest magnitude of a Gauss-Markov bias whose restricted log-likelihood on design J is at
/// least `ell_min`: over the τ's of f's profile and the geometric midpoints between them (and
/// below the first; σ's fitted there), the σ's scaled down along each τ's best pattern. The
/// fitted magnitude when none is smaller. On a 2277 s run ℓ is flat over τ from ~500 s up (within
/// 2 over 500–3000 s for a drift of τ 500 s) while σ doubles: the grid's τ's alone miss the
/// smaller sizes the data allow.
double smallest_size_within(const GapLinearisation& lin, const Eigen::MatrixXd& J,
                            const GaussMarkovFit& f, double ell_min) {
  const EffectInfo& e = effect_info(EffectId::kBiasInstability);
  const int m = lin.model().rows();
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(m, m);
  std::vector<GaussMarkovFit::AtTau> at_taus = f.profile;
  for (size_t i = 0; i < f.profile.size(); ++i) {
    const double below = i == 0 ? f.profile[0].tau_s / 1.7 : f.profile[i - 1].tau_s;
    const double tau = std::sqrt(below * f.profile[i].tau_s);
    const double scale = effect_scale(EffectId::kBiasInstability, lin.model().input().grade);
    const GmFit g =
        fit_gm(lin, J, gm_matrices(lin, tau), tau, scale * e.typical[1], scale * e.typical[0]);
    at_taus.push_back({tau, g.sa, g.sg, g.ell});
  }
  double smallest = e.magnitude(Eigen::Vector3d(f.sigma_gyro_radps, f.sigma_accel_mps2, f.tau_s));
  for (const GaussMarkovFit::AtTau& at : at_taus) {
    const GmMatrices g = gm_matrices(lin, at.tau_s);
    for (double k : {1.0, 0.85, 0.7, 0.6, 0.5, 0.4, 0.3, 0.2}) {
      const double sa = k * at.sigma_accel_mps2, sg = k * at.sigma_gyro_radps;
      if (reml(lin.r0(), J, I + sa * sa * g.Ga + sg * sg * g.Gg) < ell_min) break;
      smallest = std::min(smallest, e.magnitude(Eigen::Vector3d(sg, sa, at.tau_s)));
    }
  }
  return smallest;
}

}  // namespace

void set_gauss_markov_size(CandidateResult& r, const GapLinearisation& lin,
                           const Eigen::MatrixXd& J, const GaussMarkovFit& f) {
  const EffectInfo& e = effect_info(EffectId::kBiasInstability);
  const int m = lin.model().rows();
  r.value_si = Eigen::Vector3d(f.sigma_gyro_radps, f.sigma_accel_mps2, f.tau_s);
  r.magnitude = e.magnitude(r.value_si);
  r.magnitude_sigma = 0.0;
  // σ of the magnitude from the curvature of the profile along the fitted direction.
  const Eigen::MatrixXd I = Eigen::MatrixXd::Identity(m, m);
  if (r.magnitude > 0.0) {
    const Eigen::MatrixXd D = f.S - I;
    const double l1 = reml(lin.r0(), J, f.S);
    const double lm = reml(lin.r0(), J, I + 0.49 * D), lp = reml(lin.r0(), J, I + 1.69 * D);
    const double curv = -(lp - 2.0 * l1 + lm) / (0.3 * 0.3);
    r.magnitude_sigma = curv > 0.0 ? r.magnitude / std::sqrt(curv) : r.magnitude;
    const double floor = smallest_size_within(lin, J, f, l1 - 2.0);
    r.magnitude_sigma = std::max(r.magnitude_sigma, 0.5 * (r.magnitude - floor));
  }
  r.params.clear();
  for (int j = 0; j < 3; ++j) {
    const EffectParamInfo& pi = e.params[static_cast<size_t>(j)];
    const double rel = r.magnitude > 0.0 ? r.magnitude_sigma / r.magnitude : 0.0;
    r.params.push_back({pi.name, pi.human_unit, r.value_si(j) * pi.si_to_human,
                        pi.shape ? 0.0 : rel * r.value_si(j) * pi.si_to_human});
  }
}

CandidateResult score_bias_instability(const GapLinearisation& lin,
                                       const std::vector<std::vector<int>>& folds,
                                       const std::vector<double>& tau_grid_s) {
  const EffectInfo& e = effect_info(EffectId::kBiasInstability);
  CandidateResult r = stochastic_candidate(e);
  const int m = lin.model().rows();
  const GaussMarkovFit f = fit_gauss_markov(lin, lin.Jb(), tau_grid_s);
  r.lr = f.lr;
  r.p_value = chi2_survival(r.lr, r.k);
  r.bic_gain = r.lr - r.k * std::log(static_cast<double>(m));
  set_gauss_markov_size(r, lin, lin.Jb(), f);
  r.chi2_after = f.chi2;
  r.held_out_gap = held_out_gap_correlated(lin.r0(), lin.Jb(), f.S, folds).ratio();
  r.note = "Gauss-Markov bias offsets per segment (tau " +
           std::to_string(static_cast<int>(f.tau_s)) + " s), restricted maximum likelihood";
  return r;
}

double quantisation_noncentrality(const GapModel& model, double m) {
  const EffectInfo& e = effect_info(EffectId::kQuantisation);
  const CalibrationInput& in = model.input();
  double pairs = 0.0;
  for (const RestPeriod& p : model.rests()) pairs += 3.0 * static_cast<double>(p.size() - 1);
  const double dt = in.imu.front().dt_s;
  double lambda = 0.0;
  for (int sensor = 0; sensor < 2; ++sensor) {
    const double lsb0 = declared_rounding(in.noise, sensor).carried_lsb;
    const double q = m * e.typical[sensor == 0 ? 1 : 0];
    const double white = sensor == 0 ? in.noise.vrw_mps_per_sqrt_s : in.noise.arw_rad_per_sqrt_s;
    const double gamma0 = white * white * dt + q * q / 6.0;
    const double z = (q * q - lsb0 * lsb0) / 12.0 / (gamma0 / std::sqrt(pairs));
    lambda += z > 0.0 ? z * z : 0.0;
  }
  return lambda;
}

double bias_instability_noncentrality(const GapLinearisation& lin, double m) {
  const EffectInfo& e = effect_info(EffectId::kBiasInstability);
  const GmMatrices g = gm_matrices(lin, e.typical[2]);
  const Eigen::MatrixXd G = e.typical[1] * e.typical[1] * g.Ga + e.typical[0] * e.typical[0] * g.Gg;
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(lin.Jb());
  const Eigen::MatrixXd Q =
      qr.householderQ() * Eigen::MatrixXd::Identity(lin.Jb().rows(), lin.Jb().cols());
  const Eigen::MatrixXd MG = G - Q * (Q.transpose() * G);
  const Eigen::MatrixXd MGM = MG - (MG * Q) * Q.transpose();
  return 0.5 * std::pow(m, 4) * MGM.squaredNorm();  // tr(A²) = ||A||_F² for symmetric A
}

double output_filter_noncentrality(const GapModel& model, double m) {
  const EffectInfo& e = effect_info(EffectId::kOutputFilter);
  double pairs = 0.0;
  for (const RestPeriod& p : model.rests()) pairs += 3.0 * static_cast<double>(p.size() - 1);
  double lambda = 0.0;
  for (int j = 0; j < 2; ++j) {
    // E z = a √pairs: the lag-1 z against white noise of an AR(1) with coefficient a (the declared
    // rounding's share of γ1 is negligible beside it).
    const double a = std::min(0.99, m * e.typical[static_cast<size_t>(j)]);
    lambda += a * a * pairs;
  }
  return lambda;
}

}  // namespace imucal::calib::diagnosis
