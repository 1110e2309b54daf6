// candump log format: exact line format of can-utils 2020.11, writer/reader round trip, parse errors
// with file:line, the candump: replay transport (fast and paced), and interop with tools nobody here
// wrote: python-can's CanutilsLogReader/CanutilsLogWriter (Debian python3-can) and can-utils'
// log2asc/asc2log (Debian can-utils). Those tools are required: a missing one fails the test.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <fstream>
#include <map>
#include <random>
#include <sstream>

#include "drivers/imu/can_channel.hpp"
#include "drivers/imu/candump_log.hpp"
#include "drivers/imu/imu_codec.hpp"
#include "tests/support/run_command.hpp"

namespace imucal::drivers::imu {
namespace {

const std::string kPython = "/usr/bin/python3";  // Debian's interpreter: python3-can lives there
const std::string kScript = std::string(IMUCAL_SOURCE_DIR) + "/tests/drivers/python/candump_interop.py";

std::string temp_path(const std::string& name) {
  return "/tmp/imucal-candump-" + std::to_string(::getpid()) + "-" + name;
}

std::pair<int, std::string> run(const std::string& cmd) {
  const test_support::CommandResult r = test_support::run_command(cmd);
  return {r.code, r.out};
}

void require_tool(const std::string& check, const std::string& package) {
  const auto [rc, out] = run("{ " + check + "; } >/dev/null 2>&1; echo $?");
  ASSERT_EQ(out, "0\n") << "required tool missing: install the Debian package " << package
                        << " (apt-get install -y " << package << ")";
}

CanFrame frame(uint32_t id, std::initializer_list<uint8_t> bytes) {
  CanFrame f;
  f.can_id = id;
  for (uint8_t b : bytes) f.data[f.len++] = b;
  return f;
}

TEST(CandumpFormat, LinesAreExactlyWhatCandumpWrites) {
  // Expected strings written from the can-utils 2020.11 format: "(%010lu.%06lu) %s %s", ids as 3 or
  // 8 upper-case hex digits, data as upper-case hex pairs, "R" + DLC digit for remote frames.
  EXPECT_EQ(format_candump_line({frame(0x123, {0xDE, 0xAD, 0xBE, 0xEF}), 1'000'002'000}, "can0"),
            "(0000000001.000002) can0 123#DEADBEEF");
  EXPECT_EQ(format_candump_line({frame(0x00A, {}), 1'700'000'000'123'456'789}, "vcan0"),
            "(1700000000.123456) vcan0 00A#");
  EXPECT_EQ(format_candump_line({frame(0x1ABCDEF0 | kCanEffFlag, {0x01, 0x0A}), 5'000'000}, "can1"),
            "(0000000000.005000) can1 1ABCDEF0#010A");
  CanFrame rtr = frame(0x7FF | kCanRtrFlag, {});
  rtr.len = 4;
  EXPECT_EQ(format_candump_line({rtr, 0}, "can0"), "(0000000000.000000) can0 7FF#R4");
  rtr.len = 0;
  EXPECT_EQ(format_candump_line({rtr, 0}, "can0"), "(0000000000.000000) can0 7FF#R");
  EXPECT_EQ(format_candump_line({frame(kCanErrFlag | 0x80, {0, 0, 0, 0, 0, 0, 0, 0}), 0}, "can0"),
            "(0000000000.000000) can0 20000080#0000000000000000");
  EXPECT_THROW(format_candump_line({frame(0x1, {}), -1}, "can0"), std::invalid_argument);
  EXPECT_THROW(format_candump_line({frame(0x1, {}), 0}, "can 0"), std::invalid_argument);
}

TEST(CandumpFormat, ParserAcceptsOtherWritersVariants) {
  // python-can: "%f" timestamps without padding and a trailing R/T; can-utils' '.' byte separators.
  CandumpRecord r = parse_candump_line("(1700000000.5) can0 123#11.22.33 T");
  EXPECT_EQ(r.frame.rx_time_ns, 1'700'000'000'500'000'000);
  EXPECT_EQ(r.frame.frame, frame(0x123, {0x11, 0x22, 0x33}));
  EXPECT_EQ(r.interface, "can0");
  r = parse_candump_line("(0000000001.000001) vcan0 0000007B#aa\r");
  EXPECT_EQ(r.frame.frame, frame(0x7B | kCanEffFlag, {0xAA}));
  r = parse_candump_line("(1.0) can0 20000080# R");
  EXPECT_TRUE(r.frame.frame.is_error());
  EXPECT_EQ(r.frame.frame.len, 0);
}

TEST(CandumpFormat, BadLinesAreRefusedWithTheReason) {
  for (const char* bad : {"", "1.0 can0 123#00", "(1.0)", "(1.0) can0", "(x.0) can0 123#00", "(1.0) can0 123",
                          "(1.0) can0 1234#00", "(1.0) can0 800#00", "(1.0) can0 123#0", "(1.0) can0 123#GG",
                          "(1.0) can0 123#000000000000000000", "(1.0) can0 123##1AABB", "(1.0) can0 123#R9",
                          "(1.0) can0 123#00 X", "(1.0) can0 E0000000#00", "(1.1234567890) can0 123#"})
    EXPECT_THROW(parse_candump_line(bad), std::invalid_argument) << "'" << bad << "'";
  // Found by fuzzing: a time past int64 nanoseconds (year 2262) overflowed instead of refusing.
  EXPECT_THROW(parse_candump_line("(170000000000.000000) can0 123#00"), std::invalid_argument);
  EXPECT_NO_THROW(parse_candump_line("(9223372035.000000) can0 123#00"));
}

TEST(CandumpLog, WriterOutputIsParsedBackExactly) {
  const std::string path = temp_path("roundtrip.log");
  std::mt19937_64 rng(8);
  std::vector<ReceivedFrame> frames;
  int64_t t = 1'700'000'000'000'000'000;
  for (int k = 0; k < 2000; ++k) {
    CanFrame f;
    const auto kind = rng() % 10;
    f.can_id = kind == 0 ? ((rng() & kCanEffMask) | kCanEffFlag) : static_cast<uint32_t>(rng() & kCanSffMask);
    if (kind == 1) f.can_id |= kCanRtrFlag;
    if (kind == 2) f.can_id = kCanErrFlag | static_cast<uint32_t>(rng() & 0x1FF);
    f.len = kind == 2 ? 8 : static_cast<uint8_t>(rng() % 9);
    if (kind != 1)
      for (int i = 0; i < f.len; ++i) f.data[static_cast<std::size_t>(i)] = static_cast<uint8_t>(rng());
    t += static_cast<int64_t>(rng() % 5000) * 1000;  // microsecond steps (the format's resolution)
    frames.push_back({f, t});
  }
  {
    CandumpWriter w(path);
    for (const auto& f : frames) w.write(f, "can0");
    w.close();
    EXPECT_EQ(w.frames_written(), frames.size());
  }
  CandumpReader reader(path);
  CandumpRecord rec;
  std::size_t n = 0;
  while (reader.next(rec)) {
    ASSERT_LT(n, frames.size());
    EXPECT_EQ(rec.frame.frame, frames[n].frame) << n;
    EXPECT_EQ(rec.frame.rx_time_ns, frames[n].rx_time_ns) << n;
    EXPECT_EQ(rec.interface, "can0");
    ++n;
  }
  EXPECT_EQ(n, frames.size());
  // The same through the candump: transport.
  auto ch = CanChannel::open("candump:" + path);
  std::vector<ReceivedFrame> got;
  while (!ch->at_end()) ch->read(got, 300);
  ASSERT_EQ(got.size(), frames.size());
  for (std::size_t i = 0; i < got.size(); ++i) EXPECT_EQ(got[i].frame, frames[i].frame);
  EXPECT_EQ(ch->counters().rx_frames, frames.size());
  EXPECT_THROW(ch->write(frames[0].frame), CanChannelError);
  ::unlink(path.c_str());
}

TEST(CandumpLog, MalformedLineNamesFileAndLineButATruncatedLastLineIsTolerated) {
  const std::string path = temp_path("bad.log");
  std::ofstream(path) << "(0000000001.000000) can0 123#00\n\n(0000000001.000100) can0 12#00\n";
  CandumpReader r(path);
  CandumpRecord rec;
  ASSERT_TRUE(r.next(rec));
  try {
    r.next(rec);
    FAIL() << "line 3 is malformed";
  } catch (const CandumpParseError& e) {
    EXPECT_EQ(e.line(), 3U);
    EXPECT_NE(std::string(e.what()).find(path + ":3:"), std::string::npos) << e.what();
  }
  // A writer killed mid-line leaves an unterminated last line: skipped and counted.
  std::ofstream(path) << "(0000000001.000000) can0 123#00\n(0000000001.000100) can0 12";
  auto ch = CanChannel::open("candump:" + path);
  std::vector<ReceivedFrame> got;
  while (!ch->at_end()) ch->read(got);
  EXPECT_EQ(got.size(), 1U);
  EXPECT_EQ(ch->counters().rx_malformed, 1U);
  ::unlink(path.c_str());
  try {
    CanChannel::open("candump:" + path);
    FAIL() << "missing file";
  } catch (const CanChannelError& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos);
  }
}

TEST(CandumpLog, PacedReplayFollowsTheLoggedTimes) {
  const std::string path = temp_path("paced.log");
  {
    CandumpWriter w(path);
    for (int k = 0; k < 21; ++k) w.write({frame(0x100, {static_cast<uint8_t>(k)}), 1'000'000'000 + k * 10'000'000}, "can0");
  }
  CanOpenOptions o;
  o.replay_speed = 2.0;  // 0.2 s of log in 0.1 s
  const auto t0 = std::chrono::steady_clock::now();
  auto ch = CanChannel::open("candump:" + path, o);
  std::vector<ReceivedFrame> got;
  while (!ch->at_end()) {
    ASSERT_TRUE(ch->wait_readable(2000));
    ch->read(got);
  }
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(got.size(), 21U);
  EXPECT_GE(wall_s, 0.099);
  EXPECT_LT(wall_s, 1.0);
  ::unlink(path.c_str());
}

/// A capture like a run's: IMU samples plus other traffic.
std::vector<ReceivedFrame> capture_like(std::size_t samples) {
  std::vector<ReceivedFrame> frames;
  ImuFrameEncoder enc;
  std::mt19937_64 rng(2);
  std::normal_distribution<double> n(0.0, 1.0);
  int64_t t = 1'712'345'678'000'000'000;
  for (std::size_t k = 0; k < samples; ++k) {
    calib::core::ImuIncrement inc;
    for (int i = 0; i < 3; ++i) {
      inc.dtheta_rad(i) = 1e-3 * n(rng);
      inc.dv_mps(i) = 0.05 * n(rng);
    }
    inc.temp_c = 31.5;
    for (const CanFrame& f : enc.encode(inc)) {
      frames.push_back({f, t});
      t += 125'000;
    }
    if (k % 25 == 0) frames.push_back({frame(0x1FFFF001 | kCanEffFlag, {1, 2, 3}), t});
    if (k % 40 == 0) {
      CanFrame r = frame(0x321 | kCanRtrFlag, {});
      r.len = 2;
      frames.push_back({r, t});
    }
  }
  return frames;
}

TEST(CandumpInterop, PythonCanReadsOurLog) {
  require_tool(kPython + " -c 'import can'", "python3-can");
  const std::string path = temp_path("ours.log");
  const auto frames = capture_like(500);
  {
    CandumpWriter w(path);
    for (const auto& f : frames) w.write(f, "can0");
  }
  const auto [rc, out] = run(kPython + " " + kScript + " read " + path);
  ASSERT_EQ(rc, 0) << out;
  std::istringstream in(out);
  std::string line;
  std::size_t i = 0;
  while (std::getline(in, line)) {
    if (line.rfind("count ", 0) == 0) {
      EXPECT_EQ(std::stoul(line.substr(6)), frames.size());
      continue;
    }
    ASSERT_LT(i, frames.size());
    std::istringstream ls(line);
    std::string ts, id, data;
    int ext, rtr, err, dlc;
    ls >> ts >> id >> ext >> rtr >> err >> dlc >> data;
    const CanFrame& f = frames[i].frame;
    char expected_ts[32];
    std::snprintf(expected_ts, sizeof expected_ts, "%lld.%06lld", static_cast<long long>(frames[i].rx_time_ns / 1000000000),
                  static_cast<long long>(frames[i].rx_time_ns % 1000000000 / 1000));
    EXPECT_EQ(ts, expected_ts) << i;
    EXPECT_EQ(std::stoul(id, nullptr, 16), f.id()) << i;
    EXPECT_EQ(ext, f.is_extended() ? 1 : 0) << i;
    EXPECT_EQ(rtr, f.is_remote() ? 1 : 0) << i;
    EXPECT_EQ(err, 0) << i;
    EXPECT_EQ(dlc, f.len) << i;
    if (!f.is_remote()) {
      std::string hex;
      for (int b = 0; b < f.len; ++b) {
        char h[3];
        std::snprintf(h, sizeof h, "%02X", f.data[static_cast<std::size_t>(b)]);
        hex += h;
      }
      EXPECT_EQ(data, hex.empty() ? "-" : hex) << i;
    }
    ++i;
  }
  EXPECT_EQ(i, frames.size());
  ::unlink(path.c_str());
}

TEST(CandumpInterop, OurTransportReadsPythonCansLog) {
  require_tool(kPython + " -c 'import can'", "python3-can");
  const std::string spec = temp_path("spec.txt"), path = temp_path("python.log");
  const auto frames = capture_like(300);
  {
    std::ofstream s(spec);
    for (const auto& rf : frames) {
      const CanFrame& f = rf.frame;
      s << rf.rx_time_ns / 1000 << ' ' << std::hex << f.id() << std::dec << ' ' << f.is_extended() << ' '
        << f.is_remote() << ' ' << int(f.len) << ' ';
      if (f.is_remote() || f.len == 0) {
        s << "-";
      } else {
        for (int b = 0; b < f.len; ++b) {
          char h[3];
          std::snprintf(h, sizeof h, "%02x", f.data[static_cast<std::size_t>(b)]);
          s << h;
        }
      }
      s << '\n';
    }
  }
  const auto [rc, out] = run(kPython + " " + kScript + " write " + spec + " " + path);
  ASSERT_EQ(rc, 0) << out;
  auto ch = CanChannel::open("candump:" + path);
  std::vector<ReceivedFrame> got;
  while (!ch->at_end()) ch->read(got);
  ASSERT_EQ(got.size(), frames.size());
  for (std::size_t i = 0; i < got.size(); ++i) {
    CanFrame expected = frames[i].frame;
    if (expected.is_remote()) expected.len = 0;  // python-can 4.1 writes remote frames without DLC
    EXPECT_EQ(got[i].frame, expected) << i;
    EXPECT_EQ(got[i].rx_time_ns, frames[i].rx_time_ns) << i;
  }
  // And the IMU samples in it decode completely.
  ImuFrameDecoder dec;
  std::vector<DecodedSample> samples;
  for (const auto& f : got) dec.push(f, samples);
  dec.flush(samples);
  EXPECT_EQ(samples.size(), 300U);
  EXPECT_EQ(dec.counters().samples_lost, 0U);
  ::unlink(spec.c_str());
  ::unlink(path.c_str());
}

TEST(CandumpInterop, CanUtilsLog2ascAndAsc2logAcceptOurLog) {
  require_tool("command -v log2asc && command -v asc2log", "can-utils");
  const std::string path = temp_path("ours2.log"), asc = temp_path("ours2.asc"), back = temp_path("back.log");
  const auto frames = capture_like(200);
  {
    CandumpWriter w(path);
    for (const auto& f : frames) w.write(f, "can0");
  }
  const auto [rc1, out1] = run("log2asc -I " + path + " -O " + asc + " can0 2>&1");
  ASSERT_EQ(rc1, 0) << out1;
  const auto [rc2, out2] = run("asc2log -I " + asc + " -O " + back + " 2>&1");
  ASSERT_EQ(rc2, 0) << out2;
  // asc2log restores frames and relative times (the ASC file keeps times relative to the first).
  CandumpReader r(back);
  CandumpRecord rec;
  std::size_t i = 0;
  int64_t first = 0;
  while (r.next(rec)) {
    ASSERT_LT(i, frames.size());
    if (i == 0) first = rec.frame.rx_time_ns;
    EXPECT_EQ(rec.frame.frame, frames[i].frame) << i;
    EXPECT_EQ(rec.frame.rx_time_ns - first, frames[i].rx_time_ns - frames[0].rx_time_ns) << i;
    ++i;
  }
  EXPECT_EQ(i, frames.size());
  for (const auto& p : {path, asc, back}) ::unlink(p.c_str());
}

}  // namespace
}  // namespace imucal::drivers::imu
