#include "calib/studies/fleet/station_error.hpp"

#include <future>
#include <stdexcept>

#include "calib/core/conventions.hpp"

namespace imucal::calib::studies::fleet {
using namespace calib::ains;
using namespace calib::core;
using namespace calib::effects;

namespace {

/// The fixture turned by θ about platform axis `axis`: both triads' M gain -[θ e_axis ×].
StationError fixture_rotation(int axis) {
  const char* name = "xyz";
  StationError e;
  e.effect = std::string("fixture_rotation_") + name[axis];
  e.term = std::string("fixture mounting, turned about the platform ") + name[axis] + " axis";
  e.advice =
      "check how the fixture sits on the platform (seating faces, dowel pins, bolts) and "
      "re-survey it";
  e.unit = "arcsec";
  e.si_to_human = 1.0 / kArcsecToRad;
  e.typical_si = 180.0 * kArcsecToRad;  // 0.05°: "a fraction of a degree"
  e.analytic = true;
  Eigen::Matrix3d dM = Eigen::Matrix3d::Zero();  // -[e_axis ×]
  const int j = (axis + 1) % 3, k = (axis + 2) % 3;
  dM(j, k) = 1.0;
  dM(k, j) = -1.0;
  ParamSet r;
  r.accel_M = dM;
  r.gyro_M = dM;
  e.response = r.to_vector();
  return e;
}

/// The platform tilting once per revolution (table_wobble), about the outer-gimbal axis `axis`
/// (0: x, 1: y) at inner angle zero: the gap diagnosis' table effect that the AINS parameters also
/// feel (measured: 10″ moves accelerometer and gyro misalignments by 10-50 µrad, linear to 1 %
/// from 5″ to 50″ but for the table heading ς_z, which the weak Earth-rate signal carries).
StationError table_wobble(int axis) {
  StationError e;
  e.effect = std::string("table_wobble_") + "xy"[axis];
  e.term =
      std::string("table wobble, the platform tilting once per revolution about ") + "xy"[axis];
  e.advice =
      "check the runout of this table's inner axis (bearing, platform seating): service "
      "the table";
  e.unit = "arcsec";
  e.si_to_human = 1.0 / kArcsecToRad;
  e.typical_si = 10.0 * kArcsecToRad;
  return e;
}

}  // namespace

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
  std::vector<StationError> errors{gravity, nonorth, table_wobble(0), table_wobble(1)};
  for (int axis = 0; axis < 3; ++axis) errors.push_back(fixture_rotation(axis));
  return errors;
}

Effects station_error_effects(const std::string& effect, double size_si) {
  Effects fx;
  if (effect == "gravity_error")
    fx.gravity_error_mps2 = size_si;
  else if (effect == "table_nonorthogonality")
    fx.table_nonorthogonality_rad = size_si;
  else if (effect == "table_wobble_x")
    fx.table_wobble_rad = Eigen::Vector2d(size_si, 0.0);
  else if (effect == "table_wobble_y")
    fx.table_wobble_rad = Eigen::Vector2d(0.0, size_si);
  else
    throw std::invalid_argument("station error \"" + effect +
                                "\" is not an effect the simulator injects (gravity_error, "
                                "table_nonorthogonality, table_wobble_x, table_wobble_y)");
  return fx;
}

void measure_responses(std::vector<StationError>& errors, const RunSource& source,
                       const AinsOptions& options) {
  auto estimate = [&](const Effects& fx) {
    return calibrate_ains(source(fx, 0, /*noise=*/false), options).params.to_vector();
  };
  std::vector<std::future<ParamVector>> with(errors.size());
  for (std::size_t i = 0; i < errors.size(); ++i)
    if (!errors[i].analytic)
      with[i] = std::async(std::launch::async, [&estimate, e = errors[i]] {
        return estimate(station_error_effects(e.effect, e.typical_si));
      });
  const ParamVector without = estimate(Effects{});
  for (std::size_t i = 0; i < errors.size(); ++i)
    if (!errors[i].analytic) errors[i].response = (with[i].get() - without) / errors[i].typical_si;
}

}  // namespace imucal::calib::studies::fleet
