// "Never store a wrong calibration as good" (issue #10 item 3) through `imucal calibrate` on
// edited archives, as a QA engineer meets them: each corrupted run must end FAILED (exit 1) or
// REVIEW (exit 3) with the symptom named, never PASS. The README's table lists the same cases.
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "tests/support/imucal_cli.hpp"
#include "tests/support/temp_dir.hpp"

namespace {

namespace fs = std::filesystem;
using imucal::test_support::run_imucal;
using imucal::test_support::slurp;
using Row = std::vector<std::string>;

/// Rewrites the data rows of a CSV file (the header and comments kept) with `edit(row, index)`.
void edit_csv(const fs::path& file, const std::function<void(Row&, size_t)>& edit) {
  std::istringstream in(slurp(file));
  std::ostringstream out;
  std::string line;
  bool header = true;
  size_t i = 0;
  while (std::getline(in, line)) {
    if (line.empty() || line[0] == '#' || header) {
      header = header && (line.empty() || line[0] == '#');
      out << line << '\n';
      continue;
    }
    Row r;
    std::stringstream ls(line);
    for (std::string cell; std::getline(ls, cell, ',');) r.push_back(cell);
    edit(r, i++);
    for (size_t k = 0; k < r.size(); ++k) out << (k ? "," : "") << r[k];
    out << '\n';
  }
  std::ofstream(file) << out.str();
}

std::string num(double v) {
  std::ostringstream s;
  s.precision(17);
  s << v;
  return s.str();
}

struct Case {
  const char* name;
  const char* symptom;  ///< must appear in the output
  std::function<void(const fs::path&)> corrupt;
};

class CorruptCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new imucal::test_support::ScopedTempDir("corrupt-cli");
    const auto r = run_imucal("simulate --sequence short --seed 9 --out " + dir_->sub("clean"));
    ASSERT_EQ(r.code, 0) << r.out;
  }
  static void TearDownTestSuite() { delete dir_; }
  static imucal::test_support::ScopedTempDir* dir_;
};
imucal::test_support::ScopedTempDir* CorruptCli::dir_ = nullptr;

TEST_F(CorruptCli, TheCleanRunPasses) {
  const auto r = run_imucal("calibrate " + dir_->sub("clean"));
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("verdict: PASS"), std::string::npos);
}

TEST_F(CorruptCli, EveryCorruptionEndsFailedOrReviewNamingTheSymptom) {
  const std::vector<Case> cases = {
      {"stuck gyro axis", "stuck channel",
       [](const fs::path& d) { edit_csv(d / "imu.csv", [](Row& r, size_t) { r[2] = "0"; }); }},
      {"two swapped axes", "gyro vs gravity",
       [](const fs::path& d) {
         edit_csv(d / "imu.csv", [](Row& r, size_t) { std::swap(r[1], r[2]); });
       }},
      {"sign-flipped axis", "table vs IMU rotation",
       [](const fs::path& d) {
         edit_csv(d / "imu.csv", [](Row& r, size_t) { r[3] = num(-std::stod(r[3])); });
       }},
      {"table moved, IMU did not", "did not move with the table",
       [](const fs::path& d) {
         std::vector<Row> first;
         edit_csv(d / "imu.csv", [&](Row& r, size_t i) {
           if (i < 500) first.push_back(r);
           const Row& s = first[i % 500];
           for (int k = 1; k <= 6; ++k) r[static_cast<size_t>(k)] = s[static_cast<size_t>(k)];
         });
       }},
      {"wrong fixture orientation", "wrong fixture orientation",
       [](const fs::path& d) {
         edit_csv(d / "imu.csv", [](Row& r, size_t) {
           const std::string gx = r[1], ax = r[4];
           r[1] = r[2];
           r[2] = num(-std::stod(gx));
           r[4] = r[5];
           r[5] = num(-std::stod(ax));
         });
       }},
      {"saturated samples", "saturation",
       [](const fs::path& d) {
         const double lim = 5.0 * M_PI / 180.0 * 0.01;  // ±5 deg/s
         edit_csv(d / "imu.csv", [&](Row& r, size_t) {
           for (int k = 1; k <= 3; ++k) {
             const double v = std::stod(r[static_cast<size_t>(k)]);
             r[static_cast<size_t>(k)] = num(std::max(-lim, std::min(lim, v)));
           }
         });
       }},
      {"clock jump in the IMU stream", "clock jump",
       [](const fs::path& d) {
         for (const char* f : {"imu.csv", "table.csv"})
           edit_csv(d / f, [](Row& r, size_t i) {
             if (i >= 20000) r[0] = num(std::stod(r[0]) + 5.0);
           });
       }},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const fs::path d = dir_->sub(std::string("case-") + std::to_string(&c - cases.data()));
    fs::copy(dir_->sub("clean"), d);
    c.corrupt(d);
    const auto r = run_imucal("calibrate " + d.string());
    EXPECT_TRUE(r.code == 1 || r.code == 3) << r.out;
    EXPECT_EQ(r.out.find("verdict: PASS"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find(c.symptom), std::string::npos) << r.out;
    EXPECT_EQ(r.out.find("not observable with this sequence"), std::string::npos)
        << "broken data blamed on the sequence:\n"
        << r.out;
  }
}

}  // namespace
