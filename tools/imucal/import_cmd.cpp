#include "tools/imucal/import_cmd.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>

#include "calib/core/conventions.hpp"
#include "calib/core/unit_grade.hpp"
#include "db/archive/archive_error.hpp"
#include "db/archive/import_plausibility.hpp"
#include "db/archive/raw_recording.hpp"
#include "db/archive/run_archive.hpp"
#include "db/archive/toml_util.hpp"

namespace imucal::tools::imucal {

namespace {

bool unset(double v) { return v == ImportArgs::kUnset; }

/// A scalar (all three axes) or three values.
Eigen::Vector3d axes(const std::vector<double>& v, const char* flag) {
  if (v.size() == 1) return Eigen::Vector3d::Constant(v[0]);
  if (v.size() == 3) return {v[0], v[1], v[2]};
  throw std::invalid_argument(std::string(flag) + " takes one value (every axis) or three (x y z)");
}

/// [gyro] / [accel] of the config: scale and offset, each a number or [x, y, z].
void read_axis_section(const db::archive::TomlSection& root, const char* name,
                       std::vector<double>& scale, std::vector<double>& offset) {
  const auto s = root.section(name, {"scale", "offset"});
  if (!s) return;
  for (auto [key, out] : {std::pair{"scale", &scale}, std::pair{"offset", &offset}}) {
    if (!s->has(key) || !out->empty()) continue;  // the command line wins
    if (s->is_array(key)) {
      *out = *s->numbers(key);
      if (out->size() != 3) s->fail(key, "give one number or three [x, y, z]");
    } else {
      *out = {*s->number(key)};
    }
  }
}

void take(std::string& dst, const std::optional<std::string>& v) {
  if (dst.empty() && v) dst = *v;
}
void take(double& dst, const std::optional<double>& v) {
  if (unset(dst) && v) dst = *v;
}

/// The options the command line left out, from the TOML config.
void merge_config(ImportArgs& a) {
  std::ifstream f(a.config);
  if (!f) throw db::archive::ArchiveError(a.config, "cannot open");
  std::stringstream text;
  text << f.rdbuf();
  const toml::table t = db::archive::parse_toml_text(text.str(), a.config);
  const db::archive::TomlSection root(t, a.config, "",
                                      {"input", "gyro", "accel", "run", "station", "noise"});
  if (const auto in = root.section(
          "input", {"columns", "time_unit", "quantity", "rate_hz", "skip_lines", "strict_time"})) {
    if (!a.strict_time && in->has("strict_time")) a.strict_time = *in->boolean("strict_time");
    take(a.columns, in->string("columns"));
    take(a.time_unit, in->string("time_unit"));
    take(a.quantity, in->string("quantity"));
    take(a.rate_hz, in->number("rate_hz"));
    if (a.skip_lines < 0 && in->has("skip_lines")) {
      const double n = *in->number("skip_lines");
      if (!(n >= 0 && n == std::floor(n) && n < 1e6))
        in->fail("skip_lines", "give a whole number of lines, 0 or more");
      a.skip_lines = static_cast<int>(n);
    }
  }
  read_axis_section(root, "gyro", a.gyro_scale, a.gyro_offset);
  read_axis_section(root, "accel", a.accel_scale, a.accel_offset);
  if (const auto run = root.section("run", {"serial", "grade"})) {
    take(a.serial, run->string("serial"));
    take(a.grade, run->string("grade"));
  }
  if (const auto st =
          root.section("station", {"name", "lat_deg", "lon_deg", "height_m", "gravity_mps2"})) {
    take(a.station_name, st->string("name"));
    take(a.lat_deg, st->number("lat_deg"));
    take(a.lon_deg, st->number("lon_deg"));
    take(a.height_m, st->number("height_m"));
    take(a.gravity_mps2, st->number("gravity_mps2"));
  }
  if (const auto n = root.section("noise", {"arw_deg_per_sqrt_h", "vrw_ug_per_sqrt_hz"})) {
    take(a.arw_deg_per_sqrt_h, n->number("arw_deg_per_sqrt_h"));
    take(a.vrw_ug_per_sqrt_hz, n->number("vrw_ug_per_sqrt_hz"));
  }
}

double seconds_per(const std::string& unit) {
  if (unit.empty() || unit == "s") return 1.0;
  if (unit == "ms") return 1e-3;
  if (unit == "us") return 1e-6;
  if (unit == "ns") return 1e-9;
  throw std::invalid_argument("time unit '" + unit + "': give s, ms, us or ns");
}

db::archive::RawImportOptions raw_options(const ImportArgs& a) {
  db::archive::RawImportOptions o;
  if (!a.columns.empty()) o.columns = db::archive::parse_raw_columns(a.columns);
  o.seconds_per_time_unit = seconds_per(a.time_unit);
  if (a.quantity == "increments")
    o.quantity = db::archive::RawQuantity::kIncrements;
  else if (!a.quantity.empty() && a.quantity != "rates")
    throw std::invalid_argument("quantity '" + a.quantity + "': give rates or increments");
  if (!a.gyro_scale.empty()) o.gyro.scale = axes(a.gyro_scale, "--gyro-scale");
  if (!a.gyro_offset.empty()) o.gyro.offset = axes(a.gyro_offset, "--gyro-offset");
  if (!a.accel_scale.empty()) o.accel.scale = axes(a.accel_scale, "--accel-scale");
  if (!a.accel_offset.empty()) o.accel.offset = axes(a.accel_offset, "--accel-offset");
  if (!unset(a.rate_hz)) {
    if (!(std::isfinite(a.rate_hz) && a.rate_hz > 0.0))
      throw std::invalid_argument("--rate: give the sensor's sample rate in Hz (> 0)");
    o.rate_hz = a.rate_hz;
  }
  if (a.skip_lines > 0) o.skip_lines = static_cast<std::size_t>(a.skip_lines);
  o.strict_time = a.strict_time;
  return o;
}

/// run.toml of the imported run: a land run of the grade, at the station given.
db::archive::RunInfo run_info(const ImportArgs& a, double rate_hz) {
  if (a.serial.empty()) throw std::invalid_argument("give the unit's --serial (or [run] serial)");
  for (auto [v, name] : {std::pair{a.lat_deg, "--lat-deg"}, std::pair{a.lon_deg, "--lon-deg"},
                         std::pair{a.height_m, "--height-m"}})
    if (unset(v))
      throw std::invalid_argument(std::string("give ") + name +
                                  " (or [station] in --config): where the recording was made");
  const std::optional<calib::core::Grade> grade =
      calib::core::parse_grade(a.grade.empty() ? "navigation" : a.grade);
  if (!grade)
    throw std::invalid_argument("grade '" + a.grade + "': give navigation, tactical or mems");
  db::archive::RunInfo info;
  info.serial = a.serial;
  info.setting = calib::core::Setting::kLand;
  info.reference = db::archive::ReferenceKind::kNone;
  info.station_name = a.station_name.empty() ? "imported" : a.station_name;
  info.site.lat_rad = a.lat_deg * kDegToRad;
  info.site.lon_rad = a.lon_deg * kDegToRad;
  info.site.height_m = a.height_m;
  if (!unset(a.gravity_mps2)) info.site.gravity_mps2 = a.gravity_mps2;
  info.imu_rate_hz = rate_hz;
  info.grade = *grade;
  const calib::core::GradePrior prior = calib::core::grade_prior(*grade);
  info.arw_rad_per_sqrt_s = unset(a.arw_deg_per_sqrt_h) ? prior.arw_rad_per_sqrt_s
                                                        : a.arw_deg_per_sqrt_h * kDegToRad / 60.0;
  info.vrw_mps_per_sqrt_s =
      unset(a.vrw_ug_per_sqrt_hz) ? prior.vrw_mps_per_sqrt_s : a.vrw_ug_per_sqrt_hz * kMicroG_mps2;
  info.software_version = IMUCAL_VERSION;
  return info;
}

/// [noise]'s LSBs and their rounding from what the recording is (issue #50): a sensor read in
/// counts (a scale given and every raw value a whole number) has one count's increment as its LSB,
/// the coarsest axis's where the axes' scales differ (the noise model holds one LSB a sensor). A
/// sensor in SI or read with decimals has no LSB the importer knows of, and declares none (0, "no
/// quantisation"), rather than the station protocol's 1e-9 rad and 1e-7 m/s it never went
/// through. A logger of rates rounds each sample on its own (white, no lag-1 correlation); a unit
/// that outputs increment counts accumulates them, carrying the remainder (the default's kind).
void set_resolution(const ImportArgs& a, const db::archive::RawRecording& rec,
                    db::archive::RunInfo& info) {
  info.dtheta_lsb_rad = a.gyro_scale.empty() ? 0.0 : rec.dtheta_count_rad;
  info.dv_lsb_mps = a.accel_scale.empty() ? 0.0 : rec.dv_count_mps;
  info.lsb_rounding = a.quantity == "increments" ? calib::core::LsbRounding::kCarried
                                                 : calib::core::LsbRounding::kPerSample;
}

/// How the file was read where a reader would want to know: columns from its header, lines
/// skipped before the data, decimal commas, a time grid from the rate alone.
void print_reading_notes(const db::archive::RawRecording& rec, bool rate_given) {
  std::string cols;
  for (const std::string& c : rec.columns) cols += (cols.empty() ? "" : ",") + c;
  if (rec.columns_from == "header") std::printf("columns from the header: %s\n", cols.c_str());
  if (rec.header_lines > 0)
    std::printf("%zu line(s) before the data skipped (preamble, header)\n", rec.header_lines);
  if (rec.decimal_comma) std::printf("decimal commas read as decimal points\n");
  if (rate_given && std::find(rec.columns.begin(), rec.columns.end(), "t") == rec.columns.end())
    std::printf("no time column: samples stamped at the given rate\n");
  if (rec.repeated_rows > 0)
    std::printf("%zu row(s) repeated verbatim (same stamp, same values) dropped\n",
                rec.repeated_rows);
  if (rec.gaps > 0)
    std::printf(
        "%zu gap(s) of dropped samples (%zu samples in all) kept as gaps: the calibration leaves "
        "out the moves they fall in and uses the rests on both sides (--strict-time refuses "
        "them)\n",
        rec.gaps, rec.samples_missing);
}

/// The LSBs the archive declares and why (the diagnosis models the quantisation with them).
void print_resolution(const db::archive::RunInfo& info) {
  const auto lsb = [](double v, const char* unit) {
    char text[48];
    if (v > 0.0)
      std::snprintf(text, sizeof text, "%.4g %s", v, unit);
    else
      std::snprintf(text, sizeof text, "none");
    return std::string(text);
  };
  std::printf(
      "LSBs declared (a sensor in whole counts with a scale: one count): dtheta %s, dv %s; "
      "%s\n",
      lsb(info.dtheta_lsb_rad, "rad").c_str(), lsb(info.dv_lsb_mps, "m/s").c_str(),
      info.lsb_rounding == calib::core::LsbRounding::kPerSample
          ? "rates rounded per sample"
          : "increments with the remainder carried");
}

void print_import_report(const ImportArgs& a, const db::archive::RawRecording& rec,
                         const db::archive::RunInfo& info) {
  const double span_s = rec.imu.back().t_s - rec.imu.front().t_s + rec.imu.front().dt_s;
  if (a.json) {
    std::cout << nlohmann::json{{"out", a.out_dir},
                                {"samples", rec.imu.size()},
                                {"rate_hz", rec.rate_hz},
                                {"span_s", span_s},
                                {"jitter_rms_s", rec.jitter_rms_s},
                                {"jitter_max_s", rec.jitter_max_s},
                                {"header_lines", rec.header_lines},
                                {"columns", rec.columns},
                                {"columns_from", rec.columns_from},
                                {"decimal_comma", rec.decimal_comma},
                                {"repeated_rows_dropped", rec.repeated_rows},
                                {"gaps", rec.gaps},
                                {"samples_missing", rec.samples_missing},
                                {"dtheta_lsb_rad", info.dtheta_lsb_rad},
                                {"dv_lsb_mps", info.dv_lsb_mps},
                                {"lsb_rounding", calib::core::lsb_rounding_name(info.lsb_rounding)}}
                     .dump()
              << '\n';
    return;
  }
  std::printf(
      "wrote %s: %zu samples, %.1f s at %.4f Hz (land, no reference)\n"
      "time: host stamps re-stamped onto the sensor's uniform grid (least-squares period over "
      "the whole recording); they sat %.1f us RMS, %.1f us at worst from it; no sample "
      "interpolated%s\n",
      a.out_dir.c_str(), rec.imu.size(), span_s, rec.rate_hz, rec.jitter_rms_s * 1e6,
      rec.jitter_max_s * 1e6,
      a.quantity == "increments" ? "" : "; rates integrated over the period");
  print_reading_notes(rec, !unset(a.rate_hz));
  print_resolution(info);
}

/// A recording whose values cannot be what the options say (a unit mix-up) is refused, naming
/// the factor and the option that fixes it (db/archive/import_plausibility.hpp).
void refuse_implausible(const ImportArgs& a, const db::archive::RawRecording& rec) {
  if (a.skip_plausibility) return;
  const double gravity_mps2 = unset(a.gravity_mps2) ? kStandardGravity_mps2 : a.gravity_mps2;
  const std::optional<calib::core::Grade> grade =
      calib::core::parse_grade(a.grade.empty() ? "navigation" : a.grade);
  const std::vector<std::string> findings = db::archive::implausible_reading(
      rec, gravity_mps2, grade.value_or(calib::core::Grade::kNavigation));
  if (findings.empty()) return;
  std::string message = a.file.empty() ? a.gyro_file + ", " + a.accel_file : a.file;
  message += ": ";
  for (std::size_t i = 0; i < findings.size(); ++i) message += (i ? "; and " : "") + findings[i];
  throw std::invalid_argument(message + " (--skip-plausibility imports it as read)");
}

}  // namespace

CLI::App* add_import_command(CLI::App& app, ImportArgs& a) {
  CLI::App* im = app.add_subcommand(
      "import", "a raw IMU recording (text columns, counts or SI) into a land run archive");
  im->add_option("--out", a.out_dir, "archive directory to create")->required();
  im->add_option("--file", a.file, "one file with every channel (see --columns)");
  im->add_option("--gyro", a.gyro_file, "one file per sensor: the gyros' (time x y z)");
  im->add_option("--accel", a.accel_file, "one file per sensor: the accelerometers' (time x y z)");
  im->add_option("--config", a.config, "TOML file with any of these options (the flags win)");
  im->add_option("--columns", a.columns,
                 "--file's columns in order: t,gx,gy,gz,ax,ay,az, - to ignore one "
                 "(default t,gx,gy,gz,ax,ay,az)");
  im->add_option("--time-unit", a.time_unit, "s (default), ms, us or ns");
  im->add_option("--rate", a.rate_hz,
                 "the sensor's sample rate, Hz: required when there is no time column "
                 "(columns without t); with one, the stamps must agree within 2 %");
  im->add_option("--skip-lines", a.skip_lines,
                 "lines to skip at the top of each file (a logger's preamble; key,value lines "
                 "and a header before the data are skipped without it)")
      ->check(CLI::NonNegativeNumber);
  im->add_option("--quantity", a.quantity,
                 "rates (default: rad/s, m/s² after scaling) or "
                 "increments (rad, m/s per sample)");
  im->add_option("--gyro-scale", a.gyro_scale, "SI per raw unit (one value or x y z)")
      ->expected(1, 3);
  im->add_option("--gyro-offset", a.gyro_offset, "raw zero (one value or x y z)")->expected(1, 3);
  im->add_option("--accel-scale", a.accel_scale, "SI per raw unit (one value or x y z)")
      ->expected(1, 3);
  im->add_option("--accel-offset", a.accel_offset, "raw zero (one value or x y z)")->expected(1, 3);
  im->add_option("--serial", a.serial, "the unit's serial number");
  im->add_option("--grade", a.grade, "navigation (default), tactical or mems");
  im->add_option("--station", a.station_name, "where it was recorded (a name)");
  im->add_option("--lat-deg", a.lat_deg, "latitude of the recording, deg");
  im->add_option("--lon-deg", a.lon_deg, "longitude, deg");
  im->add_option("--height-m", a.height_m, "height above the ellipsoid, m");
  im->add_option("--gravity", a.gravity_mps2, "surveyed gravity, m/s² (default: normal gravity)");
  im->add_option("--arw", a.arw_deg_per_sqrt_h, "angle random walk, deg/√h (default: the grade's)");
  im->add_option("--vrw", a.vrw_ug_per_sqrt_hz,
                 "velocity random walk, µg/√Hz (default: the "
                 "grade's)");
  im->add_flag("--strict-time", a.strict_time,
               "refuse a row repeated verbatim and a dropped-sample gap (by default the one is "
               "dropped, the other kept as a gap the calibration works around)");
  im->add_flag("--overwrite", a.overwrite, "replace an existing archive");
  im->add_flag("--skip-plausibility", a.skip_plausibility,
               "import even when the rate, |f| at rest or the gyros' rates say a unit is wrong");
  im->add_flag("--json", a.json, "print one JSON object");
  return im;
}

int cmd_import(const ImportArgs& args) {
  ImportArgs a = args;
  if (!a.config.empty()) merge_config(a);
  const bool pair = !a.gyro_file.empty() || !a.accel_file.empty();
  if (pair == !a.file.empty())
    throw std::invalid_argument(
        "give either --file (every channel in one file) or --gyro and "
        "--accel (one file per sensor)");
  if (pair && (a.gyro_file.empty() || a.accel_file.empty()))
    throw std::invalid_argument("one file per sensor needs both --gyro and --accel");
  db::archive::check_archive_target(a.out_dir, a.overwrite,
                                    "remove it, or give --overwrite to replace it");
  const db::archive::RawImportOptions o = raw_options(a);
  db::archive::RawRecording rec =
      pair ? db::archive::read_raw_recording_pair(a.gyro_file, a.accel_file, o)
           : db::archive::read_raw_recording(a.file, o);
  refuse_implausible(a, rec);
  db::archive::RunArchive ar;
  ar.info = run_info(a, rec.rate_hz);
  set_resolution(a, rec, ar.info);
  ar.imu = rec.imu;
  db::archive::write_archive(a.out_dir, ar, a.overwrite);
  print_import_report(a, rec, ar.info);
  return 0;
}

}  // namespace imucal::tools::imucal
