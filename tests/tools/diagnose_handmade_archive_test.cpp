// A run archive made by hand — run.toml, imu.csv and table.csv written by this test from its own
// formulas, not by the project's simulator — with a gyro g-sensitivity injected and not declared.
// `imucal diagnose` must name it with its size.
//
// The test's own physics (ARCHITECTURE §3 conventions, written out here independently):
//   table: C_bn_table(outer, inner) = Rx(outer) Rz(inner) (outer axis north, inner axis the
//   platform normal), truth C_bn = exp([ς×]) C_bn_table; angles move at a constant 10 °/s between
//   rests; inertial attitude C_bi(t) = exp([ω_ie_n t×]) C_bn(t) so dθ_k = log(C_bn(k-1)ᵀ
//   exp([ω_ie_n dt×]) C_bn(k)); the table does not translate, so f_n = -g_n and dv_k = C_bn(k-1)ᵀ
//   (f_n dt + ½ dt² ω_ie_n × f_n); the unit: dθ~ = dθ + b_g dt + M_g dθ + G f_b dt, dv~ = dv + b_a
//   dt + M_a dv, white noise.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <random>
#include <vector>

#include "tests/support/run_command.hpp"
#include "tests/support/temp_dir.hpp"

namespace fs = std::filesystem;
using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

constexpr double kPi = 3.14159265358979323846, kDeg = kPi / 180.0;
constexpr double kLat = 55.78 * kDeg, kG = 9.81560, kWie = 7.292115e-5;
constexpr double kDt = 0.01, kRate = 10.0 * kDeg;
constexpr double kArw = 0.0015 * kDeg / 60.0;  // rad/√s
constexpr double kVrw = 10e-6 * 9.80665;       // m/s²/√Hz
constexpr double kDegPerHour = kDeg / 3600.0;

Matrix3d rot(const Vector3d& axis, double a) {
  return Eigen::AngleAxisd(a, axis).toRotationMatrix();
}
Matrix3d expm(const Vector3d& phi) {
  const double a = phi.norm();
  return a < 1e-15 ? Matrix3d::Identity() : rot(phi / a, a);
}
Vector3d logm(const Matrix3d& C) {
  const Eigen::AngleAxisd aa(C);
  return aa.axis() * aa.angle();
}

struct Pose {
  double outer_deg, inner_deg;
};

struct Sample {
  double t;
  Vector3d dth, dv;
  double outer_deg, inner_deg;
  bool at_rest;
};

/// Angles at time t of a piecewise schedule: rest 60 s, move one axis at 10 °/s, rest, ...
struct Schedule {
  std::vector<double> t;   // knot times
  std::vector<Pose> p;     // pose at each knot
  std::vector<char> rest;  // segment after knot i is a rest
  Pose at(double time) const {
    size_t i = 0;
    while (i + 1 < t.size() && t[i + 1] <= time) ++i;
    if (i + 1 >= t.size()) return p.back();
    const double f = (time - t[i]) / (t[i + 1] - t[i]);
    return {p[i].outer_deg + f * (p[i + 1].outer_deg - p[i].outer_deg),
            p[i].inner_deg + f * (p[i + 1].inner_deg - p[i].inner_deg)};
  }
  bool resting(double t0, double t1) const {  // whole interval inside a rest, 0.5 s from its edges
    for (size_t i = 0; i + 1 < t.size(); ++i)
      if (rest[i] && t0 >= t[i] + 0.5 && t1 <= t[i + 1] - 0.5) return true;
    return false;
  }
};

Schedule schedule() {
  // Every body axis up and down, turns about every body axis (gravity sees them).
  const std::vector<Pose> poses = {{0, 0},     {90, 0},    {90, 90},   {90, 180},  {90, 270},
                                   {180, 270}, {180, 180}, {180, 90},  {180, 0},   {270, 0},
                                   {270, 90},  {270, 180}, {360, 180}, {360, 270}, {360, 360}};
  Schedule s;
  double time = 0.0;
  for (size_t i = 0; i < poses.size(); ++i) {
    s.t.push_back(time);
    s.p.push_back(poses[i]);
    s.rest.push_back(1);
    time += 60.0;
    if (i + 1 < poses.size()) {
      s.t.push_back(time);
      s.p.push_back(poses[i]);
      s.rest.push_back(0);
      const double move = std::abs(poses[i + 1].outer_deg - poses[i].outer_deg) +
                          std::abs(poses[i + 1].inner_deg - poses[i].inner_deg);
      time += move * kDeg / kRate;
    }
  }
  s.t.push_back(time);
  s.p.push_back(poses.back());
  s.rest.push_back(0);
  return s;
}

Matrix3d C_bn_table(const Pose& p) {
  return rot(Vector3d::UnitX(), p.outer_deg * kDeg) * rot(Vector3d::UnitZ(), p.inner_deg * kDeg);
}

std::vector<Sample> make_run(const Matrix3d& G, uint64_t seed) {
  const Schedule s = schedule();
  const Vector3d w_ie_n(kWie * std::cos(kLat), 0.0, -kWie * std::sin(kLat));
  const Vector3d f_n(0.0, 0.0, -kG);
  const Matrix3d E = expm(w_ie_n * kDt);
  const Matrix3d Cs = expm(Vector3d(10.0, -15.0, 30.0) * kDeg / 3600.0);  // table misalignment ς
  const Vector3d b_a = Vector3d(50, -40, 30) * 9.80665e-6,
                 b_g = Vector3d(0.01, -0.008, 0.012) * kDegPerHour;
  Matrix3d M_a, M_g;
  M_a << 300e-6, 120e-6, -80e-6, -150e-6, -200e-6, 60e-6, 90e-6, -110e-6, 450e-6;
  M_g << -150e-6, 200e-6, -100e-6, 80e-6, 400e-6, 150e-6, -120e-6, 90e-6, 250e-6;
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n01(0.0, 1.0);
  std::vector<Sample> out;
  const size_t n = static_cast<size_t>(s.t.back() / kDt);
  Matrix3d C_prev = Cs * C_bn_table(s.at(0.0));
  for (size_t k = 1; k <= n; ++k) {
    const double t0 = (k - 1) * kDt, t1 = k * kDt;
    const Pose p = s.at(t1);
    const Matrix3d C = Cs * C_bn_table(p);
    const Vector3d dth = logm(C_prev.transpose() * E * C);
    const Vector3d dv = C_prev.transpose() * (f_n * kDt + 0.5 * kDt * kDt * w_ie_n.cross(f_n));
    const Vector3d f_b = dv / kDt;
    Sample x;
    x.t = t1;
    x.dth = dth + b_g * kDt + M_g * dth + G * f_b * kDt;
    x.dv = dv + b_a * kDt + M_a * dv;
    for (int i = 0; i < 3; ++i) {
      x.dth(i) += kArw * std::sqrt(kDt) * n01(rng);
      x.dv(i) += kVrw * std::sqrt(kDt) * n01(rng);
    }
    x.outer_deg = p.outer_deg;
    x.inner_deg = p.inner_deg;
    x.at_rest = s.resting(t0, t1);
    out.push_back(x);
    C_prev = C;
  }
  return out;
}

void write_archive(const fs::path& dir, const std::vector<Sample>& run) {
  fs::create_directories(dir);
  std::ofstream(dir / "run.toml")
      << "serial = \"HAND-1\"\nreference = \"table\"\n"
      << "[station]\nlat_deg = 55.78\nlon_deg = 12.52\nheight_m = 40.0\n"
      << "gravity_mps2 = 9.8156\n[imu]\nrate_hz = 100.0\n"
      << "[sequence]\nname = \"hand-made\"\n"
      << "[noise]\narw_deg_per_sqrt_h = 0.0015\nvrw_ug_per_sqrt_hz = 10.0\n";
  std::ofstream imu(dir / "imu.csv"), tab(dir / "table.csv");
  imu << "t_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps\n";
  tab << "t_s,outer_deg,inner_deg,at_rest\n";
  char line[512];
  for (const Sample& x : run) {
    std::snprintf(line, sizeof line, "%.6f,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g\n", x.t, x.dth(0),
                  x.dth(1), x.dth(2), x.dv(0), x.dv(1), x.dv(2));
    imu << line;
    std::snprintf(line, sizeof line, "%.6f,%.12g,%.12g,%d\n", x.t, x.outer_deg, x.inner_deg,
                  x.at_rest ? 1 : 0);
    tab << line;
  }
}

nlohmann::json diagnose_json(const fs::path& dir, int* code) {
  const auto r = imucal::test_support::run_command(std::string(IMUCAL_BIN_DIR) +
                                                   "/imucal diagnose " + dir.string() + " --json");
  *code = r.code;
  return nlohmann::json::parse(r.out);
}

}  // namespace

TEST(HandMadeArchive, WithheldGyroGSensitivityIsNamedWithItsSize) {
  const imucal::test_support::ScopedTempDir tmp("handmade");
  Matrix3d G_dph_per_g = Matrix3d::Zero();
  G_dph_per_g.diagonal() << 0.03, -0.02, 0.025;
  const Matrix3d G = G_dph_per_g * kDegPerHour / 9.80665;
  write_archive(fs::path(tmp.path()) / "run", make_run(G, 7));
  int code = -1;
  const nlohmann::json j = diagnose_json(fs::path(tmp.path()) / "run", &code);
  EXPECT_EQ(code, 0) << j.dump(1).substr(0, 2000);
  EXPECT_EQ(j["verdict"], "explained") << j["summary"];
  ASSERT_TRUE(j["best"].is_object()) << j["summary"];
  EXPECT_EQ(j["best"]["effect"], "gyro_g_sensitivity");
  // Each diagonal element within 4σ of what this test injected.
  const char* names[3] = {"G_xx", "G_yy", "G_zz"};
  for (int i = 0; i < 3; ++i)
    for (const auto& p : j["best"]["parameters"])
      if (p["name"] == names[i]) {
        EXPECT_NEAR(p["value"].get<double>(), G_dph_per_g(i, i), 4.0 * p["sigma"].get<double>())
            << names[i];
      }
  EXPECT_GT(j["held_out"]["shrinkage"].get<double>(), 0.7);
}

TEST(HandMadeArchive, WithoutTheEffectTheRunIsConsistent) {
  const imucal::test_support::ScopedTempDir tmp("handmade-null");
  write_archive(fs::path(tmp.path()) / "run", make_run(Matrix3d::Zero(), 8));
  int code = -1;
  const nlohmann::json j = diagnose_json(fs::path(tmp.path()) / "run", &code);
  EXPECT_EQ(j["verdict"], "consistent") << j["summary"];
  EXPECT_EQ(code, 0);
}
