// Interop with a Modbus master nobody here wrote: Debian's `mbpoll` (package mbpoll) reads the
// simulated table's input registers (decoding the float32 angles itself, with -B = big-endian word
// order, our ABCD) and commands a move by writing the holding registers. Fails (does not skip) when
// mbpoll is missing: tools/setup.sh installs it.
#include <gtest/gtest.h>
#include <spdlog/spdlog.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <map>
#include <regex>
#include <string>

#include "drivers/simulated/modbus_table_server.hpp"

namespace imucal {
namespace {

using drivers::simulated::TablePlc;

const bool kQuietLogsTurntableMbpoll = [] {
  spdlog::set_level(spdlog::level::err);
  return true;
}();

struct ProcessResult {
  int exit_code;
  std::string output;
};

/// Runs a shell command (bounded by `timeout`), capturing stdout and stderr.
ProcessResult run_turntable_mbpoll(const std::string& command) {
  ProcessResult r{-1, ""};
  FILE* p = popen(("timeout 10 " + command + " 2>&1").c_str(), "r");
  if (!p) return r;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) r.output.append(buf, n);
  const int status = pclose(p);
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return r;
}

/// mbpoll prints one "[ADDRESS]: VALUE" line per value.
std::map<int, std::string> values(const std::string& output) {
  std::map<int, std::string> v;
  const std::regex line(R"(\[(\d+)\]:\s+(\S+))");
  for (auto it = std::sregex_iterator(output.begin(), output.end(), line); it != std::sregex_iterator(); ++it)
    v[std::stoi((*it)[1])] = (*it)[2];
  return v;
}

/// Commands the PLC register-level (as a master would) and steps it: no time passes unless we step.
void command(TablePlc& plc, uint16_t code, uint16_t seq) {
  const uint16_t regs[2] = {code, seq};
  plc.write_holding(plc.config().map.holding.command, regs, 2);
  plc.step(0.0);
}

class MbpollInterop : public ::testing::Test {
 protected:
  void SetUp() override {
    ASSERT_EQ(access("/usr/bin/mbpoll", X_OK), 0)
        << "mbpoll is not installed (apt-get install -y mbpoll; tools/setup.sh should install it)";
    // No time source: the PLC only moves when the test steps it, so values are stable while mbpoll reads.
    server_.start();
    server_.with_plc([](TablePlc& plc) {
      const auto& m = plc.config().map;
      command(plc, m.commands.enable, 1);
      command(plc, m.commands.home, 2);
      plc.step(5.0);
      auto put = [&](uint16_t address, float v) {
        const auto r = drivers::turntable::encode_float(v, m.word_order);
        plc.write_holding(address, r.data(), 2);
      };
      put(m.holding.target_outer_deg, 12.5f);
      put(m.holding.target_inner_deg, -33.25f);
      put(m.holding.max_rate_dps, 20.0f);
      command(plc, m.commands.move, 3);
      plc.step(10.0);
    });
    ASSERT_TRUE(server_.with_plc([](TablePlc& p) { return p.in_position(); }));
  }
  std::string mbpoll(const std::string& args) {
    return "mbpoll -m tcp -a 1 -0 -o 2 -p " + std::to_string(server_.port()) + " " + args;
  }
  drivers::simulated::ModbusTableServer server_{drivers::simulated::TablePlcConfig{},
                                                drivers::simulated::ModbusTableServerConfig{}};
};

TEST_F(MbpollInterop, ReadsTheAnglesAndStatus) {
  const ProcessResult floats = run_turntable_mbpoll(mbpoll("-1 -t 3:float -B -r 0 -c 2 127.0.0.1"));
  ASSERT_EQ(floats.exit_code, 0) << floats.output;
  auto v = values(floats.output);
  ASSERT_TRUE(v.count(0) && v.count(2)) << floats.output;
  EXPECT_DOUBLE_EQ(std::stod(v[0]), 12.5) << floats.output;
  EXPECT_DOUBLE_EQ(std::stod(v[2]), -33.25) << floats.output;

  const auto& m = drivers::turntable::default_register_map();
  const ProcessResult words = run_turntable_mbpoll(mbpoll("-1 -t 3 -r 8 -c 5 127.0.0.1"));
  ASSERT_EQ(words.exit_code, 0) << words.output;
  v = values(words.output);
  ASSERT_TRUE(v.count(m.input.status) && v.count(m.input.ack_seq)) << words.output;
  const int status = std::stoi(v[m.input.status]);
  EXPECT_TRUE(status & (1 << m.status_bits.enabled)) << words.output;
  EXPECT_TRUE(status & (1 << m.status_bits.homed)) << words.output;
  EXPECT_TRUE(status & (1 << m.status_bits.in_position)) << words.output;
  EXPECT_FALSE(status & (1 << m.status_bits.moving)) << words.output;
  EXPECT_EQ(std::stoi(v[m.input.ack_seq]), 3) << words.output;
  EXPECT_EQ(std::stoi(v[m.input.heartbeat]), server_.with_plc([](TablePlc& p) { return int(p.heartbeat()); }));
}

TEST_F(MbpollInterop, CommandsAMove) {
  const auto& m = drivers::turntable::default_register_map();
  // Targets and rate as three big-endian floats at holding 0, 2, 4; then command word + sequence.
  const ProcessResult targets = run_turntable_mbpoll(mbpoll("-t 4:float -B -r 0 127.0.0.1 -- 45 -20 15"));
  ASSERT_EQ(targets.exit_code, 0) << targets.output;
  const ProcessResult cmd = run_turntable_mbpoll(mbpoll("-t 4 -r " + std::to_string(m.holding.command) + " 127.0.0.1 " +
                             std::to_string(m.commands.move) + " 77"));
  ASSERT_EQ(cmd.exit_code, 0) << cmd.output;

  server_.with_plc([&](TablePlc& plc) {
    // The targets mbpoll wrote decode with our codec.
    uint16_t h[6];
    plc.read_holding(0, 6, h);
    EXPECT_EQ(drivers::turntable::decode_float(&h[0], m.word_order), 45.0f);
    EXPECT_EQ(drivers::turntable::decode_float(&h[2], m.word_order), -20.0f);
    EXPECT_EQ(drivers::turntable::decode_float(&h[4], m.word_order), 15.0f);
    const double outer0 = plc.outer_deg();
    plc.step(0.5);
    EXPECT_EQ(plc.ack_seq(), 77);
    EXPECT_EQ(plc.ack_result(), drivers::simulated::AckResult::kAccepted);
    EXPECT_TRUE(plc.moving());
    EXPECT_GT(plc.outer_deg(), outer0);   // 12.5 -> 45: increasing
    EXPECT_GT(plc.inner_deg(), -33.25);  // -33.25 -> -20: increasing
    plc.step(10.0);
    EXPECT_TRUE(plc.in_position());
    EXPECT_EQ(plc.outer_deg(), 45.0);
    EXPECT_EQ(plc.inner_deg(), -20.0);
  });
  // And mbpoll reads the new angles back.
  const ProcessResult floats = run_turntable_mbpoll(mbpoll("-1 -t 3:float -B -r 0 -c 2 127.0.0.1"));
  auto v = values(floats.output);
  ASSERT_TRUE(v.count(0) && v.count(2)) << floats.output;
  EXPECT_DOUBLE_EQ(std::stod(v[0]), 45.0);
  EXPECT_DOUBLE_EQ(std::stod(v[2]), -20.0);
}

}  // namespace
}  // namespace imucal
