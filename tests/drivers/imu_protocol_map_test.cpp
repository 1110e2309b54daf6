// An IMU's CAN protocol as a protocol file over its DBC (drivers/imu/imu_protocol_map.hpp; issue
// #27 item 2): the built-in protocol's shipped file and a second protocol that differs in every
// way that matters read as their text says, and bad mappings are refused naming file and line.
#include "drivers/imu/imu_protocol_map.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <string>

#include "drivers/imu/builtin_protocol_text.hpp"
#include "tests/support/temp_dir.hpp"

namespace imucal::drivers::imu {
namespace {

const std::string kSourceImuProtocolMap = IMUCAL_SOURCE_DIR;

std::string slurp(const std::string& path) {
  std::ifstream f(path);
  std::ostringstream os;
  os << f.rdbuf();
  return os.str();
}

TEST(ImuProtocolMap, TheBuiltInProtocolFileReadsAsItsProtocol) {
  const ImuProtocolMap m = read_protocol_map(kSourceImuProtocolMap + "/drivers/imu/protocols/imucal-imu-1.toml");
  EXPECT_EQ(m.name, "imucal-imu-1");
  EXPECT_EQ(m.quantity, ImuProtocolMap::Quantity::kIncrements);
  ASSERT_EQ(m.messages.size(), 4u);
  EXPECT_EQ(m.message(m.completes_sample).name, "IMU_STATUS");
  EXPECT_EQ(m.message(m.completes_sample).id, 0x103u);
  EXPECT_EQ(m.signal(m.angular[1]).name, "DeltaThetaY");
  EXPECT_EQ(m.signal(m.velocity[2]).length, 26);
  EXPECT_EQ(m.counter_bits, 16);
  EXPECT_EQ(m.same_in.size(), 3u);
  EXPECT_EQ(m.fault.size(), 3u);
  EXPECT_EQ(m.check, ImuProtocolMap::Check::kCrc16CcittFalse);
  ASSERT_EQ(m.check_covers.size(), 4u);
  EXPECT_EQ(m.check_covers[3].first, 0);
  EXPECT_EQ(m.check_covers[3].last, 5);  // status bytes 0-5, before the CRC itself
}

TEST(ImuProtocolMap, ASecondProtocolWithRatesExtendedIdsAndAMultiplexedStatusReads) {
  const ImuProtocolMap m = read_protocol_map(kSourceImuProtocolMap + "/tests/data/protocols/rates16.toml");
  EXPECT_EQ(m.quantity, ImuProtocolMap::Quantity::kRates);
  ASSERT_EQ(m.messages.size(), 3u);
  for (int i : m.messages) EXPECT_TRUE(m.message(i).extended) << m.message(i).name;
  EXPECT_EQ(m.message(m.completes_sample).id, 0x18FF1200u);
  EXPECT_DOUBLE_EQ(m.angular_scale, 1.7453292519943295e-4);
  EXPECT_DOUBLE_EQ(m.velocity_scale, 9.80665e-3);
  EXPECT_EQ(m.signal(m.angular[0]).order, DbcSignal::ByteOrder::kMotorola);
  EXPECT_EQ(*m.signal(m.fault[0]).multiplex_value, 0);
  EXPECT_EQ(m.check, ImuProtocolMap::Check::kCrc8SaeJ1850);
  EXPECT_EQ(m.check_covers[2].last, 6);
}

/// The second protocol with one replacement in its file (the DBC copied beside it).
class BadMap : public ::testing::Test {
 protected:
  void SetUp() override {
    std::ofstream(dir_.sub("rates16.dbc")) << slurp(kSourceImuProtocolMap + "/tests/data/protocols/rates16.dbc");
    text_ = slurp(kSourceImuProtocolMap + "/tests/data/protocols/rates16.toml");
  }
  void expect_refused(const std::string& from, const std::string& to, const std::string& where,
                      const std::string& what) {
    std::string t = text_;
    const size_t at = t.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    t.replace(at, from.size(), to);
    const std::string path = dir_.sub("bad.toml");
    std::ofstream(path) << t;
    try {
      read_protocol_map(path);
      ADD_FAILURE() << "accepted: " << to;
    } catch (const std::invalid_argument& e) {
      const std::string msg = e.what();
      EXPECT_NE(msg.find(where), std::string::npos) << msg;
      EXPECT_NE(msg.find(what), std::string::npos) << msg;
    }
  }
  test_support::ScopedTempDir dir_{"imucal_protocol_map"};
  std::string text_;
};

int line_of(const std::string& text, const std::string& needle) {
  const size_t at = text.find(needle);
  return 1 + static_cast<int>(std::count(text.begin(), text.begin() + static_cast<long>(at), '\n'));
}

TEST_F(BadMap, AMissingSignalAZeroScaleAndATooWideCounterAreNamed) {
  const int angular = line_of(text_, "angular = [");
  expect_refused("R16_GYRO.RateY", "R16_GYRO.RateQ", "bad.toml:" + std::to_string(angular),
                 "signal 'RateQ' is not in message R16_GYRO");
  expect_refused("R16_GYRO.RateY", "R16_GYRO_RateY", "bad.toml:" + std::to_string(angular),
                 "write MESSAGE.SIGNAL");
  expect_refused("velocity_scale = 9.80665e-3", "velocity_scale = 0.0",
                 "bad.toml:" + std::to_string(line_of(text_, "velocity_scale")),
                 "velocity_scale is 0");
  expect_refused("{ signal = \"R16_STATUS.Counter\", bits = 8 }",
                 "{ signal = \"R16_STATUS.Counter\", bits = 12 }",
                 "bad.toml:" + std::to_string(line_of(text_, "R16_STATUS.Counter\"")),
                 "takes 12 bits but the signal has 8");
  expect_refused("[\"R16_GYRO.RateX\", \"R16_GYRO.RateY\", \"R16_GYRO.RateZ\"]",
                 "[\"R16_GYRO.RateX\", \"R16_GYRO.RateY\"]", "bad.toml:" + std::to_string(angular),
                 "needs 3 signals");
  expect_refused("R16_GYRO.RateZ", "R16_STATUS.Temperature", "bad.toml:" + std::to_string(angular),
                 "is multiplexed: a channel must be in every sample");
  expect_refused("completes_sample = \"R16_STATUS\"", "completes_sample = \"R16_GYRO\"",
                 "bad.toml:", "must be the last of 'messages'");
  expect_refused("\"R16_STATUS:0-6\"", "\"R16_STATUS:0-7\"",
                 "bad.toml:", "covers byte 7 of the check R16_STATUS.Crc8 itself");
  expect_refused("kind = \"crc8-sae-j1850\"", "kind = \"crc32\"",
                 "bad.toml:", "check 'crc32' is not none");
  expect_refused("[status]", "[status]\nbogus = 1", "bad.toml:", "unknown key 'bogus' in [status]");
  expect_refused("quantity = \"rates\"", "quantity = \"speeds\"", "bad.toml:", "quantity 'speeds'");
  expect_refused("dbc = \"rates16.dbc\"", "dbc = \"missing.dbc\"", "missing.dbc",
                 "cannot read the DBC file");
  expect_refused("same_in = [\"R16_GYRO.Counter\", \"R16_ACCEL.Counter\"]",
                 "same_in = [\"R16_GYRO.Counter\"]",
                 "bad.toml:", "message R16_ACCEL carries no copy of the counter's low part");
  expect_refused("temperature = \"R16_STATUS.Temperature\"",
                 "temperature = \"R16_STATUS.Temperature\"\ntemperature_unknown = 1.5",
                 "bad.toml:", "'temperature_unknown' must be an integer");
}

// A device or a directory named as a protocol or DBC file is refused, never read to its end.
TEST(ImuProtocolMap, ADeviceOrADirectoryIsNoProtocolFile) {
  for (const std::string path : {"/dev/zero", "/tmp"}) {
    try {
      read_protocol_map(path);
      ADD_FAILURE() << path << " was read";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(path + ": not a regular file (protocol file)"),
                std::string::npos)
          << e.what();
    }
    EXPECT_THROW(read_dbc(path), std::invalid_argument);
  }
}

// The compiled-in default is the shipped file byte for byte, and parses to the same protocol.
TEST(ImuProtocolMap, TheCompiledInDefaultIsTheShippedFile) {
  EXPECT_EQ(builtin_protocol_toml_text(),
            slurp(kSourceImuProtocolMap + "/drivers/imu/protocols/imucal-imu-1.toml"));
  EXPECT_EQ(builtin_protocol_dbc_text(), slurp(kSourceImuProtocolMap + "/drivers/imu/imu.dbc"));
  const auto m = builtin_protocol_map();
  EXPECT_EQ(m->name, "imucal-imu-1");
  EXPECT_EQ(m->flags.size(), 7u);  // 3 fault, 2 saturation, startup, temperature invalid
  EXPECT_EQ(m->temperature_unknown, -32768);
  EXPECT_EQ(m->tie.size(), 4u);
}

TEST_F(BadMap, ADbcWithOverlappingSignalsIsRefusedNamingTheDbcLine) {
  std::string dbc = slurp(dir_.sub("rates16.dbc"));
  const std::string from = "SG_ RateY : 31|16@0-";
  const size_t at = dbc.find(from);
  ASSERT_NE(at, std::string::npos);
  dbc.replace(at, from.size(), "SG_ RateY : 23|16@0-");  // shares byte 2 with RateX
  std::ofstream(dir_.sub("rates16.dbc")) << dbc;
  std::ofstream(dir_.sub("ok.toml")) << text_;
  try {
    read_protocol_map(dir_.sub("ok.toml"));
    ADD_FAILURE() << "an overlapping DBC was accepted";
  } catch (const std::invalid_argument& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("rates16.dbc:" + std::to_string(line_of(dbc, "SG_ RateY")) + ": "),
              std::string::npos)
        << msg;
    EXPECT_NE(msg.find("signal RateY overlaps signal RateX"), std::string::npos) << msg;
  }
}

}  // namespace
}  // namespace imucal::drivers::imu
