#pragma once
// Blind validation of the gap diagnosis (ARCHITECTURE §8 step 4, issue #8 item 4): draw runs of a
// sequence from a RunSource (calib/effects/run_source.hpp: the truth simulator, or another) with
// one effect (and, separately, pairs) injected at magnitudes drawn between 3× and 10× the effect's
// detection threshold on that sequence (at most 0.7 × the size the diagnosis still calls plausible)
// (calib/diagnosis/effect_detectability.hpp), plus null runs with none; calibrate each (NLSQ) and
// diagnose it without telling the diagnosis what was injected; count what it names.
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "calib/core/param_set.hpp"
#include "calib/core/table_model.hpp"
#include "calib/diagnosis/diagnosis.hpp"
#include "calib/diagnosis/effect_detectability.hpp"
#include "calib/effects/run_source.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::core;
using namespace calib::effects;

struct ValidationOptions {
  int runs_per_effect = 10;  ///< single-effect runs per separable effect
  int null_runs = 10;        ///< runs with no effect
  int pair_runs = 10;        ///< runs with two effects (random separable pairs)
  int triple_runs = 0;       ///< runs with three effects (random separable triples)
  uint64_t seed = 1;
  double min_factor = 3.0, max_factor = 10.0;  ///< magnitude range in detection thresholds
  int threads = 0;                             ///< 0: hardware concurrency
  /// The diagnosis' options (its false-alarm rate: diagnosis_options_for_false_alarm), used for
  /// every run and for the detection thresholds the effects are drawn at.
  DiagnosisOptions diagnosis;
  /// Restrict to these effects (default: every effect the sequence separates).
  std::vector<EffectId> effects;
  /// Called after each run with (done, total); may be empty. Called from worker threads,
  /// serialised.
  std::function<void(int, int)> on_progress;
};

/// One simulated run and what the diagnosis said.
struct ValidationRun {
  std::vector<std::string> injected;  ///< effect names (empty: null run)
  std::vector<double> factor;         ///< magnitude in thresholds, per injected effect
  uint64_t seed = 0;
  std::string verdict;
  std::string named;                   ///< best effect, "none", or "ambiguous: a|b"
  std::string second;                  ///< the explained set's second, or ""
  std::vector<std::string> explained;  ///< the explained set in the order chosen (steps)
  double shrinkage = 0.0;
  bool has_shrinkage = false;
};

struct ValidationReport {
  std::string sequence;
  std::vector<EffectDetectability> detectability;
  std::vector<std::string> effects;  ///< validated (separable) effects
  /// Effects drawn below max_factor: their plausible size (the diagnosis' limit, times 0.7) is
  /// reached first; the factor they were drawn up to.
  std::map<std::string, double> factor_cap;
  /// Separable effects left out: detectable only beyond 0.7 × their plausible size.
  std::vector<std::string> beyond_plausible;
  std::vector<ValidationRun> runs;
  /// confusion[injected][named] = count; injected "none" for null runs.
  std::map<std::string, std::map<std::string, int>> confusion;
  double top1 = 0.0;         ///< single-effect runs whose best is the injected effect
  double false_alarm = 0.0;  ///< null runs with a named effect or a verdict other than consistent
  double median_shrinkage = 0.0;  ///< over single-effect runs where the effect was named
  double pair_both = 0.0;         ///< pair runs naming both effects (in the explained set)
  double triple_all = 0.0;        ///< triple runs naming all three effects
  /// Runs with 2 or 3 effects whose first named effect is an injected one.
  double multi_first_injected = 0.0;
  /// Runs with 2 or 3 effects where a noise candidate (bias instability, quantisation) that was not
  /// injected is named ahead of an injected effect.
  int multi_noise_ahead = 0;
  int single_runs = 0, null_count = 0, pair_count = 0, triple_count = 0;
  int null_alarms = 0;  ///< null runs counted in false_alarm
};

/// `world` draws the runs (its unit's declared noise with them), `geometry` is its table's, `base`
/// its unit's parameters (the detectability's linearisation point), `sequence` the name reported.
ValidationReport validate_diagnosis(const RunSource& world, const TableGeometry& geometry,
                                    const ParamSet& base, const std::string& sequence,
                                    const ValidationOptions& opt = {});

/// The effect's typical pattern scaled to `magnitude` (its magnitude unit) with a sign, SI vector.
Eigen::VectorXd scaled_typical(const EffectInfo& e, double magnitude, double sign);

}  // namespace imucal::calib::diagnosis
