// Issue #24 end to end: stationd with a [fleet] store replicates every run through its outbox; the
// line goes on with the server down (status shows the outbox growing and the last error, without
// the password) and the outbox drains when it returns; stationctl reads the fleet store
// (--fleet URL) with bound filters only; `fleet resync` rebuilds the station's share and, after
// its database was replaced, keeps the old runs apart instead of refusing or deleting them; bad
// fleet settings are clear errors at --check-config and never stop the daemon.
#include <gtest/gtest.h>

#include "tests/e2e/station_harness.hpp"
#include "tests/support/pg_cluster.hpp"

namespace imucal::e2e {
namespace {

using test_support::PgCluster;

std::string fleet_section(const std::string& url, const std::string& password_file) {
  return "\n[fleet]\nurl = \"" + url + "\"\npassword_file = \"" + password_file + "\"\n";
}

CmdResult run_unit(Station& st, const std::string& serial) {
  return st.ctl(
      {"run", "start", "--serial", serial, "--sequence", "short", "--operator", "e2e", "--wait"},
      180s);
}

json fleet_status(const Station& st) {
  const auto r = st.request("run.status");
  if (!r || !r->value("ok", false)) return json();
  return (*r)["result"].value("fleet", json());
}

/// Polls the daemon's fleet status until `pred` holds (or 60 s); the last status seen.
template <typename P>
json wait_fleet(const Station& st, P pred) {
  json f;
  for (int i = 0; i < 600; ++i) {
    f = fleet_status(st);
    if (f.is_object() && pred(f)) return f;
    std::this_thread::sleep_for(100ms);
  }
  ADD_FAILURE() << "fleet status never reached the expected state; last: " << f.dump();
  return f;
}

TEST(StationFleet, RunsReplicateAndTheLineGoesOnWhileTheServerIsDown) {
  PgCluster pg;
  Station st;
  const std::string pw_file = st.path("fleet.pw");
  write_text(pw_file, std::string(PgCluster::kWriterPassword) + "\n");
  const std::string reader_pw = st.path("reader.pw");
  write_text(reader_pw, std::string(PgCluster::kReaderPassword) + "\n");
  ASSERT_TRUE(st.start_sim());
  st.write_config(st.config_text(fleet_section(pg.url("fleet_writer"), pw_file)));
  const CmdResult check =
      run_command({st.program("stationd"), "--config", st.config_path(), "--check-config"},
                  st.dir().path(), 30s);
  EXPECT_EQ(check.exit_code, 0) << check.out << check.err;
  EXPECT_NE(check.out.find("schema none yet"), std::string::npos) << check.out;
  // A password file others may read is named with its mode and the remedy (a warning: the check
  // still passes); once only its owner may, nothing is said.
  fs::permissions(pw_file, fs::perms::owner_read | fs::perms::owner_write | fs::perms::group_read);
  const CmdResult exposed =
      run_command({st.program("stationd"), "--config", st.config_path(), "--check-config"},
                  st.dir().path(), 30s);
  EXPECT_EQ(exposed.exit_code, 0) << exposed.err;
  EXPECT_NE(exposed.err.find("warning: fleet password_file " + pw_file + ": mode 0640"),
            std::string::npos)
      << exposed.err;
  EXPECT_NE(exposed.err.find("(chmod 600 " + pw_file + ")"), std::string::npos) << exposed.err;
  EXPECT_EQ(exposed.err.find(PgCluster::kWriterPassword), std::string::npos) << exposed.err;
  fs::permissions(pw_file, fs::perms::owner_read | fs::perms::owner_write);
  const CmdResult owner_only =
      run_command({st.program("stationd"), "--config", st.config_path(), "--check-config"},
                  st.dir().path(), 30s);
  EXPECT_EQ(owner_only.err.find("password_file"), std::string::npos) << owner_only.err;
  ASSERT_TRUE(st.start_daemon());

  ASSERT_EQ(run_unit(st, "FLT-1").exit_code, 0);
  wait_fleet(st, [](const json& f) { return f["outbox_length"] == 0 && f["connected"] == true; });
  const std::vector<std::string> fleet = {"--fleet", pg.url("fleet_reader"),
                                          "--fleet-password-file", reader_pw};
  auto fleet_ctl = [&](std::vector<std::string> args) {
    args.insert(args.begin(), fleet.begin(), fleet.end());
    return st.ctl(args);
  };
  CmdResult h = fleet_ctl({"--json", "history", "FLT-1"});
  ASSERT_EQ(h.exit_code, 0) << h.err;
  ASSERT_EQ(h.json_out()["runs"].size(), 1u);
  EXPECT_EQ(h.json_out()["runs"][0]["verdict"], "PASS");
  EXPECT_EQ(h.json_out()["runs"][0]["station"], "e2e-station");

  // The server goes away while the station is idle: its status says so without a run to send
  // (the sender's idle probe; before it, "connected" stayed true until the next run's changes).
  pg.kill9();
  const json idle_down = wait_fleet(st, [](const json& f) { return f["connected"] == false; });
  EXPECT_EQ(idle_down["outbox_length"], 0) << idle_down.dump();
  EXPECT_TRUE(idle_down["last_error"].is_string()) << idle_down.dump();
  // The next run still ends PASS, and its changes wait in the outbox.
  ASSERT_EQ(run_unit(st, "FLT-2").exit_code, 0) << st.daemon_log();
  const json down = wait_fleet(st, [](const json& f) {
    return f["outbox_length"].get<int>() > 0 && f["last_error"].is_string();
  });
  EXPECT_EQ(down["connected"], false);
  const CmdResult text = st.ctl({"run", "status"});
  EXPECT_NE(text.out.find("outbox"), std::string::npos) << text.out;
  pg.start();
  wait_fleet(st, [](const json& f) { return f["outbox_length"] == 0 && f["connected"] == true; });
  h = fleet_ctl({"--json", "history", "FLT-2"});
  ASSERT_EQ(h.exit_code, 0) << h.err;
  EXPECT_EQ(h.json_out()["runs"][0]["verdict"], "PASS");

  // The same output formats as the station's own reads.
  const CmdResult local_params = st.ctl({"--json", "params", "FLT-2"});
  const CmdResult fleet_params = fleet_ctl({"--json", "params", "FLT-2"});
  ASSERT_EQ(fleet_params.exit_code, 0) << fleet_params.err;
  json a = local_params.json_out(), b = fleet_params.json_out();
  a["source"].erase("run_id");
  b["source"].erase("run_id");
  EXPECT_EQ(a, b);
  const CmdResult local_csv = st.ctl({"export", "--format", "csv", "--serial", "FLT-1"});
  const CmdResult fleet_csv =
      fleet_ctl({"export", "--format", "csv", "--serial", "FLT-1", "--station", "e2e-station"});
  ASSERT_EQ(fleet_csv.exit_code, 0) << fleet_csv.err;
  // Identical but for the run id column (the store's own ids).
  EXPECT_EQ(std::count(local_csv.out.begin(), local_csv.out.end(), '\n'),
            std::count(fleet_csv.out.begin(), fleet_csv.out.end(), '\n'));
  EXPECT_EQ(local_csv.out.substr(0, local_csv.out.find('\n')),
            fleet_csv.out.substr(0, fleet_csv.out.find('\n')));

  // Filters are bound values: quotes and semicolons reach the server as data.
  const std::string evil = "x'; DROP TABLE runs; --";
  const CmdResult e1 = fleet_ctl({"--json", "history", "--station", evil});
  EXPECT_EQ(e1.exit_code, 0) << e1.err;
  EXPECT_EQ(e1.json_out()["runs"].size(), 0u);
  const CmdResult e2 = fleet_ctl({"export", "--format", "csv", "--station", evil});
  EXPECT_EQ(e2.exit_code, 0) << e2.err;
  EXPECT_EQ(fleet_ctl({"history", "FLT'; DROP TABLE runs; --"}).exit_code, 2);
  EXPECT_EQ(pg.admin("SELECT count(*) FROM runs", "fleet"), "2\n");

  // resync rebuilds the station's share after the store lost it.
  pg.admin("DELETE FROM runs", "fleet");
  const CmdResult rs = st.ctl({"--json", "fleet", "resync"});
  ASSERT_EQ(rs.exit_code, 0) << rs.err;
  EXPECT_EQ(rs.json_out()["written"], 2);
  EXPECT_EQ(pg.admin("SELECT count(*) FROM runs", "fleet"), "2\n");
  const CmdResult stations = fleet_ctl({"--json", "stations"});
  ASSERT_EQ(stations.exit_code, 0) << stations.err;
  EXPECT_EQ(stations.json_out()["stations"][0]["runs"], 2);

  // The password never appears: not in the log, the status, nor any error.
  for (const std::string& text : {st.daemon_log(), text.out, fleet_status(st).dump()}) {
    EXPECT_EQ(text.find(PgCluster::kWriterPassword), std::string::npos);
    EXPECT_EQ(text.find(PgCluster::kReaderPassword), std::string::npos);
  }

  // The history database is replaced while the data directory keeps the archives (a restore, a
  // new file): the new database numbers its runs after the archives, so the next run neither meets
  // an old archive directory nor an old local id in the store. It is delivered as any run.
  auto move_aside = [&](const std::string& path, const std::string& to) {
    for (const char* suffix : {"", "-wal", "-shm"})
      if (fs::exists(path + suffix)) fs::rename(path + suffix, to + suffix);
  };
  st.daemon().terminate(10s);
  move_aside(st.db_path(), st.db_path() + ".restored-over");
  ASSERT_TRUE(st.start_daemon());
  EXPECT_NE(st.daemon_log().find("New runs are numbered from 3"), std::string::npos)
      << st.daemon_log();
  const CmdResult third = run_unit(st, "FLT-3");
  ASSERT_EQ(third.exit_code, 0) << third.err << st.daemon_log();
  EXPECT_NE(third.out.find("run 3 "), std::string::npos) << third.out;
  wait_fleet(st, [](const json& f) { return f["outbox_length"] == 0; });
  EXPECT_EQ(pg.admin("SELECT count(*) FROM runs", "fleet"), "3\n");

  // The station's disk is replaced: a new, empty history and no archives, whose run ids restart
  // at 1. Its first run still ends PASS; the store refuses it (the old run 1 is another run) and
  // the status names the way out. Resync sets the old runs apart, kept, and the outbox drains.
  st.daemon().terminate(10s);
  move_aside(st.db_path(), st.db_path() + ".replaced");
  fs::rename(st.data_dir() + "/runs", st.data_dir() + "/runs.replaced");
  ASSERT_TRUE(st.start_daemon());
  ASSERT_EQ(run_unit(st, "FLT-4").exit_code, 0) << st.daemon_log();
  const json refused = wait_fleet(st, [](const json& f) {
    return f["last_error"].is_string() &&
           f["last_error"].get<std::string>().find("fleet resync") != std::string::npos;
  });
  EXPECT_GT(refused["outbox_length"].get<int>(), 0) << refused.dump();
  const CmdResult apart = st.ctl({"--json", "fleet", "resync"});
  ASSERT_EQ(apart.exit_code, 0) << apart.err;
  EXPECT_EQ(apart.json_out()["set_apart"], 3);
  const std::string apart_id = apart.json_out()["set_apart_as"].get<std::string>();
  EXPECT_EQ(apart_id.rfind("e2e-station.previous-", 0), 0u) << apart_id;
  EXPECT_EQ(apart.json_out()["written"], 1);
  wait_fleet(st, [](const json& f) { return f["outbox_length"] == 0; });
  EXPECT_EQ(pg.admin("SELECT count(*) FROM runs", "fleet"), "4\n") << "nothing deleted";
  const CmdResult old_unit = fleet_ctl({"--json", "history", "FLT-1"});
  ASSERT_EQ(old_unit.exit_code, 0) << old_unit.err;
  EXPECT_EQ(old_unit.json_out()["runs"].size(), 1u) << "the old disk's record is still there";
  const CmdResult both = fleet_ctl({"--json", "stations"});
  ASSERT_EQ(both.exit_code, 0) << both.err;
  EXPECT_EQ(both.json_out()["stations"].size(), 2u) << both.out;
  // `history --station` shows N of that station's runs, not of the whole store's four.
  const CmdResult mine = fleet_ctl({"--json", "history", "--station", "e2e-station"});
  ASSERT_EQ(mine.exit_code, 0) << mine.err;
  EXPECT_EQ(mine.json_out()["runs"].size(), 1u) << mine.out;
  EXPECT_EQ(mine.json_out()["total"], 1) << mine.out;
  const CmdResult theirs = fleet_ctl({"--json", "history", "--station", apart_id, "FLT-1"});
  ASSERT_EQ(theirs.exit_code, 0) << theirs.err;
  EXPECT_EQ(theirs.json_out()["total"], 1) << theirs.out;
}

TEST(StationFleet, BadFleetSettingsAreClearAtCheckConfigAndNeverStopTheLine) {
  PgCluster pg;
  Station st;
  const std::string pw_file = st.path("fleet.pw");
  write_text(pw_file, std::string(PgCluster::kWriterPassword) + "\n");
  auto check = [&](const std::string& fleet) {
    st.write_config(st.config_text(fleet));
    return run_command({st.program("stationd"), "--config", st.config_path(), "--check-config"},
                       st.dir().path(), 30s);
  };
  // A malformed URL is bad input in the file: named with its line, exit 2.
  CmdResult r = check("\n[fleet]\nurl = \"postgresql://u@h:99999/db\"\n");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("[fleet] url"), std::string::npos) << r.err;
  r = check("\n[fleet]\nurl = \"postgresql://u@127.0.0.1/db\"\nstation_id = \"a b\"\n");
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("station_id"), std::string::npos) << r.err;
  // Unreachable, wrong password, expired credentials, a schema from the future: exit 1, clear.
  const std::string dead =
      "postgresql://fleet_writer@127.0.0.1:" + std::to_string(test_support::free_tcp_port()) +
      "/fleet";
  r = check(fleet_section(dead, pw_file));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("cannot connect"), std::string::npos) << r.err;
  const std::string wrong_pw = st.path("wrong.pw");
  write_text(wrong_pw, "N0tThePassw0rd\n");
  r = check(fleet_section(pg.url("fleet_writer"), wrong_pw));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("password authentication failed"), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find("N0tThePassw0rd"), std::string::npos) << r.err;
  pg.admin("ALTER ROLE fleet_writer VALID UNTIL '2001-01-01'");
  r = check(fleet_section(pg.url("fleet_writer"), pw_file));
  EXPECT_EQ(r.exit_code, 1) << r.out;
  pg.admin("ALTER ROLE fleet_writer VALID UNTIL 'infinity'");
  pg.admin(
      "CREATE TABLE fleet_schema_version (version integer PRIMARY KEY, description text, "
      "applied_at timestamptz DEFAULT now()); INSERT INTO fleet_schema_version VALUES (99, "
      "'future'); ALTER TABLE fleet_schema_version OWNER TO fleet_writer",
      "fleet");
  r = check(fleet_section(pg.url("fleet_writer"), pw_file));
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_NE(r.err.find("schema version 99"), std::string::npos) << r.err;

  // The daemon starts anyway and runs; status says what is wrong.
  ASSERT_TRUE(st.start_sim());
  st.write_config(st.config_text(fleet_section(pg.url("fleet_writer"), pw_file)));
  ASSERT_TRUE(st.start_daemon());
  ASSERT_EQ(run_unit(st, "FLT-9").exit_code, 0);
  const json f = wait_fleet(st, [](const json& s) {
    return s["last_error"].is_string() && s["outbox_length"].get<int>() > 0;
  });
  EXPECT_NE(f["last_error"].get<std::string>().find("schema version 99"), std::string::npos)
      << f.dump();
}

}  // namespace
}  // namespace imucal::e2e
