// Interop with tools nobody here wrote (issue #3): Debian's `mbpoll` reads the simulator's Modbus
// registers while a daemon run moves the table, and commands a move itself (simulator alone); the
// archived capture.log is read by python3-can's CanutilsLogReader, whose frame count must equal the
// frames_logged the daemon reports (show --json and run.toml [capture]). Fails (never skips) when
// mbpoll or python3-can is missing: tools/setup.sh installs both.
#include <cmath>

#include "tests/e2e/station_harness.hpp"

namespace imucal::e2e {
namespace {

bool near_multiple_of_90(double deg, double tol) {
  const double r = std::remainder(deg, 90.0);
  return std::abs(r) <= tol;
}

TEST(StationInterop, MbpollReadsTheTableWhileARunMovesIt) {
  ASSERT_EQ(access("/usr/bin/mbpoll", X_OK), 0) << "mbpoll is not installed (tools/setup.sh installs it)";
  Station st;
  // Slower than the other tests so that mbpoll (a process per read) sees moves and rests alike.
  ASSERT_TRUE(st.start(SimOptions{50.0, 3, {}}));
  const CmdResult start = st.ctl({"--json", "run", "start", "--serial", "SIM-0100", "--sequence", "short"});
  ASSERT_EQ(start.exit_code, 0) << start.describe();
  const long long run_id = run_id_of(start.json_out());
  ASSERT_GT(run_id, 0) << start.describe();

  std::vector<TableReading> readings;
  std::set<std::pair<long, long>> poses;  // in-position poses (0.01 deg grid)
  const auto deadline = Clock::now() + 90s;
  for (;;) {
    const json run = st.live_run();
    const std::string state = run.is_null() ? "" : run.value("state", "");
    if (state != "preparing" && state != "running") break;
    if (Clock::now() > deadline) FAIL() << "the run did not leave running in 90 s: " << run.dump();
    const TableReading t = read_table(st);
    ASSERT_TRUE(t.ok) << t.raw;
    readings.push_back(t);
  }
  ASSERT_GE(readings.size(), 5u) << "too few mbpoll readings during the run";
  size_t moving = 0, in_position = 0;
  for (const auto& t : readings) {
    EXPECT_FALSE(t.fault()) << t.raw;
    EXPECT_EQ(t.fault_code, 0) << t.raw;
    EXPECT_LE(std::abs(t.outer_deg), 360.0) << t.raw;
    EXPECT_LE(std::abs(t.inner_deg), 360.0) << t.raw;
    if (t.moving()) {
      ++moving;
      EXPECT_TRUE(t.enabled()) << t.raw;  // the daemon drives it
    }
    if (t.in_position() && !t.moving()) {
      ++in_position;
      // The short sequence's poses are all multiples of 90 deg (sequences/short.toml); the daemon's
      // position tolerance is 0.01 deg and mbpoll reads float32.
      EXPECT_TRUE(near_multiple_of_90(t.outer_deg, 0.02) && near_multiple_of_90(t.inner_deg, 0.02))
          << "at rest off the sequence's poses: " << t.outer_deg << ", " << t.inner_deg;
      EXPECT_EQ(t.rate_outer_dps, 0.0) << t.raw;
      EXPECT_EQ(t.rate_inner_dps, 0.0) << t.raw;
      poses.insert({std::lround(t.outer_deg * 100), std::lround(t.inner_deg * 100)});
    }
  }
  std::fprintf(stderr, "[e2e] mbpoll: %zu readings, %zu moving, %zu in position, %zu distinct poses\n",
               readings.size(), moving, in_position, poses.size());
  EXPECT_GT(moving, 0u) << "mbpoll never saw the table move";
  EXPECT_GE(poses.size(), 3u) << "mbpoll saw fewer than 3 rest poses";
  // The heartbeat advances (the PLC program runs under the daemon's polling).
  EXPECT_NE(readings.front().heartbeat, readings.back().heartbeat);

  // Let the run finish (it must still complete with a reader on the side).
  ASSERT_TRUE(wait_until(
      [&] {
        const json j = newest_run(st, "SIM-0100");
        const std::string s = j.is_object() ? j.value("state", "") : "";
        return s == "done" || s == "review" || s == "failed" || s == "aborted";
      },
      120s, 200ms));
  const json rec = newest_run(st, "SIM-0100");
  EXPECT_EQ(rec.value("run_id", -1LL), run_id);
  EXPECT_TRUE(rec.value("state", "") == "done" || rec.value("state", "") == "review") << rec.dump(2);
}

TEST(StationInterop, MbpollCommandsAMoveOnTheSimulator) {
  ASSERT_EQ(access("/usr/bin/mbpoll", X_OK), 0) << "mbpoll is not installed (tools/setup.sh installs it)";
  Station st;
  ASSERT_TRUE(st.start_sim());
  auto ack_seq = [&] {
    const CmdResult r = st.mbpoll({"-1", "-t", "3", "-r", "11", "-c", "2"});
    auto v = mbpoll_values(r.out);
    return std::make_pair(v.count(11) ? std::stoi(v[11]) : -1, v.count(12) ? std::stoi(v[12]) : -1);
  };
  auto command = [&](int code, int seq) {
    // command + command_seq in one write (holding 6, 7), as the register map asks.
    const CmdResult r = st.mbpoll({"-t", "4", "-r", "6"}, {std::to_string(code), std::to_string(seq)});
    EXPECT_EQ(r.exit_code, 0) << r.describe();
    std::pair<int, int> ack;
    EXPECT_TRUE(wait_until([&] { return (ack = ack_seq()).first == seq; }, 10s, 20ms)) << "no ack of " << seq;
    EXPECT_EQ(ack.second, 0) << "command " << code << " rejected with " << ack.second;
  };
  // Targets and rate as big-endian float32 at holding 0, 2, 4.
  const CmdResult targets = st.mbpoll({"-t", "4:float", "-B", "-r", "0"}, {"45", "-20", "15"});
  ASSERT_EQ(targets.exit_code, 0) << targets.describe();
  command(1, 101);  // enable
  command(4, 102);  // home
  ASSERT_TRUE(wait_until([&] { const auto t = read_table(st); return t.ok && t.homed() && t.in_position(); }, 20s, 50ms))
      << read_table(st).raw;
  // Homing may have left the targets alone or not: write them again before the move.
  ASSERT_EQ(st.mbpoll({"-t", "4:float", "-B", "-r", "0"}, {"45", "-20", "15"}).exit_code, 0);
  command(2, 103);  // move
  TableReading t;
  ASSERT_TRUE(wait_until([&] { t = read_table(st); return t.ok && t.in_position() && !t.moving(); }, 30s, 50ms))
      << t.raw;
  EXPECT_NEAR(t.outer_deg, 45.0, 1e-3) << t.raw;
  EXPECT_NEAR(t.inner_deg, -20.0, 1e-3) << t.raw;
  // mbpoll's own float decoding (-B: big-endian word order) agrees.
  const CmdResult floats = st.mbpoll({"-1", "-t", "3:float", "-B", "-r", "0", "-c", "2"});
  ASSERT_EQ(floats.exit_code, 0) << floats.describe();
  auto f = mbpoll_values(floats.out);
  ASSERT_TRUE(f.count(0) && f.count(2)) << floats.describe();
  EXPECT_NEAR(std::stod(f[0]), 45.0, 1e-3) << floats.describe();
  EXPECT_NEAR(std::stod(f[2]), -20.0, 1e-3) << floats.describe();
}

TEST(StationInterop, PythonCanReadsTheArchivedCaptureLogWithTheReportedFrameCount) {
  ASSERT_EQ(access("/usr/bin/python3", X_OK), 0);
  Station st;
  ASSERT_TRUE(st.start());
  const CmdResult run = st.ctl({"run", "start", "--serial", "SIM-0101", "--sequence", "short", "--wait"}, 180s);
  ASSERT_TRUE(run.exit_code == 0 || run.exit_code == 1) << run.describe();
  const json rec = newest_run(st, "SIM-0101");
  ASSERT_TRUE(rec.is_object());
  const json shown = show_run(st, rec.value("run_id", -1LL));
  ASSERT_TRUE(shown.is_object());
  const json& capture = shown["run"]["capture"];
  ASSERT_TRUE(capture.is_object()) << "show --json reports no capture counters:\n" << shown["run"].dump(2);
  ASSERT_TRUE(capture.contains("frames_logged")) << capture.dump(2);
  const long long frames_logged = capture["frames_logged"].get<long long>();
  // 4 frames per IMU sample (drivers/imu/PROTOCOL.md): a short run has tens of thousands.
  EXPECT_GT(frames_logged, 4 * 10000);

  const std::string archive_dir = shown["run"].value("archive_path", "");
  const std::string log = archive_dir + "/capture.log";
  ASSERT_TRUE(fs::exists(log)) << log;
  const CmdResult py = run_command(
      {"/usr/bin/python3", "-c",
       "import can, sys\n"
       "n = 0\n"
       "ids = set()\n"
       "for msg in can.CanutilsLogReader(sys.argv[1]):\n"
       "    n += 1\n"
       "    ids.add(msg.arbitration_id)\n"
       "print(n)\n"
       "print(' '.join(hex(i) for i in sorted(ids)))\n",
       log},
      st.dir().path(), 120s);
  ASSERT_EQ(py.exit_code, 0) << py.describe();
  std::istringstream lines(py.out);
  long long python_count = -1;
  std::string ids_line;
  lines >> python_count;
  std::getline(lines, ids_line);
  std::getline(lines, ids_line);
  EXPECT_EQ(python_count, frames_logged) << "python-can counts " << python_count << " frames in " << log
                                        << ", the daemon reports " << frames_logged;
  // Only the IMU's four identifiers (default base 0x100).
  EXPECT_EQ(ids_line, "0x100 0x101 0x102 0x103") << py.describe();

  // run.toml [capture] states the same count.
  const std::string run_toml = read_text(archive_dir + "/run.toml");
  const std::regex rx(R"(frames_logged\s*=\s*(\d+))");
  std::smatch m;
  ASSERT_TRUE(std::regex_search(run_toml, m, rx)) << run_toml;
  EXPECT_EQ(std::stoll(m[1]), frames_logged) << run_toml;
}

}  // namespace
}  // namespace imucal::e2e
