// End to end (issue #9 item 6): field runs in the station's history. `imucal simulate --setting
// land|sea` writes a field archive; `stationctl import` (real stationd and stationctl processes,
// a real SQLite file) stores it under its serial with its setting and calibrates it as the setting
// allows; history, show and export show the setting; the unit's active parameters stay the
// latest factory PASS until QA promotes a field run, which is recorded with who and why. A bad
// archive is refused with the file named and nothing stored; a user outside the control group
// cannot import.
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <string>

#include "tests/e2e/station_harness.hpp"

namespace imucal::e2e {
namespace {

CmdResult imucal(const Station& st, const std::vector<std::string>& args) {
  std::vector<std::string> argv = {bin("imucal")};
  argv.insert(argv.end(), args.begin(), args.end());
  return run_command(argv, st.dir().path(), 120s);
}

TEST(StationImport, FieldRunsJoinTheHistoryWithTheirSettingAndBecomeActiveOnlyWhenPromoted) {
  Station st;
  ASSERT_TRUE(st.start());
  // A factory run of the unit first: its PASS is the active set.
  const CmdResult run = st.ctl(
      {"run", "start", "--serial", "SIM-7", "--sequence", "short", "--operator", "e2e", "--wait"},
      180s);
  ASSERT_EQ(run.exit_code, 0) << run.describe() << "\n" << st.daemon_log();
  const json factory_params = st.ctl({"params", "SIM-7", "--json"}).json_out();

  // A land archive of the same unit (imucal simulate names simulated units SIM-<seed>).
  const std::string land = st.dir() / "land-SIM-7";
  ASSERT_EQ(imucal(st, {"simulate", "--sequence", "short", "--setting", "land", "--seed", "7",
                        "--out", land})
                .exit_code,
            0);
  const CmdResult imp = st.ctl({"import", land, "--wait"}, 120s);
  EXPECT_EQ(imp.exit_code, 0) << imp.describe() << "\n" << st.daemon_log();

  const CmdResult hist = st.ctl({"history", "SIM-7", "--json"});
  ASSERT_EQ(hist.exit_code, 0) << hist.describe();
  const json runs = hist.json_out()["runs"];
  ASSERT_EQ(runs.size(), 2u) << runs.dump(2);
  // History is by recorded start time: the simulated land recording (minutes long, ended just
  // before the import) started before the factory run on the fast simulator.
  const std::size_t land_at = runs[0].value("setting", "") == "land" ? 0 : 1;
  const json& lr = runs[land_at];
  const json& fr = runs[1 - land_at];
  EXPECT_EQ(lr.value("setting", ""), "land") << lr.dump(2);
  EXPECT_EQ(lr.value("state", ""), "done") << lr.dump(2);  // AINS and legacy agree
  EXPECT_EQ(lr.value("verdict", ""), "PASS") << lr.dump(2);
  EXPECT_NE(lr.value("origin", "").find(land), std::string::npos) << lr.dump(2);
  EXPECT_EQ(fr.value("setting", ""), "factory");
  const long long land_id = lr.value("run_id", -1LL);
  // The station keeps its own copy of the archive.
  EXPECT_EQ(lr.value("archive_path", "").rfind(st.data_dir(), 0), 0u) << lr.dump(2);

  // The human history has the SETTING column; show names the methods (AINS and legacy).
  const CmdResult text = st.ctl({"history", "SIM-7"});
  EXPECT_NE(text.out.find("SETTING"), std::string::npos) << text.out;
  EXPECT_NE(text.out.find("land"), std::string::npos) << text.out;
  const json show = st.ctl({"show", std::to_string(land_id), "--json"}).json_out();
  ASSERT_EQ(show["calibrations"].size(), 2u) << show.dump(2);
  EXPECT_EQ(show["calibrations"][1].value("method", ""), "legacy") << show.dump(2);

  // Export carries the setting.
  const CmdResult csv = st.ctl({"export", "--serial", "SIM-7", "--format", "csv"});
  ASSERT_EQ(csv.exit_code, 0) << csv.describe();
  EXPECT_NE(csv.out.find(",setting,origin,promoted_at,promoted_by,promote_reason,"),
            std::string::npos)
      << csv.out.substr(0, 400);
  EXPECT_NE(csv.out.find(",land,imported from "), std::string::npos);

  // A field PASS does not replace the factory set ...
  EXPECT_EQ(st.ctl({"params", "SIM-7", "--json"}).json_out(), factory_params);
  // ... until QA promotes it; then it does, and the record says who and why.
  const CmdResult prom =
      st.ctl({"promote", std::to_string(land_id), "--reason", "recalibrated at the customer"});
  ASSERT_EQ(prom.exit_code, 0) << prom.describe();
  const json after = st.ctl({"params", "SIM-7", "--json"}).json_out();
  EXPECT_NE(after, factory_params);
  EXPECT_EQ(after.at("source").value("run_id", -1LL), land_id) << after.dump(2);
  EXPECT_EQ(factory_params.at("source").value("run_id", -1LL), fr.value("run_id", -1LL));
  const json rec = st.ctl({"show", std::to_string(land_id), "--json"}).json_out()["run"];
  EXPECT_EQ(rec.value("promote_reason", ""), "recalibrated at the customer") << rec.dump(2);
  EXPECT_FALSE(rec.value("promoted_by", "").empty()) << rec.dump(2);
  // A factory run of this station cannot be promoted.
  const CmdResult bad_prom =
      st.ctl({"promote", std::to_string(fr.value("run_id", -1LL)), "--reason", "x"});
  EXPECT_NE(bad_prom.exit_code, 0) << bad_prom.describe();
}

// Issue #48 item 7, through the real station: IMU-TK's Xsens recording (tests/data/imu_tk_xsens,
// a real MEMS unit turned by hand) imported as `imucal import` reads it, then `stationctl import`.
// On it land AINS cannot hold the rests as the legacy fit does: the run is done on the legacy fit's
// own limits, `show` says which method holds and why, and once QA promotes it the unit's active
// set is the legacy result — the same parameters `imucal calibrate --method legacy` gives.
TEST(StationImport, AMemsLandRunOnWhichAinsCannotHoldTheRestsIsActiveOnLegacy) {
  Station st;
  ASSERT_TRUE(st.start());
  const std::string data = std::string(IMUCAL_SOURCE_DIR) + "/tests/data/imu_tk_xsens/";
  for (const char* f : {"xsens_gyro.mat", "xsens_acc.mat"})
    ASSERT_EQ(std::system(("xz -dc '" + data + f + ".xz' > '" + (st.dir() / f) + "'").c_str()), 0);
  const std::string land = st.dir() / "xsens";
  const CmdResult imp0 =
      imucal(st, {"import", "--config", data + "import.toml", "--gyro", st.dir() / "xsens_gyro.mat",
                  "--accel", st.dir() / "xsens_acc.mat", "--out", land});
  ASSERT_EQ(imp0.exit_code, 0) << imp0.describe();
  const CmdResult legacy = imucal(st, {"calibrate", land, "--method", "legacy", "--json"});
  ASSERT_EQ(legacy.exit_code, 0) << legacy.describe();
  const json legacy_params = legacy.json_out().at("legacy").at("params");

  const CmdResult imp = st.ctl({"import", land, "--wait"}, 120s);
  EXPECT_EQ(imp.exit_code, 0) << imp.describe() << "\n" << st.daemon_log();
  const json runs = st.ctl({"history", "XSENS-IMUTK", "--json"}).json_out()["runs"];
  ASSERT_EQ(runs.size(), 1u) << runs.dump(2);
  const long long id = runs[0].value("run_id", -1LL);
  EXPECT_EQ(runs[0].value("verdict", ""), "PASS") << runs[0].dump(2);
  const json show = st.ctl({"show", std::to_string(id), "--json"}).json_out();
  const json& run = show.at("run");
  EXPECT_EQ(run.value("holding_method", ""), "legacy") << run.dump(2);
  const std::string why = run.value("holding_reason", "");
  EXPECT_NE(why.find("AINS leaves"), std::string::npos) << why;
  EXPECT_NE(why.find("rest on legacy"), std::string::npos) << why;
  const CmdResult text = st.ctl({"show", std::to_string(id)});
  EXPECT_NE(text.out.find("holds        legacy: AINS leaves"), std::string::npos) << text.out;

  ASSERT_EQ(
      st.ctl({"promote", std::to_string(id), "--reason", "hand-placed MEMS calibration"}).exit_code,
      0);
  const json params = st.ctl({"params", "XSENS-IMUTK", "--json"}).json_out();
  EXPECT_EQ(params.at("source").value("method", ""), "legacy") << params.dump(2);
  EXPECT_EQ(params.at("source").value("holding_reason", ""), why);
  for (const char* key : {"accel_bias_mps2", "accel_M", "gyro_bias_radps", "gyro_M"})
    EXPECT_EQ(params.at(key), legacy_params.at(key)) << key;
}

/// Sets run.toml's start_time and end_time of an archive directory.
void set_recorded_times(const std::string& dir, const std::string& start, const std::string& end) {
  const std::string path = dir + "/run.toml";
  std::string toml = read_text(path);
  for (const auto& [key, value] :
       {std::pair{std::string("start_time"), start}, {"end_time", end}}) {
    const std::size_t at = toml.find(key + " = ");
    ASSERT_NE(at, std::string::npos) << key << " missing in\n" << toml;
    const std::size_t eol = toml.find('\n', at);
    toml.replace(at, eol - at, key + " = \"" + value + "\"");
  }
  write_text(path, toml);
}

// Issue #19 item 3: an imported factory archive became active at once, a second import of the same
// archive made a duplicate run, the run's start was the import time and its duration "1 s", and
// `params` did not say which run its set came from.
TEST(StationImport, AnImportKeepsItsTimesIsActiveOnlyWhenPromotedAndIsNeverStoredTwice) {
  Station st;
  ASSERT_TRUE(st.start());
  const std::string factory = st.dir() / "factory-SIM-10";
  ASSERT_EQ(
      imucal(st, {"simulate", "--sequence", "short", "--seed", "10", "--out", factory}).exit_code,
      0);
  set_recorded_times(factory, "2026-03-02T08:15:00Z", "2026-03-02T08:36:40Z");
  const CmdResult imp = st.ctl({"import", factory, "--wait"}, 180s);
  ASSERT_EQ(imp.exit_code, 0) << imp.describe() << "\n" << st.daemon_log();
  const json runs = st.ctl({"history", "SIM-10", "--json"}).json_out()["runs"];
  ASSERT_EQ(runs.size(), 1u);
  const json& run = runs[0];
  const long long id = run.value("run_id", -1LL);
  EXPECT_EQ(run.value("verdict", ""), "PASS") << run.dump(2);
  EXPECT_EQ(run.value("started_at", ""), "2026-03-02T08:15:00.000Z") << run.dump(2);
  EXPECT_EQ(run.value("ended_at", ""), "2026-03-02T08:36:40.000Z") << run.dump(2);
  EXPECT_EQ(run.value("origin", "").rfind("imported from " + factory + " on ", 0), 0u)
      << run.dump(2);
  EXPECT_NE(st.ctl({"history", "SIM-10"}).out.find("21 min 40 s"), std::string::npos);

  // Not active until promoted, whatever its verdict ("never becomes active unless promoted").
  const CmdResult before = st.ctl({"params", "SIM-10"});
  EXPECT_NE(before.exit_code, 0) << "an imported archive became active:\n" << before.describe();
  EXPECT_NE((before.out + before.err).find("none promoted"), std::string::npos)
      << before.describe();

  // The same archive again: refused, naming the run that holds it; nothing stored or left behind.
  const CmdResult again = st.ctl({"import", factory, "--wait"}, 60s);
  EXPECT_NE(again.exit_code, 0) << again.describe();
  EXPECT_NE((again.out + again.err).find("already stored as run " + std::to_string(id)),
            std::string::npos)
      << again.describe();
  EXPECT_EQ(st.ctl({"history", "SIM-10", "--json"}).json_out()["runs"].size(), 1u);
  for (const auto& e : std::filesystem::directory_iterator(st.data_dir() + "/runs"))
    EXPECT_EQ(e.path().filename().string().rfind(".import-", 0), std::string::npos) << e.path();
  // ... and so is the station's own copy of it.
  const CmdResult copy = st.ctl({"import", run.value("archive_path", ""), "--wait"}, 60s);
  EXPECT_NE((copy.out + copy.err).find("already stored as run " + std::to_string(id)),
            std::string::npos)
      << copy.describe();

  // Promoted, it is active, and params names the run, in JSON and in text.
  ASSERT_EQ(
      st.ctl({"promote", std::to_string(id), "--reason", "golden unit from line 2"}).exit_code, 0);
  const CmdResult params = st.ctl({"params", "SIM-10", "--json"});
  ASSERT_EQ(params.exit_code, 0) << params.describe();
  const json source = params.json_out().at("source");
  EXPECT_EQ(source.value("run_id", -1LL), id) << source.dump(2);
  EXPECT_EQ(source.value("method", ""), "ains");
  EXPECT_EQ(source.value("promote_reason", ""), "golden unit from line 2");
  EXPECT_NE(source.value("origin", "").find(factory), std::string::npos);
  const CmdResult text = st.ctl({"params", "SIM-10"});
  EXPECT_NE(text.out.find("\"run_id\": " + std::to_string(id)), std::string::npos) << text.out;
  const json bare = st.ctl({"params", "SIM-10", "--json", "--bare"}).json_out();
  EXPECT_FALSE(bare.contains("source")) << bare.dump(2);
  EXPECT_EQ(bare.size(), 6u) << "the five schema keys and sigma";
  // What params prints still loads as a parameter set (imucal evaluate --params reads it).
  write_text(st.dir() / "active.json", text.out);
  const CmdResult check =
      imucal(st, {"evaluate", factory, "--params", st.dir() / "active.json", "--json"});
  EXPECT_EQ(check.exit_code, 0) << check.describe();
}

TEST(StationImport, SeaRunIsReviewedForHavingAinsAloneAndBadArchivesAreRefused) {
  Station st;
  ASSERT_TRUE(st.start());
  const std::string sea = st.dir() / "sea-SIM-8";
  ASSERT_EQ(imucal(st, {"simulate", "--sequence", "short", "--setting", "sea", "--seed", "8",
                        "--out", sea})
                .exit_code,
            0);
  const CmdResult imp = st.ctl({"import", sea, "--wait"}, 120s);
  const json runs = st.ctl({"history", "SIM-8", "--json"}).json_out()["runs"];
  ASSERT_EQ(runs.size(), 1u) << imp.describe() << "\n" << st.daemon_log();
  EXPECT_EQ(runs[0].value("setting", ""), "sea");
  EXPECT_EQ(runs[0].value("state", ""), "review");
  EXPECT_NE(runs[0].value("failure_reason", "").find("AINS alone"), std::string::npos)
      << runs[0].dump(2);

  // A sea archive without its GNSS fixes: refused, the file named, nothing stored.
  std::filesystem::remove(std::filesystem::path(sea) / "gnss.csv");
  const CmdResult bad = st.ctl({"import", sea});
  EXPECT_NE(bad.exit_code, 0) << bad.describe();
  EXPECT_NE((bad.out + bad.err).find("gnss.csv"), std::string::npos) << bad.describe();
  EXPECT_EQ(st.ctl({"history", "SIM-8", "--json"}).json_out()["runs"].size(), 1u);
  const CmdResult missing = st.ctl({"import", st.dir() / "no-such-dir"});
  EXPECT_NE(missing.exit_code, 0);
  EXPECT_NE((missing.out + missing.err).find("no such run archive directory"), std::string::npos)
      << missing.describe();
}

TEST(StationImport, UserOutsideTheControlGroupCannotImportOrPromote) {
  if (geteuid() != 0) GTEST_SKIP() << "needs root to drop to uid 65534";
  Station st;
  ASSERT_TRUE(st.start());
  const std::string land = st.dir() / "land-SIM-9";
  ASSERT_EQ(imucal(st, {"simulate", "--sequence", "short", "--setting", "land", "--seed", "9",
                        "--out", land})
                .exit_code,
            0);
  std::filesystem::permissions(st.dir().path(), std::filesystem::perms::all,
                               std::filesystem::perm_options::add);
  const RunAs qa{65534, 65534};
  const CmdResult imp = st.ctl({"import", land}, 30s, qa);
  EXPECT_EQ(imp.exit_code, 3) << imp.describe();
  const CmdResult prom = st.ctl({"promote", "1", "--reason", "x"}, 30s, qa);
  EXPECT_EQ(prom.exit_code, 3) << prom.describe();
  // Nothing stored: the serial is unknown to the history.
  const CmdResult h = st.ctl({"history", "SIM-9", "--json"});
  EXPECT_NE(h.exit_code, 0) << h.describe();
  EXPECT_NE((h.out + h.err).find("SIM-9"), std::string::npos) << h.describe();
}

}  // namespace
}  // namespace imucal::e2e
