// Bad input (issue #3): each a clear refusal, nothing written.
//   * malformed daemon config: stationd exits 2, the error names FILE:LINE, no database is created;
//   * unknown sequence, invalid serial number: stationctl exits 2 with a message that names the
//     sequence / states the serial rule, and no run is stored;
//   * malformed control-socket requests (garbage, wrong types, unknown commands, an over-long line):
//     error replies, and the daemon keeps serving this and other clients;
//   * a QA user (not in the control group) starting or aborting a run: refused (exit 3), nothing
//     written; reading still works for them.
#include <grp.h>
#include <sys/stat.h>

#include "db/history/serial_number.hpp"
#include "tests/e2e/station_harness.hpp"

namespace imucal::e2e {
namespace {

/// Replaces the line that starts with `key =` by `replacement`; returns its 1-based line number.
int replace_line(std::string& text, const std::string& key, const std::string& replacement) {
  std::istringstream in(text);
  std::ostringstream out;
  std::string line;
  int n = 0, found = 0;
  while (std::getline(in, line)) {
    ++n;
    if (!found && line.rfind(key + " =", 0) == 0) {
      found = n;
      out << replacement << "\n";
    } else {
      out << line << "\n";
    }
  }
  text = out.str();
  return found;
}

struct BadConfig {
  const char* what;
  const char* key;
  const char* replacement;
};

TEST(StationBadInput, MalformedConfigIsRefusedWithFileAndLineAndNoDatabaseIsCreated) {
  const std::vector<BadConfig> cases = {
      {"syntax error", "lat_deg", "lat_deg = = 55.0"},
      {"wrong type", "rate_hz", "rate_hz = \"fast\""},
      {"unknown key", "k_sigma", "k_sigma_typo = 4.0"},
      {"out of range", "lon_deg", "lon_deg = 1000.0"},
  };
  for (const auto& c : cases) {
    SCOPED_TRACE(c.what);
    Station st;
    std::string text = st.config_text();
    const int line = replace_line(text, c.key, c.replacement);
    ASSERT_GT(line, 0) << c.key;
    st.write_config(text);
    const CmdResult r = run_command({bin("stationd"), "--config", st.config_path()}, st.dir().path(), 20s);
    EXPECT_EQ(r.exit_code, 2) << r.describe();
    const std::string where = st.config_path() + ":" + std::to_string(line);
    EXPECT_NE(r.err.find(where), std::string::npos) << "the error does not name " << where << ":\n" << r.describe();
    EXPECT_FALSE(fs::exists(st.db_path())) << "a database was created for a bad config";
    EXPECT_FALSE(fs::exists(st.socket_path())) << "a socket was created for a bad config";
    // --check-config says the same.
    const CmdResult chk =
        run_command({bin("stationd"), "--config", st.config_path(), "--check-config"}, st.dir().path(), 20s);
    EXPECT_EQ(chk.exit_code, 2) << chk.describe();
    EXPECT_NE(chk.err.find(where), std::string::npos) << chk.describe();
  }
  // A missing config file: exit 2 naming it.
  Station st;
  const CmdResult r = run_command({bin("stationd"), "--config", st.path("nope.toml")}, st.dir().path(), 20s);
  EXPECT_EQ(r.exit_code, 2) << r.describe();
  EXPECT_NE(r.err.find("nope.toml"), std::string::npos) << r.describe();
  // The good config passes --check-config and still creates nothing.
  st.write_config(st.config_text());
  const CmdResult ok = run_command({bin("stationd"), "--config", st.config_path(), "--check-config"}, st.dir().path(), 20s);
  EXPECT_EQ(ok.exit_code, 0) << ok.describe();
  EXPECT_FALSE(fs::exists(st.db_path()));
}

/// Archive directories under data/runs whose name contains `serial`.
int archives_of(const Station& st, const std::string& serial) {
  int n = 0;
  std::error_code ec;
  for (const auto& e : fs::directory_iterator(st.data_dir() + "/runs", ec))
    if (e.path().filename().string().find(serial) != std::string::npos) ++n;
  return n;
}

TEST(StationBadInput, UnknownSequenceAndInvalidSerialAreRefusedAndNothingIsStored) {
  Station st;
  ASSERT_TRUE(st.start());
  // Unknown sequence.
  const CmdResult seq = st.ctl({"run", "start", "--serial", "SIM-0400", "--sequence", "no-such-sequence"});
  EXPECT_EQ(seq.exit_code, 2) << seq.describe();
  EXPECT_NE((seq.out + seq.err).find("no-such-sequence"), std::string::npos) << seq.describe();
  EXPECT_EQ(stored_run_count(st.db_path(), "SIM-0400"), 0);
  EXPECT_EQ(archives_of(st, "SIM-0400"), 0);
  const CmdResult hist = st.ctl({"--json", "history", "SIM-0400"});
  if (hist.exit_code == 0) {
    const json j = hist.json_out();
    EXPECT_TRUE(j.contains("runs") && j["runs"].empty()) << hist.describe();
  } else {
    EXPECT_EQ(hist.exit_code, 2) << "an unknown serial is bad input:\n" << hist.describe();
  }

  // Invalid serial numbers: each refused with the rule stated.
  const std::vector<std::string> bad_serials = {"bad serial", "SIM/0001", ".hidden", std::string(33, 'A'),
                                                "SIM-\u00c4\u00d6", ""};
  for (const std::string& bad : bad_serials) {
    SCOPED_TRACE("serial \"" + bad + "\"");
    const CmdResult r = st.ctl({"run", "start", "--serial", bad, "--sequence", "short"});
    EXPECT_EQ(r.exit_code, 2) << r.describe();
    const std::string msg = r.out + r.err;
    // The rule (db/history/serial_number.hpp): 1 to 32 characters, letters, digits, '-', '_', '.'.
    EXPECT_NE(msg.find("32"), std::string::npos) << "the length rule is not stated:\n" << r.describe();
    EXPECT_TRUE(contains_ci(msg, "letter") && contains_ci(msg, "digit")) << "the character rule is not stated:\n"
                                                                        << r.describe();
  }
  // The same through the socket, bypassing stationctl's own checks.
  const auto reply = st.request("run.start", {{"serial", "bad serial"}, {"sequence", "short"}});
  ASSERT_TRUE(reply) << "no reply";
  EXPECT_EQ((*reply)["ok"], json(false)) << reply->dump();
  EXPECT_EQ((*reply)["error"].value("code", ""), "invalid_input") << reply->dump();
  const auto reply_seq = st.request("run.start", {{"serial", "SIM-0401"}, {"sequence", "no-such-sequence"}});
  ASSERT_TRUE(reply_seq) << "no reply";
  EXPECT_EQ((*reply_seq)["error"].value("code", ""), "not_found") << reply_seq->dump();

  EXPECT_EQ(stored_run_total(st.db_path()), 0) << "a refused start stored a run";
  std::error_code ec;
  EXPECT_EQ(std::distance(fs::directory_iterator(st.data_dir() + "/runs", ec), fs::directory_iterator()), 0)
      << "a refused start left an archive directory";
  // Still idle and serving.
  const auto status = st.request("run.status");
  ASSERT_TRUE(status);
  EXPECT_EQ((*status)["result"].value("state", ""), "idle") << status->dump(2);
}

/// Operator names and reasons (issue #10): a newline would forge a log line or break the history
/// layout, thousands of characters bury it. stationctl refuses before connecting, the daemon
/// refuses what bypasses stationctl; nothing is stored either way.
TEST(StationBadInput, OperatorNamesAndReasonsWithControlCharactersOrTooLongAreRefused) {
  Station st;
  ASSERT_TRUE(st.start());
  const CmdResult forged =
      st.ctl({"run", "start", "--serial", "SIM-0410", "--sequence", "short", "--operator", "eve\n[info] run 1 PASS"});
  EXPECT_EQ(forged.exit_code, 2) << forged.describe();
  EXPECT_NE((forged.out + forged.err).find("control character U+000A"), std::string::npos) << forged.describe();
  const CmdResult longname =
      st.ctl({"run", "start", "--serial", "SIM-0410", "--sequence", "short", "--operator", std::string(3000, 'o')});
  EXPECT_EQ(longname.exit_code, 2) << longname.describe();
  EXPECT_NE((longname.out + longname.err).find("more than the limit of 64"), std::string::npos)
      << longname.describe();
  const CmdResult reason = st.ctl({"run", "abort", "--reason", std::string(5000, 'r')});
  EXPECT_EQ(reason.exit_code, 2) << reason.describe();
  EXPECT_NE((reason.out + reason.err).find("5000 characters"), std::string::npos) << reason.describe();
  // Straight through the socket.
  const auto reply =
      st.request("run.start", {{"serial", "SIM-0410"}, {"sequence", "short"}, {"operator", "a\x1b[2Jb"}});
  ASSERT_TRUE(reply);
  EXPECT_EQ((*reply)["error"].value("code", ""), "bad_request") << reply->dump();
  EXPECT_NE((*reply)["error"].value("message", "").find("args.operator"), std::string::npos) << reply->dump();
  EXPECT_EQ(stored_run_total(st.db_path()), 0) << "a refused start stored a run";
}

/// An error reply of code bad_request whose message names `field` (if given).
void expect_bad_request(const std::optional<json>& reply, const std::string& field, const std::string& sent) {
  ASSERT_TRUE(reply.has_value()) << "no reply to: " << sent;
  EXPECT_EQ((*reply)["ok"], json(false)) << sent << " -> " << reply->dump();
  ASSERT_TRUE((*reply)["error"].is_object()) << sent << " -> " << reply->dump();
  EXPECT_EQ((*reply)["error"].value("code", ""), "bad_request") << sent << " -> " << reply->dump();
  EXPECT_FALSE((*reply)["error"].value("message", "").empty()) << sent << " -> " << reply->dump();
  if (!field.empty()) {
    EXPECT_NE((*reply)["error"].value("message", "").find(field), std::string::npos)
        << "the message does not name '" << field << "': " << sent << " -> " << reply->dump();
  }
}

TEST(StationBadInput, MalformedSocketRequestsGetErrorRepliesAndTheDaemonKeepsServing) {
  Station st;
  ASSERT_TRUE(st.start());
  RawSocket bystander(st.socket_path());  // another client, connected throughout
  RawSocket s(st.socket_path());
  struct Case {
    std::string line;
    std::string field;
  };
  const std::vector<Case> cases = {
      {"this is not json", ""},
      {"{\"id\": 1, \"cmd\": \"history\", \"args\": {\"serial\": ", ""},  // truncated JSON
      {"[1, 2, 3]", ""},
      {"{\"id\": 2, \"args\": {}}", "cmd"},
      {"{\"id\": 3, \"cmd\": 42, \"args\": {}}", "cmd"},
      {"{\"id\": 4, \"cmd\": \"no.such.command\", \"args\": {}}", "no.such.command"},
      {"{\"id\": 5, \"cmd\": \"history\", \"args\": {\"serial\": 42}}", "serial"},
      {"{\"id\": 6, \"cmd\": \"show\", \"args\": {\"run_id\": \"seven\"}}", "run_id"},
      {"{\"id\": 7, \"cmd\": \"run.start\", \"args\": {\"serial\": [\"SIM-0402\"]}}", "serial"},
      {"{\"id\": 8, \"cmd\": \"run.start\", \"args\": {\"serial\": \"SIM-0402\", \"sequence\": 5}}", "sequence"},
      {"{\"id\": 9, \"cmd\": \"export\", \"args\": {\"format\": \"xml\"}}", "format"},
      {"{\"id\": 10, \"cmd\": \"history\", \"args\": \"SIM-0402\"}", "args"},
      {"{\"id\": 11, \"cmd\": \"history\", \"args\": {\"serial\": \"SIM-0402\", \"limit\": -1}}", "limit"},
      {std::string("{\"id\": 12, \"cmd\": \"ping\", \"args\": {}}") + "\x01\x02", ""},  // trailing bytes
  };
  for (const auto& c : cases) {
    ASSERT_TRUE(s.send_raw(c.line + "\n")) << "the daemon closed the connection before: " << c.line;
    expect_bad_request(s.reply(), c.field, c.line);
  }
  // After all that the same connection still works.
  auto pong = s.request({{"id", 100}, {"cmd", "ping"}, {"args", json::object()}});
  ASSERT_TRUE(pong) << "the connection died after bad requests";
  EXPECT_EQ((*pong)["ok"], json(true)) << pong->dump();
  EXPECT_EQ((*pong)["id"], json(100)) << pong->dump();
  EXPECT_TRUE((*pong)["result"].contains("version")) << pong->dump();
  auto other = bystander.request({{"id", 1}, {"cmd", "ping"}, {"args", json::object()}});
  ASSERT_TRUE(other) << "another client was disconnected by one client's bad requests";
  EXPECT_EQ((*other)["ok"], json(true));

  // A line over 1 MiB is refused (error reply or the connection closed), others are not affected.
  {
    RawSocket big(st.socket_path());
    const std::string huge = "{\"id\": 1, \"cmd\": \"ping\", \"args\": {\"pad\": \"" + std::string(1536 * 1024, 'x') +
                             "\"}}\n";
    big.send_raw(huge);  // may fail half-way if the daemon closes: that is a refusal too
    const auto reply = big.reply(10s);
    if (reply) {
      EXPECT_EQ((*reply)["ok"], json(false)) << reply->dump().substr(0, 300);
    }
  }
  // A client that sends half a line and disconnects.
  {
    RawSocket half(st.socket_path());
    half.send_raw("{\"id\": 1, \"cmd\": \"pi");
  }
  other = bystander.request({{"id", 2}, {"cmd", "ping"}, {"args", json::object()}});
  ASSERT_TRUE(other) << "the daemon stopped serving after an over-long line";
  EXPECT_EQ((*other)["ok"], json(true));
  EXPECT_TRUE(st.daemon().running()) << st.daemon_log();
  // stationctl still works, and nothing was stored.
  const CmdResult status = st.ctl({"run", "status"});
  EXPECT_EQ(status.exit_code, 0) << status.describe();
  EXPECT_EQ(stored_run_total(st.db_path()), 0);
}

TEST(StationBadInput, QaUserOutsideTheControlGroupCannotStartOrAbortRunsButCanRead) {
  ASSERT_EQ(geteuid(), 0u) << "this test drops to uid/gid 65534 (nobody) and needs root";
  Station st;
  ASSERT_TRUE(st.start());
  // A PASS run to read back.
  const CmdResult run = st.ctl({"run", "start", "--serial", "SIM-0501", "--sequence", "short", "--wait"}, 300s);
  ASSERT_EQ(run.exit_code, 0) << run.describe();
  // The default socket mode is 0660: owner and control group (here root's primary group) only.
  struct stat sock {};
  ASSERT_EQ(::stat(st.socket_path().c_str(), &sock), 0);
  EXPECT_EQ(sock.st_mode & 0777, 0660u);
  const RunAs qa{65534, 65534};
  const CmdResult start = st.ctl({"run", "start", "--serial", "SIM-0500", "--sequence", "short"}, 30s, qa);
  EXPECT_EQ(start.exit_code, 3) << start.describe();
  const std::string msg = start.out + start.err;
  EXPECT_TRUE(contains_ci(msg, "permission") && contains_ci(msg, "group")) << start.describe();
  EXPECT_EQ(stored_run_count(st.db_path(), "SIM-0500"), 0);
  EXPECT_EQ(archives_of(st, "SIM-0500"), 0);
  const CmdResult abort = st.ctl({"run", "abort"}, 30s, qa);
  EXPECT_EQ(abort.exit_code, 3) << abort.describe();
  const CmdResult rep = st.ctl({"reprocess", "1"}, 30s, qa);
  EXPECT_EQ(rep.exit_code, 3) << rep.describe();
  // Reading needs only read access to the database: stationctl reads it directly.
  const CmdResult hist = st.ctl({"--json", "history", "SIM-0501"}, 30s, qa);
  ASSERT_EQ(hist.exit_code, 0) << hist.describe();
  EXPECT_EQ(hist.json_out()["runs"].size(), 1u) << hist.describe();
  const CmdResult params = st.ctl({"params", "SIM-0501"}, 30s, qa);
  EXPECT_EQ(params.exit_code, 0) << params.describe();
  const auto idle = st.request("run.status");
  ASSERT_TRUE(idle);
  EXPECT_EQ((*idle)["result"].value("state", ""), "idle") << idle->dump(2);
  EXPECT_EQ(stored_run_total(st.db_path()), 1);
}

// A user inside the configured control group may start a run (accepted, stored with their name).
TEST(StationBadInput, AUserInTheControlGroupMayStartARun) {
  ASSERT_EQ(geteuid(), 0u) << "this test drops to uid/gid 65534 (nobody) and needs root";
  group* g = ::getgrgid(65534);
  ASSERT_NE(g, nullptr) << "gid 65534 has no group entry";
  Station st;
  ASSERT_TRUE(st.start_sim());
  std::string text = st.config_text();
  const auto at = text.find("[control]\n");
  ASSERT_NE(at, std::string::npos);
  text.insert(at + 10, "group = \"" + std::string(g->gr_name) + "\"\n");
  st.write_config(text);
  ASSERT_TRUE(st.start_daemon());
  struct stat sock {};
  ASSERT_EQ(::stat(st.socket_path().c_str(), &sock), 0);
  EXPECT_EQ(sock.st_gid, 65534u) << "the socket belongs to the control group";
  const RunAs member{65534, 65534};
  const CmdResult start =
      st.ctl({"run", "start", "--serial", "SIM-0502", "--sequence", "short", "--wait"}, 300s, member);
  EXPECT_EQ(start.exit_code, 0) << start.describe();
  const CmdResult show = st.ctl({"--json", "history", "SIM-0502"});
  ASSERT_EQ(show.exit_code, 0) << show.describe();
  ASSERT_EQ(show.json_out()["runs"].size(), 1u) << show.describe();
  EXPECT_EQ(show.json_out()["runs"][0].value("operator", ""), "nobody") << show.describe();
}

}  // namespace
}  // namespace imucal::e2e
