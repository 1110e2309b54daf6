#include "calib/fleet/station_error.hpp"

#include <future>
#include <stdexcept>

#include "calib/core/conventions.hpp"

namespace imucal::calib {

std::vector<StationError> station_error_catalogue() {
  StationError gravity;
  gravity.effect = "gravity_error";
  gravity.term = "common accelerometer scale";
  gravity.advice = "check the surveyed gravity of this site";
  gravity.unit = "µg";
  gravity.si_to_human = 1.0 / kMicroG_mps2;
  gravity.typical_si = 50.0 * kMicroG_mps2;
  // The scale every accelerometer appears to have: dg / g.
  gravity.alt_unit = "ppm";
  gravity.si_to_alt = 1e6 / kStandardGravity_mps2;

  StationError nonorth;
  nonorth.effect = "table_nonorthogonality";
  nonorth.term = "table axis non-orthogonality";
  nonorth.advice = "check the squareness of this table's axes (service the table)";
  nonorth.unit = "arcsec";
  nonorth.si_to_human = 1.0 / kArcsecToRad;
  nonorth.typical_si = 10.0 * kArcsecToRad;
  return {gravity, nonorth};
}

Effects station_error_effects(const std::string& effect, double size_si) {
  Effects fx;
  if (effect == "gravity_error")
    fx.gravity_error_mps2 = size_si;
  else if (effect == "table_nonorthogonality")
    fx.table_nonorthogonality_rad = size_si;
  else
    throw std::invalid_argument("station error \"" + effect +
                                "\" is not one the fleet looks for (gravity_error, "
                                "table_nonorthogonality)");
  return fx;
}

void measure_responses(std::vector<StationError>& errors, const RunSource& source,
                       const AinsOptions& options) {
  auto estimate = [&](const Effects& fx) {
    return calibrate_ains(source(fx, 0, /*noise=*/false), options).params.to_vector();
  };
  std::vector<std::future<ParamVector>> with;
  for (const StationError& e : errors)
    with.push_back(std::async(std::launch::async, [&estimate, e] {
      return estimate(station_error_effects(e.effect, e.typical_si));
    }));
  const ParamVector without = estimate(Effects{});
  for (std::size_t i = 0; i < errors.size(); ++i)
    errors[i].response = (with[i].get() - without) / errors[i].typical_si;
}

}  // namespace imucal::calib
