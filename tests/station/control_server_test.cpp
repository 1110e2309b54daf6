// The control server (station/control/control_server.hpp) over a real Unix socket, with a fake
// ControlHandler that counts its calls and a real SQLite history in a temporary directory:
// dispatch, reads identical to the repository's answer, malformed and oversize lines isolated to
// their client, many concurrent clients, peer-credential permission (a forked child running as
// nobody), error-code mapping and socket file handling.
#include "station/control/control_server.hpp"

#include <grp.h>
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "db/history/sqlite_repository.hpp"
#include "station/control/control_client.hpp"
#include "station/control/record_json.hpp"
#include "tests/db/history_fixtures.hpp"

namespace imucal::station {
using namespace imucal::station::control;
namespace {

using nlohmann::json;
using namespace std::chrono_literals;

constexpr uid_t kNobodyUid = 65534;
constexpr gid_t kNogroupGid = 65534;

class FakeHandler : public ControlHandler {
 public:
  explicit FakeHandler(const db::history::Repository& repo) : repo_(repo) {}

  json start_run(const StartRunRequest& r) override {
    enter();
    ++start_calls;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      last_start_ = r;
    }
    leave();
    if (r.serial == "BUSY-1") throw ControlError(error_code::kBusy, "run 4 is active (SIM-0004)");
    if (r.serial == "BAD") throw db::history::InvalidInput("serial number \"BAD\" is reserved");
    if (r.serial == "BOOM") throw std::runtime_error("division by zero in the fake");
    if (r.sequence && *r.sequence == "nope")
      throw db::history::NotFound("sequence \"nope\": not in the library");
    return {{"run_id", 77},
            {"serial", r.serial},
            {"sequence", r.sequence.value_or("short")},
            {"steps", 18}};
  }
  json status(std::optional<db::history::RunId> run_id) override {
    enter();
    ++status_calls;
    // Long enough that two overlapping calls would be seen.
    std::this_thread::sleep_for(200us);
    leave();
    if (run_id) return {{"run", {{"run_id", *run_id}, {"state", "running"}}}};
    return {{"state", "idle"}, {"run", nullptr}, {"last_run", nullptr}};
  }
  json abort_run(const std::string& reason) override {
    ++abort_calls;
    std::lock_guard<std::mutex> lock(mutex_);
    last_reason_ = reason;
    return {{"run_id", 77}};
  }
  json diagnose(db::history::RunId run_id) override {
    return {{"run_id", run_id}, {"verdict", "consistent"}};
  }
  json reprocess(const ReprocessRequest& q) override {
    ++reprocess_calls;
    std::lock_guard<std::mutex> lock(mutex_);
    last_reprocess_ = q;
    return {{"run_id", 78}, {"reprocessed_from", q.run_id}};
  }
  const db::history::Repository& repository() const override { return repo_; }

  std::atomic<int> start_calls{0}, status_calls{0}, abort_calls{0}, reprocess_calls{0};
  std::atomic<int> overlaps{0};
  // What the server handed over, read under the lock the server thread wrote it with (a reply
  // that went through a forked client is no happens-before edge a race detector can see).
  StartRunRequest last_start() {
    std::lock_guard<std::mutex> lock(mutex_);
    return last_start_;
  }
  ReprocessRequest last_reprocess() {
    std::lock_guard<std::mutex> lock(mutex_);
    return last_reprocess_;
  }
  std::string last_reason() {
    std::lock_guard<std::mutex> lock(mutex_);
    return last_reason_;
  }

 private:
  StartRunRequest last_start_;
  ReprocessRequest last_reprocess_;
  std::string last_reason_;
  void enter() {
    if (in_call_.exchange(true)) ++overlaps;
  }
  void leave() { in_call_ = false; }
  const db::history::Repository& repo_;
  std::atomic<bool> in_call_{false};
  std::mutex mutex_;
};

class ControlServerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // nobody must be able to reach the socket inside the temp dir: these tests are about the
    // protocol's own permission check, so the socket admits everyone (0666, not the default).
    ::chmod(dir_.path().c_str(), 0755);
    repo_ = std::make_unique<db::history::SqliteRepository>(dir_.file("history.sqlite"));
    const db::history::TimestampMs t0 = db::history::parse_time_utc("2024-05-01T10:00:00Z");
    for (int k = 0; k < 3; ++k) {
      const db::history::RunId id =
          repo_->create_run(db::test::new_run("SIM-0001", t0 + k * 3600000));
      repo_->finish_run(id, db::test::pass_completion(k + 1, t0 + k * 3600000 + 60000));
    }
    handler_ = std::make_unique<FakeHandler>(*repo_);
    ControlServerOptions o;
    o.socket_path = socket_path();
    o.version = "9.8.7-test";
    o.socket_mode = 0666;
    server_ = std::make_unique<ControlServer>(*handler_, o);
    server_->start();
  }
  void TearDown() override { server_.reset(); }

  std::string socket_path() const { return dir_.file("ctl.sock"); }

  db::test::TempDir dir_;
  std::unique_ptr<db::history::SqliteRepository> repo_;
  std::unique_ptr<FakeHandler> handler_;
  std::unique_ptr<ControlServer> server_;
};

Reply raw(ControlClient& c, const std::string& line) {
  c.send_raw(line);
  return parse_reply(c.read_line(5s));
}

TEST_F(ControlServerTest, PingAndReadsAreTheRepositorysAnswer) {
  ControlClient c(socket_path());
  const Reply ping = c.call("ping");
  ASSERT_TRUE(ping.ok) << ping.error_message;
  EXPECT_EQ(ping.result.at("version"), "9.8.7-test");

  const std::vector<std::pair<std::string, json>> reads = {
      {"history", {{"serial", "SIM-0001"}}},
      {"history", {{"serial", "SIM-0001"}, {"limit", 2}}},
      {"show", {{"run_id", 2}}},
      {"params", {{"serial", "SIM-0001"}}},
      {"export", {{"format", "csv"}}},
      {"export", {{"format", "json"}, {"serial", "SIM-0001"}}}};
  for (const auto& [cmd, args] : reads) {
    const Reply r = c.call(cmd, args);
    ASSERT_TRUE(r.ok) << cmd << ": " << r.error_message;
    const json direct = answer_repository_read(
        *repo_, validate_request(json{{"id", 1}, {"cmd", cmd}, {"args", args}}));
    EXPECT_EQ(r.result, direct) << cmd << " " << args.dump();
  }
  // The newest of the three is first.
  const Reply h = c.call("history", {{"serial", "SIM-0001"}});
  EXPECT_EQ(h.result.at("runs").at(0).at("run_id"), 3);
  // Reads need no handler call.
  EXPECT_EQ(handler_->start_calls + handler_->status_calls + handler_->abort_calls +
                handler_->reprocess_calls,
            0);
  // Repository errors keep their meaning.
  const Reply unknown = c.call("show", {{"run_id", 999}});
  EXPECT_FALSE(unknown.ok);
  EXPECT_EQ(unknown.error_code, "not_found");
  const Reply bad_serial = c.call("history", {{"serial", "no spaces allowed"}});
  EXPECT_EQ(bad_serial.error_code, "invalid_input");
  EXPECT_NE(bad_serial.error_message.find("no spaces allowed"), std::string::npos);
}

TEST_F(ControlServerTest, MalformedLinesGetErrorsAndTheConnectionStaysUsable) {
  ControlClient c(socket_path());
  Reply r = raw(c, "garbage\n");
  EXPECT_FALSE(r.ok);
  EXPECT_TRUE(r.id.is_null());
  EXPECT_EQ(r.error_code, "bad_request");
  EXPECT_NE(r.error_message.find("not valid JSON"), std::string::npos) << r.error_message;

  r = raw(c, R"({"id":3,"cmd":"run.explode"})"
             "\n");
  EXPECT_EQ(r.id, 3);
  EXPECT_EQ(r.error_code, "bad_request");
  EXPECT_NE(r.error_message.find("field 'cmd'"), std::string::npos) << r.error_message;

  r = raw(c, R"({"id":4,"cmd":"run.start","args":{"serial":5}})"
             "\n");
  EXPECT_EQ(r.id, 4);
  EXPECT_NE(r.error_message.find("field 'args.serial'"), std::string::npos) << r.error_message;

  r = raw(c, R"({"id":5,"cmd":"show","args":{"run_id":"2"}})"
             "\n");
  EXPECT_NE(r.error_message.find("field 'args.run_id'"), std::string::npos) << r.error_message;
  EXPECT_EQ(handler_->start_calls, 0) << "a refused request never reaches the handler";

  // Blank lines are skipped, CRLF is accepted, pipelined requests are answered in order.
  c.send_raw(
      "\n\r\n"
      R"({"id":10,"cmd":"ping"})"
      "\r\n"
      R"({"id":11,"cmd":"ping"})"
      "\n");
  EXPECT_EQ(parse_reply(c.read_line(5s)).id, 10);
  EXPECT_EQ(parse_reply(c.read_line(5s)).id, 11);
  EXPECT_TRUE(c.call("ping").ok);
  EXPECT_EQ(server_->stats().bad_requests, 4u);
}

TEST_F(ControlServerTest, OversizeLineClosesOnlyThatConnection) {
  ControlClient bystander(socket_path());
  ASSERT_TRUE(bystander.call("ping").ok);

  ControlClient big(socket_path());
  const std::string chunk(64 * 1024, 'x');
  // Writes can block when the server stops reading after the refusal: ignore send errors there.
  std::thread writer([&] {
    try {
      for (std::size_t sent = 0; sent <= kMaxLineBytes + chunk.size(); sent += chunk.size())
        big.send_raw(chunk);
    } catch (const ControlClientError&) {
    }
  });
  const Reply r = parse_reply(big.read_line(10s));
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.error_code, "bad_request");
  EXPECT_NE(r.error_message.find("exceeds the limit of 1048576 bytes"), std::string::npos)
      << r.error_message;
  EXPECT_TRUE(big.closed_by_peer(10s));
  writer.join();

  // The other client never noticed.
  const Reply h = bystander.call("history", {{"serial", "SIM-0001"}});
  EXPECT_TRUE(h.ok);
  EXPECT_EQ(h.result.at("runs").size(), 3u);
  EXPECT_EQ(server_->stats().oversize_closed, 1u);
}

TEST_F(ControlServerTest, ManyClientsConcurrentlyNeverOverlapInTheHandler) {
  constexpr int kClients = 40, kRounds = 15;
  std::atomic<int> failures{0};
  std::vector<std::unique_ptr<ControlClient>> clients;
  for (int i = 0; i < kClients; ++i)
    clients.push_back(std::make_unique<ControlClient>(socket_path()));
  std::vector<std::thread> threads;
  for (int i = 0; i < kClients; ++i)
    threads.emplace_back([&, i] {
      for (int k = 0; k < kRounds; ++k) {
        try {
          const Reply s = clients[static_cast<std::size_t>(i)]->call("run.status",
                                                                     {{"run_id", i * 100 + k + 1}});
          if (!s.ok || s.result.at("run").at("run_id") != i * 100 + k + 1) ++failures;
          const Reply h = clients[static_cast<std::size_t>(i)]->call(
              "history", {{"serial", "SIM-0001"}, {"limit", 1}});
          if (!h.ok || h.result.at("runs").size() != 1) ++failures;
          if (k % 5 == 0) {  // garbage from some clients in between
            clients[static_cast<std::size_t>(i)]->send_raw("{oops\n");
            if (parse_reply(clients[static_cast<std::size_t>(i)]->read_line(10s)).error_code !=
                "bad_request")
              ++failures;
          }
        } catch (const std::exception&) {
          ++failures;
        }
      }
    });
  for (auto& t : threads) t.join();
  EXPECT_EQ(failures, 0);
  EXPECT_EQ(handler_->status_calls, kClients * kRounds);
  EXPECT_EQ(handler_->overlaps, 0);
  EXPECT_EQ(server_->stats().clients, static_cast<std::size_t>(kClients));
  clients.clear();
  // The server notices the hang-ups.
  for (int i = 0; i < 100 && server_->stats().clients != 0; ++i) std::this_thread::sleep_for(10ms);
  EXPECT_EQ(server_->stats().clients, 0u);
}

TEST_F(ControlServerTest, HandlerErrorsBecomeTheirCodes) {
  ControlClient c(socket_path());
  Reply r = c.call("run.start", {{"serial", "BUSY-1"}});
  EXPECT_EQ(r.error_code, "busy");
  EXPECT_EQ(r.error_message, "run 4 is active (SIM-0004)");
  r = c.call("run.start", {{"serial", "BAD"}});
  EXPECT_EQ(r.error_code, "invalid_input");
  r = c.call("run.start", {{"serial", "SIM-1"}, {"sequence", "nope"}});
  EXPECT_EQ(r.error_code, "not_found");
  EXPECT_NE(r.error_message.find("sequence \"nope\""), std::string::npos);
  r = c.call("run.start", {{"serial", "BOOM"}});
  EXPECT_EQ(r.error_code, "internal");
  EXPECT_NE(r.error_message.find("division by zero in the fake"), std::string::npos);
  EXPECT_TRUE(c.call("ping").ok) << "the connection survives every error";
}

TEST_F(ControlServerTest, RootMayControlAndTheOperatorDefaultsToThePeer) {
  ASSERT_EQ(::getuid(), 0u) << "the station tests run as root (see common.md)";
  ControlClient c(socket_path());
  Reply r = c.call("run.start", {{"serial", "SIM-0009"}, {"sequence", "short"}});
  ASSERT_TRUE(r.ok) << r.error_message;
  EXPECT_EQ(r.result.at("run_id"), 77);
  EXPECT_EQ(handler_->start_calls, 1);
  EXPECT_EQ(handler_->last_start().serial, "SIM-0009");
  EXPECT_EQ(handler_->last_start().sequence.value_or(""), "short");
  EXPECT_EQ(handler_->last_start().operator_name, "root");
  r = c.call("run.start", {{"serial", "SIM-0009"}, {"operator", "anna"}});
  EXPECT_EQ(handler_->last_start().operator_name, "anna");
  EXPECT_FALSE(handler_->last_start().sequence.has_value());

  r = c.call("run.abort");
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(handler_->last_reason(), "aborted by root");
  r = c.call("run.abort", {{"reason", "unit fell off"}});
  EXPECT_EQ(handler_->last_reason(), "unit fell off");
  r = c.call("reprocess", {{"run_id", 2}});
  ASSERT_TRUE(r.ok);
  EXPECT_EQ(r.result.at("reprocessed_from"), 2);
  EXPECT_EQ(handler_->reprocess_calls, 1);
  // Who asked is passed on (recorded with the new run); a partial archive only when asked.
  EXPECT_EQ(handler_->last_reprocess().user, "root");
  EXPECT_FALSE(handler_->last_reprocess().allow_partial);
  r = c.call("reprocess", {{"run_id", 2}, {"partial", true}});
  ASSERT_TRUE(r.ok);
  EXPECT_TRUE(handler_->last_reprocess().allow_partial);
  r = c.call("reprocess", {{"run_id", 2}, {"partial", "yes"}});
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.error_code, "bad_request");
}

/// Runs `body` in a forked child as nobody:nogroup; returns the child's exit status and whatever
/// it wrote to its stderr pipe (diagnostics).
std::pair<int, std::string> as_nobody(const std::function<int()>& body) {
  int pipefd[2];
  if (::pipe(pipefd) != 0) return {-1, "pipe failed"};
  const pid_t pid = ::fork();
  if (pid == 0) {
    ::close(pipefd[0]);
    ::dup2(pipefd[1], STDERR_FILENO);
    if (::setgroups(0, nullptr) != 0 || ::setgid(kNogroupGid) != 0 || ::setuid(kNobodyUid) != 0)
      ::_exit(90);
    int code = 91;
    try {
      code = body();
    } catch (const std::exception& e) {
      std::fprintf(stderr, "child exception: %s\n", e.what());
    }
    std::fflush(stderr);
    ::_exit(code);
  }
  ::close(pipefd[1]);
  std::string out;
  char buf[512];
  ssize_t n;
  while ((n = ::read(pipefd[0], buf, sizeof buf)) > 0) out.append(buf, static_cast<std::size_t>(n));
  ::close(pipefd[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, out};
}

TEST_F(ControlServerTest, NobodyMayReadButNotControl) {
  const std::string group = server_->group_name();  // root's primary group
  const std::string path = socket_path();
  const auto [code, diag] = as_nobody([&]() -> int {
    ControlClient c(path);
    for (const auto& [cmd, args] :
         std::vector<std::pair<std::string, json>>{{"run.start", {{"serial", "SIM-0001"}}},
                                                   {"run.abort", json::object()},
                                                   {"reprocess", {{"run_id", 1}}}}) {
      const Reply r = c.call(cmd, args);
      if (r.ok || r.error_code != "permission_denied") {
        std::fprintf(stderr, "%s: expected permission_denied, got %s\n", cmd.c_str(),
                     r.ok ? "ok" : r.error_code.c_str());
        return 1;
      }
      if (r.error_message.find("'" + group + "'") == std::string::npos ||
          r.error_message.find("nobody") == std::string::npos) {
        std::fprintf(stderr, "message does not name the group and user: %s\n",
                     r.error_message.c_str());
        return 2;
      }
    }
    const Reply h = c.call("history", {{"serial", "SIM-0001"}});
    if (!h.ok || h.result.at("runs").size() != 3) {
      std::fprintf(stderr, "history failed: %s\n", h.error_message.c_str());
      return 3;
    }
    const Reply s = c.call("run.status");
    if (!s.ok) return 4;
    return 0;
  });
  EXPECT_EQ(code, 0) << diag;
  EXPECT_EQ(handler_->start_calls, 0);
  EXPECT_EQ(handler_->abort_calls, 0);
  EXPECT_EQ(handler_->reprocess_calls, 0);
  EXPECT_EQ(handler_->status_calls, 1);
  EXPECT_EQ(server_->stats().permission_denied, 3u);
}

TEST_F(ControlServerTest, AMemberOfTheControlGroupMayControl) {
  // A second server whose control group is nogroup: nobody's primary group.
  group* g = ::getgrgid(kNogroupGid);
  ASSERT_NE(g, nullptr) << "gid 65534 has no group entry";
  ControlServerOptions o;
  o.socket_path = dir_.file("ctl2.sock");
  o.group = g->gr_name;
  ControlServer second(*handler_, o);
  second.start();
  EXPECT_EQ(second.group_id(), kNogroupGid);
  struct stat st {};
  ASSERT_EQ(::stat(o.socket_path.c_str(), &st), 0);
  EXPECT_EQ(st.st_gid, kNogroupGid) << "the socket file belongs to the control group";
  const auto [code, diag] = as_nobody([&]() -> int {
    ControlClient c(o.socket_path);
    const Reply r = c.call("run.start", {{"serial", "SIM-0002"}});
    if (!r.ok) {
      std::fprintf(stderr, "run.start refused: %s\n", r.error_message.c_str());
      return 1;
    }
    return 0;
  });
  EXPECT_EQ(code, 0) << diag;
  EXPECT_EQ(handler_->start_calls, 1);
  EXPECT_EQ(handler_->last_start().operator_name, "nobody");

  // Group lists: nobody's own group counts even when the peer's current gid is another one
  // (getgrouplist of the passwd entry), a foreign group does not, root always does.
  EXPECT_TRUE(peer_in_group(kNobodyUid, 12345, kNogroupGid));
  EXPECT_FALSE(peer_in_group(kNobodyUid, kNogroupGid, 0));
  EXPECT_TRUE(peer_in_group(0, 0, kNogroupGid));
  EXPECT_FALSE(peer_in_group(4000000, 4000000, kNogroupGid)) << "no passwd entry, other gid";
}

TEST_F(ControlServerTest, SocketFileHandling) {
  struct stat st {};
  ASSERT_EQ(::stat(socket_path().c_str(), &st), 0);
  EXPECT_TRUE(S_ISSOCK(st.st_mode));
  EXPECT_EQ(st.st_mode & 0777, 0666u) << "the fixture's mode";

  auto start_error = [&](ControlServerOptions o) -> std::string {
    try {
      ControlServer s(*handler_, o);
      s.start();
    } catch (const std::runtime_error& e) {
      return e.what();
    }
    return "started";
  };
  ControlServerOptions o;
  o.socket_path = socket_path();
  EXPECT_NE(start_error(o).find("another process is listening"), std::string::npos);
  o.socket_path = dir_.file("missing/ctl.sock");
  EXPECT_NE(start_error(o).find("does not exist"), std::string::npos) << start_error(o);
  o.socket_path = dir_.file("plain-file");
  std::ofstream(o.socket_path) << "keep me";
  EXPECT_NE(start_error(o).find("not a socket"), std::string::npos);
  EXPECT_TRUE(std::filesystem::is_regular_file(o.socket_path)) << "never deleted";
  o.socket_path = dir_.file("g.sock");
  o.group = "no-such-group-xyz";
  EXPECT_NE(start_error(o).find("'no-such-group-xyz' does not exist"), std::string::npos);

  // A stale socket (its server died without unlinking) is replaced; the mode is applied.
  const std::string stale = dir_.file("stale.sock");
  {
    const int fd = ::socket(AF_UNIX, SOCK_STREAM, 0);
    sockaddr_un addr{};
    addr.sun_family = AF_UNIX;
    std::snprintf(addr.sun_path, sizeof addr.sun_path, "%s", stale.c_str());
    ASSERT_EQ(::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof addr), 0);
    ::close(fd);
  }
  ControlServerOptions s;
  s.socket_path = stale;
  s.socket_mode = 0660;
  ControlServer replaced(*handler_, s);
  replaced.start();
  ASSERT_EQ(::stat(stale.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0660u);
  ControlClient c(stale);
  EXPECT_TRUE(c.call("ping").ok);
  replaced.stop();
  EXPECT_FALSE(std::filesystem::exists(stale)) << "stop() removes the socket file";
}

TEST_F(ControlServerTest, UnterminatedLastLineIsAnsweredAtEndOfStream) {
  ControlClient c(socket_path());
  c.send_raw(R"({"id":21,"cmd":"ping"})");
  ::shutdown(c.fd(), SHUT_WR);
  const Reply r = parse_reply(c.read_line(5s));
  EXPECT_TRUE(r.ok);
  EXPECT_EQ(r.id, 21);
  EXPECT_TRUE(c.closed_by_peer(5s));
}

// The default socket mode (0660) admits the owner and the control group only: anyone else is
// refused by the kernel at connect, which the client reports as no permission.
TEST_F(ControlServerTest, DefaultModeAdmitsOnlyOwnerAndGroup) {
  ControlServerOptions o;
  o.socket_path = dir_.file("default.sock");
  ControlServer s(*handler_, o);
  s.start();
  struct stat st {};
  ASSERT_EQ(::stat(o.socket_path.c_str(), &st), 0);
  EXPECT_EQ(st.st_mode & 0777, 0660u) << "default mode";
  const std::string path = o.socket_path;
  const auto [code, diag] = as_nobody([&]() -> int {
    try {
      ControlClient c(path);
    } catch (const ControlClientError& e) {
      if (e.kind() != ControlClientError::Kind::kNoPermission) {
        std::fprintf(stderr, "wrong kind: %s\n", e.what());
        return 2;
      }
      return std::string(e.what()).find("control group") == std::string::npos ? 3 : 0;
    }
    return 1;  // connected
  });
  EXPECT_EQ(code, 0) << diag;
  EXPECT_EQ(s.stats().connections, 0u);
}

// An idle client is closed after idle_timeout; one that keeps talking is not. (Before: 128 idle
// clients held every slot for ever and locked the operators out.)
TEST_F(ControlServerTest, IdleConnectionsAreClosedActiveOnesAreNot) {
  ControlServerOptions o;
  o.socket_path = dir_.file("idle.sock");
  o.idle_timeout = 400ms;
  ControlServer s(*handler_, o);
  s.start();
  ControlClient idle(o.socket_path), active(o.socket_path);
  for (int i = 0; i < 10; ++i) {
    ASSERT_TRUE(active.call("ping").ok);
    std::this_thread::sleep_for(100ms);
  }
  EXPECT_TRUE(idle.closed_by_peer(2s)) << "the idle connection was not closed";
  EXPECT_TRUE(active.call("ping").ok) << "the active connection was closed";
  EXPECT_GE(s.stats().idle_closed, 1u);
}

// One user holds at most max_clients_per_user connections; the next gets an error reply naming
// the limit, and others (root) still get in.
TEST_F(ControlServerTest, ConnectionsPerUserAreCapped) {
  ControlServerOptions o;
  o.socket_path = dir_.file("cap.sock");
  o.socket_mode = 0666;
  o.max_clients_per_user = 3;
  ControlServer s(*handler_, o);
  s.start();
  const std::string path = o.socket_path;
  const auto [code, diag] = as_nobody([&]() -> int {
    std::vector<std::unique_ptr<ControlClient>> held;
    for (int i = 0; i < 3; ++i) {
      held.push_back(std::make_unique<ControlClient>(path));
      if (!held.back()->call("ping").ok) return 1;
    }
    // The refusal is written and the connection closed at once: read it without sending (a
    // request sent after the close would fail to send, not get the reply).
    ControlClient extra(path);
    const Reply r = parse_reply(extra.read_line(5s));
    if (r.ok || r.error_code != "unavailable") return 2;
    if (r.error_message.find("from nobody (3)") == std::string::npos) {
      std::fprintf(stderr, "%s\n", r.error_message.c_str());
      return 3;
    }
    held.pop_back();  // one slot free again, once the server has seen the close
    for (int attempt = 0; attempt < 50; ++attempt) {
      std::this_thread::sleep_for(100ms);
      try {
        ControlClient again(path);
        if (again.call("ping").ok) return 0;
      } catch (const ControlClientError&) {
        // refused (and closed) before the server saw the close: try again
      }
    }
    return 4;
  });
  EXPECT_EQ(code, 0) << diag;
  EXPECT_GE(s.stats().per_user_refused, 1u);
  ControlClient root(path);
  EXPECT_TRUE(root.call("ping").ok);
}

}  // namespace
}  // namespace imucal::station
