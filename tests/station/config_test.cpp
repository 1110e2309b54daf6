// stationd configuration: the shipped example parses to the values it documents; every class of
// error names FILE:LINE:COL and the key; relative paths resolve against the config's directory.
#include "station/config/config.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <regex>
#include <sstream>

#include "calib/core/conventions.hpp"
#include "calib/core/rotation.hpp"
#include "drivers/turntable/register_map.hpp"

namespace imucal::station {
using namespace imucal::station::config;
namespace {

namespace fs = std::filesystem;

const std::string kExample =
    std::string(IMUCAL_SOURCE_DIR) + "/station/config/stationd.example.toml";

std::string read_file(const std::string& path) {
  std::ifstream in(path);
  std::ostringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// A minimal valid config; line numbers below refer to this text (1-based).
const char* const kMinimal =
    "[station]\n"                          // 1
    "name = \"st\"\n"                      // 2
    "lat_deg = 10.0\n"                     // 3
    "lon_deg = 20\n"                       // 4
    "height_m = 5.0\n"                     // 5
    "data_dir = \"d\"\n"                   // 6
    "[turntable]\n"                        // 7
    "endpoint = \"tcp:127.0.0.1:1502\"\n"  // 8
    "[imu]\n"                              // 9
    "can = \"unixcan:bus.sock\"\n";        // 10

ConfigError error_of(const std::string& text) {
  try {
    parse_config(text, "cfg.toml", "/etc/imucal");
  } catch (const ConfigError& e) {
    return e;
  }
  ADD_FAILURE() << "no ConfigError for:\n" << text;
  return ConfigError("", 0, 0, "");
}

/// Replaces line `n` (1-based) of `text` by `replacement` (may contain several lines).
std::string with_line(std::string text, int n, const std::string& replacement) {
  std::istringstream in(text);
  std::ostringstream out;
  std::string line;
  for (int i = 1; std::getline(in, line); ++i) out << (i == n ? replacement : line) << '\n';
  return out.str();
}

TEST(StationConfig, ExampleParsesToTheDocumentedValues) {
  const StationConfig c = load_config(kExample);
  const std::string dir =
      fs::absolute(fs::path(kExample).parent_path()).lexically_normal().string();
  EXPECT_EQ(c.station_name, "sim-station");
  EXPECT_NEAR(c.site.lat_rad, 55.7856 * kDegToRad, 1e-12);
  EXPECT_NEAR(c.site.lon_rad, 12.5213 * kDegToRad, 1e-12);
  EXPECT_DOUBLE_EQ(c.site.height_m, 30.0);
  EXPECT_FALSE(c.site.gravity_mps2.has_value());  // commented out in the example
  EXPECT_EQ(c.data_dir, dir + "/data");
  EXPECT_EQ(c.database, dir + "/data/history.sqlite");
  EXPECT_EQ(c.control_socket, dir + "/stationd.sock");
  EXPECT_EQ(c.control_group, "");
  EXPECT_EQ(c.control_socket_mode, 0660u);
  EXPECT_EQ(c.control_idle_timeout_s, 60.0);
  EXPECT_EQ(c.control_max_connections_per_user, 16u);
  EXPECT_EQ(c.turntable.endpoint.kind, drivers::turntable::Endpoint::Kind::kTcp);
  EXPECT_EQ(c.turntable.endpoint.host, "127.0.0.1");
  EXPECT_EQ(c.turntable.endpoint.port, 1502);
  EXPECT_EQ(c.turntable.response_timeout.count(), 250);
  EXPECT_EQ(c.turntable.ack_timeout.count(), 1000);
  EXPECT_EQ(c.turntable.poll_period.count(), 20);
  EXPECT_EQ(c.turntable.heartbeat_timeout.count(), 1000);
  EXPECT_EQ(c.turntable.reconnect_give_up.count(), 10000);
  EXPECT_DOUBLE_EQ(c.move_timeout_s, 120.0);
  EXPECT_DOUBLE_EQ(c.home_timeout_s, 120.0);
  EXPECT_DOUBLE_EQ(c.turntable.position_tolerance_deg, 0.01);
  EXPECT_DOUBLE_EQ(c.max_rate_dps, 20.0);
  EXPECT_TRUE(c.turntable.map == drivers::turntable::default_register_map());
  EXPECT_EQ(c.imu().can_uri, "unixcan:" + dir + "/imu.can");
  EXPECT_DOUBLE_EQ(c.imu().rate_hz, 100.0);
  EXPECT_FALSE(c.imu().base_id);  // the protocol's own ids: the built-in protocol's 0x100-0x103
  ASSERT_TRUE(c.imu().protocol);
  EXPECT_EQ(c.imu().protocol->name, "imucal-imu-1");
  EXPECT_EQ(c.imu().protocol->message(c.imu().protocol->messages.front()).id, 0x100u);
  EXPECT_TRUE(c.imu().protocol_path.empty());
  EXPECT_EQ(c.imu().max_gap_samples, 10u);
  EXPECT_EQ(c.imu().settle_guard_samples, 50u);
  EXPECT_DOUBLE_EQ(c.imu().rest_rate_threshold_dps, 0.05);
  EXPECT_EQ(c.imu().stream_timeout_ms, 2000);
  EXPECT_EQ(c.default_sequence, "short");
  EXPECT_DOUBLE_EQ(c.k_sigma, 4.0);
  EXPECT_DOUBLE_EQ(c.gap_false_alarm, 1e-4);
  EXPECT_EQ(c.log_level, "info");
  // Unit conversions: 0.0015 deg/√h = 0.0015·π/180 rad / 60 √s; 10 µg/√Hz = 10e-6·g0 m/s/√s.
  EXPECT_NEAR(c.imu().arw_rad_per_sqrt_s(), 0.0015 * M_PI / 180.0 / 60.0, 1e-15);
  EXPECT_NEAR(c.imu().vrw_mps_per_sqrt_s(), 10e-6 * 9.80665, 1e-12);
}

TEST(StationConfig, ExampleWithItsRegisterMapUncommentedIsTheDefaultMap) {
  // The commented [turntable.registers] block of the example is meant to be uncommented as is.
  std::string text = read_file(kExample);
  std::istringstream in(text);
  std::ostringstream out;
  std::string line;
  bool in_block = false;
  while (std::getline(in, line)) {
    if (line.rfind("# [turntable.registers]", 0) == 0) in_block = true;
    if (in_block && line.rfind("[imu]", 0) == 0) in_block = false;
    if (in_block && line.rfind("# ", 0) == 0) line = line.substr(2);
    out << line << '\n';
  }
  const StationConfig c = parse_config(out.str(), "example-uncommented", "/tmp");
  EXPECT_TRUE(c.turntable.map == drivers::turntable::default_register_map());
}

TEST(StationConfig, MinimalConfigGetsTheDefaultsAndResolvesRelativePaths) {
  const StationConfig c = parse_config(kMinimal, "cfg.toml", "/etc/imucal");
  EXPECT_EQ(c.data_dir, "/etc/imucal/d");
  EXPECT_EQ(c.database, "/etc/imucal/d/history.sqlite");
  EXPECT_EQ(c.imu().can_uri, "unixcan:/etc/imucal/bus.sock");
  EXPECT_EQ(c.control_socket, "/run/imucal/stationd.sock");
  EXPECT_EQ(c.default_sequence, "factory-std");
  EXPECT_NEAR(c.site.lon_rad, 20.0 * kDegToRad, 1e-15);  // an integer is a number too
  // Absolute paths stay as they are; socketcan names an interface, not a path.
  const StationConfig d = parse_config(
      with_line(with_line(kMinimal, 6, "data_dir = \"/srv/x\""), 10, "can = \"socketcan:can0\""),
      "cfg.toml", "/etc/imucal");
  EXPECT_EQ(d.data_dir, "/srv/x");
  EXPECT_EQ(d.imu().can_uri, "socketcan:can0");
}

// The rest threshold follows the unit's noise unless given: a tactical unit's rate noise (0.2 °/√h
// at 100 Hz: 0.033 °/s a sample) would never look still under the navigation grade's 0.05 °/s.
TEST(StationConfig, TheRestThresholdFollowsTheNoiseUnlessGiven) {
  EXPECT_DOUBLE_EQ(parse_config(kMinimal, "cfg.toml", "/etc/imucal").imu().rest_rate_threshold_dps,
                   0.05);
  const std::string tactical = std::string(kMinimal) + "arw_deg_per_sqrt_h = 0.2\n";
  EXPECT_NEAR(parse_config(tactical, "cfg.toml", "/e").imu().rest_rate_threshold_dps,
              8 * 0.2 / 60 * 10, 1e-12);
  EXPECT_DOUBLE_EQ(parse_config(tactical + "rest_rate_threshold_dps = 0.3\n", "cfg.toml", "/e")
                       .imu()
                       .rest_rate_threshold_dps,
                   0.3);
}

// A protocol file in [imu] is read at load time; base_id moves its identifiers.
TEST(StationConfig, TheProtocolIsReadAtLoadTimeAndBaseIdMovesItsIds) {
  const std::string rates16 = std::string(IMUCAL_SOURCE_DIR) + "/tests/data/protocols/rates16.toml";
  const std::string with = std::string(kMinimal) + "protocol = \"" + rates16 + "\"\n";
  const StationConfig c = parse_config(with, "cfg.toml", "/e");
  ASSERT_TRUE(c.imu().protocol);
  EXPECT_EQ(c.imu().protocol->name, "rates16");
  EXPECT_EQ(c.imu().protocol_path, rates16);
  EXPECT_EQ(c.imu().protocol->message(c.imu().protocol->messages.front()).id, 0x18FF1000u);
  const StationConfig moved = parse_config(with + "base_id = 0x18FF2000\n", "cfg.toml", "/e");
  EXPECT_EQ(moved.imu().protocol->message(moved.imu().protocol->messages.back()).id, 0x18FF2200u);
  EXPECT_EQ(decoder_options(moved.imu()).protocol, moved.imu().protocol);
  // The built-in protocol's four 11-bit ids do not fit above 0x7FC.
  const ConfigError e = error_of(std::string(kMinimal) + "base_id = 0x7FE\n");
  EXPECT_EQ(e.line(), 11) << e.what();
  EXPECT_NE(std::string(e.what()).find("beyond the 11-bit range"), std::string::npos) << e.what();
}

void expect_error(const std::string& text, int line, int column, const std::string& must_contain) {
  const ConfigError e = error_of(text);
  EXPECT_EQ(e.file(), "cfg.toml");
  EXPECT_EQ(e.line(), line) << e.what();
  if (column > 0) {
    EXPECT_EQ(e.column(), column) << e.what();
  }
  EXPECT_NE(std::string(e.what()).find(must_contain), std::string::npos) << e.what();
  const std::string prefix =
      "cfg.toml:" + std::to_string(e.line()) + ":" + std::to_string(e.column()) + ": ";
  EXPECT_EQ(std::string(e.what()).rfind(prefix, 0), 0u) << e.what();
}

TEST(StationConfig, FleetIsOptionalAndItsBadValuesNameTheirKey) {
  const StationConfig none = parse_config(kMinimal, "cfg.toml", "/etc/imucal");
  EXPECT_FALSE(none.fleet.has_value());
  const StationConfig with = parse_config(
      std::string(kMinimal) +
          "[fleet]\nurl = \"postgresql://st@fleet:5432/db\"\npassword_file = \"fleet.pw\"\n",
      "cfg.toml", "/etc/imucal");
  ASSERT_TRUE(with.fleet.has_value());
  EXPECT_EQ(with.fleet->station_id, "st") << "the station name by default";
  EXPECT_EQ(with.fleet->password_file, "/etc/imucal/fleet.pw");
  EXPECT_EQ(with.fleet->batch_entries, 200u);
  const std::string f = std::string(kMinimal) + "[fleet]\n";  // [fleet] is line 11
  expect_error(f + "station_id = \"x\"\n", 11, 0, "url");
  expect_error(f + "url = \"postgresql://u@h:70000/db\"\n", 12, 1, "[fleet] url");
  expect_error(f + "url = \"postgresql:///db\"\n", 12, 1, "names no host");
  expect_error(f + "url = \"postgresql://u@h/db\"\nstation_id = \"a;b\"\n", 13, 1, "station_id");
  expect_error(f + "url = \"postgresql://u@h/db\"\npassword_file = \"p\"\npassword_env = \"E\"\n",
               14, 1, "not both");
  expect_error(f + "url = \"postgresql://u:Pw0rdX@h:x/db\"\n", 12, 1, "port");
  EXPECT_EQ(std::string(error_of(f + "url = \"postgresql://u:Pw0rdX@h:x/db\"\n").what()).find("Pw0rdX"),
            std::string::npos)
      << "the password is never shown";
}

TEST(StationConfig, UnknownKeyNamesFileLineColumnAndKey) {
  expect_error(with_line(kMinimal, 5, "height_m = 5.0\n  heigth = 3"), 6, 3,
               "unknown key 'heigth'");
  expect_error(std::string(kMinimal) + "[imus]\nx = 1\n", 11, 2, "unknown key or table 'imus'");
}

TEST(StationConfig, WrongTypeNamesTheKey) {
  expect_error(with_line(kMinimal, 3, "lat_deg = \"55\""), 3, 1,
               "[station] lat_deg: must be a number, not string");
  expect_error(std::string(kMinimal) + "rate_hz = true\n", 11, 1,
               "[imu] rate_hz: must be a number, not boolean");
  expect_error(std::string(kMinimal) + "stream_timeout_ms = 2.5\n", 11, 1,
               "[imu] stream_timeout_ms: must be an integer, not float");
  expect_error("log = 3\n" + std::string(kMinimal), 1, 1,
               "'log' must be a table ([log]), not integer");
}

TEST(StationConfig, OutOfRangeNamesTheKeyAndTheRange) {
  expect_error(with_line(kMinimal, 3, "lat_deg = 91.0"), 3, 1,
               "[station] lat_deg: 91 is out of range [-90, 90] deg");
  expect_error(std::string(kMinimal) + "rate_hz = 0\n", 11, 1, "[imu] rate_hz: 0 is out of range");
  expect_error(std::string(kMinimal) + "[control]\nsocket_mode = 0o1777\n", 12, 1,
               "[control] socket_mode: 1023 is out of range [0, 511]");
  expect_error(std::string(kMinimal) + "[log]\nlevel = \"loud\"\n", 12, 1,
               "[log] level: \"loud\" is not a log level");
  expect_error(with_line(kMinimal, 8, "endpoint = \"udp:1.2.3.4:5\""), 8, 1,
               "[turntable] endpoint:");
  expect_error(with_line(kMinimal, 10, "can = \"vcan0\""), 10, 1,
               "[imu] can: \"vcan0\" is not a CAN URI");
}

// Issue #28: the gap check's false-alarm rate per run is a setting, a probability well below 1.
TEST(StationConfig, GapFalseAlarmIsAProbabilityPerRun) {
  EXPECT_DOUBLE_EQ(parse_config(kMinimal, "cfg.toml", "/etc").gap_false_alarm, 1e-4);
  const StationConfig c = parse_config(
      std::string(kMinimal) + "[calibration]\ngap_false_alarm = 1e-3\n", "cfg.toml", "/etc");
  EXPECT_DOUBLE_EQ(c.gap_false_alarm, 1e-3);
  expect_error(std::string(kMinimal) + "[calibration]\ngap_false_alarm = 0.5\n", 12, 1,
               "[calibration] gap_false_alarm: 0.5 is out of range");
  expect_error(std::string(kMinimal) + "[calibration]\ngap_false_alarm = 0\n", 12, 1,
               "[calibration] gap_false_alarm: 0 is out of range");
}

// Issue #26: a product's known unmodelled effects, named from the catalogue and checked.
TEST(StationConfig, KnownEffectsAreCatalogueNames) {
  EXPECT_TRUE(parse_config(kMinimal, "cfg.toml", "/etc").known_effects.empty());
  const StationConfig c =
      parse_config(std::string(kMinimal) +
                       "[calibration]\nknown_effects = [\"gyro_accel_skew\", \"thermal_drift\"]\n",
                   "cfg.toml", "/etc");
  EXPECT_EQ(c.known_effects, (std::vector<std::string>{"gyro_accel_skew", "thermal_drift"}));
  expect_error(std::string(kMinimal) + "[calibration]\nknown_effects = [\"warp_drive\"]\n", 12, 1,
               "[calibration] known_effects: \"warp_drive\" is not an effect of the catalogue "
               "(accel_quadratic_k2");
  expect_error(std::string(kMinimal) + "[calibration]\nknown_effects = \"size_effect\"\n", 12, 1,
               "[calibration] known_effects: must be an array of strings, not string");
  expect_error(std::string(kMinimal) + "[calibration]\nknown_effects = [\"size_effect\", 3]\n", 12,
               1, "[calibration] known_effects: must hold strings only");
}

// Issue #21: the station names the product it calibrates; every run's run.toml carries it.
TEST(StationConfig, TheGradeOfTheProductIsNamedAndChecked) {
  EXPECT_EQ(parse_config(kMinimal, "cfg.toml", "/etc").imu().grade,
            calib::core::Grade::kNavigation);
  EXPECT_EQ(parse_config(read_file(kExample), kExample, "/etc").imu().grade,
            calib::core::Grade::kNavigation);
  const StationConfig c =
      parse_config(std::string(kMinimal) + "grade = \"mems\"\n", "cfg.toml", "/etc");
  EXPECT_EQ(c.imu().grade, calib::core::Grade::kMems);
  expect_error(std::string(kMinimal) + "grade = \"consumer\"\n", 11, 1,
               "[imu] grade: \"consumer\" is not a grade (navigation, tactical or mems)");
}

TEST(StationConfig, MissingRequiredKeyNamesTheKeyAndItsTable) {
  expect_error(with_line(kMinimal, 6, ""), 1, 1, "[station] missing required key 'data_dir'");
  expect_error(with_line(kMinimal, 8, ""), 7, 1, "[turntable] missing required key 'endpoint'");
  // A whole table missing: the key it lacks is named with the table.
  expect_error(with_line(with_line(kMinimal, 9, ""), 10, ""), 1, 1,
               "missing required key 'can' (table [imu] is missing)");
}

TEST(StationConfig, SyntaxErrorHasItsPosition) {
  expect_error(with_line(kMinimal, 4, "lon_deg = = 3"), 4, 0, "TOML syntax error");
}

TEST(StationConfig, RegisterMapErrorsPointAtTheKeyInTheConfig) {
  // A register map whose command_seq does not follow command: the map reader's check, reported at
  // the line of command_seq in THIS file.
  const std::string regs =
      "[turntable.registers]\n"          // 11
      "unit_id = 1\n"                    // 12
      "word_order = \"ABCD\"\n"          // 13
      "[turntable.registers.holding]\n"  // 14
      "target_outer_deg = 0\n"           // 15
      "target_inner_deg = 2\n"           // 16
      "max_rate_dps = 4\n"               // 17
      "command = 6\n"                    // 18
      "command_seq = 9\n"                // 19
      "[turntable.registers.input]\n"    // 20
      "actual_outer_deg = 0\nactual_inner_deg = 2\nrate_outer_dps = 4\nrate_inner_dps = 6\n"
      "status = 8\nfault_code = 9\nheartbeat = 10\nack_seq = 11\nack_result = 12\n"
      "[turntable.registers.status_bits]\nenabled = 0\nhomed = 1\nmoving = 2\nin_position = 3\n"
      "fault = 4\nestop = 5\n"
      "[turntable.registers.commands]\nenable = 1\nmove = 2\nstop = 3\nhome = 4\nclear_fault = 5\n";
  expect_error(std::string(kMinimal) + regs, 19, 1, "[turntable.registers]");
  // Fixed, the same map loads.
  const StationConfig c =
      parse_config(std::string(kMinimal) +
                       std::regex_replace(regs, std::regex("command_seq = 9"), "command_seq = 7"),
                   "cfg.toml", "/etc");
  EXPECT_TRUE(c.turntable.map == drivers::turntable::default_register_map());
}

TEST(StationConfig, UnreadableFileIsAnError) {
  try {
    load_config("/nonexistent/stationd.toml");
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/stationd.toml"), std::string::npos);
  }
}

}  // namespace

// The default sequence must exist where the daemon will look (an installed service sees no
// source tree): an unknown name names the key's line, the library and what it holds; a configured
// sequence_dir must be a directory and is where names are looked up.
TEST(StationConfig, DefaultSequenceAndSequenceDirAreChecked) {
  expect_error(std::string(kMinimal) + "[calibration]\ndefault_sequence = \"nope\"\n", 12, 1,
               "[calibration] default_sequence: \"nope\" is not a sequence of the library");
  const ConfigError e =
      error_of(std::string(kMinimal) + "[calibration]\ndefault_sequence = \"nope\"\n");
  EXPECT_NE(std::string(e.what()).find("factory-std, pos19, short"), std::string::npos) << e.what();
  expect_error(std::string(kMinimal) + "[calibration]\nsequence_dir = \"/no/such/dir\"\n", 12, 1,
               "[calibration] sequence_dir: \"/no/such/dir\" is not a directory");
  expect_error(std::string(kMinimal) + "[calibration]\ndefault_sequence = \"./no.toml\"\n", 12, 1,
               "no such file");

  const std::string dir =
      (std::filesystem::temp_directory_path() / ("imucal-seqdir-" + std::to_string(::getpid())))
          .string();
  std::filesystem::create_directories(dir);
  std::ofstream(dir + "/mine.toml") << "name = \"mine\"\n";
  // Relative to the config's directory, like every other path.
  const StationConfig ok = parse_config(std::string(kMinimal) + "[calibration]\nsequence_dir = \"" +
                                            dir + "\"\ndefault_sequence = \"mine\"\n",
                                        "cfg.toml", "/etc/imucal");
  EXPECT_EQ(ok.sequence_dir, dir);
  // The library's "factory-std" (the default) is not in the private library.
  const ConfigError missing =
      error_of(std::string(kMinimal) + "[calibration]\nsequence_dir = \"" + dir + "\"\n");
  EXPECT_NE(
      std::string(missing.what())
          .find("\"factory-std\" is not a sequence of the library " + dir + " (available: mine"),
      std::string::npos)
      << missing.what();
  std::filesystem::remove_all(dir);
}

}  // namespace imucal::station

namespace imucal::station {
using namespace imucal::station::config;
namespace {

/// kMinimal's first 8 lines (station and turntable) followed by `imus` (from line 9 on).
std::string with_imus(const std::string& imus) {
  std::istringstream in(kMinimal);
  std::string line, head;
  for (int i = 1; i <= 8 && std::getline(in, line); ++i) head += line + "\n";
  return head + imus;
}

// Issue #23: a fixture of up to four units, [[imu]] slots named in order, each its own mounting.
TEST(StationConfig, ImuSlotsAreReadInOrderWithTheirMountings) {
  const StationConfig c = parse_config(
      with_imus("[[imu]]\ncan = \"unixcan:a.sock\"\nlever_arm_m = [0.1, 0, 0.05]\n"
                "[[imu]]\ncan = \"unixcan:b.sock\"\nmount_rpy_deg = [0, 0, 90]\n"
                "[[imu]]\nslot = \"left-3\"\ncan = \"unixcan:a.sock\"\nbase_id = 0x200\n"
                "mount_matrix = [[0, 1, 0], [1, 0, 0], [0, 0, -1]]\n"),
      "cfg.toml", "/etc/imucal");
  ASSERT_EQ(c.imus.size(), 3u);
  EXPECT_EQ(c.imus[0].name, "A");
  EXPECT_EQ(c.imus[1].name, "B");
  EXPECT_EQ(c.imus[2].name, "left-3");
  EXPECT_EQ(c.imus[1].can_uri, "unixcan:/etc/imucal/b.sock");
  EXPECT_DOUBLE_EQ(c.imus[0].lever_arm_m[2], 0.05);
  EXPECT_DOUBLE_EQ(c.imus[1].mount_rpy_deg[2], 90.0);
  // The axis swap with z flipped is a rotation (x <-> y, z down): roll 180, yaw 90.
  const Eigen::Matrix3d C = calib::core::euler_to_C_bn(c.imus[2].mount_rpy_deg[0] * kDegToRad,
                                                       c.imus[2].mount_rpy_deg[1] * kDegToRad,
                                                       c.imus[2].mount_rpy_deg[2] * kDegToRad);
  Eigen::Matrix3d want;
  want << 0, 1, 0, 1, 0, 0, 0, 0, -1;
  EXPECT_LT((C - want).cwiseAbs().maxCoeff(), 1e-12) << C;
  EXPECT_EQ(&slot_named(c, "B"), &c.imus[1]);
  EXPECT_EQ(&slot_named(c, ""), &c.imus[0]);
}

// Bad fixtures stop the daemon before it starts, naming the slot's key.
TEST(StationConfig, BadSlotsAreRefusedNamingTheKey) {
  const std::string a = "[[imu]]\ncan = \"unixcan:a.sock\"\n";  // lines 9-10
  expect_error(with_imus(a + "[[imu]]\ncan = \"unixcan:a.sock\"\n"), 12, 1,
               "[imu] can: slot B reads the same bus and identifiers as slot A");
  expect_error(with_imus(a + "[[imu]]\nslot = \"A\"\ncan = \"unixcan:b.sock\"\n"), 12, 1,
               "[imu] slot: \"A\" is used twice");
  expect_error(with_imus(a + "[[imu]]\nslot = \"no space\"\ncan = \"unixcan:b.sock\"\n"), 12, 1,
               "is not a slot name");
  expect_error(with_imus(a + "mount_matrix = [[1, 0, 0], [0, 1, 0], [0, 0, -1]]\n"), 11, 1,
               "[imu] mount_matrix: is not a rotation: determinant -1");
  expect_error(with_imus(a + "mount_matrix = [[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]\n"), 11, 1,
               "[imu] mount_matrix: is not a rotation: its rows are not orthonormal");
  expect_error(with_imus(a + "mount_rpy_deg = [0, 95, 0]\n"), 11, 1,
               "[imu] mount_rpy_deg: pitch (second element) 95 deg is outside [-90, 90]");
  expect_error(with_imus(a + "lever_arm_m = [0, 3, 0]\n"), 11, 1,
               "[imu] lever_arm_m: 3 is out of range");
  std::string five;
  for (int i = 0; i < 5; ++i) five += "[[imu]]\ncan = \"unixcan:" + std::to_string(i) + ".sock\"\n";
  expect_error(with_imus(five), 9, 0, "[[imu]] must hold 1 to 4 units, not 5");
}

}  // namespace
}  // namespace imucal::station
