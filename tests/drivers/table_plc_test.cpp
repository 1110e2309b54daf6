// Simulated PLC table, driven only through its register image like a Modbus master would.
// Expected trajectories are worked out by hand from the trapezoid (rate 20 deg/s, accel 10 deg/s^2):
// accel phase 2 s / 20 deg, cruise at 20 deg/s, decel phase 2 s / 20 deg.
#include "drivers/simulated/table_plc.hpp"

#include <gtest/gtest.h>

#include <cmath>

namespace imucal::drivers::simulated {
namespace {

using drivers::turntable::decode_float;
using drivers::turntable::encode_float;
constexpr double kPi = 3.14159265358979323846;

TablePlcConfig test_config() {
  TablePlcConfig c;
  c.rate_limit_dps = 30.0;
  c.accel_limit_dps2 = 10.0;
  c.estop_decel_dps2 = 120.0;
  c.home_rate_dps = 15.0;
  c.settle_time_s = 0.5;
  c.heartbeat_period_s = 0.1;
  c.initial_outer_deg = 4.0;
  c.initial_inner_deg = -2.0;
  return c;
}

/// A minimal register-level master.
class Master {
 public:
  explicit Master(TablePlc& plc) : plc_(plc), map_(plc.config().map) {}

  AckResult command(uint16_t code) {
    const uint16_t regs[2] = {code, ++seq_};
    plc_.write_holding(map_.holding.command, regs, 2);
    plc_.step(0.0);  // one scan, no time
    EXPECT_EQ(plc_.input_image()[map_.input.ack_seq], seq_);
    return static_cast<AckResult>(plc_.input_image()[map_.input.ack_result]);
  }
  AckResult move(double outer, double inner, double rate) {
    put(map_.holding.target_outer_deg, outer);
    put(map_.holding.target_inner_deg, inner);
    put(map_.holding.max_rate_dps, rate);
    return command(map_.commands.move);
  }
  void put(uint16_t address, double v) {
    const auto r = encode_float(static_cast<float>(v), map_.word_order);
    plc_.write_holding(address, r.data(), 2);
  }
  double input_float(uint16_t address) const { return decode_float(&plc_.input_image()[address], map_.word_order); }
  bool bit(uint8_t n) const { return (plc_.input_image()[map_.input.status] >> n) & 1u; }
  /// Advances in steps of dt until t.
  void run_until(double t_s, double dt = 0.01) {
    while (plc_.time_s() < t_s - 1e-12) plc_.step(std::min(dt, t_s - plc_.time_s()));
  }
  void ready() {  // enable + home, returns at the home position, settled
    EXPECT_EQ(command(map_.commands.enable), AckResult::kAccepted);
    EXPECT_EQ(command(map_.commands.home), AckResult::kAccepted);
    run_until(plc_.time_s() + 5.0);
    EXPECT_TRUE(plc_.homed());
    EXPECT_TRUE(plc_.in_position());
  }

  TablePlc& plc_;
  const drivers::turntable::RegisterMap map_;
  uint16_t seq_ = 0;
};

TEST(TablePlc, CommandsNeedEnableAndHome) {
  TablePlc plc(test_config());
  Master m(plc);
  EXPECT_EQ(m.move(10, 0, 10), AckResult::kNotEnabled);
  EXPECT_EQ(m.command(m.map_.commands.home), AckResult::kNotEnabled);
  EXPECT_EQ(m.command(m.map_.commands.enable), AckResult::kAccepted);
  EXPECT_TRUE(m.bit(m.map_.status_bits.enabled));
  EXPECT_EQ(m.move(10, 0, 10), AckResult::kNotHomed);
  EXPECT_EQ(m.command(999), AckResult::kUnknownCommand);
  EXPECT_EQ(plc.last_command(), 999);
}

TEST(TablePlc, HomingRunsAtTheHomeRateThenSettles) {
  TablePlc plc(test_config());
  Master m(plc);
  EXPECT_NEAR(m.input_float(m.map_.input.actual_outer_deg), 4.0, 1e-6);
  EXPECT_EQ(m.command(m.map_.commands.enable), AckResult::kAccepted);
  EXPECT_EQ(m.command(m.map_.commands.home), AckResult::kAccepted);
  // Outer 4 deg at 15 deg/s, 10 deg/s^2: 4 < 15^2/10, so a triangle: 2 sqrt(4/10) s.
  const double t_outer = 2.0 * std::sqrt(0.4);
  EXPECT_NEAR(TablePlc::rest_to_rest_time_s(4.0, 15.0, 10.0), t_outer, 1e-12);
  m.run_until(t_outer - 0.01);
  EXPECT_TRUE(plc.moving());
  EXPECT_FALSE(plc.homed());
  m.run_until(t_outer + 0.01);
  EXPECT_FALSE(plc.moving());
  EXPECT_TRUE(plc.homed());
  EXPECT_FALSE(plc.in_position());  // settling
  m.run_until(t_outer + 0.49);
  EXPECT_FALSE(plc.in_position());
  m.run_until(t_outer + 0.51);
  EXPECT_TRUE(plc.in_position());
  EXPECT_TRUE(m.bit(m.map_.status_bits.in_position));
  EXPECT_TRUE(m.bit(m.map_.status_bits.homed));
  EXPECT_EQ(plc.outer_deg(), 0.0);
  EXPECT_EQ(plc.inner_deg(), 0.0);
}

TEST(TablePlc, TrapezoidAndTriangleFollowTheLimits) {
  TablePlc plc(test_config());
  Master m(plc);
  m.ready();
  const double t0 = plc.time_s();
  // Outer 0 -> 90 at 20 deg/s: 2 s accel (20 deg), 2.5 s cruise (50 deg), 2 s decel: 6.5 s.
  // Inner 0 -> -30: 30 < 20^2/10, triangle: 2 sqrt(3) s, peak sqrt(300) deg/s at -15 deg.
  ASSERT_EQ(m.move(90.0, -30.0, 20.0), AckResult::kAccepted);
  struct Check {
    double t, outer, outer_rate, outer_accel;
  };
  for (const Check& c : {Check{1.0, 5.0, 10.0, 10.0}, Check{3.0, 40.0, 20.0, 0.0}, Check{5.5, 85.0, 10.0, -10.0}}) {
    m.run_until(t0 + c.t);
    const auto s = plc.actual_state();
    EXPECT_NEAR(s.outer_rad * 180 / kPi, c.outer, 1e-9) << c.t;
    EXPECT_NEAR(s.outer_rate_radps * 180 / kPi, c.outer_rate, 1e-9) << c.t;
    EXPECT_NEAR(s.outer_accel_radps2 * 180 / kPi, c.outer_accel, 1e-9) << c.t;
    EXPECT_FALSE(s.at_rest);
    // The input registers carry the same angle (float32).
    EXPECT_NEAR(m.input_float(m.map_.input.actual_outer_deg), c.outer, 1e-4);
    EXPECT_NEAR(m.input_float(m.map_.input.rate_outer_dps), c.outer_rate, 1e-4);
    EXPECT_TRUE(m.bit(m.map_.status_bits.moving));
  }
  const double t_peak = std::sqrt(3.0);
  TablePlc plc2(test_config());
  Master m2(plc2);
  m2.ready();
  const double t2 = plc2.time_s();
  ASSERT_EQ(m2.move(90.0, -30.0, 20.0), AckResult::kAccepted);
  m2.run_until(t2 + t_peak);
  EXPECT_NEAR(plc2.actual_state().inner_rad * 180 / kPi, -15.0, 1e-9);
  EXPECT_NEAR(plc2.actual_state().inner_rate_radps * 180 / kPi, -std::sqrt(300.0), 1e-9);

  m.run_until(t0 + 6.49);
  EXPECT_TRUE(plc.moving());
  m.run_until(t0 + 6.5 + 1e-9);
  EXPECT_FALSE(plc.moving());
  EXPECT_EQ(plc.outer_deg(), 90.0);
  EXPECT_EQ(plc.inner_deg(), -30.0);
  EXPECT_TRUE(plc.actual_state().at_rest);
  m.run_until(t0 + 6.5 + 0.49);
  EXPECT_FALSE(plc.in_position());
  m.run_until(t0 + 6.5 + 0.51);
  EXPECT_TRUE(plc.in_position());
}

TEST(TablePlc, StepSizeDoesNotChangeTheTrajectory) {
  TablePlc fine(test_config()), coarse(test_config());
  Master a(fine), b(coarse);
  a.ready();
  b.ready();
  ASSERT_EQ(a.move(-123.0, 77.0, 25.0), AckResult::kAccepted);
  ASSERT_EQ(b.move(-123.0, 77.0, 25.0), AckResult::kAccepted);
  const double t0 = fine.time_s();
  for (double t : {0.37, 1.11, 2.5, 4.07, 7.77}) {
    a.run_until(t0 + t, 0.001);
    b.run_until(t0 + t, 0.37);
    EXPECT_NEAR(fine.outer_deg(), coarse.outer_deg(), 1e-9) << t;
    EXPECT_NEAR(fine.inner_deg(), coarse.inner_deg(), 1e-9) << t;
  }
}

TEST(TablePlc, CommandedRateIsClippedToTheTableLimit) {
  TablePlc plc(test_config());
  Master m(plc);
  m.ready();
  const double t0 = plc.time_s();
  ASSERT_EQ(m.move(180.0, 0.0, 1000.0), AckResult::kAccepted);
  const double expected = TablePlc::rest_to_rest_time_s(180.0, 30.0, 10.0);  // 180/30 + 3 = 9 s
  EXPECT_NEAR(expected, 9.0, 1e-12);
  double peak = 0.0;
  while (plc.moving()) {
    plc.step(0.05);
    peak = std::max(peak, plc.actual_state().outer_rate_radps * 180 / kPi);
  }
  EXPECT_NEAR(plc.time_s() - t0, expected, 0.05 + 1e-9);
  EXPECT_NEAR(peak, 30.0, 1e-9);
}

TEST(TablePlc, StopDeceleratesAtTheAccelLimit) {
  TablePlc plc(test_config());
  Master m(plc);
  m.ready();
  const double t0 = plc.time_s();
  ASSERT_EQ(m.move(90.0, 0.0, 20.0), AckResult::kAccepted);
  m.run_until(t0 + 3.0);  // at 40 deg, 20 deg/s
  ASSERT_EQ(m.command(m.map_.commands.stop), AckResult::kAccepted);
  // 20 deg/s at 10 deg/s^2: 2 s and 20 deg more.
  m.run_until(t0 + 4.99);
  EXPECT_TRUE(plc.moving());
  m.run_until(t0 + 5.01);
  EXPECT_FALSE(plc.moving());
  EXPECT_NEAR(plc.outer_deg(), 60.0, 1e-9);
  m.run_until(t0 + 8.0);
  EXPECT_FALSE(plc.in_position());  // stopped short of the target: never in position
  EXPECT_NEAR(plc.outer_deg(), 60.0, 1e-9);
}

TEST(TablePlc, RedirectMidMoveBrakesThenReturns) {
  TablePlc plc(test_config());
  Master m(plc);
  m.ready();
  const double t0 = plc.time_s();
  ASSERT_EQ(m.move(90.0, 0.0, 20.0), AckResult::kAccepted);
  m.run_until(t0 + 3.0);  // 40 deg, +20 deg/s
  ASSERT_EQ(m.move(0.0, 0.0, 20.0), AckResult::kAccepted);
  // Must brake 2 s to 60 deg (cannot reverse instantly), then 60 deg back: 60/20 + 2 = 5 s.
  double max_outer = 0.0;
  while (plc.moving()) {
    plc.step(0.01);
    max_outer = std::max(max_outer, plc.outer_deg());
    const double rate = std::abs(plc.actual_state().outer_rate_radps) * 180 / kPi;
    ASSERT_LE(rate, 20.0 + 1e-9);
  }
  EXPECT_NEAR(max_outer, 60.0, 1e-6);
  EXPECT_NEAR(plc.time_s() - t0, 3.0 + 2.0 + 5.0, 0.01 + 1e-9);
  EXPECT_EQ(plc.outer_deg(), 0.0);
}

TEST(TablePlc, InjectedFaultMidMoveLatchesAndRampsDown) {
  TablePlc plc(test_config());
  Master m(plc);
  m.ready();
  plc.arm_fault_during_next_move(0x2A, 2.0);
  const double t0 = plc.time_s();
  ASSERT_EQ(m.move(90.0, 0.0, 20.0), AckResult::kAccepted);
  m.run_until(t0 + 1.95, 0.3);
  EXPECT_FALSE(plc.fault());
  m.run_until(t0 + 2.1, 0.3);  // the step straddles the fault instant
  EXPECT_TRUE(plc.fault());
  EXPECT_TRUE(m.bit(m.map_.status_bits.fault));
  EXPECT_FALSE(m.bit(m.map_.status_bits.enabled));
  EXPECT_EQ(m.plc_.input_image()[m.map_.input.fault_code], 0x2A);
  // Fault at exactly t0 + 2 s (20 deg, 20 deg/s), ramp-down at 10 deg/s^2: stops at 40 deg at t0 + 4 s.
  m.run_until(t0 + 5.0, 0.3);
  EXPECT_FALSE(plc.moving());
  EXPECT_NEAR(plc.outer_deg(), 40.0, 1e-9);
  EXPECT_FALSE(plc.in_position());
  EXPECT_EQ(m.move(90.0, 0.0, 20.0), AckResult::kFaultActive);
  EXPECT_EQ(m.command(m.map_.commands.enable), AckResult::kFaultActive);
  EXPECT_EQ(m.command(m.map_.commands.stop), AckResult::kAccepted);  // stop always works
  EXPECT_EQ(m.command(m.map_.commands.clear_fault), AckResult::kAccepted);
  EXPECT_EQ(plc.fault_code(), 0);
  EXPECT_EQ(m.move(90.0, 0.0, 20.0), AckResult::kNotEnabled);
  EXPECT_EQ(m.command(m.map_.commands.enable), AckResult::kAccepted);
  EXPECT_EQ(m.move(90.0, 0.0, 20.0), AckResult::kAccepted);  // still homed
}

TEST(TablePlc, EstopStopsHardAndBlocksCommands) {
  TablePlc plc(test_config());
  Master m(plc);
  m.ready();
  const double t0 = plc.time_s();
  ASSERT_EQ(m.move(90.0, 0.0, 20.0), AckResult::kAccepted);
  m.run_until(t0 + 3.0);  // 40 deg, 20 deg/s
  plc.set_estop(true);
  EXPECT_TRUE(m.bit(m.map_.status_bits.estop));
  // 20 deg/s at 120 deg/s^2: 1/6 s, 20^2 / 240 = 1.6667 deg.
  m.run_until(t0 + 3.0 + 1.0 / 6.0 + 0.001, 0.001);
  EXPECT_FALSE(plc.moving());
  EXPECT_NEAR(plc.outer_deg(), 40.0 + 400.0 / 240.0, 1e-9);
  EXPECT_EQ(m.command(m.map_.commands.enable), AckResult::kEstopActive);
  EXPECT_EQ(m.command(m.map_.commands.clear_fault), AckResult::kEstopActive);
  EXPECT_EQ(m.command(m.map_.commands.stop), AckResult::kAccepted);
  plc.set_estop(false);
  EXPECT_EQ(m.move(0.0, 0.0, 20.0), AckResult::kNotEnabled);
  EXPECT_EQ(m.command(m.map_.commands.enable), AckResult::kAccepted);
  EXPECT_EQ(m.move(0.0, 0.0, 20.0), AckResult::kAccepted);
}

TEST(TablePlc, SequenceNumbersActOnce) {
  TablePlc plc(test_config());
  Master m(plc);
  m.ready();
  const uint64_t handled = plc.commands_handled();
  plc.step(0.1);
  plc.step(0.1);  // same sequence still in the holding registers: nothing new
  EXPECT_EQ(plc.commands_handled(), handled);
  const uint16_t zero_seq[2] = {m.map_.commands.enable, 0};
  plc.write_holding(m.map_.holding.command, zero_seq, 2);
  plc.step(0.1);  // sequence 0 = no command
  EXPECT_EQ(plc.commands_handled(), handled);
  EXPECT_THROW(plc.write_holding(7, zero_seq, 2), std::out_of_range);
}

TEST(TablePlc, BadMoveParametersAreRejected) {
  TablePlc plc(test_config());
  Master m(plc);
  m.ready();
  EXPECT_EQ(m.move(10.0, 0.0, 0.0), AckResult::kBadParameter);
  EXPECT_EQ(m.move(10.0, 0.0, -5.0), AckResult::kBadParameter);
  EXPECT_EQ(m.move(std::nan(""), 0.0, 5.0), AckResult::kBadParameter);
  EXPECT_FALSE(plc.moving());
  EXPECT_THROW(plc.step(-1.0), std::invalid_argument);
  EXPECT_THROW(plc.inject_fault(0), std::invalid_argument);
}

TEST(TablePlc, HeartbeatCountsPlcTimeUnlessFrozen) {
  TablePlc plc(test_config());
  Master m(plc);
  for (int i = 0; i < 25; ++i) plc.step(0.04);  // 1.0 s at a 0.1 s period: 10 ticks
  EXPECT_EQ(plc.heartbeat(), 10);
  EXPECT_EQ(plc.input_image()[m.map_.input.heartbeat], 10);
  plc.set_heartbeat_frozen(true);
  plc.step(1.0);
  EXPECT_EQ(plc.heartbeat(), 10);
  plc.set_heartbeat_frozen(false);
  plc.step(6553.6);  // 65536 ticks: wraps to the same value
  EXPECT_EQ(plc.heartbeat(), 10);
}

TEST(TablePlc, CustomMapLayoutIsHonoured) {
  TablePlcConfig c = test_config();
  c.map.word_order = drivers::turntable::WordOrder::kCDAB;
  c.map.status_bits.moving = 9;
  c.map.input.status = 40;
  c.map.commands.move = 0x100;
  TablePlc plc(c);
  Master m(plc);
  ASSERT_EQ(plc.input_image().size(), 41u);
  m.ready();
  ASSERT_EQ(m.move(10.0, 0.0, 10.0), AckResult::kAccepted);
  plc.step(0.5);
  EXPECT_EQ((plc.input_image()[40] >> 9) & 1u, 1u);
  // CDAB: low word first.
  const float outer = plc.outer_deg();
  const auto& in = plc.input_image();
  EXPECT_EQ(in[c.map.input.actual_outer_deg + 1],
            encode_float(outer, drivers::turntable::WordOrder::kABCD)[0]);
}

}  // namespace
}  // namespace imucal::drivers::simulated

namespace imucal::drivers::simulated {
namespace {

// table_time_offset (ARCHITECTURE §7) in the station simulator: the encoder registers show the
// motion of encoder_delay_s ago; the physics (actual_state) is not delayed. Outer 0 -> 90 at 20 °/s
// with 10 °/s² (the trapezoid above): at t = 3 s the axis is at 40° cruising at 20 °/s, so an
// encoder 0.25 s late reads 40 - 20·0.25 = 35°.
TEST(TablePlc, ALaggingEncoderReportsTheAnglesOfItsDelayAgo) {
  TablePlcConfig cfg = test_config();
  cfg.encoder_delay_s = 0.25;
  TablePlc plc(cfg);
  Master m(plc);
  m.ready();
  const double t0 = plc.time_s();
  ASSERT_EQ(m.move(90.0, -30.0, 20.0), AckResult::kAccepted);
  m.run_until(t0 + 3.0);
  EXPECT_NEAR(plc.actual_state().outer_rad * 180 / kPi, 40.0, 1e-9);
  EXPECT_NEAR(m.input_float(m.map_.input.actual_outer_deg), 35.0, 1e-4);
  EXPECT_NEAR(m.input_float(m.map_.input.rate_outer_dps), 20.0, 1e-4);
  // At the end both agree again (once the delay has passed).
  m.run_until(t0 + 10.0);
  EXPECT_NEAR(m.input_float(m.map_.input.actual_outer_deg), 90.0, 1e-4);
}

// A lagging encoder across a replanned motion: the registers follow the motion that really happened
// delay_s ago, not the new plan. Redirected at t0 + 3 s (40°, +20 °/s) back to 0, the axis brakes
// at 10 °/s²: 0.1 s later an encoder 0.25 s late still shows the old cruise, 40 - 20·0.15 = 37°,
// and 0.3 s after the redirect it shows the braking, 40 + 20·0.05 - 5·0.05² = 40.9875°. A stop
// mid-move likewise.
TEST(TablePlc, ALaggingEncoderFollowsTheMotionThroughARedirectAndAStop) {
  TablePlcConfig cfg = test_config();
  cfg.encoder_delay_s = 0.25;
  TablePlc plc(cfg);
  Master m(plc);
  m.ready();
  const double t0 = plc.time_s();
  ASSERT_EQ(m.move(90.0, 0.0, 20.0), AckResult::kAccepted);
  m.run_until(t0 + 3.0);
  ASSERT_EQ(m.move(0.0, 0.0, 20.0), AckResult::kAccepted);
  m.run_until(t0 + 3.1);
  EXPECT_NEAR(m.input_float(m.map_.input.actual_outer_deg), 37.0, 1e-4);
  EXPECT_NEAR(m.input_float(m.map_.input.rate_outer_dps), 20.0, 1e-4);
  m.run_until(t0 + 3.3);
  EXPECT_NEAR(m.input_float(m.map_.input.actual_outer_deg), 40.9875, 1e-4);
  EXPECT_NEAR(m.input_float(m.map_.input.rate_outer_dps), 19.5, 1e-4);
  // Braking ends at 60° (t0 + 5 s), back at 0 at t0 + 10 s. A new move out, stopped mid-cruise.
  m.run_until(t0 + 11.0);
  EXPECT_NEAR(m.input_float(m.map_.input.actual_outer_deg), 0.0, 1e-4);
  const double t1 = plc.time_s();
  ASSERT_EQ(m.move(90.0, 0.0, 20.0), AckResult::kAccepted);
  m.run_until(t1 + 3.0);  // 40°, +20 °/s
  ASSERT_EQ(m.command(m.map_.commands.stop), AckResult::kAccepted);
  m.run_until(t1 + 3.2);  // the encoder shows t1 + 2.95 s: 39°
  EXPECT_NEAR(m.input_float(m.map_.input.actual_outer_deg), 39.0, 1e-4);
  m.run_until(t1 + 10.0);
  EXPECT_NEAR(m.input_float(m.map_.input.actual_outer_deg), 60.0, 1e-4);
}

// The size effect's quadrature needs the instants where the planned acceleration jumps: the
// trapezoid's corners at t0 + 2, 4.5 and 6.5 s (outer) and the triangle's at t0 + √3, 2√3 (inner).
TEST(TablePlc, AccelerationSwitchTimesAreTheProfileCorners) {
  TablePlc plc(test_config());
  Master m(plc);
  m.ready();
  const double t0 = plc.time_s();
  ASSERT_EQ(m.move(90.0, -30.0, 20.0), AckResult::kAccepted);
  const auto sw = plc.accel_switch_times(t0 + 0.5, t0 + 7.0);
  const std::vector<double> expect = {t0 + std::sqrt(3.0), t0 + 2.0, t0 + 2.0 * std::sqrt(3.0),
                                      t0 + 4.5, t0 + 6.5};
  ASSERT_EQ(sw.size(), expect.size());
  for (size_t i = 0; i < sw.size(); ++i) EXPECT_NEAR(sw[i], expect[i], 1e-9) << i;
  EXPECT_TRUE(plc.accel_switch_times(t0 + 2.1, t0 + 2.2).empty());
}

// A pending fault cuts the plan: 0 -> 90 at 20 °/s, 10 °/s², fault 3 s into the move (cruising):
// the corners are the end of the acceleration (t0 + 2), the fault (t0 + 3) and the end of the
// ramp-down from 20 °/s at 10 °/s² (t0 + 5) — not the planned 4.5 and 6.5 s. And they are right:
// the axis really decelerates on exactly those pieces.
TEST(TablePlc, AccelerationSwitchTimesFollowAPendingFault) {
  TablePlc plc(test_config());
  Master m(plc);
  m.ready();
  plc.arm_fault_during_next_move(0x17, 3.0);
  const double t0 = plc.time_s();
  ASSERT_EQ(m.move(90.0, 0.0, 20.0), AckResult::kAccepted);
  const auto sw = plc.accel_switch_times(t0 + 0.5, t0 + 7.0);
  const std::vector<double> expect = {t0 + 2.0, t0 + 3.0, t0 + 5.0};
  ASSERT_EQ(sw.size(), expect.size());
  for (size_t i = 0; i < sw.size(); ++i) EXPECT_NEAR(sw[i], expect[i], 1e-9) << i;
  m.run_until(t0 + 4.0);
  EXPECT_TRUE(plc.fault());
  EXPECT_NEAR(plc.actual_state().outer_accel_radps2 * 180 / kPi, -10.0, 1e-9);
  m.run_until(t0 + 5.5);
  EXPECT_NEAR(plc.outer_deg(), 20.0 + 20.0 + 20.0, 1e-9);  // ramp 20°, cruise 1 s, brake 20°
}

}  // namespace
}  // namespace imucal::drivers::simulated
