#pragma once
// Sanity checks of a run's raw IMU data before any calibration, so that a broken sensor stream
// or a wrong set-up is refused with the symptom named — instead of calibrated into nonsense, or
// blamed on the sequence ("not observable"). Issue #10: "never store a wrong calibration as good".
//
//   clock jump        the IMU's time steps by other than its sample interval (factory only);
//   stuck channel     a gyro or accelerometer channel holds one value for most of the run;
//   saturation        a channel reaches the same extreme value again and again (clipped;
//                     factory only: a field run's clipped and dropped samples spoil the move
//                     they fall in, which the methods leave out — CalibrationInput::unusable);
//   gravity magnitude the accelerometers at rest do not measure |g| (±5 %);
//   gyro vs gravity   the gyros' rotation between two rests does not carry the measured gravity
//                     direction of one rest to the next (axes swapped, a sign flipped, a dead gyro)
//                     — every setting, no reference needed;
//   factory only:
//   gravity direction the measured gravity at rest is not where the table's attitude puts it
//                     (unit mounted in the wrong fixture orientation, accelerometer axes swapped);
//   table vs IMU      the IMU did not turn as the table did between two rests (the table moved but
//                     the unit did not, or the gyros disagree with the encoders).
// Tolerances are far outside what calibration errors within the datasheet envelope cause
// (calib/checks/limit_check.hpp: 5000 ppm, 5 mrad ≈ 0.3°): a finding here is never a calibration
// matter.
#include <stdexcept>
#include <string>
#include <vector>

#include "calib/core/calibration_input.hpp"

namespace imucal::calib::checks {
using namespace calib::core;

struct DataProblem {
  std::string symptom;  ///< "stuck channel", "saturation", "gravity direction", ...
  std::string detail;   ///< for the operator: which channel / rest / rotation, the numbers
};

struct DataCheckOptions {
  double stuck_fraction = 0.5;          ///< of all samples in one constant stretch
  int saturation_repeats = 10;          ///< samples at the same extreme value
  double gravity_magnitude_tol = 0.05;  ///< relative
  double direction_tol_deg = 3.0;       ///< gravity direction; gyro-carried gravity (plus the
                                        ///< rotation_tol_fraction of the angle turned)
  double rotation_tol_deg = 3.0;        ///< table vs IMU rotation (plus rotation_tol_fraction)
  double rotation_tol_fraction = 0.05;  ///< of the table's rotation angle
  size_t min_rest_samples = 50;
  /// Subtract the gyros' common offset (the median of the rests' mean rates) before carrying
  /// gravity across a move: a MEMS gyro's offset of a few °/s would otherwise turn it by tens of
  /// degrees. Off at navigation grade (the offset is Earth rate, far inside the tolerance).
  bool remove_gyro_offset = false;
  /// Remove each accelerometer's offset and scale (an ellipsoid fit to the rests' |f| = g) before
  /// comparing the gravity directions across a move: a MEMS unit's 200 mg biases tilt them by up
  /// to 20°. Off at navigation grade (1 mg is 0.06°).
  bool remove_accel_offset = false;
};

/// The defaults, widened to what an uncalibrated unit of the grade may be (calib/core/
/// unit_grade.hpp): the gravity magnitude by its scale and bias envelopes, the gyro-carried
/// gravity by its scale and misalignment envelopes (run.toml's [prior] overrides included).
/// Navigation grade without overrides: the defaults. A dead,
/// stuck, clipped, swapped or sign-flipped axis stays far outside these at every grade.
DataCheckOptions data_check_options(const UnitPrior& prior);

/// Every problem found (empty: the data look sane). Needs in.imu and in.reference of equal size.
std::vector<DataProblem> check_data(const CalibrationInput& in, const DataCheckOptions& o = {});

/// Thrown by the calibration pipeline when check_data finds problems; the message lists them.
class DataCheckError : public std::invalid_argument {
 public:
  explicit DataCheckError(std::vector<DataProblem> problems);
  const std::vector<DataProblem>& problems() const { return problems_; }

 private:
  std::vector<DataProblem> problems_;
};

}  // namespace imucal::calib::checks
