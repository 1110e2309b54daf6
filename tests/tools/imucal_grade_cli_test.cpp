// `imucal simulate --grade G --sequence hand` (issue #21): a hand-placed MEMS run drawn from the
// grade's envelope, written with its [prior]; the real `imucal calibrate` finds its rests without
// a calibration and the legacy method recovers the unit from scratch (against truth.json, in the
// method's own frame). Bad input: `--sequence hand` on a table, an unknown grade — one line naming
// it, non-zero exit, nothing written.
#include <gtest/gtest.h>

#include <filesystem>
#include <nlohmann/json.hpp>

#include "calib/core/body_frame.hpp"
#include "calib/core/conventions.hpp"
#include "db/archive/run_archive.hpp"
#include "tests/support/imucal_cli.hpp"
#include "tests/support/temp_dir.hpp"

namespace imucal {
namespace {

namespace fs = std::filesystem;
using test_support::run_imucal;

calib::ParamSet params_of(const nlohmann::json& p) {
  calib::ParamSet s;
  for (int i = 0; i < 3; ++i) {
    s.accel_bias_mps2(i) = p.at("accel_bias_mps2").at(i).get<double>();
    s.gyro_bias_radps(i) = p.at("gyro_bias_radps").at(i).get<double>();
    for (int j = 0; j < 3; ++j) {
      s.accel_M(i, j) = p.at("accel_M").at(i).at(j).get<double>();
      s.gyro_M(i, j) = p.at("gyro_M").at(i).at(j).get<double>();
    }
  }
  return s;
}

TEST(ImucalGradeCli, AHandPlacedMemsRunIsCalibratedFromScratch) {
  test_support::ScopedTempDir tmp("imucal-grade");
  const std::string dir = tmp.path() + "/mems";
  const auto sim =
      run_imucal("simulate --sequence hand --setting land --grade mems --seed 4 --out " + dir);
  ASSERT_EQ(sim.code, 0) << sim.out;
  const archive::RunArchive a = archive::read_archive(dir);
  EXPECT_EQ(a.info.grade, calib::Grade::kMems);
  ASSERT_TRUE(a.truth.has_value());
  const calib::ParamSet truth = a.truth->params;
  // The unit is far from nominal: offsets of several °/s.
  EXPECT_GT(truth.gyro_bias_radps.cwiseAbs().minCoeff(), 2.0 * kDegToRad);
  const auto cal = run_imucal("calibrate " + dir + " --method legacy --json", false);
  ASSERT_EQ(cal.code, 0) << cal.out;
  const nlohmann::json j = nlohmann::json::parse(cal.out);
  EXPECT_EQ(j.at("verdict"), "PASS") << j.at("limits").dump();
  const calib::ParamSet est = params_of(j.at("legacy").at("params"));
  const calib::ParamSet ref = calib::to_accel_symmetric_frame(truth).params;
  EXPECT_LT((est.accel_bias_mps2 - ref.accel_bias_mps2).cwiseAbs().maxCoeff(),
            1e-3 * kStandardGravity_mps2);
  EXPECT_LT((est.accel_M - ref.accel_M).cwiseAbs().maxCoeff(), 1000e-6);
  EXPECT_LT((est.gyro_bias_radps - ref.gyro_bias_radps).cwiseAbs().maxCoeff(), 0.02 * kDegToRad);
  EXPECT_LT((est.gyro_M - ref.gyro_M).cwiseAbs().maxCoeff(), 2000e-6);
}

TEST(ImucalGradeCli, HandOnATableAndAnUnknownGradeAreRefusedWritingNothing) {
  test_support::ScopedTempDir tmp("imucal-grade-bad");
  const std::string dir = tmp.path() + "/out";
  const auto table = run_imucal("simulate --sequence hand --out " + dir);
  EXPECT_NE(table.code, 0);
  EXPECT_NE(table.out.find("--sequence hand"), std::string::npos) << table.out;
  EXPECT_FALSE(fs::exists(dir));
  const auto grade = run_imucal("simulate --sequence short --grade consumer --out " + dir);
  EXPECT_NE(grade.code, 0);
  EXPECT_NE(grade.out.find("--grade"), std::string::npos) << grade.out;
  EXPECT_FALSE(fs::exists(dir));
}

}  // namespace
}  // namespace imucal
