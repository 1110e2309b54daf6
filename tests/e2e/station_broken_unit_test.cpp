// "Never store a wrong calibration as good" end to end (issue #10 item 3): stationsim simulates a
// broken or wrongly mounted unit (--imu-fault), stationd runs the factory sequence on it, and the
// run must end FAILED or REVIEW with a reason that names the symptom — never PASS, never the
// unit's active parameters. Real processes (stationsim, stationd, stationctl).
#include "tests/e2e/station_harness.hpp"

namespace imucal::e2e {
namespace {

struct BrokenUnit {
  const char* fault;    ///< stationsim --imu-fault
  const char* symptom;  ///< must appear in the run's reason
};

class StationBrokenUnit : public ::testing::TestWithParam<BrokenUnit> {};

TEST_P(StationBrokenUnit, RunEndsFailedOrReviewNamingTheSymptom) {
  const BrokenUnit& c = GetParam();
  Station st;
  ASSERT_TRUE(st.start(SimOptions{200.0, 31, {"--imu-fault", c.fault}}));
  const std::string serial = "SIM-0900";
  const CmdResult run =
      st.ctl({"run", "start", "--serial", serial, "--sequence", "short", "--wait"}, 300s);
  EXPECT_EQ(run.exit_code, 1) << run.describe() << "\n" << st.daemon_log();
  const json rec = newest_run(st, serial);
  ASSERT_TRUE(rec.is_object());
  const std::string state = rec.value("state", "");
  EXPECT_TRUE(state == "failed" || state == "review") << rec.dump(2);
  EXPECT_NE(rec.value("failure_reason", "").find(c.symptom), std::string::npos) << rec.dump(2);
  const CmdResult params = st.ctl({"params", serial});
  EXPECT_NE(params.exit_code, 0) << "a broken unit got active parameters\n" << params.describe();
}

INSTANTIATE_TEST_SUITE_P(
    Faults, StationBrokenUnit,
    ::testing::Values(BrokenUnit{"stuck:gyro-y", "gyro axis of that rotation is dead"},
                      BrokenUnit{"swap:gyro-xy", "gyro vs gravity"},
                      BrokenUnit{"flip:gyro-z", "table vs IMU rotation"},
                      BrokenUnit{"not-on-table", "did not move with the table"},
                      BrokenUnit{"fixture-rot90", "wrong fixture orientation"},
                      BrokenUnit{"saturate:5", "saturation (IMU_STATUS.GyroSaturated)"}),
    [](const ::testing::TestParamInfo<BrokenUnit>& i) {
      std::string n = i.param.fault;
      for (char& ch : n)
        if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
      return n;
    });

}  // namespace
}  // namespace imucal::e2e
