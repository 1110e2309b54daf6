// Issue #23 "What it must show": Monte Carlo RMS(error/σ) in [0.9, 1.1] per parameter group on
// factory-fast, for both methods on the same noise seeds (the σ each reports is honest on the new
// sequence, as tests/calib/factory_mc_slow_test.cpp holds them on factory-std with a [0.7, 1.4]
// band). The sample RMS of n ratios scatters by about 1/√(2n) around its true value: at the full
// count (IMUCAL_WHOLE_COUNTS=1 or IMUCAL_MC_SEEDS ≥ 400, n ≥ 1200 per group, a standard error ≤
// 0.02) the band is [0.9, 1.1] as the issue states; a quicker run (the default 20 seeds, CI) widens
// it by three of those standard errors, said in its output — the figure in the README is from the
// full count. AINS's gyro misalignments sit at the band's lower edge (its σ ~10 % larger than its
// errors): 0.8995 at 200 seeds, 0.901 at 400; README says so.
#include <gtest/gtest.h>

#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <mutex>
#include <thread>

#include "calib/ains/ains.hpp"
#include "calib/core/site_presets.hpp"
#include "calib/nlsq/nlsq.hpp"
#include "calib/sim/sim_input.hpp"
#include "calib/sim/truth_sim.hpp"
#include "sequences/library.hpp"
#include "tests/support/ci_count.hpp"

using namespace imucal;
using namespace imucal::calib;
using namespace imucal::calib::ains;
using namespace imucal::calib::core;
using namespace imucal::calib::effects;
using namespace imucal::calib::nlsq;
using namespace imucal::calib::sim;

namespace {

constexpr int kFullCount = 400;

/// 20 seeds in ctest, the full count under IMUCAL_WHOLE_COUNTS=1; IMUCAL_MC_SEEDS overrides.
int mc_seeds_factory_fast_mc() { return test_support::test_count("IMUCAL_MC_SEEDS", 20, kFullCount); }

struct GroupStats {
  std::array<double, kNumParamGroups> z2{};
  std::array<int, kNumParamGroups> n{};
  void add(const CalibrationResult& r, const ParamVector& truth) {
    const ParamVector e = r.params.to_vector() - truth, s = r.sigma.to_vector();
    for (int i = 0; i < ParamSet::kSize; ++i) {
      const int g = static_cast<int>(param_info(i).group);
      z2[g] += std::pow(e(i) / s(i), 2);
      ++n[g];
    }
  }
  double rms(int g) const { return std::sqrt(z2[g] / n[g]); }
};

}  // namespace

TEST(FactoryFastMonteCarlo, BothMethodsReportHonestSigmaWithinTenPercent) {
  const auto profile = sequences::load_profile("factory-fast");
  const Site site = demo_factory_site();
  const UnitModel unit = default_unit();
  const int seeds = mc_seeds_factory_fast_mc();
  const ParamVector truth = unit.params.to_vector();
  GroupStats ains, nlsq;
  std::mutex m;
  std::atomic<int> next{0}, unconverged{0};
  auto worker = [&] {
    for (int k = next++; k < seeds; k = next++) {
      SimOptions opt;
      opt.seed = 23000 + static_cast<uint64_t>(k);
      const SimResult sim = simulate(profile, TableGeometry{}, site, unit, opt);
      const CalibrationInput in = input_from_simulation(sim, TableGeometry{}, site, unit.noise);
      const CalibrationResult a = calibrate_ains(in), b = calibrate_nlsq(in);
      std::lock_guard<std::mutex> lock(m);
      if (!(a.converged && b.converged)) ++unconverged;
      ains.add(a, truth);
      nlsq.add(b, truth);
    }
  };
  std::thread second(worker);  // two cores
  worker();
  second.join();
  EXPECT_EQ(unconverged, 0);
  std::printf("factory-fast Monte Carlo, %d seeds (full count %d)\n", seeds, kFullCount);
  std::printf("%-20s %5s %12s %12s %16s\n", "group", "n", "AINS err/σ", "NLSQ err/σ", "band");
  for (int g = 0; g < kNumParamGroups; ++g) {
    const std::string name = group_name(static_cast<ParamGroup>(g));
    const double slack = seeds >= kFullCount ? 0.0 : 3.0 / std::sqrt(2.0 * ains.n[g]);
    const double lo = 0.9 - slack, hi = 1.1 + slack;
    std::printf("%-20s %5d %12.3f %12.3f     [%.3f, %.3f]\n", name.c_str(), ains.n[g], ains.rms(g),
                nlsq.rms(g), lo, hi);
    EXPECT_GE(ains.rms(g), lo) << name;
    EXPECT_LE(ains.rms(g), hi) << name;
    EXPECT_GE(nlsq.rms(g), lo) << name;
    EXPECT_LE(nlsq.rms(g), hi) << name;
  }
}
