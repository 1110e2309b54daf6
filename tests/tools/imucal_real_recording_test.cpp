// A real unit's recording through the real `imucal` binary (issue #21 items 5, 6): IMU-TK's Xsens
// test data (tests/data/imu_tk_xsens, two raw files of counts) imported as a user would —
// `imucal import` with nominal values only (import.toml: gyro offsets to 2.85 °/s, scales a
// quarter off) — into a land archive of a MEMS unit. `calibrate --method legacy` finds its
// rests without a calibration, passes the data checks at its grade, calibrates from scratch and
// passes the MEMS limits; the calibration then makes every rest see one gravity and the gyros carry
// gravity from rest to rest — the figures of the multi-position method's own residuals, computed
// here from the archive and the printed parameters alone. Imported as navigation grade, the same
// recording is refused naming the missing rest.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <fstream>
#include <nlohmann/json.hpp>

#include "calib/core/conventions.hpp"
#include "calib/core/rotation.hpp"
#include "calib/core/variation_rest_detector.hpp"
#include "db/archive/run_archive.hpp"
#include "tests/support/imucal_cli.hpp"
#include "tests/support/temp_dir.hpp"

namespace imucal {
namespace {

using calib::ImuSeries;
using Eigen::Matrix3d;
using Eigen::Vector3d;

constexpr double kGravity_mps2 = 9.81744;  // the gravity IMU-TK's own example calibrates with

/// The recording as a user gets it in: the two files decompressed beside the archive, then
/// `imucal import` with the committed config (tests/data/imu_tk_xsens/import.toml); `extra`
/// flags override it. Returns the archive directory.
std::string import_xsens(const test_support::ScopedTempDir& dir, const std::string& extra = "") {
  const std::string data = std::string(IMUCAL_SOURCE_DIR) + "/tests/data/imu_tk_xsens/";
  for (const char* f : {"xsens_gyro.mat", "xsens_acc.mat"})
    EXPECT_EQ(
        std::system(("xz -dc '" + data + f + ".xz' > '" + dir.path() + "/" + f + "'").c_str()), 0);
  const std::string out = dir.path() + "/run";
  const auto r = test_support::run_imucal("import --config " + data + "import.toml --gyro " +
                                          dir.path() + "/xsens_gyro.mat --accel " + dir.path() +
                                          "/xsens_acc.mat --out " + out + " " + extra);
  EXPECT_EQ(r.code, 0) << r.out;
  return out;
}

Matrix3d matrix(const nlohmann::json& j) {
  Matrix3d m;
  for (int i = 0; i < 3; ++i)
    for (int k = 0; k < 3; ++k) m(i, k) = j.at(i).at(k).get<double>();
  return m;
}
Vector3d vector(const nlohmann::json& j) {
  return {j.at(0).get<double>(), j.at(1).get<double>(), j.at(2).get<double>()};
}

TEST(ImucalRealRecording, LegacyCalibratesTheImuTkXsensUnitFromScratch) {
  test_support::ScopedTempDir dir("imucal-xsens");
  const std::string run = import_xsens(dir);
  const ImuSeries imu = archive::read_archive(run).imu;  // as imported: re-stamped, rates × T
  ASSERT_EQ(imu.size(), 51175u);
  const auto r = test_support::run_imucal("calibrate " + run + " --method legacy --json",
                                          /*merge_stderr=*/false);
  ASSERT_EQ(r.code, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j.at("verdict"), "PASS") << j.at("limits").dump();
  const nlohmann::json& legacy = j.at("legacy");
  EXPECT_TRUE(legacy.at("converged").get<bool>());
  const nlohmann::json& p = legacy.at("params");
  const Vector3d b_a = vector(p.at("accel_bias_mps2")), b_g = vector(p.at("gyro_bias_radps"));
  const Matrix3d M_a = matrix(p.at("accel_M")), M_g = matrix(p.at("gyro_M"));
  // The unit as it is: gyro scales a quarter below nominal, offsets of −2.9 and −2.4 °/s.
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(M_g(i, i), -0.237, 0.01) << i;
  EXPECT_NEAR(b_g(1) * kRadToDeg, -2.87, 0.05);
  EXPECT_NEAR(b_g(2) * kRadToDeg, -2.35, 0.05);

  // The calibration's own test: compensate (eq. 18, 23 inverted) and look at the rests again.
  const Matrix3d Ma_inv = (Matrix3d::Identity() + M_a).inverse();
  const Matrix3d Mg_inv = (Matrix3d::Identity() + M_g).inverse();
  const auto rest =
      calib::detect_rest_by_variation(imu, calib::variation_rest_options(calib::Grade::kMems));
  struct Span {
    size_t begin, end;
    Vector3d f;
  };
  std::vector<Span> spans;
  for (size_t k = 0; k < imu.size();) {
    if (!rest.at_rest[k]) {
      ++k;
      continue;
    }
    Span s{k, k, Vector3d::Zero()};
    while (s.end < imu.size() && rest.at_rest[s.end]) {
      s.f += Ma_inv * (imu[s.end].dv_mps / imu[s.end].dt_s - b_a);
      ++s.end;
    }
    s.f /= static_cast<double>(s.end - s.begin);
    spans.push_back(s);
    k = s.end;
  }
  double g2 = 0.0, c2 = 0.0;
  for (const auto& s : spans) g2 += std::pow(s.f.norm() - kGravity_mps2, 2);
  for (size_t i = 0; i + 1 < spans.size(); ++i) {
    // Across the move only: from the last sample of one rest to the first of the next.
    Matrix3d C = Matrix3d::Identity();  // body there w.r.t. body here, compensated gyros
    for (size_t k = spans[i].end; k <= spans[i + 1].begin; ++k)
      C = C * calib::rotvec_to_matrix<double>(
                  Vector3d(Mg_inv * (imu[k].dtheta_rad - b_g * imu[k].dt_s)));
    const Vector3d carried = C.transpose() * spans[i].f;
    c2 +=
        std::pow(std::atan2(carried.cross(spans[i + 1].f).norm(), carried.dot(spans[i + 1].f)), 2);
  }
  const double gravity_rms_mg = std::sqrt(g2 / spans.size()) / kStandardGravity_mps2 * 1e3;
  const double carried_rms_deg = std::sqrt(c2 / (spans.size() - 1)) * kRadToDeg;
  std::printf(
      "xsens (IMU-TK data), legacy from scratch: %zu rests; gravity magnitude residual RMS "
      "%.3f mg; gyro-carried gravity RMS %.3f deg\n",
      spans.size(), gravity_rms_mg, carried_rms_deg);
  // Raw, the rests' |f| spread over 9.0–12.6 m/s² and the gyros carry gravity tens of degrees
  // astray; a multi-position calibration worth the name leaves its noise (a tenth of a mg over a
  // few seconds' rest) and the hand's settling (tenths of a degree).
  EXPECT_LT(gravity_rms_mg, 0.2);
  EXPECT_LT(carried_rms_deg, 1.0);
}

TEST(ImucalRealRecording, HeldToNavigationGradeTheUnitHasNoRestAndGradeOnTheCommandLineFixesIt) {
  test_support::ScopedTempDir dir("imucal-xsens-nav");
  const std::string run = import_xsens(dir, "--grade navigation");
  const auto nav = test_support::run_imucal("calibrate " + run + " --method legacy");
  EXPECT_NE(nav.code, 0);
  EXPECT_NE(nav.out.find("no rest found in the IMU data at all"), std::string::npos) << nav.out;
  const auto mems = test_support::run_imucal("calibrate " + run + " --method legacy --grade mems");
  EXPECT_EQ(mems.code, 0) << mems.out;
  EXPECT_NE(mems.out.find("verdict: PASS"), std::string::npos) << mems.out;
  const auto bad = test_support::run_imucal("calibrate " + run + " --grade consumer");
  EXPECT_NE(bad.code, 0);
  EXPECT_NE(bad.out.find("--grade"), std::string::npos) << bad.out;
}

}  // namespace
}  // namespace imucal
