// End to end (issue #9 item 6): field runs in the station's history. `imucal simulate --setting
// land|sea` writes a field archive; `stationctl import` (real stationd and stationctl processes,
// a real SQLite file) stores it under its serial with its setting and calibrates it as the setting
// allows; history, show and export show the setting; the unit's active parameters stay the
// latest factory PASS until QA promotes a field run, which is recorded with who and why. A bad
// archive is refused with the file named and nothing stored; a user outside the control group
// cannot import.
#include <gtest/gtest.h>
#include <unistd.h>

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
  const json& lr = runs[0];  // newest first
  EXPECT_EQ(lr.value("setting", ""), "land") << lr.dump(2);
  EXPECT_EQ(lr.value("state", ""), "done") << lr.dump(2);  // AINS and legacy agree
  EXPECT_EQ(lr.value("verdict", ""), "PASS") << lr.dump(2);
  EXPECT_NE(lr.value("origin", "").find(land), std::string::npos) << lr.dump(2);
  EXPECT_EQ(runs[1].value("setting", ""), "factory");
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
  const json rec = st.ctl({"show", std::to_string(land_id), "--json"}).json_out()["run"];
  EXPECT_EQ(rec.value("promote_reason", ""), "recalibrated at the customer") << rec.dump(2);
  EXPECT_FALSE(rec.value("promoted_by", "").empty()) << rec.dump(2);
  // A factory run cannot be promoted.
  const CmdResult bad_prom =
      st.ctl({"promote", std::to_string(runs[1].value("run_id", -1LL)), "--reason", "x"});
  EXPECT_NE(bad_prom.exit_code, 0) << bad_prom.describe();
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
