// Issue #23 "What it must show", last factory-fast line: a station run on factory-fast (the
// designed sequence, 60 % of factory-std's table time) ends PASS end to end — stationsim +
// stationd + stationctl as real processes — and the stored parameters lie within 4 σ of the
// simulator's truth, each σ close to the CRLB the designer promised (within 30 %: one run).
#include <cmath>

#include "calib/checks/crlb.hpp"
#include "db/archive/param_json.hpp"
#include "db/archive/run_archive.hpp"
#include "sequences/library.hpp"
#include "tests/e2e/station_harness.hpp"

namespace imucal::e2e {
namespace {

TEST(StationFactoryFast, ARunOnTheDesignedSequencePassesWithinFourSigmaOfTruth) {
  Station st;
  ASSERT_TRUE(st.start());
  const auto t0 = Clock::now();
  const CmdResult run = st.ctl({"run", "start", "--serial", "FAST-0001", "--sequence",
                                "factory-fast", "--operator", "e2e", "--wait"},
                               600s);
  std::fprintf(stderr, "[e2e] factory-fast run: %.1f s wall\n",
               std::chrono::duration<double>(Clock::now() - t0).count());
  ASSERT_EQ(run.exit_code, 0) << run.describe() << "\ndaemon log:\n" << st.daemon_log();
  EXPECT_TRUE(contains_ci(run.out + run.err, "PASS")) << run.describe();

  const json runs = history_runs(st, "FAST-0001");
  ASSERT_EQ(runs.size(), 1u) << runs.dump(2);
  EXPECT_EQ(runs[0].value("state", ""), "done");
  EXPECT_EQ(runs[0]["verdict"], json("PASS")) << runs[0].dump(2);
  EXPECT_EQ(runs[0].value("sequence_name", ""), "factory-fast");

  const CmdResult params = st.ctl({"--json", "params", "FAST-0001"});
  ASSERT_EQ(params.exit_code, 0) << params.describe();
  write_text(st.path("params.json"), params.out);
  calib::core::ParamSet sigma;
  const calib::core::ParamSet estimate =
      db::archive::read_param_file(st.path("params.json"), &sigma);
  const db::archive::Truth truth = db::archive::read_truth_json(st.truth_path());
  const auto profile = sequences::load_profile("factory-fast");
  const calib::core::ParamVector crlb =
      calib::checks::compute_crlb(profile, calib::core::TableGeometry{},
                                  calib::core::demo_factory_site(), calib::core::NoiseModel{},
                                  100.0)
          .sigma.to_vector();
  const calib::core::ParamVector x = estimate.to_vector(), x_true = truth.params.to_vector(),
                                 s = sigma.to_vector();
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
    const auto& info = calib::core::param_info(i);
    EXPECT_LE(std::abs(x(i) - x_true(i)), 4.0 * s(i))
        << info.name << ": error " << (x(i) - x_true(i)) * info.si_to_human << " "
        << info.human_unit << ", sigma " << s(i) * info.si_to_human;
    EXPECT_NEAR(s(i) / crlb(i), 1.0, 0.3) << info.name << ": the stored sigma against the CRLB";
  }
}

}  // namespace
}  // namespace imucal::e2e
