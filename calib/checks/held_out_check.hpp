#pragma once
// A calibration checked on another recording of the same unit (issue #48 item 6, ARCHITECTURE §6
// "Held-out check"): a parameter set compensates the run's raw increments with the shared error
// model (calib/core/imu_error_model.hpp, ImuCompensator: f = (I + dM_a)⁻¹ (f~ − b_a), the same
// for the gyros — the inverse of eq. 18 and 23 that the evaluation and the methods use), and the
// run's own physics judges the result without any reference:
//  * at every rest, the magnitude of the mean specific force against local gravity
//    (EarthModel(in.site).gravity_mps2()): what the accelerometers' biases and scales spoil;
//  * across every move, from the middle of rest p to the middle of rest p+1, the angle between
//    the gravity direction of rest p carried by the integrated gyros to rest p+1 and the gravity
//    direction seen there: what the gyros' scales, misalignments and biases spoil (and the
//    accelerometers' misalignments, which move where gravity is seen).
// These are the two observations the legacy method fits (calib/legacy/legacy.hpp), here measured
// on data the parameters were not fitted to. Beside each, the same figure uncompensated: nominal
// values, nothing subtracted. Rests are the input's at_rest spans (the grade's detector, as the
// input was built), each trimmed at both ends as the legacy method trims them.
//
// The Earth rate turns gravity across a move (Ω cos φ · Δt about north: 0.02° in 10 s at 56°). At
// navigation grade each rest's north comes from its own compensated mean rate (gyrocompassing, as
// the legacy method's heading fit does) and the rotation is removed as its joint model does. A
// tactical or MEMS gyro cannot find north (its bias exceeds the Earth rate), so below navigation
// grade only the vertical part is known — which does not move gravity at all — and the horizontal
// part is left in: the result gives its largest effect on any move (earth_rate_bound_rad), which
// at MEMS grade is below the angle random walk over the same move (1 °/√h: 0.05° in 10 s).
#include <string>
#include <vector>

#include "calib/core/calibration_input.hpp"
#include "calib/core/param_set.hpp"

namespace imucal::calib::checks {
using namespace calib::core;

struct HeldOutCheckOptions {
  size_t min_rest_samples = 100;  ///< shorter at_rest runs are not used (as the legacy method)
  double trim_s = 1.0;            ///< dropped from both ends of every rest before averaging
};

/// One rest: the span averaged (after trimming) and |mean f| − g, uncompensated and compensated.
struct RestFigure {
  double t_begin_s = 0.0, t_end_s = 0.0;
  double raw_mps2 = 0.0, corrected_mps2 = 0.0;
};

/// One move, middle of rest p to middle of rest p+1: the angle between gravity carried by the
/// gyros and gravity seen, uncompensated and compensated; tilt_rad, the angle between the two
/// rests' compensated gravity directions (how far the move tipped the unit).
struct MoveFigure {
  double t_from_s = 0.0, t_to_s = 0.0;
  double tilt_rad = 0.0;
  double raw_rad = 0.0, corrected_rad = 0.0;
  /// Why the move is not judged ("" when it is): a clipped or dropped sample in it
  /// (CalibrationInput::unusable) — its figures are shown but stay out of the RMS.
  std::string left_out;
};

struct HeldOutCheck {
  double gravity_mps2 = 0.0;  ///< local gravity the magnitudes are compared with
  std::vector<RestFigure> rests;
  std::vector<MoveFigure> moves;
  /// RMS over rests (m/s²) and over the moves not left out (rad), each column.
  double rest_rms_raw_mps2 = 0.0, rest_rms_corrected_mps2 = 0.0;
  double move_rms_raw_rad = 0.0, move_rms_corrected_rad = 0.0;
  /// true: the Earth rate's horizontal part was removed (navigation grade, north from the gyros);
  /// false: left in, turning gravity by at most earth_rate_bound_rad on the longest move.
  bool earth_rate_heading = false;
  double earth_rate_bound_rad = 0.0;
};

/// Throws std::invalid_argument for malformed input (check_input_samples) and for a run with
/// fewer than two usable rests, saying how many were found.
HeldOutCheck check_held_out(const CalibrationInput& in, const ParamSet& params,
                            const HeldOutCheckOptions& options = {});

}  // namespace imucal::calib::checks
