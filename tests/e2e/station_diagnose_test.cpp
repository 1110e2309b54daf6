// `stationctl diagnose` off the control thread (issue #22 item 3): the diagnosis of an hour's run
// (factory-60) takes seconds of CPU; meanwhile another client polls `run.status` every 100 ms and
// every answer comes within 50 ms. While it runs a second diagnosis and a run start are refused
// naming it; while a run captures, a diagnosis is refused with the reason.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <thread>

#include "station/control/control_client.hpp"
#include "tests/e2e/station_harness.hpp"

namespace imucal::e2e {
namespace {

TEST(StationDiagnose, AnHoursDiagnosisLeavesStatusAnsweredWithin50ms) {
  Station st;
  SimOptions o;
  o.speed = 400.0;
  ASSERT_TRUE(st.start(o));
  const CmdResult run = st.ctl({"run", "start", "--serial", "DIAG-0001", "--sequence", "factory-60",
                                "--operator", "e2e", "--wait"},
                               600s);
  ASSERT_EQ(run.exit_code, 0) << run.describe() << "\ndaemon log:\n" << st.daemon_log();
  const std::string run_id = std::to_string(run_id_of(newest_run(st, "DIAG-0001")));

  std::atomic<bool> done{false};
  CmdResult diag;
  std::thread diagnosing([&] {
    diag = st.ctl({"diagnose", run_id, "--json"}, 300s);
    done = true;
  });
  station::control::ControlClient poller(st.socket_path());
  std::vector<double> latency_ms;
  bool refused_second = false, refused_start = false;
  while (!done) {
    const auto t0 = Clock::now();
    const station::control::Reply r = poller.call("run.status");
    latency_ms.push_back(std::chrono::duration<double, std::milli>(Clock::now() - t0).count());
    EXPECT_TRUE(r.ok) << r.error_message;
    if (latency_ms.size() == 5) {  // the diagnosis is under way by now
      station::control::ControlClient other(st.socket_path());
      const station::control::Reply second =
          other.call("diagnose", {{"run_id", std::stoll(run_id)}});
      refused_second = !second.ok && second.error_code == "busy" &&
                       second.error_message.find("being diagnosed") != std::string::npos;
      station::control::ControlClient starter(st.socket_path());
      const station::control::Reply start = starter.call("run.start", {{"serial", "DIAG-0002"}});
      refused_start = !start.ok && start.error_message.find("being diagnosed") != std::string::npos;
      EXPECT_TRUE(refused_second) << second.error_code << ": " << second.error_message;
      EXPECT_TRUE(refused_start) << start.error_code << ": " << start.error_message;
    }
    std::this_thread::sleep_for(100ms);
  }
  diagnosing.join();
  EXPECT_EQ(diag.exit_code, 0) << diag.describe();
  EXPECT_EQ(diag.json_out().value("run_id", 0LL), std::stoll(run_id)) << diag.describe();
  const double worst = *std::max_element(latency_ms.begin(), latency_ms.end());
  std::fprintf(stderr, "[e2e] %zu status answers during the diagnosis, slowest %.1f ms\n",
               latency_ms.size(), worst);
  EXPECT_GE(latency_ms.size(), 6u) << "the diagnosis took under 0.6 s: nothing was measured";
  EXPECT_LT(worst, 50.0);

  // While a run captures, a diagnosis is refused with the reason (exit 3: refused).
  ASSERT_EQ(st.ctl({"run", "start", "--serial", "DIAG-0003", "--sequence", "short"}).exit_code, 0);
  const CmdResult during = st.ctl({"diagnose", run_id});
  EXPECT_EQ(during.exit_code, 3) << during.describe();
  EXPECT_NE((during.out + during.err).find("one run at a time"), std::string::npos)
      << during.describe();
  st.ctl({"run", "abort"});
}

}  // namespace
}  // namespace imucal::e2e
