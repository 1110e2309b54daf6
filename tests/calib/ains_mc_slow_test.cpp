// Monte Carlo consistency of the AINS (ARCHITECTURE §9): over N noise seeds (env IMUCAL_MC_SEEDS,
// default 20) the normalised error (estimate - truth)/σ must have RMS in [0.7, 1.4] per parameter
// group, and the RMS error must reach the CRLB (≤ 1.2 × CRLB per group). Also reports runtime and
// memory of one 60-minute 100 Hz calibration.
#include <gtest/gtest.h>
#include <sys/resource.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <string>

#include "ains_test_support.hpp"
#include "calib/ains/ains.hpp"
#include "calib/checks/crlb.hpp"
#include "calib/sim/sim_input.hpp"

namespace imucal::calib {
using namespace imucal::calib::ains;
using namespace imucal::calib::checks;
using namespace imucal::calib::core;
using namespace imucal::calib::effects;
using namespace imucal::calib::sim;
namespace {

int mc_seeds() {
  const char* env = std::getenv("IMUCAL_MC_SEEDS");
  const int n = env ? std::atoi(env) : 20;
  return n > 0 ? n : 20;
}

TEST(AinsMonteCarlo, NormalisedErrorsAreConsistentAndReachTheCrlb) {
  const auto profile = testing::short_profile();
  const TableGeometry geom{};
  const UnitModel unit = default_unit();
  const int n = mc_seeds();
  const CrlbResult crlb = compute_crlb(profile, geom, testing::factory_site(), unit.noise, 100.0);
  const ParamVector truth = unit.params.to_vector();
  const ParamVector crlb_sigma = crlb.sigma.to_vector();

  std::array<double, kNumParamGroups> sum_z2{}, sum_e2{};
  std::array<int, kNumParamGroups> count{};
  int converged = 0;
  double runtime = 0.0;
  for (int s = 0; s < n; ++s) {
    const SimResult sim =
        testing::simulate_run(profile, geom, unit, 1000 + static_cast<uint64_t>(s), true);
    const CalibrationInput in =
        input_from_simulation(sim, geom, testing::factory_site(), unit.noise);
    const CalibrationResult r = calibrate_ains(in);
    converged += r.converged;
    runtime += r.runtime_s;
    const ParamVector e = r.params.to_vector() - truth;
    const ParamVector sig = r.sigma.to_vector();
    for (int i = 0; i < ParamSet::kSize; ++i) {
      const int g = static_cast<int>(param_info(i).group);
      sum_z2[g] += (e(i) / sig(i)) * (e(i) / sig(i));
      sum_e2[g] += (e(i) / crlb_sigma(i)) * (e(i) / crlb_sigma(i));  // RMS error in CRLB units
      ++count[g];
    }
  }

  std::printf("AINS Monte Carlo, sequence '%s', %d seeds, mean runtime %.3f s\n",
              profile.name.c_str(), n, runtime / n);
  std::printf("%-20s %14s %22s\n", "group", "RMS(err/sigma)", "RMS(err)/CRLB");
  for (int g = 0; g < kNumParamGroups; ++g) {
    const double rms_z = std::sqrt(sum_z2[g] / count[g]);
    const double rms_e_crlb = std::sqrt(sum_e2[g] / count[g]);
    std::printf("%-20s %14.3f %22.3f\n", group_name(static_cast<ParamGroup>(g)).c_str(), rms_z,
                rms_e_crlb);
    // The spec's bounds hold for >= 20 seeds. A reduced CI count widens them to ±4 standard
    // deviations of an RMS over `count` unit normals (sd ≈ 1/sqrt(2 count)), never narrower.
    const double widen = n >= 20 ? 0.0 : 4.0 / std::sqrt(2.0 * count[g]);
    EXPECT_GE(rms_z, std::min(0.7, 1.0 - widen)) << group_name(static_cast<ParamGroup>(g));
    EXPECT_LE(rms_z, std::max(1.4, 1.0 + widen)) << group_name(static_cast<ParamGroup>(g));
    EXPECT_LE(rms_e_crlb, std::max(1.2, 1.0 + widen)) << group_name(static_cast<ParamGroup>(g));
  }
  EXPECT_EQ(converged, n);
}

long max_rss_mb() {
  struct rusage ru {};
  getrusage(RUSAGE_SELF, &ru);
  return ru.ru_maxrss / 1024;
}

TEST(AinsMonteCarlo, SixtyMinuteRunRuntimeAndMemory) {
  // 60 min at 100 Hz: the factory-standard pattern of moves with rests stretched to fill an hour.
  sequences::MotionProfile p = testing::start_profile("sixty-minutes", 120.0);
  const double moves[][2] = {{1, 90}, {0, 90},  {1, 180},  {0, -180}, {1, -90}, {0, 90},
                             {1, 90}, {0, -90}, {1, -180}, {0, 180},  {1, 90},  {0, -90}};
  while (p.duration_s() < 3600.0 - 140.0)
    for (const auto& m : moves)
      if (p.duration_s() < 3600.0 - 140.0) testing::append_move(p, m[0] > 0.5, m[1], 100.0);
  p.segments.back().t1_s = 3600.0;  // stretch the final rest to exactly one hour
  const TableGeometry geom{};
  const UnitModel unit = default_unit();
  const SimResult sim = testing::simulate_run(p, geom, unit, 77, true);
  const CalibrationInput in = input_from_simulation(sim, geom, testing::factory_site(), unit.noise);
  const long rss_before = max_rss_mb();
  const std::clock_t cpu0 = std::clock();
  const AinsResult r = calibrate_ains_detailed(in);
  const double cpu_s = static_cast<double>(std::clock() - cpu0) / CLOCKS_PER_SEC;
  const long rss_after = max_rss_mb();
  std::printf(
      "60-min run: %zu samples (%.0f s), %d passes, runtime %.3f s wall / %.3f s CPU, %zu smoothed "
      "epochs, "
      "peak RSS %ld MB before / %ld MB after calibration (input itself ~%zu MB)\n",
      in.imu.size(), p.duration_s(), r.calibration.iterations, r.calibration.runtime_s, cpu_s,
      r.smoothed.size(), rss_before, rss_after,
      (in.imu.size() * (sizeof(ImuIncrement) + sizeof(ReferenceSample))) >> 20);
  EXPECT_TRUE(r.calibration.converged);
  EXPECT_LT(rss_after - rss_before, 250);
  const ParamVector e = r.calibration.params.to_vector() - unit.params.to_vector();
  const ParamVector s = r.calibration.sigma.to_vector();
  for (int i = 0; i < ParamSet::kSize; ++i)
    EXPECT_LT(std::abs(e(i)), 4.0 * s(i)) << param_info(i).name;
}

}  // namespace
}  // namespace imucal::calib
