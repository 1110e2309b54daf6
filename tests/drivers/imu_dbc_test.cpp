// drivers/imu/imu.dbc describes the frames the codec actually sends: a DBC reader nobody here wrote
// (canmatrix, Debian python3-canmatrix) decodes encoded samples and must find the same raw field
// values as the protocol's definition. The tool is required: a missing one fails the test.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <map>
#include <random>
#include <sstream>

#include "drivers/imu/imu_codec.hpp"
#include "tests/support/run_command.hpp"

namespace imucal::drivers::imu {
namespace {

std::pair<int, std::string> run_imu_dbc(const std::string& cmd) {
  const test_support::CommandResult r = test_support::run_command(cmd);
  return {r.code, r.out};
}

TEST(ImuDbc, CanmatrixDecodesOurFramesToTheDocumentedFields) {
  const std::string py = "/usr/bin/python3";
  ASSERT_EQ(run_imu_dbc(py + " -c 'import canmatrix.formats' >/dev/null 2>&1; echo $?").second, "0\n")
      << "required tool missing: install the Debian package python3-canmatrix";
  const std::string dbc = std::string(IMUCAL_SOURCE_DIR) + "/drivers/imu/imu.dbc";
  const std::string script = std::string(IMUCAL_SOURCE_DIR) + "/tests/drivers/python/dbc_decode.py";
  const std::string frames_path = "/tmp/imucal-dbc-" + std::to_string(::getpid()) + ".txt";

  // Samples covering signs, extremes, saturation, unknown temperature and the counter's high byte.
  ImuFrameEncoder enc(kDefaultImuBaseId, false);
  std::mt19937_64 rng(1);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<CanFrame> frames;
  for (int k = 0; k < 300; ++k) {
    calib::core::ImuIncrement inc;
    for (int i = 0; i < 3; ++i) {
      inc.dtheta_rad(i) = 0.6 * u(rng);  // sometimes beyond the range: saturates
      inc.dv_mps(i) = 3.5 * u(rng);
    }
    inc.temp_c = k % 7 == 0 ? std::nan("") : 100.0 * u(rng);
    for (const CanFrame& f : enc.encode(inc, k % 5 == 0 ? status::kGyroFault | status::kBitFail : 0))
      frames.push_back(f);
  }
  {
    std::ofstream out(frames_path);
    for (const CanFrame& f : frames) {
      char line[40];
      std::snprintf(line, sizeof line, "%X ", f.id());
      out << line;
      for (uint8_t b : f.data) {
        std::snprintf(line, sizeof line, "%02X", b);
        out << line;
      }
      out << '\n';
    }
  }
  const auto [rc, out] = run_imu_dbc(py + " " + script + " " + dbc + " " + frames_path + " 2>/dev/null");
  ASSERT_EQ(rc, 0) << out;
  ::unlink(frames_path.c_str());

  std::map<std::size_t, std::map<std::string, long long>> raw;
  std::map<uint32_t, std::string> messages;
  std::istringstream in(out);
  std::string first;
  while (in >> first) {
    if (first == "message") {
      std::string id, name;
      int dlc;
      in >> id >> name >> dlc;
      EXPECT_EQ(dlc, 8) << name;
      messages[static_cast<uint32_t>(std::stoul(id, nullptr, 16))] = name;
      continue;
    }
    std::string signal;
    long long value;
    in >> signal >> value;
    raw[std::stoul(first)][signal] = value;
  }
  EXPECT_EQ(messages, (std::map<uint32_t, std::string>{
                          {0x100, "IMU_AXIS_X"}, {0x101, "IMU_AXIS_Y"}, {0x102, "IMU_AXIS_Z"}, {0x103, "IMU_STATUS"}}));
  ASSERT_EQ(raw.size(), frames.size());
  const char* axis = "XYZ";
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const CanFrame& f = frames[i];
    auto& sig = raw[i];
    const int part = static_cast<int>(f.id() - kDefaultImuBaseId);
    EXPECT_EQ(sig["SampleCounterLow"], f.data[0]) << i;
    if (part < 3) {
      const AxisFields a = unpack_axis(f.data);
      EXPECT_EQ(sig[std::string("DeltaTheta") + axis[part]], a.dtheta_count) << i;
      EXPECT_EQ(sig[std::string("DeltaV") + axis[part]], a.dv_count) << i;
    } else {
      const StatusFields s = unpack_status(f.data);
      EXPECT_EQ(sig["GyroFault"], (s.status & status::kGyroFault) ? 1 : 0) << i;
      EXPECT_EQ(sig["AccelFault"], (s.status & status::kAccelFault) ? 1 : 0) << i;
      EXPECT_EQ(sig["GyroSaturated"], (s.status & status::kGyroSaturated) ? 1 : 0) << i;
      EXPECT_EQ(sig["AccelSaturated"], (s.status & status::kAccelSaturated) ? 1 : 0) << i;
      EXPECT_EQ(sig["TempInvalid"], (s.status & status::kTempInvalid) ? 1 : 0) << i;
      EXPECT_EQ(sig["Startup"], (s.status & status::kStartup) ? 1 : 0) << i;
      EXPECT_EQ(sig["BitFail"], (s.status & status::kBitFail) ? 1 : 0) << i;
      EXPECT_EQ(sig["StatusReserved"], s.status >> 7) << i;
      EXPECT_EQ(sig["Temperature"], s.temperature_count) << i;
      EXPECT_EQ(sig["SampleCounterHigh"], s.counter >> 8) << i;
      EXPECT_EQ(sig["Crc16"], s.crc) << i;
    }
  }
}

}  // namespace
}  // namespace imucal::drivers::imu
