#pragma once
// stationd's configuration file (TOML; station/config/stationd.example.toml documents every key
// with its unit and default). Read once at start-up; a bad file stops the daemon before it touches
// anything.
//
// Every error is a ConfigError whose what() reads "FILE:LINE:COL: message", the message naming the
// key ("[imu] rate_hz ..."): unknown key or table, wrong type, value out of range, missing required
// key, TOML syntax. Relative paths (data_dir, database, control socket, the path of a
// unixcan:/candump: URI) are resolved against the directory of the configuration file, so a config
// works from any working directory. Loading never creates, opens or modifies anything but the
// config file itself.
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "calib/core/earth.hpp"
#include "calib/core/unit_grade.hpp"
#include "calib/diagnosis/false_alarm.hpp"
#include "drivers/imu/imu_codec.hpp"
#include "drivers/imu/imu_protocol_map.hpp"
#include "drivers/turntable/turntable_client.hpp"

namespace imucal::station::config {

class ConfigError : public std::runtime_error {
 public:
  ConfigError(const std::string& file, int line, int column, const std::string& message);
  const std::string& file() const { return file_; }
  int line() const { return line_; }
  int column() const { return column_; }
  /// The message without the "FILE:LINE:COL: " prefix.
  const std::string& message() const { return message_; }

 private:
  std::string file_;
  int line_, column_;
  std::string message_;
};

/// The most units a fixture holds (issue #23): one table run captures and calibrates them all.
constexpr std::size_t kMaxImuSlots = 4;

/// One unit's place on the fixture and its link: an [imu] table, or one entry of [[imu]].
struct ImuSlotConfig {
  /// slot: the fixture position's name (1–16 characters, letters, digits, '-', '_'); "A" for the
  /// only unit of an [imu] table, "A", "B", ... in file order when [[imu]] entries omit it.
  std::string name = "A";
  std::string can_uri;  ///< can (required): "unixcan:PATH" | "socketcan:IFACE" | "candump:FILE"
  double rate_hz = 100.0;
  /// protocol: the unit's protocol file (drivers/imu/PROTOCOL.md; "" = the built-in protocol,
  /// /usr/share/imucal/protocols/imucal-imu-1.toml), relative to the config file's directory.
  std::string protocol_path;
  /// base_id: moves the protocol's identifiers so that its lowest is this one (unset: as in the
  /// protocol's DBC file; 0x100 for the built-in one).
  std::optional<uint32_t> base_id;
  /// The protocol as read and checked at load time, with base_id applied.
  std::shared_ptr<const drivers::imu::ImuProtocolMap> protocol;
  double arw_deg_per_sqrt_h =
      0.0015;                        ///< gyro angle random walk (noise weighting of the estimators)
  double vrw_ug_per_sqrt_hz = 10.0;  ///< accelerometer velocity random walk
  /// The product this station calibrates (calib/core/unit_grade.hpp): written to every run's
  /// run.toml [prior], so the data checks, limits and the filter's prior follow it.
  calib::core::Grade grade = calib::core::Grade::kNavigation;
  uint64_t max_gap_samples = 10;
  uint64_t settle_guard_samples = 50;
  /// Default: 8 σ of a still unit's per-sample rate noise from arw and rate_hz, at least 0.05.
  double rest_rate_threshold_dps = 0.05;
  int stream_timeout_ms = 2000;

  /// mount_rpy_deg: the slot's nominal frame against the table's platform frame (ZYX Euler angles,
  /// deg, pitch within ±90; the archive's [table] mount, C_bp), or given as mount_matrix (C_bp by
  /// rows, checked to be a rotation) and kept here as its angles. lever_arm_m: the unit's centre
  /// from the table's rotation centre, platform axes, m — recorded with the run and taken out of
  /// the accelerometer data before calibrating (a rigid offset senses ω×(ω×r) + ω̇×r while the table
  /// turns).
  std::array<double, 3> mount_rpy_deg{0.0, 0.0, 0.0};
  std::array<double, 3> lever_arm_m{0.0, 0.0, 0.0};

  /// The noise model in SI units (calib::core::NoiseModel's fields).
  double arw_rad_per_sqrt_s() const;
  double vrw_mps_per_sqrt_s() const;
};

/// [fleet] (issue #24): the factory's fleet store this station replicates its history to. The
/// station never waits for it: runs are stored in SQLite first and an outbox carries them over
/// (station/daemon/fleet_sender.hpp).
struct FleetConfig {
  std::string url;            ///< url (required in [fleet]): postgresql://USER@HOST:PORT/DB
  std::string station_id;     ///< station_id (default [station] name): the station's key
  std::string password_file;  ///< password_file: first line is the password (read at each connect)
  std::string password_env;   ///< password_env: an environment variable holding it
  /// How many outbox entries one transaction to the fleet store carries.
  std::size_t batch_entries = 200;
};

struct StationConfig {
  std::string source_path;  ///< the config file (as given)
  std::string base_dir;     ///< its directory, absolute; relative paths were resolved against it

  // [station]
  std::string station_name;  ///< name (required): recorded with every run
  calib::core::Site site;    ///< lat_deg, lon_deg, height_m (required), gravity_mps2 (optional)
  std::string data_dir;      ///< data_dir (required): run archives go to <data_dir>/runs/
  std::string database;      ///< database (default <data_dir>/history.sqlite)

  // [control]
  std::string control_socket = "/run/imucal/stationd.sock";  ///< socket
  std::string control_group;             ///< group ("" = the daemon's primary group)
  unsigned control_socket_mode = 0660;   ///< socket_mode (owner and control group)
  double control_idle_timeout_s = 60.0;  ///< idle_timeout_s: idle connections are closed
  std::size_t control_max_connections_per_user = 16;  ///< max_connections_per_user

  // [turntable] (+ [turntable.registers])
  drivers::turntable::TurntableClientConfig
      turntable;                  ///< endpoint (required), timeouts, tolerance, map
  double move_timeout_s = 120.0;  ///< per move, wall time
  double home_timeout_s = 120.0;
  double max_rate_dps = 20.0;  ///< station limit; sequences are validated against it, rates clipped

  // [imu] (one unit) or [[imu]] (a fixture of up to kMaxImuSlots units on the same table): the
  // slots in file order; never empty once loaded.
  std::vector<ImuSlotConfig> imus{ImuSlotConfig{}};
  /// The first (on a one-unit station the only) slot.
  const ImuSlotConfig& imu() const { return imus.front(); }
  ImuSlotConfig& imu() { return imus.front(); }

  // [fleet]: absent = this station keeps its history to itself (no outbox)
  std::optional<FleetConfig> fleet;

  // [calibration]
  std::string default_sequence = "factory-std";
  /// sequence_dir: the sequence library ("" = the lookup of sequences/library.hpp); relative to
  /// the config file's directory.
  std::string sequence_dir;
  double k_sigma = 4.0;
  /// The gap check's false-alarm rate per run: the probability that a run of a unit without any
  /// unmodelled effect ends REVIEW through the sim-to-real gap check
  /// (calib/diagnosis/diagnosis.hpp, diagnosis_options_for_false_alarm). 1e-4: a line of 300 units
  /// a day sees one needless review in about a month; a larger rate detects smaller effects
  /// (README, "The gap check").
  double gap_false_alarm = calib::diagnosis::kDefaultGapFalseAlarm;
  /// The product's known unmodelled effects (catalogue names, e.g. from `imucal gap-budget`): a
  /// significant gap that the diagnosis explains by these alone is kept with the run but does not
  /// make it REVIEW. An unexplained gap, or one explained by any other effect, still does.
  /// Empty (the default): every significant gap is a REVIEW.
  std::vector<std::string> known_effects;

  // [log]
  std::string log_level = "info";  ///< trace, debug, info, warn, error, critical, off
};

/// The IMU frame decoder's options of a slot ([imu] protocol, base_id, rate_hz).
drivers::imu::DecoderOptions decoder_options(const ImuSlotConfig& slot);
/// The slot of that name; the first slot for "" (a run of a one-unit station) or a name the
/// configuration no longer has.
const ImuSlotConfig& slot_named(const StationConfig& config, const std::string& name);

/// Reads and checks the file. Throws ConfigError (a file that cannot be read: line 0, column 0).
StationConfig load_config(const std::string& path);

/// Same for text; `origin` names it in errors and `base_dir` resolves relative paths.
StationConfig parse_config(std::string_view text, const std::string& origin,
                           const std::string& base_dir);

/// The log level words accepted by [log] level and --log-level.
bool is_log_level(const std::string& level);

}  // namespace imucal::station::config
