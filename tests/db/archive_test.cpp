// Run archive (ARCHITECTURE §5): bit-exact write/read round trip of a simulated run, the
// calibration input it yields vs. the in-memory path, one test per class of bad archive (each error
// must name the file and the line or field), atomic writes, and the attitude.csv reference checked
// by hand.
#include <gtest/gtest.h>
#include <stdlib.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "calib/core/calibration_input.hpp"
#include "calib/core/conventions.hpp"
#include "calib/core/earth.hpp"
#include "calib/core/rotation.hpp"
#include "calib/sim/sim_input.hpp"
#include "db/archive/archive_error.hpp"
#include "db/archive/archive_input.hpp"
#include "db/archive/io_util.hpp"
#include "db/archive/run_archive.hpp"
#include "tests/support/temp_dir.hpp"

namespace imucal::db::archive {
namespace {

namespace fs = std::filesystem;

using TempDir = test_support::ScopedTempDir;

/// Entries of a directory, sorted (to detect leftovers of a failed write).
std::vector<std::string> dir_entries(const TempDir& dir) {
  std::vector<std::string> v;
  for (const auto& e : fs::directory_iterator(dir.path()))
    v.push_back(e.path().filename().string());
  std::sort(v.begin(), v.end());
  return v;
}

std::string slurp(const std::string& p) { return read_text_file(p); }
void put(const std::string& p, const std::string& text) {
  std::ofstream f(p, std::ios::trunc | std::ios::binary);
  f << text;
}
void replace_in_file(const std::string& p, const std::string& from, const std::string& to) {
  std::string s = slurp(p);
  const size_t i = s.find(from);
  ASSERT_NE(i, std::string::npos) << "'" << from << "' not in " << p;
  s.replace(i, from.size(), to);
  put(p, s);
}

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

const calib::core::Site kSite{55.78 * kDegToRad, 12.52 * kDegToRad, 25.0, std::nullopt};

// 2 s rest, 90 deg outer-axis turn in 2 s (bang-bang), 2 s rest: enough for every check.
sequences::MotionProfile short_profile() {
  const double a = 90.0 * kDegToRad;  // rad/s^2: 0.5 a 1^2 twice = 90 deg
  sequences::MotionProfile p;
  p.name = "short";
  sequences::ProfileSegment r0{0.0, 2.0, sequences::SegmentKind::kRest, {}, {}, 0};
  sequences::ProfileSegment m1{2.0, 3.0, sequences::SegmentKind::kMove, {0.0, 0.0, a}, {}, 1};
  sequences::ProfileSegment m2{3.0, 4.0, sequences::SegmentKind::kMove, {0.5 * a, a, -a}, {}, 1};
  sequences::ProfileSegment r1{4.0, 6.0, sequences::SegmentKind::kRest, {a, 0.0, 0.0}, {}, 2};
  p.segments = {r0, m1, m2, r1};
  return p;
}

struct SimRun {
  RunArchive archive;
  calib::sim::SimResult sim;
  calib::core::TableGeometry geometry;
};

SimRun simulated_run() {
  SimRun r;
  r.geometry.heading_rad = 1.5 * kDegToRad;
  r.geometry.C_bp =
      calib::core::euler_to_C_bn(0.5 * kDegToRad, -0.25 * kDegToRad, 180.0 * kDegToRad);
  calib::effects::UnitModel unit = calib::effects::default_unit();
  unit.effects.accel_k2_per_mps2 = {1e-6, 0.0, 0.0};
  calib::sim::SimOptions opt;
  opt.rate_hz = 100.0;
  opt.seed = 7;
  r.sim = calib::sim::simulate(short_profile(), r.geometry, kSite, unit, opt);

  RunInfo& ri = r.archive.info;
  ri.serial = "FOG-2024-0042";
  ri.station_name = "factory \"A\" bay 3";  // needs escaping in TOML
  ri.site = kSite;
  ri.site.gravity_mps2 = 9.815432;
  ri.imu_rate_hz = opt.rate_hz;
  ri.table = TableSetup::from_geometry(r.geometry);
  ri.sequence_name = "short";
  ri.sequence_sha256 = std::string(64, 'a');
  ri.software_version = "0.1.0";
  ri.start_time = "2024-05-01T10:00:00Z";
  ri.end_time = "2024-05-01T10:00:06.5+02:00";
  ri.reference = ReferenceKind::kTable;
  ri.arw_rad_per_sqrt_s = unit.noise.arw_rad_per_sqrt_s;
  ri.vrw_mps_per_sqrt_s = unit.noise.vrw_mps_per_sqrt_s;
  r.archive.imu = r.sim.imu;
  r.archive.table = r.sim.table;
  r.archive.truth = truth_from_unit(unit);
  return r;
}

ArchiveError read_error(const std::string& dir) {
  try {
    const RunArchive a = read_archive(dir);
    to_calibration_input(a);
  } catch (const ArchiveError& e) {
    return e;
  }
  ADD_FAILURE() << "no ArchiveError reading " << dir;
  return ArchiveError("none", "none");
}

TEST(Archive, SimulatedRunRoundTripsBitExactly) {
  TempDir tmp("imucal_archive_test");
  const SimRun run = simulated_run();
  const std::string dir = tmp.sub("run1");
  write_archive(dir, run.archive);
  const RunArchive b = read_archive(dir);
  const RunArchive& a = run.archive;

  EXPECT_EQ(b.origin, dir);
  EXPECT_EQ(b.info.serial, a.info.serial);
  EXPECT_EQ(b.info.station_name, a.info.station_name);
  EXPECT_TRUE(same_bits(b.info.site.lat_rad, a.info.site.lat_rad));
  EXPECT_TRUE(same_bits(b.info.site.lon_rad, a.info.site.lon_rad));
  EXPECT_TRUE(same_bits(b.info.site.height_m, a.info.site.height_m));
  ASSERT_TRUE(b.info.site.gravity_mps2.has_value());
  EXPECT_TRUE(same_bits(*b.info.site.gravity_mps2, *a.info.site.gravity_mps2));
  EXPECT_EQ(b.info.imu_rate_hz, a.info.imu_rate_hz);
  EXPECT_EQ(b.info.table.outer_axis_t, a.info.table.outer_axis_t);
  EXPECT_EQ(b.info.table.inner_axis_o, a.info.table.inner_axis_o);
  EXPECT_TRUE(same_bits(b.info.table.heading_rad, a.info.table.heading_rad));
  // C_bp -> roll/pitch/yaw -> deg -> rad: the matrix survives to round-off.
  EXPECT_LT((b.info.table.geometry().C_bp - run.geometry.C_bp).cwiseAbs().maxCoeff(), 1e-15);
  EXPECT_EQ(b.info.sequence_name, a.info.sequence_name);
  EXPECT_EQ(b.info.sequence_sha256, a.info.sequence_sha256);
  EXPECT_EQ(b.info.software_version, a.info.software_version);
  EXPECT_EQ(b.info.start_time, a.info.start_time);
  EXPECT_EQ(b.info.end_time, a.info.end_time);
  EXPECT_EQ(b.info.reference, ReferenceKind::kTable);
  EXPECT_TRUE(same_bits(b.info.arw_rad_per_sqrt_s, a.info.arw_rad_per_sqrt_s));
  EXPECT_TRUE(same_bits(b.info.vrw_mps_per_sqrt_s, a.info.vrw_mps_per_sqrt_s));

  ASSERT_EQ(b.imu.size(), a.imu.size());
  ASSERT_EQ(b.imu.size(), 600u);
  for (size_t k = 0; k < a.imu.size(); ++k) {
    ASSERT_TRUE(same_bits(b.imu[k].t_s, a.imu[k].t_s)) << k;
    for (int i = 0; i < 3; ++i) {
      ASSERT_TRUE(same_bits(b.imu[k].dtheta_rad(i), a.imu[k].dtheta_rad(i))) << k;
      ASSERT_TRUE(same_bits(b.imu[k].dv_mps(i), a.imu[k].dv_mps(i))) << k;
    }
    ASSERT_TRUE(same_bits(b.imu[k].temp_c, a.imu[k].temp_c)) << k;
    // dt is derived from t_s: the simulator's constant 1/rate to round-off of the time stamps.
    ASSERT_NEAR(b.imu[k].dt_s, a.imu[k].dt_s, 1e-15) << k;
  }
  ASSERT_EQ(b.table.size(), a.table.size());
  size_t exact_angles = 0;
  for (size_t k = 0; k < a.table.size(); ++k) {
    ASSERT_TRUE(same_bits(b.table[k].t_s, a.table[k].t_s)) << k;
    ASSERT_EQ(b.table[k].at_rest, a.table[k].at_rest) << k;
    // Radians go through degrees; the writer picks the degree value that maps back exactly when
    // one exists (about 90 % of doubles), otherwise the nearest (1 ulp).
    for (auto [x, y] : {std::pair{b.table[k].outer_rad, a.table[k].outer_rad},
                        std::pair{b.table[k].inner_rad, a.table[k].inner_rad}}) {
      ASSERT_LE(std::fabs(x - y), std::fabs(std::nextafter(y, 10.0) - y) + 1e-300) << k;
      exact_angles += same_bits(x, y);
    }
  }
  EXPECT_GE(exact_angles, a.table.size() * 2 * 8 / 10);
  ASSERT_TRUE(b.truth.has_value());
  EXPECT_EQ(b.truth->params.to_vector(), a.truth->params.to_vector());
  EXPECT_EQ(b.truth->effects, a.truth->effects);

  // Writing what was read reproduces the files byte for byte (idempotent format).
  const std::string dir2 = tmp.sub("run2");
  write_archive(dir2, b);
  for (const char* f : {"run.toml", "imu.csv", "table.csv", "truth.json"})
    EXPECT_EQ(slurp(dir + "/" + f), slurp(dir2 + "/" + f)) << f;
}

TEST(Archive, CalibrationInputMatchesTheInMemoryPath) {
  TempDir tmp("imucal_archive_test");
  const SimRun run = simulated_run();
  write_archive(tmp.sub("run"), run.archive);
  const calib::core::CalibrationInput from_disk =
      to_calibration_input(read_archive(tmp.sub("run")));
  calib::core::NoiseModel noise;
  noise.arw_rad_per_sqrt_s = run.archive.info.arw_rad_per_sqrt_s;
  noise.vrw_mps_per_sqrt_s = run.archive.info.vrw_mps_per_sqrt_s;
  const calib::core::CalibrationInput mem =
      calib::sim::input_from_simulation(run.sim, run.geometry, run.archive.info.site, noise);
  ASSERT_EQ(from_disk.reference.size(), mem.reference.size());
  size_t rest = 0;
  for (size_t k = 0; k < mem.reference.size(); ++k) {
    ASSERT_LT((from_disk.reference[k].C_bn_ref - mem.reference[k].C_bn_ref).cwiseAbs().maxCoeff(),
              1e-15)
        << k;
    ASSERT_EQ(from_disk.reference[k].at_rest, mem.reference[k].at_rest);
    ASSERT_EQ(from_disk.reference[k].t_s, mem.imu[k].t_s);
    rest += mem.reference[k].at_rest;
  }
  // Two 2 s rests less 0.5 s guards at each end, at 100 Hz: 2 x 100 samples.
  EXPECT_NEAR(static_cast<double>(rest), 200.0, 2.0);
  EXPECT_EQ(from_disk.site.lat_rad, kSite.lat_rad);
  EXPECT_EQ(*from_disk.site.gravity_mps2, 9.815432);
  EXPECT_EQ(from_disk.noise.arw_rad_per_sqrt_s, noise.arw_rad_per_sqrt_s);
  EXPECT_EQ(from_disk.noise.dtheta_lsb_rad, calib::core::NoiseModel{}.dtheta_lsb_rad);
  // The 90 deg outer turn is a rotation about the outer axis, fixed in n: a_n = Rz(heading) a_t.
  const Eigen::Matrix3d C0 = from_disk.reference.front().C_bn_ref;
  const Eigen::Matrix3d C1 = from_disk.reference.back().C_bn_ref;
  const Eigen::Matrix3d R_n = C1 * C0.transpose();
  const Eigen::Vector3d a_n = calib::core::euler_to_C_bn(0, 0, run.geometry.heading_rad) *
                              run.geometry.outer_axis_t.normalized();
  EXPECT_LT((R_n * a_n - a_n).norm(), 1e-12);
  EXPECT_NEAR(calib::core::matrix_to_rotvec(R_n).norm(), 90.0 * kDegToRad, 1e-12);
}

// Writes a valid table-referenced archive: n samples at 100 Hz, level and at rest except where
// the caller changes things. Returns the directory.
std::string write_simple(const TempDir& tmp, const std::string& name, size_t n = 50) {
  RunArchive a;
  a.info.serial = "S1";
  a.info.site = kSite;
  a.info.imu_rate_hz = 100.0;
  const double g = calib::core::EarthModel(kSite).gravity_mps2();
  for (size_t k = 0; k < n; ++k) {
    calib::core::ImuIncrement s;
    s.t_s = static_cast<double>(k + 1) / 100.0;  // correctly rounded: shortest text "0.03"
    s.dt_s = k == 0 ? 0.01 : s.t_s - a.imu.back().t_s;
    s.dv_mps = {0.0, 0.0, -g * 0.01};
    s.temp_c = std::nan("");
    a.imu.push_back(s);
    a.table.push_back({s.t_s, 0.0, 0.0, k >= 10});
  }
  const std::string dir = tmp.sub(name);
  write_archive(dir, a);
  return dir;
}

TEST(Archive, SimpleArchiveIsValidAndHasNoTempColumn) {
  TempDir tmp("imucal_archive_test");
  const std::string dir = write_simple(tmp, "ok");
  const RunArchive a = read_archive(dir);
  EXPECT_TRUE(std::isnan(a.imu[0].temp_c));
  EXPECT_EQ(a.imu[0].dt_s, 0.01);  // first interval = 1 / rate_hz
  const std::string head =
      "t_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps\n0.01,";
  EXPECT_EQ(slurp(dir + "/imu.csv").substr(0, head.size()), head);
  EXPECT_EQ(to_calibration_input(a).reference.size(), 50u);
  EXPECT_FALSE(fs::exists(dir + "/truth.json"));
}

TEST(Archive, UnknownRunTomlKeyNamedWithLine) {
  TempDir tmp("imucal_archive_test");
  const std::string dir = write_simple(tmp, "r");
  replace_in_file(dir + "/run.toml", "[imu]\nrate_hz = 100.0\n",
                  "[imu]\nrate_hz = 100.0\nrate = 200\n");
  const ArchiveError e = read_error(dir);
  EXPECT_EQ(e.file(), dir + "/run.toml");
  EXPECT_EQ(e.field(), "imu.rate");
  const std::string text = slurp(dir + "/run.toml");
  const size_t expected_line =
      1 + static_cast<size_t>(std::count(
              text.begin(), text.begin() + static_cast<long>(text.find("rate = 200")), '\n'));
  EXPECT_EQ(e.line(), expected_line);
  EXPECT_NE(std::string(e.what()).find("unknown key"), std::string::npos) << e.what();
}

// [prior] (issue #21): the grade and the shortest rest, read, written back only when they say
// something, and refused with file, line and key when wrong.
TEST(Archive, PriorGradeReadsWritesBackAndIsRefusedWhenWrong) {
  TempDir tmp("imucal_archive_test");
  const std::string dir = write_simple(tmp, "r");
  const std::string orig = slurp(dir + "/run.toml");
  EXPECT_EQ(orig.find("[prior]"), std::string::npos);  // navigation grade: not written
  EXPECT_EQ(read_archive(dir).info.grade, calib::core::Grade::kNavigation);
  replace_in_file(dir + "/run.toml", "[imu]\n",
                  "[prior]\ngrade = \"mems\"\nmin_rest_s = 2.5\n[imu]\n");
  RunArchive a = read_archive(dir);
  EXPECT_EQ(a.info.grade, calib::core::Grade::kMems);
  EXPECT_EQ(a.info.min_rest_s, 2.5);
  const std::string again = tmp.path() + "/again";
  write_archive(again, a, false);
  const RunArchive b = read_archive(again);
  EXPECT_EQ(b.info.grade, calib::core::Grade::kMems);
  EXPECT_EQ(b.info.min_rest_s, 2.5);
  struct Case {
    std::string prior, field, says;
  };
  for (const Case& c :
       {Case{"grade = \"consumer\"", "prior.grade", "\"navigation\", \"tactical\" or \"mems\""},
        Case{"min_rest_s = 0.1", "prior.min_rest_s", "[0.5, 600]"},
        Case{"grades = \"mems\"", "prior.grades", "unknown key"},
        Case{"scale_ppm = 600000", "prior.scale_ppm", "(0, 500000] ppm"},
        Case{"gyro_bias_deg_per_s = 0", "prior.gyro_bias_deg_per_s", "(0, 100] deg/s"},
        Case{"accel_bias_mg = -5", "prior.accel_bias_mg", "(0, 2000] mg"},
        Case{"misalignment_mrad = 250", "prior.misalignment_mrad", "(0, 200] mrad"}}) {
    put(dir + "/run.toml", orig);
    replace_in_file(dir + "/run.toml", "[imu]\n", "[prior]\n" + c.prior + "\n[imu]\n");
    const ArchiveError e = read_error(dir);
    EXPECT_EQ(e.field(), c.field) << e.what();
    EXPECT_EQ(e.file(), dir + "/run.toml");
    EXPECT_GT(e.line(), 0u);
    EXPECT_NE(std::string(e.what()).find(c.says), std::string::npos) << e.what();
  }
}

// Issue #27: the protocol the daemon read the unit through and its resolution are recorded; the
// resolution reaches the calibration input's noise model (the gap diagnosis' quantisation) and
// survives a write/read; the built-in protocol's resolution is not written.
TEST(Archive, TheProtocolAndItsResolutionReadWriteBackAndReachTheInput) {
  TempDir tmp("imucal_archive_test");
  const std::string dir = write_simple(tmp, "r");
  const std::string orig = slurp(dir + "/run.toml");
  EXPECT_EQ(orig.find("dtheta_lsb_rad"), std::string::npos);
  replace_in_file(dir + "/run.toml", "[imu]\n", "[imu]\nprotocol = \"rates16\"\n");
  replace_in_file(dir + "/run.toml", "[noise]\n",
                  "[noise]\ndtheta_lsb_rad = 1.75e-6\ndv_lsb_mps = 9.8e-5\n");
  const RunArchive a = read_archive(dir);
  EXPECT_EQ(a.info.imu_protocol, "rates16");
  EXPECT_EQ(a.info.dtheta_lsb_rad, 1.75e-6);
  EXPECT_EQ(a.info.dv_lsb_mps, 9.8e-5);
  const calib::core::CalibrationInput in = to_calibration_input(a);
  EXPECT_EQ(in.noise.dtheta_lsb_rad, 1.75e-6);
  EXPECT_EQ(in.noise.dv_lsb_mps, 9.8e-5);
  const std::string again = tmp.path() + "/again";
  write_archive(again, a, false);
  const RunArchive b = read_archive(again);
  EXPECT_EQ(b.info.imu_protocol, "rates16");
  EXPECT_EQ(b.info.dtheta_lsb_rad, 1.75e-6);
  EXPECT_EQ(b.info.dv_lsb_mps, 9.8e-5);
  put(dir + "/run.toml", orig);
  replace_in_file(dir + "/run.toml", "[noise]\n", "[noise]\ndv_lsb_mps = -1\n");
  const ArchiveError e = read_error(dir);
  EXPECT_EQ(e.field(), "noise.dv_lsb_mps") << e.what();
  EXPECT_NE(std::string(e.what()).find("[0, 1)"), std::string::npos) << e.what();
}

// Issue #50: how the LSBs were rounded ([noise] lsb_rounding) reads, reaches the calibration input
// and survives a write/read; absent it is the carried rounding (an archive from before reads
// unchanged, and the default is not written); a value other than the two is refused naming the
// file, line and key.
TEST(Archive, TheLsbRoundingReadsWritesBackAndIsRefusedWhenWrong) {
  TempDir tmp("imucal_archive_test");
  const std::string dir = write_simple(tmp, "r");
  const std::string orig = slurp(dir + "/run.toml");
  EXPECT_EQ(orig.find("lsb_rounding"), std::string::npos);
  EXPECT_EQ(to_calibration_input(read_archive(dir)).noise.lsb_rounding,
            calib::core::LsbRounding::kCarried);
  replace_in_file(
      dir + "/run.toml", "[noise]\n",
      "[noise]\ndtheta_lsb_rad = 3e-6\ndv_lsb_mps = 2e-4\nlsb_rounding = \"per_sample\"\n");
  const RunArchive a = read_archive(dir);
  EXPECT_EQ(a.info.lsb_rounding, calib::core::LsbRounding::kPerSample);
  const calib::core::CalibrationInput in = to_calibration_input(a);
  EXPECT_EQ(in.noise.lsb_rounding, calib::core::LsbRounding::kPerSample);
  EXPECT_EQ(in.noise.dtheta_lsb_rad, 3e-6);
  EXPECT_EQ(in.noise.dv_lsb_mps, 2e-4);
  const std::string again = tmp.path() + "/again";
  write_archive(again, a, false);
  EXPECT_NE(slurp(again + "/run.toml").find("lsb_rounding = \"per_sample\""), std::string::npos);
  EXPECT_EQ(read_archive(again).info.lsb_rounding, calib::core::LsbRounding::kPerSample);
  for (const char* bad : {"\"per-sample\"", "\"rounded\"", "1"}) {
    put(dir + "/run.toml", orig);
    replace_in_file(dir + "/run.toml", "[noise]\n",
                    std::string("[noise]\nlsb_rounding = ") + bad + "\n");
    const ArchiveError e = read_error(dir);
    EXPECT_EQ(e.field(), "noise.lsb_rounding") << e.what();
    EXPECT_EQ(e.file(), dir + "/run.toml");
    EXPECT_GT(e.line(), 0u) << e.what();
  }
  put(dir + "/run.toml", orig);
  replace_in_file(dir + "/run.toml", "[noise]\n", "[noise]\nlsb_rounding = \"sometimes\"\n");
  const std::string says = read_error(dir).what();
  EXPECT_NE(says.find("\"carried\""), std::string::npos) << says;
  EXPECT_NE(says.find("\"per_sample\""), std::string::npos) << says;
  EXPECT_NE(says.find("sometimes"), std::string::npos) << says;
}

// Issue #21: the grade's envelopes may be overridden per product; the overrides reach the
// calibration input exactly and survive a write/read.
TEST(Archive, PriorEnvelopeOverridesReadWriteBackAndReachTheInput) {
  TempDir tmp("imucal_archive_test");
  const std::string dir = write_simple(tmp, "r");
  replace_in_file(dir + "/run.toml", "[imu]\n",
                  "[prior]\ngrade = \"tactical\"\nscale_ppm = 20000\naccel_bias_mg = 12.5\n"
                  "gyro_bias_deg_per_s = 0.01\nmisalignment_mrad = 7\n[imu]\n");
  const RunArchive a = read_archive(dir);
  ASSERT_TRUE(a.info.prior_overrides.scale && a.info.prior_overrides.accel_bias_mps2);
  EXPECT_DOUBLE_EQ(*a.info.prior_overrides.scale, 0.02);
  EXPECT_DOUBLE_EQ(*a.info.prior_overrides.accel_bias_mps2, 12.5e-3 * 9.80665);
  EXPECT_DOUBLE_EQ(*a.info.prior_overrides.gyro_bias_radps, 0.01 * kDegToRad);
  EXPECT_DOUBLE_EQ(*a.info.prior_overrides.misalignment_rad, 7e-3);
  const calib::core::CalibrationInput in = to_calibration_input(a);
  const calib::core::GradePrior env = in.unit_prior().envelope();
  EXPECT_DOUBLE_EQ(env.scale, 0.02);  // not the tactical class's 1 %
  EXPECT_DOUBLE_EQ(env.arw_rad_per_sqrt_s,
                   calib::core::grade_prior(calib::core::Grade::kTactical).arw_rad_per_sqrt_s);
  const std::string again = tmp.path() + "/again";
  write_archive(again, a, false);
  const RunArchive b = read_archive(again);
  EXPECT_EQ(*b.info.prior_overrides.scale, *a.info.prior_overrides.scale);
  EXPECT_EQ(*b.info.prior_overrides.accel_bias_mps2, *a.info.prior_overrides.accel_bias_mps2);
  EXPECT_EQ(*b.info.prior_overrides.gyro_bias_radps, *a.info.prior_overrides.gyro_bias_radps);
  EXPECT_EQ(*b.info.prior_overrides.misalignment_rad, *a.info.prior_overrides.misalignment_rad);
}

TEST(Archive, MissingRequiredKeysNamed) {
  TempDir tmp("imucal_archive_test");
  const std::string dir = write_simple(tmp, "r");
  const std::string orig = slurp(dir + "/run.toml");
  struct Case {
    std::string from, to, field;
  };
  for (const Case& c : {Case{"serial = \"S1\"\n", "", "serial"},
                        Case{"lat_deg = ", "#lat_deg = ", "station.lat_deg"},
                        Case{"lon_deg = ", "#lon_deg = ", "station.lon_deg"},
                        Case{"height_m = ", "#height_m = ", "station.height_m"},
                        Case{"rate_hz = ", "#rate_hz = ", "imu.rate_hz"}}) {
    put(dir + "/run.toml", orig);
    replace_in_file(dir + "/run.toml", c.from, c.to);
    const ArchiveError e = read_error(dir);
    EXPECT_EQ(e.field(), c.field) << e.what();
    EXPECT_NE(std::string(e.what()).find(dir + "/run.toml: field '" + c.field + "': missing"),
              std::string::npos)
        << e.what();
  }
  // Out-of-range and wrong-typed values name the key and line.
  put(dir + "/run.toml", orig);
  replace_in_file(dir + "/run.toml", "rate_hz = 100.0", "rate_hz = \"100\"");
  EXPECT_EQ(read_error(dir).field(), "imu.rate_hz");
  put(dir + "/run.toml", orig);
  replace_in_file(dir + "/run.toml", "reference = \"table\"",
                  "reference = \"table\"\nstart_time = \"yesterday\"");
  const ArchiveError t = read_error(dir);
  EXPECT_EQ(t.field(), "start_time");
  EXPECT_GT(t.line(), 0u);
}

TEST(Archive, BothOrNeitherReferenceFileRejected) {
  TempDir tmp("imucal_archive_test");
  const std::string dir = write_simple(tmp, "r");
  put(dir + "/attitude.csv", "t_s,roll_deg,pitch_deg,yaw_deg,at_rest\n0.01,0,0,0,1\n");
  const ArchiveError both = read_error(dir);
  EXPECT_EQ(both.file(), dir);
  EXPECT_NE(both.message().find("both table.csv and attitude.csv"), std::string::npos)
      << both.what();
  fs::remove(dir + "/attitude.csv");
  fs::remove(dir + "/table.csv");
  const ArchiveError neither = read_error(dir);
  EXPECT_NE(neither.message().find("neither table.csv nor attitude.csv"), std::string::npos)
      << neither.what();
}

TEST(Archive, ReferenceKeyMustMatchTheFilePresent) {
  TempDir tmp("imucal_archive_test");
  const std::string dir = write_simple(tmp, "r");
  replace_in_file(dir + "/run.toml", "reference = \"table\"", "reference = \"attitude\"");
  const ArchiveError e = read_error(dir);
  EXPECT_EQ(e.field(), "reference");
  EXPECT_EQ(e.line(), 3u) << e.what();
}

TEST(Archive, BadAtRestValueNamedWithLineAndColumn) {
  TempDir tmp("imucal_archive_test");
  const std::string dir = write_simple(tmp, "r");
  replace_in_file(dir + "/table.csv", "\n0.05,0,0,0\n", "\n0.05,0,0,0.5\n");  // data row 5 = line 6
  const ArchiveError e = read_error(dir);
  EXPECT_EQ(e.file(), dir + "/table.csv");
  EXPECT_EQ(e.line(), 6u);
  EXPECT_EQ(e.field(), "at_rest");
  EXPECT_NE(e.message().find("must be 0 or 1"), std::string::npos);
}

TEST(Archive, CsvErrorsInsideAnArchiveNameTheFile) {
  TempDir tmp("imucal_archive_test");
  const std::string dir = write_simple(tmp, "r");
  replace_in_file(dir + "/imu.csv", "\n0.03,", "\n0.03,nan,");
  const ArchiveError nan = read_error(dir);
  EXPECT_EQ(nan.file(), dir + "/imu.csv");
  EXPECT_EQ(nan.line(), 4u);
  EXPECT_EQ(nan.field(), "dtheta_x_rad");
  const std::string dir2 = write_simple(tmp, "r2");
  replace_in_file(dir2 + "/table.csv", "\n0.04,0,0,0\n", "\n0.025,0,0,0\n");  // line 5, before 0.03
  const ArchiveError back = read_error(dir2);
  EXPECT_EQ(back.file(), dir2 + "/table.csv");
  EXPECT_EQ(back.line(), 5u);
  EXPECT_EQ(back.field(), "t_s");
}

TEST(Archive, MismatchedTimeAxisNamesFirstBadLine) {
  TempDir tmp("imucal_archive_test");
  const std::string dir = write_simple(tmp, "r");
  // Shift row 7 (line 8) by 2 µs: still increasing, but off the IMU axis.
  replace_in_file(dir + "/table.csv", "\n0.07,", "\n0.070002,");
  const ArchiveError e = read_error(dir);
  EXPECT_EQ(e.file(), dir + "/table.csv");
  EXPECT_EQ(e.line(), 8u);
  EXPECT_NE(e.message().find("does not match imu.csv line 8"), std::string::npos) << e.what();
  // 0.5 µs is within tolerance.
  replace_in_file(dir + "/table.csv", "\n0.070002,", "\n0.0700005,");
  EXPECT_NO_THROW(to_calibration_input(read_archive(dir)));
  // Different row count.
  std::string t = slurp(dir + "/table.csv");
  t.erase(t.rfind('\n', t.size() - 2) + 1);
  put(dir + "/table.csv", t);
  const ArchiveError rows = read_error(dir);
  EXPECT_EQ(rows.file(), dir + "/table.csv");
  EXPECT_NE(rows.message().find("49 data rows but imu.csv has 50"), std::string::npos)
      << rows.what();
}

TEST(Archive, NoRestPeriodsRejected) {
  TempDir tmp("imucal_archive_test");
  const std::string dir = write_simple(tmp, "r");
  std::string t = slurp(dir + "/table.csv");
  for (size_t p = t.find(",1\n"); p != std::string::npos; p = t.find(",1\n"))
    t.replace(p, 3, ",0\n");
  put(dir + "/table.csv", t);
  const ArchiveError e = read_error(dir);
  EXPECT_EQ(e.file(), dir + "/table.csv");
  EXPECT_EQ(e.message(), "no rest periods in table.csv: at_rest is never 1");
}

TEST(Archive, ImplausibleIncrementsAndRateMismatchRejected) {
  TempDir tmp("imucal_archive_test");
  {
    const std::string dir = write_simple(tmp, "a");
    // dv written as acceleration (m/s^2) instead of m/s per sample on one line: 100x too large.
    std::string t = slurp(dir + "/imu.csv");
    const size_t line5 = t.find("\n0.04,") + 1;
    const size_t end5 = t.find('\n', line5);
    put(dir + "/imu.csv", t.substr(0, line5) + "0.04,0,0,0,0,0,-250" + t.substr(end5));
    const ArchiveError e = read_error(dir);
    EXPECT_EQ(e.file(), dir + "/imu.csv");
    EXPECT_EQ(e.line(), 5u);
    EXPECT_NE(e.message().find("exceeds 20 g"), std::string::npos) << e.what();
  }
  {
    const std::string dir = write_simple(tmp, "b");
    replace_in_file(dir + "/imu.csv", "\n0.04,0,0,0,", "\n0.04,0.2,0,0,");  // 20 rad/s = 1146 deg/s
    const ArchiveError e = read_error(dir);
    EXPECT_EQ(e.line(), 5u);
    EXPECT_NE(e.message().find("exceeds 1000 deg/s"), std::string::npos) << e.what();
  }
  {
    const std::string dir = write_simple(tmp, "c");
    replace_in_file(dir + "/run.toml", "rate_hz = 100.0", "rate_hz = 200.0");
    const ArchiveError e = read_error(dir);
    EXPECT_EQ(e.file(), dir + "/imu.csv");
    EXPECT_NE(e.message().find("does not match run.toml [imu] rate_hz = 200"), std::string::npos)
        << e.what();
  }
}

TEST(Archive, AtomicWriteRefusesExistingTargetAndLeavesNothingBehind) {
  TempDir tmp("imucal_archive_test");
  const std::string dir = write_simple(tmp, "run");
  const std::string before = slurp(dir + "/imu.csv");
  const std::vector<std::string> entries = dir_entries(tmp);
  RunArchive other = read_archive(dir);
  other.info.serial = "OTHER";
  try {
    write_archive(dir, other);
    FAIL() << "overwrote an existing archive";
  } catch (const ArchiveError& e) {
    EXPECT_EQ(e.file(), dir);
    EXPECT_NE(e.message().find("refusing to overwrite"), std::string::npos);
  }
  EXPECT_EQ(dir_entries(tmp), entries);  // no run.tmp-XXXXXX left behind
  EXPECT_EQ(slurp(dir + "/imu.csv"), before);
  EXPECT_EQ(read_archive(dir).info.serial, "S1");

  // A failure half way through writing (NaN in sample 30) leaves neither target nor temp dir.
  RunArchive bad = other;
  bad.imu[30].dv_mps(1) = std::nan("");
  try {
    write_archive(tmp.sub("new"), bad);
    FAIL() << "wrote NaN";
  } catch (const ArchiveError& e) {
    EXPECT_EQ(e.line(), 32u);
    EXPECT_EQ(e.field(), "dv_y_mps");
  }
  EXPECT_EQ(dir_entries(tmp), entries);
  // ... nor does it touch an existing archive when overwriting.
  EXPECT_THROW(write_archive(dir, bad, /*overwrite=*/true), ArchiveError);
  EXPECT_EQ(dir_entries(tmp), entries);
  EXPECT_EQ(read_archive(dir).info.serial, "S1");

  // Explicit overwrite replaces it atomically and cleans up the old one.
  write_archive(dir, other, /*overwrite=*/true);
  EXPECT_EQ(read_archive(dir).info.serial, "OTHER");
  EXPECT_EQ(dir_entries(tmp), entries);

  // An existing empty directory is a valid target.
  fs::create_directory(tmp.sub("empty"));
  write_archive(tmp.sub("empty"), other);
  EXPECT_EQ(read_archive(tmp.sub("empty")).info.serial, "OTHER");
}

TEST(Archive, WriterRejectsInconsistentReference) {
  TempDir tmp("imucal_archive_test");
  RunArchive a = read_archive(write_simple(tmp, "r"));
  a.attitude.push_back({0.01, 0, 0, 0, true});
  EXPECT_THROW(write_archive(tmp.sub("x"), a), ArchiveError);
  a.attitude.clear();
  a.table.clear();
  EXPECT_THROW(write_archive(tmp.sub("x"), a), ArchiveError);
  EXPECT_FALSE(fs::exists(tmp.sub("x")));
}

TEST(Archive, AttitudeReferenceBuildsCbnFromNedEuler) {
  TempDir tmp("imucal_archive_test");
  const std::string dir = write_simple(tmp, "att");
  fs::remove(dir + "/table.csv");
  replace_in_file(dir + "/run.toml", "reference = \"table\"", "reference = \"attitude\"");
  // Same time axis; yaw 90 deg for all rows except row 1 (pitch 90 deg) and row 2 (roll 90 deg).
  std::ostringstream csv;
  csv << "t_s,roll_deg,pitch_deg,yaw_deg,at_rest\n";
  for (int k = 0; k < 50; ++k) {
    const char* rpy = k == 1 ? "0,90,0" : (k == 2 ? "90,0,0" : "0,0,90");
    csv << format_double((k + 1) / 100.0) << "," << rpy << "," << (k >= 10 ? 1 : 0) << "\n";
  }
  put(dir + "/attitude.csv", csv.str());
  const RunArchive a = read_archive(dir);
  ASSERT_EQ(a.info.reference, ReferenceKind::kAttitude);
  ASSERT_EQ(a.attitude.size(), 50u);
  EXPECT_EQ(a.attitude[5].yaw_rad, 90.0 * kDegToRad);
  const calib::core::CalibrationInput in = to_calibration_input(a);
  const Eigen::Vector3d x_b(1, 0, 0), y_b(0, 1, 0);
  // Yaw 90 deg (heading east): body x points east, body y points south.
  EXPECT_LT((in.reference[5].C_bn_ref * x_b - Eigen::Vector3d(0, 1, 0)).norm(), 1e-15);
  EXPECT_LT((in.reference[5].C_bn_ref * y_b - Eigen::Vector3d(-1, 0, 0)).norm(), 1e-15);
  // Pitch 90 deg (nose up): body x points up = -down.
  EXPECT_LT((in.reference[1].C_bn_ref * x_b - Eigen::Vector3d(0, 0, -1)).norm(), 1e-15);
  // Roll 90 deg (right wing down): body y points down.
  EXPECT_LT((in.reference[2].C_bn_ref * y_b - Eigen::Vector3d(0, 0, 1)).norm(), 1e-15);
  EXPECT_FALSE(in.reference[5].at_rest);
  EXPECT_TRUE(in.reference[10].at_rest);

  // Pitch beyond 90 deg is not a valid ZYX attitude.
  replace_in_file(dir + "/attitude.csv", "\n0.04,0,0,90,", "\n0.04,0,91,90,");
  const ArchiveError e = read_error(dir);
  EXPECT_EQ(e.file(), dir + "/attitude.csv");
  EXPECT_EQ(e.line(), 5u);
  EXPECT_EQ(e.field(), "pitch_deg");

  // Round trip of an attitude archive.
  replace_in_file(dir + "/attitude.csv", "\n0.04,0,91,90,", "\n0.04,0,-12.5,90,");
  const RunArchive b = read_archive(dir);
  write_archive(tmp.sub("att2"), b);
  EXPECT_EQ(slurp(dir + "/attitude.csv"), slurp(tmp.sub("att2") + "/attitude.csv"));
}

TEST(Archive, RawIntegralDvIsRotationCompensatedOnImport) {
  // Body turning about z at 10 deg/s under a constant n-frame specific force with a horizontal
  // part a: f_b(t) = Rz(-ω t) f_n. The archive's dv is ∫ C_{b(t)}^{b(t_{k-1})} f_b dt
  // = Rz(-ω t_{k-1}) f_n dt exactly; a raw-integral IMU delivers ∫ Rz(-ω t) f_n dt instead.
  TempDir tmp("imucal_archive_test");
  const std::string dir = tmp.sub("raw");
  fs::create_directory(dir);
  const double w = 10.0 * kDegToRad, a = 1.0, g = 9.81, dt = 0.01;
  std::ostringstream imu, table;
  imu << "t_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps\n";
  table << "t_s,outer_deg,inner_deg,at_rest\n";
  std::vector<Eigen::Vector3d> exact;
  for (int k = 0; k < 20; ++k) {
    const double t0 = k * dt, t1 = (k + 1) * dt;
    const Eigen::Vector3d raw((a / w) * (std::sin(w * t1) - std::sin(w * t0)),
                              (a / w) * (std::cos(w * t1) - std::cos(w * t0)), -g * dt);
    exact.emplace_back(a * std::cos(w * t0) * dt, -a * std::sin(w * t0) * dt, -g * dt);
    imu << format_double(t1) << ",0,0," << format_double(w * dt) << "," << format_double(raw(0))
        << "," << format_double(raw(1)) << "," << format_double(raw(2)) << "\n";
    table << format_double(t1) << ",0,0,1\n";
  }
  put(dir + "/imu.csv", imu.str());
  put(dir + "/table.csv", table.str());
  const std::string toml =
      "serial = \"R\"\n[station]\nlat_deg = 0\nlon_deg = 0\nheight_m = 0\n[imu]\nrate_hz = 100\n";
  put(dir + "/run.toml", toml);
  const RunArchive as_is = read_archive(dir);
  put(dir + "/run.toml", toml + "dv_convention = \"raw_integral\"\n");
  const RunArchive converted = read_archive(dir);
  double worst_raw = 0.0, worst_conv = 0.0;
  for (size_t k = 0; k < exact.size(); ++k) {
    worst_raw = std::max(worst_raw, (as_is.imu[k].dv_mps - exact[k]).norm());
    worst_conv = std::max(worst_conv, (converted.imu[k].dv_mps - exact[k]).norm());
  }
  // Uncompensated: ½ ω dt · a dt = 8.7e-6 m/s per sample (87 µg as a specific force).
  EXPECT_GT(worst_raw, 8e-6);
  // First-order compensation leaves a second-order term (ω dt)^2 a dt / 12 (Taylor expansion of
  // the exact integral); bound it by twice that.
  EXPECT_LT(worst_conv, (w * dt) * (w * dt) * a * dt / 6.0);
  // Written back, the archive is in the interval-start convention (no dv_convention key).
  write_archive(tmp.sub("raw2"), converted);
  EXPECT_EQ(slurp(tmp.sub("raw2") + "/run.toml").find("dv_convention"), std::string::npos);
  EXPECT_EQ(read_archive(tmp.sub("raw2")).imu[7].dv_mps, converted.imu[7].dv_mps);
  // Unknown conventions are rejected.
  put(dir + "/run.toml", toml + "dv_convention = \"body_end\"\n");
  EXPECT_EQ(read_error(dir).field(), "imu.dv_convention");
}

// Bit-for-bit equality of two calibration inputs (NaN payloads included).
void expect_identical(const calib::core::CalibrationInput& a,
                      const calib::core::CalibrationInput& b) {
  auto same = [](const auto& x, const auto& y) { return std::memcmp(&x, &y, sizeof x) == 0; };
  EXPECT_EQ(a.setting, b.setting);
  EXPECT_TRUE(same(a.site.lat_rad, b.site.lat_rad) && same(a.site.lon_rad, b.site.lon_rad) &&
              same(a.site.height_m, b.site.height_m) && a.site.gravity_mps2 == b.site.gravity_mps2);
  EXPECT_TRUE(same(a.noise.arw_rad_per_sqrt_s, b.noise.arw_rad_per_sqrt_s) &&
              same(a.noise.vrw_mps_per_sqrt_s, b.noise.vrw_mps_per_sqrt_s));
  ASSERT_EQ(a.imu.size(), b.imu.size());
  for (size_t k = 0; k < a.imu.size(); ++k) {
    const calib::core::ImuIncrement &x = a.imu[k], &y = b.imu[k];
    ASSERT_TRUE(same(x.t_s, y.t_s) && same(x.dt_s, y.dt_s) && same(x.temp_c, y.temp_c) &&
                x.dtheta_rad == y.dtheta_rad && x.dv_mps == y.dv_mps)
        << "imu sample " << k;
  }
  ASSERT_EQ(a.reference.size(), b.reference.size());
  for (size_t k = 0; k < a.reference.size(); ++k) {
    const calib::core::ReferenceSample &x = a.reference[k], &y = b.reference[k];
    ASSERT_TRUE(same(x.t_s, y.t_s) && same(x.C_bn_ref, y.C_bn_ref) && x.at_rest == y.at_rest &&
                same(x.outer_rad, y.outer_rad) && same(x.inner_rad, y.inner_rad))
        << "reference sample " << k;
  }
  ASSERT_EQ(a.gnss.size(), b.gnss.size());
}

TEST(Archive, ConvertingAGivenUpArchiveGivesTheSameInputBitForBit) {
  TempDir tmp("imucal_archive_test");
  const SimRun run = simulated_run();
  write_archive(tmp.sub("run"), run.archive);
  const RunArchive kept = read_archive(tmp.sub("run"));
  RunArchive given = read_archive(tmp.sub("run"));
  const calib::core::CalibrationInput from_const = to_calibration_input(kept);
  const calib::core::CalibrationInput from_moved = to_calibration_input(std::move(given));
  expect_identical(from_const, from_moved);
  EXPECT_EQ(from_moved.imu.size(), run.archive.imu.size());
  // The samples went into the input; what describes the run stays.
  EXPECT_TRUE(given.imu.empty());
  EXPECT_TRUE(given.table.empty());
  EXPECT_EQ(given.info.serial, "FOG-2024-0042");
  EXPECT_TRUE(given.truth.has_value());
  EXPECT_EQ(given.origin, tmp.sub("run"));

  // An attitude reference too.
  const std::string dir = write_simple(tmp, "att");
  fs::remove(dir + "/table.csv");
  replace_in_file(dir + "/run.toml", "reference = \"table\"", "reference = \"attitude\"");
  std::ostringstream csv;
  csv << "t_s,roll_deg,pitch_deg,yaw_deg,at_rest\n";
  for (int k = 0; k < 50; ++k)
    csv << format_double((k + 1) / 100.0) << ",1.5,-2.25," << k << "," << (k >= 10 ? 1 : 0) << "\n";
  put(dir + "/attitude.csv", csv.str());
  RunArchive att = read_archive(dir);
  const calib::core::CalibrationInput att_const = to_calibration_input(att);
  expect_identical(att_const, to_calibration_input(std::move(att)));
  EXPECT_TRUE(att.attitude.empty());
}

TEST(Archive, TimeMismatchInEitherHalfNamesTheFirstBadLine) {
  TempDir tmp("imucal_archive_test");
  const std::string dir = write_simple(tmp, "r");  // 50 rows: the halves are rows 0-24, 25-49
  replace_in_file(dir + "/table.csv", "\n0.41,", "\n0.410002,");  // row 40, line 42
  for (const bool moved : {false, true}) {
    RunArchive a = read_archive(dir);
    try {
      moved ? to_calibration_input(std::move(a)) : to_calibration_input(a);
      ADD_FAILURE() << "no error";
    } catch (const ArchiveError& e) {
      EXPECT_EQ(e.line(), 42u) << e.what();
    }
  }
  replace_in_file(dir + "/table.csv", "\n0.07,", "\n0.070002,");  // row 6, line 8: wins
  const ArchiveError e = read_error(dir);
  EXPECT_EQ(e.line(), 8u);
  EXPECT_NE(e.message().find("does not match imu.csv line 8"), std::string::npos) << e.what();
}

TEST(Archive, LargeArchiveReadOnTwoThreadsReportsTheFirstErrorInTheFile) {
  TempDir tmp("imucal_archive_test");
  const size_t n = 30000;  // 300 s at 100 Hz: both CSV files are split between two threads
  const std::string dir = write_simple(tmp, "big", n);
  ASSERT_GT(fs::file_size(dir + "/table.csv"), 256u * 1024u);
  {
    RunArchive a = read_archive(dir);
    ASSERT_EQ(a.imu.size(), n);
    ASSERT_EQ(a.table.size(), n);
    EXPECT_EQ(a.imu[n - 1].t_s, 300.0);
    EXPECT_EQ(a.imu[n / 2].dt_s, a.imu[n / 2].t_s - a.imu[n / 2 - 1].t_s);
    const calib::core::CalibrationInput in = to_calibration_input(a);
    expect_identical(in, to_calibration_input(std::move(a)));
  }
  // A bad rest flag in each half of table.csv: the first one (data row 100, line 102) is named.
  const std::string flags = tmp.sub("flags");
  fs::copy(dir, flags);
  replace_in_file(flags + "/table.csv", "\n250.01,0,0,1\n", "\n250.01,0,0,2\n");
  EXPECT_EQ(read_error(flags).line(), 25002u);
  replace_in_file(flags + "/table.csv", "\n1.01,0,0,1\n", "\n1.01,0,0,0.5\n");
  const ArchiveError flag = read_error(flags);
  EXPECT_EQ(flag.line(), 102u);
  EXPECT_EQ(flag.field(), "at_rest");
  EXPECT_EQ(flag.message(), "must be 0 or 1, got 0.5");
  // A bad cell in each half of imu.csv: the first one.
  const std::string cells = tmp.sub("cells");
  fs::copy(dir, cells);
  replace_in_file(cells + "/imu.csv", "\n290.01,0,", "\n290.01,0x,");
  EXPECT_EQ(read_error(cells).line(), 29002u);
  replace_in_file(cells + "/imu.csv", "\n2.01,0,", "\n2.01,0x,");
  const ArchiveError cell = read_error(cells);
  EXPECT_EQ(cell.file(), cells + "/imu.csv");
  EXPECT_EQ(cell.line(), 202u);
  EXPECT_EQ(cell.field(), "dtheta_x_rad");
}

TEST(Archive, MissingPiecesNamed) {
  TempDir tmp("imucal_archive_test");
  const ArchiveError nodir = read_error(tmp.sub("nope"));
  EXPECT_NE(nodir.message().find("no such run archive directory"), std::string::npos);
  const std::string dir = write_simple(tmp, "r");
  fs::remove(dir + "/imu.csv");
  const ArchiveError noimu = read_error(dir);
  EXPECT_EQ(noimu.file(), dir + "/imu.csv");
  fs::remove(dir + "/run.toml");
  const ArchiveError notoml = read_error(dir);
  EXPECT_EQ(notoml.file(), dir + "/run.toml");
}

}  // namespace
}  // namespace imucal::db::archive
