// The Debian package (issue #11, item 4): built with cpack from this build tree, lintian reports no
// error, its contents and conffiles are where the issue and Debian say, and a simulated unit runs
// through a station made of the installed files only: stationsim, stationd and stationctl from the
// package's /usr/bin, the sequence from its /usr/share/imucal/sequences (IMUCAL_SEQUENCE_DIR unset,
// so the source tree compiled in is not consulted), and the installed stationweb serves that run's
// page from the station's history. Where the test runs as root and the package is
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
#include "tests/tools/stationweb_process.hpp"
#include "tools/stationweb/httplib.hpp"

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
const std::vector<std::string> kPrograms = {"imucal", "stationd", "stationctl", "stationsim",
                                            "stationweb"};
const std::vector<std::string> kUnits = {"stationd.service", "stationweb.service"};

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
        "./lib/systemd/system/stationd.service", "./lib/systemd/system/stationweb.service",
        "./usr/share/doc/imucal/copyright", "./usr/share/doc/imucal/changelog.gz"})
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
  EXPECT_NE(control.out.find("libcpp-httplib"), std::string::npos) << control.out;  // stationweb

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
  // The units run the installed programs: the daemon on the packaged config, the web view on the
  // history the daemon writes there (station/config/config.cpp: <data_dir>/history.sqlite), on
  // loopback.
  const std::string text = imucal::e2e::read_text(tmp / "lib/systemd/system/stationd.service");
  EXPECT_NE(text.find("ExecStart=/usr/bin/stationd --config /etc/imucal/stationd.toml"),
            std::string::npos)
      << text;
  const std::string web = imucal::e2e::read_text(tmp / "lib/systemd/system/stationweb.service");
  EXPECT_NE(web.find("ExecStart=/usr/bin/stationweb --db /var/lib/imucal/history.sqlite "
                     "--listen 127.0.0.1:8090\n"),
            std::string::npos)
      << web;
  const std::string config = imucal::e2e::read_text(tmp / "etc/imucal/stationd.toml");
  EXPECT_NE(config.find("data_dir = \"/var/lib/imucal\""), std::string::npos) << config;
  EXPECT_NE(web.find("User=imucal\n"), std::string::npos) << web;
}

/// systemd's own check of a unit file: no error and nothing to remark (an unknown key or section,
/// a bad value, an ExecStart that is not an absolute path to an executable).
void expect_unit_verifies(const std::string& unit) {
  const auto r = run_command("systemd-analyze verify --man=no " + unit + " 2>&1");
  EXPECT_EQ(r.code, 0) << unit << ":\n" << r.out;
  EXPECT_EQ(r.out, "") << unit;
}

/// The installed stationweb, as QA's view of the station's history: the index lists the run and
/// its page shows it (serial, verdict) as stationctl does.
void expect_web_view_serves(const std::string& bin, const Station& st, const std::string& run_id) {
  std::unique_ptr<imucal::test_support::StationwebProcess> web;
  try {
    web = std::make_unique<imucal::test_support::StationwebProcess>(
        bin + "/stationweb", st.db_path(), st.db_path() + ".stationweb.log");
  } catch (const std::exception& e) {
    FAIL() << e.what() << "\n" << imucal::e2e::read_text(st.db_path() + ".stationweb.log");
  }
  httplib::Client client("127.0.0.1", web->port());
  const auto index = client.Get("/");
  ASSERT_TRUE(index) << "no answer from the installed stationweb";
  EXPECT_EQ(index->status, 200);
  EXPECT_NE(index->body.find("PKG-0001"), std::string::npos) << index->body;
  const auto page = client.Get("/run/" + run_id);
  ASSERT_TRUE(page);
  EXPECT_EQ(page->status, 200) << page->body;
  EXPECT_NE(page->body.find("PKG-0001"), std::string::npos) << page->body;
  EXPECT_NE(page->body.find("PASS"), std::string::npos) << page->body;
  EXPECT_EQ(web->stop(), 0) << "stationweb did not stop cleanly on SIGTERM";
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
    const long long run_id = imucal::e2e::newest_run(st, "PKG-0001").value("run_id", -1LL);
    expect_web_view_serves(bin, st, std::to_string(run_id));
  }
  if (where.system)  // the programs the units start exist only after a real install
    for (const auto& unit : kUnits) expect_unit_verifies("/lib/systemd/system/" + unit);

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
