#pragma once
// The sequence designer (issue #23 item 2): a rotation sequence for a given table time that keeps
// every calibration parameter's Cramér–Rao σ as close as it can to a reference sequence's, judged
// parameter by parameter against what the time allows, and that keeps every catalogue effect the
// reference separates separable, with a detection threshold at most `threshold_factor` times the
// reference's. Pure math: the caller gives the reference as a parsed sequence, the table's limits,
// and the exact (noise-free) run of a motion profile for the effects' analysis (the simulator is
// not ours to include, ARCHITECTURE §2); the caller writes the result.
//
// What is searched, greedily, each step judged by the CRLB (calib/checks/crlb.hpp):
//  1. the rotation rate and acceleration: the reference's or the table's limits;
//  2. from the reference's tour (its rest poses in its order), one move at a time, the one that
//     helps most of: drop a rest pose (a pose between two rotations about the same axis, the two
//     merged into one, or the first or last pose); add a full turn to a rotation; change a
//     rotation by a half turn (every later pose of that axis turned by 180°: other rest attitudes
//     and headings); raise or lower one pose's share of the rest (factors 1.5 down to 1.03);
//  3. a polish: small changes of the rest shares on the largest ratio alone.
// What it minimises: the ratios σ_i / target_i over the 27 parameters and, for every effect the
// reference separates, threshold / (threshold_factor × the reference's) (a large ratio when no
// longer separable) — a soft maximum of them in step 2 (the effects analysed for the few tours
// best by σ), their maximum in step 3. Targets (--like): the reference with its rests scaled
// uniformly to the new time (the obvious cut), and for the bias parameters the smaller of that
// and bias_floor_factor × the white-noise floor N/√T (no sequence beats N/√T:
// tests/calib/sequence_time_floor_test.cpp). Targets (--target-from): K × that sequence's σ, the
// least time reaching them found by bisection. A local search: it finds a good sequence near the
// reference, not the best of all sequences.
#include <functional>
#include <string>
#include <vector>

#include "calib/ains/ains.hpp"
#include "calib/core/calibration_input.hpp"
#include "calib/core/earth.hpp"
#include "calib/core/noise_model.hpp"
#include "calib/core/param_set.hpp"
#include "calib/core/table_model.hpp"
#include "calib/diagnosis/diagnosis.hpp"
#include "calib/diagnosis/effect_detectability.hpp"
#include "calib/studies/design/rest_tour.hpp"
#include "sequences/motion_profile.hpp"
#include "sequences/sequence.hpp"
#include "sequences/validator.hpp"

namespace imucal::calib::studies::design {
using namespace calib::ains;
using namespace calib::core;
using namespace calib::diagnosis;

/// The exact (noise-free) run of a profile at a rate, with the unit's declared noise model: what
/// effect_detectability needs (a RunSource's run with noise off). Called from two threads at once.
using ExactRun =
    std::function<CalibrationInput(const sequences::MotionProfile& profile, double rate_hz)>;

struct DesignSetting {
  TableGeometry geometry;
  Site site;
  NoiseModel noise;
  AinsOptions ains;               ///< the prior of the CRLB
  sequences::TableLimits limits;  ///< the station's, tightened by the reference's [limits]
  double rate_hz = 100.0;         ///< the IMU rate of the final figures
  /// The IMU rate of the search's CRLB runs: σ depends on the noise densities and the trajectory,
  /// hardly on the rate (the final figures are at rate_hz), and a run costs ∝ rate.
  double search_rate_hz = 20.0;
  double bias_floor_factor = 1.05;
  double threshold_factor = 1.5;
  DiagnosisOptions diagnosis;  ///< its false-alarm rate sets the detection thresholds
  ExactRun exact_run;          ///< empty: the effects are neither guarded nor reported
  ParamSet base;               ///< the unit's parameters: the effects' linearisation point
  std::function<void(const std::string&)> progress;  ///< one line per search step (may be empty)
};

/// The σ of one sequence and, when analysed, its effects.
struct SequenceFigures {
  double duration_s = 0.0;
  ParamVector sigma = ParamVector::Zero();
  std::vector<EffectDetectability> effects;  ///< empty when not analysed
};

struct SequenceDesign {
  sequences::Sequence sequence;  ///< the design (name, description and source_path from the caller)
  RestTour tour;
  SequenceFigures reference;  ///< the reference (--like), at rate_hz
  SequenceFigures cut;  ///< the reference with its rests scaled uniformly to the design's time
  SequenceFigures design;
  ParamVector target = ParamVector::Zero();  ///< what the objective divides by (search rate)
  double objective = 0.0;  ///< largest ratio to its target (σ and effects), search rate; ≤ 1: met
  bool targets_met = false;  ///< objective ≤ 1 and (when analysed) the effects kept
  bool effects_kept =
      true;  ///< every effect the reference separates: separable, threshold ≤ factor×
  std::vector<std::string> log;  ///< what the search changed, in order
  int evaluations = 0;           ///< CRLB runs of the search
};

/// The design lasting `total_s` like `reference`. Throws std::invalid_argument when total_s is
/// outside the limits or too short for any tour of the reference's poses.
SequenceDesign design_for_time(const sequences::Sequence& reference, double total_s,
                               const DesignSetting& setting);

/// The shortest design (to 1 %) with σ_i ≤ factor × σ_i of `target` for every parameter, starting
/// from `reference`'s tour; the effects are judged against `target`'s. Throws
/// std::invalid_argument when even the longest time allowed does not reach the target.
SequenceDesign design_for_target(const sequences::Sequence& reference,
                                 const sequences::Sequence& target, double factor,
                                 const DesignSetting& setting);

/// The white-noise floor N/√T of parameter i for a run of duration_s: VRW/√T for an accelerometer
/// bias, ARW/√T for a gyro bias, 0 for every other parameter.
double white_noise_floor(int i, const NoiseModel& noise, double duration_s);

/// Per effect of the reference's list: separable on the reference and not kept on the design
/// (not separable, or threshold over factor × the reference's). Names, empty when all kept.
std::vector<std::string> effects_lost(const std::vector<EffectDetectability>& reference,
                                      const std::vector<EffectDetectability>& design,
                                      double threshold_factor);

}  // namespace imucal::calib::studies::design
