// `imucal check` and `imucal apply` (issue #48 item 6) as a user runs them: the real binary on two
// simulated land recordings of the SAME MEMS unit (one unit file, two seeds: other hand placements,
// other noise), the first calibrated with `imucal calibrate --method legacy --grade mems --json`,
// the second checked with that result. The figures are judged by physics, not by the code:
//  * uncompensated, the unit's errors (accelerometer biases 45–120 mg and scales 4–8 %, gyro
//    offsets 2.5–3.5 °/s and scales 12–20 %) put |f| − g at tens of mg and the carried gravity tens
//    of degrees off;
//  * compensated, what is left is this recording's white noise — VRW/√T along gravity at a rest of
//    T seconds; ARW²Δt per axis across a move of Δt plus each rest's direction noise — plus the
//    Earth's turn under gravity (Ω cos φ Δt, which no MEMS gyro can take out: it cannot find
//    north) and the first recording's fit error, the same noise spread over its 39 rests and 38
//    moves (a fraction of one rest's): within twice the noise floor;
//  * apply writes the recording compensated, so a zero parameter set on it sees what the
//    calibration saw on the original (the rests found afresh on compensated data may end a sample
//    or two elsewhere: a sample's noise over a rest's length);
//  * bad input (a missing file, a JSON of neither form, a run archive as CALIBRATION, a DIR
//    without IMU data, an existing --out) is one line naming the file, exit 1, nothing written.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <string>

#include "calib/core/conventions.hpp"
#include "calib/core/earth.hpp"
#include "calib/core/site_presets.hpp"
#include "tests/support/imucal_cli.hpp"
#include "tests/support/temp_dir.hpp"

namespace fs = std::filesystem;

namespace {

using ProcImucalCheckCli = imucal::test_support::CommandResult;
using imucal::test_support::slurp;

ProcImucalCheckCli run_imucal_check_cli(const std::string& args, bool merge_stderr = true) {
  return imucal::test_support::run_imucal(args, merge_stderr);
}

/// The unit of both recordings: a MEMS unit read with nominal scales, the class's worst noise.
constexpr const char* kCheckCliUnit = R"(grade = "mems"
[accel]
bias_ug = [80000.0, -45000.0, 120000.0]
M_ppm = [[40000.0, 15000.0, -20000.0],
         [-10000.0, -60000.0, 25000.0],
         [30000.0, -5000.0, 80000.0]]
[gyro]
bias_deg_per_h = [10800.0, -12600.0, 9000.0]
M_ppm = [[150000.0, 20000.0, -30000.0],
         [10000.0, -120000.0, 40000.0],
         [-25000.0, 15000.0, 200000.0]]
[noise]
arw_deg_per_sqrt_h = 1.0
vrw_ug_per_sqrt_hz = 300.0
)";
constexpr double kCheckCliVrw = 300e-6 * imucal::kStandardGravity_mps2;  // m/s/√s
constexpr double kCheckCliArw = 1.0 * imucal::kDegToRad / 60.0;          // rad/√s
constexpr const char* kCheckCliZeroParams =
    R"({"accel_bias_mps2":[0,0,0],"accel_M":[[0,0,0],[0,0,0],[0,0,0]],"gyro_bias_radps":[0,0,0],)"
    R"("gyro_M":[[0,0,0],[0,0,0],[0,0,0]],"table_misalignment_rad":[0,0,0]})";

class CheckCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new imucal::test_support::ScopedTempDir("check-cli");
    std::ofstream(root() / "unit.toml") << kCheckCliUnit;
    std::ofstream(root() / "zero.json") << kCheckCliZeroParams;
    for (const char* seed : {"5", "6"})
      ASSERT_EQ(run_imucal_check_cli("simulate --setting land --sequence hand --unit " +
                                     (root() / "unit.toml").string() + " --seed " + seed +
                                     " --out " + (root() / ("run" + std::string(seed))).string())
                    .code,
                0);
    for (const char* method : {"legacy", "all"}) {
      const ProcImucalCheckCli c = run_imucal_check_cli(
          "calibrate " + run(1) + " --grade mems --json --method " + method, false);
      ASSERT_EQ(c.code, 0) << c.out;
      std::ofstream(root() / (std::string(method) + ".json")) << c.out;
    }
  }
  static void TearDownTestSuite() { delete dir_; }
  static fs::path root() { return fs::path(dir_->path()); }
  /// The first (calibrated) or second (checked) recording.
  static std::string run(int i) { return (root() / (i == 1 ? "run5" : "run6")).string(); }
  static std::string file(const std::string& name) { return (root() / name).string(); }
  static nlohmann::json check_json(const std::string& calibration, const std::string& dir) {
    const ProcImucalCheckCli p =
        run_imucal_check_cli("check " + calibration + " " + dir + " --json", false);
    EXPECT_EQ(p.code, 0) << p.out;
    return nlohmann::json::parse(p.out);
  }
  /// Every entry of the test's directory: what a refused command must leave as it was.
  static std::string everything() {
    std::string s;
    for (const auto& e : fs::recursive_directory_iterator(root())) s += e.path().string() + "\n";
    return s;
  }
  /// exit 1, one line on stderr naming `needle`, nothing written.
  static void expect_refused(const std::string& args, const std::string& needle) {
    const std::string before = everything();
    const ProcImucalCheckCli p = run_imucal_check_cli(args);
    EXPECT_EQ(p.code, 1) << args << "\n" << p.out;
    EXPECT_NE(p.out.find(needle), std::string::npos) << args << "\n" << p.out;
    EXPECT_EQ(std::count(p.out.begin(), p.out.end(), '\n'), 1) << p.out;
    EXPECT_EQ(everything(), before) << args;
  }
  static imucal::test_support::ScopedTempDir* dir_;
};
imucal::test_support::ScopedTempDir* CheckCli::dir_ = nullptr;

/// √(mean VRW²/T) over the rests and √(mean E[angle²]) over the moves: white noise and the
/// Earth's turn (header comment).
struct CheckCliFloor {
  double rest_mps2 = 0.0, move_rad = 0.0;
};
CheckCliFloor check_cli_noise_floor(const nlohmann::json& j) {
  const double lat = imucal::calib::core::demo_factory_site().lat_rad;
  const double g = j.at("gravity_mps2").get<double>();
  auto T = [](const nlohmann::json& r) {
    return r.at("t_end_s").get<double>() - r.at("t_begin_s").get<double>();
  };
  const nlohmann::json& rests = j.at("rests");
  const nlohmann::json& moves = j.at("moves");
  double r2 = 0.0, m2 = 0.0;
  for (const auto& r : rests) r2 += kCheckCliVrw * kCheckCliVrw / T(r);
  for (size_t p = 0; p < moves.size(); ++p) {
    const double dt = moves[p].at("t_to_s").get<double>() - moves[p].at("t_from_s").get<double>();
    const double dir2 =
        kCheckCliVrw * kCheckCliVrw / (g * g) * (1.0 / T(rests[p]) + 1.0 / T(rests[p + 1]));
    const double earth = imucal::calib::core::wgs84::kEarthRate_radps * std::cos(lat) * dt;
    m2 += 2.0 * (kCheckCliArw * kCheckCliArw * dt + dir2) + earth * earth;
  }
  return {std::sqrt(r2 / static_cast<double>(rests.size())),
          std::sqrt(m2 / static_cast<double>(moves.size()))};
}

TEST_F(CheckCli, ACalibrationOnASecondRecordingOfTheUnitLeavesItsNoise) {
  const nlohmann::json j = check_json(file("legacy.json"), run(2));
  EXPECT_EQ(j.at("calibration").at("form"), "calibrate_json");
  EXPECT_EQ(j.at("calibration").at("method"), "legacy");
  EXPECT_EQ(j.at("calibration").at("verdict"), "PASS");  // the calibration's, carried along
  EXPECT_EQ(j.at("uncalibrated"), "nominal values");
  EXPECT_EQ(j.at("grade"), "mems");
  ASSERT_GE(j.at("rests").size(), 30u);  // a 50 s start and 38 hand-placed positions
  EXPECT_EQ(j.at("moves").size(), j.at("rests").size() - 1);
  const nlohmann::json& rms = j.at("rms");
  const CheckCliFloor floor = check_cli_noise_floor(j);
  std::printf(
      "|f|-g RMS raw %.2f mg, corrected %.3f mg (noise %.3f mg); carried gravity RMS raw %.2f "
      "deg, corrected %.4f deg (noise and Earth %.4f deg)\n",
      rms.at("rest_raw_mps2").get<double>() / imucal::kStandardGravity_mps2 * 1e3,
      rms.at("rest_corrected_mps2").get<double>() / imucal::kStandardGravity_mps2 * 1e3,
      floor.rest_mps2 / imucal::kStandardGravity_mps2 * 1e3,
      rms.at("move_raw_rad").get<double>() * imucal::kRadToDeg,
      rms.at("move_corrected_rad").get<double>() * imucal::kRadToDeg,
      floor.move_rad * imucal::kRadToDeg);
  EXPECT_LT(rms.at("rest_corrected_mps2").get<double>(), 2.0 * floor.rest_mps2);
  EXPECT_LT(rms.at("move_corrected_rad").get<double>(), 2.0 * floor.move_rad);
  // Uncompensated: tens of mg (biases 45–120 mg), tens of degrees (3 °/s over 8 s moves).
  EXPECT_GT(rms.at("rest_raw_mps2").get<double>(), 20e-3 * imucal::kStandardGravity_mps2);
  EXPECT_GT(rms.at("move_raw_rad").get<double>(), 10.0 * imucal::kDegToRad);
  // The human report: both columns, the two RMS lines, and what "raw" means.
  const ProcImucalCheckCli t =
      run_imucal_check_cli("check " + file("legacy.json") + " " + run(2), false);
  ASSERT_EQ(t.code, 0) << t.out;
  for (const char* s : {"uncalibrated: nominal values", "|f|-g raw [mg]", "|f|-g corrected [mg]",
                        "gravity carried raw [deg]", "RMS over ", " rests: |f|-g raw ",
                        " moves: gravity carried raw ", "method legacy: the method that passed"})
    EXPECT_NE(t.out.find(s), std::string::npos) << s << "\n" << t.out;
}

TEST_F(CheckCli, FromAllMethodsTheActiveSetIsTakenOrTheOneNamed) {
  const nlohmann::json all = check_json(file("all.json"), run(2));
  EXPECT_EQ(all.at("calibration").at("method"), "ains");
  const ProcImucalCheckCli named = run_imucal_check_cli(
      "check " + file("all.json") + " " + run(2) + " --method legacy --json", false);
  ASSERT_EQ(named.code, 0) << named.out;
  EXPECT_EQ(nlohmann::json::parse(named.out).at("calibration").at("method"), "legacy");
  // A result that failed its limits is not taken silently.
  nlohmann::json failed = nlohmann::json::parse(slurp(file("legacy.json")));
  failed["limits"]["failures"].push_back(
      {{"method", "legacy"}, {"term", "accel_bias_mps2[0]"}, {"detail", "legacy: outside"}});
  std::ofstream(file("failed.json")) << failed.dump();
  expect_refused("check " + file("failed.json") + " " + run(2), "no method's result passed");
  // A parameter set file (as stationctl params prints) works as it is.
  std::ofstream(file("legacy-params.json"))
      << nlohmann::json::parse(slurp(file("legacy.json"))).at("legacy").at("params").dump();
  const nlohmann::json p = check_json(file("legacy-params.json"), run(2));
  EXPECT_EQ(p.at("calibration").at("form"), "parameter_set");
  EXPECT_EQ(p.at("rms"), check_json(file("legacy.json"), run(2)).at("rms"));
  fs::remove(file("failed.json"));
  fs::remove(file("legacy-params.json"));
}

TEST_F(CheckCli, ApplyWritesTheRecordingAsTheCalibrationSeesIt) {
  const std::string out = file("applied");
  const ProcImucalCheckCli a =
      run_imucal_check_cli("apply " + file("legacy.json") + " " + run(2) + " --out " + out);
  ASSERT_EQ(a.code, 0) << a.out;
  EXPECT_TRUE(fs::exists(fs::path(out) / "imu.csv"));
  EXPECT_EQ(slurp(fs::path(out) / "run.toml"), slurp(fs::path(run(2)) / "run.toml"));
  EXPECT_FALSE(fs::exists(fs::path(out) / "truth.json"));  // it describes the uncorrected unit
  const nlohmann::json before = check_json(file("legacy.json"), run(2));
  const nlohmann::json after = check_json(file("zero.json"), out);
  ASSERT_EQ(after.at("rests").size(), before.at("rests").size());
  ASSERT_EQ(after.at("moves").size(), before.at("moves").size());
  // Rests found afresh on the compensated data end within a few samples of the original's; a
  // sample's noise (VRW·√100 Hz ≈ 3 mg) over a rest of ≥ 100 samples moves its mean by < 0.03 mg
  // per sample moved.
  for (size_t p = 0; p < after.at("rests").size(); ++p) {
    const auto& r0 = before["rests"][p];
    const auto& r1 = after["rests"][p];
    EXPECT_NEAR(r1.at("t_begin_s").get<double>(), r0.at("t_begin_s").get<double>(), 0.05);
    EXPECT_NEAR(r1.at("t_end_s").get<double>(), r0.at("t_end_s").get<double>(), 0.05);
    EXPECT_NEAR(r1.at("raw_mps2").get<double>(), r0.at("corrected_mps2").get<double>(),
                0.1e-3 * imucal::kStandardGravity_mps2)
        << "rest " << p;
    EXPECT_EQ(r1.at("raw_mps2"), r1.at("corrected_mps2"));
  }
  for (size_t p = 0; p < after.at("moves").size(); ++p)
    EXPECT_NEAR(after["moves"][p].at("raw_rad").get<double>(),
                before["moves"][p].at("corrected_rad").get<double>(), 0.01 * imucal::kDegToRad)
        << "move " << p;
  EXPECT_NEAR(after["rms"].at("rest_raw_mps2").get<double>(),
              before["rms"].at("rest_corrected_mps2").get<double>(),
              0.05 * before["rms"].at("rest_corrected_mps2").get<double>());
  EXPECT_NEAR(after["rms"].at("move_raw_rad").get<double>(),
              before["rms"].at("move_corrected_rad").get<double>(),
              0.05 * before["rms"].at("move_corrected_rad").get<double>());
  // An existing --out is refused and left as it was.
  expect_refused("apply " + file("legacy.json") + " " + run(2) + " --out " + out,
                 "--out " + out + ": already exists");
  fs::remove_all(out);
}

TEST_F(CheckCli, BadInputIsOneLineNamingTheFileAndNothingIsWritten) {
  const std::string out = file("never");
  std::ofstream(file("neither.json")) << R"({"accel_bias": [0, 0, 0]})";
  std::ofstream(file("broken.json")) << "{\n  \"legacy\": \n";
  fs::create_directories(file("no-imu"));
  fs::copy_file(fs::path(run(2)) / "run.toml", fs::path(file("no-imu")) / "run.toml");
  for (const char* cmd : {"check", "apply"}) {
    const std::string tail = std::string(cmd) == "apply" ? " --out " + out : "";
    expect_refused(std::string(cmd) + " " + file("missing.json") + " " + run(2) + tail,
                   file("missing.json") + ": no such file");
    expect_refused(std::string(cmd) + " " + file("neither.json") + " " + run(2) + tail,
                   file("neither.json") + ": neither a parameter set");
    expect_refused(std::string(cmd) + " " + file("broken.json") + " " + run(2) + tail,
                   file("broken.json") + ":3: invalid JSON");
    expect_refused(std::string(cmd) + " " + run(1) + " " + run(2) + tail,
                   run(1) + ": a run archive holds no calibration result");
    expect_refused(std::string(cmd) + " " + file("legacy.json") + " " + file("no-imu") + tail,
                   file("no-imu") + "/imu.csv");
    expect_refused(
        std::string(cmd) + " " + file("legacy.json") + " " + run(2) + " --method nlsq" + tail,
        file("legacy.json") + ": no 'nlsq' result");
    EXPECT_FALSE(fs::exists(out));
  }
  // --json: the error is one JSON object on stdout too.
  const ProcImucalCheckCli j =
      run_imucal_check_cli("check " + file("missing.json") + " " + run(2) + " --json", false);
  EXPECT_EQ(j.code, 1);
  EXPECT_NE(nlohmann::json::parse(j.out).at("error").get<std::string>().find("no such file"),
            std::string::npos);
  fs::remove(file("neither.json"));
  fs::remove(file("broken.json"));
  fs::remove_all(file("no-imu"));
}

}  // namespace
