// Reprocessing a flagged station's runs (issue #25 item 2) as QA does it, end to end: stationsim
// and stationd as separate processes, two units calibrated, then one `stationctl reprocess ID ID
// --gravity-mps2 G` through the daemon's socket: each run reprocessed in turn (the daemon takes one
// job at a time), every accelerometer scale moved by -50 ppm for a surveyed gravity 50 µg higher,
// the old runs kept beside the new; a batch with a run the daemon refuses stops there and names
// the command that goes on; a run given twice is refused before anything starts.
#include <gtest/gtest.h>

#include "calib/core/conventions.hpp"
#include "calib/core/site_presets.hpp"
#include "tests/e2e/station_harness.hpp"

namespace imucal::e2e {
namespace {

/// The AINS accelerometer scale diagonal of a run, from `stationctl show --json`.
std::vector<double> ains_scales(const Station& st, long long run_id) {
  const json show = show_run(st, run_id);
  for (const json& c : show.value("calibrations", json::array()))
    if (c.value("method", "") == "ains") {
      const json& m = c.at("params").at("accel_M");
      return {m[0][0].get<double>(), m[1][1].get<double>(), m[2][2].get<double>()};
    }
  ADD_FAILURE() << "run " << run_id << " has no AINS result";
  return {};
}

TEST(StationReprocess, SeveralRunsWithACorrectedGravityOneAfterAnotherThroughStationctl) {
  Station st;
  SimOptions o;
  o.speed = 400.0;
  ASSERT_TRUE(st.start(o));
  std::vector<long long> old_ids;
  for (const char* serial : {"REP-0001", "REP-0002"}) {
    const CmdResult run = st.ctl(
        {"run", "start", "--serial", serial, "--sequence", "short", "--operator", "e2e", "--wait"},
        600s);
    ASSERT_EQ(run.exit_code, 0) << run.describe() << "\ndaemon log:\n" << st.daemon_log();
    old_ids.push_back(run_id_of(newest_run(st, serial)));
  }
  const std::string a = std::to_string(old_ids[0]), b = std::to_string(old_ids[1]);

  // A run given twice: refused before anything starts.
  const CmdResult twice = st.ctl({"reprocess", a, a});
  EXPECT_EQ(twice.exit_code, 2) << twice.describe();
  EXPECT_NE(twice.err.find("is given twice"), std::string::npos) << twice.describe();

  char g[32];
  std::snprintf(g, sizeof g, "%.9f",
                *calib::core::demo_factory_site().gravity_mps2 + 50 * kMicroG_mps2);
  const CmdResult batch = st.ctl({"reprocess", a, b, "--gravity-mps2", g}, 600s);
  ASSERT_EQ(batch.exit_code, 0) << batch.describe() << "\ndaemon log:\n" << st.daemon_log();
  EXPECT_NE(batch.out.find("run " + a + " -> "), std::string::npos) << batch.describe();
  EXPECT_NE(batch.out.find("run " + b + " -> "), std::string::npos) << batch.describe();
  EXPECT_NE(batch.err.find("[2/2] run " + b + " reprocessing as run"), std::string::npos)
      << batch.describe();
  EXPECT_NE(batch.err.find("only once QA promotes them"), std::string::npos) << batch.describe();
  for (std::size_t i = 0; i < old_ids.size(); ++i) {
    const std::string serial = i == 0 ? "REP-0001" : "REP-0002";
    const json runs = history_runs(st, serial);
    ASSERT_EQ(runs.size(), 2u) << "the old run is kept beside the new: " << runs.dump(1);
    const json& fresh = runs[0];
    EXPECT_EQ(fresh.value("reprocessed_from", 0LL), old_ids[i]) << fresh.dump(1);
    const std::vector<double> before = ains_scales(st, old_ids[i]);
    const std::vector<double> after = ains_scales(st, run_id_of(fresh));
    ASSERT_EQ(after.size(), 3u);
    ASSERT_EQ(before.size(), 3u);
    // f~ = (1 + s) f and f = g: a g 50 µg larger leaves (1 + s) g unchanged, s lower by 50 ppm.
    for (int k = 0; k < 3; ++k)
      EXPECT_NEAR((after[k] - before[k]) * 1e6, -50.0 * kMicroG_mps2 / kStandardGravity_mps2 * 1e6,
                  1.0)
          << serial << " axis " << k;
  }

  // A batch whose second run the daemon refuses (no such run) stops there, the first done, and
  // says how to go on.
  const CmdResult stopped = st.ctl({"reprocess", a, "99999", b}, 600s);
  EXPECT_NE(stopped.exit_code, 0) << stopped.describe();
  EXPECT_NE(stopped.out.find("run " + a + " -> "), std::string::npos) << stopped.describe();
  EXPECT_EQ(stopped.out.find("run " + b + " -> "), std::string::npos) << stopped.describe();
  EXPECT_NE(stopped.err.find("reprocessed 1 of 3; to go on: stationctl reprocess 99999 " + b + ")"),
            std::string::npos)
      << stopped.describe();
}

}  // namespace
}  // namespace imucal::e2e
