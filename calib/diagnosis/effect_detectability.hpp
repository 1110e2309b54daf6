#pragma once
// Detection thresholds and separability of the effects catalogue on a rotation sequence (issue #8
// item 3): from the Fisher information of the gap model augmented by each effect (the same model
// and linearisation the diagnosis fits, calib/diagnosis/gap_linearisation.hpp), evaluated
// noise-free along the sequence's true trajectory with the unit's declared noise as weights. No
// data needed.
//
// For an effect with columns J_c (whitened, in units of its typical size) and the base columns J_b:
//  * its directions with no signature, and those whose multiple correlation with the base exceeds
//    the separability limit (0.95), are not separable (calib/diagnosis/gap_fit.hpp: separability);
//  * two effects whose separable signatures correlate (canonically) above the limit are confounded;
//  * the detection threshold is the magnitude of the effect's typical pattern at which the expected
//    likelihood-ratio statistic, k + λ with λ = ||(signature not explained by the base)||², reaches
//    the diagnosis' critical value χ²_k(1 - α/N) (k separable directions, N candidates). At 3× the
//    threshold λ is 9× larger: the diagnosis detects it essentially always.
#include <limits>
#include <string>
#include <vector>

#include "calib/core/calibration_input.hpp"
#include "calib/core/param_set.hpp"
#include "calib/core/table_model.hpp"
#include "calib/diagnosis/diagnosis.hpp"
#include "calib/effects/catalogue.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::core;
using namespace calib::effects;

struct EffectDetectability {
  EffectId id{};
  std::string name;
  int directions = 0;                        ///< non-shape parameters
  int separable_directions = 0;              ///< fitted by the diagnosis on this sequence
  int no_signature = 0;                      ///< directions that change no residual
  double max_correlation = 0.0;              ///< largest multiple correlation with the base
  std::vector<std::string> aliases;          ///< base parameters the worst direction mimics
  std::vector<std::string> confounded_with;  ///< effects it cannot be told from
  double max_cross_correlation = 0.0;        ///< largest canonical correlation with another effect
  double threshold = std::numeric_limits<double>::infinity();  ///< in `unit`; inf = not detectable
  double typical = 0.0;  ///< magnitude of the catalogue's typical value
  std::string unit;
  /// Detectable and separable from the base and from every other effect on this sequence.
  bool separable() const { return separable_directions > 0 && confounded_with.empty(); }
  std::string reason;  ///< why not separable (empty when separable)
};

/// One entry per catalogue effect, in catalogue order. `exact_run` is the sequence's run without
/// noise or effects (the true trajectory; a RunSource's run with noise off), whose declared noise
/// model supplies the weights; `base` the unit's parameters, the linearisation point.
std::vector<EffectDetectability> effect_detectability(const CalibrationInput& exact_run,
                                                      const TableGeometry& geometry,
                                                      const ParamSet& base,
                                                      const DiagnosisOptions& opt = {});

}  // namespace imucal::calib::diagnosis
