// Monte Carlo consistency of the NLSQ calibration (ARCHITECTURE §9): over N independent noise
// realisations of the factory-standard sequence, the estimation error divided by the reported σ
// must have RMS in [0.7, 1.4] for every parameter group, with and without the table heading. Too
// small means σ is pessimistic, too large means σ lies (missing noise source, wrong whitening, bias
// of the method).
// N = $IMUCAL_MC_SEEDS (default 20).
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "calib/core/calibration_input.hpp"
#include "calib/core/site_presets.hpp"
#include "calib/nlsq/nlsq.hpp"
#include "calib/sim/sim_input.hpp"
#include "calib/sim/truth_sim.hpp"
#include "sequences/library.hpp"

using namespace imucal;
using namespace imucal::calib;
using namespace imucal::calib::core;
using namespace imucal::calib::effects;
using namespace imucal::calib::nlsq;
using namespace imucal::calib::sim;

namespace {

int mc_seeds_nlsq_mc() {
  const char* s = std::getenv("IMUCAL_MC_SEEDS");
  if (s == nullptr || *s == '\0') return 20;
  const int n = std::atoi(s);
  return n > 0 ? n : 20;
}

Site factory_site() { return demo_factory_site(); }

struct GroupStatsNlsqMc {
  double sum_sq = 0.0;
  int count = 0;
  double max_abs = 0.0;
};

void run_monte_carlo(const std::string& sequence, const UnitModel& unit, uint64_t seed0,
                     const NlsqOptions& opt = {}) {
  const sequences::MotionProfile profile = sequences::load_profile(sequence);
  const TableGeometry geom;
  const int n = mc_seeds_nlsq_mc();
  std::array<GroupStatsNlsqMc, kNumParamGroups> groups{};
  std::array<double, ParamSet::kSize> per_param_sq{};
  double runtime_sum = 0.0, runtime_max = 0.0;
  size_t samples = 0;
  int iterations_max = 0;
  for (int k = 0; k < n; ++k) {
    SimOptions so;
    so.noise = true;
    so.seed = seed0 + static_cast<uint64_t>(k);
    const SimResult sim = simulate(profile, geom, factory_site(), unit, so);
    const CalibrationInput in = input_from_simulation(sim, geom, factory_site(), unit.noise);
    samples = in.imu.size();
    const CalibrationResult res = calibrate_nlsq(in, opt);
    ASSERT_TRUE(res.converged) << "seed " << so.seed;
    runtime_sum += res.runtime_s;
    runtime_max = std::max(runtime_max, res.runtime_s);
    iterations_max = std::max(iterations_max, res.iterations);
    const ParamVector x = res.params.to_vector();
    const ParamVector t = sim.truth.to_vector();
    const ParamVector s = res.sigma.to_vector();
    for (int i = 0; i < ParamSet::kSize; ++i) {
      ASSERT_GT(s(i), 0.0) << param_info(i).name;
      const double z = (x(i) - t(i)) / s(i);
      GroupStatsNlsqMc& g = groups[static_cast<size_t>(param_info(i).group)];
      g.sum_sq += z * z;
      g.count += 1;
      g.max_abs = std::max(g.max_abs, std::abs(z));
      per_param_sq[static_cast<size_t>(i)] += z * z;
    }
  }
  std::printf("NLSQ Monte Carlo (%s): sequence '%s', %zu samples, %d seeds\n",
              opt.use_table_heading ? "with table heading" : "gravity only, eq. 50",
              sequence.c_str(), samples, n);
  std::printf("  calibrate_nlsq runtime: mean %.3f s, max %.3f s; outer iterations <= %d\n",
              runtime_sum / n, runtime_max, iterations_max);
  std::printf("  %-22s %10s %8s %10s\n", "group", "RMS(e/s)", "count", "max|e/s|");
  for (int gi = 0; gi < kNumParamGroups; ++gi) {
    const GroupStatsNlsqMc& g = groups[static_cast<size_t>(gi)];
    const double rms = std::sqrt(g.sum_sq / g.count);
    std::printf("  %-22s %10.3f %8d %10.3f\n", group_name(static_cast<ParamGroup>(gi)).c_str(), rms,
                g.count, g.max_abs);
  }
  std::printf("  per parameter RMS(e/s):\n");
  for (int i = 0; i < ParamSet::kSize; ++i)
    std::printf("    %-28s %6.3f\n", param_info(i).name.c_str(),
                std::sqrt(per_param_sq[static_cast<size_t>(i)] / n));
  for (int gi = 0; gi < kNumParamGroups; ++gi) {
    const GroupStatsNlsqMc& g = groups[static_cast<size_t>(gi)];
    const double rms = std::sqrt(g.sum_sq / g.count);
    EXPECT_GE(rms, 0.7) << group_name(static_cast<ParamGroup>(gi)) << ": sigma too pessimistic";
    EXPECT_LE(rms, 1.4) << group_name(static_cast<ParamGroup>(gi)) << ": sigma too optimistic";
  }
}

}  // namespace

TEST(NlsqMonteCarlo, FactoryStdDefaultUnitErrorOverSigmaRms) {
  run_monte_carlo("factory-std", default_unit(), 1000);
}

// The paper's gravity-only eq. 50 form (NlsqOptions::use_table_heading = false): less precise on
// the gyro terms, but its σ must be just as honest.
TEST(NlsqMonteCarlo, FactoryStdGravityOnlyErrorOverSigmaRms) {
  NlsqOptions opt;
  opt.use_table_heading = false;
  run_monte_carlo("factory-std", default_unit(), 3000, opt);
}

// Far from nominal (edge of the unit spec): the re-linearised solution must be as consistent.
TEST(NlsqMonteCarlo, ShortSequenceFarFromNominalErrorOverSigmaRms) {
  UnitModel unit = default_unit();
  ParamSet& p = unit.params;
  p.accel_bias_mps2 = Eigen::Vector3d(-2000.0, 1800.0, 2000.0) * kMicroG_mps2;
  p.accel_M << -2000e-6, 2e-3, -1.5e-3,  //
      -2e-3, 2000e-6, 1.9e-3,            //
      1.7e-3, -2e-3, -2000e-6;
  p.gyro_bias_radps = Eigen::Vector3d(-0.1, 0.09, 0.1) * kDegPerHourToRadPerSec;
  p.gyro_M << 2000e-6, -2e-3, 1.8e-3,  //
      2e-3, -2000e-6, -1.6e-3,         //
      -2e-3, 1.9e-3, 2000e-6;
  run_monte_carlo("short", unit, 5000);
}
