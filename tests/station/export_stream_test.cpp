// Streamed exports over the control socket (station/control/export_stream.hpp, issue #11 item 3),
// with a real SQLite history of 400 runs (800 rows, ~1.1 MB of CSV: more than the socket buffers
// hold): the streamed bytes are exactly the export the repository writes, in each format; a client
// that goes away in the middle leaves the server serving and its export thread ended; errors before
// the first byte are ordinary error replies; the concurrency cap refuses with busy.
#include <gtest/gtest.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <sstream>
#include <string>
#include <thread>

#include "calib/core/param_set.hpp"
#include "db/history/export.hpp"
#include "db/history/sqlite_repository.hpp"
#include "station/control/control_client.hpp"
#include "station/control/control_server.hpp"
#include "tests/db/history_fixtures.hpp"

namespace imucal::station {
using namespace imucal::station::control;
namespace {

using nlohmann::json;
using namespace std::chrono_literals;

/// Reads only: the control commands are not what these tests are about.
class ReadOnlyHandler : public ControlHandler {
 public:
  explicit ReadOnlyHandler(const db::history::Repository& repo) : repo_(repo) {}
  json start_run(const StartRunRequest&) override { throw ControlError("internal", "not here"); }
  json status(std::optional<db::history::RunId>) override { return {{"state", "idle"}}; }
  json abort_run(const std::string&) override { throw ControlError("internal", "not here"); }
  json reprocess(const ReprocessRequest&) override { throw ControlError("internal", "not here"); }
  json diagnose(db::history::RunId) override { throw ControlError("internal", "not here"); }
  const db::history::Repository& repository() const override { return repo_; }

 private:
  const db::history::Repository& repo_;
};

constexpr int kRuns = 400;  // 800 rows, ~1.1 MB of CSV: far more than the socket buffers hold

class ExportStreamTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    // The calibration core's parameter table (a function-local static) built here, before any
    // thread: the TSan tree links the calibration core uninstrumented (tools/sanitizers.sh), so
    // TSan cannot see the guard of its lazy construction and would report the first reads from two
    // threads as a race.
    (void)calib::core::param_info(0);
    dir_ = new db::test::TempDir();
    db::history::SqliteRepository repo(dir_->file("history.sqlite"));
    const db::history::TimestampMs t0 = db::history::parse_time_utc("2024-05-01T10:00:00Z");
    for (int k = 0; k < kRuns; ++k) {
      const std::string serial = "SN-" + std::to_string(k % 50);
      const db::history::RunId id = repo.create_run(db::test::new_run(serial, t0 + k * 60000));
      repo.finish_run(id, k % 7 == 3 ? db::test::review_completion(k, t0 + k * 60000 + 30000)
                                     : db::test::pass_completion(k, t0 + k * 60000 + 30000));
    }
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }

  void start_server(std::size_t max_exports = 4) {
    repo_ = std::make_unique<db::history::SqliteRepository>(db_path());
    handler_ = std::make_unique<ReadOnlyHandler>(*repo_);
    ControlServerOptions o;
    o.socket_path = dir_->file("ctl-" + std::to_string(++servers_) + ".sock");
    o.database_path = db_path();
    o.max_exports = max_exports;
    server_ = std::make_unique<ControlServer>(*handler_, o);
    server_->start();
  }
  void TearDown() override { server_.reset(); }

  static std::string db_path() { return dir_->file("history.sqlite"); }
  std::string socket_path() const { return server_->socket_path(); }

  /// What the repository itself writes for this export.
  std::string direct(const std::string& format,
                     const db::history::ExportFilter& filter = {}) const {
    std::ostringstream out;
    db::history::export_history(*repo_, filter, format, out);
    return out.str();
  }

  static db::test::TempDir* dir_;
  static int servers_;
  std::unique_ptr<db::history::SqliteRepository> repo_;
  std::unique_ptr<ReadOnlyHandler> handler_;
  std::unique_ptr<ControlServer> server_;
};
db::test::TempDir* ExportStreamTest::dir_ = nullptr;
int ExportStreamTest::servers_ = 0;

TEST_F(ExportStreamTest, StreamedBytesAreExactlyTheRepositorysExportInEveryFormat) {
  start_server();
  for (const char* format : {"csv", "json", "ndjson"}) {
    ControlClient c(socket_path());
    std::string got;
    std::size_t pieces = 0;
    const Reply r = c.call_streamed("export", {{"format", format}, {"stream", true}},
                                    [&](std::string_view bytes) {
                                      got.append(bytes);
                                      ++pieces;
                                    });
    ASSERT_TRUE(r.ok) << format << ": " << r.error_message;
    EXPECT_EQ(r.result.at("rows").get<int>(), 2 * kRuns) << format;  // both methods of each run
    const std::string want = direct(format);
    EXPECT_GT(want.size(), 4u * ExportStreams::kFrameBytes) << "too small to need frames";
    EXPECT_EQ(got.size(), want.size()) << format;
    EXPECT_TRUE(got == want) << format << ": the streamed export differs from the repository's";
    EXPECT_GT(pieces, 4u) << format << ": arrived in one piece, not streamed";
  }
  // With a filter, and one object per line in NDJSON.
  ControlClient c(socket_path());
  std::string got;
  const Reply r =
      c.call_streamed("export", {{"format", "ndjson"}, {"serial", "SN-7"}, {"stream", true}},
                      [&](std::string_view bytes) { got.append(bytes); });
  ASSERT_TRUE(r.ok) << r.error_message;
  EXPECT_EQ(got, direct("ndjson", {std::string("SN-7"), std::nullopt, std::nullopt}));
  std::istringstream lines(got);
  int n = 0;
  for (std::string line; std::getline(lines, line); ++n)
    EXPECT_EQ(json::parse(line).at("serial"), "SN-7");
  EXPECT_EQ(n, r.result.at("rows").get<int>());
  EXPECT_EQ(n, 2 * kRuns / 50);
}

TEST_F(ExportStreamTest, AClientThatGoesAwayMidStreamLeavesTheServerServing) {
  start_server();
  for (int k = 0; k < 3; ++k) {
    ControlClient c(socket_path());
    c.send_raw(R"({"id":1,"cmd":"export","args":{"format":"json","stream":true}})"
               "\n");
    const Reply header = parse_reply(c.read_line(10s));
    ASSERT_TRUE(header.ok) << header.error_message;
    EXPECT_TRUE(header.result.at("stream").get<bool>());
    (void)c.read_line(10s);  // the first frame's size; then hang up without reading on
  }
  // The server answers at once, and its export threads end (their sends fail).
  ControlClient c(socket_path());
  EXPECT_TRUE(c.call("ping", json::object(), 5s).ok);
  const auto deadline = std::chrono::steady_clock::now() + 20s;
  while (server_->stats().exports > 0 && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(10ms);
  EXPECT_EQ(server_->stats().exports, 0u) << "an export thread outlived its client";
  std::string got;
  const Reply r = c.call_streamed("export", {{"format", "csv"}, {"stream", true}},
                                  [&](std::string_view bytes) { got.append(bytes); });
  ASSERT_TRUE(r.ok) << r.error_message;
  EXPECT_EQ(got, direct("csv"));
}

TEST_F(ExportStreamTest, ErrorsBeforeTheFirstByteAreOrdinaryErrorReplies) {
  start_server();
  ControlClient c(socket_path());
  bool any = false;
  const Reply unknown =
      c.call_streamed("export", {{"format", "csv"}, {"serial", "NOPE-1"}, {"stream", true}},
                      [&](std::string_view) { any = true; });
  EXPECT_FALSE(unknown.ok);
  EXPECT_EQ(unknown.error_code, "not_found") << unknown.error_message;
  EXPECT_NE(unknown.error_message.find("NOPE-1"), std::string::npos) << unknown.error_message;
  EXPECT_FALSE(any);
  // A bad format is refused by the protocol check, before any export starts.
  ControlClient d(socket_path());
  const Reply bad = d.call_streamed("export", {{"format", "xml"}, {"stream", true}},
                                    [&](std::string_view) { any = true; });
  EXPECT_FALSE(bad.ok);
  EXPECT_EQ(bad.error_code, "bad_request");
  EXPECT_NE(bad.error_message.find("ndjson"), std::string::npos) << bad.error_message;
  EXPECT_FALSE(any);
}

TEST_F(ExportStreamTest, OverTheCapAStreamedExportIsRefusedBusy) {
  start_server(/*max_exports=*/0);
  ControlClient c(socket_path());
  const Reply r =
      c.call_streamed("export", {{"format", "csv"}, {"stream", true}}, [](std::string_view) {});
  EXPECT_FALSE(r.ok);
  EXPECT_EQ(r.error_code, "busy") << r.error_message;
  // The single-reply export still works (small exports, older clients).
  ControlClient d(socket_path());
  const Reply whole = d.call("export", {{"format", "csv"}, {"serial", "SN-3"}});
  ASSERT_TRUE(whole.ok) << whole.error_message;
  EXPECT_EQ(whole.result.at("content").get<std::string>(),
            direct("csv", {std::string("SN-3"), std::nullopt, std::nullopt}));
}

}  // namespace
}  // namespace imucal::station
