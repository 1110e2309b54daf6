#pragma once
// rest_tremor (calib/effects/rest_tremor.hpp) as a diagnosis candidate (ARCHITECTURE §7-8): is the
// unit still in its rests, or does a hand hold it there? Judged on a statistic of its own that
// exists only under real motion:
//
//  * per rest, in windows of at most 4 s, the compensated gyro rate less the window's mean rate is
//    integrated into the tilt θ(t) (the hand's turn; the bias, the Earth's rate and any net turn
//    go with the mean), and the accelerometers' specific force f(t) is taken as it is; both are
//    averaged over blocks of 0.2 s (the tremor's 6–11 Hz and a pivot's shake average out, the
//    sway stays) and each window's mean and linear trend are removed;
//  * a body turned by θ senses f = f̄ + f̄ × θ: regressed on x = f̄ × θ, the accelerometers' blocks
//    give a slope β of 1 under a hand's motion and 0 under any sensor noise, because the gyros'
//    and accelerometers' noises are independent. Per body axis the slope's σ comes from the
//    regression's own residuals (robust to misdeclared noise and to filtered, correlated samples,
//    which a 0.2 s block averages); the axes are pooled by their precision. z = β/σ(β); LR = z²
//    when β > 0 (one-sided: a turned body cannot sense gravity turned the other way), k = 1;
//  * the held-out gap over folds of rests (as the output filter's): z² of each held-out fold's
//    slope against 0 (before) and against the slope of the other folds (after), averaged;
//  * the size: rate_rms, the RMS rate per axis about a line fitted to each block (the tremor, the
//    sway's rate taken out with the line; the declared white noise subtracted, the tremor band's
//    loss to the line put back), and tilt_rms, the RMS of the blocks' detrended tilt (the gyro's
//    random walk subtracted, the sway band's loss to the blocks and the detrend put back), each
//    with σ from the scatter between rests; the slope in the note.
//
// What it does not do: change the segment residuals. A hand's motion is not the unit's: it is not
// removed from the data (--compensate refuses it), and the rests' means keep whatever net turn
// and mean tilt the hand gave them (docs/validation/diagnosis.md, "Tremor in a rest").
#include <vector>

#include "calib/core/calibration_input.hpp"
#include "calib/core/param_set.hpp"
#include "calib/diagnosis/diagnosis.hpp"
#include "calib/diagnosis/gap_model.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::core;

/// The candidate on the run's rests, the increments compensated by `base`.
CandidateResult score_rest_tremor(const CalibrationInput& in, const std::vector<RestPeriod>& rests,
                                  const ParamSet& base, int folds);

/// The rests whose gyros are as quiet as the quietest one's: a rest's raw rate variance about its
/// line (mean over the axes) at most kStillRatio times the quietest rest's. Sensor noise alone
/// differs between rests by the variance estimate's spread (6 % on a 2 s rest at 100 Hz); a hand
/// raises it by 4-400x (the corpus' hand-held rests: gyro scatter 0.1-2 °/s against 0.05-0.1 on
/// the bench). Where a hand holds the unit the lag-1 candidates (quantisation, the output filter)
/// are judged on these alone — if the tremor's own test finds no motion in them either: a hand's
/// tremor and sway raise the gyros' lag-1 autocorrelation as a low-pass filter would.
constexpr double kStillRatio = 2.0;
std::vector<RestPeriod> still_rests(const CalibrationInput& in,
                                    const std::vector<RestPeriod>& rests);

/// Its detection noncentrality for the catalogue's typical pattern scaled by m on this run's rests
/// (calib/diagnosis/effect_detectability.cpp): E z² = Σ x²/σ_y², with the sway's tilt RMS m × the
/// typical one as it survives the blocks and detrend, σ_y² the declared VRW over a block.
double rest_tremor_noncentrality(const GapModel& model, double m);

}  // namespace imucal::calib::diagnosis
