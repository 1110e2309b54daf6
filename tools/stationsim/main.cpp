// stationsim: the simulated station hardware (turntable PLC on Modbus TCP + IMU on a unixcan bus)
// in one process with one physics clock (ARCHITECTURE §4; docs/integrator.md, "Commissioning with
// the simulator"); run `stationsim --help`. Exit codes: 0 clean exit (SIGTERM/SIGINT, --duration-s
// reached), 1 runtime failure (cannot listen, the physics thread failed), 2 bad input (flag or unit
// file).
#include <signal.h>
#include <spdlog/sinks/stdout_color_sinks.h>
#include <spdlog/spdlog.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "calib/core/conventions.hpp"
#include "calib/core/earth.hpp"
#include "calib/core/rotation.hpp"
#include "calib/core/site_presets.hpp"
#include "calib/effects/catalogue.hpp"
#include "db/archive/unit_file.hpp"
#include "drivers/imu/imu_codec.hpp"
#include "drivers/simulated/station_sim.hpp"

namespace {

using imucal::drivers::simulated::StationSim;
using imucal::drivers::simulated::StationSimConfig;
using imucal::drivers::simulated::StationSimFaults;
using imucal::drivers::simulated::StationSimStats;
using imucal::drivers::simulated::StationSimUnit;

/// Bad command-line input: exit 2 with this one-line message.
struct BadInput : std::runtime_error {
  using std::runtime_error::runtime_error;
};

std::vector<std::string> split(const std::string& s, char sep) {
  std::vector<std::string> parts;
  std::string cur;
  std::istringstream in(s);
  while (std::getline(in, cur, sep)) parts.push_back(cur);
  if (!s.empty() && s.back() == sep) parts.emplace_back();
  return parts;
}

double to_double(const std::string& text, const std::string& flag) {
  try {
    size_t used = 0;
    const double v = std::stod(text, &used);
    if (used == text.size() && std::isfinite(v)) return v;
  } catch (const std::exception&) {
  }
  throw BadInput(flag + ": '" + text + "' is not a number");
}

long to_int(const std::string& text, const std::string& flag, long lo, long hi) {
  try {
    size_t used = 0;
    const long v = std::stol(text, &used);
    if (used == text.size() && v >= lo && v <= hi) return v;
  } catch (const std::exception&) {
  }
  throw BadInput(flag + ": '" + text + "' is not an integer in [" + std::to_string(lo) + ", " +
                 std::to_string(hi) + "]");
}

void parse_modbus(const std::string& text, StationSimConfig& cfg) {
  const auto colon = text.rfind(':');
  if (colon == std::string::npos || colon == 0)
    throw BadInput("--modbus: '" + text + "' is not ADDR:PORT");
  cfg.modbus.address = text.substr(0, colon);
  cfg.modbus.port = static_cast<int>(to_int(text.substr(colon + 1), "--modbus port", 0, 65535));
}

StationSimFaults::Delay parse_delay(const std::string& text) {
  const auto p = split(text, ':');
  if (p.size() != 3) throw BadInput("--modbus-delay-at: '" + text + "' is not T:MS:COUNT");
  StationSimFaults::Delay d{};
  d.at_s = to_double(p[0], "--modbus-delay-at T");
  d.delay_ms = static_cast<int>(to_int(p[1], "--modbus-delay-at MS", 0, 3'600'000));
  d.count = static_cast<int>(to_int(p[2], "--modbus-delay-at COUNT", 1, 1'000'000));
  if (d.at_s < 0) throw BadInput("--modbus-delay-at: T must be >= 0, got '" + p[0] + "'");
  return d;
}

StationSimFaults::TableFault parse_table_fault(const std::string& text) {
  const auto p = split(text, ':');
  if (p.empty() || p.size() > 3)
    throw BadInput("--table-fault-move: '" + text + "' is not N[:AFTER_S[:CODE]]");
  StationSimFaults::TableFault f{};
  f.move_number = static_cast<int>(to_int(p[0], "--table-fault-move N", 1, 1'000'000));
  f.after_s = p.size() > 1 ? to_double(p[1], "--table-fault-move AFTER_S") : 1.0;
  f.code =
      static_cast<uint16_t>(p.size() > 2 ? to_int(p[2], "--table-fault-move CODE", 1, 65535) : 17);
  if (f.after_s < 0) throw BadInput("--table-fault-move: AFTER_S must be >= 0, got '" + p[1] + "'");
  return f;
}

/// Writes `text` to `path` atomically: a reader sees the old file, no file, or all of the new one.
void write_atomically(const std::string& path, const std::string& text) {
  const std::string tmp = path + ".tmp." + std::to_string(::getpid());
  {
    std::ofstream f(tmp, std::ios::trunc);
    if (!f) throw std::runtime_error("cannot write " + tmp + ": " + std::strerror(errno));
    f << text;
    f.flush();
    if (!f) throw std::runtime_error("cannot write " + tmp);
  }
  if (std::rename(tmp.c_str(), path.c_str()) != 0) {
    const std::string why = std::strerror(errno);
    std::remove(tmp.c_str());
    throw std::runtime_error("cannot rename " + tmp + " to " + path + ": " + why);
  }
}

nlohmann::json stats_json(const StationSimStats& s) {
  return {{"sim_time_s", s.sim_time_s},
          {"samples_sent", s.samples_sent},
          {"frames_sent", s.frames_sent},
          {"frames_lost", s.frames_lost},
          {"frames_corrupted", s.frames_corrupted},
          {"frames_refused", s.frames_refused},
          {"imu_resets", s.imu_resets},
          {"modbus_drops", s.modbus_drops},
          {"modbus_requests", s.modbus_requests},
          {"achieved_speed", s.achieved_speed}};
}

void print_status(const StationSimStats& s) {
  std::fprintf(
      stderr,
      "stationsim: t=%.1f s sim, speed %.1fx, samples %llu, frames %llu (lost %llu, corrupted "
      "%llu), modbus requests %llu\n",
      s.sim_time_s, s.achieved_speed, static_cast<unsigned long long>(s.samples_sent),
      static_cast<unsigned long long>(s.frames_sent),
      static_cast<unsigned long long>(s.frames_lost),
      static_cast<unsigned long long>(s.frames_corrupted),
      static_cast<unsigned long long>(s.modbus_requests));
}

}  // namespace

namespace {

/// The command line, as given (checked by config_from).
struct CliArgs {
  std::string modbus = "127.0.0.1:1502", can_path, unit_path, truth_out, ready_file, stats_file;
  double speed = 100.0, rate_hz = 100.0, duration_s = -1.0;
  uint64_t seed = 1;
  double lat_deg = 0.0, lon_deg = 0.0, height_m = 0.0;
  double gravity = std::nan("");
  double can_loss = 0.0, can_corrupt = 0.0;
  std::vector<double> reset_at, drop_at;
  std::vector<std::string> delay_at, effect_specs;
  std::string table_fault, imu_fault, protocol;
  int64_t base_id = -1;
  bool wait_for_can_peer = false;
  std::string mount, lever_arm;   ///< the first unit's slot: R/P/Y deg, X/Y/Z m
  double cut_stream_at = -1.0;    ///< the first unit's frames stop at this sim time (< 0: never)
  std::vector<std::string> also;  ///< more units on the fixture (--also SPEC)
};

void add_options(CLI::App& app, CliArgs& a) {
  const imucal::calib::core::Site demo = imucal::calib::core::demo_factory_site();
  a.lat_deg = demo.lat_rad / imucal::kDegToRad;
  a.lon_deg = demo.lon_rad / imucal::kDegToRad;
  a.height_m = demo.height_m;
  app.set_version_flag("--version", std::string(IMUCAL_VERSION));
  app.add_option("--modbus", a.modbus,
                 "Modbus TCP listen address ADDR:PORT (port 0 = a free port)");
  app.add_option("--can", a.can_path, "unixcan bus socket path (the simulator is the bus)")
      ->required();
  app.add_option("--unit", a.unit_path, "unit file (db/archive format); default: the default unit");
  app.add_option(
         "--effect", a.effect_specs,
         "inject a catalogue effect, NAME=V[,V...] in SI (repeatable; imucal effects lists them)")
      ->take_all();
  app.add_option("--protocol", a.protocol,
                 "the IMU's CAN protocol file (drivers/imu/PROTOCOL.md); default: the built-in "
                 "protocol");
  app.add_option("--base-id", a.base_id,
                 "move the protocol's CAN ids so that the lowest is this one (default: as in its "
                 "DBC file)");
  app.add_option("--speed", a.speed, "sim seconds per wall second");
  app.add_option("--rate-hz", a.rate_hz, "IMU sample rate");
  app.add_option("--seed", a.seed, "random seed (noise, CAN faults)");
  app.add_option("--lat-deg", a.lat_deg, "site latitude, deg");
  app.add_option("--lon-deg", a.lon_deg, "site longitude, deg");
  app.add_option("--height-m", a.height_m, "site height, m");
  app.add_option("--gravity-mps2", a.gravity,
                 "surveyed gravity, m/s^2 (default: normal gravity at the site)");
  app.add_option("--can-loss", a.can_loss, "per-frame CAN loss probability");
  app.add_option("--can-corrupt", a.can_corrupt, "per-frame CAN corruption probability");
  app.add_option("--imu-reset-at", a.reset_at, "IMU reset at this sim time, s (repeatable)");
  app.add_option("--modbus-drop-at", a.drop_at,
                 "drop every Modbus connection at this sim time, s (repeatable)");
  app.add_option("--modbus-delay-at", a.delay_at,
                 "T:MS:COUNT: from sim time T hold back COUNT replies by MS ms");
  app.add_option("--table-fault-move", a.table_fault,
                 "N[:AFTER_S[:CODE]]: table fault AFTER_S (1.0) into accepted "
                 "move N, fault code CODE (17)");
  app.add_option("--imu-fault", a.imu_fault,
                 "a broken or wrongly mounted unit: stuck:CH, swap:gyro-xy, flip:CH, not-on-table, "
                 "fixture-rot90, saturate:DPS (CH: gyro-x .. accel-z)");
  app.add_option("--truth-out", a.truth_out, "write the unit's truth.json here");
  app.add_option("--ready-file", a.ready_file,
                 "write {pid, modbus, can, speed} JSON here once listening");
  app.add_option("--stats-file", a.stats_file, "write the final statistics JSON here on exit");
  app.add_option("--duration-s", a.duration_s,
                 "exit after this much sim time (default: run until signalled)");
  app.add_option("--mount", a.mount,
                 "R/P/Y: the unit's slot frame against the platform, ZYX Euler angles in deg");
  app.add_option("--lever-arm", a.lever_arm,
                 "X/Y/Z: the unit's centre from the rotation centre, platform axes, m");
  app.add_option("--cut-stream-at", a.cut_stream_at,
                 "the unit's CAN frames stop this long (sim s) after the station first connected "
                 "to its bus (a cable pulled mid-capture)");
  app.add_option("--also", a.also,
                 "another unit on the fixture (up to 3, repeatable): CAN_PATH[,unit=FILE]"
                 "[,truth=FILE][,seed=N][,effect=NAME=V/V...][,mount=R/P/Y][,lever=X/Y/Z]"
                 "[,cut=T] — its own bus, unit, noise seed (default --seed + its number), "
                 "catalogue effect, mounting and stream cut; the same rate and table");
  app.add_flag("--wait-for-can-peer", a.wait_for_can_peer,
               "start the physics clock when the first CAN peer connects (benchmarks, tests)");
}

/// The unit file and the catalogue effects on top of it (withheld from the station).
/// A unit file (none: the default unit) with catalogue effects on top of it; errors name the
/// option (`flag` for the file, `effect_flag` for an effect) and the file.
imucal::calib::effects::UnitModel load_unit(const std::string& path,
                                            const std::vector<std::string>& effects,
                                            const std::string& flag,
                                            const std::string& effect_flag) {
  imucal::calib::effects::UnitModel unit = imucal::calib::effects::default_unit();
  if (!path.empty()) {
    try {
      unit = imucal::db::archive::read_unit_file(path);
    } catch (const std::exception& e) {
      const std::string what = e.what();
      // The archive reader names the file and line; make sure the file is named either way.
      throw BadInput(flag + ": " + (what.find(path) == std::string::npos ? path + ": " : "") +
                     what);
    }
  }
  for (const std::string& spec : effects) {
    try {
      imucal::calib::effects::apply_effect_spec(unit.effects, spec);
    } catch (const std::exception& e) {
      throw BadInput(effect_flag + " " + spec + ": " + e.what());
    }
  }
  return unit;
}

void apply_unit(const CliArgs& a, StationSimConfig& cfg) {
  cfg.unit = load_unit(a.unit_path, a.effect_specs, "--unit", "--effect");
}

/// Speed, rate, seed and the site (gravity: surveyed, or normal gravity at the site).
void apply_clock_and_site(const CliArgs& a, StationSimConfig& cfg) {
  if (!(a.speed > 0.0 && std::isfinite(a.speed))) throw BadInput("--speed: must be > 0");
  if (!(a.rate_hz > 0.0 && std::isfinite(a.rate_hz))) throw BadInput("--rate-hz: must be > 0");
  if (!(std::abs(a.lat_deg) <= 90.0)) throw BadInput("--lat-deg: must be in [-90, 90]");
  if (!(std::abs(a.lon_deg) <= 360.0)) throw BadInput("--lon-deg: must be in [-360, 360]");
  if (!std::isfinite(a.height_m)) throw BadInput("--height-m: must be finite");
  cfg.speed = a.speed;
  cfg.rate_hz = a.rate_hz;
  cfg.seed = a.seed;
  cfg.wait_for_can_peer = a.wait_for_can_peer;
  try {
    if (!a.protocol.empty())
      cfg.protocol = std::make_shared<const imucal::drivers::imu::ImuProtocolMap>(
          imucal::drivers::imu::read_protocol_map(a.protocol));
    if (a.base_id >= 0) cfg.base_id = static_cast<uint32_t>(a.base_id);
    cfg.protocol = imucal::drivers::imu::resolve_protocol(cfg.protocol, cfg.base_id);
  } catch (const std::invalid_argument& e) {
    throw BadInput(std::string(a.protocol.empty() ? "--base-id" : "--protocol") + ": " + e.what());
  }
  cfg.site.lat_rad = a.lat_deg * imucal::kDegToRad;
  cfg.site.lon_rad = a.lon_deg * imucal::kDegToRad;
  cfg.site.height_m = a.height_m;
  if (std::isnan(a.gravity)) {
    cfg.site.gravity_mps2 =
        imucal::calib::core::EarthModel::normal_gravity_mps2(cfg.site.lat_rad, a.height_m);
  } else {
    if (!(a.gravity > 9.7 && a.gravity < 9.9))
      throw BadInput("--gravity-mps2: must be in (9.7, 9.9)");
    cfg.site.gravity_mps2 = a.gravity;
  }
}

/// The injected faults: CAN loss and corruption, IMU resets, Modbus drops and delays, a table
/// fault during a move, a broken or wrongly mounted unit.
void apply_faults(const CliArgs& a, StationSimConfig& cfg) {
  if (!(a.can_loss >= 0.0 && a.can_loss <= 1.0)) throw BadInput("--can-loss: must be in [0, 1]");
  if (!(a.can_corrupt >= 0.0 && a.can_corrupt <= 1.0))
    throw BadInput("--can-corrupt: must be in [0, 1]");
  cfg.faults.can_loss = a.can_loss;
  cfg.faults.can_corrupt = a.can_corrupt;
  for (double t : a.reset_at)
    if (!(t >= 0.0)) throw BadInput("--imu-reset-at: must be >= 0");
  for (double t : a.drop_at)
    if (!(t >= 0.0)) throw BadInput("--modbus-drop-at: must be >= 0");
  cfg.faults.imu_reset_at_s = a.reset_at;
  cfg.faults.modbus_drop_at_s = a.drop_at;
  for (const auto& d : a.delay_at) cfg.faults.modbus_delay.push_back(parse_delay(d));
  if (!a.table_fault.empty()) cfg.faults.table_fault = parse_table_fault(a.table_fault);
  if (!a.imu_fault.empty()) {
    try {
      cfg.faults.imu_fault = imucal::drivers::simulated::parse_imu_fault(a.imu_fault);
    } catch (const std::invalid_argument& e) {
      throw BadInput(e.what());
    }
  }
}

/// "A/B/C" as three numbers (an --also, --mount or --lever-arm value).
Eigen::Vector3d vector3(const std::string& text, const std::string& flag) {
  const auto p = split(text, '/');
  if (p.size() != 3) throw BadInput(flag + ": '" + text + "' is not three numbers A/B/C");
  return {to_double(p[0], flag), to_double(p[1], flag), to_double(p[2], flag)};
}

Eigen::Matrix3d mount_of(const std::string& text, const std::string& flag) {
  const Eigen::Vector3d rpy_deg = vector3(text, flag);
  if (std::abs(rpy_deg(1)) > 90.0) throw BadInput(flag + ": pitch must be within [-90, 90] deg");
  return imucal::calib::core::euler_to_C_bn(rpy_deg(0) * imucal::kDegToRad,
                                            rpy_deg(1) * imucal::kDegToRad,
                                            rpy_deg(2) * imucal::kDegToRad);
}

Eigen::Vector3d lever_of(const std::string& text, const std::string& flag) {
  const Eigen::Vector3d r = vector3(text, flag);
  if (!(r.array().abs() <= 2.0).all()) throw BadInput(flag + ": must be within 2 m on every axis");
  return r;
}

/// One --also SPEC: CAN_PATH then key=value items.
StationSimUnit parse_also(const std::string& spec, uint64_t seed, std::string& truth_out) {
  const auto items = split(spec, ',');
  const std::string flag = "--also " + spec;
  if (items.empty() || items[0].empty() || items[0].find('=') != std::string::npos)
    throw BadInput(flag + ": expected CAN_PATH first, then key=value items");
  StationSimUnit u;
  u.can_path = items[0];
  u.seed = seed;
  std::string unit_path;
  std::vector<std::string> effects;  // applied on top of the unit file, in any order of the keys
  for (size_t i = 1; i < items.size(); ++i) {
    const auto eq = items[i].find('=');
    const std::string key = items[i].substr(0, eq),
                      value = eq == std::string::npos ? "" : items[i].substr(eq + 1);
    if (eq == std::string::npos || value.empty())
      throw BadInput(flag + ": '" + items[i] + "' is not key=value");
    if (key == "unit") {
      unit_path = value;
    } else if (key == "truth") {
      truth_out = value;
    } else if (key == "seed") {
      u.seed = static_cast<uint64_t>(to_int(value, flag + " seed", 0, 1L << 62));
    } else if (key == "effect") {
      effects.push_back(value);
      std::replace(effects.back().begin(), effects.back().end(), '/', ',');
    } else if (key == "mount") {
      u.C_bp = mount_of(value, flag + " mount");
    } else if (key == "lever") {
      u.lever_arm_m = lever_of(value, flag + " lever");
    } else if (key == "cut") {
      u.stream_cut_at_s = to_double(value, flag + " cut");
      if (*u.stream_cut_at_s < 0) throw BadInput(flag + ": cut must be >= 0");
    } else {
      throw BadInput(flag + ": unknown key '" + key +
                     "' (unit, truth, seed, effect, mount, lever, cut)");
    }
  }
  u.unit = load_unit(unit_path, effects, flag + ": unit", flag + ": effect");
  return u;
}

/// The fixture: the first unit's slot (--mount, --lever-arm, --cut-stream-at) and the others
/// (--also); their truth.json paths in `truth_outs` (index 0: the first unit's --truth-out).
void apply_fixture(const CliArgs& a, StationSimConfig& cfg, std::vector<std::string>& truth_outs) {
  if (!a.mount.empty()) cfg.geometry.C_bp = mount_of(a.mount, "--mount");
  if (!a.lever_arm.empty()) cfg.lever_arm_m = lever_of(a.lever_arm, "--lever-arm");
  if (a.cut_stream_at >= 0) cfg.stream_cut_at_s = a.cut_stream_at;
  if (a.also.size() > 3) throw BadInput("--also: at most 3 more units (4 on the fixture)");
  truth_outs = {a.truth_out};
  for (size_t i = 0; i < a.also.size(); ++i) {
    std::string truth;
    cfg.more_units.push_back(parse_also(a.also[i], a.seed + 1000003ULL * (i + 1), truth));
    truth_outs.push_back(truth);
  }
}

/// The simulator's configuration from the command line; BadInput naming the option.
StationSimConfig config_from(const CliArgs& a, std::vector<std::string>& truth_outs) {
  StationSimConfig cfg;
  parse_modbus(a.modbus, cfg);
  cfg.can_path = a.can_path;
  apply_unit(a, cfg);
  apply_clock_and_site(a, cfg);
  apply_faults(a, cfg);
  apply_fixture(a, cfg, truth_outs);
  return cfg;
}

/// truth.json, then the ready line on stdout (and in --ready-file) once the simulator listens.
void announce_ready(StationSim& sim, const CliArgs& a, const StationSimConfig& cfg,
                    const std::vector<std::string>& truth_outs) {
  if (!a.truth_out.empty())
    imucal::db::archive::write_truth_json(a.truth_out,
                                          imucal::db::archive::truth_from_unit(cfg.unit));
  for (size_t i = 0; i < cfg.more_units.size(); ++i)
    if (i + 1 < truth_outs.size() && !truth_outs[i + 1].empty())
      imucal::db::archive::write_truth_json(
          truth_outs[i + 1], imucal::db::archive::truth_from_unit(cfg.more_units[i].unit));
  sim.start();
  nlohmann::json ready;
  ready["pid"] = static_cast<int>(::getpid());
  ready["modbus"] = sim.modbus_endpoint();
  ready["can"] = sim.can_uri();
  if (!cfg.more_units.empty()) {  // every unit's bus, the first one included
    ready["units"] = nlohmann::json::array();
    for (size_t i = 0; i <= cfg.more_units.size(); ++i)
      ready["units"].push_back({{"can", sim.can_uri(i)}});
  }
  ready["speed"] = a.speed;
  // Beyond the contract's keys: what a harness needs to set up the daemon for this station.
  ready["rate_hz"] = a.rate_hz;
  ready["site"] = {{"lat_deg", a.lat_deg},
                   {"lon_deg", a.lon_deg},
                   {"height_m", a.height_m},
                   {"gravity_mps2", imucal::calib::core::EarthModel(cfg.site).gravity_mps2()}};
  if (!a.ready_file.empty()) write_atomically(a.ready_file, ready.dump() + "\n");
  std::cout << ready.dump() << std::endl;
}

/// Runs until SIGTERM/SIGINT, --duration-s or a physics failure (exit 1), with a status line
/// every 2 s.
int serve(StationSim& sim, const CliArgs& a, const sigset_t& sigs) {
  auto last_status = std::chrono::steady_clock::now();
  for (;;) {
    // Wake at most every 100 ms wall, sooner when --duration-s is about to be reached.
    long wait_ns = 100'000'000;
    if (a.duration_s >= 0.0)
      wait_ns = std::clamp(static_cast<long>((a.duration_s - sim.time_s()) / a.speed * 1e9),
                           200'000L, wait_ns);
    const timespec wait{0, wait_ns};
    const int sig = sigtimedwait(&sigs, nullptr, &wait);
    if (sig == SIGTERM || sig == SIGINT) {
      std::fprintf(stderr, "stationsim: %s, stopping\n", sig == SIGTERM ? "SIGTERM" : "SIGINT");
      return 0;
    }
    const std::string err = sim.error();
    if (!err.empty()) {
      std::fprintf(stderr, "stationsim: physics thread failed: %s\n", err.c_str());
      return 1;
    }
    if (a.duration_s >= 0.0 && sim.time_s() >= a.duration_s) return 0;
    const auto now = std::chrono::steady_clock::now();
    if (now - last_status >= std::chrono::seconds(2)) {
      print_status(sim.stats());
      last_status = now;
    }
  }
}

/// Stops the simulator; the final statistics on stderr and in --stats-file.
int stop_and_report(StationSim& sim, const CliArgs& a, int rc) {
  sim.stop();
  const StationSimStats final_stats = sim.stats();
  print_status(final_stats);
  if (!a.stats_file.empty()) {
    try {
      write_atomically(a.stats_file, stats_json(final_stats).dump(2) + "\n");
    } catch (const std::exception& e) {
      std::fprintf(stderr, "stationsim: %s\n", e.what());
      rc = 1;
    }
  }
  return rc;
}

}  // namespace

int main(int argc, char** argv) {
  // SIGTERM/SIGINT are taken synchronously by the main thread (sigtimedwait in serve); block them
  // before any thread starts so that every thread inherits the mask.
  sigset_t sigs;
  sigemptyset(&sigs);
  sigaddset(&sigs, SIGTERM);
  sigaddset(&sigs, SIGINT);
  pthread_sigmask(SIG_BLOCK, &sigs, nullptr);
  signal(SIGPIPE, SIG_IGN);  // a peer closing its socket is an error return, not a death

  // Library logs go to stderr: stdout carries only the ready line (a harness reads it).
  spdlog::set_default_logger(spdlog::stderr_color_mt("stationsim"));

  CLI::App app{
      "stationsim: simulated turntable (Modbus TCP) and IMU (CAN over unixcan), one physics clock"};
  CliArgs args;
  add_options(app, args);
  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::fprintf(stderr, "stationsim: %s\n", e.what());
    return 2;
  }

  StationSimConfig cfg;
  std::vector<std::string> truth_outs;  // per unit, "" = none
  try {
    cfg = config_from(args, truth_outs);
  } catch (const BadInput& e) {
    std::fprintf(stderr, "stationsim: %s\n", e.what());
    return 2;
  }
  std::unique_ptr<StationSim> sim;
  try {
    sim = std::make_unique<StationSim>(cfg);
  } catch (const std::invalid_argument& e) {
    std::fprintf(stderr, "stationsim: %s%s\n",
                 args.unit_path.empty() ? "" : ("--unit " + args.unit_path + ": ").c_str(),
                 e.what());
    return 2;
  }
  try {
    announce_ready(*sim, args, cfg, truth_outs);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "stationsim: %s\n", e.what());
    return 1;
  }
  return stop_and_report(*sim, args, serve(*sim, args, sigs));
}
