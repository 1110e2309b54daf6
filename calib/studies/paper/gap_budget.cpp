#include "calib/studies/paper/gap_budget.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <random>
#include <stdexcept>

#include "calib/core/conventions.hpp"

namespace imucal::calib::studies::paper {
using namespace calib::checks;
using namespace calib::core;
using namespace calib::effects;
using namespace calib::sim;

namespace {

using ColumnMetric = std::array<std::array<double, 2>, kNumPaperColumns>;

BudgetCandidate setup_candidate(std::string name, std::string unit, double probe, double hi,
                                std::string source,
                                std::function<void(PaperSetupErrors&, double)> set) {
  BudgetCandidate c;
  c.name = std::move(name);
  c.unit = std::move(unit);
  c.probe = probe;
  c.prior_hi = hi;
  c.prior_source = std::move(source);
  c.apply = [set](PaperTablesOptions& o, double size) { set(o.setup, size); };
  return c;
}

/// One simulation's units: their squared metrics per column and metric, and the factory AINS's
/// evaluated parameters with their σ (for the calibration shift, BudgetEntry).
struct SimUnits {
  std::vector<ColumnMetric> squares;
  std::vector<ParamVector> params, sigma;
};

SimUnits sim_units(const PaperTables& t) {
  SimUnits out;
  for (const PaperUnitResult& u : t.units) {
    ColumnMetric sq{};
    for (int c = 0; c < kNumPaperColumns; ++c) {
      const EvaluationMetrics& m = u.metrics[static_cast<size_t>(c)];
      sq[static_cast<size_t>(c)] = {m.orientation_rmse_mdeg * m.orientation_rmse_mdeg,
                                    m.accel_rmse_ug * m.accel_rmse_ug};
    }
    out.squares.push_back(sq);
    const auto ains = static_cast<size_t>(PaperColumn::kFactoryAins);
    out.params.push_back(u.params[ains].to_vector());
    out.sigma.push_back(u.sigma[ains].to_vector());
  }
  return out;
}

/// RMS over the units and the 24 unit parameters of (probe - base) / σ_base.
double shift_in_sigma(const SimUnits& probe, const SimUnits& base) {
  double sum = 0.0;
  int n = 0;
  for (size_t u = 0; u < base.params.size(); ++u)
    for (int i = 0; i < 24; ++i) {
      const double z = (probe.params[u](i) - base.params[u](i)) / base.sigma[u](i);
      if (!std::isfinite(z)) continue;
      sum += z * z;
      ++n;
    }
  return n > 0 ? std::sqrt(sum / n) : 0.0;
}

/// The mean over the units `picked` (indices into per_unit, repeats allowed) of a difference
/// `a - b` of per-unit squares (b empty: of a alone).
ColumnMetric mean_over(const std::vector<ColumnMetric>& a, const std::vector<ColumnMetric>& b,
                       const std::vector<int>& picked) {
  ColumnMetric out{};
  for (int u : picked)
    for (int c = 0; c < kNumPaperColumns; ++c)
      for (int m = 0; m < 2; ++m) {
        const auto cs = static_cast<size_t>(c), ms = static_cast<size_t>(m);
        const auto us = static_cast<size_t>(u);
        out[cs][ms] += (a[us][cs][ms] - (b.empty() ? 0.0 : b[us][cs][ms])) /
                       static_cast<double>(picked.size());
      }
  return out;
}

/// The mean over the units `picked` of each metric (the square roots of the per-unit squares):
/// what the paper's tables report.
ColumnMetric means_of(const std::vector<ColumnMetric>& squares, const std::vector<int>& picked) {
  ColumnMetric out{};
  for (int u : picked)
    for (size_t c = 0; c < out.size(); ++c)
      for (size_t m = 0; m < 2; ++m)
        out[c][m] +=
            std::sqrt(squares[static_cast<size_t>(u)][c][m]) / static_cast<double>(picked.size());
  return out;
}

ColumnMetric square_roots(ColumnMetric a) {
  for (auto& col : a)
    for (double& v : col) v = std::sqrt(std::max(v, 0.0));
  return a;
}

/// Σ_cm |T - pred| / T over the column means: how far a prediction is from the paper (the gap's
/// size; means, as the tables report them, and not mean squares, which one unit's heavy tail
/// dominates).
double gap_size(const ColumnMetric& predicted, const ColumnMetric& target) {
  double d = 0.0;
  for (int c = 0; c < kNumPaperColumns; ++c)
    for (int m = 0; m < 2; ++m) {
      const double t = target[static_cast<size_t>(c)][static_cast<size_t>(m)];
      d += std::abs(t - predicted[static_cast<size_t>(c)][static_cast<size_t>(m)]) / t;
    }
  return d;
}

/// 0, 1, …, n - 1: every unit once.
std::vector<int> every_unit(size_t n) {
  std::vector<int> units(n);
  for (size_t u = 0; u < n; ++u) units[u] = static_cast<int>(u);
  return units;
}

/// The sample standard deviation (0 for fewer than two values).
double spread(const std::vector<double>& v) {
  if (v.size() < 2) return 0.0;
  double mean = 0.0, ss = 0.0;
  for (double x : v) mean += x / static_cast<double>(v.size());
  for (double x : v) ss += (x - mean) * (x - mean);
  return std::sqrt(ss / static_cast<double>(v.size() - 1));
}

}  // namespace

namespace {

/// An effect acting on both sensor triads (warm-up drift, bias instability) is two candidates,
/// its accelerometer part and its gyro part: a unit's accelerometers and gyros drift
/// independently, and a heading re-found by gyrocompassing turns gyro drift alone into heading
/// error — sized together, the drift the acceleration columns ask for would be forced onto the
/// orientation columns.
std::vector<PaperEffectSize::Part> budget_parts(const EffectInfo& info) {
  bool accel = false, gyro = false;
  for (const EffectParamInfo& p : info.params) {
    accel = accel || paper_effect_param_in_part(p.name, PaperEffectSize::Part::kAccel);
    gyro = gyro || paper_effect_param_in_part(p.name, PaperEffectSize::Part::kGyro);
  }
  if (accel && gyro) return {PaperEffectSize::Part::kAccel, PaperEffectSize::Part::kGyro};
  return {PaperEffectSize::Part::kAll};
}

}  // namespace

std::vector<BudgetCandidate> default_budget_candidates() {
  std::vector<BudgetCandidate> out;
  out.push_back(setup_candidate("uncalibrated_gyro_bias", "deg/h", 0.01, 0.01,
                                "paper §VI (gyro biases not calibrated); navigation-grade FOG/RLG "
                                "datasheets 0.001-0.01 deg/h",
                                [](PaperSetupErrors& s, double v) {
                                  s.uncalibrated_gyro_bias_radps = v * kDegPerHourToRadPerSec;
                                }));
  out.push_back(setup_candidate(
      "table_position_error", "mdeg", 3.0, 2.0,
      "paper §I (about 0.001 deg); precision two-axis table specifications 1-7 arcsec",
      [](PaperSetupErrors& s, double v) { s.table_position_error_rad = v * 1e-3 * kDegToRad; }));
  out.push_back(setup_candidate(
      "fixture_heading", "mdeg", 100.0, 50.0,
      "paper §VII (small, unknown); fixture machining tolerance up to 0.5 mrad",
      [](PaperSetupErrors& s, double v) { s.fixture_heading_rad = v * 1e-3 * kDegToRad; }));
  out.push_back(setup_candidate(
      "fixture_flex", "urad/g", 100.0, 200.0,
      "issue #26 (flex under rotation); an engineering estimate for a several-kilogram unit on a "
      "machined fixture, 0-40 arcsec per g, not a datasheet class",
      [](PaperSetupErrors& s, double v) { s.fixture_flex_rad_per_g = v * 1e-6; }));
  out.push_back(setup_candidate(
      "evaluation_heading_reopen", "mdeg", 100.0, 1000.0,
      "paper §VII (a ZUPT-aided INS, its heading aiding not stated): 0 = heading held by the "
      "gyros between rests, up to 1000 mdeg = re-found by gyrocompassing at every rest",
      [](PaperSetupErrors& s, double v) {
        s.evaluation_heading_reopen_rad = v * 1e-3 * kDegToRad;
      }));
  // Gyrocompassing at every rest turns every drift into heading error: it amplifies the others.
  out.back().amplifier = true;
  for (const EffectInfo& info : effect_catalogue())
    for (const PaperEffectSize::Part part : budget_parts(info)) {
      BudgetCandidate c;
      c.name = info.name + paper_effect_part_suffix(part);
      c.unit = "x typical";
      c.probe = 3.0;
      c.prior_hi = 5.0;
      c.prior_source = "effects catalogue's typical navigation-grade size (ARCHITECTURE §7), 0-5x";
      const EffectId id = info.id;
      c.apply = [id, part](PaperTablesOptions& o, double size) {
        if (size > 0.0) o.catalogue.push_back({id, size, part});
      };
      out.push_back(std::move(c));
    }
  return out;
}

BudgetTarget budget_target(const PaperPublished& published) {
  BudgetTarget t;
  for (size_t c = 0; c < kNumPaperColumns; ++c)
    for (size_t m = 0; m < 2; ++m) {
      const auto& rows = m == 0 ? published.orientation_mdeg : published.accel_ug;
      std::array<double, 6> v{};
      for (size_t r = 0; r < 6; ++r) v[r] = rows[r][c];
      std::array<double, 6> sorted = v;
      std::sort(sorted.begin(), sorted.end());
      const double median = 0.5 * (sorted[2] + sorted[3]);
      int kept = 0;
      for (size_t r = 0; r < 6; ++r) {
        if (v[r] > kBudgetOutlierFactor * median) {
          char text[160];
          std::snprintf(text, sizeof text, "IMU %zu, %s %s: %.2f %s, %.1fx the column's median",
                        r + 1, paper_column_name(static_cast<PaperColumn>(c)),
                        m == 0 ? "orientation" : "acceleration", v[r], m == 0 ? "mdeg" : "ug",
                        v[r] / median);
          t.left_out.push_back(text);
          continue;
        }
        t.mean_square[c][m] += v[r] * v[r];
        t.mean[c][m] += v[r];
        ++kept;
      }
      t.mean_square[c][m] /= kept;
      t.mean[c][m] /= kept;
    }
  return t;
}

std::vector<double> fit_budget_weights(const ColumnMetric& baseline,
                                       const std::vector<ColumnMetric>& gains,
                                       const BudgetTarget& target, const std::vector<double>& lo,
                                       const std::vector<double>& hi) {
  const size_t K = gains.size();
  if (lo.size() != K || hi.size() != K)
    throw std::invalid_argument("gap budget: bounds do not match the candidates");
  // Relative residuals r_j = (pred_j - T_j) / T_j, linear in x: r = a + G x (convex in x).
  constexpr int J = 2 * kNumPaperColumns;
  std::array<double, J> a{};
  std::vector<std::array<double, J>> G(K);
  for (int c = 0; c < kNumPaperColumns; ++c)
    for (int m = 0; m < 2; ++m) {
      const int j = 2 * c + m;
      const double t = target.mean_square[static_cast<size_t>(c)][static_cast<size_t>(m)];
      if (!(t > 0.0)) throw std::invalid_argument("gap budget: a target mean square is not > 0");
      a[j] = (baseline[static_cast<size_t>(c)][static_cast<size_t>(m)] - t) / t;
      for (size_t k = 0; k < K; ++k)
        G[k][j] = gains[k][static_cast<size_t>(c)][static_cast<size_t>(m)] / t;
    }
  std::vector<double> x(lo);
  std::array<double, J> r = a;
  for (size_t k = 0; k < K; ++k)
    for (int j = 0; j < J; ++j) r[j] += G[k][j] * x[k];
  // Projected coordinate descent: each step minimises exactly along one x_k within its bounds.
  for (int sweep = 0; sweep < 2000; ++sweep) {
    double largest_step = 0.0;
    for (size_t k = 0; k < K; ++k) {
      double num = 0.0, den = 0.0;
      for (int j = 0; j < J; ++j) {
        num += r[j] * G[k][j];
        den += G[k][j] * G[k][j];
      }
      if (den <= 0.0) continue;
      const double x_new = std::clamp(x[k] - num / den, lo[k], hi[k]);
      const double step = x_new - x[k];
      if (step == 0.0) continue;
      for (int j = 0; j < J; ++j) r[j] += G[k][j] * step;
      x[k] = x_new;
      largest_step = std::max(largest_step, std::abs(step) / std::max(hi[k], 1e-12));
    }
    if (largest_step < 1e-10) break;
  }
  return x;
}

double budget_share(const ColumnMetric& with, const ColumnMetric& without,
                    const ColumnMetric& baseline, const BudgetTarget& target) {
  double moved = 0.0, distance = 0.0;
  for (size_t c = 0; c < with.size(); ++c)
    for (size_t m = 0; m < 2; ++m) {
      moved += (with[c][m] - without[c][m]) / target.mean[c][m];
      distance += (target.mean[c][m] - baseline[c][m]) / target.mean[c][m];
    }
  return moved / distance;
}

PaperTablesOptions budget_model(const PaperTablesOptions& base,
                                const std::vector<BudgetCandidate>& candidates,
                                const std::vector<double>& sizes) {
  PaperTablesOptions o = base;
  o.effects = PaperEffects{};
  o.setup = PaperSetupErrors{};
  o.catalogue.clear();
  for (size_t k = 0; k < candidates.size(); ++k)
    if (sizes[k] > 0.0) candidates[k].apply(o, sizes[k]);
  return o;
}

namespace {

/// Step 1's simulations: the baseline's and each candidate's probe, per unit (same seeds).
struct Probes {
  SimUnits base;
  std::vector<SimUnits> probe;  ///< per candidate
  std::vector<double> size;     ///< the size each candidate was probed at
  std::vector<ColumnMetric> gains(const std::vector<int>& units) const {
    std::vector<ColumnMetric> g(probe.size());
    for (size_t k = 0; k < probe.size(); ++k)
      g[k] = mean_over(probe[k].squares, base.squares, units);
    return g;
  }
  /// Whether candidate k's probe raised a column's mean square by more than twice its standard
  /// error over the units (paired with the baseline's units) and, scaled to the top of its prior
  /// range, by at least 1 % of the target's there: whether it can explain any of the gap.
  bool measurable(size_t k, double prior_hi, const BudgetTarget& target) const {
    const double n = static_cast<double>(base.squares.size());
    for (int c = 0; c < kNumPaperColumns; ++c)
      for (int m = 0; m < 2; ++m) {
        const auto cs = static_cast<size_t>(c), ms = static_cast<size_t>(m);
        double sum = 0.0, sum2 = 0.0;
        for (size_t u = 0; u < base.squares.size(); ++u) {
          const double d = probe[k].squares[u][cs][ms] - base.squares[u][cs][ms];
          sum += d;
          sum2 += d * d;
        }
        const double mean = sum / n;
        const double se = n > 1 ? std::sqrt(std::max(0.0, sum2 / n - mean * mean) / (n - 1)) : 0.0;
        const double at_prior_hi = mean * std::pow(prior_hi / size[k], 2);
        if (mean > 2.0 * se && at_prior_hi >= 0.01 * target.mean_square[cs][ms]) return true;
      }
    return false;
  }
};

/// Step 3a: the surrogate's fit, x_k = (s_k / probe_k)² within the priors; returns the sizes.
std::vector<double> fit_surrogate(const Probes& pr, const std::vector<BudgetCandidate>& candidates,
                                  const BudgetTarget& target, const std::vector<bool>& can_matter) {
  std::vector<double> lo(candidates.size()), hi(candidates.size());
  for (size_t k = 0; k < candidates.size(); ++k) {
    lo[k] = std::pow(candidates[k].prior_lo / pr.size[k], 2);
    hi[k] = can_matter[k] ? std::pow(candidates[k].prior_hi / pr.size[k], 2) : 0.0;
    lo[k] = std::min(lo[k], hi[k]);
  }
  const std::vector<int> units = every_unit(pr.base.squares.size());
  std::vector<double> s =
      fit_budget_weights(mean_over(pr.base.squares, {}, units), pr.gains(units), target, lo, hi);
  for (size_t k = 0; k < s.size(); ++k) s[k] = pr.size[k] * std::sqrt(s[k]);
  return s;
}

/// Σ_cm (ln(M / T))²: what the search minimises, on mean squares. Logarithmic, so that a start
/// that overshoots a column sixteenfold (interacting sources the surrogate only added) does not
/// outweigh every other column, and a factor off counts the same either way.
double misfit(const ColumnMetric& m, const BudgetTarget& target) {
  double d = 0.0;
  for (size_t c = 0; c < m.size(); ++c)
    for (size_t j = 0; j < 2; ++j) {
      const double r = std::log(std::max(m[c][j], 1e-300) / target.mean_square[c][j]);
      d += r * r;
    }
  return d;
}

/// The whole model near the fitted sizes, linearised in q_k = (s_k / hi_k)² over the sources the
/// search may move (those that can matter): M(q') = at + Σ_k slope_k (q'_k - q_k), mean squares
/// over the search's units.
struct WholeModel {
  std::vector<double> sizes;        ///< every candidate's (0 = not in the model)
  std::vector<size_t> free;         ///< the candidates the search may move
  SimUnits at;                      ///< the whole model at `sizes`, per unit
  ColumnMetric at_mean{};           ///< its mean squares
  std::vector<ColumnMetric> slope;  ///< per free source, d(mean square) / dq
};

std::vector<double> q_of(const std::vector<BudgetCandidate>& candidates, const WholeModel& w,
                         const std::vector<double>& sizes) {
  std::vector<double> q(w.free.size());
  for (size_t a = 0; a < w.free.size(); ++a)
    q[a] = std::pow(sizes[w.free[a]] / candidates[w.free[a]].prior_hi, 2);
  return q;
}

/// The free sizes from q (the inverse of q_k = (s_k / hi_k)²) into a copy of `sizes`.
std::vector<double> sizes_from_q(const std::vector<BudgetCandidate>& candidates,
                                 const WholeModel& w, const std::vector<double>& q) {
  std::vector<double> s = w.sizes;
  for (size_t a = 0; a < w.free.size(); ++a)
    s[w.free[a]] = candidates[w.free[a]].prior_hi * std::sqrt(std::max(0.0, q[a]));
  return s;
}

/// The linear model's best q for `target` within the priors and a trust region: each size in the
/// model within a factor √ρ of the current one (a source leaves the model only geometrically, so
/// that a source whose prior is wide — the heading re-finding's, 0–1000 mdeg — cannot jump to
/// zero on one step of a poor slope), a source out of the model free to enter up to √ρ / 10 of
/// its prior's top.
std::vector<double> linear_step(const std::vector<BudgetCandidate>& candidates, const WholeModel& w,
                                const BudgetTarget& target, double rho) {
  const std::vector<double> q = q_of(candidates, w, w.sizes);
  // Gauss–Newton on the logarithmic misfit: ln(M/T) ≈ ln(M0/T) + Σ slope (q' - q) / M0, which is
  // fit_budget_weights' relative residual (pred - t') / t' for t' = M0 and a constant
  // M0 (1 + ln(M0/T)) - Σ slope q.
  const ColumnMetric& M0 = w.at_mean;
  ColumnMetric base{};
  BudgetTarget here;
  for (size_t c = 0; c < base.size(); ++c)
    for (size_t m = 0; m < 2; ++m) {
      here.mean_square[c][m] = std::max(M0[c][m], 1e-300);
      base[c][m] = here.mean_square[c][m] *
                   (1.0 + std::log(here.mean_square[c][m] / target.mean_square[c][m]));
    }
  std::vector<double> lo(q.size()), hi(q.size());
  for (size_t a = 0; a < q.size(); ++a) {
    for (size_t c = 0; c < base.size(); ++c)
      for (size_t m = 0; m < 2; ++m) base[c][m] -= w.slope[a][c][m] * q[a];
    const BudgetCandidate& cand = candidates[w.free[a]];
    const double floor = std::pow(cand.prior_lo / cand.prior_hi, 2);
    lo[a] = std::max(floor, q[a] / rho);
    hi[a] = std::min(1.0, q[a] > 0.0 ? q[a] * rho : 0.01 * rho);
    lo[a] = std::min(lo[a], hi[a]);
  }
  return fit_budget_weights(base, w.slope, here, lo, hi);
}

/// Broyden's rank-one update of the slopes from one step dq that moved the mean squares by dM:
/// the least change of the slopes that makes the linear model reproduce the step.
void broyden_update(WholeModel& w, const std::vector<double>& dq, const ColumnMetric& dM) {
  double dq2 = 0.0;
  for (double d : dq) dq2 += d * d;
  if (!(dq2 > 0.0)) return;
  for (size_t c = 0; c < dM.size(); ++c)
    for (size_t m = 0; m < 2; ++m) {
      double predicted = 0.0;
      for (size_t a = 0; a < dq.size(); ++a) predicted += w.slope[a][c][m] * dq[a];
      const double miss = dM[c][m] - predicted;
      for (size_t a = 0; a < dq.size(); ++a) w.slope[a][c][m] += miss * dq[a] / dq2;
    }
}

/// The linear model's leave-one-out share of source k (a candidate index): the gap of the whole
/// model minus the whole model with k's term taken out, as budget_share.
double linear_leave_one_out(const std::vector<BudgetCandidate>& candidates, const WholeModel& w,
                            size_t k, const BudgetTarget& target, const ColumnMetric& base_mean) {
  const auto a = std::find(w.free.begin(), w.free.end(), k);
  if (a == w.free.end()) return 0.0;
  const size_t i = static_cast<size_t>(a - w.free.begin());
  const double q = std::pow(w.sizes[k] / candidates[k].prior_hi, 2);
  // The means scale as the root of the mean squares (the units' spread kept).
  const ColumnMetric at = means_of(w.at.squares, every_unit(w.at.squares.size()));
  ColumnMetric without = at;
  for (size_t c = 0; c < without.size(); ++c)
    for (size_t m = 0; m < 2; ++m)
      without[c][m] *=
          std::sqrt(std::max(0.0, w.at_mean[c][m] - w.slope[i][c][m] * q) / w.at_mean[c][m]);
  return budget_share(at, without, base_mean, target);
}

/// Share of the gap that `with` closes against `without`, over `units` (gap measured from the
/// baseline's `gap_none`).
double share_between(const SimUnits& with, const SimUnits& without, const ColumnMetric& base_mean,
                     const BudgetTarget& target, const std::vector<int>& units) {
  return budget_share(means_of(with.squares, units), means_of(without.squares, units), base_mean,
                      target);
}

/// A leave-one-out share and its σ over resamples of the units (their draws scatter it).
void share_with_spread(const SimUnits& with, const SimUnits& without, const ColumnMetric& base_mean,
                       const BudgetTarget& target, uint64_t seed, double& share, double& sd) {
  const size_t n = with.squares.size();
  share = share_between(with, without, base_mean, target, every_unit(n));
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> pick_unit(0, static_cast<int>(n) - 1);
  std::vector<double> resampled;
  for (int r = 0; r < 200; ++r) {
    std::vector<int> units(n);
    for (int& u : units) u = pick_unit(rng);
    resampled.push_back(share_between(with, without, base_mean, target, units));
  }
  sd = spread(resampled);
}

}  // namespace

namespace {

/// One budget's simulations and its steps (fit_gap_budget, the header's steps 1–4).
class BudgetRun {
 public:
  BudgetRun(const sequences::MotionProfile& profile, const Site& site,
            const std::vector<BudgetCandidate>& candidates, const BudgetOptions& options)
      : profile_(profile),
        site_(site),
        candidates_(candidates),
        options_(options),
        K_(candidates.size()),
        total_(static_cast<int>(K_) + 1) {}

  int simulations() const { return simulations_; }
  bool converged() const { return converged_; }
  const std::vector<BudgetSearchStep>& path() const { return path_; }

  /// Step 1: the baseline and one probe per candidate, on the same seeds (the same units).
  Probes probe_all() {
    Probes pr;
    pr.base = simulate(std::vector<double>(K_, 0.0), "baseline", options_.probe_units);
    for (size_t k = 0; k < K_; ++k) {
      pr.size.push_back(candidates_[k].probe);
      std::vector<double> sizes(K_, 0.0);
      sizes[k] = candidates_[k].probe;
      pr.probe.push_back(simulate(sizes, candidates_[k].name, options_.probe_units));
    }
    return pr;
  }

  /// Step 3: the sizes searched on the whole model, from the surrogate's fit. Sources interact
  /// (a heading re-found by gyrocompassing turns every drift into heading error, steeply: the
  /// orientation metric grows tenfold between a re-finding σ of 3 and 27 mdeg under the same
  /// drift), so no fixed correction of the additive surrogate settles. A trust-region
  /// quasi-Newton search on the whole model over the search's units (more than the probes': six
  /// units' draws make a lucky or unlucky mean): the slopes of the surrogate's sources from one
  /// simulated step each, of the other sources that can matter from their probes, every
  /// simulated step updating them (Broyden), Gauss–Newton on the logarithmic misfit within a
  /// trust region (sizes within a factor 4, then 2, then 1.3); a step is kept only if the whole
  /// model there is closer to the paper, otherwise the region shrinks. Converged when a kept step
  /// improves the misfit by less than 2 % or the sizes stop moving.
  WholeModel search_whole_model(const Probes& pr, const BudgetTarget& target,
                                const std::vector<bool>& can_matter,
                                const std::vector<double>& start) {
    WholeModel w;
    w.sizes = start;
    SimUnits at;
    bool have_at = false;
    for (size_t k = 0; k < K_; ++k)
      if (candidates_[k].amplifier && can_matter[k]) {
        fit_amplifier(k, target, w.sizes, at);
        have_at = true;
      }
    for (size_t k = 0; k < K_; ++k)
      if (can_matter[k] && w.sizes[k] > 0.0) w.free.push_back(k);
    if (!have_at) {
      total_ += 1;
      at = simulate(w.sizes, "the fitted model", search_units());
    }
    set_at(w, std::move(at));
    path_.push_back({w.sizes, misfit(w.at_mean, target), true});
    if (w.free.empty()) {
      converged_ = true;
      return w;
    }
    initial_slopes(w, pr);
    constexpr int kSteps = 8;
    for (int step = 0; step < kSteps && !converged_; ++step) {
      const double before = misfit(w.at_mean, target);
      const std::vector<double> q_now = q_of(candidates_, w, w.sizes);
      bool kept = false;
      for (double rho : {16.0, 4.0, 1.7}) {
        const std::vector<double> next =
            sizes_from_q(candidates_, w, linear_step(candidates_, w, target, rho));
        if (largest_relative_move(w.sizes, next) < 0.02) {
          converged_ = true;
          break;
        }
        total_ += 1;
        SimUnits there = simulate(next, "the fitted model", search_units());
        const ColumnMetric there_mean = mean_over(there.squares, {}, every_unit(search_units()));
        learn_from_step(w, q_now, next, there_mean);
        const double after = misfit(there_mean, target);
        path_.push_back({next, after, after < before});
        if (after < before) {
          w.sizes = next;
          set_at(w, std::move(there));
          kept = true;
          converged_ = after > 0.98 * before;
          break;
        }
      }
      // No step within the smallest region improves: a local minimum of the whole model's misfit.
      if (!kept) converged_ = true;
    }
    return w;
  }

  /// Step 4's simulations: the whole model without each source whose removal the linear model
  /// puts at 2 % of the gap or more (the others' leave-one-out shares are the linear model's:
  /// a simulation would not tell them from the units' scatter). Empty SimUnits for those.
  std::vector<SimUnits> leave_one_out_runs(const WholeModel& w, const BudgetTarget& target,
                                           const ColumnMetric& base_mean) {
    std::vector<SimUnits> out(K_);
    std::vector<size_t> simulated;
    for (size_t k = 0; k < K_; ++k)
      if (w.sizes[k] > 0.0 && linear_leave_one_out(candidates_, w, k, target, base_mean) >= 0.02)
        simulated.push_back(k);
    total_ += static_cast<int>(simulated.size());
    for (size_t k : simulated) {
      std::vector<double> without = w.sizes;
      without[k] = 0.0;
      out[k] = simulate(without, "without " + candidates_[k].name, search_units());
    }
    return out;
  }

  /// The intervals (a parametric bootstrap): "papers" of six units simulated from the fitted
  /// model on seeds of their own — the scatter of six units' draws as the paper's IMUs had it —
  /// each fitted again by the whole model's local linear model. The σ of each size over them.
  std::vector<double> replicate_spread(const WholeModel& w) {
    std::vector<std::vector<double>> boot(K_);
    total_ += options_.replicates;
    for (int r = 0; r < options_.replicates; ++r) {
      PaperTablesOptions o = budget_model(options_.tables, candidates_, w.sizes);
      o.seed = options_.tables.seed + 5000 + static_cast<uint64_t>(r);
      const std::vector<ColumnMetric> paper =
          count(sim_units(run_paper_tables(profile_, site_, o)), "replicate").squares;
      BudgetTarget t;
      t.mean_square = mean_over(paper, {}, every_unit(paper.size()));
      // The priors bound the replicate's fit, not the trust region: a replicate may land anywhere.
      const std::vector<double> sb =
          sizes_from_q(candidates_, w, linear_step(candidates_, w, t, 1e12));
      for (size_t k = 0; k < K_; ++k) boot[k].push_back(sb[k]);
    }
    std::vector<double> sd(K_);
    for (size_t k = 0; k < K_; ++k) sd[k] = spread(boot[k]);
    return sd;
  }

  int search_units() const { return std::max(options_.tables.units, options_.search_units); }

  /// An amplifier's size (BudgetCandidate::amplifier) with every other source at `sizes`: the
  /// size at which the orientation columns' mean log ratio ln(M / T) to the paper is zero, by a
  /// secant search in ln(size) on the whole model (it is monotone there; at most six
  /// simulations). Sets sizes[k] and leaves the whole model there in `at`.
  void fit_amplifier(size_t k, const BudgetTarget& target, std::vector<double>& sizes,
                     SimUnits& at) {
    const BudgetCandidate& c = candidates_[k];
    const auto orientation_log_ratio = [&](double size, SimUnits& run) {
      sizes[k] = size;
      total_ += 1;
      run = simulate(sizes, c.name + " on the whole model", search_units());
      const ColumnMetric m = mean_over(run.squares, {}, every_unit(run.squares.size()));
      double r = 0.0;
      for (size_t col = 0; col < m.size(); ++col)
        r += std::log(m[col][0] / target.mean_square[col][0]) / static_cast<double>(m.size());
      return r;
    };
    const double lo = std::max(c.prior_lo, 1e-3 * c.prior_hi), hi = c.prior_hi;
    double s1 = std::clamp(0.1 * c.probe, lo, hi);
    SimUnits run1, run2;
    double r1 = orientation_log_ratio(s1, run1);
    double s2 = std::clamp(r1 < 0.0 ? 4.0 * s1 : 0.25 * s1, lo, hi);
    double r2 = orientation_log_ratio(s2, run2);
    for (int it = 0; it < 4 && std::abs(r2) > 0.05 && s2 != s1; ++it) {
      // The secant in ln(size), a step at most a factor 16.
      double ln_next = std::log(s2) - r2 * (std::log(s2) - std::log(s1)) / (r2 - r1);
      if (!std::isfinite(ln_next) || r2 == r1) ln_next = std::log(s2) + (r2 < 0.0 ? 1.0 : -1.0);
      ln_next = std::clamp(ln_next, std::log(s2) - std::log(16.0), std::log(s2) + std::log(16.0));
      const double s3 = std::clamp(std::exp(ln_next), lo, hi);
      if (s3 == s2) break;  // at a bound of the prior
      s1 = s2;
      r1 = r2;
      run1 = std::move(run2);
      s2 = s3;
      r2 = orientation_log_ratio(s2, run2);
    }
    if (std::abs(r1) < std::abs(r2)) {
      s2 = s1;
      run2 = std::move(run1);
    }
    sizes[k] = s2;
    at = std::move(run2);
  }

 private:
  void set_at(WholeModel& w, SimUnits at) const {
    w.at = std::move(at);
    w.at_mean = mean_over(w.at.squares, {}, every_unit(w.at.squares.size()));
  }

  /// The first slopes: a simulated step of 25 % in size (−20 % at the top of its prior) for each
  /// source in the surrogate's fit, the probe's gain over the baseline for the others.
  void initial_slopes(WholeModel& w, const Probes& pr) {
    const std::vector<int> probe_units = every_unit(pr.base.squares.size());
    for (size_t k : w.free)
      if (w.sizes[k] > 0.0) total_ += 1;
    for (size_t k : w.free) {
      const double hi = candidates_[k].prior_hi;
      ColumnMetric slope{};
      if (w.sizes[k] > 0.0) {
        std::vector<double> s = w.sizes;
        s[k] = w.sizes[k] * 1.25 <= hi ? w.sizes[k] * 1.25 : w.sizes[k] * 0.8;
        const double dq = (s[k] * s[k] - w.sizes[k] * w.sizes[k]) / (hi * hi);
        const SimUnits stepped = simulate(s, "slope of " + candidates_[k].name, search_units());
        slope = mean_over(stepped.squares, w.at.squares, every_unit(search_units()));
        for (auto& col : slope)
          for (double& v : col) v /= dq;
      } else {
        slope = mean_over(pr.probe[k].squares, pr.base.squares, probe_units);
        const double q_probe = std::pow(pr.size[k] / hi, 2);
        for (auto& col : slope)
          for (double& v : col) v /= q_probe;
      }
      w.slope.push_back(slope);
    }
  }

  /// Every simulated step teaches the slopes, kept or not.
  void learn_from_step(WholeModel& w, const std::vector<double>& q_now,
                       const std::vector<double>& next, const ColumnMetric& there_mean) const {
    const std::vector<double> q_next = q_of(candidates_, w, next);
    std::vector<double> dq(q_now.size());
    for (size_t a = 0; a < dq.size(); ++a) dq[a] = q_next[a] - q_now[a];
    ColumnMetric dM{};
    for (size_t c = 0; c < dM.size(); ++c)
      for (size_t m = 0; m < 2; ++m) dM[c][m] = there_mean[c][m] - w.at_mean[c][m];
    broyden_update(w, dq, dM);
  }

  double largest_relative_move(const std::vector<double>& a, const std::vector<double>& b) const {
    double moved = 0.0;
    for (size_t k = 0; k < K_; ++k)
      moved =
          std::max(moved, std::abs(b[k] - a[k]) / std::max(a[k], 0.05 * candidates_[k].prior_hi));
    return moved;
  }

  SimUnits count(SimUnits units, const std::string& what) {
    ++simulations_;
    if (options_.on_progress) options_.on_progress(simulations_, total_, what);
    return units;
  }
  SimUnits simulate(const std::vector<double>& sizes, const std::string& what, int units) {
    PaperTablesOptions o = budget_model(options_.tables, candidates_, sizes);
    o.units = units;
    return count(sim_units(run_paper_tables(profile_, site_, o)), what);
  }

  const sequences::MotionProfile& profile_;
  const Site& site_;
  const std::vector<BudgetCandidate>& candidates_;
  const BudgetOptions& options_;
  size_t K_;
  int total_;
  int simulations_ = 0;
  bool converged_ = false;
  std::vector<BudgetSearchStep> path_;
};

/// Step 4: the budget's entries and shares at the fitted sizes, largest leave-one-out share
/// first. Add-one from the probe scaled as the size squared (a source alone adds in variance);
/// leave-one-out from the whole model simulated without the source.
void assemble(GapBudget& out, const std::vector<BudgetCandidate>& candidates, const Probes& pr,
              const WholeModel& w, const std::vector<SimUnits>& without,
              const std::vector<double>& sd, const std::vector<bool>& can_matter,
              const BudgetTarget& target, uint64_t seed) {
  const std::vector<int> probe_units = every_unit(pr.base.squares.size());
  out.baseline = mean_over(pr.base.squares, {}, probe_units);
  out.predicted = w.at_mean;
  const double gap_none = gap_size(means_of(pr.base.squares, probe_units), target.mean);
  out.baseline_mean = means_of(pr.base.squares, probe_units);
  out.explained_share =
      1.0 -
      gap_size(means_of(w.at.squares, every_unit(w.at.squares.size())), target.mean) / gap_none;
  for (size_t k = 0; k < candidates.size(); ++k) {
    BudgetEntry e;
    e.candidate = candidates[k];
    e.size = w.sizes[k];
    e.measurable = can_matter[k];
    e.calibration_shift_sigma = shift_in_sigma(pr.probe[k], pr.base) * w.sizes[k] / pr.size[k];
    const double lo = candidates[k].prior_lo, hi = candidates[k].prior_hi;
    e.size_lo = e.measurable ? std::max(lo, w.sizes[k] - sd[k]) : lo;
    e.size_hi = e.measurable ? std::min(hi, w.sizes[k] + sd[k]) : hi;
    if (w.sizes[k] > 0.0) {
      ColumnMetric alone = mean_over(pr.probe[k].squares, pr.base.squares, probe_units);
      const double x = std::pow(w.sizes[k] / pr.size[k], 2);
      for (size_t c = 0; c < alone.size(); ++c)
        for (size_t m = 0; m < 2; ++m) alone[c][m] = out.baseline[c][m] + x * alone[c][m];
      e.share_add_one =
          budget_share(square_roots(alone), out.baseline_mean, out.baseline_mean, target);
      e.share_simulated = !without[k].squares.empty();
      if (e.share_simulated)
        share_with_spread(w.at, without[k], out.baseline_mean, target, seed + k,
                          e.share_leave_one_out, e.share_leave_one_out_sd);
      else
        e.share_leave_one_out = linear_leave_one_out(candidates, w, k, target, out.baseline_mean);
    }
    out.entries.push_back(std::move(e));
  }
  std::stable_sort(out.entries.begin(), out.entries.end(),
                   [](const BudgetEntry& a, const BudgetEntry& b) {
                     return a.share_leave_one_out > b.share_leave_one_out;
                   });
}

}  // namespace

GapBudget fit_gap_budget(const sequences::MotionProfile& profile, const Site& site,
                         const std::vector<BudgetCandidate>& candidates,
                         const PaperPublished& published, const BudgetOptions& options) {
  if (candidates.empty()) throw std::invalid_argument("gap budget: no candidate");
  if (options.probe_units < 1 || options.search_units < 1 || options.replicates < 0)
    throw std::invalid_argument(
        "gap budget: probe and search units must be at least 1, replicates at least 0");
  for (const BudgetCandidate& c : candidates)
    if (!(c.probe > 0.0) || !(c.prior_hi > c.prior_lo) || c.prior_lo < 0.0)
      throw std::invalid_argument("gap budget: candidate " + c.name +
                                  " needs a probe > 0 and a prior range 0 <= lo < hi");
  const auto t0 = std::chrono::steady_clock::now();
  BudgetRun run(profile, site, candidates, options);
  Probes pr = run.probe_all();
  const BudgetTarget target = budget_target(published);
  std::vector<bool> can_matter(candidates.size());
  for (size_t k = 0; k < candidates.size(); ++k)
    can_matter[k] = pr.measurable(k, candidates[k].prior_hi, target);
  // The amplifiers act on what the other sources put in: the surrogate, which only adds, sizes
  // the others without them, the search then sizes each amplifier on the whole model first.
  std::vector<bool> additive = can_matter;
  for (size_t k = 0; k < candidates.size(); ++k)
    if (candidates[k].amplifier) additive[k] = false;
  const WholeModel w = run.search_whole_model(pr, target, can_matter,
                                              fit_surrogate(pr, candidates, target, additive));
  const ColumnMetric base_mean = means_of(pr.base.squares, every_unit(pr.base.squares.size()));
  const std::vector<SimUnits> without = run.leave_one_out_runs(w, target, base_mean);
  const std::vector<double> sd = run.replicate_spread(w);

  GapBudget out;
  out.target = target.mean_square;
  out.target_mean = target.mean;
  out.target_left_out = target.left_out;
  assemble(out, candidates, pr, w, without, sd, can_matter, target, options.tables.seed);
  out.probe_units = options.probe_units;
  out.search_units = run.search_units();
  out.simulations = run.simulations();
  out.converged = run.converged();
  out.search_path = run.path();
  out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace imucal::calib::studies::paper
