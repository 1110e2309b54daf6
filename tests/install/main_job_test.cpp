// A newcomer's first run (issue #11, item 5): the README's main-job command, copied from the
// README, run from nothing — every Debian package reported missing — installs no test-only
// package and builds only the four programs, then runs the simulated unit to its verdict.
// apt-get and dpkg-query are replaced by shims on PATH that log what they are asked and report
// every package missing (the machine keeps its packages); the build goes to a tree of its own
// (BUILD_DIR) beside build/, so ccache serves it from the main build's objects: ccache's base
// directory is the repository (tools/ccache_launcher.sh), and a tree elsewhere would differ in its
// relative -I paths and miss every object (1 300 s of a cold CI run, 2026-11-29).
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <filesystem>
#include <fstream>
#include <set>
#include <sstream>
#include <string>

#include "tests/e2e/station_harness.hpp"
#include "tests/support/run_command.hpp"

namespace {

namespace fs = std::filesystem;
using imucal::e2e::read_text;
using imucal::test_support::run_command;

/// The README's main-job command: the line of its first code block marked "# main job".
std::string readme_main_job_command() {
  std::istringstream readme(read_text(std::string(IMUCAL_SOURCE_DIR) + "/README.md"));
  for (std::string line; std::getline(readme, line);) {
    const auto mark = line.find("# main job");
    if (mark == std::string::npos) continue;
    std::string cmd = line.substr(0, mark);
    while (!cmd.empty() && cmd.back() == ' ') cmd.pop_back();
    return cmd;
  }
  return "";
}

void write_executable(const fs::path& p, const std::string& text) {
  std::ofstream(p) << text;
  fs::permissions(p, fs::perms::owner_all | fs::perms::group_read | fs::perms::group_exec |
                         fs::perms::others_read | fs::perms::others_exec);
}

TEST(MainJob, FromNothingInstallsNoTestPackageBuildsOnlyTheFourProgramsAndReachesTheVerdict) {
  const std::string command = readme_main_job_command();
  ASSERT_FALSE(command.empty()) << "README.md has no line marked '# main job'";

  const imucal::e2e::TempDir tmp;
  const fs::path shims = tmp / "shims", apt_log = tmp / "apt.log";
  fs::create_directories(shims);
  write_executable(shims / "dpkg-query", "#!/bin/sh\nexit 1\n");  // nothing is installed
  write_executable(shims / "apt-get", "#!/bin/sh\necho \"$*\" >> '" + apt_log.string() + "'\n");
  write_executable(shims / "sudo", "#!/bin/sh\nexec \"$@\"\n");

  // Beside build/ (a name .gitignore's build-*/ covers), removed before and after a passing run.
  const std::string build = std::string(IMUCAL_SOURCE_DIR) + "/build-main-job-test";
  fs::remove_all(build);
  const auto r = run_command("cd '" + std::string(IMUCAL_SOURCE_DIR) + "' && env PATH='" +
                             shims.string() + ":" + std::getenv("PATH") + "' BUILD_DIR='" + build +
                             "' DEMO_DIR='" + (tmp / "demo") + "' " + command + " 2>&1");
  EXPECT_EQ(r.code, 0) << command << "\n" << r.out;
  EXPECT_NE(r.out.find("PASS"), std::string::npos) << r.out;

  // What it asked apt for: the four programs' build dependencies, and nothing only tests need.
  const std::string asked = read_text(apt_log);
  EXPECT_NE(asked.find("libceres-dev"), std::string::npos) << asked;
  EXPECT_NE(asked.find("libmodbus-dev"), std::string::npos) << asked;
  for (const char* test_only :
       {"qemu", "linux-image", "can-utils", "mbpoll", "python3-can", "chromium", "clang-16",
        "busybox", "lintian", "help2man", "libgtest-dev", "libgmock-dev", "libbenchmark-dev",
        "libcpp-httplib-dev"})
    EXPECT_EQ(asked.find(test_only), std::string::npos) << test_only << " in: " << asked;

  // What it built: the four programs and no test program or benchmark.
  std::set<std::string> programs;
  for (const auto& e : fs::directory_iterator(build + "/bin")) programs.insert(e.path().filename());
  EXPECT_EQ(programs, (std::set<std::string>{"imucal", "stationctl", "stationd", "stationsim"}));
  int test_programs = 0;
  for (const auto& e : fs::recursive_directory_iterator(build)) {
    const std::string name = e.path().filename();
    // A room's test program (<room>_tests), a test file's script (<room>_<file>_test), a benchmark.
    const auto ends_with = [&name](const std::string& tail) {
      return name.size() > tail.size() && name.compare(name.size() - tail.size(), tail.size(), tail) == 0;
    };
    if (e.is_regular_file() && (ends_with("_test") || ends_with("_tests") ||
                                name.find("bench") != std::string::npos))
      ++test_programs;
  }
  EXPECT_EQ(test_programs, 0);
  EXPECT_NE(read_text(build + "/CMakeCache.txt").find("IMUCAL_BUILD_TESTS:BOOL=OFF"),
            std::string::npos);
  if (!::testing::Test::HasFailure()) fs::remove_all(build);  // a failed run keeps its tree
}

}  // namespace
