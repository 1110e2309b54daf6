// TurntableClient against the simulated PLC's Modbus TCP server on a loopback address (real libmodbus on both
// ends). The PLC runs 10x accelerated; expected timings come from the PLC's rate/accel limits.
#include "drivers/turntable/turntable_client.hpp"

#include <gtest/gtest.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <string>
#include <thread>

#include "drivers/simulated/modbus_table_server.hpp"

namespace imucal {
namespace {

using namespace std::chrono_literals;
using drivers::simulated::AckResult;
using drivers::simulated::ModbusTableServer;
using drivers::simulated::TablePlc;
using drivers::simulated::TablePlcConfig;
using drivers::turntable::TurntableClient;
using drivers::turntable::TurntableClientConfig;

constexpr double kSpeed = 10.0;  // PLC seconds per wall second

const bool kQuietLogs = [] {  // IMUCAL_TEST_LOG=1 shows the driver's debug log
  spdlog::set_level(std::getenv("IMUCAL_TEST_LOG") ? spdlog::level::debug : spdlog::level::err);
  return true;
}();

TablePlcConfig plc_config() {
  TablePlcConfig c;
  c.rate_limit_dps = 60.0;
  c.accel_limit_dps2 = 60.0;
  c.estop_decel_dps2 = 300.0;
  c.home_rate_dps = 60.0;
  c.settle_time_s = 0.2;
  c.heartbeat_period_s = 0.02;
  c.initial_outer_deg = 6.0;
  c.initial_inner_deg = -3.0;
  return c;
}

/// A loopback address (Linux routes all of 127/8 to lo) of this test process alone: 127.P1.P0.N from the
/// pid's low 16 bits and a per-process counter. ctest runs every TEST as its own process, two at a time,
/// and other suites run beside it. With every server on 127.0.0.1, a port freed by one process (server
/// stopped, destroyed, or refusing connections) can be handed by the kernel to another process's
/// simulated table, and a client that keeps (re)connecting to the freed port (LinkLoss..., ConnectFails...,
/// Dropped...) then talks to a table it does not own: its start-up/safe stop stops that other test's move
/// mid-way. A per-process address makes "tcp:ADDRESS:PORT" name one table only.
std::string loopback_address() {
  static int counter = 0;
  const unsigned pid = static_cast<unsigned>(getpid());
  counter = counter % 254 + 1;
  return "127." + std::to_string((pid >> 8) & 0xffu) + "." + std::to_string(pid & 0xffu) + "." +
         std::to_string(counter);
}

drivers::simulated::ModbusTableServerConfig server_config() {
  drivers::simulated::ModbusTableServerConfig c;
  c.address = loopback_address();
  return c;
}

struct Station {
  explicit Station(TablePlcConfig plc = plc_config())
      : server(plc, server_config(), drivers::simulated::ScaledRealTime(kSpeed)) {
    server.start();
  }
  TurntableClientConfig client_config() const {
    TurntableClientConfig c;
    c.endpoint.host = server.config().address;
    c.endpoint.port = server.port();
    c.response_timeout = 200ms;
    c.backoff_initial = 20ms;
    c.backoff_max = 400ms;
    c.reconnect_give_up = 3000ms;
    c.poll_period = 10ms;
    c.heartbeat_timeout = 500ms;
    return c;
  }
  double plc_time() { return server.with_plc([](TablePlc& p) { return p.time_s(); }); }
  double plc_outer() { return server.with_plc([](TablePlc& p) { return p.outer_deg(); }); }
  uint16_t plc_last_command() { return server.with_plc([](TablePlc& p) { return p.last_command(); }); }
  /// Waits (bounded) until the PLC's outer angle passes `deg`.
  void wait_outer_past(double deg) {
    const auto deadline = std::chrono::steady_clock::now() + 3s;
    while (plc_outer() < deg && std::chrono::steady_clock::now() < deadline) std::this_thread::sleep_for(1ms);
    ASSERT_GE(plc_outer(), deg);
  }
  ModbusTableServer server;
};

/// A client that retries a request up to 3 times after 100 ms without a reply.
TurntableClientConfig retrying_config(const Station& st) {
  auto cfg = st.client_config();
  cfg.response_timeout = 100ms;
  cfg.max_attempts = 3;
  return cfg;
}

/// Connected, enabled and homed.
void make_ready(TurntableClient& c) {
  c.connect();
  c.enable();
  const auto s = c.home(3000ms);
  ASSERT_TRUE(s.homed);
  ASSERT_NEAR(s.outer_deg, 0.0, 1e-6);
}

TEST(TurntableEndpoint, ParsesTcpAndRtu) {
  const auto tcp = drivers::turntable::Endpoint::parse("tcp:10.0.0.7:1502");
  EXPECT_EQ(tcp.kind, drivers::turntable::Endpoint::Kind::kTcp);
  EXPECT_EQ(tcp.host, "10.0.0.7");
  EXPECT_EQ(tcp.port, 1502);
  const auto rtu = drivers::turntable::Endpoint::parse("rtu:/dev/ttyUSB0:38400:8N2");
  EXPECT_EQ(rtu.kind, drivers::turntable::Endpoint::Kind::kRtu);
  EXPECT_EQ(rtu.device, "/dev/ttyUSB0");
  EXPECT_EQ(rtu.baud, 38400);
  EXPECT_EQ(rtu.parity, 'N');
  EXPECT_EQ(rtu.stop_bits, 2);
  EXPECT_EQ(rtu.to_string(), "rtu:/dev/ttyUSB0:38400:8N2");
  EXPECT_THROW(drivers::turntable::Endpoint::parse("tcp:host:0"), std::invalid_argument);
  EXPECT_THROW(drivers::turntable::Endpoint::parse("tcp:host:70000"), std::invalid_argument);
  EXPECT_THROW(drivers::turntable::Endpoint::parse("tcp:host"), std::invalid_argument);
  EXPECT_THROW(drivers::turntable::Endpoint::parse("rtu:/dev/ttyS0:19200:9X1"),
               std::invalid_argument);
  EXPECT_THROW(drivers::turntable::Endpoint::parse("udp:host:502"), std::invalid_argument);
}

TEST(TurntableClient, EnableHomeMoveReachesTargetWithinThePhysics) {
  Station st;
  TurntableClient c(st.client_config());
  EXPECT_EQ(c.state(), drivers::turntable::State::kDisconnected);
  c.connect();
  EXPECT_EQ(c.state(), drivers::turntable::State::kDisabled);
  c.enable();
  // Homing from (6, -3) deg at 60 deg/s, 60 deg/s^2: triangle 2 sqrt(6/60) s = 0.632 s PLC.
  const double t_home0 = st.plc_time();
  const auto h = c.home(3000ms);
  EXPECT_TRUE(h.homed && h.in_position);
  EXPECT_GE(st.plc_time() - t_home0, 2.0 * std::sqrt(0.1) + 0.2 - 0.05);

  // Outer 0 -> 90 at 30 deg/s: 90/30 + 30/60 = 3.5 s; inner 0 -> -45: 45/30 + 0.5 = 2.0 s; +0.2 s settle.
  const double expected_s = TablePlc::rest_to_rest_time_s(90.0, 30.0, 60.0) + 0.2;
  ASSERT_NEAR(expected_s, 3.7, 1e-12);
  c.move_to(90.0, -45.0, 30.0);
  const double t_ack = st.plc_time();
  EXPECT_EQ(c.state(), drivers::turntable::State::kMoving);
  const auto s = c.wait_in_position(3000ms);
  const double elapsed = st.plc_time() - t_ack;
  EXPECT_NEAR(s.outer_deg, 90.0, 1e-4);
  EXPECT_NEAR(s.inner_deg, -45.0, 1e-4);
  EXPECT_TRUE(s.in_position && !s.moving && s.enabled && !s.fault);
  EXPECT_EQ(c.state(), drivers::turntable::State::kInPosition);
  // Not before the physics allows; not much later than one poll period (10 ms wall = 0.1 s PLC).
  EXPECT_GE(elapsed, expected_s - 0.1);
  EXPECT_LE(elapsed, expected_s + 0.5);
  // The PLC's actual state (what the IMU simulator will see) agrees.
  const auto a = st.server.with_plc([](TablePlc& p) { return p.actual_state(); });
  EXPECT_NEAR(a.outer_rad, M_PI / 2, 1e-12);
  EXPECT_NEAR(a.inner_rad, -M_PI / 4, 1e-12);
  EXPECT_TRUE(a.at_rest);
  const auto n = c.counters();
  EXPECT_EQ(n.commands, 4u);  // start-up stop, enable, home, move
  EXPECT_EQ(n.timeouts + n.bad_responses + n.link_errors + n.reconnects, 0u);
}

TEST(TurntableClient, StopMidMoveStopsShortOfTheTarget) {
  Station st;
  TurntableClient c(st.client_config());
  make_ready(c);
  c.move_to(90.0, 0.0, 30.0);
  st.wait_outer_past(20.0);
  const double outer_at_stop = st.plc_outer();
  c.stop();
  const auto s = c.wait_stopped(2000ms);
  EXPECT_FALSE(s.moving);
  EXPECT_FALSE(s.in_position);
  EXPECT_EQ(st.plc_last_command(), c.config().map.commands.stop);
  // At most 30 deg/s when stop was sent: braking at 60 deg/s^2 takes <= 7.5 deg, plus the angle the
  // table covered while the command travelled (< 50 ms wall = 0.5 s PLC at <= 30 deg/s).
  EXPECT_GT(s.outer_deg, outer_at_stop);
  EXPECT_LT(s.outer_deg, outer_at_stop + 7.5 + 15.0);
  EXPECT_LT(s.outer_deg, 80.0);
  EXPECT_EQ(c.state(), drivers::turntable::State::kReady);
}

TEST(TurntableClient, FaultMidMoveIsATypedErrorAndTheClientStopsTheTable) {
  Station st;
  TurntableClient c(st.client_config());
  make_ready(c);
  st.server.with_plc([](TablePlc& p) { p.arm_fault_during_next_move(0x2A, 1.0); });
  c.move_to(90.0, 0.0, 30.0);
  const auto stops_before = c.counters().commands;
  try {
    c.wait_in_position(3000ms);
    FAIL() << "no fault reported";
  } catch (const drivers::turntable::TableFaultError& e) {
    EXPECT_EQ(e.fault_code(), 0x2A);
    EXPECT_EQ(e.kind(), drivers::turntable::ErrorKind::kFault);
    EXPECT_NE(std::string(e.what()).find("code 42"), std::string::npos) << e.what();
  }
  EXPECT_EQ(c.state(), drivers::turntable::State::kFault);
  EXPECT_EQ(c.counters().commands, stops_before + 1);  // the safe stop, acknowledged
  EXPECT_EQ(st.plc_last_command(), c.config().map.commands.stop);
  // Fault 1 s PLC into the move: 7.5 deg accelerating + 0.5 s at 30 deg/s = 22.5 deg; the ramp-down at
  // 60 deg/s^2 adds 30^2 / 120 = 7.5 deg: standstill at 30 deg.
  const auto s = c.wait_stopped(2000ms);
  EXPECT_NEAR(s.outer_deg, 30.0, 1e-4);
  EXPECT_THROW(c.move_to(0.0, 0.0, 30.0), drivers::turntable::TableFaultError);
  c.clear_fault();
  c.enable();
  c.move_to(0.0, 0.0, 30.0);
  EXPECT_NEAR(c.wait_in_position(3000ms).outer_deg, 0.0, 1e-6);
}

TEST(TurntableClient, EstopIsATypedErrorAndBlocksMoves) {
  Station st;
  TurntableClient c(st.client_config());
  make_ready(c);
  c.move_to(90.0, 0.0, 30.0);
  st.wait_outer_past(10.0);
  st.server.with_plc([](TablePlc& p) { p.set_estop(true); });
  EXPECT_THROW(c.wait_in_position(3000ms), drivers::turntable::EstopError);
  EXPECT_EQ(c.state(), drivers::turntable::State::kEstop);
  EXPECT_THROW(c.move_to(0.0, 0.0, 30.0), drivers::turntable::EstopError);
  EXPECT_LT(c.wait_stopped(1000ms).outer_deg, 50.0);
  st.server.with_plc([](TablePlc& p) { p.set_estop(false); });
  c.enable();
  c.move_to(0.0, 0.0, 30.0);
  EXPECT_NEAR(c.wait_in_position(3000ms).outer_deg, 0.0, 1e-6);
}

TEST(TurntableClient, DroppedConnectionMidMoveReconnectsWithBackoffAndCompletes) {
  Station st;
  auto cfg = st.client_config();
  TurntableClient c(cfg);
  make_ready(c);
  c.move_to(90.0, -45.0, 30.0);
  st.wait_outer_past(10.0);
  st.server.refuse_connections_for(300ms);
  st.server.drop_clients();
  const auto t0 = std::chrono::steady_clock::now();
  const auto s = c.wait_in_position(5000ms);
  const auto took = std::chrono::steady_clock::now() - t0;
  EXPECT_NEAR(s.outer_deg, 90.0, 1e-4);
  EXPECT_NEAR(s.inner_deg, -45.0, 1e-4);
  const auto n = c.counters();
  EXPECT_GE(n.link_errors, 1u);
  EXPECT_EQ(n.reconnects, 1u);
  // Refused for 300 ms with retries after 20, 40, 80, 160 ms...: exponential backoff gives 3..6 failed
  // connects (a fixed 20 ms retry would give ~15).
  EXPECT_GE(n.connect_failures, 3u);
  EXPECT_LE(n.connect_failures, 6u);
  EXPECT_GE(took, 300ms);
  EXPECT_GE(st.server.stats().dropped, 1u);
}

TEST(TurntableClient, LinkLossBeyondGiveUpIsAClearError) {
  Station st;
  auto cfg = st.client_config();
  cfg.reconnect_give_up = 300ms;
  TurntableClient c(cfg);
  make_ready(c);
  st.server.stop();
  const auto t0 = std::chrono::steady_clock::now();
  try {
    c.status();
    FAIL() << "status() succeeded with the server gone";
  } catch (const drivers::turntable::LinkError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot reconnect"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find(cfg.endpoint.to_string()), std::string::npos) << e.what();
  }
  EXPECT_LT(std::chrono::steady_clock::now() - t0, 2s);
  EXPECT_EQ(c.state(), drivers::turntable::State::kDisconnected);
  EXPECT_FALSE(c.safe_stop());  // cannot be delivered, says so, does not throw
}

TEST(TurntableClient, ReplyDelayBeyondTimeoutIsCountedAndRecovered) {
  Station st;
  TurntableClient c(retrying_config(st));
  make_ready(c);
  // One reply 150 ms late: the first attempt times out, a retry gets through within the same call.
  auto before = c.counters();
  st.server.delay_replies(150ms, 1);
  const auto s = c.status();
  EXPECT_NEAR(s.outer_deg, st.plc_outer(), 1e-4);
  EXPECT_EQ(c.counters().timeouts - before.timeouts, 1u);
  for (int i = 0; i < 5; ++i) EXPECT_NO_THROW(c.status());
  EXPECT_EQ(c.counters().timeouts - before.timeouts, 1u);

  // A reply held back longer than all attempts: a timeout error, the link is re-opened on the next call.
  before = c.counters();
  st.server.delay_replies(500ms, 1);
  EXPECT_THROW(c.status(), drivers::turntable::RequestTimeoutError);
  EXPECT_EQ(c.counters().timeouts - before.timeouts, 3u);
  EXPECT_EQ(c.state(), drivers::turntable::State::kDisconnected);
  std::this_thread::sleep_for(300ms);  // the server finishes its stalled reply
  EXPECT_NO_THROW(c.status());
  EXPECT_EQ(c.counters().reconnects - before.reconnects, 1u);
  c.move_to(10.0, 0.0, 30.0);
  EXPECT_NEAR(c.wait_in_position(3000ms).outer_deg, 10.0, 1e-5);
}

// Issue #10 item 7: the reply to a timed-out attempt arrives while the retry is outstanding. It
// must be flushed (Modbus TCP transaction ids differ), never taken for the retry's answer. The
// table moves meanwhile, so the two replies carry different angles: the late one the angle when
// the first attempt was received, the retry's one ~45° further (0.15 s wall = 1.5 s of PLC time
// at 30 °/s).
TEST(TurntableClient, ALateReplyIsFlushedNotTakenForTheRetrysAnswer) {
  Station st;
  TurntableClient c(retrying_config(st));
  make_ready(c);
  c.move_to(340.0, 0.0, 30.0);
  st.wait_outer_past(20.0);
  const auto before = c.counters();
  const double p0 = st.plc_outer();
  st.server.delay_replies(150ms, 1);
  const auto s = c.status();
  const double p1 = st.plc_outer();
  ASSERT_LT(p1, 330.0) << "the move ended during the exchange: the replies would not differ";
  EXPECT_EQ(c.counters().timeouts - before.timeouts, 1u);
  // The late reply did reach the client while the retry was outstanding, and was refused there.
  EXPECT_EQ(c.counters().bad_responses - before.bad_responses, 1u);
  EXPECT_GT(s.outer_deg, p0 + 20.0)
      << "the late reply (outer " << p0 << " deg when it was read) was taken for the "
      << "retry's answer; PLC now at " << p1;
  EXPECT_LE(s.outer_deg, p1 + 1e-3);  // the registers carry float32 angles
  // The exchange has recovered: further reads follow the table without another timeout.
  double last = s.outer_deg;
  for (int i = 0; i < 5; ++i) {
    const auto r = c.status();
    EXPECT_GE(r.outer_deg, last - 1e-6);
    last = r.outer_deg;
  }
  EXPECT_EQ(c.counters().timeouts - before.timeouts, 1u);
}

// Issue #22: under load a status read timed out twice and its third attempt then read the first
// attempt's late reply; that spent the last attempt and aborted a soak run. A late reply is owed by
// a timed-out attempt, so it does not cost an attempt of its own: with 100 ms x 3 attempts, a reply
// held back 250 ms lands inside the third attempt, and the read still succeeds.
TEST(TurntableClient, ALateReplyAfterTwoTimeoutsDoesNotSpendTheLastAttempt) {
  Station st;
  TurntableClient c(retrying_config(st));
  make_ready(c);
  const auto before = c.counters();
  st.server.delay_replies(250ms, 1);
  drivers::turntable::TableStatus s;
  ASSERT_NO_THROW(s = c.status());
  EXPECT_NEAR(s.outer_deg, st.plc_outer(), 1e-4);
  EXPECT_EQ(c.counters().timeouts - before.timeouts, 2u);
  EXPECT_GE(c.counters().bad_responses - before.bad_responses, 1u);
  EXPECT_NE(c.state(), drivers::turntable::State::kDisconnected);  // no reconnect was needed
  for (int i = 0; i < 5; ++i) EXPECT_NO_THROW(c.status());
  EXPECT_EQ(c.counters().timeouts - before.timeouts, 2u);
}

TEST(TurntableClient, SeveralClientsAtOnce) {
  Station st;
  TurntableClient commander(st.client_config());
  make_ready(commander);
  commander.move_to(90.0, 0.0, 30.0);
  std::atomic<int> failures{0}, reads{0};
  std::vector<std::thread> observers;
  for (int k = 0; k < 3; ++k) {
    observers.emplace_back([&] {
      auto cfg = st.client_config();
      cfg.stop_on_connect = false;  // observers must not stop the commander's move
      TurntableClient obs(cfg);
      try {
        obs.connect();
        double last = -1.0;
        for (int i = 0; i < 30; ++i) {
          const auto s = obs.status();
          // The outer axis moves 0 -> 90 monotonically: every observer must see that.
          if (s.outer_deg < last - 1e-6 || s.outer_deg < -1e-6 || s.outer_deg > 90.0 + 1e-6) ++failures;
          last = s.outer_deg;
          ++reads;
          std::this_thread::sleep_for(5ms);
        }
      } catch (const std::exception& e) {
        ADD_FAILURE() << e.what();
        ++failures;
      }
    });
  }
  drivers::turntable::TableStatus s;
  try {
    s = commander.wait_in_position(3000ms);
  } catch (const std::exception& e) {
    ADD_FAILURE() << e.what();
  }
  for (auto& t : observers) t.join();
  EXPECT_EQ(failures.load(), 0);
  EXPECT_EQ(reads.load(), 90);
  EXPECT_NEAR(s.outer_deg, 90.0, 1e-4);
  EXPECT_GE(st.server.stats().accepted, 4u);
}

TEST(TurntableClient, StaleHeartbeatIsAFault) {
  Station st;
  auto cfg = st.client_config();
  cfg.heartbeat_timeout = 300ms;
  TurntableClient c(cfg);
  make_ready(c);
  c.move_to(90.0, 0.0, 30.0);
  st.server.with_plc([](TablePlc& p) { p.set_heartbeat_frozen(true); });
  const auto t0 = std::chrono::steady_clock::now();
  EXPECT_THROW(c.wait_in_position(3000ms), drivers::turntable::HeartbeatError);
  EXPECT_GE(std::chrono::steady_clock::now() - t0, 300ms);
  EXPECT_EQ(c.counters().heartbeat_stale, 1u);
  EXPECT_EQ(c.state(), drivers::turntable::State::kFault);
  EXPECT_EQ(st.plc_last_command(), cfg.map.commands.stop);
}

TEST(TurntableClient, RejectedCommandsAndBadArguments) {
  Station st;
  TurntableClient c(st.client_config());
  c.connect();
  try {
    c.move_to(10.0, 0.0, 10.0);
    FAIL() << "move accepted while disabled";
  } catch (const drivers::turntable::CommandRejectedError& e) {
    EXPECT_EQ(e.result(), static_cast<uint16_t>(AckResult::kNotEnabled));
  }
  c.enable();
  try {
    c.move_to(10.0, 0.0, 10.0);
    FAIL() << "move accepted before homing";
  } catch (const drivers::turntable::CommandRejectedError& e) {
    EXPECT_EQ(e.result(), static_cast<uint16_t>(AckResult::kNotHomed));
  }
  EXPECT_EQ(c.counters().rejected, 2u);
  const auto requests = c.counters().requests;
  EXPECT_THROW(c.move_to(std::nan(""), 0.0, 10.0), drivers::turntable::InvalidArgumentError);
  EXPECT_THROW(c.move_to(0.0, INFINITY, 10.0), drivers::turntable::InvalidArgumentError);
  EXPECT_THROW(c.move_to(0.0, 0.0, 0.0), drivers::turntable::InvalidArgumentError);
  EXPECT_THROW(c.move_to(0.0, 0.0, -1.0), drivers::turntable::InvalidArgumentError);
  EXPECT_EQ(c.counters().requests, requests);  // refused before anything was sent
}

TEST(TurntableClient, AbortFromAnotherThreadStopsTheTable) {
  Station st;
  TurntableClient c(st.client_config());
  make_ready(c);
  c.move_to(90.0, 0.0, 30.0);
  std::thread aborter([&] {
    std::this_thread::sleep_for(100ms);
    c.request_abort();
  });
  EXPECT_THROW(c.wait_in_position(3000ms), drivers::turntable::AbortedError);
  aborter.join();
  EXPECT_EQ(st.plc_last_command(), c.config().map.commands.stop);
  EXPECT_LT(c.wait_stopped(2000ms).outer_deg, 80.0);
  c.clear_abort();
}

TEST(TurntableClient, ConnectCommandsASafeStop) {
  Station st;
  TurntableClient a(st.client_config());
  make_ready(a);
  a.move_to(90.0, 0.0, 30.0);
  st.wait_outer_past(10.0);
  TurntableClient b(st.client_config());  // e.g. a restarted daemon
  b.connect();
  EXPECT_EQ(st.plc_last_command(), b.config().map.commands.stop);
  const auto s = b.wait_stopped(2000ms);
  EXPECT_LT(s.outer_deg, 80.0);
  EXPECT_FALSE(s.in_position);
}

TEST(TurntableClient, UnmappedRegistersGiveAModbusException) {
  Station st;
  auto cfg = st.client_config();
  cfg.map.input.ack_result = 40;  // the server maps input registers 0..12 only
  TurntableClient c(cfg);
  EXPECT_THROW(c.connect(), drivers::turntable::ModbusExceptionError);
  EXPECT_EQ(c.counters().exceptions, 1u);
}

TEST(TurntableClient, ConnectFailsClearlyWhenNothingListens) {
  TurntableClientConfig cfg;
  {
    Station st;
    cfg.endpoint = st.client_config().endpoint;
  }  // server gone: the port is closed (and the address is this process's own)
  cfg.backoff_initial = 20ms;
  cfg.reconnect_give_up = 100ms;
  TurntableClient c(cfg);
  EXPECT_THROW(c.connect(), drivers::turntable::LinkError);
  EXPECT_GE(c.counters().connect_failures, 2u);
  EXPECT_EQ(c.state(), drivers::turntable::State::kDisconnected);
}

}  // namespace
}  // namespace imucal
