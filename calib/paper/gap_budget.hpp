#pragma once
// The gap budget against the paper (issue #26): which error sources, at which sizes, turn the
// simulated Tables I–IV (calib/paper/paper_tables.hpp) into the published ones.
//
// Method (an approximate simulation-based inference, stated so that it can be checked):
//  1. Probe: the six simulated units are run once without any candidate (the baseline) and once
//     with each candidate alone at a probe size, on the same seeds (common random numbers, so the
//     difference is the candidate's own contribution and not a new noise draw).
//  2. Surrogate: independent error sources add in variance, so for each table column c and metric
//     m the mean over the units of the squared metric is modelled as
//         E[M²_cm](s) = B_cm + Σ_k (s_k / probe_k)² (P_kcm - B_cm),
//     B the baseline's and P_k the probe's mean square. Checked afterwards by simulating the
//     fitted model (the "verification" row: the surrogate's error shows there).
//  3. Fit: the sizes s_k within their prior ranges minimising Σ_cm ((E[M²_cm] - T_cm) / T_cm)²,
//     T the published mean square over the six IMUs — a convex problem in s_k², solved by
//     projected coordinate descent. Sources interact (a heading re-found at every rest turns gyro
//     drift into heading error), so the fitted model is then simulated whole, what it does beyond
//     the sum is held as an interaction term and the fit repeated until the sizes settle. Every
//     source the fit keeps is probed again at its fitted size and the fit repeated (the metrics
//     need not grow exactly as the size squared). Intervals (±1σ): a parametric bootstrap — papers
//     simulated from the fitted model on seeds of their own, each fitted again with the probes'
//     units resampled (six units' random draws scatter a mean square by tens of per cent: the
//     paper's IMUs had theirs too).
//  4. Shares: the part of the gap Σ_cm (T_cm - B_cm)/T_cm that each source closes alone (add-one)
//     and that is lost without it (leave-one-out).
#include <functional>
#include <string>
#include <vector>

#include "calib/paper/paper_tables.hpp"

namespace imucal::calib {

/// One candidate error source: a catalogue effect or one of the set-up's (PaperSetupErrors).
struct BudgetCandidate {
  std::string name;       ///< "uncalibrated_gyro_bias", a catalogue name, ...
  std::string unit;       ///< the human unit of its size ("deg/h", "mdeg", "x typical")
  double probe = 1.0;     ///< the size of the probe run (human unit)
  double prior_lo = 0.0;  ///< the prior range of its size (human unit)
  double prior_hi = 1.0;
  std::string prior_source;  ///< where the range comes from, in words
  /// Sets the source at `size` (human unit) in the paper-tables options.
  std::function<void(PaperTablesOptions&, double size)> apply;
};

/// The default candidates: the set-up's sources of §I, §VI–VII and the effects catalogue.
std::vector<BudgetCandidate> default_budget_candidates();

/// The paper's tables reduced to what the budget fits: per column and metric (0 orientation,
/// 1 acceleration), the mean square over the IMUs of the published values.
struct BudgetTarget {
  std::array<std::array<double, 2>, kNumPaperColumns> mean_square{};
};
/// From the per-IMU published values (rows 0–5 of PaperPublished, IMU 1–6).
BudgetTarget budget_target(const PaperPublished& published);

struct BudgetOptions {
  PaperTablesOptions tables;  ///< units, seed, threads, rate (effects and setup are the budget's)
  /// Papers simulated from the fitted model for the intervals (a parametric bootstrap).
  int replicates = 10;
  /// Called after each simulation with (done, total) and what it was.
  std::function<void(int, int, const std::string&)> on_progress;
};

struct BudgetEntry {
  BudgetCandidate candidate;
  double size = 0.0;                    ///< fitted, human unit
  double size_lo = 0.0, size_hi = 0.0;  ///< size ∓ the bootstrap's σ, within the prior
  double share_add_one = 0.0;           ///< of the gap, this source alone
  double share_leave_one_out = 0.0;     ///< of the gap, lost without this source
  /// false: at its probe size the source raised no column's metric beyond twice the standard
  /// error over the units — it cannot explain any gap, its size is not identifiable (0 in the
  /// fit, the interval the whole prior).
  bool measurable = true;
  /// How far the source moves the factory AINS's evaluated parameters at the fitted size: RMS over
  /// the units and the 24 unit parameters of the shift from the baseline's, in the baseline's σ
  /// (measured at the probe size, scaled linearly). ≥ 1: it biases a calibration (fix it in the
  /// model); below: it only degrades the evaluation metric (fix it in the fixture or the
  /// evaluation).
  double calibration_shift_sigma = 0.0;
  bool biases_calibration() const { return calibration_shift_sigma >= 1.0; }
};

struct GapBudget {
  std::vector<BudgetEntry> entries;  ///< sorted by share_add_one, largest first
  std::array<std::array<double, 2>, kNumPaperColumns> baseline{};   ///< mean square, no source
  std::array<std::array<double, 2>, kNumPaperColumns> target{};     ///< the paper's mean square
  std::array<std::array<double, 2>, kNumPaperColumns> predicted{};  ///< the surrogate at the fit
  /// The sources together beyond their sum (whole model simulated minus the additive surrogate).
  std::array<std::array<double, 2>, kNumPaperColumns> interaction{};
  double explained_share = 0.0;  ///< of the gap, closed by the fitted model (surrogate)
  /// false: with the interaction term the fit kept swinging for four rounds; the sizes are the
  /// last round's and `predicted` is the whole model at them (the probes' seeds).
  bool interactions_settled = false;
  int simulations = 0;
  double wall_s = 0.0;
};

/// Probes every candidate, fits their sizes to the published rows 0–5 (IMU 1–6) and bootstraps
/// the intervals. K + 1 simulations, one more per source kept, and `replicates`. Throws
/// std::invalid_argument for no candidate or a probe <= 0.
GapBudget fit_gap_budget(const sequences::MotionProfile& profile, const Site& site,
                         const std::vector<BudgetCandidate>& candidates,
                         const PaperPublished& published, const BudgetOptions& options);

/// The fit alone (step 3), on given baseline and probe mean squares: x_k = (s_k / probe_k)² within
/// [lo_k, hi_k]. Exposed for tests.
std::vector<double> fit_budget_weights(
    const std::array<std::array<double, 2>, kNumPaperColumns>& baseline,
    const std::vector<std::array<std::array<double, 2>, kNumPaperColumns>>& gains,
    const BudgetTarget& target, const std::vector<double>& lo, const std::vector<double>& hi);

/// The paper-tables options with every candidate at its fitted size (sizes in candidates' order).
PaperTablesOptions budget_model(const PaperTablesOptions& base,
                                const std::vector<BudgetCandidate>& candidates,
                                const std::vector<double>& sizes);

}  // namespace imucal::calib
