// `imucal gap-budget --against paper` (issue #26) as a user runs it: the budget as one JSON object
// with every source's size, interval, prior, shares and where to fix it, the simulated means
// beside the paper's, a progress line on stderr; an unknown source or target refused by name.
// The budget's last step checks the fitted model on new seeds, 16 units by default: ctest asks
// for 2 (--check-units; the test reads that the check ran and reported, not its figure), and the
// progress test for one unit everywhere (it reads stderr). Under IMUCAL_WHOLE_COUNTS=1 both run
// at the command's defaults.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "calib/effects/catalogue.hpp"
#include "db/archive/unit_file.hpp"
#include "tests/support/ci_count.hpp"
#include "tests/support/imucal_cli.hpp"
#include "tests/support/temp_dir.hpp"

namespace imucal {
namespace {

using test_support::run_imucal;

/// The options that make the CI count cheaper (empty at the whole count).
std::string ci_only(const std::string& options) {
  return test_support::whole_counts() ? "" : " " + options;
}

TEST(GapBudgetCli, PrintsTheBudgetWithEverySourcesSizeShareAndWhereToFixIt) {
  const auto r = run_imucal(
      "gap-budget --units 2 --sequence short --replicates 2 "
      "--candidates accel_quadratic_k2,fixture_heading --json" +
          ci_only("--check-units 2"),
      false);
  ASSERT_EQ(r.code, 0) << r.out;
  const auto j = nlohmann::json::parse(r.out);
  ASSERT_EQ(j["entries"].size(), 2u);
  for (const auto& e : j["entries"]) {
    for (const char* key :
         {"size", "size_lo", "size_hi", "prior", "prior_source", "share_add_one",
          "share_leave_one_out", "share_leave_one_out_sd", "calibration_shift_sigma", "measurable"})
      EXPECT_TRUE(e.contains(key)) << key;
    EXPECT_LE(e["size_lo"].get<double>(), e["size"].get<double>());
    EXPECT_GE(e["size_hi"].get<double>(), e["size"].get<double>());
    EXPECT_GE(e["size"].get<double>(), e["prior"][0].get<double>());
    EXPECT_LE(e["size"].get<double>(), e["prior"][1].get<double>());
  }
  // K2 raises the acceleration metric; a constant fixture heading moves no metric (§VII's γ_np).
  EXPECT_EQ(j["entries"][0]["name"], "accel_quadratic_k2");
  EXPECT_TRUE(j["entries"][0]["measurable"].get<bool>());
  EXPECT_FALSE(j["entries"][1]["measurable"].get<bool>());
  EXPECT_EQ(j["entries"][1]["share_add_one"].get<double>(), 0.0);
  for (const char* column :
       {"factory AINS", "factory NLSQ", "factory legacy", "land AINS", "sea AINS"}) {
    const auto& c = j["columns"][column];
    EXPECT_GT(c["accel_rmse_ug"]["paper_mean"].get<double>(), 20.0) << column;
    EXPECT_GT(c["accel_rmse_ug"]["simulated_mean"].get<double>(), 0.0) << column;
    EXPECT_GT(c["orientation_rmse_mdeg"]["baseline_rms"].get<double>(), 0.0) << column;
  }
  // baseline, two probes, the whole model and K2's slope, two share runs, two replicates and
  // the two checks
  EXPECT_GE(j["simulations"].get<int>(), 11);
  EXPECT_TRUE(j.contains("converged"));
  EXPECT_TRUE(j.contains("top_removal_share_new_seeds"));
}

TEST(GapBudgetCli, AnUnknownSourceOrTargetIsRefusedByName) {
  const auto bad = run_imucal("gap-budget --units 1 --candidates accel_quadratic_k2,bogus");
  EXPECT_EQ(bad.code, 1) << bad.out;
  EXPECT_NE(bad.out.find("unknown candidate 'bogus'"), std::string::npos) << bad.out;
  EXPECT_NE(bad.out.find("fixture_heading"), std::string::npos) << "lists the known ones";
  const auto target = run_imucal("gap-budget --against nature");
  EXPECT_EQ(target.code, 2) << target.out;
  EXPECT_NE(target.out.find("nature"), std::string::npos) << target.out;
}

// --model: no fit, one model simulated and set beside the paper, per IMU and in the means.
TEST(GapBudgetCli, SimulatesAGivenModelPerImuBesideThePaper) {
  const auto ideal = run_imucal(
      "gap-budget --units 2 --sequence short --model accel_quadratic_k2=0 --json", false);
  const auto k2 = run_imucal(
      "gap-budget --units 2 --sequence short --model accel_quadratic_k2=5 --json", false);
  ASSERT_EQ(ideal.code, 0) << ideal.out;
  ASSERT_EQ(k2.code, 0) << k2.out;
  const auto a = nlohmann::json::parse(ideal.out), b = nlohmann::json::parse(k2.out);
  ASSERT_EQ(b["units"].size(), 2u);
  EXPECT_EQ(b["model"]["accel_quadratic_k2"].get<double>(), 5.0);
  const auto& m = b["means"]["factory AINS"];
  EXPECT_NEAR(m["paper_accel_rmse_ug"].get<double>(), 27.6689, 1e-9);
  // The same units with K2 at five times its typical size: the acceleration metric grows.
  EXPECT_GT(m["accel_rmse_ug"].get<double>(),
            1.5 * a["means"]["factory AINS"]["accel_rmse_ug"].get<double>());
  const double u1 = b["units"][0]["factory AINS"]["accel_rmse_ug"].get<double>();
  const double u2 = b["units"][1]["factory AINS"]["accel_rmse_ug"].get<double>();
  EXPECT_NEAR(m["accel_rmse_ug"].get<double>(), (u1 + u2) / 2.0, 1e-9);
}

// Each simulated mean beside how well the paper's own six IMUs fix it (issue #26): the legacy
// acceleration's mean is IMU 3's event, so the 25 % bar is one the paper's own IMUs do not hold
// there; every other column's they do. Ideal units on `short` miss every mean by far, so both
// kinds of miss are printed.
TEST(GapBudgetCli, SaysWhereThePapersOwnImusDoNotHoldTheBar) {
  const auto json = run_imucal(
      "gap-budget --units 2 --sequence short --model accel_quadratic_k2=0 --json", false);
  ASSERT_EQ(json.code, 0) << json.out;
  const auto j = nlohmann::json::parse(json.out);
  const auto& legacy = j["means"]["factory legacy"]["accel_against_paper"];
  EXPECT_FALSE(legacy["bar_held_by_papers_own_imus"].get<bool>());
  EXPECT_EQ(legacy["paper_most_influential_imu"].get<int>(), 3);
  EXPECT_NEAR(legacy["paper_mean_without_it"].get<double>(), 29.11, 0.01);
  EXPECT_GT(legacy["simulated_mean_standard_error"].get<double>(), 0.0);
  EXPECT_LT(legacy["distance_in_standard_errors"].get<double>(), 0.0) << "ideal units lie below";
  for (const char* column : {"factory AINS", "factory NLSQ", "land AINS", "sea AINS"})
    EXPECT_TRUE(
        j["means"][column]["accel_against_paper"]["bar_held_by_papers_own_imus"].get<bool>())
        << column;
  EXPECT_TRUE(
      j["means"]["factory legacy"]["orientation_against_paper"]["bar_held_by_papers_own_imus"]
          .get<bool>());

  const auto text =
      run_imucal("gap-budget --units 2 --sequence short --model accel_quadratic_k2=0", false);
  ASSERT_EQ(text.code, 0) << text.out;
  EXPECT_NE(text.out.find("factory legacy acceleration: "), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("do not hold that bar: without IMU 3 its mean is 29.11"),
            std::string::npos)
      << text.out;
  EXPECT_NE(text.out.find("factory AINS acceleration: "), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("outside a bar its own IMUs hold"), std::string::npos) << text.out;
}

TEST(GapBudgetCli, ABadModelIsRefusedNamingTheItem) {
  for (const auto& [model, says] : std::vector<std::pair<std::string, std::string>>{
           {"accel_quadratic_k2=9", "outside its prior range"},
           {"accel_quadratic_k2", "is not NAME=SIZE"},
           {"accel_quadratic_k2=abc", "is not a number"},
           {"bogus=1", "unknown candidate 'bogus'"}}) {
    const auto r = run_imucal("gap-budget --units 1 --model " + model);
    EXPECT_EQ(r.code, 1) << model << ": " << r.out;
    EXPECT_NE(r.out.find(says), std::string::npos) << model << ": " << r.out;
  }
}

/// An output file that cannot be written: exit 1 naming it, nothing left behind.
void expect_unwritable_refused(const std::string& option, const std::string& missing) {
  const auto bad = run_imucal("gap-budget --units 1 --sequence short --model gyro_accel_skew=1 " +
                              option + " " + missing);
  EXPECT_EQ(bad.code, 1) << option << ": " << bad.out;
  EXPECT_NE(bad.out.find(missing), std::string::npos) << option << ": " << bad.out;
  EXPECT_FALSE(std::filesystem::exists(missing)) << option;
}

// --write-unit (issue #26 item 3): the model as a unit file that the simulators read back, every
// effect at the size of a 1σ draw with the catalogue's signs; what a unit cannot hold is named in
// its head. A file that cannot be written is refused and nothing is left behind.
TEST(GapBudgetCli, WritesTheModelAsAUnitFileThatReadsBack) {
  test_support::ScopedTempDir dir("gap_budget_cli_test");
  const std::string path = dir.path() + "/paper-like.toml";
  const auto r = run_imucal(
      "gap-budget --units 1 --sequence short --model "
      "gyro_accel_skew=5,table_wobble=2,evaluation_heading_reopen=3 --write-unit " +
      path);
  ASSERT_EQ(r.code, 0) << r.out;
  const calib::effects::UnitModel u = db::archive::read_unit_file(path);
  EXPECT_NEAR(u.effects.gyro_accel_skew_s, 5.0 * 0.5e-3, 1e-12);  // 5x the typical 0.5 ms
  const calib::effects::EffectInfo& wobble =
      calib::effects::effect_info(calib::effects::EffectId::kTableWobble);
  EXPECT_NEAR(u.effects.table_wobble_rad(0), 2.0 * wobble.typical[0], 1e-15);
  EXPECT_NEAR(u.effects.table_wobble_rad(1), 2.0 * wobble.typical[1], 1e-15);
  EXPECT_TRUE(u.effects.thermal_accel_mps2.isZero());  // no warm-up in this model
  std::ifstream in(path);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("--model gyro_accel_skew=5,table_wobble=2,evaluation_heading_reopen=3"),
            std::string::npos)
      << text;
  EXPECT_NE(text.find("#   evaluation_heading_reopen=3 mdeg"), std::string::npos) << text;

  expect_unwritable_refused("--write-unit", dir.path() + "/no/such/dir/unit.toml");
}

// --plot: the per-IMU picture, one dot per unit and column, the paper's six IMUs beside them, both
// metrics; a file that cannot be written is refused naming it.
TEST(GapBudgetCli, PlotsThePapersImusBesideTheSimulatedUnits) {
  test_support::ScopedTempDir dir("gap_budget_cli_test");
  const std::string svg = dir.path() + "/units.svg";
  const auto r =
      run_imucal("gap-budget --units 3 --sequence short --model gyro_accel_skew=2 --plot " + svg);
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream in(svg);
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  ASSERT_EQ(text.rfind("<svg", 0), 0u) << text.substr(0, 200);
  EXPECT_NE(text.find("</svg>"), std::string::npos);
  const auto count = [&](const std::string& what) {
    size_t n = 0;
    for (size_t at = text.find(what); at != std::string::npos; at = text.find(what, at + 1)) ++n;
    return n;
  };
  EXPECT_EQ(count("class='paper'"), 2u * 5u * 6u);  // two metrics, five columns, six IMUs
  EXPECT_EQ(count("class='model'"), 2u * 5u * 3u);
  // The paper's own values are on it (IMU 3's legacy acceleration, Table III).
  EXPECT_NE(text.find("factory legacy, paper IMU 3: 89.65"), std::string::npos);

  expect_unwritable_refused("--plot", dir.path() + "/no/such/dir/units.svg");
}

TEST(GapBudgetCli, ShowsItsProgressOnStderr) {
  // stderr alone (the JSON-free report goes to /dev/null).
  const auto r = test_support::run_command(
      std::string(IMUCAL_BIN_DIR) +
      "/imucal gap-budget --units 1 --sequence short --replicates 0 --candidates fixture_heading" +
      ci_only("--probe-units 1 --search-units 1 --check-units 1") + " 2>&1 >/dev/null");
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("gap-budget: 1/"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("simulations"), std::string::npos) << r.out;
}

}  // namespace
}  // namespace imucal
