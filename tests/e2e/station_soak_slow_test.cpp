// Soak (issue #10, item 8): consecutive simulated runs (short sequence, accelerated) while a second
// process keeps querying the history — `stationctl history` and `export` through the daemon, and
// the same straight from the database file (no socket: stationctl reads the file itself) while the
// daemon writes it. Every run must PASS; no query may fail or show SQLITE_BUSY / "locked" to its
// user; the daemon's resident memory must stay flat (within 10 % from the warmed-up runs to the
// last ones) and its open descriptors must not grow.
// IMUCAL_SOAK_RUNS sets the count (CI: 15; the full soak: 50, figures in the README). The daemon's
// RSS steps up over the first few runs (the allocator gives the control, capture and calibration
// threads their own arenas, each grown to the run's peak once), so the reference is the mean of
// three runs after the first third, compared with the mean of the last three.
#include <atomic>
#include <mutex>
#include <thread>

#include "tests/e2e/station_harness.hpp"

namespace imucal::e2e {
namespace {

int env_int(const char* name, int fallback) {
  const char* v = std::getenv(name);
  return (v && *v) ? std::atoi(v) : fallback;
}

double env_double(const char* name, double fallback) {
  const char* v = std::getenv(name);
  return (v && *v) ? std::atof(v) : fallback;
}

/// VmRSS of a process in kB (-1 if unreadable).
long rss_kb(pid_t pid) {
  std::ifstream in("/proc/" + std::to_string(pid) + "/status");
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("VmRSS:", 0) == 0) return std::atol(line.c_str() + 6);
  return -1;
}

/// Open file descriptors of a process (-1 if unreadable).
long fd_count(pid_t pid) {
  std::error_code ec;
  long n = 0;
  for (fs::directory_iterator it("/proc/" + std::to_string(pid) + "/fd", ec), end; !ec && it != end;
       it.increment(ec))
    ++n;
  return ec ? -1 : n;
}

/// The querying process side: stationctl invocations in a loop until stopped.
class Querier {
 public:
  explicit Querier(const Station& st) : st_(st), thread_([this] { loop(); }) {}
  ~Querier() { stop(); }
  void stop() {
    stop_ = true;
    if (thread_.joinable()) thread_.join();
  }
  int queries() const { return queries_; }
  const std::vector<std::string>& failures() const { return failures_; }
  /// Holds the loop after its current query (for a quiet moment to count descriptors).
  void pause() { busy_.lock(); }
  void resume() { busy_.unlock(); }

 private:
  void loop() {
    const std::string no_socket = st_.path("no-daemon.sock");  // forces the direct file read
    for (int k = 0; !stop_; ++k) {
      std::vector<std::string> args;
      if (k % 2 == 1) args = {"--socket", no_socket, "--db", st_.db_path()};
      if (k % 4 < 2)
        args.insert(args.end(), {"--json", "history", "SIM-SOAK-1"});
      else
        args.insert(args.end(), {"export", "--format", (k % 8 < 4) ? "csv" : "json"});
      std::unique_lock<std::mutex> lk(busy_);
      const CmdResult r = st_.ctl(args, 60s);
      lk.unlock();
      std::this_thread::sleep_for(5ms);  // lets pause() in (the mutex is not fair)
      ++queries_;
      const std::string all = r.out + r.err;
      // A unit with no runs yet is "not found" (exit 2): the only acceptable failure, early on.
      const bool unknown_yet = r.exit_code == 2 && contains_ci(all, "no unit");
      if ((r.exit_code != 0 && !unknown_yet) || contains_ci(all, "busy") ||
          contains_ci(all, "locked"))
        failures_.push_back(r.describe());
    }
  }

  const Station& st_;
  std::atomic<bool> stop_{false};
  std::atomic<int> queries_{0};
  std::vector<std::string> failures_;
  std::mutex busy_;
  std::thread thread_;
};

struct Sample {
  long rss_kb = 0;
  long fds = 0;
};

TEST(StationSoak, ConsecutiveRunsWithParallelQueriesAllPassWithFlatMemoryAndNoDescriptorLeak) {
  const int n = env_int("IMUCAL_SOAK_RUNS", 15);
  ASSERT_GE(n, 12) << "IMUCAL_SOAK_RUNS below 12 cannot show a trend after the warm-up";
  Station st;
  ASSERT_TRUE(st.start(SimOptions{env_double("IMUCAL_SOAK_SPEED", 400.0),
                                  static_cast<uint64_t>(env_int("IMUCAL_SOAK_SEED", 41)),
                                  {}}));
  const pid_t daemon = st.daemon().pid();
  std::vector<Sample> samples;
  const Sample at_start{rss_kb(daemon), fd_count(daemon)};
  int passed = 0;
  {
    Querier q(st);
    for (int i = 0; i < n; ++i) {
      const CmdResult r = st.ctl({"run", "start", "--serial", "SIM-SOAK-" + std::to_string(i % 3),
                                  "--sequence", "short", "--wait"},
                                 300s);
      EXPECT_EQ(r.exit_code, 0) << "run " << i << " did not PASS:\n"
                                << r.describe() << st.daemon_log();
      if (r.exit_code == 0) ++passed;
      q.pause();  // no client connected: the daemon's own descriptors only
      std::this_thread::sleep_for(200ms);
      samples.push_back({rss_kb(daemon), fd_count(daemon)});
      q.resume();
      std::fprintf(stderr,
                   "[soak] run %d: exit %d, daemon RSS %ld kB, %ld fds, %d queries so far\n", i + 1,
                   r.exit_code, samples.back().rss_kb, samples.back().fds, q.queries());
    }
    q.stop();
    EXPECT_GE(q.queries(), n) << "the querying process hardly ran";
    for (const auto& f : q.failures()) ADD_FAILURE() << "a query failed during the soak:\n" << f;
    std::fprintf(stderr, "[soak] %d queries in parallel, %zu failed\n", q.queries(),
                 q.failures().size());
  }
  EXPECT_EQ(passed, n);
  ASSERT_TRUE(st.daemon().running()) << st.daemon_log();

  // Memory: the mean of three runs after the warm-up (the first third) against the last three.
  auto mean_rss = [&](size_t from, size_t to) {
    double s = 0;
    for (size_t k = from; k < to; ++k) s += samples[k].rss_kb;
    return s / static_cast<double>(to - from);
  };
  const size_t warm_from = std::max<size_t>(4, samples.size() / 3);
  const double warm = mean_rss(warm_from, warm_from + 3);
  const double last = mean_rss(samples.size() - 3, samples.size());
  std::fprintf(stderr,
               "[soak] daemon RSS: start %ld kB, warmed-up %.0f kB, last %.0f kB (%+.1f %%); fds "
               "%ld -> %ld\n",
               at_start.rss_kb, warm, last, 100.0 * (last - warm) / warm, samples[warm_from].fds,
               samples.back().fds);
  EXPECT_LE(last, 1.10 * warm) << "the daemon's resident memory grew over the soak";
  // Descriptors: after the warm-up every run ends with the same open set (idle, no client).
  EXPECT_LE(samples.back().fds, samples[warm_from].fds)
      << "descriptors leak: " << samples[warm_from].fds << " -> " << samples.back().fds;
}

}  // namespace
}  // namespace imucal::e2e
