#include "drivers/simulated/table_plc.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <string>

namespace imucal::drivers::simulated {
namespace {
constexpr double kDegToRad = 3.14159265358979323846 / 180.0;
// Distances below this (deg) count as "already there" when planning; 1e-9 deg is far below any
// encoder resolution and far above double round-off for angles of a few turns.
constexpr double kPlanEpsDeg = 1e-9;
}  // namespace

double TablePlc::AxisProfile::end_s() const {
  double t = t0_s;
  for (const auto& p : pieces) t += p.duration_s;
  return t;
}

std::vector<double> TablePlc::AxisProfile::boundaries() const {
  std::vector<double> b;
  double t = t0_s;
  b.push_back(t);
  for (const auto& p : pieces) b.push_back(t += p.duration_s);
  return b;
}

void TablePlc::AxisProfile::eval(double t_s, double* angle_deg, double* rate_dps,
                                 double* accel_dps2) const {
  double tau = std::max(0.0, t_s - t0_s);
  double pos = angle0_deg, vel = rate0_dps, acc = 0.0;
  bool inside = false;
  for (const auto& p : pieces) {
    if (tau < p.duration_s) {  // t lies inside this piece
      pos += vel * tau + 0.5 * p.accel_dps2 * tau * tau;
      vel += p.accel_dps2 * tau;
      acc = p.accel_dps2;
      inside = true;
      break;
    }
    pos += vel * p.duration_s + 0.5 * p.accel_dps2 * p.duration_s * p.duration_s;
    vel += p.accel_dps2 * p.duration_s;
    tau -= p.duration_s;
  }
  if (!inside && !pieces.empty()) {  // profile finished: at rest at its end point
    vel = 0.0;
    if (final_angle_deg) pos = *final_angle_deg;
  }
  *angle_deg = pos;
  *rate_dps = vel;
  *accel_dps2 = acc;
}

TablePlc::AxisProfile TablePlc::plan_move(double t0_s, double angle_deg, double rate_dps,
                                          double target_deg, double vmax_dps, double amax_dps2) {
  AxisProfile pr;
  pr.t0_s = t0_s;
  pr.angle0_deg = angle_deg;
  pr.rate0_dps = rate_dps;
  pr.final_angle_deg = target_deg;
  double pos = angle_deg, vel = rate_dps;
  const double a = amax_dps2;
  auto add = [&](double dur, double acc) {
    if (!(dur > 0.0)) return;
    pr.pieces.push_back({dur, acc});
    pos += vel * dur + 0.5 * acc * dur * dur;
    vel += acc * dur;
  };
  // Each pass either finishes the plan or brings the axis to a simpler case (rate inside the limit,
  // or at rest); at most: brake below vmax -> overshoot stop -> plan from rest.
  for (int pass = 0; pass < 4; ++pass) {
    const double d = target_deg - pos;
    if (std::abs(d) <= kPlanEpsDeg && vel == 0.0) break;
    const double s = d > kPlanEpsDeg ? 1.0 : d < -kPlanEpsDeg ? -1.0 : (vel > 0.0 ? 1.0 : -1.0);
    const double u = s * vel;               // rate towards the target
    const double D = std::max(0.0, s * d);  // distance to go
    if (u < 0.0) {                          // moving away: brake to rest first
      add(-u / a, s * a);
      vel = 0.0;
      continue;
    }
    if (u > vmax_dps) {  // faster than the new limit: brake down to it
      add((u - vmax_dps) / a, -s * a);
      vel = s * vmax_dps;
      continue;
    }
    if (u * u / (2.0 * a) >
        D + kPlanEpsDeg) {  // cannot stop in time: stop past the target, come back
      add(u / a, -s * a);
      vel = 0.0;
      continue;
    }
    // Accelerate to the peak rate, (cruise,) decelerate to rest exactly at the target:
    // (vp^2 - u^2)/(2a) + vp^2/(2a) = D  =>  vp = sqrt(a D + u^2 / 2).
    const double vp = std::max(u, std::sqrt(a * D + 0.5 * u * u));
    if (vp <= vmax_dps) {
      add((vp - u) / a, s * a);
      add(vp / a, -s * a);
    } else {
      add((vmax_dps - u) / a, s * a);
      add((D - (vmax_dps * vmax_dps - u * u) / (2.0 * a) - vmax_dps * vmax_dps / (2.0 * a)) /
              vmax_dps,
          0.0);
      add(vmax_dps / a, -s * a);
    }
    break;
  }
  return pr;
}

TablePlc::AxisProfile TablePlc::plan_stop(double t0_s, double angle_deg, double rate_dps,
                                          double decel_dps2) {
  AxisProfile pr;
  pr.t0_s = t0_s;
  pr.angle0_deg = angle_deg;
  pr.rate0_dps = rate_dps;
  if (rate_dps != 0.0) {
    pr.pieces.push_back(
        {std::abs(rate_dps) / decel_dps2, rate_dps > 0.0 ? -decel_dps2 : decel_dps2});
    pr.final_angle_deg = angle_deg + rate_dps * std::abs(rate_dps) / (2.0 * decel_dps2);
  }
  return pr;
}

double TablePlc::rest_to_rest_time_s(double distance_deg, double rate_dps, double accel_dps2) {
  const double d = std::abs(distance_deg);
  if (d >= rate_dps * rate_dps / accel_dps2) return d / rate_dps + rate_dps / accel_dps2;
  return 2.0 * std::sqrt(d / accel_dps2);
}

TablePlc::TablePlc(const TablePlcConfig& config) : cfg_(config) {
  auto positive = [](double v, const char* name) {
    if (!(v > 0.0) || !std::isfinite(v))
      throw std::invalid_argument(std::string("TablePlcConfig.") + name +
                                  " must be positive and finite");
  };
  positive(cfg_.rate_limit_dps, "rate_limit_dps");
  positive(cfg_.accel_limit_dps2, "accel_limit_dps2");
  positive(cfg_.estop_decel_dps2, "estop_decel_dps2");
  positive(cfg_.home_rate_dps, "home_rate_dps");
  positive(cfg_.heartbeat_period_s, "heartbeat_period_s");
  if (!(cfg_.settle_time_s >= 0.0))
    throw std::invalid_argument("TablePlcConfig.settle_time_s must be >= 0");
  holding_.assign(cfg_.map.holding_extent(), 0);
  input_.assign(cfg_.map.input_extent(), 0);
  outer_.angle0_deg = cfg_.initial_outer_deg;
  inner_.angle0_deg = cfg_.initial_inner_deg;
  publish_inputs();
}

void TablePlc::write_holding(uint16_t address, const uint16_t* values, size_t count) {
  if (size_t(address) + count > holding_.size())
    throw std::out_of_range("TablePlc::write_holding: registers [" + std::to_string(address) +
                            ", " + std::to_string(address + count) +
                            ") outside the holding map (size " + std::to_string(holding_.size()) +
                            ")");
  std::copy(values, values + count, holding_.begin() + address);
}

void TablePlc::read_holding(uint16_t address, size_t count, uint16_t* out) const {
  if (size_t(address) + count > holding_.size())
    throw std::out_of_range("TablePlc::read_holding: registers outside the holding map");
  std::copy(holding_.begin() + address, holding_.begin() + address + count, out);
}

sequences::TableState TablePlc::actual_state() const {
  double a, r, acc;
  sequences::TableState s;
  outer_.eval(t_s_, &a, &r, &acc);
  s.outer_rad = a * kDegToRad;
  s.outer_rate_radps = r * kDegToRad;
  s.outer_accel_radps2 = acc * kDegToRad;
  inner_.eval(t_s_, &a, &r, &acc);
  s.inner_rad = a * kDegToRad;
  s.inner_rate_radps = r * kDegToRad;
  s.inner_accel_radps2 = acc * kDegToRad;
  s.at_rest = motion_ == Motion::kNone;
  return s;
}

std::vector<double> TablePlc::accel_switch_times(double t0_s, double t1_s) const {
  // A pending fault cuts the plan short: the corners after it never happen; its ramp-down's do.
  const double cut_s =
      pending_fault_ ? pending_fault_->second : std::numeric_limits<double>::infinity();
  std::vector<double> out;
  auto add_corners = [&](const AxisProfile& p, double until_s) {
    if (p.pieces.empty()) return;
    for (double b : p.boundaries())
      if (b > t0_s && b < t1_s && b <= until_s) out.push_back(b);
  };
  for (const AxisProfile* p : {&outer_, &inner_}) {
    add_corners(*p, cut_s);
    if (pending_fault_ && cut_s < t1_s) {
      double a, r, acc;
      p->eval(cut_s, &a, &r, &acc);
      add_corners(plan_stop(cut_s, a, r, cfg_.accel_limit_dps2), t1_s);
    }
  }
  if (cut_s > t0_s && cut_s < t1_s) out.push_back(cut_s);
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

double TablePlc::outer_deg() const {
  double a, r, acc;
  outer_.eval(t_s_, &a, &r, &acc);
  return a;
}

double TablePlc::inner_deg() const {
  double a, r, acc;
  inner_.eval(t_s_, &a, &r, &acc);
  return a;
}

uint16_t TablePlc::status_word() const {
  const auto& b = cfg_.map.status_bits;
  auto bit = [](bool on, uint8_t n) { return static_cast<uint16_t>(on ? (1u << n) : 0u); };
  return static_cast<uint16_t>(bit(enabled_, b.enabled) | bit(homed_, b.homed) |
                               bit(moving(), b.moving) | bit(in_position_, b.in_position) |
                               bit(fault_, b.fault) | bit(estop_, b.estop));
}

void TablePlc::step(double dt_s) {
  if (!(dt_s >= 0.0) || !std::isfinite(dt_s))
    throw std::invalid_argument("TablePlc::step: dt_s must be finite and >= 0, got " +
                                std::to_string(dt_s));
  scan_commands();
  const double t_end = t_s_ + dt_s;
  if (pending_fault_ && pending_fault_->second <= t_end) {
    advance_to(std::max(t_s_, pending_fault_->second));
    const uint16_t code = pending_fault_->first;
    pending_fault_.reset();
    inject_fault(code);
  }
  advance_to(t_end);
  if (!heartbeat_frozen_) {
    heartbeat_phase_s_ += dt_s;
    // The small tolerance keeps e.g. 25 steps of 0.04 s at a 0.1 s period at 10 ticks despite
    // round-off.
    const double ticks = std::floor(heartbeat_phase_s_ / cfg_.heartbeat_period_s + 1e-9);
    if (ticks > 0.0) {
      heartbeat_ =
          static_cast<uint16_t>(heartbeat_ + static_cast<uint64_t>(std::fmod(ticks, 65536.0)));
      heartbeat_phase_s_ = std::max(0.0, heartbeat_phase_s_ - ticks * cfg_.heartbeat_period_s);
    }
  }
  publish_inputs();
}

void TablePlc::scan_commands() {
  const uint16_t seq = holding_[cfg_.map.holding.command_seq];
  if (seq == 0 || seq == last_seq_) return;
  last_seq_ = seq;
  last_command_ = holding_[cfg_.map.holding.command];
  ack_result_ = static_cast<uint16_t>(execute(last_command_));
  ack_seq_ = seq;
  ++commands_handled_;
}

AckResult TablePlc::execute(uint16_t code) {
  const auto& c = cfg_.map.commands;
  if (code == c.stop) {  // always accepted: stop must work in every state
    if (moving()) ramp_down(cfg_.accel_limit_dps2);
    settling_ = false;
    in_position_ = false;
    pending_fault_.reset();
    return AckResult::kAccepted;
  }
  if (code != c.enable && code != c.move && code != c.home && code != c.clear_fault)
    return AckResult::kUnknownCommand;
  if (estop_) return AckResult::kEstopActive;
  if (code == c.clear_fault) {
    fault_ = false;
    fault_code_ = 0;
    return AckResult::kAccepted;
  }
  if (fault_) return AckResult::kFaultActive;
  if (code == c.enable) {
    enabled_ = true;
    return AckResult::kAccepted;
  }
  if (!enabled_) return AckResult::kNotEnabled;
  if (code == c.home) {
    start_motion(Motion::kHome, cfg_.home_outer_deg, cfg_.home_inner_deg, cfg_.home_rate_dps);
    return AckResult::kAccepted;
  }
  // move
  if (!homed_) return AckResult::kNotHomed;
  const double outer = holding_float(cfg_.map.holding.target_outer_deg);
  const double inner = holding_float(cfg_.map.holding.target_inner_deg);
  const double rate = holding_float(cfg_.map.holding.max_rate_dps);
  if (!std::isfinite(outer) || !std::isfinite(inner) || !std::isfinite(rate) || !(rate > 0.0))
    return AckResult::kBadParameter;
  start_motion(Motion::kMove, outer, inner, std::min(rate, cfg_.rate_limit_dps));
  return AckResult::kAccepted;
}

void TablePlc::start_motion(Motion kind, double outer_target_deg, double inner_target_deg,
                            double rate_dps) {
  double a_o, r_o, a_i, r_i, acc;
  outer_.eval(t_s_, &a_o, &r_o, &acc);
  inner_.eval(t_s_, &a_i, &r_i, &acc);
  replan(plan_move(t_s_, a_o, r_o, outer_target_deg, rate_dps, cfg_.accel_limit_dps2),
         plan_move(t_s_, a_i, r_i, inner_target_deg, rate_dps, cfg_.accel_limit_dps2));
  motion_ = kind;
  settling_ = false;
  in_position_ = false;
  if (kind == Motion::kMove && armed_fault_) {
    pending_fault_ = std::make_pair(armed_fault_->first, t_s_ + armed_fault_->second);
    armed_fault_.reset();
  }
}

void TablePlc::ramp_down(double decel_dps2) {
  double a_o, r_o, a_i, r_i, acc;
  outer_.eval(t_s_, &a_o, &r_o, &acc);
  inner_.eval(t_s_, &a_i, &r_i, &acc);
  replan(plan_stop(t_s_, a_o, r_o, decel_dps2), plan_stop(t_s_, a_i, r_i, decel_dps2));
  motion_ = (outer_.pieces.empty() && inner_.pieces.empty()) ? Motion::kNone : Motion::kStopping;
  settling_ = false;
  in_position_ = false;
}

void TablePlc::replan(AxisProfile outer, AxisProfile inner) {
  if (cfg_.encoder_delay_s > 0.0) replaced_.emplace_back(std::move(outer_), std::move(inner_));
  outer_ = std::move(outer);
  inner_ = std::move(inner);
}

std::pair<const TablePlc::AxisProfile*, const TablePlc::AxisProfile*> TablePlc::profiles_at(
    double t_s) const {
  // Both axes are always replanned together, so the outer profile's start dates the pair.
  if (t_s >= outer_.t0_s || replaced_.empty()) return {&outer_, &inner_};
  for (auto it = replaced_.rbegin(); it != replaced_.rend(); ++it)
    if (t_s >= it->first.t0_s) return {&it->first, &it->second};
  return {&replaced_.front().first, &replaced_.front().second};  // before it: its start state
}

void TablePlc::advance_to(double t_s) {
  t_s_ = t_s;
  if (motion_ != Motion::kNone) {
    const double end_s = std::max(outer_.end_s(), inner_.end_s());
    if (t_s_ >= end_s) {
      if (motion_ == Motion::kHome) homed_ = true;
      settling_ = motion_ == Motion::kMove || motion_ == Motion::kHome;
      motion_end_s_ = end_s;
      motion_ = Motion::kNone;
    }
  }
  in_position_ =
      settling_ && motion_ == Motion::kNone && t_s_ - motion_end_s_ >= cfg_.settle_time_s;
}

void TablePlc::inject_fault(uint16_t code) {
  if (code == 0)
    throw std::invalid_argument("TablePlc::inject_fault: fault code 0 means 'no fault'");
  fault_ = true;
  fault_code_ = code;
  enabled_ = false;
  pending_fault_.reset();
  ramp_down(cfg_.accel_limit_dps2);
  publish_inputs();
}

void TablePlc::arm_fault_during_next_move(uint16_t code, double after_s) {
  if (code == 0)
    throw std::invalid_argument(
        "TablePlc::arm_fault_during_next_move: fault code 0 means 'no fault'");
  if (!(after_s >= 0.0))
    throw std::invalid_argument("TablePlc::arm_fault_during_next_move: after_s must be >= 0");
  armed_fault_ = std::make_pair(code, after_s);
}

void TablePlc::set_estop(bool open) {
  if (open && !estop_) {
    estop_ = true;
    enabled_ = false;
    pending_fault_.reset();
    ramp_down(cfg_.estop_decel_dps2);
  } else if (!open) {
    estop_ = false;
  }
  publish_inputs();
}

float TablePlc::holding_float(uint16_t address) const {
  return drivers::turntable::decode_float(&holding_[address], cfg_.map.word_order);
}

void TablePlc::put_float(uint16_t address, double value) {
  drivers::turntable::encode_float(static_cast<float>(value), cfg_.map.word_order,
                                   &input_[address]);
}

void TablePlc::publish_inputs() {
  const auto& in = cfg_.map.input;
  double a, r, acc;
  // A lagging encoder (table_time_offset) reports the motion of encoder_delay_s ago: the profiles
  // that ran then (a replaced plan ran up to its replacement's start). Older plans are dropped.
  const double t_enc = t_s_ - cfg_.encoder_delay_s;
  size_t obsolete = 0;
  while (obsolete < replaced_.size() &&
         (obsolete + 1 < replaced_.size() ? replaced_[obsolete + 1].first.t0_s : outer_.t0_s) <=
             t_enc)
    ++obsolete;
  replaced_.erase(replaced_.begin(), replaced_.begin() + static_cast<std::ptrdiff_t>(obsolete));
  const auto [outer, inner] = profiles_at(t_enc);
  outer->eval(t_enc, &a, &r, &acc);
  put_float(in.actual_outer_deg, a);
  put_float(in.rate_outer_dps, r);
  inner->eval(t_enc, &a, &r, &acc);
  put_float(in.actual_inner_deg, a);
  put_float(in.rate_inner_dps, r);
  input_[in.status] = status_word();
  input_[in.fault_code] = fault_code_;
  input_[in.heartbeat] = heartbeat_;
  input_[in.ack_seq] = ack_seq_;
  input_[in.ack_result] = ack_result_;
}

}  // namespace imucal::drivers::simulated
