// `imucal import` as loggers write (issue #48 item 4): a microcontroller's log with a "key,value"
// preamble and no time column, a fixed preamble of numbers skipped by count, decimal commas with
// ';', and columns taken from the header's own names — a header that contradicts --columns is an
// error naming both, never silently overruled (a gyro and accelerometer swapped that way used to
// import with exit 0 and come back from `calibrate` as "no rest found"). Each case's recording is
// one whose values are known, and the test reads them back from the archive.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "db/archive/run_archive.hpp"
#include "tests/support/imucal_cli.hpp"
#include "tests/support/temp_dir.hpp"

namespace imucal {
namespace {

namespace fs = std::filesystem;
using test_support::run_imucal;

const char* const kLoggerSite = " --lat-deg 48.1 --lon-deg 11.6 --height-m 520 --serial LOG-2";

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
  EXPECT_NE(refused.result.out.find("plain.txt:2: time 12 s does not increase"), std::string::npos)
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

}  // namespace
}  // namespace imucal
