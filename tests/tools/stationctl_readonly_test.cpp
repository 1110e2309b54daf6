// build/bin/stationctl as operators and QA run it, against a history database filled through the
// repository: with no daemon (read-only fallback: history ordering, show, params loadable by
// read_param_file, export, exit codes of bad input and of control commands), and against an
// in-process control server with a scripted handler (the socket and the fallback print the same;
// --wait's progress lines and exit codes).
#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <spawn.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <nlohmann/json.hpp>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "db/archive/param_json.hpp"
#include "db/history/sqlite_repository.hpp"
#include "station/control/control_server.hpp"
#include "tests/db/history_fixtures.hpp"

namespace imucal {
namespace {

namespace fs = std::filesystem;
using db::test::TempDir;
using nlohmann::json;

struct ProcStationctlReadonly {
  int code;
  std::string out;
  std::string err;
};

std::string slurp_stationctl_readonly(const std::string& path) {
  std::ifstream f(path, std::ios::binary);
  std::stringstream ss;
  ss << f.rdbuf();
  return ss.str();
}

std::vector<std::string> lines_of_stationctl_readonly(const std::string& text) {
  std::vector<std::string> out;
  std::stringstream ss(text);
  for (std::string l; std::getline(ss, l);) out.push_back(l);
  return out;
}

/// Serials and times. SN-A: run 1 10:00 PASS (seed 1), run 2 12:00 PASS (seed 2), run 3 11:00
/// REVIEW (seed 3), run 4 13:00 aborted; SN-B: run 5 09:00 PASS (seed 5), run 6 09:30 failed.
class StationctlTest : public ::testing::Test {
 protected:
  void SetUp() override {
    db_ = dir_.file("history.sqlite");
    db::history::SqliteRepository repo(db_);
    const db::history::TimestampMs t = db::history::parse_time_utc("2024-05-01T00:00:00Z");
    const db::history::TimestampMs h = 3600000;
    auto pass = [&](const char* sn, db::history::TimestampMs at, long seed) {
      const db::history::RunId id = repo.create_run(db::test::new_run(sn, at));
      repo.finish_run(id, db::test::pass_completion(seed, at + 600000));
      return id;
    };
    auto ended = [&](const char* sn, db::history::TimestampMs at, db::history::RunState state,
                     const char* reason) {
      const db::history::RunId id = repo.create_run(db::test::new_run(sn, at));
      db::history::RunCompletion c;
      c.state = state;
      c.ended_at_ms = at + 30000;
      c.reason = reason;
      repo.finish_run(id, c);
      return id;
    };
    EXPECT_EQ(pass("SN-A", t + 10 * h, 1), 1);
    EXPECT_EQ(pass("SN-A", t + 12 * h, 2), 2);
    const db::history::RunId r3 = repo.create_run(db::test::new_run("SN-A", t + 11 * h));
    repo.finish_run(r3, db::test::review_completion(3, t + 11 * h + 600000));
    EXPECT_EQ(ended("SN-A", t + 13 * h, db::history::RunState::kAborted, "operator: wrong fixture"),
              4);
    EXPECT_EQ(pass("SN-B", t + 9 * h, 5), 5);
    EXPECT_EQ(ended("SN-B", t + 9 * h + h / 2, db::history::RunState::kFailed, "table fault 17"),
              6);
  }

  /// stationctl with the absent socket and the database, unless `extra` says otherwise.
  ProcStationctlReadonly ctl(const std::string& args, const std::string& target = "") {
    const std::string err_file = dir_.file("stderr.txt");
    const std::string t =
        target.empty() ? "--socket " + dir_.file("absent.sock") + " --db " + db_ : target;
    const std::string cmd = std::string(IMUCAL_BIN_DIR) + "/stationctl " + t + " " + args + " 2>" +
                            err_file + " </dev/null";
    FILE* p = popen(cmd.c_str(), "r");
    std::string out;
    char buf[4096];
    size_t n;
    while ((n = fread(buf, 1, sizeof buf, p)) > 0) out.append(buf, n);
    const int st = pclose(p);
    return {WIFEXITED(st) ? WEXITSTATUS(st) : -1, out, slurp_stationctl_readonly(err_file)};
  }

  TempDir dir_;
  std::string db_;
};

// Issue #19 item 11: `history` without a serial was refused ("SN is required"); QA wants the line's
// newest runs whatever the unit.
TEST_F(StationctlTest, HistoryWithoutASerialListsEveryUnitsNewestRuns) {
  const ProcStationctlReadonly p = ctl("history");
  ASSERT_EQ(p.code, 0) << p.err;
  const auto lines = lines_of_stationctl_readonly(p.out);
  ASSERT_EQ(lines.size(), 8u) << p.out;  // title, header, 6 runs
  EXPECT_NE(lines[0].find("all units"), std::string::npos) << lines[0];
  EXPECT_NE(lines[1].find("SERIAL"), std::string::npos) << lines[1];
  // 13:00 SN-A 4, 12:00 2, 11:00 3, 10:00 1, 09:30 SN-B 6, 09:00 5.
  const char* expected[] = {"4 ", "2 ", "3 ", "1 ", "6 ", "5 "};
  for (std::size_t i = 0; i < 6; ++i)
    EXPECT_EQ(lines[i + 2].rfind(expected[i], 0), 0u) << lines[i + 2];
  EXPECT_NE(lines[6].find("SN-B"), std::string::npos) << lines[6];
  const json j = json::parse(ctl("--json history --limit 3").out);
  EXPECT_TRUE(j.at("serial").is_null());
  EXPECT_EQ(j.at("runs").size(), 3u);
  EXPECT_EQ(j.at("total"), 6);
}

TEST_F(StationctlTest, HistoryFromTheDatabaseIsNewestFirst) {
  const ProcStationctlReadonly p = ctl("history SN-A");
  ASSERT_EQ(p.code, 0) << p.err;
  EXPECT_NE(p.err.find("reading the database " + db_ + " read-only"), std::string::npos) << p.err;
  EXPECT_NE(p.err.find("absent.sock"), std::string::npos) << "the note names the socket";
  const auto lines = lines_of_stationctl_readonly(p.out);
  ASSERT_EQ(lines.size(), 7u) << p.out;               // title, header, 4 runs, the yield
  const char* expected[] = {"4 ", "2 ", "3 ", "1 "};  // 13:00, 12:00, 11:00, 10:00
  for (int i = 0; i < 4; ++i)
    EXPECT_EQ(lines[static_cast<std::size_t>(i + 2)].rfind(expected[i], 0), 0u)
        << lines[static_cast<std::size_t>(i + 2)];
  EXPECT_NE(lines[2].find("aborted"), std::string::npos);
  EXPECT_NE(lines[2].find("operator: wrong fixture"), std::string::npos);
  EXPECT_NE(lines[4].find("REVIEW"), std::string::npos);
  // Runs 1 and 2 PASS, 3 REVIEW: the unit decided three; 4, the operator's abort, is not its own.
  EXPECT_EQ(lines[6].rfind("Yield: 2 PASS of 3 run(s)", 0), 0u) << lines[6];
  EXPECT_NE(lines[6].find("1 abort(s)"), std::string::npos) << lines[6];

  const ProcStationctlReadonly j = ctl("--json history SN-B");
  ASSERT_EQ(j.code, 0) << j.err;
  const json h = json::parse(j.out);
  ASSERT_EQ(h.at("runs").size(), 2u);
  EXPECT_EQ(h["runs"][0].at("run_id"), 6);
  EXPECT_EQ(h["runs"][0].at("failure_reason"), "table fault 17");
  EXPECT_EQ(h["runs"][1].at("run_id"), 5);

  const ProcStationctlReadonly limited = ctl("history SN-A --limit 2 --json");
  ASSERT_EQ(limited.code, 0) << limited.err;
  EXPECT_EQ(json::parse(limited.out).at("runs").size(), 2u);
  const std::size_t total = json::parse(ctl("--json history SN-A").out).at("runs").size();
  ASSERT_GT(total, 2u);
  EXPECT_EQ(json::parse(limited.out).at("total"), total);
  // The text says how many of how many it shows (it said "1 run" of many).
  const ProcStationctlReadonly one = ctl("history SN-A --limit 1");
  ASSERT_EQ(one.code, 0) << one.err;
  EXPECT_NE(one.out.find("(newest 1 of " + std::to_string(total) + " runs)"), std::string::npos)
      << one.out;
}

TEST_F(StationctlTest, ShowPrintsTheRunAndItsParameters) {
  const ProcStationctlReadonly p = ctl("show 3");
  ASSERT_EQ(p.code, 0) << p.err;
  EXPECT_EQ(p.out.rfind("Run 3  SN-A  review  verdict REVIEW  (cross-check REVIEW)", 0), 0u)
      << p.out;
  EXPECT_NE(p.out.find("accel_bias_mps2[1]: |Δ| = 12.3 µg"), std::string::npos) << p.out;
  EXPECT_NE(p.out.find("gyro_M[2][2]"), std::string::npos);

  const ProcStationctlReadonly j = ctl("--json show 2");
  ASSERT_EQ(j.code, 0) << j.err;
  const json s = json::parse(j.out);
  EXPECT_EQ(s.at("run").at("serial"), "SN-A");
  ASSERT_EQ(s.at("calibrations").size(), 2u);
  calib::core::ParamSet sigma;
  const calib::core::ParamSet nlsq =
      db::archive::param_set_from_json(s["calibrations"][1].at("params"), "show 2", &sigma);
  EXPECT_EQ(nlsq.to_vector(), db::test::seeded_params(2, 1).to_vector());
  EXPECT_EQ(sigma.to_vector(), db::test::seeded_sigma(2, 1).to_vector());
}

// Issue #19 item 9: no internal operation names in messages (was "history.sqlite: show: no run
// 99").
TEST_F(StationctlTest, ShowOfAnUnknownRunNamesTheRunAndTheDatabase) {
  const ProcStationctlReadonly r = ctl("show 99");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.err.find("no run 99 in " + db_), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("show:"), std::string::npos) << r.err;
}

TEST_F(StationctlTest, ParamsOutputLoadsAsTheStoredActiveSet) {
  // SN-A's latest done+PASS run is run 2 (12:00): the REVIEW at 11:00 and the abort at 13:00 do
  // not count. Its AINS set (seed 2, method 0) is the active one.
  for (const char* flags : {"", "--json "}) {
    const ProcStationctlReadonly p = ctl(std::string(flags) + "params SN-A");
    ASSERT_EQ(p.code, 0) << p.err;
    const std::string file = dir_.file("params.json");
    std::ofstream(file) << p.out;
    calib::core::ParamSet sigma;
    const calib::core::ParamSet loaded = db::archive::read_param_file(file, &sigma);
    EXPECT_EQ(loaded.to_vector(), db::test::seeded_params(2, 0).to_vector()) << flags;
    EXPECT_EQ(sigma.to_vector(), db::test::seeded_sigma(2, 0).to_vector()) << flags;
  }
}

TEST_F(StationctlTest, ExportCsvAndJson) {
  // All: PASS/REVIEW runs have 2 rows (ains, nlsq), aborted/failed runs 1 -> 4*2 + 2 = 10 rows.
  const ProcStationctlReadonly csv = ctl("export --format csv");
  ASSERT_EQ(csv.code, 0) << csv.err;
  auto lines = lines_of_stationctl_readonly(csv.out);
  ASSERT_EQ(lines.size(), 11u);
  EXPECT_EQ(lines[0].rfind("run_id,serial,state,verdict,", 0), 0u);
  // Oldest first: SN-B's 09:00 run.
  EXPECT_EQ(lines[1].rfind("5,SN-B,done,PASS,", 0), 0u) << lines[1];

  const ProcStationctlReadonly js =
      ctl("export --serial SN-A --since 2024-05-01T11:30:00Z --format json");
  ASSERT_EQ(js.code, 0) << js.err;
  const json arr = json::parse(js.out);
  ASSERT_EQ(arr.size(), 3u);  // run 2 (two methods) and run 4
  EXPECT_EQ(arr[0].at("run_id"), 2);
  EXPECT_EQ(arr[2].at("run_id"), 4);
  EXPECT_TRUE(arr[2].at("calibration").is_null());

  const std::string out_file = dir_.file("export.csv");
  const ProcStationctlReadonly to_file =
      ctl("export --serial SN-B --format csv --output " + out_file);
  ASSERT_EQ(to_file.code, 0) << to_file.err;
  EXPECT_TRUE(to_file.out.empty());
  EXPECT_NE(to_file.err.find("3 rows written to " + out_file), std::string::npos) << to_file.err;
  EXPECT_EQ(lines_of_stationctl_readonly(slurp_stationctl_readonly(out_file)).size(), 4u);
}

/// The file type of a path, not following a final symbolic link.
mode_t lstat_type(const std::string& path) {
  struct stat st {};
  return ::lstat(path.c_str(), &st) == 0 ? (st.st_mode & S_IFMT) : 0;
}

// Issue #19, item 1: `--output PATH` must never destroy what is at PATH. As root, /dev/full became
// a regular file ("12 rows written", exit 0) and a named pipe and a symbolic link were replaced.
TEST_F(StationctlTest, ExportOutputWritesDevicesAndPipesInPlaceAndFollowsLinks) {
  const std::string rows = ctl("export --serial SN-B --format csv").out;
  ASSERT_EQ(lines_of_stationctl_readonly(rows).size(), 4u);

  // A full device: the write error with its reason, exit non-zero, the device still a device. As
  // root (CI) a device node of our own (the same major/minor as /dev/full) keeps /dev untouched.
  std::string full = "/dev/full";
  if (::geteuid() == 0) {
    full = dir_.file("full");
    ASSERT_EQ(::mknod(full.c_str(), S_IFCHR | 0666, makedev(1, 7)), 0) << std::strerror(errno);
  }
  const ProcStationctlReadonly to_full = ctl("export --serial SN-B --format csv --output " + full);
  EXPECT_NE(to_full.code, 0) << to_full.err;
  EXPECT_NE(to_full.err.find("cannot write " + full + ": No space left on device"),
            std::string::npos)
      << to_full.err;
  EXPECT_EQ(to_full.err.find("rows written"), std::string::npos) << to_full.err;
  EXPECT_EQ(lstat_type(full), static_cast<mode_t>(S_IFCHR));

  // A named pipe: its reader gets the rows; the pipe stays a pipe.
  const std::string fifo = dir_.file("rows.fifo");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  std::string from_pipe;
  std::thread reader([&] {
    std::ifstream in(fifo, std::ios::binary);  // blocks until stationctl opens the pipe
    from_pipe.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  });
  const ProcStationctlReadonly to_fifo = ctl("export --serial SN-B --format csv --output " + fifo);
  reader.join();
  EXPECT_EQ(to_fifo.code, 0) << to_fifo.err;
  EXPECT_EQ(from_pipe, rows);
  EXPECT_EQ(lstat_type(fifo), static_cast<mode_t>(S_IFIFO));

  // A symbolic link to a regular file: the target gets the rows (its permissions kept), the link
  // stays a link; a dangling link's target is created.
  const std::string target = dir_.file("target.csv"), link = dir_.file("link.csv");
  { std::ofstream(target) << "old content\n"; }
  ASSERT_EQ(::chmod(target.c_str(), 0640), 0);
  fs::create_symlink("target.csv", link);
  const ProcStationctlReadonly to_link = ctl("export --serial SN-B --format csv --output " + link);
  EXPECT_EQ(to_link.code, 0) << to_link.err;
  EXPECT_EQ(lstat_type(link), static_cast<mode_t>(S_IFLNK));
  EXPECT_EQ(slurp_stationctl_readonly(target), rows);
  EXPECT_EQ(fs::status(target).permissions() & fs::perms::all,
            fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
  const std::string dangling = dir_.file("dangling.csv");
  fs::create_symlink("created.csv", dangling);
  const ProcStationctlReadonly to_dangling =
      ctl("export --serial SN-B --format csv --output " + dangling);
  EXPECT_EQ(to_dangling.code, 0) << to_dangling.err;
  EXPECT_EQ(lstat_type(dangling), static_cast<mode_t>(S_IFLNK));
  EXPECT_EQ(slurp_stationctl_readonly(dir_.file("created.csv")), rows);

  // /dev/stdout is the process's own standard output (here the test's pipe).
  const ProcStationctlReadonly to_stdout =
      ctl("export --serial SN-B --format csv --output /dev/stdout");
  EXPECT_EQ(to_stdout.code, 0) << to_stdout.err;
  EXPECT_EQ(to_stdout.out, rows);

  // Refused before anything is written, naming the user's path (never a temporary file) and the
  // system's reason; nothing left beside it.
  const ProcStationctlReadonly to_dir =
      ctl("export --serial SN-B --format csv --output " + dir_.path());
  EXPECT_NE(to_dir.code, 0);
  EXPECT_NE(to_dir.err.find("cannot write " + dir_.path() + ": it is a directory"),
            std::string::npos)
      << to_dir.err;
  const ProcStationctlReadonly to_proc =
      ctl("export --serial SN-B --format csv --output /proc/nope.csv");
  EXPECT_NE(to_proc.code, 0);
  EXPECT_NE(to_proc.err.find("cannot write /proc/nope.csv: "), std::string::npos) << to_proc.err;
  EXPECT_EQ(to_proc.err.find("tmp"), std::string::npos) << to_proc.err;
  const std::string missing_dir = dir_.file("no-such-dir") + "/x.csv";
  const ProcStationctlReadonly to_missing =
      ctl("export --serial SN-B --format csv --output " + missing_dir);
  EXPECT_NE(to_missing.code, 0);
  EXPECT_NE(to_missing.err.find("cannot write " + missing_dir + ": No such file or directory"),
            std::string::npos)
      << to_missing.err;
  for (const auto& e : fs::directory_iterator(dir_.path()))
    EXPECT_EQ(e.path().filename().string().rfind(".", 0), std::string::npos)
        << "a temporary file was left: " << e.path();
}

TEST_F(StationctlTest, BadInputExitsWithTwo) {
  ProcStationctlReadonly p = ctl("history 'bad serial'");
  EXPECT_EQ(p.code, 2) << p.err;
  EXPECT_NE(p.err.find("serial number \"bad serial\""), std::string::npos) << p.err;
  EXPECT_NE(p.err.find("1 to 32 characters"), std::string::npos) << "states the rule: " << p.err;
  p = ctl("run start --serial ../etc");
  EXPECT_EQ(p.code, 2) << p.err;
  p = ctl("history SN-Z");
  EXPECT_EQ(p.code, 2) << p.err;
  EXPECT_NE(p.err.find("SN-Z"), std::string::npos) << p.err;
  p = ctl("show 99");
  EXPECT_EQ(p.code, 2) << p.err;
  EXPECT_NE(p.err.find("99"), std::string::npos) << p.err;
  p = ctl("params SN-Z");
  EXPECT_EQ(p.code, 2) << p.err;
  p = ctl("export --serial SN-Z --format csv");
  EXPECT_EQ(p.code, 2) << p.err;
  p = ctl("export --format xml");
  EXPECT_EQ(p.code, 2) << p.err;
  p = ctl("export --format csv --since yesterday");
  EXPECT_EQ(p.code, 2) << p.err;
  EXPECT_NE(p.err.find("--since"), std::string::npos) << p.err;
  p = ctl("show zero");
  EXPECT_EQ(p.code, 2) << p.err;
  p = ctl("");
  EXPECT_EQ(p.code, 2) << p.err;
  p = ctl("frobnicate");
  EXPECT_EQ(p.code, 2) << p.err;
  EXPECT_TRUE(p.out.empty());
}

TEST_F(StationctlTest, VersionPrintsTheVersionAndExitsZero) {
  // It exited 2, as bad input: a script asking for the version read a failure.
  const ProcStationctlReadonly p = ctl("--version");
  EXPECT_EQ(p.code, 0) << p.err;
  EXPECT_NE(p.out.find(IMUCAL_VERSION), std::string::npos) << p.out;
}

TEST_F(StationctlTest, ControlCommandsWithoutTheDaemonExitWithFour) {
  const std::string sock = dir_.file("absent.sock");
  for (const char* args : {"run start --serial SIM-0001", "run abort", "reprocess 1",
                           "run start --serial SIM-0001 --wait", "run status"}) {
    const ProcStationctlReadonly p = ctl(args);
    EXPECT_EQ(p.code, 4) << args << ": " << p.err;
    EXPECT_NE(p.err.find("cannot connect to stationd at " + sock), std::string::npos)
        << args << ": " << p.err;
    EXPECT_TRUE(p.out.empty()) << args;
  }
  // A run's state is a read: it comes from the database.
  const ProcStationctlReadonly s = ctl("run status --run 4");
  ASSERT_EQ(s.code, 0) << s.err;
  EXPECT_NE(s.out.find("run 4 SN-A: aborted"), std::string::npos) << s.out;
  EXPECT_NE(s.out.find("operator: wrong fixture"), std::string::npos) << s.out;

  // Neither daemon nor database: a read cannot be answered.
  const ProcStationctlReadonly none = ctl("history SN-A", "--socket " + sock + " --db ''");
  EXPECT_EQ(none.code, 4) << none.err;
  EXPECT_NE(none.err.find("give --db or --config"), std::string::npos) << none.err;
  // A database that is not there is an error, never created by a read.
  const ProcStationctlReadonly missing =
      ctl("history SN-A", "--socket " + sock + " --db " + dir_.file("no.sqlite"));
  EXPECT_EQ(missing.code, 4) << missing.err;
  EXPECT_NE(missing.err.find("no.sqlite"), std::string::npos) << missing.err;
  EXPECT_FALSE(fs::exists(dir_.file("no.sqlite")));
}

TEST_F(StationctlTest, ConfigFileGivesSocketAndDatabase) {
  // The shipped example config; its relative database path resolves against the config's dir.
  const std::string conf_dir = dir_.file("conf");
  fs::create_directories(conf_dir + "/data");
  fs::copy_file(std::string(IMUCAL_SOURCE_DIR) + "/station/config/stationd.example.toml",
                conf_dir + "/stationd.toml");
  fs::copy_file(db_, conf_dir + "/data/history.sqlite");
  const ProcStationctlReadonly p =
      ctl("history SN-B --json", "--config " + conf_dir + "/stationd.toml");
  ASSERT_EQ(p.code, 0) << p.err;
  EXPECT_EQ(json::parse(p.out).at("runs").size(), 2u);
  EXPECT_NE(p.err.find(conf_dir + "/stationd.sock"), std::string::npos) << p.err;
  EXPECT_NE(p.err.find(conf_dir + "/data/history.sqlite"), std::string::npos) << p.err;

  std::ofstream(conf_dir + "/broken.toml") << "[station]\nname = 5\n";
  const ProcStationctlReadonly bad = ctl("history SN-B", "--config " + conf_dir + "/broken.toml");
  EXPECT_EQ(bad.code, 2) << bad.err;
  EXPECT_NE(bad.err.find("broken.toml:2"), std::string::npos) << bad.err;
}

// ----- against a live control server -------------------------------------------------------------

/// A daemon stand-in: run.start answers run 41; its status walks through a scripted life.
class ScriptedHandler : public station::control::ControlHandler {
 public:
  ScriptedHandler(const db::history::Repository& repo, std::vector<json> script)
      : repo_(repo), script_(std::move(script)) {}
  json start_run(const station::control::StartRunRequest& r) override {
    if (r.serial == "SIM-BUSY")
      throw station::control::ControlError(station::control::error_code::kBusy,
                                           "run 40 (SIM-0040) is running; one run at a time");
    return {{"run_id", 41}, {"serial", r.serial}, {"sequence", "short"}, {"steps", 3}};
  }
  json status(std::optional<db::history::RunId> run_id) override {
    if (!run_id) return {{"state", "idle"}, {"run", nullptr}, {"last_run", nullptr}};
    const std::size_t i = std::min(calls_++, script_.size() - 1);
    json run = script_[i];
    run["run_id"] = *run_id;
    run["serial"] = "SIM-0001";
    return {{"run", run}};
  }
  json abort_run(const std::string&) override { return {{"run_id", 41}}; }
  json reprocess(const station::control::ReprocessRequest& q) override {
    return {{"run_id", 42}, {"reprocessed_from", q.run_id}};
  }
  json diagnose(db::history::RunId id) override {
    return {{"run_id", id}, {"verdict", "consistent"}};
  }
  const db::history::Repository& repository() const override { return repo_; }

 private:
  const db::history::Repository& repo_;
  std::vector<json> script_;
  std::size_t calls_ = 0;
};

json live(const char* state, const char* phase, int step, double left) {
  return {{"state", state},      {"phase", phase},     {"step", step}, {"steps", 3},
          {"time_left_s", left}, {"verdict", nullptr}, {"reason", ""}};
}

std::vector<json> script_ending(const char* state, const char* verdict, const char* reason) {
  json end = {
      {"state", state}, {"verdict", verdict ? json(verdict) : json(nullptr)}, {"reason", reason}};
  return {live("preparing", "homing", 0, 30),       live("running", "moving", 1, 20),
          live("running", "moving", 1, 19),  // only the time left changed: no new line
          live("running", "resting", 1, 15),        live("running", "resting", 2, 10),
          live("calibrating", "calibrating", 3, 0), end};
}

class StationctlLive : public StationctlTest {
 protected:
  void serve(std::vector<json> script) {
    ro_ = std::make_unique<db::history::SqliteRepository>(db_);
    handler_ = std::make_unique<ScriptedHandler>(*ro_, std::move(script));
    station::control::ControlServerOptions o;
    o.socket_path = dir_.file("live.sock");
    o.database_path = db_;  // streamed exports read it, as the daemon's do
    server_ = std::make_unique<station::control::ControlServer>(*handler_, o);
    server_->start();
  }
  std::string live_target() const { return "--socket " + dir_.file("live.sock") + " --db " + db_; }

  std::unique_ptr<db::history::SqliteRepository> ro_;
  std::unique_ptr<ScriptedHandler> handler_;
  std::unique_ptr<station::control::ControlServer> server_;
};

TEST_F(StationctlLive, SocketAndFallbackPrintTheSame) {
  serve(script_ending("done", "PASS", ""));
  for (const char* args :
       {"history SN-A", "--json history SN-A", "show 3", "--json show 1", "params SN-A",
        "export --format csv", "export --format json", "history SN-B --limit 1"}) {
    const ProcStationctlReadonly via_socket = ctl(args, live_target());
    const ProcStationctlReadonly via_db = ctl(args);
    ASSERT_EQ(via_socket.code, 0) << args << ": " << via_socket.err;
    ASSERT_EQ(via_db.code, 0) << args << ": " << via_db.err;
    EXPECT_EQ(via_socket.out, via_db.out) << args;
    EXPECT_TRUE(via_socket.err.empty())
        << "no fallback note when the daemon answers: " << via_socket.err;
  }
  // Errors too: same exit code over the socket.
  EXPECT_EQ(ctl("show 99", live_target()).code, 2);
  EXPECT_EQ(ctl("history SN-Z", live_target()).code, 2);
}

TEST_F(StationctlLive, WaitFollowsTheRunToPass) {
  serve(script_ending("done", "PASS", ""));
  const ProcStationctlReadonly p =
      ctl("run start --serial SIM-0001 --sequence short --wait", live_target());
  EXPECT_EQ(p.code, 0) << p.err;
  EXPECT_EQ(p.out, "run 41 SIM-0001: done, verdict PASS\n");
  // Not a TTY: one line per change of state, phase or step (the 19 s repeat is not shown).
  const auto lines = lines_of_stationctl_readonly(p.err);
  const std::vector<std::string> expected = {
      "run 41 started: SIM-0001",
      "run 41 SIM-0001: step 0/3 homing, 30 s left",
      "run 41 SIM-0001: step 1/3 moving, 20 s left",
      "run 41 SIM-0001: step 1/3 resting, 15 s left",
      "run 41 SIM-0001: step 2/3 resting, 10 s left",
      "run 41 SIM-0001: calibrating"};  // the outcome goes to stdout, once
  EXPECT_EQ(lines, expected) << p.err;
}

TEST_F(StationctlLive, WaitExitsOneWhenTheRunDoesNotPass) {
  serve(script_ending("review", "REVIEW", "gyro_M[0][0]: |Δ| = 90 ppm > 4σ bound 40 ppm"));
  const ProcStationctlReadonly p = ctl("--json run start --serial SIM-0001 --wait", live_target());
  EXPECT_EQ(p.code, 1) << p.err;
  const json r = json::parse(p.out);
  EXPECT_EQ(r.at("run").at("state"), "review");
  EXPECT_EQ(r.at("run").at("reason"), "gyro_M[0][0]: |Δ| = 90 ppm > 4σ bound 40 ppm");
}

TEST_F(StationctlLive, RefusalsExitWithThree) {
  serve(script_ending("done", "PASS", ""));
  const ProcStationctlReadonly p = ctl("run start --serial SIM-BUSY", live_target());
  EXPECT_EQ(p.code, 3) << p.err;
  EXPECT_NE(p.err.find("run 40 (SIM-0040) is running; one run at a time"), std::string::npos)
      << p.err;
  const ProcStationctlReadonly s = ctl("run start --serial SIM-0002", live_target());
  EXPECT_EQ(s.code, 0) << s.err;
  EXPECT_EQ(s.out, "run 41 started: SIM-0002, sequence short, 3 steps\n");
  const ProcStationctlReadonly r = ctl("reprocess 2", live_target());
  EXPECT_EQ(r.code, 0) << r.err;
  EXPECT_EQ(r.out, "run 42 reprocesses run 2\n");
  const ProcStationctlReadonly st = ctl("run status", live_target());
  EXPECT_EQ(st.code, 0) << st.err;
  EXPECT_NE(st.out.find("No active run."), std::string::npos) << st.out;
}

/// A run that never ends: for following and stopping to follow.
std::vector<json> endless() { return {live("running", "resting", 1, 99)}; }

// A daemon that stops answering and does not come back: one line when it stops, then exit 4 once
// --give-up-after has passed (issue #50 item 2; before, exit 4 at once with "stationd closed the
// connection").
TEST_F(StationctlLive, LosingTheDaemonWhileWaitingExitsFourWhenItDoesNotComeBack) {
  serve(endless());
  std::thread stopper([&] {
    std::this_thread::sleep_for(std::chrono::milliseconds(700));
    server_->stop();
  });
  const ProcStationctlReadonly p =
      ctl("run start --serial SIM-0001 --wait --give-up-after 2", live_target());
  stopper.join();
  EXPECT_EQ(p.code, 4) << p.err;
  EXPECT_NE(p.err.find("stationd stopped answering while following run 41"), std::string::npos)
      << p.err;
  EXPECT_NE(p.err.find("has not answered for"), std::string::npos) << p.err;
  EXPECT_NE(p.err.find("stationctl run status --run 41"), std::string::npos) << p.err;
}

TEST_F(StationctlLive, CtrlCStopsFollowingNotTheRun) {
  serve(endless());
  const std::string bin = std::string(IMUCAL_BIN_DIR) + "/stationctl";
  const std::string sock = dir_.file("live.sock"), err_file = dir_.file("sigint.err");
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, STDOUT_FILENO, "/dev/null", O_WRONLY, 0);
  posix_spawn_file_actions_addopen(&actions, STDERR_FILENO, err_file.c_str(),
                                   O_WRONLY | O_CREAT | O_TRUNC, 0644);
  std::vector<std::string> args = {bin,     "--socket", sock,       "run",
                                   "start", "--serial", "SIM-0001", "--wait"};
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  pid_t pid = 0;
  ASSERT_EQ(posix_spawn(&pid, bin.c_str(), &actions, nullptr, argv.data(), environ), 0);
  posix_spawn_file_actions_destroy(&actions);
  // Wait until it follows (its first progress line), then interrupt.
  for (int i = 0;
       i < 200 && slurp_stationctl_readonly(err_file).find("resting") == std::string::npos; ++i)
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  ::kill(pid, SIGINT);
  int status = 0;
  ASSERT_EQ(::waitpid(pid, &status, 0), pid);
  ASSERT_TRUE(WIFEXITED(status)) << "killed by the signal instead of handling it";
  EXPECT_EQ(WEXITSTATUS(status), 130);
  EXPECT_NE(slurp_stationctl_readonly(err_file).find("stopped following run 41; the run goes on"),
            std::string::npos)
      << slurp_stationctl_readonly(err_file);
}

}  // namespace
}  // namespace imucal
