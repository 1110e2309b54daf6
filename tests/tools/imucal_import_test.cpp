// `imucal import` (issue #21 item 5): a raw recording as it comes — here a simulated MEMS
// hand-placed run written out as a logger would (rates in deg/s and g, time in ms stamped by a
// host clock with jitter, columns in its own order, a header, a column to ignore) — becomes an
// archive that calibrates exactly like the simulator's own: the re-stamping onto the sensor's grid
// loses nothing. Bad input names the file, line and column (or the option), exits non-zero and
// writes nothing.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "calib/core/body_frame.hpp"
#include "calib/core/conventions.hpp"
#include "db/archive/param_json.hpp"
#include "db/archive/run_archive.hpp"
#include "tests/support/imucal_cli.hpp"
#include "tests/support/temp_dir.hpp"

namespace imucal {
namespace {

namespace fs = std::filesystem;
using test_support::run_imucal;

constexpr double kJitter_s = 100e-6;  ///< host stamps' jitter, RMS
const char* const kSite = " --lat-deg 48.1 --lon-deg 11.6 --height-m 520 --serial LOGGER-1";

/// A number on a command line, every digit (std::to_string keeps six decimals: 17 ppm of a scale).
std::string exact(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.17g", v);
  return buf;
}

/// The archive's samples as a logger's CSV: "counter;t_ms;ax;ay;az;gx;gy;gz" in g and deg/s.
void write_logger_csv(const db::archive::RunArchive& a, const std::string& path, uint64_t seed) {
  std::ofstream f(path);
  f << "counter;t_ms;ax_g;ay_g;az_g;gx_dps;gy_dps;gz_dps\n";
  f.precision(17);
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> jitter(0.0, kJitter_s);
  for (size_t k = 0; k < a.imu.size(); ++k) {
    const auto& s = a.imu[k];
    const Eigen::Vector3d f_g = s.dv_mps / s.dt_s / 9.80665;
    const Eigen::Vector3d w_dps = s.dtheta_rad / s.dt_s / kDegToRad;
    f << k << ';' << (s.t_s + jitter(rng)) * 1e3 << ';' << f_g(0) << ';' << f_g(1) << ';' << f_g(2)
      << ';' << w_dps(0) << ';' << w_dps(1) << ';' << w_dps(2) << '\n';
  }
}

calib::core::ParamSet params_of_imucal_import(const nlohmann::json& p) {
  return db::archive::param_set_from_json(p, "imucal calibrate --json");
}

nlohmann::json legacy_params(const std::string& dir) {
  const auto r = run_imucal("calibrate " + dir + " --method legacy --json", false);
  EXPECT_EQ(r.code, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j.at("verdict"), "PASS") << dir;
  return j.at("legacy");
}

TEST(ImucalImport, ALoggersCsvWithJitterCalibratesLikeTheSimulatorsOwnArchive) {
  test_support::ScopedTempDir tmp("imucal-import");
  const std::string sim = tmp.path() + "/sim", csv = tmp.path() + "/log.csv",
                    out = tmp.path() + "/imported";
  ASSERT_EQ(
      run_imucal("simulate --sequence hand --setting land --grade mems --seed 5 --out " + sim).code,
      0);
  const db::archive::RunArchive a = db::archive::read_archive(sim);
  write_logger_csv(a, csv, 5);
  // The logger's own site: the simulator's (normal gravity there, no surveyed value).
  const std::string site =
      " --serial LOGGER-1 --lat-deg " + exact(a.info.site.lat_rad / kDegToRad) + " --lon-deg " +
      exact(a.info.site.lon_rad / kDegToRad) + " --height-m " + exact(a.info.site.height_m);
  const auto r = run_imucal(
      "import --file " + csv + " --columns -,t,ax,ay,az,gx,gy,gz --time-unit ms --gyro-scale " +
          exact(kDegToRad) + " --accel-scale 9.80665 --grade mems --json --out " + out + site,
      false);
  ASSERT_EQ(r.code, 0) << r.out;
  const nlohmann::json rep = nlohmann::json::parse(r.out);
  EXPECT_EQ(rep.at("samples").get<size_t>(), a.imu.size());
  EXPECT_NEAR(rep.at("rate_hz").get<double>(), a.info.imu_rate_hz, 1e-6 * a.info.imu_rate_hz);
  // The stamps' jitter is measured as injected (RMS within 10 %), and the samples are put back
  // on the sensor's grid: every time within 5 µs of the simulator's (0.05 % of a period: the
  // period fitted to 35 000 jittered stamps), every increment the simulator's to 1e-7.
  EXPECT_NEAR(rep.at("jitter_rms_s").get<double>(), kJitter_s, 0.1 * kJitter_s);
  const db::archive::RunArchive b = db::archive::read_archive(out);
  ASSERT_EQ(b.imu.size(), a.imu.size());
  double worst_t = 0.0, worst_rel = 0.0;
  for (size_t k = 0; k < a.imu.size(); ++k) {
    worst_t = std::max(worst_t, std::abs(b.imu[k].t_s - a.imu[k].t_s));
    worst_rel = std::max(
        worst_rel, (b.imu[k].dtheta_rad - a.imu[k].dtheta_rad).norm() / a.imu[k].dtheta_rad.norm());
    worst_rel =
        std::max(worst_rel, (b.imu[k].dv_mps - a.imu[k].dv_mps).norm() / a.imu[k].dv_mps.norm());
  }
  EXPECT_LT(worst_t, 5e-6);
  EXPECT_LT(worst_rel, 1e-7);
  EXPECT_EQ(b.info.grade, calib::core::Grade::kMems);
  EXPECT_EQ(b.info.setting, calib::core::Setting::kLand);
  // Calibrated, the two archives agree within a quarter σ on every term — what one sample more or
  // less at a rest's edge moves (the rests are cut at stamps that now differ by a microsecond) —
  // and both within 4σ of the truth.
  const nlohmann::json pa = legacy_params(sim), pb = legacy_params(out);
  const calib::core::ParamSet truth = calib::core::to_accel_symmetric_frame(a.truth->params).params;
  const calib::core::ParamVector t = truth.to_vector();
  const calib::core::ParamVector va = params_of_imucal_import(pa.at("params")).to_vector(),
                                 vb = params_of_imucal_import(pb.at("params")).to_vector(),
                                 sa = params_of_imucal_import(pa.at("sigma")).to_vector();
  for (int i = 0; i < 24; ++i) {
    EXPECT_LT(std::abs(va(i) - vb(i)), 0.3 * sa(i)) << calib::core::param_info(i).name;
    EXPECT_LT(std::abs(vb(i) - t(i)), 4.0 * sa(i)) << calib::core::param_info(i).name;
  }
}

/// A small recording "t gx gy gz ax ay az" at 100 Hz, whitespace-separated, with a comment.
std::string small_recording(size_t n) {
  std::string s = "# logger v1\n";
  for (size_t k = 0; k < n; ++k)
    s += std::to_string(0.01 * static_cast<double>(k)) + "  0.001 0.002 0.003\t0.1 0.2 9.8\n";
  return s;
}

struct BadCase {
  const char* name;
  std::string text;       ///< the --file contents
  std::string flags;      ///< beyond --file and --out
  std::string must_name;  ///< in the one-line error
};

TEST(ImucalImport, BadInputNamesFileLineAndColumnAndWritesNothing) {
  test_support::ScopedTempDir tmp("imucal-import-bad");
  const std::string good = small_recording(50);
  auto replace_line = [&](int line, const std::string& with) {  // 1-based, line 1 = comment
    std::string s = good;
    size_t pos = 0;
    for (int l = 1; l < line; ++l) pos = s.find('\n', pos) + 1;
    return s.substr(0, pos) + with + s.substr(s.find('\n', pos));
  };
  auto drop_lines = [&](int from, int to) {  // 1-based, inclusive: dropped samples
    size_t a = 0, b = 0;
    for (int l = 1; l < from; ++l) a = good.find('\n', a) + 1;
    b = a;
    for (int l = from; l <= to; ++l) b = good.find('\n', b) + 1;
    return good.substr(0, a) + good.substr(b);
  };
  const std::vector<BadCase> cases = {
      {"cell", replace_line(5, "0.03 0.001 1.2x 0.003 0.1 0.2 9.8"), kSite,
       "rec.txt:5: column '3 (gy)'"},
      {"columns", replace_line(6, "0.04 0.001 0.002 0.1 0.2 9.8"), kSite,
       "rec.txt:6: 6 columns, expected 7"},
      {"time", replace_line(7, "0.02 0.001 0.002 0.003 0.1 0.2 9.8"), kSite,
       "rec.txt:7: time 0.02 s does not increase"},
      {"gap", drop_lines(10, 19), std::string(kSite) + " --strict-time", "rec.txt:10: a gap of"},
      {"nan", replace_line(4, "0.02 nan 0.002 0.003 0.1 0.2 9.8"), kSite,
       "rec.txt:4: column '2 (gx)'"},
      {"site", good, " --serial X", "--lat-deg"},
      {"grade", good, std::string(kSite) + " --grade consumer", "grade 'consumer'"},
      {"names", good, std::string(kSite) + " --columns t,gx,gy,gz,ax,ay",
       "'az' must appear exactly once"},
      {"scale", good, std::string(kSite) + " --gyro-scale 1 2", "--gyro-scale takes one value"},
      {"unit", good, std::string(kSite) + " --time-unit min", "time unit 'min'"},
  };
  for (const BadCase& c : cases) {
    const std::string file = tmp.path() + "/rec.txt", out = tmp.path() + "/out";
    std::ofstream(file) << c.text;
    const auto r = run_imucal("import --file " + file + " --out " + out + c.flags);
    EXPECT_NE(r.code, 0) << c.name << ": " << r.out;
    EXPECT_NE(r.out.find(c.must_name), std::string::npos) << c.name << ": " << r.out;
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << c.name << ": " << r.out;
    EXPECT_FALSE(fs::exists(out)) << c.name;
  }
  // The good recording imports (so every refusal above is the one defect's).
  std::ofstream(tmp.path() + "/rec.txt") << good;
  const auto ok =
      run_imucal("import --file " + tmp.path() + "/rec.txt --out " + tmp.path() + "/ok" + kSite);
  EXPECT_EQ(ok.code, 0) << ok.out;
  EXPECT_TRUE(fs::exists(tmp.path() + "/ok/run.toml"));
}

TEST(ImucalImport, OneFilePerSensorMustHoldTheSameSamplesAndTheConfigIsStrict) {
  test_support::ScopedTempDir tmp("imucal-import-pair");
  std::string g, a;
  for (int k = 0; k < 40; ++k) {
    g += std::to_string(0.01 * k) + " 0.01 0.02 0.03\n";
    a += std::to_string(0.01 * k) + " 0.1 0.2 9.8\n";
  }
  std::ofstream(tmp.path() + "/g.txt") << g;
  std::ofstream(tmp.path() + "/a.txt") << a + "0.4 0.1 0.2 9.8\n";
  const std::string out = tmp.path() + "/out";
  const auto rows = run_imucal("import --gyro " + tmp.path() + "/g.txt --accel " + tmp.path() +
                               "/a.txt --out " + out + kSite);
  EXPECT_NE(rows.code, 0);
  EXPECT_NE(rows.out.find("a.txt: 41 data rows"), std::string::npos) << rows.out;
  EXPECT_FALSE(fs::exists(out));
  std::ofstream(tmp.path() + "/a.txt") << a;
  std::ofstream(tmp.path() + "/c.toml") << "[gyro]\nscale = 1.0\nofset = 3\n";
  const auto key = run_imucal("import --gyro " + tmp.path() + "/g.txt --accel " + tmp.path() +
                              "/a.txt --config " + tmp.path() + "/c.toml --out " + out + kSite);
  EXPECT_NE(key.code, 0);
  EXPECT_NE(key.out.find("c.toml:3"), std::string::npos) << key.out;
  EXPECT_NE(key.out.find("ofset"), std::string::npos) << key.out;
  EXPECT_FALSE(fs::exists(out));
  const auto both = run_imucal("import --file " + tmp.path() + "/g.txt --gyro " + tmp.path() +
                               "/g.txt --accel " + tmp.path() + "/a.txt --out " + out + kSite);
  EXPECT_NE(both.code, 0);
  EXPECT_NE(both.out.find("either --file"), std::string::npos) << both.out;
  const auto fine = run_imucal("import --gyro " + tmp.path() + "/g.txt --accel " + tmp.path() +
                               "/a.txt --out " + out + kSite);
  EXPECT_EQ(fine.code, 0) << fine.out;
  const db::archive::RunArchive ar = db::archive::read_archive(out);
  ASSERT_EQ(ar.imu.size(), 40u);
  EXPECT_NEAR(ar.imu[3].dtheta_rad(1), 0.02 * 0.01, 1e-12);  // rate × period
  EXPECT_NEAR(ar.imu[3].dv_mps(2), 9.8 * 0.01, 1e-12);
}

// A recording with no rest at all (a unit turned the whole time) imports — it is well-formed — but
// no calibration can use it: one line naming the file and why, exit 1, the archive as it was.
TEST(ImucalImport, ARecordingWithNoRestAtAllIsRefusedByTheCalibrationAtMemsGrade) {
  test_support::ScopedTempDir tmp("imucal-import-norest");
  std::string text;
  for (int k = 0; k < 6000; ++k) {
    const double t = 0.01 * k;
    text += std::to_string(t) + " " + std::to_string(0.5 * std::sin(0.3 * t) + 0.3) + " " +
            std::to_string(0.2 * std::cos(0.5 * t)) + " 0.1 " + std::to_string(0.5 * std::sin(t)) +
            " 0.3 9.8\n";
  }
  std::ofstream(tmp.path() + "/rec.txt") << text;
  const std::string out = tmp.path() + "/run";
  ASSERT_EQ(
      run_imucal("import --file " + tmp.path() + "/rec.txt --grade mems --out " + out + kSite).code,
      0);
  const std::string before = test_support::listing(out);
  const auto r = run_imucal("calibrate " + out);
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("imu.csv: no usable first rest"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("no rest found in the IMU data at all"), std::string::npos) << r.out;
  EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << r.out;
  EXPECT_EQ(test_support::listing(out), before);
}

}  // namespace
}  // namespace imucal
