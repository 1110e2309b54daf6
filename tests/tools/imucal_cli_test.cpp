// End-to-end tests of build/bin/imucal as a user runs it: real files, real process, exit codes and
// the one-line errors that name the file and line/field.
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <sstream>
#include <string>

#include "calib/core/rotation.hpp"

namespace fs = std::filesystem;

namespace {

struct ProcResult {
  int code;
  std::string out;  ///< stdout + stderr
};

ProcResult run_shell(const std::string& cmd) {
  FILE* p = popen(cmd.c_str(), "r");
  std::string out;
  char buf[4096];
  size_t n;
  while ((n = fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
  const int st = pclose(p);
  return {WIFEXITED(st) ? WEXITSTATUS(st) : -1, out};
}

ProcResult run_imucal_cli(const std::string& args) {
  return run_shell(std::string(IMUCAL_BIN_DIR) + "/imucal " + args + " 2>&1");
}

std::string slurp_imucal_cli(const fs::path& p) {
  std::ifstream f(p);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

void spit(const fs::path& p, const std::string& s) { std::ofstream(p) << s; }

class ImucalCli : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    base_ = fs::temp_directory_path() / ("imucal_cli_" + std::to_string(getpid()));
    fs::create_directories(base_);
    const ProcResult r =
        run_imucal_cli("simulate --sequence short --seed 3 --out " + (base_ / "sim").string());
    ASSERT_EQ(r.code, 0) << r.out;
  }
  static void TearDownTestSuite() { fs::remove_all(base_); }

  /// A copy of the simulated archive with one file replaced by `edit(text)`.
  fs::path variant(const std::string& name, const std::string& file,
                   const std::function<std::string(std::string)>& edit) {
    const fs::path d = base_ / name;
    fs::remove_all(d);
    fs::copy(base_ / "sim", d);
    spit(d / file, edit(slurp_imucal_cli(d / file)));
    return d;
  }

  static fs::path base_;
};
fs::path ImucalCli::base_;

/// Replace the n-th line (1-based) of a text.
std::string replace_line(const std::string& text, int n, const std::string& line) {
  std::stringstream in(text), out;
  std::string l;
  for (int i = 1; std::getline(in, l); ++i) out << (i == n ? line : l) << '\n';
  return out.str();
}

std::string line_of(const std::string& text, int n) {
  std::stringstream in(text);
  std::string l;
  for (int i = 1; std::getline(in, l); ++i)
    if (i == n) return l;
  return "";
}

}  // namespace

TEST_F(ImucalCli, CalibrateJsonHasTheDocumentedShapeAndPasses) {
  const ProcResult r =
      run_imucal_cli("calibrate " + (base_ / "sim").string() + " --method all --json");
  ASSERT_EQ(r.code, 0) << r.out;
  const auto j = nlohmann::json::parse(r.out);
  for (const char* m : {"ains", "nlsq"}) {
    ASSERT_TRUE(j.contains(m));
    EXPECT_TRUE(j[m]["params"].contains("accel_M"));
    EXPECT_TRUE(j[m]["sigma"].contains("gyro_bias_radps"));
    EXPECT_GT(j[m]["metrics"]["orientation_rmse_mdeg"].get<double>(), 0.0);
    EXPECT_GT(j[m]["metrics"]["accel_rmse_ug"].get<double>(), 0.0);
    EXPECT_GT(j[m]["runtime_s"].get<double>(), 0.0);
  }
  EXPECT_EQ(j["crosscheck"]["verdict"], "PASS");
  EXPECT_TRUE(j["crosscheck"]["failures"].empty());
  EXPECT_FALSE(j.contains("holding")) << "the factory: AINS and NLSQ, no method holds alone";
}

TEST_F(ImucalCli, HumanOutputCarriesUnitsAndVerdict) {
  const ProcResult r = run_imucal_cli("calibrate " + (base_ / "sim").string());
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("µg"), std::string::npos);
  EXPECT_NE(r.out.find("deg/h"), std::string::npos);
  EXPECT_NE(r.out.find("cross-check: PASS"), std::string::npos);
}

TEST_F(ImucalCli, HandMadeAttitudeArchiveCalibratesLikeTheSimulatedOne) {
  // Data from elsewhere: build attitude.csv (roll/pitch/yaw of the table attitude) and a run.toml
  // by hand, no truth.json, and compare with the table.csv archive.
  const fs::path d = base_ / "handmade";
  fs::remove_all(d);
  fs::create_directories(d);
  fs::copy_file(base_ / "sim" / "imu.csv", d / "imu.csv");
  std::stringstream tab(slurp_imucal_cli(base_ / "sim" / "table.csv"));
  std::ofstream att(d / "attitude.csv");
  att << "t_s,roll_deg,pitch_deg,yaw_deg,at_rest\n";
  std::string l;
  std::getline(tab, l);
  att.precision(17);
  while (std::getline(tab, l)) {
    double t, outer, inner;
    int rest;
    ASSERT_EQ(std::sscanf(l.c_str(), "%lf,%lf,%lf,%d", &t, &outer, &inner, &rest), 4) << l;
    // Default geometry: outer about north (x), inner about the platform normal (z).
    const Eigen::Matrix3d C =
        imucal::calib::core::axis_angle(Eigen::Vector3d::UnitX(), outer * M_PI / 180) *
        imucal::calib::core::axis_angle(Eigen::Vector3d::UnitZ(), inner * M_PI / 180);
    const Eigen::Vector3d e = imucal::calib::core::C_bn_to_euler(C) * 180.0 / M_PI;
    att << t << ',' << e(0) << ',' << e(1) << ',' << e(2) << ',' << rest << '\n';
  }
  att.close();
  std::string toml = slurp_imucal_cli(base_ / "sim" / "run.toml");
  const auto pos = toml.find("reference = \"table\"");
  ASSERT_NE(pos, std::string::npos) << toml;
  toml.replace(pos, 19, "reference = \"attitude\"");
  spit(d / "run.toml", toml);

  const ProcResult a =
      run_imucal_cli("calibrate " + (base_ / "sim").string() + " --method nlsq --json");
  const ProcResult b = run_imucal_cli("calibrate " + d.string() + " --method nlsq --json");
  ASSERT_EQ(a.code, 0) << a.out;
  ASSERT_EQ(b.code, 0) << b.out;
  const auto ja = nlohmann::json::parse(a.out)["nlsq"], jb = nlohmann::json::parse(b.out)["nlsq"];
  for (const char* key : {"accel_bias_mps2", "gyro_bias_radps", "table_misalignment_rad"})
    for (int i = 0; i < 3; ++i) {
      const double sa = ja["sigma"][key][i].get<double>();
      EXPECT_NEAR(ja["params"][key][i].get<double>(), jb["params"][key][i].get<double>(), 0.05 * sa)
          << key << "[" << i << "]";
    }
}

TEST_F(ImucalCli, BadInputGivesOneLineErrorNamingFileAndLine) {
  struct Case {
    std::string name, file;
    std::function<std::string(std::string)> edit;
    std::string expect;  ///< substring of the error
  };
  const std::vector<Case> cases = {
      {"missing_col", "imu.csv",
       [](std::string s) {
         const std::string l = line_of(s, 50);
         return replace_line(s, 50, l.substr(0, l.rfind(',')));
       },
       "imu.csv:50"},
      {"extra_col", "imu.csv",
       [](std::string s) { return replace_line(s, 60, line_of(s, 60) + ",1.0"); }, "imu.csv:60"},
      {"nan", "imu.csv",
       [](std::string s) {
         std::string l = line_of(s, 70);
         l.replace(l.find(',') + 1, l.find(',', l.find(',') + 1) - l.find(',') - 1, "nan");
         return replace_line(s, 70, l);
       },
       "imu.csv:70"},
      {"inf", "table.csv",
       [](std::string s) {
         std::string l = line_of(s, 80);
         return replace_line(
             s, 80, l.substr(0, l.find(',')) + ",inf" + l.substr(l.find(',', l.find(',') + 1)));
       },
       "table.csv:80"},
      {"time_backwards", "imu.csv",
       [](std::string s) { return replace_line(s, 90, line_of(s, 40)); }, "imu.csv:90"},
      {"truncated", "imu.csv", [](std::string s) { return s.substr(0, s.size() / 2); }, "imu.csv"},
      {"no_rest", "table.csv",
       [](std::string s) {
         std::stringstream in(s), out;
         std::string l;
         std::getline(in, l);
         out << l << '\n';
         while (std::getline(in, l)) out << l.substr(0, l.rfind(',')) << ",0\n";
         return out.str();
       },
       "rest"},
      {"bad_toml_key", "run.toml", [](std::string s) { return s + "\nbogus_key = 1\n"; },
       "run.toml"},
  };
  for (const auto& c : cases) {
    const fs::path d = variant(c.name, c.file, c.edit);
    const ProcResult r = run_imucal_cli("calibrate " + d.string() + " --method nlsq");
    EXPECT_EQ(r.code, 1) << c.name << ": " << r.out;
    EXPECT_NE(r.out.find("imucal: error: "), std::string::npos) << c.name << ": " << r.out;
    EXPECT_NE(r.out.find(c.expect), std::string::npos) << c.name << ": " << r.out;
    EXPECT_EQ(std::count(r.out.begin(), r.out.end(), '\n'), 1) << c.name << ": " << r.out;
  }
}

TEST_F(ImucalCli, BadSequencesAreRejectedNamingTheProblem) {
  const fs::path seq = base_ / "too_fast.toml";
  spit(
      seq,
      "name = \"too-fast\"\n[start]\nrest_s = 30.0\n\n[[step]]\nrotate = \"inner\"\nby_deg = 90.0\n"
      "rate_dps = 500.0\n\n[[step]]\nrest_s = 30.0\n");
  ProcResult r =
      run_imucal_cli("simulate --sequence " + seq.string() + " --out " + (base_ / "x").string());
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("too_fast.toml:"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(base_ / "x"));

  // Rank-deficient: only rotations about body z never tilt the unit.
  const fs::path flat = base_ / "flat.toml";
  spit(flat,
       "name = \"flat\"\n[start]\nrest_s = 30.0\n\n[[step]]\nrotate = \"inner\"\nby_deg = 90.0\n\n"
       "[[step]]\nrest_s = 30.0\n\n[[step]]\nrotate = \"inner\"\nby_deg = -180.0\n\n[[step]]\n"
       "rest_s = 30.0\n");
  r = run_imucal_cli("simulate --sequence " + flat.string() + " --out " + (base_ / "y").string());
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("unobservable"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("accel_M[2][2]"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(base_ / "y"));
  r = run_imucal_cli("crlb --sequence " + flat.string());
  EXPECT_EQ(r.code, 3) << r.out;

  r = run_imucal_cli("simulate --sequence no-such-sequence --out " + (base_ / "z").string());
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("factory-std"), std::string::npos)
      << "should list the available names: " << r.out;
  // Issue #19 item 9: a typo reads as one (was "imucal: error: shrot:0: no such sequence file or
  // library name; ...").
  r = run_imucal_cli("simulate --sequence shrot --out " + (base_ / "z").string());
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("imucal: error: unknown sequence 'shrot' (library "), std::string::npos)
      << r.out;
  EXPECT_EQ(r.out.find(":0:"), std::string::npos) << r.out;
}

// Issue #19 item 9: the refusal names the command's flag (was "pass overwrite=true"), before any
// simulation work; with the flag the archive is replaced.
TEST_F(ImucalCli, SimulateIntoAnExistingArchiveNamesTheOverwriteFlag) {
  const std::string dir = (base_ / "sim").string();
  const auto before = fs::last_write_time(base_ / "sim" / "imu.csv");
  ProcResult r = run_imucal_cli("simulate --sequence short --seed 4 --out " + dir);
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find(dir + ": exists and is not empty"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("--overwrite"), std::string::npos) << r.out;
  EXPECT_EQ(r.out.find("overwrite=true"), std::string::npos) << r.out;
  EXPECT_TRUE(fs::last_write_time(base_ / "sim" / "imu.csv") == before);
  const fs::path other = base_ / "replaced";
  r = run_imucal_cli("simulate --sequence short --seed 4 --out " + other.string());
  ASSERT_EQ(r.code, 0) << r.out;
  r = run_imucal_cli("simulate --sequence short --seed 5 --out " + other.string() + " --overwrite");
  EXPECT_EQ(r.code, 0) << r.out;
}

TEST_F(ImucalCli, EvaluateReproducesTheCalibrateMetricsAndRejectsBadParameterFiles) {
  const ProcResult c =
      run_imucal_cli("calibrate " + (base_ / "sim").string() + " --method ains --json");
  ASSERT_EQ(c.code, 0) << c.out;
  const auto cj = nlohmann::json::parse(c.out)["ains"];
  const fs::path params = base_ / "ains_params.json";
  spit(params, cj["params"].dump());
  const ProcResult e = run_imucal_cli("evaluate " + (base_ / "sim").string() + " --params " +
                                      params.string() + " --json");
  ASSERT_EQ(e.code, 0) << e.out;
  const auto ej = nlohmann::json::parse(e.out);
  EXPECT_DOUBLE_EQ(ej["accel_rmse_ug"].get<double>(), cj["metrics"]["accel_rmse_ug"].get<double>());
  EXPECT_DOUBLE_EQ(ej["orientation_rmse_mdeg"].get<double>(),
                   cj["metrics"]["orientation_rmse_mdeg"].get<double>());

  // A parameter file with a wrong shape names the field.
  auto bad = cj["params"];
  bad["accel_M"][1] = {1.0, 2.0};
  spit(params, bad.dump());
  const ProcResult b =
      run_imucal_cli("evaluate " + (base_ / "sim").string() + " --params " + params.string());
  EXPECT_EQ(b.code, 1) << b.out;
  EXPECT_NE(b.out.find("accel_M[1]"), std::string::npos) << b.out;
}

TEST_F(ImucalCli, CrlbReportsEveryParameterForTheShippedSequences) {
  for (const char* seq : {"short", "factory-std", "pos19"}) {
    const ProcResult r = run_imucal_cli(std::string("crlb --json --sequence ") + seq);
    ASSERT_EQ(r.code, 0) << seq << ": " << r.out;
    const auto j = nlohmann::json::parse(r.out);
    EXPECT_TRUE(j["unobservable"].empty()) << seq;
    for (const char* key : {"accel_bias_mps2", "gyro_bias_radps", "table_misalignment_rad"})
      for (int i = 0; i < 3; ++i) EXPECT_GT(j["sigma"][key][i].get<double>(), 0.0) << seq << key;
  }
}

TEST_F(ImucalCli, PlotWritesAnSvgWithEveryParameterAndEveryRestPeriod) {
  const fs::path svg = base_ / "run.svg";
  const ProcResult r =
      run_imucal_cli("calibrate " + (base_ / "sim").string() + " --json --plot " + svg.string());
  ASSERT_EQ(r.code, 0) << r.out;
  const std::string text = slurp_imucal_cli(svg);
  ASSERT_EQ(text.rfind("<svg", 0), 0u) << text.substr(0, 80);
  EXPECT_NE(text.find("cross-check PASS"), std::string::npos);
  const auto j = nlohmann::json::parse(r.out);
  // One tooltip per parameter in the cross-check panel, one per method and rest period below.
  auto count = [&](const std::string& needle) {
    size_t n = 0;
    for (size_t p = text.find(needle); p != std::string::npos; p = text.find(needle, p + 1)) ++n;
    return n;
  };
  EXPECT_EQ(count(" σ</title>"), 27u);
  const size_t rests = j["ains"]["metrics"]["rest_periods"].get<size_t>();
  EXPECT_EQ(count("µg</title>"), 2 * rests);
  EXPECT_EQ(count("mdeg</title>"), 2 * rests);
  // Python's XML parser (a tool nobody here wrote) accepts it.
  const std::string cmd =
      "/usr/bin/python3 -c \"import xml.etree.ElementTree as E; E.parse('" + svg.string() + "')\"";
  EXPECT_EQ(std::system(cmd.c_str()), 0);
}

namespace {

// Usage errors exit 2 like every other tool's (not CLI11's 105–109); help and version exit 0.
TEST(ImucalUsage, UsageErrorsExitTwo) {
  for (const char* args : {"", "calibrate", "calibrate --method bogus x", "frobnicate",
                           "simulate --sequence short", "paper-tables --units 0"}) {
    const ProcResult r = run_imucal_cli(args);
    EXPECT_EQ(r.code, 2) << "imucal " << args << "\n" << r.out;
    EXPECT_FALSE(r.out.empty()) << args;
  }
  EXPECT_EQ(run_imucal_cli("--help").code, 0);
  EXPECT_EQ(run_imucal_cli("--version").code, 0);
}

// Issue #19 item 11: `imucal --help` began "(simulate, calibrate, evaluate, crlb)", 4 of its 9
// commands. Every command the README documents is listed under "Subcommands:" with its own help,
// and the description names either none of them or all.
TEST(ImucalUsage, HelpListsEveryDocumentedCommand) {
  std::ifstream readme(std::string(IMUCAL_SOURCE_DIR) + "/README.md");
  std::set<std::string> documented;
  std::string line;
  const std::regex usage(R"(^imucal ([a-z-]+) )");
  std::smatch m;
  while (std::getline(readme, line))
    if (std::regex_search(line, m, usage)) documented.insert(m[1]);
  ASSERT_GE(documented.size(), 9u) << "the README's imucal usage block";
  const ProcResult help = run_imucal_cli("--help");
  ASSERT_EQ(help.code, 0);
  const std::size_t sub = help.out.find("Subcommands:");
  ASSERT_NE(sub, std::string::npos) << help.out;
  const std::string description = help.out.substr(0, help.out.find('\n'));
  std::size_t named = 0;
  for (const std::string& cmd : documented) {
    EXPECT_NE(help.out.find("\n  " + cmd + " ", sub), std::string::npos) << cmd << "\n" << help.out;
    EXPECT_EQ(run_imucal_cli(cmd + " --help").code, 0) << cmd;
    named += description.find(cmd) != std::string::npos ? 1 : 0;
  }
  EXPECT_TRUE(named == 0 || named == documented.size()) << description;
}

// With --json, an error is a JSON object on stdout as well (a script parsing the output reads the
// error instead of failing to parse), with the same exit code.
TEST(ImucalUsage, JsonErrorsAreJson) {
  const ProcResult r = run_shell(std::string(IMUCAL_BIN_DIR) +
                                 "/imucal calibrate /nonexistent-dir --json 2>/dev/null");
  EXPECT_EQ(r.code, 1);
  const auto j = nlohmann::json::parse(r.out);
  EXPECT_NE(j["error"].get<std::string>().find("/nonexistent-dir"), std::string::npos);
  EXPECT_EQ(j["exit_code"], 1);
}

}  // namespace

// --plot writes SVG; a name that promises another format is refused before any work.
TEST_F(ImucalCli, PlotRefusesANameThatIsNotSvg) {
  const fs::path png = base_ / "run.png";
  const ProcResult r =
      run_imucal_cli("calibrate " + (base_ / "sim").string() + " --plot " + png.string());
  EXPECT_EQ(r.code, 2) << r.out;
  EXPECT_NE(r.out.find("name it .svg"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(png));
}

// An installed (or unpacked) program finds the sequence library under its own prefix
// (<prefix>/share/imucal/sequences), not through the source tree compiled in: a service with
// ProtectHome or a package on another machine has no source tree.
TEST(ImucalInstalled, FindsTheSequencesUnderItsOwnPrefix) {
  const fs::path prefix = fs::temp_directory_path() / ("imucal-prefix-" + std::to_string(getpid()));
  fs::create_directories(prefix / "bin");
  fs::create_directories(prefix / "share/imucal/sequences");
  fs::copy_file(std::string(IMUCAL_BIN_DIR) + "/imucal", prefix / "bin/imucal");
  fs::copy_file(std::string(IMUCAL_SOURCE_DIR) + "/sequences/short.toml",
                prefix / "share/imucal/sequences/only-here.toml");
  auto run = [&](const std::string& args) {
    return run_shell("env -u IMUCAL_SEQUENCE_DIR " + (prefix / "bin/imucal").string() + " " + args +
                     " 2>&1");
  };
  const auto found = run("crlb --sequence only-here --json");
  EXPECT_TRUE(found.code == 0 || found.code == 3) << found.out;
  EXPECT_NE(found.out.find("\"duration_s\""), std::string::npos) << found.out;
  // The source tree's library is not consulted: "pos19" exists only there.
  const auto missing = run("crlb --sequence pos19");
  EXPECT_EQ(missing.code, 1) << missing.out;
  EXPECT_NE(missing.out.find("only-here"), std::string::npos) << missing.out;
  fs::remove_all(prefix);
}

// An archive whose run.toml says the capture did not complete (an aborted or interrupted run) is
// REVIEW at best: `imucal calibrate` exits 3 and says why, even when both methods agree.
TEST_F(ImucalCli, PartialArchiveIsReviewAtBest) {
  const fs::path dir = variant("partial", "run.toml", [](std::string t) {
    return t +
           "\n[capture]\ncomplete = false\nframes_received = 0\nframes_logged = 0\n"
           "frames_foreign = 0\nframes_error = 0\nframes_malformed = 0\nframes_duplicate = 0\n"
           "frames_out_of_order = 0\nframes_discarded = 0\nsamples_decoded = 0\n"
           "samples_lost = 0\nsamples_corrupt = 0\nsamples_incomplete = 0\nsamples_late = 0\n"
           "samples_filled = 0\nimu_resets = 0\nrx_overflow = 0\nrows_written = 0\n"
           "rest_samples = 0\nmax_gap_samples = 0\n";
  });
  const ProcResult r = run_imucal_cli("calibrate " + dir.string());
  EXPECT_EQ(r.code, 3) << r.out;
  EXPECT_NE(r.out.find("capture incomplete"), std::string::npos) << r.out;
  const ProcResult j = run_imucal_cli("calibrate " + dir.string() + " --json");
  EXPECT_EQ(j.code, 3);
  const auto json = nlohmann::json::parse(j.out.substr(j.out.find('{')));
  EXPECT_EQ(json["verdict"], "REVIEW");
  EXPECT_TRUE(json["partial_archive"].get<bool>());
}
