#include "drivers/sim/station_sim.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "calib/sim/truth_stream.hpp"
#include "drivers/imu/can_channel.hpp"
#include "drivers/sim/imu_can_node.hpp"

namespace imucal::sim {

namespace {

void check_probability(double p, const char* name) {
  if (!(p >= 0.0 && p <= 1.0))
    throw std::invalid_argument(std::string("StationSimConfig.faults.") + name +
                                " must be in [0, 1], got " + std::to_string(p));
}

void check_time(double t, const char* name) {
  if (!(std::isfinite(t) && t >= 0.0))
    throw std::invalid_argument(std::string("StationSimConfig.faults.") + name +
                                ": sim time must be finite and >= 0, got " + std::to_string(t));
}

/// How long a CAN write may wait for a slow reader before the frames count as refused: long enough
/// that a live consumer never loses frames (back-pressure slows the simulator instead), short
/// enough that a hung one cannot stall the table for long.
constexpr int kCanWriteTimeoutMs = 500;

/// A noise seed derived from (seed, n): splitmix64, so that the streams of neighbouring seeds and
/// counts are unrelated.
uint64_t noise_seed(uint64_t seed, uint64_t n) {
  uint64_t z = seed + 0x9e3779b97f4a7c15ULL * (n + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

/// The scheduled Modbus faults (dropped connections, delayed replies), applied by physics time.
class ModbusFaultSchedule {
 public:
  explicit ModbusFaultSchedule(const StationSimFaults& f)
      : drops_(f.modbus_drop_at_s), delays_(f.modbus_delay) {
    std::sort(drops_.begin(), drops_.end());
    std::sort(delays_.begin(), delays_.end(),
              [](const auto& a, const auto& b) { return a.at_s < b.at_s; });
  }
  /// Applies every fault due by t_s; returns the connections dropped.
  uint64_t apply_due(double t_s, ModbusTableServer& server) {
    uint64_t dropped = 0;
    for (; next_drop_ < drops_.size() && drops_[next_drop_] <= t_s; ++next_drop_, ++dropped)
      server.drop_clients();
    for (; next_delay_ < delays_.size() && delays_[next_delay_].at_s <= t_s; ++next_delay_)
      server.delay_replies(std::chrono::milliseconds(delays_[next_delay_].delay_ms),
                           delays_[next_delay_].count);
    return dropped;
  }

 private:
  std::vector<double> drops_;
  std::vector<StationSimFaults::Delay> delays_;
  size_t next_drop_ = 0, next_delay_ = 0;
};

/// When the sensor noise restarts: from a stream of its own at each accepted home command (a
/// station starts every run with one) and at the end of each motion after it — stream (seed, homes,
/// motions ended since the home). A run's noise then does not depend on how long the station idled
/// before it, nor each rest's on how long the daemon took to command the moves before it: both are
/// wall-clock latencies times the speed factor (issue #28: on a slow machine the soak's third run
/// always read the same unlucky stretch of one continuous stream). Left: the daemon's latency
/// between a motion's end and the start of its rest count, a second or two of sim time at 400x.
class NoiseRestarts {
 public:
  explicit NoiseRestarts(uint64_t seed) : seed_(seed) {}
  void home_accepted() {
    ++homes_;
    motions_ = 0;
    due_ = true;
  }
  /// After each sample, with whether the table is moving at its end.
  void sample_done(bool moving) {
    if (was_moving_ && !moving) {  // the motion ended inside this sample
      ++motions_;
      due_ = true;
    }
    was_moving_ = moving;
  }
  /// Restarts the stream's noise if due (from the next sample on).
  void apply(calib::TruthStream& stream) {
    if (!due_) return;
    stream.reseed_noise(noise_seed(noise_seed(seed_, homes_), motions_));
    due_ = false;
  }

 private:
  uint64_t seed_, homes_ = 0, motions_ = 0;
  bool due_ = false, was_moving_ = false;
};

}  // namespace

StationSim::StationSim(StationSimConfig cfg) : cfg_(std::move(cfg)) {
  if (!(std::isfinite(cfg_.rate_hz) && cfg_.rate_hz > 0.0))
    throw std::invalid_argument("StationSimConfig.rate_hz must be positive, got " +
                                std::to_string(cfg_.rate_hz));
  if (!(std::isfinite(cfg_.speed) && cfg_.speed > 0.0))
    throw std::invalid_argument("StationSimConfig.speed must be positive, got " +
                                std::to_string(cfg_.speed));
  if (cfg_.can_path.empty()) throw std::invalid_argument("StationSimConfig.can_path is empty");
  const StationSimFaults& f = cfg_.faults;
  check_probability(f.can_loss, "can_loss");
  check_probability(f.can_corrupt, "can_corrupt");
  for (double t : f.imu_reset_at_s) check_time(t, "imu_reset_at_s");
  for (double t : f.modbus_drop_at_s) check_time(t, "modbus_drop_at_s");
  for (const auto& d : f.modbus_delay) {
    check_time(d.at_s, "modbus_delay.at_s");
    if (d.delay_ms < 0 || d.count < 1)
      throw std::invalid_argument(
          "StationSimConfig.faults.modbus_delay: delay_ms must be >= 0 and count >= 1");
  }
  if (f.table_fault) {
    if (f.table_fault->move_number < 1)
      throw std::invalid_argument(
          "StationSimConfig.faults.table_fault.move_number must be >= 1 (1-based)");
    if (!(std::isfinite(f.table_fault->after_s) && f.table_fault->after_s >= 0.0))
      throw std::invalid_argument("StationSimConfig.faults.table_fault.after_s must be >= 0");
    if (f.table_fault->code == 0)
      throw std::invalid_argument(
          "StationSimConfig.faults.table_fault.code must be non-zero (0 = no fault)");
  }
  // table_time_offset: the PLC's encoder registers lag the motion
  // (TablePlcConfig::encoder_delay_s); an encoder that leads the motion cannot be simulated by a
  // PLC that only knows the present.
  if (cfg_.unit.effects.table_time_offset_s < 0.0)
    throw std::invalid_argument(
        "StationSimConfig.unit.effects: table_time_offset must be >= 0 in the station simulator "
        "(the "
        "PLC's encoder can lag the motion, not lead it)");
  cfg_.plc.encoder_delay_s = cfg_.unit.effects.table_time_offset_s;
  // Built here so that whatever the stream refuses is refused before anything listens (every
  // catalogue effect streams; the time offset is the PLC's, above).
  calib::SimOptions o;
  o.rate_hz = cfg_.rate_hz;
  o.seed = cfg_.seed;
  calib::TruthStream check(cfg_.geometry, cfg_.site, cfg_.unit, o);
  (void)check;
}

StationSim::~StationSim() { stop(); }

void StationSim::start() {
  if (running_.load()) return;
  imu::CanOpenOptions can_opt;
  can_opt.listen = true;
  can_opt.write_timeout_ms = kCanWriteTimeoutMs;
  channel_ = imu::CanChannel::open(can_uri(), can_opt);  // throws naming the path

  ImuCanNodeOptions node_opt;
  node_opt.rate_hz = cfg_.rate_hz;
  node_opt.speed_factor = 0.0;  // the physics thread paces
  node_opt.frame_loss_probability = cfg_.faults.can_loss;
  node_opt.corruption_probability = cfg_.faults.can_corrupt;
  node_opt.reset_at_s = cfg_.faults.imu_reset_at_s;
  node_opt.seed = cfg_.seed ^ 0x9e3779b97f4a7c15ULL;  // independent of the sensor noise stream
  node_opt.protocol = cfg_.protocol;
  node_opt.base_id = cfg_.base_id;
  node_ = std::make_unique<ImuCanNode>(*channel_, node_opt);

  // No TimeSource: the physics thread is the only one that advances the PLC.
  server_ = std::make_unique<ModbusTableServer>(cfg_.plc, cfg_.modbus);
  server_->start();  // throws naming the address

  stop_.store(false);
  running_.store(true);
  thread_ = std::thread([this] { run(); });
}

void StationSim::stop() {
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
  if (server_) server_->stop();
  running_.store(false);
  // The channel and node stay until destruction so stats() remains valid; the bus socket is closed
  // here so that peers see the end.
  channel_.reset();
}

int StationSim::modbus_port() const { return server_ ? server_->port() : 0; }

std::string StationSim::modbus_endpoint() const {
  return "tcp:" + cfg_.modbus.address + ":" + std::to_string(modbus_port());
}

std::string StationSim::can_uri() const { return "unixcan:" + cfg_.can_path; }

double StationSim::time_s() const { return sim_time_s_.load(); }

ModbusTableServer& StationSim::table_server() {
  if (!server_) throw std::logic_error("StationSim::table_server: not started");
  return *server_;
}

void StationSim::inject_imu_reset() { reset_requested_.store(true); }

std::string StationSim::error() const {
  std::lock_guard<std::mutex> lock(mu_);
  return error_;
}

StationSimStats StationSim::stats() const {
  StationSimStats s{};
  {
    std::lock_guard<std::mutex> lock(mu_);
    s.samples_sent = node_stats_.samples_sent;
    s.frames_sent = node_stats_.frames_sent;
    s.frames_lost = node_stats_.frames_lost;
    s.frames_corrupted = node_stats_.frames_corrupted;
    s.frames_refused = node_stats_.frames_refused;
    s.imu_resets = node_stats_.imu_resets;
    s.achieved_speed = wall_elapsed_s_ > 0.0 ? node_stats_.sim_time_s / wall_elapsed_s_ : 0.0;
  }
  s.sim_time_s = time_s();
  s.modbus_drops = modbus_drops_.load();
  s.modbus_requests = server_ ? server_->stats().requests : 0;
  return s;
}

void StationSim::record_sample_sent(double t_s, double wall_elapsed_s) {
  sim_time_s_.store(t_s);
  const ImuCanNodeStats& ns = node_->stats();
  std::lock_guard<std::mutex> lock(mu_);
  node_stats_.samples_sent = ns.samples_transmitted;
  node_stats_.frames_sent = ns.frames_sent;
  node_stats_.frames_lost = ns.frames_lost;
  node_stats_.frames_corrupted = ns.frames_corrupted;
  node_stats_.frames_refused = ns.frames_refused + channel_->counters().tx_overflow;
  node_stats_.imu_resets = ns.resets;
  node_stats_.sim_time_s = t_s;
  wall_elapsed_s_ = wall_elapsed_s;
}

void StationSim::run() {
  calib::SimOptions o;
  o.rate_hz = cfg_.rate_hz;
  o.seed = cfg_.seed;
  o.noise = true;
  calib::TruthStream stream(cfg_.geometry, cfg_.site, cfg_.unit, o);
  const uint16_t move_code = cfg_.plc.map.commands.move;
  const uint16_t home_code = cfg_.plc.map.commands.home;
  NoiseRestarts noise_restarts(cfg_.seed);

  ModbusFaultSchedule modbus_faults(cfg_.faults);
  ImuFaultInjector fault(cfg_.faults.imu_fault);
  const auto& table_fault = cfg_.faults.table_fault;
  bool fault_armed = false;
  uint64_t commands_seen = 0;

  // Arms the table fault on the PLC once move_number - 1 moves were accepted, so that the PLC's
  // own "next accepted move" is the right one. mu_ of the server held (inside with_plc).
  auto arm_if_due = [&](TablePlc& plc) {
    if (table_fault && !fault_armed &&
        moves_accepted_.load() + 1 == static_cast<uint64_t>(table_fault->move_number)) {
      plc.arm_fault_during_next_move(table_fault->code, table_fault->after_s);
      fault_armed = true;
    }
  };
  // Steps the PLC forward to t and counts the move commands it accepted on the way.
  auto advance = [&](TablePlc& plc, double t) {
    plc.step(std::max(0.0, t - plc.time_s()));
    if (plc.commands_handled() != commands_seen) {
      commands_seen = plc.commands_handled();
      if (plc.last_command() == move_code && plc.ack_result() == AckResult::kAccepted) {
        moves_accepted_.fetch_add(1);
        arm_if_due(plc);
      }
      if (plc.last_command() == home_code && plc.ack_result() == AckResult::kAccepted)
        noise_restarts.home_accepted();
    }
  };

  std::vector<imu::ReceivedFrame> from_peers;
  try {
    if (cfg_.wait_for_can_peer) {
      while (!stop_.load() && channel_->counters().peers_connected == 0) {
        channel_->read(from_peers);  // accepts peers
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
      }
    }
    clock_ = std::make_unique<ScaledRealTime>(cfg_.speed);
    const ScaledRealTime& clock = *clock_;
    server_->with_plc([&](TablePlc& plc) { arm_if_due(plc); });
    while (!stop_.load()) {
      const double t_next = stream.next_time_s();
      // Sample k is due when the physics clock reaches its end time. Behind the clock: no sleep
      // (catch up, never skip).
      const double now = clock();
      if (t_next > now) {
        // Short sleeps keep stop() responsive even at a slow speed factor.
        const double wait_s = std::min((t_next - now) / cfg_.speed, 0.02);
        std::this_thread::sleep_for(std::chrono::duration<double>(wait_s));
        continue;
      }
      modbus_drops_.fetch_add(modbus_faults.apply_due(t_next, *server_));
      calib::ImuIncrement inc;
      server_->with_plc([&](TablePlc& plc) {
        // Commands written over Modbus since the last sample are acted on at the interval start (a
        // PLC scan), so the motion they start is planned before its acceleration jumps are asked
        // for: the size effect's quadrature is split exactly there (DESIGN §7).
        advance(plc, stream.interval_start_s());
        const std::vector<double> breaks =
            stream.needs_interior_states()
                ? plc.accel_switch_times(stream.interval_start_s(), stream.next_time_s())
                : std::vector<double>{};
        inc = stream.next(
            [&](double t) {
              advance(plc, t);
              return plc.actual_state();
            },
            breaks);
        noise_restarts.sample_done(plc.moving());
      });
      noise_restarts.apply(stream);
      if (reset_requested_.exchange(false)) node_->reset();
      if (stream.samples() % 16 == 0) {
        // A bus: what other nodes send reaches the other peers (the listener forwards on read).
        from_peers.clear();
        channel_->read(from_peers);
      }
      const uint16_t fault_flags = fault.apply(inc);
      node_->send(
          inc,
          fault_flags);  // outside the PLC lock: a slow CAN reader must not block Modbus replies
      record_sample_sent(inc.t_s, clock() / cfg_.speed);
    }
  } catch (const std::exception& e) {
    std::lock_guard<std::mutex> lock(mu_);
    error_ = e.what();
  }
}

}  // namespace imucal::sim
