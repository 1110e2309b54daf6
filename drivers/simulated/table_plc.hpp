#pragma once
// Simulated PLC-driven two-axis turntable: pure logic, no I/O, one physics clock advanced by
// step(dt_s).
//
// The PLC is seen through its Modbus register image (drivers::turntable::RegisterMap): the master
// writes holding registers (targets, rate, command + sequence number), the PLC scans them at the
// start of each step(), acts on a new sequence number once, echoes it in ack_seq with an AckResult,
// and publishes actual angles, rates, status bits, fault code and heartbeat in the input registers
// at the end of each step().
//
// Motion: each axis follows a time-optimal trapezoidal profile (triangular when the rate limit is
// not reached) under the rate limit (the commanded max rate, clipped to the table's rate_limit_dps)
// and the table's acceleration limit. A new move replans from the current angle AND rate, so moves
// can be chained or redirected mid-flight. The profile is piecewise-constant acceleration evaluated
// in closed form at any instant (like sequences::MotionProfile), so step() size never changes the
// trajectory and actual_state() is exact: the IMU simulator can be driven by the table's ACTUAL
// motion. Angles are absolute (no wrapping): a target of 360 from 0 is one full turn.
//
// Status semantics:
//   enabled     drives under control; set by `enable`, cleared by a fault or e-stop.
//   homed       set when a `home` motion completes; never cleared (simulated absolute encoders).
//   moving      a profile (move, home, or deceleration after stop/fault/e-stop) is running.
//   in_position the last move/home target was reached and settle_time_s has elapsed since; cleared
//   by
//               any new motion command, stop, fault or e-stop.
//   fault       latched by a fault (injected); the axes decelerate at the acceleration limit; needs
//               clear_fault, then enable.
//   estop       e-stop circuit open; the axes decelerate at estop_decel_dps2, the drives are
//   disabled;
//               commands other than stop are rejected until it is released.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include "drivers/turntable/register_map.hpp"
#include "sequences/motion_profile.hpp"

namespace imucal::drivers::simulated {

/// Value the PLC writes to ack_result for an acted-on command.
enum class AckResult : uint16_t {
  kAccepted = 0,
  kUnknownCommand = 1,
  kNotEnabled = 2,    ///< move/home need `enable` first
  kNotHomed = 3,      ///< move needs a completed `home`
  kFaultActive = 4,   ///< enable/move/home while a fault is latched
  kEstopActive = 5,   ///< anything but stop while the e-stop is open
  kBadParameter = 6,  ///< non-finite target, or max rate <= 0 / non-finite
};

struct TablePlcConfig {
  drivers::turntable::RegisterMap map = drivers::turntable::default_register_map();
  double rate_limit_dps = 30.0;     ///< hardware rate limit; commanded rates are clipped to it
  double accel_limit_dps2 = 20.0;   ///< acceleration limit (moves, stop, fault ramp-down)
  double estop_decel_dps2 = 120.0;  ///< deceleration when the e-stop opens
  double home_rate_dps = 10.0;      ///< rate of the homing motion
  double home_outer_deg = 0.0;      ///< angles the homing motion ends at
  double home_inner_deg = 0.0;
  double settle_time_s = 0.3;        ///< standstill time before in_position is reported
  double heartbeat_period_s = 0.05;  ///< heartbeat increments once per period of PLC time
  double initial_outer_deg = 0.0;    ///< power-up angles
  double initial_inner_deg = 0.0;
  /// The encoder readings (actual angle and rate registers) lag the physical motion by this much, s
  /// (>= 0): the effects catalogue's table_time_offset. The motion itself (actual_state()) is not
  /// delayed.
  double encoder_delay_s = 0.0;
};

class TablePlc {
 public:
  explicit TablePlc(const TablePlcConfig& config = {});

  const TablePlcConfig& config() const { return cfg_; }

  /// Advances the PLC clock by dt_s >= 0: scans for a new command, moves the axes, publishes
  /// inputs.
  void step(double dt_s);
  /// PLC clock, s since construction.
  double time_s() const { return t_s_; }

  // --- register image (what a Modbus server exposes) ---
  /// Writes holding registers [address, address + count); throws std::out_of_range outside the map.
  void write_holding(uint16_t address, const uint16_t* values, size_t count);
  void read_holding(uint16_t address, size_t count, uint16_t* out) const;
  const std::vector<uint16_t>& holding_image() const { return holding_; }
  const std::vector<uint16_t>& input_image() const { return input_; }

  // --- actual motion ---
  /// Exact angles (rad), rates and accelerations at the current PLC time; at_rest = no profile
  /// running.
  sequences::TableState actual_state() const;
  /// The times strictly inside (t0_s, t1_s) where either axis' planned acceleration jumps (profile
  /// piece boundaries, and a pending fault's ramp-down), ascending: where a quadrature over the
  /// motion must be split (size effect). Exact for the plan as it stands: a command scanned later
  /// starts a new plan at its scan time (call step(0) first to act on written commands).
  std::vector<double> accel_switch_times(double t0_s, double t1_s) const;
  double outer_deg() const;
  double inner_deg() const;

  // --- status ---
  bool enabled() const { return enabled_; }
  bool homed() const { return homed_; }
  bool moving() const { return motion_ != Motion::kNone; }
  bool in_position() const { return in_position_; }
  bool fault() const { return fault_; }
  bool estop() const { return estop_; }
  uint16_t fault_code() const { return fault_code_; }
  uint16_t heartbeat() const { return heartbeat_; }
  uint16_t status_word() const;
  uint64_t commands_handled() const { return commands_handled_; }
  /// Code of the last command acted on (0 before the first) and its sequence number / result.
  uint16_t last_command() const { return last_command_; }
  uint16_t ack_seq() const { return ack_seq_; }
  AckResult ack_result() const { return static_cast<AckResult>(ack_result_); }

  // --- fault injection ---
  /// Latches a fault with `code` (non-zero) now: drives disabled, axes ramp down at the accel
  /// limit.
  void inject_fault(uint16_t code);
  /// Latches a fault with `code` `after_s` of PLC time after the next accepted move starts (a fault
  /// mid-move). Fires at that instant even if step() straddles it.
  void arm_fault_during_next_move(uint16_t code, double after_s);
  /// Opens (true) or closes (false) the e-stop circuit.
  void set_estop(bool open);
  /// Freezes the heartbeat counter (a hung PLC program) while true.
  void set_heartbeat_frozen(bool frozen) { heartbeat_frozen_ = frozen; }

  /// Duration of a rest-to-rest move of `distance_deg` at the given rate and accel limits
  /// (trapezoid or triangle): d/v + v/a if d >= v^2/a, else 2 sqrt(d/a). For tests and planners.
  static double rest_to_rest_time_s(double distance_deg, double rate_dps, double accel_dps2);

 private:
  /// One axis: piecewise-constant acceleration from (angle0, rate0) at t0.
  struct AxisProfile {
    double t0_s = 0.0;
    double angle0_deg = 0.0;
    double rate0_dps = 0.0;
    struct Piece {
      double duration_s;
      double accel_dps2;
    };
    std::vector<Piece> pieces;
    std::optional<double> final_angle_deg;  ///< exact end angle (removes round-off at the end)

    double end_s() const;
    /// Piece boundaries (t0 + cumulative durations).
    std::vector<double> boundaries() const;
    void eval(double t_s, double* angle_deg, double* rate_dps, double* accel_dps2) const;
  };
  enum class Motion { kNone, kMove, kHome, kStopping };

  static AxisProfile plan_move(double t0_s, double angle_deg, double rate_dps, double target_deg,
                               double vmax_dps, double amax_dps2);
  static AxisProfile plan_stop(double t0_s, double angle_deg, double rate_dps, double decel_dps2);

  /// Replaces both axes' profiles (a new motion from now), keeping the replaced ones while a
  /// lagging encoder still shows them.
  void replan(AxisProfile outer, AxisProfile inner);
  /// The profiles that were running at t_s (t_s <= now): the current ones or a replaced pair.
  std::pair<const AxisProfile*, const AxisProfile*> profiles_at(double t_s) const;
  void scan_commands();
  AckResult execute(uint16_t code);
  void start_motion(Motion kind, double outer_target_deg, double inner_target_deg, double rate_dps);
  void ramp_down(double decel_dps2);
  void advance_to(double t_s);
  void publish_inputs();
  float holding_float(uint16_t address) const;
  void put_float(uint16_t address, double value);

  TablePlcConfig cfg_;
  std::vector<uint16_t> holding_;
  std::vector<uint16_t> input_;
  double t_s_ = 0.0;

  AxisProfile outer_, inner_;
  /// Replaced (outer, inner) profiles, oldest first, kept only while encoder_delay_s reaches back
  /// to them: the encoder shows the motion that really happened then, not the new plan.
  std::vector<std::pair<AxisProfile, AxisProfile>> replaced_;
  Motion motion_ = Motion::kNone;
  bool settling_ = false;  ///< a move/home ended at its target; in_position after settle_time_s
  double motion_end_s_ = 0.0;

  bool enabled_ = false, homed_ = false, in_position_ = false, fault_ = false, estop_ = false;
  uint16_t fault_code_ = 0;
  uint16_t last_seq_ = 0;
  uint16_t ack_seq_ = 0;
  uint16_t ack_result_ = 0;
  uint64_t commands_handled_ = 0;
  uint16_t last_command_ = 0;

  uint16_t heartbeat_ = 0;
  bool heartbeat_frozen_ = false;
  double heartbeat_phase_s_ = 0.0;

  std::optional<std::pair<uint16_t, double>> armed_fault_;    ///< (code, delay after move start)
  std::optional<std::pair<uint16_t, double>> pending_fault_;  ///< (code, absolute PLC time)
};

}  // namespace imucal::drivers::simulated
