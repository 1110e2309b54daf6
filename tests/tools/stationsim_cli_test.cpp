// The real stationsim binary: its ready file, Modbus interop with Debian's mbpoll (a master nobody
// here wrote) reading the input registers and commanding a move through the register map's
// command/sequence handshake, clean exit on SIGTERM with the statistics file, truth.json, and
// refusal of bad flags and unit files (exit 2, message naming them). mbpoll missing = failure
// (tools/setup.sh installs it), not a skip.
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include "calib/sim/truth_sim.hpp"
#include "db/archive/unit_file.hpp"
#include "drivers/turntable/register_map.hpp"

extern char** environ;

using namespace std::chrono_literals;

namespace {

const std::string kBinary = std::string(IMUCAL_BIN_DIR) + "/stationsim";

std::string read_file(const std::string& path) {
  std::ifstream f(path);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// A fresh directory per test and a loopback address of this process alone (see
/// turntable_client_test.cpp: a freed port must never lead to another process's table).
struct Scratch {
  Scratch() {
    char tmpl[] = "/tmp/stationsim_cli_XXXXXX";
    dir = ::mkdtemp(tmpl);
    static int n = 0;
    const unsigned pid = static_cast<unsigned>(::getpid());
    address = "127." + std::to_string((pid >> 8) & 0xffu) + "." + std::to_string(pid & 0xffu) + "." +
              std::to_string(++n % 254 + 1);
  }
  ~Scratch() { std::system(("rm -rf '" + dir + "'").c_str()); }
  std::string path(const std::string& name) const { return dir + "/" + name; }
  std::string dir, address;
};

/// A child process (stationsim by default), stdout/stderr into files of the scratch directory.
class Child {
 public:
  Child(const Scratch& s, std::vector<std::string> args, const std::string& program = kBinary,
        const std::string& tag = "stationsim")
      : out_(s.path(tag + ".out")), err_(s.path(tag + ".err")) {
    args.insert(args.begin(), program);
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    argv.push_back(nullptr);
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_addopen(&fa, 1, out_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&fa, 2, err_.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
    const int rc = posix_spawn(&pid_, program.c_str(), &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    if (rc != 0) pid_ = -1;
  }
  ~Child() {
    if (pid_ > 0 && !exited_) {
      ::kill(pid_, SIGKILL);
      ::waitpid(pid_, nullptr, 0);
    }
  }
  pid_t pid() const { return pid_; }
  /// Exit code, or -1 if it did not exit within the timeout (or died by a signal).
  int wait(std::chrono::milliseconds timeout) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (std::chrono::steady_clock::now() < end) {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        exited_ = true;
        return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
      }
      std::this_thread::sleep_for(5ms);
    }
    return -1;
  }
  std::string out() const { return read_file(out_); }
  std::string err() const { return read_file(err_); }

 private:
  std::string out_, err_;
  pid_t pid_ = -1;
  bool exited_ = false;
};

/// Waits for the ready file (written atomically: complete JSON or absent) and parses it.
nlohmann::json wait_ready(const std::string& path, Child& child) {
  const auto end = std::chrono::steady_clock::now() + 10s;
  while (std::chrono::steady_clock::now() < end) {
    if (::access(path.c_str(), F_OK) == 0) return nlohmann::json::parse(read_file(path));
    std::this_thread::sleep_for(5ms);
  }
  ADD_FAILURE() << "no ready file; stderr: " << child.err();
  return nlohmann::json();
}

/// One mbpoll run to completion: exit code and everything it printed.
std::pair<int, std::string> run_mbpoll(const Scratch& s, const std::vector<std::string>& args) {
  Child tool(s, args, "/usr/bin/mbpoll", "mbpoll");
  const int rc = tool.wait(10000ms);
  return {rc, tool.out() + tool.err()};
}

/// mbpoll's "[ADDRESS]: VALUE" result lines as address -> value text.
std::map<int, std::string> register_values(const std::string& output) {
  std::map<int, std::string> v;
  std::istringstream lines(output);
  std::string line;
  while (std::getline(lines, line)) {
    int address = 0;
    char value[64] = {};
    if (std::sscanf(line.c_str(), "[%d]: %63s", &address, value) == 2) v[address] = value;
  }
  return v;
}

}  // namespace

TEST(StationsimCli, MbpollReadsTheTableAndCommandsAMoveOverTheHandshake) {
  ASSERT_EQ(::access("/usr/bin/mbpoll", X_OK), 0)
      << "mbpoll is not installed (apt-get install -y mbpoll; tools/setup.sh installs it)";
  Scratch s;
  Child sim(s, {"--modbus", s.address + ":0", "--can", s.path("bus.sock"), "--speed", "20", "--ready-file",
                s.path("ready.json"), "--stats-file", s.path("stats.json")});
  ASSERT_GT(sim.pid(), 0);
  const nlohmann::json ready = wait_ready(s.path("ready.json"), sim);
  ASSERT_TRUE(ready.is_object());
  EXPECT_EQ(ready["pid"].get<int>(), sim.pid());
  EXPECT_EQ(ready["can"].get<std::string>(), "unixcan:" + s.path("bus.sock"));
  EXPECT_DOUBLE_EQ(ready["speed"].get<double>(), 20.0);
  const std::string modbus = ready["modbus"].get<std::string>();
  const std::smatch m = [&] {
    std::smatch r;
    std::regex_match(modbus, r, std::regex(R"(tcp:([0-9.]+):(\d+))"));
    return r;
  }();
  ASSERT_EQ(m.size(), 3u) << modbus;
  EXPECT_EQ(m[1].str(), s.address);
  const std::string port = m[2].str();
  // The same JSON is the first line on stdout.
  const std::string out = sim.out();
  EXPECT_EQ(nlohmann::json::parse(out.substr(0, out.find('\n'))), ready) << out;

  const auto& map = imucal::drivers::turntable::default_register_map();
  // mbpoll OPTIONS HOST [VALUES...]: values to write follow the host.
  auto mbpoll = [&](const std::string& options, const std::string& write_values = "") {
    std::vector<std::string> args = {"-m", "tcp", "-a", "1", "-0", "-o", "2", "-p", port};
    std::istringstream o(options + " " + s.address + " " + write_values);
    for (std::string w; o >> w;) args.push_back(w);
    return run_mbpoll(s, args);
  };
  auto write_command = [&](uint16_t code, int seq) {
    // Command word and sequence number in ONE write (the handshake of register_map.hpp).
    const auto r = mbpoll("-t 4 -r " + std::to_string(map.holding.command),
                          std::to_string(code) + " " + std::to_string(seq));
    ASSERT_EQ(r.first, 0) << r.second;
  };
  auto input_words = [&] {
    const auto r = mbpoll("-1 -t 3 -r " + std::to_string(map.input.status) + " -c 5");
    EXPECT_EQ(r.first, 0) << r.second;
    return register_values(r.second);
  };
  auto angles = [&] {
    const auto r = mbpoll("-1 -t 3:float -B -r " + std::to_string(map.input.actual_outer_deg) + " -c 2");
    EXPECT_EQ(r.first, 0) << r.second;
    auto v = register_values(r.second);
    return std::make_pair(std::stod(v.at(map.input.actual_outer_deg)), std::stod(v.at(map.input.actual_inner_deg)));
  };
  /// Polls until the table acknowledged `seq` and `bit` is set (bounded).
  auto wait_for = [&](int seq, uint8_t bit) {
    const auto end = std::chrono::steady_clock::now() + 8s;
    std::map<int, std::string> v;
    while (std::chrono::steady_clock::now() < end) {
      v = input_words();
      if (v.count(map.input.ack_seq) && std::stoi(v[map.input.ack_seq]) == seq &&
          (std::stoi(v[map.input.status]) >> bit & 1)) {
        EXPECT_EQ(std::stoi(v[map.input.ack_result]), 0) << "command " << seq << " rejected";
        return true;
      }
      std::this_thread::sleep_for(10ms);
    }
    return false;
  };

  write_command(map.commands.enable, 1);
  ASSERT_TRUE(wait_for(1, map.status_bits.enabled));
  write_command(map.commands.home, 2);
  ASSERT_TRUE(wait_for(2, map.status_bits.in_position));
  const auto home = angles();
  EXPECT_DOUBLE_EQ(home.first, 0.0);
  EXPECT_DOUBLE_EQ(home.second, 0.0);
  // Targets and rate: three big-endian floats at holding 0, 2, 4, then the move command.
  const auto t = mbpoll("-t 4:float -B -r " + std::to_string(map.holding.target_outer_deg), "-- 45 -20 15");
  ASSERT_EQ(t.first, 0) << t.second;
  write_command(map.commands.move, 3);
  ASSERT_TRUE(wait_for(3, map.status_bits.in_position));
  const auto end = angles();
  EXPECT_DOUBLE_EQ(end.first, 45.0);
  EXPECT_DOUBLE_EQ(end.second, -20.0);

  // SIGTERM: clean exit 0 and the final statistics.
  ASSERT_EQ(::kill(sim.pid(), SIGTERM), 0);
  ASSERT_EQ(sim.wait(5000ms), 0) << sim.err();
  const nlohmann::json st = nlohmann::json::parse(read_file(s.path("stats.json")));
  const double t_sim = st["sim_time_s"].get<double>();
  // The move took (45 - 0) / 15 + 15 / 20 s at least (trapezoid at the accel limit) plus settling.
  EXPECT_GT(t_sim, 45.0 / 15.0 + 15.0 / 20.0);
  EXPECT_EQ(st["samples_sent"].get<uint64_t>(), static_cast<uint64_t>(std::llround(t_sim * 100.0)));
  EXPECT_EQ(st["frames_sent"].get<uint64_t>(), 4 * st["samples_sent"].get<uint64_t>());
  EXPECT_GE(st["modbus_requests"].get<uint64_t>(), 8u);
  EXPECT_EQ(st["frames_lost"].get<uint64_t>(), 0u);
  EXPECT_NE(sim.err().find("stationsim: SIGTERM"), std::string::npos) << sim.err();
  // The bus socket is gone with the process.
  EXPECT_NE(::access(s.path("bus.sock").c_str(), F_OK), 0);
}

TEST(StationsimCli, DurationAndTruthOut) {
  Scratch s;
  Child sim(s, {"--modbus", s.address + ":0", "--can", s.path("bus.sock"), "--speed", "200", "--duration-s",
                "20", "--truth-out", s.path("truth.json"), "--stats-file", s.path("stats.json"), "--seed", "5"});
  ASSERT_EQ(sim.wait(10000ms), 0) << sim.err();
  const nlohmann::json st = nlohmann::json::parse(read_file(s.path("stats.json")));
  // Stops at the duration (within one wake-up of the main loop: 0.2 ms wall = 0.04 s sim here, plus
  // scheduling slack).
  EXPECT_GE(st["sim_time_s"].get<double>(), 20.0);
  EXPECT_LT(st["sim_time_s"].get<double>(), 22.0);
  const auto truth = imucal::db::archive::read_truth_json(s.path("truth.json"));
  const auto unit = imucal::calib::effects::default_unit();
  EXPECT_TRUE(truth.params.gyro_M.isApprox(unit.params.gyro_M, 1e-12));
  EXPECT_TRUE(truth.params.accel_bias_mps2.isApprox(unit.params.accel_bias_mps2, 1e-12));
  EXPECT_DOUBLE_EQ(truth.noise.arw_rad_per_sqrt_s, unit.noise.arw_rad_per_sqrt_s);
}

TEST(StationsimCli, BadFlagsAndUnitFilesExitTwoNamingThem) {
  Scratch s;
  struct Case {
    std::vector<std::string> args;
    std::string named;
  };
  std::ofstream(s.path("bad_unit.toml")) << "[gyro]\nbias_deg_per_h = [0.01, 0.0, 0.0]\nbogus_key = 3\n";
  std::ofstream(s.path("bad_value.toml")) << "[accel]\nbias_ug = \"fifty\"\n";
  // A protocol file (issue #27) naming a signal its DBC does not have, on line 8.
  const std::string dbc = std::string(IMUCAL_SOURCE_DIR) + "/drivers/imu/imu.dbc";
  std::ofstream(s.path("bad_protocol.toml"))
      << "[protocol]\nname = \"x\"\ndbc = \"" << dbc
      << "\"\nquantity = \"increments\"\nmessages = [\"IMU_STATUS\"]\n"
         "completes_sample = \"IMU_STATUS\"\n[channels]\n"
         "angular = [\"IMU_STATUS.Nope\", \"IMU_STATUS.Nope\", \"IMU_STATUS.Nope\"]\n";
  const std::vector<Case> cases = {
      {{"--protocol", s.path("missing.toml")}, "--protocol: " + s.path("missing.toml")},
      {{"--protocol", s.path("bad_protocol.toml")},
       s.path("bad_protocol.toml") + ":8: signal 'Nope' is not in message IMU_STATUS"},
      {{"--base-id", "0x7FE"}, "beyond the 11-bit range"},
      {{"--speed", "fast"}, "--speed"},
      {{"--frobnicate"}, "--frobnicate"},
      {{"--can-loss", "1.5"}, "--can-loss"},
      {{"--modbus", "localhost"}, "--modbus"},
      {{"--modbus-delay-at", "3:100"}, "--modbus-delay-at"},
      {{"--table-fault-move", "0"}, "--table-fault-move"},
      {{"--unit", s.path("missing.toml")}, s.path("missing.toml")},
      {{"--unit", s.path("bad_unit.toml")}, s.path("bad_unit.toml") + ":3"},
      {{"--unit", s.path("bad_value.toml")}, s.path("bad_value.toml") + ":2"},
  };
  for (const auto& c : cases) {
    std::vector<std::string> args = {"--can", s.path("bus.sock"), "--modbus", s.address + ":0"};
    args.insert(args.end(), c.args.begin(), c.args.end());
    Child sim(s, args);
    EXPECT_EQ(sim.wait(5000ms), 2) << c.named << ": " << sim.err();
    EXPECT_NE(sim.err().find(c.named), std::string::npos) << sim.err();
    EXPECT_EQ(sim.out(), "") << c.named;  // nothing announced
    EXPECT_NE(::access(s.path("bus.sock").c_str(), F_OK), 0) << c.named << ": bus created";
  }
  // --can is required.
  Child no_can(s, {"--modbus", s.address + ":0"});
  EXPECT_EQ(no_can.wait(5000ms), 2);
  EXPECT_NE(no_can.err().find("--can"), std::string::npos) << no_can.err();
}
