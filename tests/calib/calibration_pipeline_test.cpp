// The calibration job (calib/pipeline/calibration_pipeline.hpp) with its two methods run
// concurrently (issue #11) gives exactly what it gives with them one after the other: the same
// parameters, sigmas, metrics and cross-check, bit for bit; progress phases never arrive from two
// threads at once; an error of the method on the second thread reaches the caller.
#include "calib/pipeline/calibration_pipeline.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <set>
#include <string>

#include "ains_test_support.hpp"
#include "calib/sim/sim_input.hpp"

namespace imucal::calib {
using namespace imucal::calib::core;
using namespace imucal::calib::effects;
using namespace imucal::calib::pipeline;
using namespace imucal::calib::sim;
namespace {

CalibrationInput short_run_input(uint64_t seed) {
  const UnitModel unit = default_unit();
  const SimResult sim =
      testing::simulate_run(testing::short_profile(), TableGeometry{}, unit, seed, true);
  return input_from_simulation(sim, TableGeometry{}, testing::factory_site(), unit.noise);
}

TEST(CalibrationPipeline, ConcurrentMethodsGiveBitForBitTheSequentialResult) {
  const CalibrationInput in = short_run_input(11);
  PipelineOptions sequential;
  sequential.concurrent = false;
  PipelineOptions concurrent;
  std::atomic<int> inside{0}, overlaps{0};
  std::set<std::string> phases;
  concurrent.on_phase = [&](const std::string& p) {
    if (inside++ > 0) ++overlaps;
    phases.insert(p);
    inside--;
  };
  const PipelineResult a = run_calibration(in, sequential);
  const PipelineResult b = run_calibration(in, concurrent);
  ASSERT_TRUE(a.ains && a.nlsq && b.ains && b.nlsq);
  for (const auto& [x, y] : {std::pair{&*a.ains, &*b.ains}, std::pair{&*a.nlsq, &*b.nlsq}}) {
    EXPECT_EQ(x->result.params.to_vector(), y->result.params.to_vector());
    EXPECT_EQ(x->result.sigma.to_vector(), y->result.sigma.to_vector());
    EXPECT_EQ(x->metrics.orientation_rmse_mdeg, y->metrics.orientation_rmse_mdeg);
    EXPECT_EQ(x->metrics.accel_rmse_ug, y->metrics.accel_rmse_ug);
  }
  ASSERT_TRUE(a.crosscheck && b.crosscheck);
  EXPECT_EQ(a.crosscheck->pass, b.crosscheck->pass);
  EXPECT_EQ(a.pass(), b.pass());
  EXPECT_EQ(overlaps.load(), 0);
  EXPECT_EQ(phases.count("AINS calibration"), 1u);
  EXPECT_EQ(phases.count("NLSQ calibration"), 1u);
  EXPECT_EQ(phases.count("cross-check"), 1u);
  EXPECT_EQ(phases.count("checking the data"), 1u);
}

TEST(CalibrationPipeline, AnErrorOnTheSecondThreadReachesTheCaller) {
  CalibrationInput in = short_run_input(12);
  PipelineOptions o;
  o.check_data = false;
  o.nlsq.max_outer_iterations = 0;  // refused by NLSQ alone, on the second thread
  try {
    run_calibration(in, o);
    ADD_FAILURE() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("max_outer_iterations"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace imucal::calib
