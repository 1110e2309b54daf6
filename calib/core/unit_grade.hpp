#pragma once
// A unit's grade and the prior that comes with it (issue #21 item 1, ARCHITECTURE §2 core: "unit
// grades and priors"). The station was written for navigation-grade units (fibre-optic gyros,
// pendulous accelerometers, near nominal after assembly); a factory also builds tactical and MEMS
// units, and field units come back aged. Everything that assumes a unit before seeing its data
// should take it from here: so far the rest detection that needs no calibration
// (calib/core/variation_rest_detector.hpp).
//
// The envelopes are datasheet classes, the spread of uncalibrated units of each class (the
// values a calibration from scratch must reach), not one product's specification:
//  * navigation — FOG/RLG with force-rebalanced accelerometers: gyro bias ≤ 0.05 °/h, ARW ≤ 0.005
//    °/√h, accelerometer bias ≤ 1 mg, scale ≤ 0.1 %, misalignment ≤ 1 mrad before calibration;
//  * tactical — small FOG / high-end MEMS: gyro bias ≤ 10 °/h, ARW ≤ 0.2 °/√h, accelerometer bias
//    ≤ 5 mg, scale ≤ 1 %, misalignment ≤ 5 mrad;
//  * mems — consumer and industrial MEMS read with nominal scales: gyro bias ≤ 5 °/s, ARW ≤ 1
//    °/√h, accelerometer bias ≤ 200 mg, scale ≤ 30 %, misalignment ≤ 50 mrad (issue #21: a real
//    unit had a gyro scale 24 % from nominal, gyro biases to 2.9 °/s, accelerometer biases to
//    124 mg).
#include <optional>
#include <string>

namespace imucal::calib::core {

enum class Grade { kNavigation, kTactical, kMems };

/// "navigation", "tactical", "mems".
const char* grade_name(Grade g);
/// The inverse of grade_name; nullopt for anything else.
std::optional<Grade> parse_grade(const std::string& name);

/// What a unit of a grade may be before calibration (envelopes, SI) and how it behaves at rest.
struct GradePrior {
  double gyro_bias_radps = 0.0;     ///< |bias| per axis, envelope
  double accel_bias_mps2 = 0.0;     ///< |bias| per axis, envelope
  double scale = 0.0;               ///< |scale factor error| per axis (fraction), envelope
  double misalignment_rad = 0.0;    ///< |non-orthogonality / misalignment| per pair, envelope
  double arw_rad_per_sqrt_s = 0.0;  ///< angle random walk, worst of the class
  double vrw_mps_per_sqrt_s = 0.0;  ///< velocity random walk, worst of the class
  /// Rest detection: variations of the rate and the specific force (RMS over a short window, per
  /// axis) below which a unit counts as still whatever its own noise — a bench's and a calm
  /// deck's disturbances, which a quiet unit resolves but which are not a hand turning it.
  double still_rate_radps = 0.0;
  double still_force_mps2 = 0.0;
  /// How far a rest's mean rate may sit from the unit's common gyro offset: Earth rate, the
  /// gyros' g-sensitivity and bias drift between rests, well below any deliberate rotation.
  double rest_rate_spread_radps = 0.0;
  /// How much larger than the effects catalogue's typical (navigation-grade) sizes this class's
  /// unmodelled effects may be: the gap diagnosis' plausibility limit and its signature floor scale
  /// with it. A MEMS gyro's g-sensitivity (~0.1 °/s/g on datasheets) is ~4·10⁴ times the
  /// catalogue's typical 0.009 °/h/g, a tactical one's (~1 °/h/g) ~10²; navigation 1, tactical 100,
  /// MEMS 10⁴.
  double effect_scale = 1.0;
  /// Field runs' initial rest (issue #48 item 2). Navigation grade levels and gyrocompasses on it:
  /// at least first_rest_min_s of stillness, starting within first_rest_latest_start_s of the
  /// first sample. Tactical and MEMS gyros cannot find north (bias ≥ Earth rate × cos φ: the AINS
  /// searches the heading instead), so their first still position of any length serves, wherever
  /// it starts (0 and infinity); a run whose recording needs more says so ([prior] first_rest_s).
  double first_rest_min_s = 0.0;
  double first_rest_latest_start_s = 0.0;
  /// The shortest window the coarse alignment accepts: gyrocompassing needs 10 s (navigation),
  /// levelling alone needs about a second (tactical, MEMS).
  double alignment_min_window_s = 10.0;
  /// Rest detection by variation (calib/core/variation_rest_detector.hpp): the gyro's second
  /// opinion. A window whose rate varies less than this (RMS per axis) is still as far as the gyro
  /// can tell: a hand holding a unit on a surface shakes it by 0.3–1 °/s (the corpus' hand-held
  /// starts), a turn by tens of °/s. 0: the detector's noise threshold alone.
  double tremor_rate_radps = 0.0;
  /// The accelerometer's share of the same: a hand holding a unit still shakes its specific force
  /// over a short window by up to 2.5 times the unit's bench noise (the MPU-6050 corpus recording's
  /// hand-held positions: 4–7 mg against 3.3 mg on the bench), a hand turning it by tens to
  /// hundreds of mg. The accelerometer's threshold is at least this multiple of the unit's own
  /// noise (a fixed floor of 10 mg took a quiet unit's settling after a set-down for rest: IMU-TK's
  /// Xsens, gravity turning 0.39° within a rest); 0: the detector's variance factor alone.
  double tremor_force_noise_ratio = 0.0;
  /// Rest detection by variation: quiet spans shorter than this are not rests. A hand-held
  /// calibration's positions last 2–4 s (the MPU-6050 authors': 3 s), and the hand settles into
  /// them: 1.5 s at the tremor grades, 2 s otherwise.
  double min_rest_s = 2.0;
};

GradePrior grade_prior(Grade g);

/// run.toml [prior] overrides of a grade's envelopes (issue #21): a product whose datasheet is
/// wider or narrower than its class's. Empty: the grade's.
struct EnvelopeOverrides {
  std::optional<double> gyro_bias_radps, accel_bias_mps2, scale, misalignment_rad;
  bool any() const { return gyro_bias_radps || accel_bias_mps2 || scale || misalignment_rad; }
};

/// What may be assumed about a unit before its data: its grade and any overrides of the grade's
/// envelopes. A bare grade converts to it (no overrides).
struct UnitPrior {
  Grade grade = Grade::kNavigation;
  EnvelopeOverrides overrides;
  UnitPrior() = default;
  UnitPrior(Grade g) : grade(g) {}  // NOLINT(google-explicit-constructor): a grade is a prior
  UnitPrior(Grade g, EnvelopeOverrides o) : grade(g), overrides(o) {}
  /// A navigation-grade unit without overrides: everything as before the grades existed.
  bool plain_navigation() const { return grade == Grade::kNavigation && !overrides.any(); }
  /// grade_prior(grade) with the overrides applied.
  GradePrior envelope() const;
};

/// Each override's admissible range, SI (what run.toml checks): gyro bias (0, 100 °/s],
/// accelerometer bias (0, 2 g], scale (0, 0.5], misalignment (0, 0.2 rad].
struct EnvelopeRange {
  double max_gyro_bias_radps, max_accel_bias_mps2, max_scale, max_misalignment_rad;
};
EnvelopeRange envelope_range();

}  // namespace imucal::calib::core
