// `imucal diagnose DIR --report OUTDIR` as a person sees it: the real binary writes the page, and
// Debian's Chromium (headless) renders it. The DOM must hold the pictures (the heat map, the NIS
// chart, the score chart, the held-out comparison) and the candidate table with the withheld effect
// ranked first; the screenshot must not be blank. Bad --report targets are refused, nothing
// written.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>

#include "tests/support/run_command.hpp"
#include "tests/support/temp_dir.hpp"

namespace fs = std::filesystem;

namespace {

using Proc = imucal::test_support::CommandResult;

Proc run(const std::string& cmd) { return imucal::test_support::run_command(cmd + " 2>&1"); }

std::string imucal_bin() { return std::string(IMUCAL_BIN_DIR) + "/imucal"; }

std::string slurp(const fs::path& p) {
  std::ifstream f(p, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

/// Width and height from a PNG's IHDR chunk (bytes 16..23, big-endian).
std::pair<int, int> png_size(const std::string& png) {
  if (png.size() < 24 || png.compare(1, 3, "PNG") != 0) return {0, 0};
  auto be = [&](size_t o) {
    return (static_cast<unsigned char>(png[o]) << 24) |
           (static_cast<unsigned char>(png[o + 1]) << 16) |
           (static_cast<unsigned char>(png[o + 2]) << 8) | static_cast<unsigned char>(png[o + 3]);
  };
  return {static_cast<int>(be(16)), static_cast<int>(be(20))};
}

}  // namespace

TEST(DiagnosisReport, ChromiumRendersTheReportWithItsPictures) {
  ASSERT_EQ(run("command -v chromium").code, 0)
      << "Debian's chromium is not installed (tools/setup.sh installs it)";
  const imucal::test_support::ScopedTempDir tmp("report");
  const fs::path dir = fs::path(tmp.path()) / "run", out = fs::path(tmp.path()) / "report";
  // A withheld gyro g-sensitivity, ~3.5x the short sequence's detection threshold.
  ASSERT_EQ(run(imucal_bin() + " simulate --sequence short --seed 9 --out " + dir.string() +
                " --effect gyro_g_sensitivity=4.9e-8,0,0,0,-4.9e-8,0,0,0,4e-8")
                .code,
            0);
  const Proc d = run(imucal_bin() + " diagnose " + dir.string() + " --report " + out.string());
  ASSERT_TRUE(d.code == 0 || d.code == 3) << d.out;
  ASSERT_TRUE(fs::exists(out / "report.html"));
  const nlohmann::json j = nlohmann::json::parse(slurp(out / "diagnosis.json"));
  for (const char* k : {"verdict", "best", "candidates", "held_out", "segments", "serial"})
    EXPECT_TRUE(j.contains(k)) << k;

  const std::string chrome =
      "timeout 90 chromium --headless --no-sandbox --disable-gpu --hide-scrollbars ";
  const std::string url = "file://" + (out / "report.html").string();
  const Proc dom = run(chrome + "--dump-dom " + url);
  ASSERT_EQ(dom.code, 0) << dom.out.substr(0, 2000);
  for (const char* id : {"heatmap", "nis", "scores", "heldout", "candidates"})
    EXPECT_NE(dom.out.find(std::string("id=\"") + id + "\""), std::string::npos) << id;
  // The heat map has a cell per segment and sensor axis.
  const std::regex cell("<rect[^>]*fill=\"#[0-9a-f]{6}\"><title>");
  const size_t cells = static_cast<size_t>(std::distance(
      std::sregex_iterator(dom.out.begin(), dom.out.end(), cell), std::sregex_iterator()));
  EXPECT_GE(cells, 6 * j["segments"].size());
  // The withheld effect heads the ranking table.
  const size_t table = dom.out.find("id=\"candidates\"");
  ASSERT_NE(table, std::string::npos);
  EXPECT_LT(dom.out.find("gyro_g_sensitivity", table), dom.out.find("accel_quadratic_k2", table));

  const fs::path shot = out / "shot.png";
  const Proc s = run(chrome + "--window-size=1300,2400 --screenshot=" + shot.string() + " " + url);
  ASSERT_EQ(s.code, 0) << s.out.substr(0, 2000);
  const std::string png = slurp(shot);
  EXPECT_EQ(png_size(png), (std::pair<int, int>{1300, 2400}));
  // A blank page compresses to a few kB; the rendered report with its charts is far larger.
  EXPECT_GT(png.size(), 60000u);
}

TEST(DiagnosisReport, ABadReportTargetIsRefusedAndNothingIsWritten) {
  const imucal::test_support::ScopedTempDir tmp("report-bad");
  const fs::path dir = fs::path(tmp.path()) / "run", file = fs::path(tmp.path()) / "taken";
  ASSERT_EQ(run(imucal_bin() + " simulate --sequence short --seed 2 --out " + dir.string()).code,
            0);
  std::ofstream(file) << "x";
  const Proc p = run(imucal_bin() + " diagnose " + dir.string() + " --report " + file.string());
  EXPECT_EQ(p.code, 1);
  EXPECT_NE(p.out.find("not a directory"), std::string::npos) << p.out;
  EXPECT_EQ(slurp(file), "x");
  // A diagnosis that fails (unknown candidate) creates no report directory.
  const fs::path out = fs::path(tmp.path()) / "never";
  EXPECT_EQ(run(imucal_bin() + " diagnose " + dir.string() + " --candidates nope --report " +
                out.string())
                .code,
            1);
  EXPECT_FALSE(fs::exists(out));
}
