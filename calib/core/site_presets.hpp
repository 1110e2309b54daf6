#pragma once
// The demonstration factory site used by the simulator front ends and tests when no station
// configuration says otherwise: DTU, Kongens Lyngby, with a "surveyed" gravity equal to the
// normal gravity there (a real station configures its survey value).
#include "calib/core/conventions.hpp"
#include "calib/core/earth.hpp"

namespace imucal::calib::core {

inline Site demo_factory_site() {
  Site s;
  s.lat_rad = 55.7856 * kDegToRad;
  s.lon_rad = 12.5213 * kDegToRad;
  s.height_m = 30.0;
  s.gravity_mps2 = EarthModel::normal_gravity_mps2(s.lat_rad, s.height_m);
  return s;
}

}  // namespace imucal::calib::core
