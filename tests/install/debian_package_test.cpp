// The Debian package (issue #11, item 4): built with cpack from this build tree, lintian reports no
// error, its contents and conffiles are where the issue and Debian say, and a simulated unit runs
// through a station made of the installed files only: stationsim, stationd and stationctl from the
// package's /usr/bin, the sequence from its /usr/share/imucal/sequences (IMUCAL_SEQUENCE_DIR unset,
// so the source tree compiled in is not consulted). Where the test runs as root and the package is
// not installed yet, it is installed for real (`apt-get install ./imucal_….deb`: the account, the
// operators' group and /var/lib/imucal from the maintainer scripts) and purged afterwards;
// otherwise it is unpacked into a temporary root.
#include <grp.h>
#include <gtest/gtest.h>
#include <pwd.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include "tests/e2e/station_harness.hpp"
#include "tests/support/run_command.hpp"

namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using imucal::e2e::Station;
using imucal::test_support::run_command;

#ifndef IMUCAL_BUILD_DIR
#error "IMUCAL_BUILD_DIR must name the build tree"
#endif

const std::string kVersion = IMUCAL_VERSION;
const std::string kDeb = "imucal_" + kVersion + "_amd64.deb";
const std::vector<std::string> kPrograms = {"imucal", "stationd", "stationctl", "stationsim"};

std::string quote(const std::string& s) { return "'" + s + "'"; }

bool installed_on_this_machine() {
  return run_command("dpkg-query -W -f='${Status}' imucal 2>/dev/null").out ==
         "install ok installed";
}

/// Builds the package once for all tests of this program, into a directory of its own.
class DebianPackage : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new imucal::e2e::TempDir();
    const auto r = run_command("cd " + quote(IMUCAL_BUILD_DIR) + " && cpack -G DEB -B " +
                               quote(dir_->path()) + " 2>&1");
    build_log_ = r.out;
    deb_ = (*dir_) / kDeb;
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  void SetUp() override {
    ASSERT_TRUE(fs::exists(deb_)) << "cpack did not make " << deb_ << ":\n" << build_log_;
  }
  static std::string deb() { return deb_; }
  static std::string contents() { return run_command("dpkg-deb -c " + quote(deb_)).out; }

 private:
  static imucal::e2e::TempDir* dir_;
  static std::string deb_;
  static std::string build_log_;
};
imucal::e2e::TempDir* DebianPackage::dir_ = nullptr;
std::string DebianPackage::deb_;
std::string DebianPackage::build_log_;

// One test for what the built package is (lintian, contents, control data, man pages), one for
// installing and running it: each ctest process builds the package once.
TEST_F(DebianPackage, IsLintianCleanAndHoldsEverythingWhereDebianWantsIt) {
  const auto r =
      run_command("lintian --fail-on error --tag-display-limit 0 " + quote(deb()) + " 2>&1");
  // Warnings and notes are printed for the record; an error fails.
  std::printf("%s", r.out.c_str());
  EXPECT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out.find("E: "), std::string::npos) << r.out;

  const std::string list = contents();
  for (const auto& p : kPrograms) {
    EXPECT_NE(list.find("./usr/bin/" + p + "\n"), std::string::npos) << p << "\n" << list;
    EXPECT_NE(list.find("./usr/share/man/man1/" + p + ".1.gz"), std::string::npos) << p;
  }
  for (const char* f :
       {"./usr/share/imucal/sequences/factory-std.toml", "./usr/share/imucal/sequences/short.toml",
        "./usr/share/imucal/sequences/factory-fast.toml", "./usr/share/imucal/units/default.toml",
        "./usr/share/imucal/imu.dbc", "./usr/share/imucal/protocols/imucal-imu-1.toml",
        "./usr/share/imucal/stationd.example.toml", "./etc/imucal/stationd.toml",
        "./lib/systemd/system/stationd.service", "./usr/share/doc/imucal/copyright",
        "./usr/share/doc/imucal/changelog.gz"})
    EXPECT_NE(list.find(std::string(f) + "\n"), std::string::npos) << f << "\n" << list;
  // No test program and nothing from the build tree.
  EXPECT_EQ(list.find("_test"), std::string::npos) << list;
  EXPECT_EQ(list.find("/usr/local"), std::string::npos) << list;

  const auto conffiles = run_command("dpkg-deb -I " + quote(deb()) + " conffiles");
  EXPECT_EQ(conffiles.out, "/etc/imucal/stationd.toml\n");
  const auto control = run_command("dpkg-deb -f " + quote(deb()) + " Package Version Depends");
  EXPECT_NE(control.out.find("Version: " + kVersion), std::string::npos) << control.out;
  EXPECT_NE(control.out.find("adduser"), std::string::npos) << control.out;     // postinst needs it
  EXPECT_NE(control.out.find("libmodbus5"), std::string::npos) << control.out;  // dpkg-shlibdeps

  // Man pages: name, the --help text, exit status, version.
  const imucal::e2e::TempDir tmp;
  ASSERT_EQ(run_command("dpkg-deb -x " + quote(deb()) + " " + quote(tmp.path())).code, 0);
  for (const auto& p : kPrograms) {
    const auto page = run_command("zcat " + quote(tmp / ("usr/share/man/man1/" + p + ".1.gz")));
    ASSERT_EQ(page.code, 0) << p;
    EXPECT_NE(page.out.find(".SH NAME\n" + p + " \\-"), std::string::npos) << page.out;
    EXPECT_NE(page.out.find(".SH \"EXIT STATUS\""), std::string::npos) << page.out;
    EXPECT_NE(page.out.find(".SH OPTIONS"), std::string::npos) << p << ": the --help text";
    EXPECT_NE(page.out.find(kVersion), std::string::npos) << p;
  }
  // The unit runs the installed daemon on the packaged config.
  const std::string text = imucal::e2e::read_text(tmp / "lib/systemd/system/stationd.service");
  EXPECT_NE(text.find("ExecStart=/usr/bin/stationd --config /etc/imucal/stationd.toml"),
            std::string::npos)
      << text;
}

/// The root the package's files are in: "/" after a real install, else a temporary unpack.
struct InstalledRoot {
  std::string root;
  bool system = false;
};

TEST_F(DebianPackage, InstallsAndRunsASimulatedUnitFromTheInstalledFilesOnly) {
  const imucal::e2e::TempDir unpack;
  InstalledRoot where;
  const bool created_account = getpwnam("imucal") == nullptr;
  const bool had_data_dir = fs::exists("/var/lib/imucal");
  if (geteuid() == 0 && !installed_on_this_machine()) {
    const auto r = run_command("DEBIAN_FRONTEND=noninteractive apt-get install -y -qq " +
                               quote(deb()) + " 2>&1 </dev/null");
    ASSERT_EQ(r.code, 0) << r.out;
    where = {"", true};
    // The maintainer scripts: the account, its group (the operators'), the data directory.
    const passwd* pw = getpwnam("imucal");
    ASSERT_NE(pw, nullptr) << "postinst created no account imucal";
    const group* gr = getgrnam("imucal");
    ASSERT_NE(gr, nullptr) << "postinst created no group imucal";
    EXPECT_EQ(pw->pw_gid, gr->gr_gid);
    struct stat st {};
    ASSERT_EQ(::stat("/var/lib/imucal", &st), 0);
    EXPECT_EQ(st.st_uid, pw->pw_uid);
    EXPECT_TRUE(S_ISDIR(st.st_mode));
  } else {
    ASSERT_EQ(run_command("dpkg-deb -x " + quote(deb()) + " " + quote(unpack.path())).code, 0);
    where = {unpack.path(), false};
    std::printf("not root or imucal already installed: unpacked into %s\n", unpack.path().c_str());
  }
  const std::string bin = where.root + "/usr/bin";

  {
    // The packaged configuration is valid as shipped.
    const auto check =
        run_command("env -u IMUCAL_SEQUENCE_DIR " + bin + "/stationd --config " +
                    quote(where.root + "/etc/imucal/stationd.toml") + " --check-config 2>&1");
    EXPECT_EQ(check.code, 0) << check.out;
    {
      // The installed built-in protocol file (and the DBC it names) reads as a station's protocol.
      Station ps;
      ps.write_config(ps.config_text(
          "", "protocol = \"" + where.root + "/usr/share/imucal/protocols/imucal-imu-1.toml\"\n"));
      const auto pc = run_command(bin + "/stationd --config " + quote(ps.config_path()) +
                                  " --check-config 2>&1");
      EXPECT_EQ(pc.code, 0) << pc.out;
    }

    // A station of installed files: a short unit run ends PASS.
    unsetenv("IMUCAL_SEQUENCE_DIR");
    Station st;
    st.use_programs_from(bin);
    ASSERT_TRUE(st.start_sim());
    st.write_config(st.config_text());
    ASSERT_TRUE(st.start_daemon());
    EXPECT_NE(
        st.daemon_log().find("sequence library " + where.root + "/usr/share/imucal/sequences"),
        std::string::npos)
        << st.daemon_log();
    const auto run = st.ctl({"run", "start", "--serial", "PKG-0001", "--sequence", "short",
                             "--operator", "installer", "--wait"},
                            300s);
    EXPECT_EQ(run.exit_code, 0) << run.describe();
    EXPECT_NE(run.out.find("PASS"), std::string::npos) << run.describe();
    const auto history = st.ctl({"--json", "history", "PKG-0001"});
    EXPECT_EQ(history.exit_code, 0) << history.describe();
    EXPECT_NE(history.out.find("\"done\""), std::string::npos) << history.describe();
  }

  if (where.system) {  // leave the machine as it was (records and account stay on purge by design)
    const auto purge = run_command("apt-get purge -y -qq imucal 2>&1 </dev/null");
    EXPECT_EQ(purge.code, 0) << purge.out;
    EXPECT_FALSE(fs::exists("/usr/bin/stationd"));
    EXPECT_TRUE(fs::exists("/var/lib/imucal")) << "purge removed the quality records";
    if (created_account)
      run_command("deluser --quiet --system imucal 2>&1; delgroup --quiet --system imucal 2>&1");
    if (!had_data_dir) fs::remove_all("/var/lib/imucal");
  }
}

}  // namespace
