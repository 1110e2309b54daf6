// `imucal import` as loggers write (issue #48 item 4): a microcontroller's log with a "key,value"
// preamble and no time column, a fixed preamble of numbers skipped by count, decimal commas with
// ';', and columns taken from the header's own names — a header that contradicts --columns is an
// error naming both, never silently overruled (a gyro and accelerometer swapped that way used to
// import with exit 0 and come back from `calibrate` as "no rest found"). Each case's recording is
// one whose values are known, and the test reads them back from the archive.
// Plausibility at import (issue #48 item 5): a unit read as another (g as m/s², counts without a
// scale, deg/s as rad/s, ms as s, increments as rates) is refused naming the factor and the option
// that fixes it, and the same file with that option imports.
// Time as loggers keep it (issue #48 items 3 and 4): a row written twice is dropped, a gap of lost
// samples kept as a gap (not closed up, not refused) — and a calibration of such a recording leaves
// out the move the gap fell in and says so; --strict-time refuses both.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "calib/core/conventions.hpp"
#include "db/archive/run_archive.hpp"
#include "tests/support/imucal_cli.hpp"
#include "tests/support/temp_dir.hpp"

namespace imucal {
namespace {

namespace fs = std::filesystem;
using test_support::run_imucal;

// MEMS grade: the made-up rates (up to 0.003 rad/s at rest) are beyond a navigation unit's bias.
const char* const kLoggerSite =
    " --lat-deg 48.1 --lon-deg 11.6 --height-m 520 --serial LOG-2 --grade mems";

/// Sample k's values: a gyro rate (rad/s) and a specific force (m/s²) per axis, all distinct.
double gyro_at(int k, int axis) { return 0.001 * (axis + 1) + 1e-5 * k; }
double accel_at(int k, int axis) { return axis == 2 ? 9.8 - 1e-4 * k : 0.1 * (axis + 1); }

/// `n` rows "sep"-separated in the order `order` ("t" and the six channels), at 100 Hz.
std::string rows(int n, const std::vector<std::string>& order, const std::string& sep,
                 bool decimal_comma = false) {
  std::string s;
  for (int k = 0; k < n; ++k) {
    for (size_t c = 0; c < order.size(); ++c) {
      const std::string& name = order[c];
      double v = 0.0;
      if (name == "t") v = 0.01 * k;
      if (name.size() == 2 && name[0] == 'g') v = gyro_at(k, name[1] - 'x');
      if (name.size() == 2 && name[0] == 'a') v = accel_at(k, name[1] - 'x');
      char buf[40];
      std::snprintf(buf, sizeof buf, "%.9g", v);
      std::string cell = buf;
      if (decimal_comma)
        for (char& ch : cell)
          if (ch == '.') ch = ',';
      s += (c ? sep : "") + cell;
    }
    s += '\n';
  }
  return s;
}

struct Imported {
  test_support::CommandResult result;
  nlohmann::json report;  ///< --json's object, when it imported
  std::string out;        ///< the archive directory
};

Imported import_text(const test_support::ScopedTempDir& tmp, const std::string& name,
                     const std::string& text, const std::string& flags) {
  const std::string file = tmp.path() + "/" + name + ".txt";
  std::ofstream(file) << text;
  Imported im;
  im.out = tmp.path() + "/" + name;
  im.result =
      run_imucal("import --json --file " + file + " --out " + im.out + kLoggerSite + flags, false);
  if (im.result.code == 0) im.report = nlohmann::json::parse(im.result.out);
  return im;
}

/// The archive holds sample k's known values (gyro and accelerometer not swapped, right scale).
void expect_known_values(const std::string& dir, int n) {
  const db::archive::RunArchive ar = db::archive::read_archive(dir);
  ASSERT_EQ(ar.imu.size(), static_cast<size_t>(n)) << dir;
  for (int k : {0, n / 2, n - 1})
    for (int a = 0; a < 3; ++a) {
      EXPECT_NEAR(ar.imu[k].dtheta_rad(a) / ar.imu[k].dt_s, gyro_at(k, a), 1e-9) << dir << " " << k;
      EXPECT_NEAR(ar.imu[k].dv_mps(a) / ar.imu[k].dt_s, accel_at(k, a), 1e-7) << dir << " " << k;
    }
  EXPECT_NEAR(ar.imu[1].t_s - ar.imu[0].t_s, 0.01, 1e-12) << dir;
}

TEST(ImucalImportLoggers, APreambleOfKeyValueLinesAndNoTimeColumnImportWithTheRateGiven) {
  test_support::ScopedTempDir tmp("imucal-import-loggers");
  const std::string preamble = "device,MPU6050\nrate_hz,100\nfirmware,1.2\naccel_fs,2\n";
  const std::string text =
      preamble + "gx,gy,gz,ax,ay,az\n" + rows(300, {"gx", "gy", "gz", "ax", "ay", "az"}, ",");
  const Imported ok = import_text(tmp, "rate", text, " --rate 100");
  ASSERT_EQ(ok.result.code, 0) << ok.result.out;
  EXPECT_EQ(ok.report.at("header_lines"), 5);
  EXPECT_EQ(ok.report.at("columns_from"), "header");
  EXPECT_NEAR(ok.report.at("rate_hz").get<double>(), 100.0, 1e-9);
  expect_known_values(ok.out, 300);
  // Without the rate: one line saying what is missing, nothing written.
  const Imported no_rate = import_text(tmp, "norate", text, "");
  EXPECT_NE(no_rate.result.code, 0);
  EXPECT_NE(no_rate.result.out.find("no time column"), std::string::npos) << no_rate.result.out;
  EXPECT_NE(no_rate.result.out.find("--rate"), std::string::npos) << no_rate.result.out;
  EXPECT_FALSE(fs::exists(no_rate.out));
  // A rate that the stamps contradict (a time column in ms read as s would be 1 000 times off).
  const Imported wrong = import_text(
      tmp, "wrongrate", rows(300, {"t", "gx", "gy", "gz", "ax", "ay", "az"}, " "), " --rate 200");
  EXPECT_NE(wrong.result.code, 0);
  EXPECT_NE(wrong.result.out.find("the rate given is 200 Hz"), std::string::npos)
      << wrong.result.out;
}

TEST(ImucalImportLoggers, APreambleOfNumbersIsSkippedByCountAndOtherwiseRefused) {
  test_support::ScopedTempDir tmp("imucal-import-skip");
  // A logger that first writes two lines of its own figures, as many cells as a sample.
  const std::string text = "12 34 56 78 90 12 34\n12 34 56 78 90 12 34\n" +
                           rows(200, {"t", "gx", "gy", "gz", "ax", "ay", "az"}, " ");
  const Imported refused = import_text(tmp, "plain", text, "");
  EXPECT_NE(refused.result.code, 0);
  // (Its second line repeats the first verbatim: dropped as a logger's repeated row, so the first
  // data row is what stops it.)
  EXPECT_NE(
      refused.result.out.find("plain.txt:3: time 0 s does not increase (previous sample 12 s)"),
      std::string::npos)
      << refused.result.out;
  const Imported ok = import_text(tmp, "skipped", text, " --skip-lines 2");
  ASSERT_EQ(ok.result.code, 0) << ok.result.out;
  EXPECT_EQ(ok.report.at("header_lines"), 2);
  expect_known_values(ok.out, 200);
}

TEST(ImucalImportLoggers, DecimalCommasWithSemicolonsAreRead) {
  test_support::ScopedTempDir tmp("imucal-import-comma");
  const std::string text =
      "t;gx;gy;gz;ax;ay;az\n" + rows(200, {"t", "gx", "gy", "gz", "ax", "ay", "az"}, ";", true);
  const Imported ok = import_text(tmp, "comma", text, "");
  ASSERT_EQ(ok.result.code, 0) << ok.result.out;
  EXPECT_TRUE(ok.report.at("decimal_comma").get<bool>());
  expect_known_values(ok.out, 200);
  // A cell with two commas is not a number: named, as any bad cell is.
  const Imported bad = import_text(tmp, "twocommas", text + "2,00;0,1,2;0;0;0;0;9,8\n", "");
  EXPECT_NE(bad.result.code, 0);
  EXPECT_NE(bad.result.out.find("twocommas.txt:202: column '2 (gx)'"), std::string::npos)
      << bad.result.out;
}

TEST(ImucalImportLoggers, TheHeadersNamesPlaceTheColumnsAndAContradictionIsAnError) {
  test_support::ScopedTempDir tmp("imucal-import-header");
  // The accelerometer first, names with units as loggers write them, a counter to ignore.
  const std::string text =
      "counter,time_s,acc_x [g],acc_y [g],acc_z [g],gyro_x_dps,gyro_y_dps,"
      "gyro_z_dps\n";
  std::string body;
  const std::string data = rows(200, {"t", "ax", "ay", "az", "gx", "gy", "gz"}, ",");
  int k = 0;
  for (size_t pos = 0; pos < data.size(); ++k) {
    const size_t end = data.find('\n', pos);
    body += std::to_string(k) + "," + data.substr(pos, end - pos + 1);
    pos = end + 1;
  }
  const Imported ok = import_text(tmp, "named", text + body, "");
  ASSERT_EQ(ok.result.code, 0) << ok.result.out;
  EXPECT_EQ(ok.report.at("columns_from"), "header");
  EXPECT_EQ(ok.report.at("columns"),
            nlohmann::json({"-", "t", "ax", "ay", "az", "gx", "gy", "gz"}));
  expect_known_values(ok.out, 200);
  // --columns that agree with the header are fine; ones that swap the sensors are refused.
  const Imported agree = import_text(tmp, "agree", text + body, " --columns -,t,ax,ay,az,gx,gy,gz");
  EXPECT_EQ(agree.result.code, 0) << agree.result.out;
  const Imported swapped =
      import_text(tmp, "swapped", text + body, " --columns -,t,gx,gy,gz,ax,ay,az");
  EXPECT_NE(swapped.result.code, 0);
  EXPECT_NE(swapped.result.out.find("swapped.txt:1: the header names the columns "
                                    "-,t,ax,ay,az,gx,gy,gz but the columns given are "
                                    "-,t,gx,gy,gz,ax,ay,az"),
            std::string::npos)
      << swapped.result.out;
  EXPECT_FALSE(fs::exists(swapped.out));
}

// A column the user marks "-" is not read: a text label there (mad-lab-fau/imucal's Ferraris
// sessions carry the section's name, "x_a", on every row) is no bad cell.
TEST(ImucalImportLoggers, AColumnMarkedToIgnoreMayHoldText) {
  test_support::ScopedTempDir tmp("imucal-import-label");
  std::string text;
  const std::string data = rows(200, {"t", "gx", "gy", "gz", "ax", "ay", "az"}, ",");
  for (size_t pos = 0; pos < data.size();) {
    const size_t end = data.find('\n', pos);
    text += "x_a," + data.substr(pos, end - pos + 1);
    pos = end + 1;
  }
  const Imported ok = import_text(tmp, "label", text, " --columns -,t,gx,gy,gz,ax,ay,az");
  ASSERT_EQ(ok.result.code, 0) << ok.result.out;
  expect_known_values(ok.out, 200);
  // Read as a channel, the label is a bad cell named as ever.
  const Imported bad = import_text(tmp, "labelread", text, " --columns t,-,gx,gy,gz,ax,ay,az");
  EXPECT_NE(bad.result.code, 0);
  EXPECT_NE(bad.result.out.find("labelread.txt:1: column '1 (t)'"), std::string::npos)
      << bad.result.out;
}

/// A unit at rest 5 s, turned about z at 90 °/s for 2 s, at rest again: "t gx gy gz ax ay az" in
/// the units given (time factor, gyro and accelerometer factors applied to SI) or as increments.
std::string turned_unit(double time_factor, double gyro_factor, double accel_factor,
                        bool increments = false) {
  std::string s;
  const double dt = 0.01;
  for (int k = 0; k < 1500; ++k) {
    const double t = dt * k;
    const double wz = (t >= 5.0 && t < 7.0) ? 90.0 * 0.017453292519943295 : 0.0;
    const double w[3] = {2e-4, -1e-4, wz + 5e-5};
    const double f[3] = {0.02 * std::sin(0.7 * t), -0.03, 9.807};
    char buf[200];
    const double per = increments ? dt : 1.0;
    std::snprintf(buf, sizeof buf, "%.10g %.10g %.10g %.10g %.10g %.10g %.10g\n", t * time_factor,
                  w[0] * gyro_factor * per, w[1] * gyro_factor * per, w[2] * gyro_factor * per,
                  f[0] * accel_factor * per, f[1] * accel_factor * per, f[2] * accel_factor * per);
    s += buf;
  }
  return s;
}

/// A MEMS unit with gyro offsets of about 1 °/s, at rest 5 s, turned about z at 20 °/s for 4.5 s,
/// at rest again; its gyros written in deg/s (`gyro_deg`) or rad/s.
std::string offset_unit(bool gyro_deg) {
  constexpr double kDeg = 0.017453292519943295;
  std::string s;
  for (int k = 0; k < 1500; ++k) {
    const double t = 0.01 * k;
    const double w[3] = {1.0 * kDeg, -0.6 * kDeg,
                         0.8 * kDeg + (t >= 5.0 && t < 9.5 ? 20.0 * kDeg : 0.0)};
    const double g = gyro_deg ? 1.0 / kDeg : 1.0;
    char buf[200];
    std::snprintf(buf, sizeof buf, "%.10g %.10g %.10g %.10g %.10g %.10g %.10g\n", t, w[0] * g,
                  w[1] * g, w[2] * g, 0.02, -0.03, 9.807);
    s += buf;
  }
  return s;
}

TEST(ImucalImportPlausibility, AGyroRestRateBeyondTheGradesBiasIsRefusedNamingTheGradeOrTheScale) {
  test_support::ScopedTempDir tmp("imucal-import-rest-rate");
  // deg/s read as rad/s: 1.4 °/s of offset reads as 80 °/s at rest, while the turn (1 146 °/s)
  // stays below any gyro's range — only the rest rate tells.
  const Imported deg = import_text(tmp, "deg", offset_unit(true), "");
  EXPECT_NE(deg.result.code, 0);
  EXPECT_NE(deg.result.out.find("deg/s read as rad/s? — give --gyro-scale 0.0174533"),
            std::string::npos)
      << deg.result.out;
  EXPECT_FALSE(fs::exists(deg.out));
  const Imported scaled =
      import_text(tmp, "scaled", offset_unit(true), " --gyro-scale 0.0174532925");
  EXPECT_EQ(scaled.result.code, 0) << scaled.result.out;
  // The same unit in rad/s said to be of navigation grade (the import's default): its 1.4 °/s is
  // no such unit's bias (0.05 °/h) — named, before a calibration would find "no rest".
  const std::string nav_site = " --lat-deg 48.1 --lon-deg 11.6 --height-m 520 --serial LOG-3";
  const std::string file = tmp.path() + "/nav.txt";
  std::ofstream(file) << offset_unit(false);
  const auto nav = run_imucal("import --file " + file + " --out " + tmp.path() + "/nav" + nav_site);
  EXPECT_NE(nav.code, 0);
  EXPECT_NE(nav.out.find("beyond what a navigation unit's bias may be"), std::string::npos)
      << nav.out;
  EXPECT_NE(nav.out.find("another grade (--grade)"), std::string::npos) << nav.out;
  const auto mems = run_imucal("import --file " + file + " --out " + tmp.path() + "/mems" +
                               nav_site + " --grade mems");
  EXPECT_EQ(mems.code, 0) << mems.out;
}

TEST(ImucalImportPlausibility, EachUnitMixUpIsRefusedNamingTheFixAndImportsWithIt) {
  test_support::ScopedTempDir tmp("imucal-import-plausible");
  constexpr double kDeg = 0.017453292519943295, kG = 9.80665;
  struct MixUp {
    const char* name;
    std::string text;
    std::string must_name;  ///< in the refusal
    std::string fix;        ///< the option that makes it import
  };
  const std::vector<MixUp> cases = {
      {"g_as_si", turned_unit(1, 1, 1 / kG), "--accel-scale 9.80665", " --accel-scale 9.80665"},
      {"mg", turned_unit(1, 1, 1000 / kG), "--accel-scale 0.00980665", " --accel-scale 0.00980665"},
      {"counts", turned_unit(1, 1 / (kDeg / 131.0), 16384 / kG), "raw counts without their scale",
       " --accel-scale 5.98550415e-4 --gyro-scale 1.33231240e-4"},  // 9.80665/16384, kDeg/131
      {"deg_as_rad", turned_unit(1, 1 / kDeg, 1), "deg/s read as rad/s",
       " --gyro-scale 0.0174532925"},
      {"ms_as_s", turned_unit(1000, 1, 1),
       "ms read as s? They would give 100 Hz — give --time-unit", " --time-unit ms"},
      {"increments", turned_unit(1, 1, 1, true), "--quantity increments", " --quantity increments"},
  };
  // The same unit in SI imports as it is (so each refusal is its mix-up's).
  const Imported si = import_text(tmp, "si", turned_unit(1, 1, 1), "");
  ASSERT_EQ(si.result.code, 0) << si.result.out;
  for (const MixUp& c : cases) {
    const Imported refused = import_text(tmp, c.name, c.text, "");
    EXPECT_NE(refused.result.code, 0) << c.name << ": " << refused.result.out;
    EXPECT_NE(refused.result.out.find(c.must_name), std::string::npos)
        << c.name << ": " << refused.result.out;
    EXPECT_EQ(std::count(refused.result.out.begin(), refused.result.out.end(), '\n'), 1)
        << c.name << ": " << refused.result.out;
    EXPECT_FALSE(fs::exists(refused.out)) << c.name;
    const Imported fixed = import_text(tmp, std::string(c.name) + "_fixed", c.text, c.fix);
    EXPECT_EQ(fixed.result.code, 0) << c.name << " with" << c.fix << ": " << fixed.result.out;
    if (fixed.result.code == 0) {
      const db::archive::RunArchive ar = db::archive::read_archive(fixed.out);
      const auto& s = ar.imu[100];  // at rest: gravity along z, in SI again
      EXPECT_NEAR(s.dv_mps(2) / s.dt_s, 9.807, 0.01) << c.name;
    }
  }
  // Whoever knows better imports it as read.
  const Imported forced = import_text(tmp, "forced", cases[0].text, " --skip-plausibility");
  EXPECT_EQ(forced.result.code, 0) << forced.result.out;
}

/// Lines of `text` without lines [from, to) (0-based) and with line `twice` written twice.
std::string edit_lines(const std::string& text, size_t from, size_t to, size_t twice) {
  std::string out, line;
  std::istringstream in(text);
  for (size_t k = 0; std::getline(in, line); ++k) {
    if (k >= from && k < to) continue;
    out += line + "\n";
    if (k == twice) out += line + "\n";
  }
  return out;
}

TEST(ImucalImportTime, ARepeatedRowIsDroppedAndAGapKeptUnlessStrictTime) {
  test_support::ScopedTempDir tmp("imucal-import-time");
  const std::string text =
      edit_lines(rows(300, {"t", "gx", "gy", "gz", "ax", "ay", "az"}, " "), 120, 124, 50);
  const Imported ok = import_text(tmp, "logger", text, "");
  ASSERT_EQ(ok.result.code, 0) << ok.result.out;
  EXPECT_EQ(ok.report.at("repeated_rows_dropped"), 1);
  EXPECT_EQ(ok.report.at("gaps"), 1);
  EXPECT_EQ(ok.report.at("samples_missing"), 4);
  const db::archive::RunArchive ar = db::archive::read_archive(ok.out);
  ASSERT_EQ(ar.imu.size(), 296u);
  // Sample 120 of the archive is the recording's sample 124, 50 ms after the one before it.
  EXPECT_NEAR(ar.imu[120].t_s - ar.imu[119].t_s, 0.05, 1e-9);
  EXPECT_NEAR(ar.imu[120].dtheta_rad(0) / 0.01, gyro_at(124, 0), 1e-9);
  EXPECT_NEAR(ar.imu[51].t_s - ar.imu[50].t_s, 0.01, 1e-9);
  EXPECT_NEAR(ar.imu[51].dtheta_rad(0) / 0.01, gyro_at(51, 0), 1e-9);
  // --strict-time: the repeated row refused by its line (the header-less file's line 52).
  const Imported strict = import_text(tmp, "strict", text, " --strict-time");
  EXPECT_NE(strict.result.code, 0);
  EXPECT_NE(strict.result.out.find("strict.txt:52: time 0.5 s does not increase"),
            std::string::npos)
      << strict.result.out;
  EXPECT_FALSE(fs::exists(strict.out));
  // The same stamp with other values is no repeat: refused, whatever the option.
  std::string other = rows(100, {"t", "gx", "gy", "gz", "ax", "ay", "az"}, " ");
  other.insert(other.find("\n", other.find("\n") + 1) + 1, "0.01 1 2 3 4 5 6\n");
  const Imported clash = import_text(tmp, "clash", other, "");
  EXPECT_NE(clash.result.code, 0);
  EXPECT_NE(clash.result.out.find("with other values"), std::string::npos) << clash.result.out;
}

TEST(ImucalImportTime, ARecordingThatLostSamplesInAMoveCalibratesWithoutThatMove) {
  test_support::ScopedTempDir tmp("imucal-import-gap-move");
  const std::string sim_dir = tmp.path() + "/sim";
  const auto sim =
      run_imucal("simulate --sequence hand --setting land --grade mems --seed 4 --out " + sim_dir);
  ASSERT_EQ(sim.code, 0) << sim.out;
  const db::archive::RunArchive ar = db::archive::read_archive(sim_dir);
  // The logger's text: rates, and 8 samples lost around the fastest turn after the first minute.
  size_t fastest = 0;
  for (size_t k = 0; k < ar.imu.size(); ++k)
    if (ar.imu[k].t_s > 60.0 && ar.imu[k].dtheta_rad.norm() > ar.imu[fastest].dtheta_rad.norm())
      fastest = k;
  std::string text;
  for (size_t k = 0; k < ar.imu.size(); ++k) {
    if (k >= fastest - 4 && k < fastest + 4) continue;
    const auto& s = ar.imu[k];
    char buf[256];
    std::snprintf(buf, sizeof buf, "%.6f %.12g %.12g %.12g %.12g %.12g %.12g\n", s.t_s,
                  s.dtheta_rad(0) / s.dt_s, s.dtheta_rad(1) / s.dt_s, s.dtheta_rad(2) / s.dt_s,
                  s.dv_mps(0) / s.dt_s, s.dv_mps(1) / s.dt_s, s.dv_mps(2) / s.dt_s);
    text += buf;
  }
  const std::string file = tmp.path() + "/logger.txt", out = tmp.path() + "/imported";
  std::ofstream(file) << text;
  char site[160];
  std::snprintf(site, sizeof site, " --lat-deg %.9f --lon-deg %.9f --height-m %.3f",
                ar.info.site.lat_rad * kRadToDeg, ar.info.site.lon_rad * kRadToDeg,
                ar.info.site.height_m);
  const auto im =
      run_imucal("import --file " + file + " --out " + out + " --grade mems --serial GAP-1" + site);
  ASSERT_EQ(im.code, 0) << im.out;
  EXPECT_NE(im.out.find("1 gap(s) of dropped samples (8 samples in all) kept"), std::string::npos)
      << im.out;
  const auto cal = run_imucal("calibrate " + out + " --method legacy");
  EXPECT_EQ(cal.code, 0) << cal.out;
  EXPECT_NE(cal.out.find("left out of the gyro fit: 8 samples missing"), std::string::npos)
      << cal.out;
}

/// Sample k's counts of a logger at rest (whole numbers): gyro x y z, accelerometer x y z.
std::array<int, 6> counts_at(int k) {
  return {1 + k % 5, -2 + k % 3, 1 - k % 4, 20 + k % 3, -15 + k % 2, 16341 + k % 7};
}

/// `n` rows of counts, "gx,gy,gz,ax,ay,az", preceded by the time stamp `t_of(k)` (in the file's
/// unit) when one is given.
std::string count_rows(int n, const std::function<double(int)>& t_of = nullptr) {
  std::string s;
  for (int k = 0; k < n; ++k) {
    if (t_of) s += std::to_string(std::llround(t_of(k))) + ",";
    const std::array<int, 6> c = counts_at(k);
    for (int i = 0; i < 6; ++i) s += std::to_string(c[i]) + (i < 5 ? "," : "\n");
  }
  return s;
}

/// run.toml's [noise] of an imported archive: its LSBs and rounding as read, and the text.
struct DeclaredLsbs {
  double dtheta_rad = -1.0, dv_mps = -1.0;
  calib::core::LsbRounding rounding = calib::core::LsbRounding::kCarried;
  std::string toml;
};
DeclaredLsbs declared_lsbs(const std::string& dir) {
  const db::archive::RunArchive ar = db::archive::read_archive(dir);
  std::ifstream f(dir + "/run.toml");
  std::stringstream toml;
  toml << f.rdbuf();
  return {ar.info.dtheta_lsb_rad, ar.info.dv_lsb_mps, ar.info.lsb_rounding, toml.str()};
}

// Issue #50: a logger of counts rounds each rate sample on its own, so the increment's LSB is one
// count × scale × the sample period, and its error is white. The importer declares both in
// run.toml's [noise] (the diagnosis models the quantisation with them) on every path of rates: a
// key,value preamble without a time column (--rate), jittered stamps (the period fitted to them),
// one file per sensor. The expected LSBs are the scales and periods written here; where the axes'
// scales differ, the coarsest.
TEST(ImucalImportResolution, RatesInCountsDeclareOneCountTimesScaleTimesPeriodRoundedPerSample) {
  test_support::ScopedTempDir tmp("imucal-import-lsb");
  const std::string scales = " --gyro-scale 1.3e-4 1.5e-4 1.4e-4 --accel-scale 6e-4";
  const std::string preamble = "device,counts-logger\nrate_hz,200\n";
  const Imported rate = import_text(tmp, "rate", preamble + "gx,gy,gz,ax,ay,az\n" + count_rows(600),
                                    scales + " --rate 200");
  ASSERT_EQ(rate.result.code, 0) << rate.result.out;
  DeclaredLsbs d = declared_lsbs(rate.out);
  EXPECT_NEAR(d.dtheta_rad, 1.5e-4 / 200.0, 1e-12 * d.dtheta_rad);
  EXPECT_NEAR(d.dv_mps, 6e-4 / 200.0, 1e-12 * d.dv_mps);
  EXPECT_EQ(d.rounding, calib::core::LsbRounding::kPerSample);
  EXPECT_NE(d.toml.find("lsb_rounding = \"per_sample\""), std::string::npos) << d.toml;
  EXPECT_EQ(rate.report.at("lsb_rounding"), "per_sample");

  // Stamps in µs at 80 Hz with up to ±200 µs of jitter: the period is the one fitted to them.
  const auto jittered = [](int k) { return 12500.0 * k + 200.0 * std::sin(1.3 * k); };
  const Imported stamped =
      import_text(tmp, "stamped", "t,gx,gy,gz,ax,ay,az\n" + count_rows(800, jittered),
                  scales + " --time-unit us");
  ASSERT_EQ(stamped.result.code, 0) << stamped.result.out;
  d = declared_lsbs(stamped.out);
  EXPECT_NEAR(d.dtheta_rad, 1.5e-4 * 0.0125, 1e-5 * d.dtheta_rad);
  EXPECT_NEAR(d.dv_mps, 6e-4 * 0.0125, 1e-5 * d.dv_mps);
  EXPECT_EQ(d.rounding, calib::core::LsbRounding::kPerSample);

  // One file per sensor ("t x y z"), at 100 Hz.
  std::ofstream gyro(tmp.path() + "/g.txt"), accel(tmp.path() + "/a.txt");
  for (int k = 0; k < 500; ++k) {
    const std::array<int, 6> c = counts_at(k);
    gyro << 0.01 * k << ' ' << c[0] << ' ' << c[1] << ' ' << c[2] << '\n';
    accel << 0.01 * k << ' ' << c[3] << ' ' << c[4] << ' ' << c[5] << '\n';
  }
  gyro.close();
  accel.close();
  const auto pair = run_imucal("import --gyro " + tmp.path() + "/g.txt --accel " + tmp.path() +
                                   "/a.txt --out " + tmp.path() + "/pair" + kLoggerSite + scales,
                               false);
  ASSERT_EQ(pair.code, 0) << pair.out;
  EXPECT_NE(pair.out.find("rates rounded per sample"), std::string::npos) << pair.out;
  d = declared_lsbs(tmp.path() + "/pair");
  EXPECT_NEAR(d.dtheta_rad, 1.5e-4 * 0.01, 1e-9 * d.dtheta_rad);
  EXPECT_NEAR(d.dv_mps, 6e-4 * 0.01, 1e-9 * d.dv_mps);
}

// Issue #50: increment counts (an accumulating register) declare one count × scale with the
// remainder carried (the default, not written); a recording in SI decimals, or in decimals with a
// scale (deg/s), has no resolution the importer knows of and declares none (0) — not the station
// protocol's 1e-9 rad and 1e-7 m/s it never went through.
TEST(ImucalImportResolution, IncrementCountsAreCarriedAndDecimalsDeclareNoLsb) {
  test_support::ScopedTempDir tmp("imucal-import-lsb-inc");
  const Imported inc = import_text(tmp, "inc", "gx,gy,gz,ax,ay,az\n" + count_rows(600),
                                   " --rate 200 --quantity increments --gyro-scale 1e-6 "
                                   "--accel-scale 3e-6");
  ASSERT_EQ(inc.result.code, 0) << inc.result.out;
  DeclaredLsbs d = declared_lsbs(inc.out);
  EXPECT_EQ(d.dtheta_rad, 1e-6);
  EXPECT_EQ(d.dv_mps, 3e-6);
  EXPECT_EQ(d.rounding, calib::core::LsbRounding::kCarried);
  EXPECT_EQ(d.toml.find("lsb_rounding"), std::string::npos) << d.toml;

  const std::string si_rows = rows(300, {"t", "gx", "gy", "gz", "ax", "ay", "az"}, " ");
  const Imported si = import_text(tmp, "si", si_rows, "");
  ASSERT_EQ(si.result.code, 0) << si.result.out;
  d = declared_lsbs(si.out);
  EXPECT_EQ(d.dtheta_rad, 0.0);
  EXPECT_EQ(d.dv_mps, 0.0);
  const Imported deg = import_text(tmp, "deg", si_rows, " --gyro-scale 0.0174533");
  ASSERT_EQ(deg.result.code, 0) << deg.result.out;
  EXPECT_EQ(declared_lsbs(deg.out).dtheta_rad, 0.0);
}

}  // namespace
}  // namespace imucal
