// WGS-84 Earth model against published reference values (NIMA TR8350.2 / Groves).
#include "calib/core/earth.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include "calib/core/conventions.hpp"
#include "calib/core/strapdown.hpp"

using namespace imucal;
using namespace imucal::calib;
using namespace imucal::calib::core;

TEST(Earth, NormalGravityMatchesWgs84ReferenceValues) {
  // TR8350.2: γ_e = 9.7803253359, γ_p = 9.8321849378 m/s².
  EXPECT_NEAR(EarthModel::normal_gravity_mps2(0.0, 0.0), 9.7803253359, 1e-10);
  EXPECT_NEAR(EarthModel::normal_gravity_mps2(kPi / 2, 0.0), 9.8321849378, 1e-9);
  // Free-air gradient ≈ -3.086e-6 s^-2 at mid latitudes.
  const double lat = 45.0 * kDegToRad;
  const double grad =
      (EarthModel::normal_gravity_mps2(lat, 100.0) - EarthModel::normal_gravity_mps2(lat, 0.0)) /
      100.0;
  EXPECT_NEAR(grad, -3.086e-6, 0.005e-6);
}

TEST(Earth, SurveyedGravityOverridesTheModel) {
  Site s;
  s.lat_rad = 55.0 * kDegToRad;
  s.gravity_mps2 = 9.815;
  EXPECT_DOUBLE_EQ(EarthModel(s).gravity_mps2(), 9.815);
  EXPECT_DOUBLE_EQ(EarthModel(s).g_n()(2), 9.815);
  // The strapdown keeps the surveyed value at the site and applies the gradient away from it.
  const Strapdown sd{EarthModel(s)};
  EXPECT_DOUBLE_EQ(sd.gravity_at(s.lat_rad, s.height_m), 9.815);
  EXPECT_NEAR(sd.gravity_at(s.lat_rad, s.height_m + 10.0) - 9.815, -3.086e-5, 0.01e-5);
}

TEST(Earth, EarthRateResolvesIntoNedByLatitude) {
  const double lat = 30.0 * kDegToRad;
  const Eigen::Vector3d w = EarthModel::w_ie_n_at(lat);
  EXPECT_NEAR(w.norm(), 7.292115e-5, 1e-15);
  EXPECT_NEAR(w(0), 7.292115e-5 * std::sqrt(3.0) / 2.0, 1e-15);  // north
  EXPECT_DOUBLE_EQ(w(1), 0.0);
  EXPECT_NEAR(w(2), -7.292115e-5 * 0.5, 1e-15);  // up = negative down
}

TEST(Earth, RadiiOfCurvature) {
  // Equator: R_E = a, R_N = a(1-e²); pole: both a/sqrt(1-e²).
  EXPECT_NEAR(EarthModel::radius_east_m(0.0), 6378137.0, 1e-6);
  EXPECT_NEAR(EarthModel::radius_north_m(0.0), 6335439.327, 1e-3);
  EXPECT_NEAR(EarthModel::radius_north_m(kPi / 2), 6399593.626, 1e-3);
  EXPECT_NEAR(EarthModel::radius_east_m(kPi / 2), 6399593.626, 1e-3);
}
