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
#include <functional>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "calib/core/conventions.hpp"
#include "calib/core/rotation.hpp"
#include "calib/core/variation_rest_detector.hpp"
#include "db/archive/run_archive.hpp"
#include "tests/support/imu_tk_xsens.hpp"
#include "tests/support/imucal_cli.hpp"
#include "tests/support/temp_dir.hpp"

namespace imucal {
namespace {

using calib::core::ImuSeries;
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

/// A calibration as what it does to one raw sample: compensated specific force and rate.
struct Compensation {
  std::function<Vector3d(const calib::core::ImuIncrement&)> f_mps2, w_radps;
};

/// The multi-position method's own residuals under a calibration: at every rest span, |f̄| - g;
/// across every move (last sample of one rest to the first of the next), the angle between the
/// gravity the compensated gyros carry over and the gravity the next rest sees.
struct Figures {
  size_t rests = 0;
  double gravity_rms_mg = 0.0, carried_rms_deg = 0.0;
  /// The same magnitudes weighted by each rest's length (its mean's noise variance is VRW²/T):
  /// the residual a fit by the rests' noise minimises, where every rest counts the same above.
  double gravity_weighted_rms_mg = 0.0;
};

Figures residual_figures(const ImuSeries& imu, const std::vector<bool>& at_rest,
                         const Compensation& c) {
  struct Span {
    size_t begin, end;
    Vector3d f;
  };
  std::vector<Span> spans;
  for (size_t k = 0; k < imu.size();) {
    if (!at_rest[k]) {
      ++k;
      continue;
    }
    Span s{k, k, Vector3d::Zero()};
    while (s.end < imu.size() && at_rest[s.end]) s.f += c.f_mps2(imu[s.end++]);
    s.f /= static_cast<double>(s.end - s.begin);
    spans.push_back(s);
    k = s.end;
  }
  double g2 = 0.0, c2 = 0.0, gw2 = 0.0, w = 0.0;
  for (const auto& s : spans) {
    const double e2 = std::pow(s.f.norm() - kGravity_mps2, 2), n = double(s.end - s.begin);
    g2 += e2;
    gw2 += n * e2;
    w += n;
  }
  for (size_t i = 0; i + 1 < spans.size(); ++i) {
    Matrix3d C = Matrix3d::Identity();  // body there w.r.t. body here, compensated gyros
    for (size_t k = spans[i].end; k <= spans[i + 1].begin; ++k)
      C = C * calib::core::rotvec_to_matrix<double>(Vector3d(c.w_radps(imu[k]) * imu[k].dt_s));
    const Vector3d carried = C.transpose() * spans[i].f;
    c2 +=
        std::pow(std::atan2(carried.cross(spans[i + 1].f).norm(), carried.dot(spans[i + 1].f)), 2);
  }
  Figures out;
  out.rests = spans.size();
  out.gravity_rms_mg = std::sqrt(g2 / spans.size()) / kStandardGravity_mps2 * 1e3;
  out.gravity_weighted_rms_mg = std::sqrt(gw2 / w) / kStandardGravity_mps2 * 1e3;
  out.carried_rms_deg = std::sqrt(c2 / (spans.size() - 1)) * kRadToDeg;
  return out;
}

/// IMU-TK's calibration of this recording (tests/data/imu_tk_xsens/imu_tk_result.txt): X' = T K
/// (X - B) on raw counts, which the imported archive holds as (counts - 32768) × the nominal
/// scale of import.toml, per second.
Compensation imu_tk_compensation() {
  std::ifstream f(std::string(IMUCAL_SOURCE_DIR) + "/tests/data/imu_tk_xsens/imu_tk_result.txt");
  EXPECT_TRUE(f.good());
  std::map<std::string, std::vector<double>> v;
  for (std::string line; std::getline(f, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream ls(line);
    std::string key;
    ls >> key;
    for (double x; ls >> x;) v[key].push_back(x);
  }
  auto mat = [&](const char* key) {
    EXPECT_EQ(v[key].size(), 9u) << key;
    Matrix3d m;
    for (int i = 0; i < 9; ++i) m(i / 3, i % 3) = v[key].at(static_cast<size_t>(i));
    return m;
  };
  auto vec = [&](const char* key) {
    EXPECT_EQ(v[key].size(), 3u) << key;
    return Vector3d(v[key].at(0), v[key].at(1), v[key].at(2));
  };
  const Matrix3d TKa = mat("acc_misalignment") * vec("acc_scale").asDiagonal();
  const Matrix3d TKg = mat("gyro_misalignment") * vec("gyro_scale").asDiagonal();
  const Vector3d Ba = vec("acc_bias"), Bg = vec("gyro_bias");
  using test_support::kAccel_mps2_per_count, test_support::kGyro_radps_per_count,
      test_support::kZero_counts;  // the nominal values of import.toml
  return {[=](const calib::core::ImuIncrement& s) {
            const Vector3d counts =
                (s.dv_mps / s.dt_s / kAccel_mps2_per_count).array() + kZero_counts;
            return Vector3d(TKa * (counts - Ba));
          },
          [=](const calib::core::ImuIncrement& s) {
            const Vector3d counts =
                (s.dtheta_rad / s.dt_s / kGyro_radps_per_count).array() + kZero_counts;
            return Vector3d(TKg * (counts - Bg));
          }};
}

/// A calibrate --json result as what it does to one sample (eq. 18 and 23 inverted).
Compensation compensation_of(const nlohmann::json& p) {
  const Vector3d b_a = vector(p.at("accel_bias_mps2")), b_g = vector(p.at("gyro_bias_radps"));
  const Matrix3d Ma_inv = (Matrix3d::Identity() + matrix(p.at("accel_M"))).inverse();
  const Matrix3d Mg_inv = (Matrix3d::Identity() + matrix(p.at("gyro_M"))).inverse();
  return {[=](const calib::core::ImuIncrement& s) {
            return Vector3d(Ma_inv * (s.dv_mps / s.dt_s - b_a));
          },
          [=](const calib::core::ImuIncrement& s) {
            return Vector3d(Mg_inv * (s.dtheta_rad / s.dt_s - b_g));
          }};
}

TEST(ImucalRealRecording, LegacyCalibratesTheImuTkXsensUnitFromScratch) {
  test_support::ScopedTempDir dir("imucal-xsens");
  const std::string run = import_xsens(dir);
  const ImuSeries imu = db::archive::read_archive(run).imu;  // as imported: re-stamped, rates × T
  ASSERT_EQ(imu.size(), 51175u);
  const auto r = test_support::run_imucal("calibrate " + run + " --method legacy --json",
                                          /*merge_stderr=*/false);
  ASSERT_EQ(r.code, 0) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j.at("verdict"), "PASS") << j.at("limits").dump();
  const nlohmann::json& legacy = j.at("legacy");
  EXPECT_TRUE(legacy.at("converged").get<bool>());
  const nlohmann::json& p = legacy.at("params");
  const Vector3d b_g = vector(p.at("gyro_bias_radps"));
  const Matrix3d M_g = matrix(p.at("gyro_M"));
  // The unit as it is: gyro scales a quarter below nominal, offsets of −2.9 and −2.4 °/s.
  for (int i = 0; i < 3; ++i) EXPECT_NEAR(M_g(i, i), -0.237, 0.01) << i;
  EXPECT_NEAR(b_g(1) * kRadToDeg, -2.87, 0.05);
  EXPECT_NEAR(b_g(2) * kRadToDeg, -2.35, 0.05);

  // The calibration's own test: compensate (eq. 18, 23 inverted) and look at the rests again —
  // and do the same with the peer's own calibration of this recording (IMU-TK, reproduced by
  // tests/data/imu_tk_xsens/reproduce_imu_tk.sh), on the same rests and moves.
  const Compensation ours = compensation_of(p);
  const auto rest = calib::core::detect_rest_by_variation(
      imu, calib::core::variation_rest_options(calib::core::Grade::kMems));
  const Figures mine = residual_figures(imu, rest.at_rest, ours);
  const Figures peer = residual_figures(imu, rest.at_rest, imu_tk_compensation());
  std::printf(
      "xsens (IMU-TK data) on the same %zu rests: gravity magnitude residual RMS %.3f mg (IMU-TK "
      "%.3f), gyro-carried gravity RMS %.3f deg (IMU-TK %.3f)\n",
      mine.rests, mine.gravity_rms_mg, peer.gravity_rms_mg, mine.carried_rms_deg,
      peer.carried_rms_deg);
  std::printf("  gravity magnitude residual weighted by rest length: %.4f mg (IMU-TK %.4f)\n",
              mine.gravity_weighted_rms_mg, peer.gravity_weighted_rms_mg);
  // Raw, the rests' |f| spread over 9.0–12.6 m/s² and the gyros carry gravity tens of degrees
  // astray; a multi-position calibration worth the name leaves its noise (a tenth of a mg over a
  // few seconds' rest) and the hand's settling (tenths of a degree) — and the peer's does.
  // Weighted by each rest's noise (its length), the figure a fit by the rests' noise minimises,
  // this calibration is no worse than the peer's; counting every rest the same (IMU-TK's own
  // objective, on its own intervals), the peer's sits 4 % lower.
  EXPECT_LE(mine.gravity_weighted_rms_mg, peer.gravity_weighted_rms_mg);
  EXPECT_LT(mine.gravity_rms_mg, 0.2);
  EXPECT_LT(mine.carried_rms_deg, 1.0);
  EXPECT_LT(peer.gravity_rms_mg, 0.2);
  EXPECT_LT(peer.carried_rms_deg, 1.0);
}

// Issue #48 item 7: on this real MEMS recording land AINS leaves more at the rests than 1.5× the
// legacy fit does (the test's own residual arithmetic on the rest detector's spans, not the
// program's). `--method all` says so with both figures, its verdict is the legacy fit's own, and
// the set `imucal check` takes from it — the station's active set — is legacy's.
TEST(ImucalRealRecording, AllRestsOnLegacyWhereLandAinsCannotHoldTheRests) {
  test_support::ScopedTempDir dir("imucal-xsens-holds");
  const std::string run = import_xsens(dir);
  const std::string cal = dir.path() + "/all.json";
  const auto r = test_support::run_imucal(
      "calibrate " + run + " --method all --setting land --grade mems --json", false);
  ASSERT_NE(r.code, 1) << r.out;
  std::ofstream(cal) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  const ImuSeries imu = db::archive::read_archive(run).imu;
  const auto rest = calib::core::detect_rest_by_variation(
      imu, calib::core::variation_rest_options(calib::core::Grade::kMems));
  const Figures ains =
      residual_figures(imu, rest.at_rest, compensation_of(j.at("ains").at("params")));
  const Figures legacy =
      residual_figures(imu, rest.at_rest, compensation_of(j.at("legacy").at("params")));
  std::printf("xsens --method all: |f|-g RMS over %zu rests AINS %.3f mg, legacy %.3f mg (%.2fx)\n",
              ains.rests, ains.gravity_rms_mg, legacy.gravity_rms_mg,
              ains.gravity_rms_mg / legacy.gravity_rms_mg);
  ASSERT_GT(ains.gravity_rms_mg, 1.5 * legacy.gravity_rms_mg) << "the premise of this test";

  const nlohmann::json& h = j.at("holding");
  EXPECT_EQ(h.at("method"), "legacy") << h.dump(2);
  EXPECT_EQ(h.at("max_ratio").get<double>(), 1.5);
  const std::string why = h.at("reason");
  char figure[32];
  for (const char* key : {"ains_rest_rms_mps2", "legacy_rest_rms_mps2"}) {
    const double mg = h.at(key).get<double>() / kStandardGravity_mps2 * 1e3;
    ASSERT_TRUE(mg >= 0.1 && mg < 1.0) << key << " " << mg << " mg";
    std::snprintf(figure, sizeof figure, "%.2f mg", mg);
    EXPECT_NE(why.find(figure), std::string::npos) << figure << " in: " << why;
  }
  EXPECT_NE(why.find("over the " + std::to_string(h.at("rests").get<size_t>()) + " rests"),
            std::string::npos)
      << why;
  EXPECT_NE(why.find("the filter cannot hold the rests"), std::string::npos) << why;
  EXPECT_NE(why.find("rest on legacy"), std::string::npos) << why;

  // The verdict is the legacy fit's on its own (`--method legacy`): PASS, exit 0.
  const auto alone =
      test_support::run_imucal("calibrate " + run + " --method legacy --json", false);
  EXPECT_EQ(j.at("verdict"), nlohmann::json::parse(alone.out).at("verdict"));
  EXPECT_EQ(j.at("verdict"), "PASS") << j.at("limits").dump();
  EXPECT_EQ(r.code, 0);

  // `imucal check` with this calibration takes the set that holds, and judges it on the same
  // rests as the program's own figure.
  const auto check = test_support::run_imucal("check " + cal + " " + run + " --json", false);
  ASSERT_EQ(check.code, 0) << check.out;
  const nlohmann::json c = nlohmann::json::parse(check.out);
  EXPECT_EQ(c.at("calibration").at("method"), "legacy") << c.at("calibration").dump();
  EXPECT_NEAR(c.at("rms").at("rest_corrected_mps2").get<double>(),
              h.at("legacy_rest_rms_mps2").get<double>(), 1e-9);
  EXPECT_EQ(c.at("rests").size(), h.at("rests").get<size_t>());

  // The printed report says the same.
  const auto text = test_support::run_imucal("calibrate " + run + " --method all", false);
  EXPECT_NE(text.out.find("holds: legacy — AINS leaves"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("verdict: PASS — on legacy alone"), std::string::npos) << text.out;
}

TEST(ImucalRealRecording, HeldToNavigationGradeTheUnitHasNoRestAndGradeOnTheCommandLineFixesIt) {
  test_support::ScopedTempDir dir("imucal-xsens-nav");
  // Imported as navigation grade, its gyros' offsets at rest (a few °/s) are no navigation unit's
  // bias: refused at import naming the grade (issue #48 item 5), not later as "no rest".
  const std::string data = std::string(IMUCAL_SOURCE_DIR) + "/tests/data/imu_tk_xsens/";
  const std::string run = import_xsens(dir, "--grade navigation --skip-plausibility");
  const auto refused = test_support::run_imucal(
      "import --config " + data + "import.toml --gyro " + dir.path() + "/xsens_gyro.mat --accel " +
      dir.path() + "/xsens_acc.mat --out " + dir.path() + "/refused --grade navigation");
  EXPECT_NE(refused.code, 0);
  EXPECT_NE(refused.out.find("beyond what a navigation unit's bias may be"), std::string::npos)
      << refused.out;
  EXPECT_NE(refused.out.find("(--grade)"), std::string::npos) << refused.out;
  EXPECT_FALSE(std::filesystem::exists(dir.path() + "/refused"));
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

// Diagnosis without a table on real data (issue #21 item 4): each rest's attitude an unknown, the
// legacy calibration the model under test. The unit departs from the model by far (χ²/dof ~75);
// the diagnosis names what a MEMS gyro is known for — a g-sensitivity of ~0.2 °/s/g (Xsens's MTi
// datasheet class: 0.1 °/s/g) — and a few milliseconds' skew between the gyro and accelerometer
// files' time stamps (they were stamped apart), which together remove most of the held-out gap.
// What remains is said, not hidden: the verdict stays "unexplained" (exit 3).
TEST(ImucalRealRecording, DiagnosisWithoutATableNamesTheGyrosGSensitivityAndTheTimingSkew) {
  test_support::ScopedTempDir dir("imucal-xsens-diag");
  const std::string run = import_xsens(dir);
  const std::string report = dir.path() + "/report";
  const auto r = test_support::run_imucal("diagnose " + run + " --json --report " + report,
                                          /*merge_stderr=*/false);
  EXPECT_EQ(r.code, 3) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  EXPECT_TRUE(j.at("table_free").get<bool>());
  EXPECT_EQ(j.at("grade"), "mems");
  EXPECT_GT(j.at("overall").at("gap").get<double>(), 10.0);
  std::map<std::string, nlohmann::json> cand;
  for (const auto& c : j.at("candidates")) cand[c.at("effect").get<std::string>()] = c;
  ASSERT_TRUE(j.at("best").is_object()) << j.at("summary");
  EXPECT_EQ(j.at("best").at("effect"), "gyro_g_sensitivity");
  EXPECT_EQ(j.at("second").at("effect"), "gyro_accel_skew");
  const double g_sens_deg_per_s_per_g =
      cand.at("gyro_g_sensitivity").at("magnitude").get<double>() / 3600.0;
  std::printf("xsens: g-sensitivity %.3f deg/s/g, skew %.2f ms, held-out gap %.1f -> %.2f\n",
              g_sens_deg_per_s_per_g, cand.at("gyro_accel_skew").at("magnitude").get<double>(),
              j.at("held_out").at("gap_before").get<double>(),
              j.at("held_out").at("gap_after_pair").get<double>());
  // Stepwise (issue #22 item 2): the two named first, then whatever else the held-out segments
  // confirm; each step must shrink the held-out gap.
  const nlohmann::json& steps = j.at("steps");
  ASSERT_GE(steps.size(), 2u);
  EXPECT_EQ(steps.at(0).at("effect"), "gyro_g_sensitivity");
  EXPECT_EQ(steps.at(1).at("effect"), "gyro_accel_skew");
  double held = j.at("held_out").at("gap_before").get<double>();
  for (const auto& st : steps) {
    // A per-sample noise step (quantisation, the output filter) changes no segment residual: its
    // held_out_after is its own lag-1 statistic's, not comparable with the segments' gap.
    if (st.at("effect") == "output_filter" || st.at("effect") == "quantisation") continue;
    std::printf("  step %s = %.4g +- %.2g %s: held-out gap -> %.3f\n",
                st.at("effect").get<std::string>().c_str(), st.at("magnitude").get<double>(),
                st.at("sigma").get<double>(), st.at("unit").get<std::string>().c_str(),
                st.at("held_out_after").get<double>());
    EXPECT_LT(st.at("held_out_after").get<double>(), held) << st.dump();
    held = st.at("held_out_after").get<double>();
  }
  EXPECT_GT(g_sens_deg_per_s_per_g, 0.1);
  EXPECT_LT(g_sens_deg_per_s_per_g, 0.4);
  EXPECT_TRUE(cand.at("gyro_g_sensitivity").at("significant").get<bool>());
  EXPECT_TRUE(cand.at("gyro_accel_skew").at("significant").get<bool>());
  EXPECT_GT(j.at("held_out").at("shrinkage").get<double>(), 0.8);
  EXPECT_TRUE(std::ifstream(report + "/report.html").good());

  // Land AINS on the unit as it is: its model has no g-sensitivity, and a fifth of a degree per
  // second that changes with every position is far beyond its noise — the innovations say so
  // (mean NIS 17, σ scaled by its root). (Before the MEMS tilt track, b83918f, the passes did not
  // converge at all: mean NIS 456, the nominal's own tilt wander on top.)
  const auto plain = test_support::run_imucal("calibrate " + run + " --json", false);
  auto misfit_warned = [](const nlohmann::json& ains) {
    for (const auto& w : ains.at("warnings"))
      if (w.get<std::string>().rfind("innovations larger than the noise model", 0) == 0)
        return true;
    return false;
  };
  EXPECT_TRUE(misfit_warned(nlohmann::json::parse(plain.out).at("ains"))) << plain.out;
  // With the diagnosed effects removed first, the innovations fit the noise model, the AINS
  // converges and agrees with the multi-position method on nearly every term (what still differs
  // is printed: the cross-check's failures).
  const auto fixed = test_support::run_imucal(
      "calibrate " + run + " --json --compensate " + report + "/diagnosis.json", false);
  const nlohmann::json c = nlohmann::json::parse(fixed.out);
  EXPECT_TRUE(c.at("ains").at("converged").get<bool>()) << c.at("ains").at("warnings").dump();
  EXPECT_FALSE(misfit_warned(c.at("ains"))) << c.at("ains").at("warnings").dump();
  EXPECT_TRUE(c.at("limits").at("pass").get<bool>()) << c.at("limits").dump();
  // Every step but a noise one (the output filter: left to the noise model, not subtracted).
  size_t removable = 0;
  for (const auto& st : steps)
    removable += st.at("effect") == "output_filter" || st.at("effect") == "quantisation" ? 0 : 1;
  ASSERT_EQ(c.at("compensated").at("effects").size(), removable);
  EXPECT_EQ(
      c.at("compensated").at("effects").at(0).get<std::string>().rfind("gyro_g_sensitivity", 0),
      0u);
  const size_t failing = c.at("crosscheck").at("failures").size();
  std::printf(
      "xsens compensated: land AINS converged, cross-check with legacy: %zu of 24 terms "
      "beyond 4 sigma\n",
      failing);
  EXPECT_LE(failing, 4u) << c.at("crosscheck").dump();
}

// The Xsens unit low-pass filters its output (issue #48 item 8): its rest samples are correlated
// sample to sample (the whiteness line's lag-1 z far above 0 on every axis), which white noise
// cannot do and quantisation would do with the opposite sign. The diagnosis names output_filter
// (a first-order filter y_k = a y_{k-1} + (1-a) x_k) with each sensor's coefficient well inside
// (0, 1), and the coefficient fitted on four folds of rests predicts the fifth: its held-out gap
// shrinks by more than the diagnosis' documented fraction (min_shrinkage, half the excess). The
// segment residuals' gap is not the filter's (its DC gain is 1): the verdict stays "unexplained".
TEST(ImucalRealRecording, DiagnosisNamesTheXsensOutputFilterFromItsCorrelatedRestSamples) {
  test_support::ScopedTempDir dir("imucal-xsens-filter");
  const std::string run = import_xsens(dir);
  const auto r = test_support::run_imucal("diagnose " + run + " --json", /*merge_stderr=*/false);
  EXPECT_EQ(r.code, 3) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  for (const auto& [axis, w] : j.at("whiteness").at("axes").items())
    EXPECT_GT(w.at("lag1_z").get<double>(), 5.0) << axis;
  nlohmann::json f;
  for (const auto& c : j.at("candidates"))
    if (c.at("effect") == "output_filter") f = c;
  ASSERT_TRUE(f.is_object());
  EXPECT_TRUE(f.at("significant").get<bool>()) << f.dump();
  bool in_steps = false;
  for (const auto& st : j.at("steps")) in_steps = in_steps || st.at("effect") == "output_filter";
  EXPECT_TRUE(in_steps) << j.at("summary");
  for (const auto& p : f.at("parameters")) {
    const double a = p.at("value").get<double>(), s = p.at("sigma").get<double>();
    std::printf("xsens output_filter %s = %.3f +- %.3f\n", p.at("name").get<std::string>().c_str(),
                a, s);
    EXPECT_GT(a, 3.0 * s);
    EXPECT_LT(a, 1.0);
  }
  const double before = f.at("held_out_gap_before").get<double>();
  const double after = f.at("held_out_gap").get<double>();
  std::printf(
      "xsens: lag-1 held-out gap %.1f -> %.2f; segments chi2/dof %.1f, after the steps %.2f, "
      "held-out %.1f -> %.2f; verdict %s\n",
      before, after, j.at("overall").at("gap").get<double>(),
      j.at("overall").at("gap_after_best").get<double>(),
      j.at("held_out").at("gap_before").get<double>(),
      j.at("held_out").at("gap_after_pair").get<double>(),
      j.at("verdict").get<std::string>().c_str());
  EXPECT_GT(before, 10.0);
  EXPECT_GT((before - after) / (before - 1.0), 0.5);
}

// IMU-TK's Xsens unit was placed on a surface for each position, not held (issue #48 item 8): a
// real null for the hand's tremor. Its accelerometers do not follow its gyro-integrated tilt
// within the rests — the slope of rest_tremor's regression is 0 within its σ — so rest_tremor is
// neither significant nor named, and the output filter stays judged on every rest (the hand's
// motion would have narrowed it to the still ones).
TEST(ImucalRealRecording, DiagnosisFindsNoHandInTheXsensRests) {
  test_support::ScopedTempDir dir("imucal-xsens-tremor");
  const std::string run = import_xsens(dir);
  const auto r = test_support::run_imucal("diagnose " + run + " --json", /*merge_stderr=*/false);
  EXPECT_EQ(r.code, 3) << r.out;
  const nlohmann::json j = nlohmann::json::parse(r.out);
  nlohmann::json t, f;
  for (const auto& c : j.at("candidates")) {
    if (c.at("effect") == "rest_tremor") t = c;
    if (c.at("effect") == "output_filter") f = c;
  }
  ASSERT_TRUE(t.is_object());
  std::printf("xsens rest_tremor: lr %.2f, p %.3g; %s\n", t.at("lr").get<double>(),
              t.at("p_value").get<double>(), t.at("note").get<std::string>().c_str());
  EXPECT_FALSE(t.at("significant").get<bool>()) << t.dump();
  EXPECT_GT(t.at("p_value").get<double>(), 1e-3 / 15.0);
  for (const auto& st : j.at("steps")) EXPECT_NE(st.at("effect"), "rest_tremor") << j.at("summary");
  ASSERT_TRUE(f.is_object());
  EXPECT_EQ(f.at("note").get<std::string>().find("rests whose gyros show no motion"),
            std::string::npos)
      << f.at("note");
}

// --compensate takes a diagnosis and nothing else: each bad input named, nothing calibrated.
TEST(ImucalRealRecording, CompensateRefusesWhatIsNotADiagnosisFinding) {
  test_support::ScopedTempDir dir("imucal-xsens-comp");
  const std::string run = import_xsens(dir);
  auto write = [&](const std::string& name, const std::string& text) {
    std::ofstream(dir.path() + "/" + name) << text;
    return dir.path() + "/" + name;
  };
  const struct {
    std::string file, says;
  } cases[] = {
      {dir.path() + "/missing.json", "cannot read it"},
      {write("text.json", "not json"), "not JSON"},
      {write("other.json", "{\"ains\": {}}"), "not a gap diagnosis"},
      {write("none.json", "{\"verdict\": \"consistent\", \"best\": null}"),
       "names no effect to compensate"},
      {write("noise.json",
             "{\"verdict\": \"explained\", \"best\": {\"effect\": \"quantisation\", "
             "\"parameters\": [{\"name\": \"dtheta_lsb\", \"value\": 50}, {\"name\": "
             "\"dv_lsb\", \"value\": 10}]}}"),
       "is noise"},
      {write("partial.json",
             "{\"verdict\": \"explained\", \"best\": {\"effect\": \"gyro_accel_skew\", "
             "\"parameters\": []}}"),
       "parameter t_GA missing"},
      {write(
           "unknown.json",
           "{\"verdict\": \"explained\", \"best\": {\"effect\": \"wobble\", \"parameters\": []}}"),
       "unknown effect \"wobble\""},
  };
  for (const auto& c : cases) {
    const auto r = test_support::run_imucal("calibrate " + run + " --compensate " + c.file);
    EXPECT_EQ(r.code, 1) << c.file << ": " << r.out;
    EXPECT_NE(r.out.find("--compensate " + c.file), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(c.says), std::string::npos) << r.out;
  }
}

}  // namespace
}  // namespace imucal
