// Register map as data: the shipped example equals the built-in default; bad maps are refused with
// the offending line (lines located here by searching the text, independently of the parser).
#include <gtest/gtest.h>

#include <fstream>
#include <sstream>

#include "drivers/turntable/register_map.hpp"

namespace imucal::drivers::turntable {
namespace {

const std::string kExamplePath = std::string(IMUCAL_SOURCE_DIR) + "/drivers/turntable/register_map.example.toml";

std::string example_text() {
  std::ifstream in(kExamplePath);
  EXPECT_TRUE(in.good()) << kExamplePath;
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

/// 1-based line number of the first line starting with `prefix`.
int line_starting_with(const std::string& text, const std::string& prefix) {
  std::istringstream in(text);
  std::string line;
  for (int n = 1; std::getline(in, line); ++n)
    if (line.rfind(prefix, 0) == 0) return n;
  ADD_FAILURE() << "no line starts with " << prefix;
  return -1;
}

/// Replaces the first line starting with `prefix` by `replacement` (which may be empty = delete).
std::string replace_line(const std::string& text, const std::string& prefix, const std::string& replacement) {
  std::istringstream in(text);
  std::string line, out;
  bool done = false;
  while (std::getline(in, line)) {
    if (!done && line.rfind(prefix, 0) == 0) {
      done = true;
      if (!replacement.empty()) out += replacement + "\n";
      continue;
    }
    out += line + "\n";
  }
  EXPECT_TRUE(done) << prefix;
  return out;
}

void expect_error(const std::string& text, int line, const std::string& fragment) {
  try {
    parse_register_map(text, "map.toml");
    ADD_FAILURE() << "accepted a bad map; expected error containing '" << fragment << "'";
  } catch (const RegisterMapError& e) {
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    EXPECT_EQ(std::string(e.what()).rfind("map.toml:" + std::to_string(line) + ":", 0), 0u) << e.what();
  }
}

TEST(RegisterMap, ExampleFileEqualsDefault) {
  const RegisterMap loaded = load_register_map(kExamplePath);
  EXPECT_TRUE(loaded == default_register_map()) << describe(loaded) << "\nvs\n" << describe(default_register_map());
}

TEST(RegisterMap, DefaultMatchesTheDocumentedLayout) {
  // ARCHITECTURE §4: targets and rate are float32 high word first; the handshake pair is adjacent.
  const RegisterMap m = default_register_map();
  EXPECT_EQ(m.word_order, WordOrder::kABCD);
  EXPECT_EQ(m.holding.command_seq, m.holding.command + 1);
  EXPECT_EQ(m.holding_extent(), 8);
  EXPECT_EQ(m.input_extent(), 13);
  EXPECT_EQ(m.input_first(), 0);
}

TEST(RegisterMap, ReadsANonDefaultMap) {
  std::string t = example_text();
  t = replace_line(t, "word_order", "word_order = \"CDAB\"");
  t = replace_line(t, "unit_id", "unit_id = 17");
  t = replace_line(t, "command = 6", "command = 20");
  t = replace_line(t, "command_seq = 7", "command_seq = 21");
  t = replace_line(t, "heartbeat = 10", "heartbeat = 100");
  t = replace_line(t, "estop = 5", "estop = 15");
  t = replace_line(t, "clear_fault = 5", "clear_fault = 0x55");
  const RegisterMap m = parse_register_map(t, "custom.toml");
  EXPECT_EQ(m.word_order, WordOrder::kCDAB);
  EXPECT_EQ(m.unit_id, 17);
  EXPECT_EQ(m.holding.command, 20);
  EXPECT_EQ(m.holding.command_seq, 21);
  EXPECT_EQ(m.input.heartbeat, 100);
  EXPECT_EQ(m.input_extent(), 101);
  EXPECT_EQ(m.status_bits.estop, 15);
  EXPECT_EQ(m.commands.clear_fault, 0x55);
  EXPECT_TRUE(m != default_register_map());
}

TEST(RegisterMap, UnknownKeyNamesItsLine) {
  std::string t = replace_line(example_text(), "max_rate_dps = 4", "max_rate_dps = 4\nmax_accel_dps2 = 20");
  expect_error(t, line_starting_with(t, "max_accel_dps2"), "unknown key 'max_accel_dps2'");
  t = replace_line(example_text(), "unit_id", "unit_id = 1\nbaud = 9600");
  expect_error(t, line_starting_with(t, "baud"), "unknown key 'baud'");
}

TEST(RegisterMap, OverlappingRegistersAreRefused) {
  // target_inner_deg at 1 overlaps the float32 target_outer_deg at [0, 1].
  std::string t = replace_line(example_text(), "target_inner_deg = 2", "target_inner_deg = 1");
  expect_error(t, line_starting_with(t, "target_inner_deg"), "overlaps 'target_outer_deg'");
  // status on the second register of rate_inner_dps [6, 7].
  t = replace_line(example_text(), "status = 8", "status = 7");
  expect_error(t, line_starting_with(t, "status = 7"), "overlaps 'rate_inner_dps'");
  // The same address in different register spaces is fine (holding 0 and input 0 both exist).
  EXPECT_NO_THROW(parse_register_map(example_text(), "ok.toml"));
}

TEST(RegisterMap, MissingCommandNamesTheTable) {
  std::string t = replace_line(example_text(), "move = 2", "");
  expect_error(t, line_starting_with(t, "[register_map.commands]"), "missing required key 'move'");
  t = replace_line(example_text(), "command_seq = 7", "");
  expect_error(t, line_starting_with(t, "[register_map.holding]"), "missing required key 'command_seq'");
}

TEST(RegisterMap, HandshakeBitsAndCodesAreChecked) {
  std::string t = replace_line(example_text(), "command_seq = 7", "command_seq = 9");
  expect_error(t, line_starting_with(t, "command_seq"), "must directly follow 'command'");
  t = replace_line(example_text(), "estop = 5", "estop = 2");
  expect_error(t, line_starting_with(t, "estop = 2"), "already used by 'moving'");
  t = replace_line(example_text(), "estop = 5", "estop = 16");
  expect_error(t, line_starting_with(t, "estop = 16"), "out of range");
  t = replace_line(example_text(), "home = 4", "home = 2");
  expect_error(t, line_starting_with(t, "home = 2"), "already used by 'move'");
  t = replace_line(example_text(), "enable = 1", "enable = 0");
  expect_error(t, line_starting_with(t, "enable = 0"), "out of range");
  t = replace_line(example_text(), "word_order", "word_order = \"little\"");
  expect_error(t, line_starting_with(t, "word_order"), "must be one of");
  t = replace_line(example_text(), "heartbeat = 10", "heartbeat = \"ten\"");
  expect_error(t, line_starting_with(t, "heartbeat"), "must be an integer");
  t = replace_line(example_text(), "ack_seq = 11", "ack_seq = 65536");
  expect_error(t, line_starting_with(t, "ack_seq"), "out of range");
  t = replace_line(example_text(), "actual_inner_deg = 2", "actual_inner_deg = 65535");  // float needs 2
  expect_error(t, line_starting_with(t, "actual_inner_deg"), "out of range");
  t = replace_line(example_text(), "ack_seq = 11", "ack_seq = 65535");  // last address is valid
  EXPECT_EQ(parse_register_map(t, "edge.toml").input_extent(), 65536);
}

TEST(RegisterMap, SyntaxErrorsAndMissingTable) {
  std::string t = replace_line(example_text(), "homed = 1", "homed = = 1");
  expect_error(t, line_starting_with(t, "homed"), "TOML syntax error");
  expect_error("[other]\nx = 1\n", 1, "missing required table [register_map]");
  EXPECT_THROW(load_register_map("/nonexistent/map.toml"), RegisterMapError);
}

}  // namespace
}  // namespace imucal::drivers::turntable
