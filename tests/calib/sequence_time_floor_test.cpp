// Why issue #11's "factory-fast" cannot have every parameter group's CRLB σ at or below
// factory-std's in 60 % of its table time: a constant bias seen through white noise of density N
// for T seconds cannot be known better than N/√T, whatever the sequence (its Fisher information is
// at most T/N²; the other parameters only take information away). factory-std already sits within
// a few per cent of that floor for the accelerometer and gyro biases, so any sequence that is 40 %
// shorter has σ ≥ √(1/0.6) ≈ 1.29 × the floor there. This test holds the CRLB engine to the floor
// (it would fail if the covariance run invented information) and prints the table time that σ ≤
// factory-std's would need.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <regex>
#include <sstream>
#include <string>

#include "calib/checks/crlb.hpp"
#include "calib/core/site_presets.hpp"
#include "sequences/library.hpp"
#include "sequences/parser.hpp"
#include "sequences/profile_generator.hpp"

namespace imucal::calib {
using namespace imucal::calib::checks;
using namespace imucal::calib::core;
namespace {

std::string read_file(const std::string& path) {
  std::ifstream in(path);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// factory-std with every rest scaled by `rest_factor` and rotations at `rate_dps`.
sequences::MotionProfile scaled_factory_std(double rest_factor, double rate_dps) {
  std::string text = read_file(std::string(IMUCAL_SEQUENCE_DIR) + "/factory-std.toml");
  std::string out;
  std::istringstream lines(text);
  const std::regex rest(R"(^rest_s = ([0-9.]+))"), rate(R"(^rate_dps = ([0-9.]+))");
  for (std::string line; std::getline(lines, line);) {
    std::smatch m;
    if (std::regex_search(line, m, rest))
      line = "rest_s = " + std::to_string(std::stod(m[1]) * rest_factor);
    else if (std::regex_search(line, m, rate))
      line = "rate_dps = " + std::to_string(rate_dps);
    out += line + "\n";
  }
  return sequences::generate_profile(sequences::parse_sequence_string(out, "scaled factory-std"));
}

struct Floors {
  double accel_ratio = 0;  ///< worst σ / (VRW/√T) over the three accelerometer biases
  double gyro_ratio = 0;   ///< the same for the gyro biases with ARW
  ParamSet sigma;
  double duration_s = 0;
};

Floors floors_of(const sequences::MotionProfile& p, const NoiseModel& noise) {
  const CrlbResult c = compute_crlb(p, TableGeometry{}, demo_factory_site(), noise, 100.0);
  Floors f;
  f.sigma = c.sigma;
  f.duration_s = p.duration_s();
  const double accel_floor = noise.vrw_mps_per_sqrt_s / std::sqrt(f.duration_s);
  const double gyro_floor = noise.arw_rad_per_sqrt_s / std::sqrt(f.duration_s);
  f.accel_ratio = 1e9;
  f.gyro_ratio = 1e9;
  for (int i = 0; i < 3; ++i) {
    f.accel_ratio = std::min(f.accel_ratio, c.sigma.accel_bias_mps2(i) / accel_floor);
    f.gyro_ratio = std::min(f.gyro_ratio, c.sigma.gyro_bias_radps(i) / gyro_floor);
  }
  return f;
}

TEST(SequenceTimeFloor, NoSequenceBeatsTheBiasNoiseFloorSoFactoryStdsSigmaNeedsMostOfItsTime) {
  const NoiseModel noise;
  const Floors std_floors = floors_of(sequences::load_profile("factory-std"), noise);
  // The engine never beats the floor, on factory-std or on a 40 % shorter variant of it.
  EXPECT_GE(std_floors.accel_ratio, 1.0);
  EXPECT_GE(std_floors.gyro_ratio, 1.0);
  const Floors fast = floors_of(scaled_factory_std(0.6, 20.0), noise);
  EXPECT_GE(fast.accel_ratio, 1.0);
  EXPECT_GE(fast.gyro_ratio, 1.0);
  EXPECT_LE(fast.duration_s, 0.61 * std_floors.duration_s);
  // factory-std is close to the floor already (within 15 %): no design can gain much on it.
  EXPECT_LT(std_floors.accel_ratio, 1.15);

  // The table time any sequence needs for accelerometer-bias σ at or below factory-std's, judged
  // by the group's worst axis (the most lenient reading of "the group's σ"): T ≥ (VRW/σ)².
  const double best = std_floors.sigma.accel_bias_mps2.maxCoeff();
  const double t_needed = std::pow(noise.vrw_mps_per_sqrt_s / best, 2);
  const double t_needed_gyro =
      std::pow(noise.arw_rad_per_sqrt_s / std_floors.sigma.gyro_bias_radps.maxCoeff(), 2);
  std::printf(
      "factory-std %.0f s: accel bias sigma <= %.3f ug (floor ratio %.3f), gyro bias floor "
      "ratio %.3f\n",
      std_floors.duration_s, best / kMicroG_mps2, std_floors.accel_ratio, std_floors.gyro_ratio);
  std::printf(
      "any sequence needs >= %.0f s (%.2f of factory-std) for accel bias sigma <= "
      "factory-std's; factory-std at 0.6 of its rests and 20 deg/s (%.0f s, %.2f): accel "
      "bias sigma x%.2f, gyro bias x%.2f\n",
      t_needed, t_needed / std_floors.duration_s, fast.duration_s,
      fast.duration_s / std_floors.duration_s,
      fast.sigma.accel_bias_mps2.maxCoeff() / std_floors.sigma.accel_bias_mps2.maxCoeff(),
      fast.sigma.gyro_bias_radps.maxCoeff() / std_floors.sigma.gyro_bias_radps.maxCoeff());
  std::printf("and >= %.0f s (%.2f of factory-std) for gyro bias sigma <= factory-std's\n",
              t_needed_gyro, t_needed_gyro / std_floors.duration_s);
  EXPECT_GT(t_needed_gyro, 0.6 * std_floors.duration_s);
  EXPECT_GT(t_needed, 0.6 * std_floors.duration_s)
      << "the floor would allow issue #11's 60 % target after all";
}

}  // namespace
}  // namespace imucal::calib
