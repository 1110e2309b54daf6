#pragma once
// Sim-to-real gap diagnosis (ARCHITECTURE §8, issue #8): where a recorded run departs from the
// model (calibrated parameters + declared noise), which unmodelled effect of the catalogue
// (calib/effects/catalogue.hpp) explains it, and how far the gap shrinks once that effect is
// modelled, on held-out segments.
//
//  1. Localise: the segment residuals of calib/diagnosis/gap_model.hpp after refitting the base
//  parameters,
//     normalised by the model's own predicted spread (leverage included), per segment × sensor
//     axis; per segment the NIS against χ²; overall χ²/dof against its expectation 1.
//  2. Attribute: each candidate effect is refitted jointly with the 27 base parameters (linearised
//  at
//     the calibrated point, Jacobians by differences of the same residual model), scored by the
//     likelihood ratio (χ² drop, whitened residuals) and BIC. Candidate directions whose multiple
//     correlation with the base parameters exceeds 0.95 are not separable on this sequence and are
//     left out of its fit; a candidate left with none is reported as not separable, with the base
//     parameters it aliases, never as a finding; two candidates whose signatures correlate > 0.95
//     are not separable from each other.
//  A table-free run (land, by hand; issue #21) is diagnosed the same way with each rest's attitude
//  an unknown of every fit (calib/diagnosis/gap_model.hpp): the base columns are then the 24 sensor
//  parameters and those attitudes, and the held-out check leaves out what only the held-out move
//  measures (its relative heading). A sea run has no still rest: its residuals are the navigation
//  filter's GNSS innovations under each hypothesis (gap_model.hpp, "Sea runs"), the base columns
//  the 24 sensor parameters.
//  3. Explain stepwise (issue #22 item 2): from the best finding, forward selection adds at each
//     step the candidate that predicts the held-out segments best among those whose likelihood
//     ratio, given the effects already chosen, passes the candidates' level and that shrink the
//     held-out gap; it stops when none does (what is left is consistent with the model as far as
//     any candidate can tell, or nothing separable is left). A set of candidates the sequence
//     cannot tell apart (K2 | asymmetry) enters as one candidate, named as the set (issue #49
//     item 2). Then each member must earn its place in the final joint fit (issue #49 item 1):
//     significant given all the others refitted, at least 2σ from zero, plausible for the grade
//     (EffectInfo::plausible_max), and needed by the held-out gap; one that is not is dropped and
//     reported as "fitted, not supported" with its reason. A noise candidate (an undeclared
//     Gauss-Markov bias) comes last (issue #49 item 3): after the deterministic effects only if the
//     set still needs it and it the set, alone only when no deterministic effect earned a place.
//  4. Quantify: the gap on held-out segments (K-fold over rests and the moves after them) before
//     and after each step; the base parameters that move, in σ.
#include <array>
#include <cstdint>
#include <limits>
#include <optional>
#include <string>
#include <vector>

#include "calib/core/param_set.hpp"
#include "calib/diagnosis/false_alarm.hpp"
#include "calib/diagnosis/gap_model.hpp"
#include "calib/diagnosis/whiteness.hpp"
#include "calib/effects/catalogue.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::core;
using namespace calib::effects;

struct DiagnosisOptions {
  /// Candidate effects (default: the whole catalogue).
  std::vector<EffectId> candidates;
  /// Family-wise significance: a candidate counts when its likelihood ratio's p-value is below
  /// alpha / (number of candidates) (Bonferroni); the run counts as consistent when the overall χ²
  /// has p >= alpha.
  double alpha = 1e-3;
  /// A finding must shrink the held-out gap: the best effect (pair, or an ambiguous set) counts as
  /// an explanation only when it removes at least this fraction of the held-out gap's excess,
  /// (before - after) / (before - 1). Below it the run is judged as if no candidate were
  /// significant (a significant gap is then "unexplained", and the summary names no effect): an
  /// effect that fits a few segments' noise better but predicts none of the held-out segments is
  /// not a cause (issue #28: a null run was "explained" by a latitude error that shrank the
  /// held-out gap by 3 %).
  double min_shrinkage = 0.5;
  double separability_limit = 0.95;
  /// A candidate direction that correlates above separability_limit but at most this much with the
  /// base parameters is fitted with the candidate's separable directions (its values are not
  /// resolved and the note says so): left out, its remainder (1 - ρ² of its signature) is a gap
  /// that another candidate takes (issue #21: a MEMS unit's K2 on hand-placed positions, its z
  /// direction at 0.972, was named after a wandering bias). Above it the direction is near
  /// degenerate (variance inflated more than 100×) and stays out.
  double fit_limit = 0.995;
  /// A candidate's fitted size above this many times its catalogue typical (navigation-grade) size
  /// is not physically plausible: not a finding however significant its fit (a K2 run's leakage
  /// read as a 4.6 m size effect). It is multiplied by the unit's grade's effect_scale
  /// (calib/core/unit_grade.hpp: 1 navigation, 100 tactical, 10⁴ MEMS). A fitted size counts as
  /// beyond it only when it is so by more than 2σ of its own.
  double max_plausible_typical = 50.0;
  int folds = 5;
  size_t min_rest_samples = 100;
  /// Time constants searched for the thermal warm-up (its shape parameter), s.
  std::vector<double> thermal_tau_grid_s = {300.0, 600.0, 1200.0, 2400.0};
  /// Correlation times searched for an undeclared Gauss-Markov bias, s.
  std::vector<double> instability_tau_grid_s = {300.0, 1000.0, 3000.0};
  uint64_t twin_seed = 1;  ///< noise seed of the simulated twin
};

struct SegmentGap {
  GapSegment segment;
  /// Post-fit residual of each component over its predicted spread (leverage included): N(0, 1)
  /// under the model. Components: gap_component_name().
  std::array<double, kGapRowsPerSegment> z{};
  std::array<double, kGapRowsPerSegment> residual_si{};  ///< raw post-fit residual
  double nis = 0.0;           ///< whitened χ² of the segment after the fit
  double nis_expected = 0.0;  ///< its expectation under the model (6 - leverage)
  double nis_twin =
      0.0;  ///< the same segment's NIS on the simulated twin (calib/diagnosis/simulated_twin.hpp)
  double p_value = 1.0;  ///< P(χ²(6) > nis·6/expected)
};

struct CandidateParam {
  std::string name, unit;           ///< human unit
  double value = 0.0, sigma = 0.0;  ///< human units
};

struct CandidateResult {
  EffectId id{};
  std::string name;
  bool separable = false;  ///< has at least one direction separable from the base (and fitted)
  std::string note;        ///< why not separable / partly separable / confounded, empty if clean
  int k = 0;               ///< parameter directions fitted
  double lr = 0.0;         ///< χ² drop when added (likelihood ratio statistic)
  double p_value = 1.0;    ///< P(χ²(k) > lr)
  double bic_gain = 0.0;   ///< lr - k ln(rows)
  /// p_value < alpha / candidates, separable from the base and from every other significant
  /// candidate, and of a plausible size: a finding on its own.
  bool significant = false;
  /// Significant by its test and plausible, but another such candidate mimics it on this sequence
  /// (confounded_with): the two explain the gap as a set, neither alone.
  bool in_ambiguous_set = false;
  /// size - 2σ ≤ max_plausible_typical × its catalogue typical size
  bool plausible = true;
  double typical_ratio = std::numeric_limits<double>::quiet_NaN();  ///< magnitude / typical
  double magnitude = 0.0, magnitude_sigma = 0.0;
  std::string unit;  ///< unit of magnitude
  std::vector<CandidateParam> params;
  Eigen::VectorXd value_si;   ///< estimated effect parameter vector (SI, shape parameters set)
  double held_out_gap = 0.0;  ///< held-out gap ratio with this candidate added
  /// For a candidate judged on a statistic of its own (quantisation: the lag-1 autocovariance), the
  /// held-out gap of that statistic without it; NaN for the others (the segment gap applies).
  double held_out_gap_before = std::numeric_limits<double>::quiet_NaN();
  double max_correlation = 0.0;  ///< largest multiple correlation of its directions with the base
  /// Whitened χ² of the segment residuals with the candidate added (for a Gauss-Markov bias: under
  /// its covariance); NaN when it does not change the segment residuals (quantisation).
  double chi2_after = std::numeric_limits<double>::quiet_NaN();
  std::vector<std::string> confounded_with;  ///< other candidates it cannot be told from
};

/// One step of the stepwise explanation (forward selection, issue #22 item 2): the effect added,
/// its size in the joint fit of the whole explained set, and the gap once it is added.
struct DiagnosisStep {
  size_t candidate = 0;  ///< index into DiagnosisResult::candidates
  std::string effect;
  /// Its size and parameters fitted jointly with every other step's effect (and the base); for a
  /// noise candidate (bias instability, quantisation) its own fit.
  double magnitude = 0.0, magnitude_sigma = 0.0;
  std::string unit;
  std::vector<CandidateParam> params;
  double p_value = 1.0;  ///< its likelihood-ratio test given the steps before it
  /// Overall χ²/dof once it is added (NaN for quantisation, which changes no segment residual).
  double gap_after = std::numeric_limits<double>::quiet_NaN();
  /// Held-out gap once it is added (quantisation: its own statistic's).
  double held_out_after = std::numeric_limits<double>::quiet_NaN();
  /// Empty, or why this finding is less certain than its test says (a trend that the bias
  /// instability named after it would explain as well).
  std::string note;
  /// The other members of a set this sequence cannot tell apart that the step stands for (issue #49
  /// item 2: "accel_quadratic_k2 | accel_asymmetry"); its size is that of `effect`, the member that
  /// predicts the held-out segments best. Empty for a single effect.
  std::vector<std::string> set;
};

/// A member of the stepwise explanation that was fitted but is not supported (issue #49 item 1):
/// in the final joint fit of the set it fails one of the tests a named effect must pass — its size
/// significant given all the others refitted and at least 2σ from zero, plausible for the unit's
/// grade, and leaving it out worsens the held-out gap. Dropped from the explanation, reported.
struct UnsupportedEffect {
  std::string effect;
  double magnitude = 0.0, magnitude_sigma = 0.0;  ///< its size in the joint fit it failed in
  std::string unit;
  double p_value = 1.0;  ///< its likelihood-ratio test given all the others refitted
  std::string reason;    ///< every test it failed, for people
};

struct ParamShift {
  std::string name, unit;
  double shift_sigma = 0.0;  ///< change when the best effect is added, in σ of the base fit
  double shift = 0.0;        ///< in human units
};

struct DiagnosisResult {
  std::string verdict;  ///< "consistent", "explained", "unexplained"
  std::string summary;  ///< one sentence for people
  std::vector<SegmentGap> segments;
  /// The segments' residual components (SegmentGap::z in this order): "accel x" ... "gyro z", at
  /// sea "gnss north", "gnss east"; and their JSON keys ("accel_x", "gnss_north").
  std::vector<std::string> components, component_keys;
  /// The residuals are the navigation filter's GNSS innovations (a sea run), not rest and move
  /// residuals.
  bool innovation_residuals = false;
  int rows = 0, dof = 0;
  double chi2 = 0.0;
  double overall_gap = 0.0;       ///< χ²/dof after the base fit
  double overall_expected = 1.0;  ///< its expectation under the model
  double overall_sigma = 0.0;     ///< its spread under the model, sqrt(2/dof)
  double overall_p = 1.0;
  /// χ²/dof of the simulated twin (the same trajectory simulated with the calibrated model and the
  /// declared noise, through the same residual model): what the model predicts for this run.
  double twin_gap = 0.0;
  double gap_after_best = 0.0;              ///< χ²/dof with the best effect (pair) added
  std::vector<CandidateResult> candidates;  ///< ranked, best first
  std::optional<size_t> best;               ///< index into candidates
  std::optional<size_t> second;             ///< the explained set's second member
  /// The explained set in the order it was built (best first; noise candidates after every
  /// deterministic effect), each with its joint size and the gap after it; empty when no effect is
  /// a finding. best and second are its first two members.
  std::vector<DiagnosisStep> steps;
  /// Effects the stepwise search chose but whose place in the final set is not earned (issue #49
  /// item 1), in the order they were dropped: never in explained_by or the verdict.
  std::vector<UnsupportedEffect> unsupported;
  /// Significant candidates that explain the gap equally and that this sequence cannot tell apart
  /// (the top one first); then best is empty and the finding is the set (explained_by).
  std::vector<std::string> ambiguous;
  /// What the gap is explained by: the best effect (and its pair), or the ambiguous set; empty
  /// when the verdict is not "explained".
  std::vector<std::string> explained_by;
  /// The best candidate (or ambiguous set's first) that was significant but shrank the held-out gap
  /// by less than DiagnosisOptions::min_shrinkage, and that shrinkage; empty when there was none.
  /// Never a finding: reported beside the verdict for the engineer, never in the summary.
  std::string weak_candidate;
  double weak_shrinkage = 0.0;
  /// The held-out gap before any effect, after the best one, and (has_pair) after the whole
  /// explained set when it has more than one member; shrinkage is the whole set's.
  struct HeldOut {
    double gap_before = 0.0, gap_after = 0.0, gap_after_pair = 0.0, shrinkage = 0.0;
    bool has_after = false, has_pair = false;
  } held_out;
  std::vector<ParamShift> moved;  ///< base parameters that move by more than 1 σ, largest first
  /// Where the gap that remains (after the best effect, if any) lies: segment × component, largest
  /// |z| first (at most 10, only |z| > 3).
  std::vector<std::pair<std::string, double>> remaining;
  WhitenessStats whiteness;  ///< per-sample statistics of the rest residuals (over time)
  ParamSet base;             ///< refitted base parameters (no effect)
  ParamSet base_sigma;
  double runtime_s = 0.0;
};

/// Diagnose a run against the model `base` (a calibration of the same run). Throws
/// std::invalid_argument for input the diagnosis cannot use (fewer than 2 rests, no noise model,
/// a run too short for a candidate's parameters), naming the problem.
DiagnosisResult diagnose(const DiagnosisInput& in, const ParamSet& base,
                         const DiagnosisOptions& opt = {});

/// The options of a diagnosis whose false-alarm rate on a run without any unmodelled effect is at
/// most `per_run` (the station's [calibration] gap_false_alarm): the overall χ² test and the
/// candidates' tests (Bonferroni over the candidates) each get half of it.
DiagnosisOptions diagnosis_options_for_false_alarm(double per_run);

}  // namespace imucal::calib::diagnosis
