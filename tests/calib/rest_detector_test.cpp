// At-rest detection from the IMU data alone (calib/core/rest_detector.hpp), on field-simulator runs
// whose true rest spans are known: no false rest while the hand turns the unit, and at least 95 %
// of the true rest time found — also on a drifting, rocking deck.
#include "calib/core/rest_detector.hpp"

#include <gtest/gtest.h>

#include "calib/core/site_presets.hpp"
#include "calib/sim/field_sim.hpp"
#include "sequences/library.hpp"

namespace imucal::calib {
using namespace imucal::calib::core;
using namespace imucal::calib::effects;
using namespace imucal::calib::sim;
namespace {

struct Score {
  double found = 0.0;     ///< fraction of true rest samples detected
  size_t false_rest = 0;  ///< samples detected at rest while the hand turns the unit
};

Score score(const FieldSimResult& r, const std::vector<bool>& rest) {
  size_t true_rest = 0, hit = 0;
  Score s;
  for (size_t k = 0; k < rest.size(); ++k) {
    true_rest += r.true_rest[k];
    hit += r.true_rest[k] && rest[k];
    s.false_rest += !r.true_rest[k] && rest[k];
  }
  s.found = true_rest ? static_cast<double>(hit) / true_rest : 0.0;
  return s;
}

FieldSimResult run_rest_detector(Setting s, uint64_t seed, double rock_deg = 0.05) {
  FieldSimOptions o;
  o.setting = s;
  o.seed = seed;
  o.rock_amplitude_deg = rock_deg;
  Site site = demo_factory_site();
  site.gravity_mps2.reset();
  return simulate_field(sequences::load_profile("factory-std"), site, default_unit(), o);
}

TEST(RestDetector, SeaWithDriftAndRockingNoFalseRestAndNearlyAllRestFound) {
  for (uint64_t seed : {1, 2, 3}) {
    const FieldSimResult r = run_rest_detector(Setting::kSea, seed);
    const Score s = score(r, detect_rest(r.imu));
    EXPECT_EQ(s.false_rest, 0u) << "seed " << seed;
    EXPECT_GE(s.found, 0.95) << "seed " << seed;
    std::printf("sea seed %llu: %.1f %% of the true rest time found, %zu false rest samples\n",
                static_cast<unsigned long long>(seed), 100 * s.found, s.false_rest);
  }
}

TEST(RestDetector, RougherSeaStillNoFalseRest) {
  // Four times the calm-water rocking (0.2°, peak rate ≈ 0.16 °/s): still far below a hand turn.
  const FieldSimResult r = run_rest_detector(Setting::kSea, 4, 0.2);
  const Score s = score(r, detect_rest(r.imu));
  EXPECT_EQ(s.false_rest, 0u);
  EXPECT_GE(s.found, 0.95);
}

TEST(RestDetector, LandRun) {
  const FieldSimResult r = run_rest_detector(Setting::kLand, 5);
  const Score s = score(r, detect_rest(r.imu));
  EXPECT_EQ(s.false_rest, 0u);
  EXPECT_GE(s.found, 0.95);
}

TEST(RestDetector, ShortPausesAreNotRestAndBadOptionsAreRefused) {
  // A 4 s pause (shorter than min_rest_s = 10 s) inside motion is not a rest.
  ImuSeries imu(3000);
  for (size_t k = 0; k < imu.size(); ++k) {
    imu[k].t_s = 0.01 * (k + 1);
    imu[k].dt_s = 0.01;
    const bool pause = k >= 1300 && k < 1700;
    imu[k].dtheta_rad = Eigen::Vector3d(pause ? 0.0 : 0.2 * 0.01, 0, 0);  // 11 °/s turning
    imu[k].dv_mps = Eigen::Vector3d(0, 0, -9.8 * 0.01);
  }
  const std::vector<bool> rest = detect_rest(imu);
  for (size_t k = 0; k < imu.size(); ++k) EXPECT_FALSE(rest[k]) << k;
  RestDetectorOptions bad;
  bad.window_s = 0.0;
  EXPECT_THROW(detect_rest(imu, bad), std::invalid_argument);
  imu[7].dv_mps(1) = std::nan("");
  try {
    detect_rest(imu);
    ADD_FAILURE() << "a NaN sample must be refused";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("imu[7]"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace imucal::calib
