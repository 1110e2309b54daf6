#pragma once
// The station errors of issue #25: what a station does wrong to every unit it calibrates, the
// same way — invisible in one run (a wrong surveyed gravity is exactly a common scale factor of
// the three accelerometers; a table whose axes are out of square shifts misalignment terms),
// visible across the units of a fleet. Each has its catalogue effect (calib/effects/catalogue.hpp,
// the simulator's truth), the words QA reads in an alarm, and its *response*: how the AINS
// estimate of the 27 parameters moves per SI unit of the error (d x̂ / d e), measured on exact
// runs of the station's sequence (measure_responses). The response does not depend on the unit to
// first order (the same 50 µg moved four different units' scales by 49.94–49.97 ppm alike).
//
// A fixture mounted off by a small rotation θ (the housing turned by θ on the platform) is not an
// effect the simulator injects into the unit: it is exactly a reparametrisation of the unit, the
// sensor models seen from the platform becoming (I + M) Rᵀ = I + M - [θ×] to first order for both
// triads (calib/core/body_frame.hpp). Its response is that algebra (`analytic`), one candidate
// per platform axis; tests/fleet/station_signature_sim_test.cpp checks it against the simulator
// with a turned fixture and the AINS.
#include <string>
#include <vector>

#include "calib/ains/ains.hpp"
#include "calib/core/param_set.hpp"
#include "calib/effects/run_source.hpp"

namespace imucal::calib::studies::fleet {
using namespace calib::ains;
using namespace calib::core;
using namespace calib::effects;

struct StationError {
  /// "gravity_error", "table_nonorthogonality" (effects catalogue names), "table_wobble_x|y" (the
  /// catalogue's table_wobble about one axis), "fixture_rotation_x|y|z"
  std::string effect;
  std::string term;    ///< what moves, for people: "common accelerometer scale"
  std::string advice;  ///< what to check: "check the surveyed gravity of this site"
  std::string unit;    ///< the human unit of its size: "µg", "arcsec"
  double si_to_human;  ///< size in `unit` = size in SI × this
  double typical_si;   ///< the size its response is measured at (ARCHITECTURE §7 typical)
  /// Also show the size in this second unit (e.g. ppm of accelerometer scale for a gravity
  /// error); empty for none.
  std::string alt_unit;
  double si_to_alt = 0.0;
  ParamVector response = ParamVector::Zero();  ///< d x̂ / d e, per SI unit of the error
  /// The response is known by algebra (set by the catalogue), not measured on runs.
  bool analytic = false;
};

/// The station errors the fleet looks for; the measured ones' responses not yet measured (zero).
std::vector<StationError> station_error_catalogue();

/// Measures each (non-analytic) error's response on exact runs (noise off) of `source`: the AINS
/// estimate with the error at its typical size minus the one without, divided by the size. Runs in
/// parallel.
void measure_responses(std::vector<StationError>& errors, const RunSource& source,
                       const AinsOptions& options = {});

/// The catalogue effect set with one station error of size `size_si` (std::invalid_argument for a
/// name the catalogue does not know, or an analytic error, which no effect set expresses).
Effects station_error_effects(const std::string& effect, double size_si);

}  // namespace imucal::calib::studies::fleet
