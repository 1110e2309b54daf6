// `imucal calibrate` on a unit far outside its datasheet, as a QA engineer would run it: every
// method alone and both together must end REVIEW (exit 3) naming the term, never exit 0 with
// absurd numbers. The unit file is the far-from-nominal test unit with one gyro scale factor made
// 2 % — ten times the envelope a healthy unit lies in.
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <regex>
#include <string>

#include "tests/support/imucal_cli.hpp"
#include "tests/support/temp_dir.hpp"

namespace {

using imucal::test_support::run_imucal;
using imucal::test_support::slurp;

class LimitsCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new imucal::test_support::ScopedTempDir("limits-cli");
    std::string unit = slurp(std::string(IMUCAL_SOURCE_DIR) + "/db/archive/units/far.toml");
    // gyro M_ppm's first entry -2000 → 20000 (a 2 % scale factor on gyro x).
    const auto at = unit.find("[gyro]");
    ASSERT_NE(at, std::string::npos);
    const auto entry = unit.find("[[-2000.0", at);
    ASSERT_NE(entry, std::string::npos);
    unit.replace(entry, 9, "[[20000.0");
    std::ofstream(dir_->sub("broken.toml")) << unit;
    const auto r = run_imucal("simulate --sequence short --seed 5 --unit " +
                              dir_->sub("broken.toml") + " --out " + dir_->sub("run"));
    ASSERT_EQ(r.code, 0) << r.out;
  }
  static void TearDownTestSuite() { delete dir_; }
  static imucal::test_support::ScopedTempDir* dir_;
};
imucal::test_support::ScopedTempDir* LimitsCli::dir_ = nullptr;

TEST_F(LimitsCli, EachMethodAloneEndsReviewNamingTheTerm) {
  for (const char* method : {"ains", "nlsq", "legacy"}) {
    const auto r = run_imucal("calibrate " + dir_->sub("run") + " --method " + method);
    EXPECT_EQ(r.code, 3) << method << "\n" << r.out;
    // Either the estimate is outside the envelope or the estimator gave up — both named.
    EXPECT_TRUE(std::regex_search(r.out, std::regex("gyro_M\\[0\\]\\[0\\] = [0-9]+ ppm outside|"
                                                    "did not converge")))
        << method << "\n"
        << r.out;
    EXPECT_NE(r.out.find("verdict: REVIEW"), std::string::npos) << method;
  }
}

TEST_F(LimitsCli, BothMethodsAndJsonSayReview) {
  const auto r = run_imucal("calibrate " + dir_->sub("run") + " --json", false);
  EXPECT_EQ(r.code, 3) << r.out;
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_EQ(j["verdict"], "REVIEW");
  EXPECT_FALSE(j["limits"]["pass"].get<bool>());
  ASSERT_FALSE(j["limits"]["failures"].empty());
  EXPECT_FALSE(j["limits"]["failures"][0]["detail"].get<std::string>().empty());
}

TEST_F(LimitsCli, TheFarFromNominalTestUnitStillPasses) {
  const auto s =
      run_imucal("simulate --sequence short --seed 5 --unit " + std::string(IMUCAL_SOURCE_DIR) +
                 "/db/archive/units/far.toml --out " + dir_->sub("far"));
  ASSERT_EQ(s.code, 0) << s.out;
  const auto r = run_imucal("calibrate " + dir_->sub("far") + " --method ains");
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("limits: all hold"), std::string::npos) << r.out;
}

}  // namespace
