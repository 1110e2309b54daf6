#pragma once
// `imucal import`: a raw IMU recording as it comes (issue #21 item 5) into a land run archive that
// `imucal calibrate` reads — one file with every channel (--file, --columns) or one per sensor
// (--gyro, --accel: time x y z each), in counts or SI (--gyro-scale/--gyro-offset,
// --accel-scale/--accel-offset: SI = (raw - offset) * scale), rates or increments, host time
// stamps re-stamped onto the sensor's own uniform grid (db/archive/raw_recording.hpp says how).
// Every option may also come from a TOML file (--config; the command line wins):
//   [input]   columns = "t,gx,gy,gz,ax,ay,az", time_unit = "s"|"ms"|"us"|"ns",
//             quantity = "rates"|"increments", rate_hz = R (no time column), skip_lines = N
//   [gyro]    scale = S or [Sx, Sy, Sz], offset = O or [Ox, Oy, Oz]
//   [accel]   scale, offset (as [gyro])
//   [run]     serial = "...", grade = "navigation"|"tactical"|"mems"
//   [station] name, lat_deg, lon_deg, height_m (required), gravity_mps2 (optional)
//   [noise]   arw_deg_per_sqrt_h, vrw_ug_per_sqrt_hz (default: the grade's worst of class)
// A sensor in counts (a scale given, every raw value whole) declares its LSB in run.toml [noise]:
// one count × scale × period for rates, rounded per sample; × 1 for increments, carried (issue
// #50). SI or decimal values declare none (0).
// Bad input is one line naming the file, line and column or key; nothing is written. A recording
// whose values cannot be what the options say (a unit mix-up: db/archive/import_plausibility.hpp)
// is refused naming the factor and the option that fixes it (--skip-plausibility imports it).
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

namespace imucal::tools::imucal {

struct ImportArgs {
  std::string file, gyro_file, accel_file, out_dir, config;
  std::string columns, time_unit, quantity;
  std::vector<double> gyro_scale, gyro_offset, accel_scale, accel_offset;
  std::string serial, grade, station_name;
  double lat_deg = kUnset, lon_deg = kUnset, height_m = kUnset, gravity_mps2 = kUnset;
  double arw_deg_per_sqrt_h = kUnset, vrw_ug_per_sqrt_hz = kUnset;
  double rate_hz = kUnset;  ///< the sensor's sample rate (required without a time column)
  int skip_lines = -1;      ///< lines to skip at the top of each file (-1: none given)
  bool overwrite = false, json = false;
  bool skip_plausibility = false;  ///< import even a recording whose units look wrong
  bool strict_time = false;        ///< refuse repeated rows and dropped-sample gaps
  static constexpr double kUnset = -1e300;
};

CLI::App* add_import_command(CLI::App& app, ImportArgs& args);
int cmd_import(const ImportArgs& args);

}  // namespace imucal::tools::imucal
