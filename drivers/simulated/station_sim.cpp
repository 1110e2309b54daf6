#include "drivers/simulated/station_sim.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "calib/sim/truth_stream.hpp"
#include "drivers/imu/can_channel.hpp"
#include "drivers/simulated/imu_can_node.hpp"

namespace imucal::drivers::simulated {

namespace {

void check_fault_probability(double p, const char* name) {
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

}  // namespace

// Outside the anonymous namespace: StationSim::Unit (declared in the header) holds one, and in a
// unity build (CMakeLists.txt) gcc warns of a member whose type has internal linkage.
namespace detail {

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
  void apply(calib::sim::TruthStream& stream) {
    if (!due_) return;
    stream.reseed_noise(noise_seed(noise_seed(seed_, homes_), motions_));
    due_ = false;
  }

 private:
  uint64_t seed_, homes_ = 0, motions_ = 0;
  bool due_ = false, was_moving_ = false;
};

}  // namespace detail

/// One unit on the fixture: its configuration, bus and CAN node, and (physics thread) its truth
/// stream, fault injector and noise restarts.
struct StationSim::Unit {
  explicit Unit(StationSimUnit c) : cfg(std::move(c)) {}
  StationSimUnit cfg;
  std::unique_ptr<drivers::imu::CanChannel> channel;
  std::unique_ptr<ImuCanNode> node;
  std::unique_ptr<calib::sim::TruthStream> stream;
  std::unique_ptr<ImuFaultInjector> fault;
  std::unique_ptr<detail::NoiseRestarts> noise;

  /// The unit's truth: its own mounting, and the slot's lever arm as the size effect of all
  /// three accelerometers (a rigid offset from the rotation centre, body axes).
  calib::sim::TruthStream make_stream(const StationSimConfig& station) const {
    calib::core::TableGeometry geometry = station.geometry;
    geometry.C_bp = cfg.C_bp;
    calib::effects::UnitModel truth = cfg.unit;
    const Eigen::Vector3d r_b = cfg.C_bp.transpose() * cfg.lever_arm_m;
    for (Eigen::Vector3d& r : truth.effects.accel_lever_arm_m) r += r_b;
    calib::sim::SimOptions o;
    o.rate_hz = station.rate_hz;
    o.seed = cfg.seed;
    o.noise = true;
    return calib::sim::TruthStream(geometry, station.site, truth, o);
  }
  /// The cable is pulled stream_cut_at_s after the first peer (the station) connected to the
  /// unit's bus: a capture that started, then lost its unit.
  bool cut(double t_s) {
    if (!cfg.stream_cut_at_s) return false;
    if (!peer_since_s && channel->counters().peers_connected > 0) peer_since_s = t_s;
    return peer_since_s && t_s > *peer_since_s + *cfg.stream_cut_at_s;
  }
  std::optional<double> peer_since_s;
};

StationSim::StationSim(StationSimConfig cfg) : cfg_(std::move(cfg)) {
  if (!(std::isfinite(cfg_.rate_hz) && cfg_.rate_hz > 0.0))
    throw std::invalid_argument("StationSimConfig.rate_hz must be positive, got " +
                                std::to_string(cfg_.rate_hz));
  if (!(std::isfinite(cfg_.speed) && cfg_.speed > 0.0))
    throw std::invalid_argument("StationSimConfig.speed must be positive, got " +
                                std::to_string(cfg_.speed));
  if (cfg_.can_path.empty()) throw std::invalid_argument("StationSimConfig.can_path is empty");
  const StationSimFaults& f = cfg_.faults;
  check_fault_probability(f.can_loss, "can_loss");
  check_fault_probability(f.can_corrupt, "can_corrupt");
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
  if (cfg_.more_units.size() > 3)
    throw std::invalid_argument("StationSimConfig.more_units: at most 3 (4 units on the fixture)");
  StationSimUnit first;
  first.can_path = cfg_.can_path;
  first.unit = cfg_.unit;
  first.seed = cfg_.seed;
  first.C_bp = cfg_.geometry.C_bp;
  first.lever_arm_m = cfg_.lever_arm_m;
  first.imu_fault = cfg_.faults.imu_fault;
  first.stream_cut_at_s = cfg_.stream_cut_at_s;
  first.protocol = cfg_.protocol;
  first.base_id = cfg_.base_id;
  units_.push_back(std::make_unique<Unit>(first));
  for (const StationSimUnit& u : cfg_.more_units) {
    if (u.can_path.empty())
      throw std::invalid_argument("StationSimConfig.more_units: a unit's can_path is empty");
    for (const auto& other : units_)
      if (other->cfg.can_path == u.can_path)
        throw std::invalid_argument("StationSimConfig.more_units: bus " + u.can_path +
                                    " is used twice");
    units_.push_back(std::make_unique<Unit>(u));
  }
  // Built here so that whatever the stream refuses is refused before anything listens (every
  // catalogue effect streams; the time offset is the PLC's, above).
  for (const auto& u : units_) {
    if (u->cfg.stream_cut_at_s) check_time(*u->cfg.stream_cut_at_s, "stream_cut_at_s");
    (void)u->make_stream(cfg_);
  }
}

StationSim::~StationSim() { stop(); }

void StationSim::start() {
  if (running_.load()) return;
  drivers::imu::CanOpenOptions can_opt;
  can_opt.listen = true;
  can_opt.write_timeout_ms = kCanWriteTimeoutMs;
  for (size_t i = 0; i < units_.size(); ++i) {
    Unit& u = *units_[i];
    u.channel = drivers::imu::CanChannel::open(can_uri(i), can_opt);  // throws naming the path
    ImuCanNodeOptions node_opt;
    node_opt.rate_hz = cfg_.rate_hz;
    node_opt.speed_factor = 0.0;  // the physics thread paces
    node_opt.frame_loss_probability = cfg_.faults.can_loss;
    node_opt.corruption_probability = cfg_.faults.can_corrupt;
    if (i == 0) node_opt.reset_at_s = cfg_.faults.imu_reset_at_s;
    node_opt.seed = u.cfg.seed ^ 0x9e3779b97f4a7c15ULL;  // independent of the sensor noise stream
    node_opt.protocol = u.cfg.protocol;
    node_opt.base_id = u.cfg.base_id;
    u.node = std::make_unique<ImuCanNode>(*u.channel, node_opt);
  }

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
  // The nodes stay until destruction so stats() remains valid; the bus sockets are closed here so
  // that peers see the end.
  for (const auto& u : units_) u->channel.reset();
}

int StationSim::modbus_port() const { return server_ ? server_->port() : 0; }

std::string StationSim::modbus_endpoint() const {
  return "tcp:" + cfg_.modbus.address + ":" + std::to_string(modbus_port());
}

std::string StationSim::can_uri() const { return "unixcan:" + cfg_.can_path; }

std::string StationSim::can_uri(size_t unit) const {
  return "unixcan:" + units_.at(unit)->cfg.can_path;
}

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
  const ImuCanNodeStats& ns = units_.front()->node->stats();
  std::lock_guard<std::mutex> lock(mu_);
  node_stats_.samples_sent = ns.samples_transmitted;
  node_stats_.frames_sent = ns.frames_sent;
  node_stats_.frames_lost = ns.frames_lost;
  node_stats_.frames_corrupted = ns.frames_corrupted;
  node_stats_.frames_refused = ns.frames_refused + units_.front()->channel->counters().tx_overflow;
  node_stats_.imu_resets = ns.resets;
  node_stats_.sim_time_s = t_s;
  wall_elapsed_s_ = wall_elapsed_s;
}

std::vector<size_t> StationSim::prepare_units() {
  for (const auto& u : units_) {
    u->stream = std::make_unique<calib::sim::TruthStream>(u->make_stream(cfg_));
    u->fault = std::make_unique<ImuFaultInjector>(u->cfg.imu_fault);
    u->noise = std::make_unique<detail::NoiseRestarts>(u->cfg.seed);
  }
  // The units whose quadrature samples the table inside an interval go first: the PLC only steps
  // forward, and the others then read the states they asked for (same interval, same nodes).
  std::vector<size_t> order(units_.size());
  for (size_t i = 0; i < order.size(); ++i) order[i] = i;
  std::stable_sort(order.begin(), order.end(), [&](size_t a, size_t b) {
    return units_[a]->stream->needs_interior_states() &&
           !units_[b]->stream->needs_interior_states();
  });
  return order;
}

void StationSim::wait_for_peers(std::vector<drivers::imu::ReceivedFrame>& scratch) {
  auto all_connected = [&] {
    for (const auto& u : units_)
      if (u->channel->counters().peers_connected == 0) return false;
    return true;
  };
  while (!stop_.load() && !all_connected()) {
    for (const auto& u : units_) u->channel->read(scratch);  // accepts peers
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  }
}

void StationSim::run() {
  const std::vector<size_t> order = prepare_units();
  auto interior = [&](size_t i) { return units_[i]->stream->needs_interior_states(); };
  const bool any_interior = interior(order.front());
  calib::sim::TruthStream& clock_stream = *units_.front()->stream;  // every unit has the same rate
  const uint16_t move_code = cfg_.plc.map.commands.move;
  const uint16_t home_code = cfg_.plc.map.commands.home;

  ModbusFaultSchedule modbus_faults(cfg_.faults);
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
        for (const auto& u : units_) u->noise->home_accepted();
    }
  };

  std::vector<drivers::imu::ReceivedFrame> from_peers;
  // The table states this interval's streams asked for, in time order (the next units read them).
  std::vector<std::pair<double, sequences::TableState>> states;
  try {
    if (cfg_.wait_for_can_peer) wait_for_peers(from_peers);
    clock_ = std::make_unique<ScaledRealTime>(cfg_.speed);
    const ScaledRealTime& clock = *clock_;
    server_->with_plc([&](TablePlc& plc) { arm_if_due(plc); });
    std::vector<calib::core::ImuIncrement> incs(units_.size());
    while (!stop_.load()) {
      const double t_next = clock_stream.next_time_s();
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
      server_->with_plc([&](TablePlc& plc) {
        // Commands written over Modbus since the last sample are acted on at the interval start (a
        // PLC scan), so the motion they start is planned before its acceleration jumps are asked
        // for: the size effect's quadrature is split exactly there (ARCHITECTURE §7).
        advance(plc, clock_stream.interval_start_s());
        const std::vector<double> breaks =
            any_interior ? plc.accel_switch_times(clock_stream.interval_start_s(), t_next)
                         : std::vector<double>{};
        auto state_at = [&](double t) {
          for (auto it = states.rbegin(); it != states.rend(); ++it)
            if (it->first == t) return it->second;
          advance(plc, t);
          states.emplace_back(t, plc.actual_state());
          return states.back().second;
        };
        if (states.size() > 1) states.erase(states.begin(), states.end() - 1);  // keep t_{k-1}
        for (size_t i : order)
          incs[i] = interior(i) ? units_[i]->stream->next(state_at, breaks)
                                : units_[i]->stream->next(state_at);
        for (const auto& u : units_) u->noise->sample_done(plc.moving());
      });
      for (const auto& u : units_) u->noise->apply(*u->stream);
      if (reset_requested_.exchange(false)) units_.front()->node->reset();
      if (clock_stream.samples() % 16 == 0) {
        // A bus: what other nodes send reaches the other peers (the listener forwards on read).
        for (const auto& u : units_) {
          from_peers.clear();
          u->channel->read(from_peers);
        }
      }
      // Outside the PLC lock: a slow CAN reader must not block Modbus replies.
      for (size_t i = 0; i < units_.size(); ++i) {
        Unit& u = *units_[i];
        const uint16_t fault_flags = u.fault->apply(incs[i]);
        if (!u.cut(incs[i].t_s)) u.node->send(incs[i], fault_flags);
      }
      record_sample_sent(incs[0].t_s, clock() / cfg_.speed);
    }
  } catch (const std::exception& e) {
    std::lock_guard<std::mutex> lock(mu_);
    error_ = e.what();
  }
}

}  // namespace imucal::drivers::simulated
