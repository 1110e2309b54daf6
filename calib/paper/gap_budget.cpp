#include "calib/paper/gap_budget.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <random>
#include <stdexcept>

#include "calib/core/conventions.hpp"

namespace imucal::calib {

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

/// Σ_cm |T - pred| / T: how far a prediction is from the paper (the gap's size).
double gap_size(const ColumnMetric& predicted, const ColumnMetric& target) {
  double d = 0.0;
  for (int c = 0; c < kNumPaperColumns; ++c)
    for (int m = 0; m < 2; ++m) {
      const double t = target[static_cast<size_t>(c)][static_cast<size_t>(m)];
      d += std::abs(t - predicted[static_cast<size_t>(c)][static_cast<size_t>(m)]) / t;
    }
  return d;
}

ColumnMetric plus(ColumnMetric a, const ColumnMetric& b) {
  for (size_t c = 0; c < a.size(); ++c)
    for (size_t m = 0; m < 2; ++m) a[c][m] += b[c][m];
  return a;
}

/// 0, 1, …, n - 1: every unit once.
std::vector<int> every_unit(size_t n) {
  std::vector<int> units(n);
  for (size_t u = 0; u < n; ++u) units[u] = static_cast<int>(u);
  return units;
}

/// The surrogate (header, step 2) at weights x.
ColumnMetric surrogate(const ColumnMetric& baseline, const std::vector<ColumnMetric>& gains,
                       const std::vector<double>& x) {
  ColumnMetric out = baseline;
  for (size_t k = 0; k < gains.size(); ++k)
    for (int c = 0; c < kNumPaperColumns; ++c)
      for (int m = 0; m < 2; ++m)
        out[static_cast<size_t>(c)][static_cast<size_t>(m)] +=
            x[k] * gains[k][static_cast<size_t>(c)][static_cast<size_t>(m)];
  return out;
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
  for (const EffectInfo& info : effect_catalogue()) {
    BudgetCandidate c;
    c.name = info.name;
    c.unit = "x typical";
    c.probe = 3.0;
    c.prior_hi = 5.0;
    c.prior_source = "effects catalogue's typical navigation-grade size (DESIGN §7), 0-5x";
    const EffectId id = info.id;
    c.apply = [id](PaperTablesOptions& o, double size) {
      if (size > 0.0) o.catalogue.push_back({id, size});
    };
    out.push_back(std::move(c));
  }
  return out;
}

BudgetTarget budget_target(const PaperPublished& published) {
  BudgetTarget t;
  for (size_t r = 0; r < 6; ++r)
    for (size_t c = 0; c < kNumPaperColumns; ++c) {
      const double o = published.orientation_mdeg[r][c], a = published.accel_ug[r][c];
      t.mean_square[c][0] += o * o / 6.0;
      t.mean_square[c][1] += a * a / 6.0;
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
  /// What the sources do together beyond the sum of what each does alone (the full model's
  /// simulation minus the surrogate at the last fit), held fixed in the next fit.
  ColumnMetric interaction{};
  ColumnMetric baseline(const std::vector<int>& units) const {
    return plus(mean_over(base.squares, {}, units), interaction);
  }
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

/// Fits x_k = (s_k / probe_k)² within the priors; returns the sizes s_k.
std::vector<double> fit_sizes(const Probes& pr, const std::vector<BudgetCandidate>& candidates,
                              const std::vector<int>& units, const BudgetTarget& target,
                              const std::vector<bool>& can_matter) {
  std::vector<double> lo(candidates.size()), hi(candidates.size());
  for (size_t k = 0; k < candidates.size(); ++k) {
    lo[k] = std::pow(candidates[k].prior_lo / pr.size[k], 2);
    hi[k] = can_matter[k] ? std::pow(candidates[k].prior_hi / pr.size[k], 2) : 0.0;
    lo[k] = std::min(lo[k], hi[k]);
  }
  std::vector<double> s = fit_budget_weights(pr.baseline(units), pr.gains(units), target, lo, hi);
  for (size_t k = 0; k < s.size(); ++k) s[k] = pr.size[k] * std::sqrt(s[k]);
  return s;
}

/// Step 4 for one candidate: its shares of the gap at the fitted sizes (surrogate).
void set_shares(BudgetEntry& e, size_t k, const GapBudget& b,
                const std::vector<ColumnMetric>& gains, const std::vector<double>& x) {
  const double gap_none = gap_size(b.baseline, b.target);
  const double gap_full = gap_size(b.predicted, b.target);
  std::vector<double> alone(x.size(), 0.0), without = x;
  alone[k] = x[k];
  without[k] = 0.0;
  e.share_add_one = 1.0 - gap_size(surrogate(b.baseline, gains, alone), b.target) / gap_none;
  // Without k, the interaction term stays (it is the whole model's, attributed to no one source).
  e.share_leave_one_out =
      (gap_size(surrogate(plus(b.baseline, b.interaction), gains, without), b.target) - gap_full) /
      gap_none;
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

  /// The interaction term: the whole model at `sizes` simulated on the probes' seeds, minus the
  /// additive surrogate there.
  void set_interaction(Probes& pr, const std::vector<int>& units,
                       const std::vector<double>& sizes) {
    const ColumnMetric whole = mean_over(simulate(sizes, "the fitted model").squares, {}, units);
    std::vector<double> x(K_);
    for (size_t k = 0; k < K_; ++k) x[k] = std::pow(sizes[k] / pr.size[k], 2);
    pr.interaction = ColumnMetric{};
    const ColumnMetric sum = surrogate(pr.baseline(units), pr.gains(units), x);
    for (size_t c = 0; c < whole.size(); ++c)
      for (size_t m = 0; m < 2; ++m) pr.interaction[c][m] = whole[c][m] - sum[c][m];
  }

  /// Step 1: the baseline and one probe per candidate, on the same seeds (the same units).
  Probes probe_all() {
    Probes pr;
    pr.base = simulate(std::vector<double>(K_, 0.0), "baseline");
    for (size_t k = 0; k < K_; ++k) {
      pr.size.push_back(candidates_[k].probe);
      pr.probe.push_back(probe_at(k, candidates_[k].probe));
    }
    return pr;
  }

  /// Step 3, twice: the metrics need not grow exactly as the size squared (a field calibration
  /// degrades faster under a large effect), so every source the first fit keeps is probed again
  /// at its fitted size and the fit repeated there.
  std::vector<double> fit_refined(Probes& pr, const std::vector<int>& units,
                                  const BudgetTarget& target, const std::vector<bool>& can_matter) {
    std::vector<double> sizes = fit_sizes(pr, candidates_, units, target, can_matter);
    std::vector<size_t> again;
    for (size_t k = 0; k < K_; ++k)
      if (sizes[k] > 0.0 && std::abs(sizes[k] - pr.size[k]) > 0.2 * pr.size[k]) again.push_back(k);
    total_ += static_cast<int>(again.size());
    for (size_t k : again) {
      pr.size[k] = std::max(sizes[k], 0.05 * candidates_[k].prior_hi);
      pr.probe[k] = probe_at(k, pr.size[k]);
    }
    if (!again.empty()) sizes = fit_sizes(pr, candidates_, units, target, can_matter);
    return fit_with_interactions(pr, units, target, can_matter, sizes);
  }

  /// The surrogate adds the sources' mean squares; sources interact (a heading re-found by
  /// gyrocompassing turns every gyro drift into a heading error). So the fitted model is
  /// simulated whole on the probes' seeds, what it does beyond the sum is held as an interaction
  /// term and the fit repeated — until the sizes move less than 5 % (at most four rounds).
  std::vector<double> fit_with_interactions(Probes& pr, const std::vector<int>& units,
                                            const BudgetTarget& target,
                                            const std::vector<bool>& can_matter,
                                            std::vector<double> sizes) {
    constexpr int kRounds = 4;
    total_ += kRounds;
    for (int round = 0; round < kRounds; ++round) {
      set_interaction(pr, units, sizes);
      const std::vector<double> next = fit_sizes(pr, candidates_, units, target, can_matter);
      double moved = 0.0;
      for (size_t k = 0; k < K_; ++k)
        moved = std::max(moved, std::abs(next[k] - sizes[k]) /
                                    std::max(sizes[k], 0.05 * candidates_[k].prior_hi));
      if (moved < 0.05) {
        total_ -= kRounds - 1 - round;
        settled_ = true;
        return next;
      }
      sizes = next;
    }
    // Not settled (the interaction grows with the sizes, so a fixed term overshoots and the fit
    // swings): keep the last sizes, and the interaction of the whole model at exactly those, so
    // that what the budget predicts is what the fitted model does on the probes' seeds.
    total_ += 1;
    set_interaction(pr, units, sizes);
    return sizes;
  }

  bool interactions_settled() const { return settled_; }

  /// The intervals (a parametric bootstrap): "papers" simulated from the fitted model on seeds of
  /// their own, each fitted again with the simulated units resampled — the scatter of six units'
  /// draws as the paper's IMUs had it, and the probes' own. The σ of each size over them.
  std::vector<double> replicate_spread(const Probes& pr, const std::vector<double>& sizes,
                                       const std::vector<bool>& can_matter) {
    std::vector<std::vector<double>> boot(K_);
    total_ += options_.replicates;
    std::mt19937_64 rng(options_.tables.seed * 31ULL + 7ULL);
    const size_t n = pr.base.squares.size();
    std::uniform_int_distribution<int> pick_unit(0, static_cast<int>(n) - 1);
    for (int r = 0; r < options_.replicates; ++r) {
      PaperTablesOptions o = budget_model(options_.tables, candidates_, sizes);
      o.seed = options_.tables.seed + 5000 + static_cast<uint64_t>(r);
      const std::vector<ColumnMetric> paper =
          count(sim_units(run_paper_tables(profile_, site_, o)), "replicate").squares;
      std::vector<int> units(n);
      for (int& u : units) u = pick_unit(rng);
      BudgetTarget t;
      t.mean_square = mean_over(paper, {}, every_unit(paper.size()));
      const std::vector<double> sb = fit_sizes(pr, candidates_, units, t, can_matter);
      for (size_t k = 0; k < K_; ++k) boot[k].push_back(sb[k]);
    }
    std::vector<double> sd(K_);
    for (size_t k = 0; k < K_; ++k) sd[k] = spread(boot[k]);
    return sd;
  }

 private:
  SimUnits count(SimUnits units, const std::string& what) {
    ++simulations_;
    if (options_.on_progress) options_.on_progress(simulations_, total_, what);
    return units;
  }
  SimUnits simulate(const std::vector<double>& sizes, const std::string& what) {
    return count(sim_units(run_paper_tables(profile_, site_,
                                            budget_model(options_.tables, candidates_, sizes))),
                 what);
  }
  SimUnits probe_at(size_t k, double size) {
    std::vector<double> sizes(K_, 0.0);
    sizes[k] = size;
    return simulate(sizes, candidates_[k].name);
  }

  const sequences::MotionProfile& profile_;
  const Site& site_;
  const std::vector<BudgetCandidate>& candidates_;
  const BudgetOptions& options_;
  size_t K_;
  int total_;
  int simulations_ = 0;
  bool settled_ = false;
};

/// Step 4: the budget's entries and shares at the fitted sizes, largest add-one share first.
void assemble(GapBudget& out, const std::vector<BudgetCandidate>& candidates, const Probes& pr,
              const std::vector<double>& sizes, const std::vector<double>& sd,
              const std::vector<bool>& can_matter) {
  const std::vector<int> all_units = every_unit(pr.base.squares.size());
  const std::vector<ColumnMetric> gains = pr.gains(all_units);
  std::vector<double> x(sizes.size());
  for (size_t k = 0; k < sizes.size(); ++k) x[k] = std::pow(sizes[k] / pr.size[k], 2);
  out.baseline = mean_over(pr.base.squares, {}, all_units);
  out.interaction = pr.interaction;
  out.predicted = surrogate(pr.baseline(all_units), gains, x);
  out.explained_share =
      1.0 - gap_size(out.predicted, out.target) / gap_size(out.baseline, out.target);
  for (size_t k = 0; k < sizes.size(); ++k) {
    BudgetEntry e;
    e.candidate = candidates[k];
    e.size = sizes[k];
    e.measurable = can_matter[k];
    e.calibration_shift_sigma = shift_in_sigma(pr.probe[k], pr.base) * sizes[k] / pr.size[k];
    const double lo = candidates[k].prior_lo, hi = candidates[k].prior_hi;
    e.size_lo = e.measurable ? std::max(lo, sizes[k] - sd[k]) : lo;
    e.size_hi = e.measurable ? std::min(hi, sizes[k] + sd[k]) : hi;
    set_shares(e, k, out, gains, x);
    out.entries.push_back(std::move(e));
  }
  std::stable_sort(
      out.entries.begin(), out.entries.end(),
      [](const BudgetEntry& a, const BudgetEntry& b) { return a.share_add_one > b.share_add_one; });
}

}  // namespace

GapBudget fit_gap_budget(const sequences::MotionProfile& profile, const Site& site,
                         const std::vector<BudgetCandidate>& candidates,
                         const PaperPublished& published, const BudgetOptions& options) {
  if (candidates.empty()) throw std::invalid_argument("gap budget: no candidate");
  for (const BudgetCandidate& c : candidates)
    if (!(c.probe > 0.0) || !(c.prior_hi >= c.prior_lo) || c.prior_lo < 0.0)
      throw std::invalid_argument("gap budget: candidate " + c.name +
                                  " needs a probe > 0 and a prior range 0 <= lo <= hi");
  const auto t0 = std::chrono::steady_clock::now();
  BudgetRun run(profile, site, candidates, options);
  Probes pr = run.probe_all();
  const BudgetTarget target = budget_target(published);
  std::vector<bool> can_matter(candidates.size());
  for (size_t k = 0; k < candidates.size(); ++k)
    can_matter[k] = pr.measurable(k, candidates[k].prior_hi, target);
  const std::vector<double> sizes =
      run.fit_refined(pr, every_unit(pr.base.squares.size()), target, can_matter);
  const std::vector<double> sd = run.replicate_spread(pr, sizes, can_matter);

  GapBudget out;
  out.target = target.mean_square;
  assemble(out, candidates, pr, sizes, sd, can_matter);
  out.simulations = run.simulations();
  out.interactions_settled = run.interactions_settled();
  out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace imucal::calib
