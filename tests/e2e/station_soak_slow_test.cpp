// Soak (issue #10, item 8; issue #22, item 4): consecutive simulated runs (short sequence,
// accelerated) while a second process keeps querying the history — `stationctl history` and
// `export` through the daemon, and the same straight from the database file (no socket: stationctl
// reads the file itself) while the daemon writes it. Every run must PASS; no query may fail or show
// SQLITE_BUSY / "locked" to its user; the daemon's resident memory must stay flat and its open
// descriptors must not grow.
// The count: CI 12 runs over 3 units (the fewest that leave a trend after the warm-up: a leak of a
// descriptor a run, or RSS creeping over ~130 kB a run, fails it); the whole count under
// IMUCAL_WHOLE_COUNTS=1 is the long soak's 1000 runs over 50 units (tools/bench_soak.sh, ~50 min,
// figures in docs/validation/reliability.md: a creep of a few kB a run). IMUCAL_SOAK_RUNS and
// IMUCAL_SOAK_UNITS override them. The daemon's RSS steps up over the first few runs (the allocator
// grows to the run's peak once, SQLite's page cache fills up to its bound), so the checks look past
// the first third:
//   * the mean of three runs after the first third against the mean of the last three: within 10 %;
//   * the least-squares slope of RSS over the second half of the runs: at most kSlopeBoundKbPerRun
//     plus kStepAllowanceKb spread over that half (see below).
// IMUCAL_SOAK_UNITS sets how many units the runs rotate over (default 3; the querier asks for the
// whole history of SIM-SOAK-1). stationd builds a history reply whole, ~12 kB of heap per run in it
// (measured: a unit with 50 / 200 / 1600 runs, +0.6 / +2.4 / +19.6 MB of RSS), kept resident until
// the next calibration trims the heap: with 3 units a long soak's RSS follows that unit's history
// (+2.7 kB a run over runs 90-150 of 150), which the slope check takes for a creep. A station
// calibrates many units, each a few times; the long soak runs over 50 (20 runs each in 1000).
// IMUCAL_SOAK_LOG=FILE writes one CSV row per run (flushed as it goes): the run, its id and
// verdict, the daemon's RSS and descriptors, the database and WAL file sizes, the latency of a
// `stationctl history` made right after the run (no other query beside it), and the count, median
// and maximum latency of the parallel querier's history and export queries during that run.
#include <poll.h>
#include <spawn.h>
#include <sys/syscall.h>

#include <atomic>
#include <deque>
#include <mutex>
#include <thread>
#include <utility>

#include "tests/e2e/station_harness.hpp"
#include "tests/support/ci_count.hpp"

#if defined(__has_feature)
#if __has_feature(address_sanitizer)
#define IMUCAL_SOAK_UNDER_ASAN 1
#endif
#endif
#if defined(__SANITIZE_ADDRESS__)
#define IMUCAL_SOAK_UNDER_ASAN 1
#endif

namespace imucal::e2e {
namespace {

#ifdef IMUCAL_SOAK_UNDER_ASAN
constexpr bool kUnderAddressSanitizer = true;
#else
constexpr bool kUnderAddressSanitizer = false;
#endif

// The slope check (issue #22 item 4). The creep it must catch: SQLite's page cache following the
// growing database, 10.6 kB a run over runs 101-200 before it was bounded
// (db/history/sqlite_repository.hpp; bounded, the cache is full by run ~85 and stays). The bound is
// 2 kB a run (2 MB over 1000 runs) plus one step of kStepAllowanceKb anywhere in the fitted half
// (the allocator's; a step of S in the middle of L runs gives a slope of 1.5 S / L): over 1000 runs
// (500 fitted) 3.5 kB a run, well under the creep; over CI's 12 runs (6 fitted) 130 kB a run —
// there the 10 % check and the descriptors carry the test: a creep of a few kB a run cannot show
// above the allocator's noise in 12 runs.
constexpr double kSlopeBoundKbPerRun = 2.0;
constexpr double kStepAllowanceKb = 512.0;

int env_int_station_soak(const char* name, int fallback) {
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

/// Size of a file in bytes (0 if missing).
long long file_bytes(const std::string& path) {
  std::error_code ec;
  const auto n = fs::file_size(path, ec);
  return ec ? 0 : static_cast<long long>(n);
}

double ms_since(Clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

/// One stationctl from spawn to exit, timed by the exit itself (a pidfd): st.ctl() polls its child
/// every 5 ms, too coarse for queries of a few ms. stdout and stderr go to OUT_BASE.out / .err
/// (overwritten by the next call with the same base).
struct Timed {
  CmdResult r;
  double ms = 0;
};
Timed timed_ctl(const Station& st, const std::vector<std::string>& args,
                const std::string& out_base, std::chrono::milliseconds timeout) {
  std::vector<std::string> argv = {st.program("stationctl"), "--config", st.config_path()};
  argv.insert(argv.end(), args.begin(), args.end());
  std::vector<char*> cargv;
  for (auto& a : argv) cargv.push_back(a.data());
  cargv.push_back(nullptr);
  const std::string out_path = out_base + ".out", err_path = out_base + ".err";
  posix_spawn_file_actions_t fa;
  posix_spawn_file_actions_init(&fa);
  posix_spawn_file_actions_addopen(&fa, 0, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&fa, 1, out_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_addopen(&fa, 2, err_path.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  Timed t;
  t.r.command = shell_quote(argv);
  pid_t pid = -1;
  const auto t0 = Clock::now();
  const int rc = ::posix_spawn(&pid, cargv[0], &fa, nullptr, cargv.data(), environ);
  posix_spawn_file_actions_destroy(&fa);
  if (rc != 0) {
    t.r.err = std::string("posix_spawn: ") + std::strerror(rc);
    return t;
  }
  const int pidfd = static_cast<int>(::syscall(SYS_pidfd_open, pid, 0));
  if (pidfd >= 0) {
    pollfd p{pidfd, POLLIN, 0};
    int ready;
    do {
      const auto left =
          std::chrono::duration_cast<std::chrono::milliseconds>(t0 + timeout - Clock::now());
      ready = ::poll(&p, 1, static_cast<int>(std::max<long long>(0, left.count())));
    } while (ready < 0 && errno == EINTR);
    ::close(pidfd);
    if (ready == 0) {
      ::kill(pid, SIGKILL);
      t.r.timed_out = true;
    }
  }
  int status = 0;
  while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  t.ms = ms_since(t0);
  t.r.exit_code = t.r.timed_out         ? -1
                  : WIFEXITED(status)   ? WEXITSTATUS(status)
                  : WIFSIGNALED(status) ? 128 + WTERMSIG(status)
                                        : -1;
  t.r.out = read_text(out_path);
  t.r.err = read_text(err_path);
  return t;
}

/// What a long soak must not keep (it measures none of it): the captured output of every finished
/// stationctl (the exports grow with the history: the files would total ~250 GB over 1000 runs)
/// and the run archives but the newest few (18 MB a run; nothing reads a finished run's archive
/// during the soak). Called while no stationctl runs.
void prune_storage(const Station& st, std::deque<std::string>& archives,
                   const std::string& newest) {
  constexpr std::size_t kKeptArchives = 3;
  std::error_code ec;
  for (fs::directory_iterator it(st.path(""), ec), end; !ec && it != end; it.increment(ec)) {
    const std::string name = it->path().filename().string();
    if (name.rfind("cmd-", 0) == 0) fs::remove(it->path(), ec);
  }
  const std::string runs_dir = st.data_dir() + "/";
  if (newest.rfind(runs_dir, 0) == 0) archives.push_back(newest);
  while (archives.size() > kKeptArchives) {
    fs::remove_all(archives.front(), ec);
    archives.pop_front();
  }
}

/// Count, median and maximum of latencies in ms (0s if none).
struct LatencyStats {
  std::size_t n = 0;
  double median_ms = 0, max_ms = 0;
};
LatencyStats stats_of(std::vector<double> v) {
  LatencyStats s;
  s.n = v.size();
  if (v.empty()) return s;
  std::sort(v.begin(), v.end());
  s.median_ms = v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
  s.max_ms = v.back();
  return s;
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
  /// The latencies (ms) of the history and export queries since the last call.
  std::pair<std::vector<double>, std::vector<double>> take_latencies() {
    std::lock_guard<std::mutex> lk(latencies_mutex_);
    return {std::exchange(history_ms_, {}), std::exchange(export_ms_, {})};
  }

 private:
  void loop() {
    const std::string no_socket = st_.path("no-daemon.sock");  // forces the direct file read
    for (int k = 0; !stop_; ++k) {
      std::vector<std::string> args;
      if (k % 2 == 1) args = {"--socket", no_socket, "--db", st_.db_path()};
      const bool history = k % 4 < 2;
      if (history)
        args.insert(args.end(), {"--json", "history", "SIM-SOAK-1"});
      else
        args.insert(args.end(), {"export", "--format", (k % 8 < 4) ? "csv" : "json"});
      std::unique_lock<std::mutex> lk(busy_);
      const Timed t = timed_ctl(st_, args, st_.path("querier"), 60s);
      lk.unlock();
      const CmdResult& r = t.r;
      {
        std::lock_guard<std::mutex> l(latencies_mutex_);
        (history ? history_ms_ : export_ms_).push_back(t.ms);
      }
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
  std::mutex latencies_mutex_;
  std::vector<double> history_ms_, export_ms_;
  std::thread thread_;
};

struct Sample {
  long rss_kb = 0;
  long fds = 0;
};

/// Least-squares slope of samples[from..).rss_kb against the run index (kB per run).
double rss_slope(const std::vector<Sample>& samples, std::size_t from) {
  const double m = static_cast<double>(samples.size() - from);
  double sx = 0, sy = 0;
  for (std::size_t k = from; k < samples.size(); ++k) {
    sx += static_cast<double>(k);
    sy += static_cast<double>(samples[k].rss_kb);
  }
  const double mx = sx / m, my = sy / m;
  double sxy = 0, sxx = 0;
  for (std::size_t k = from; k < samples.size(); ++k) {
    const double dx = static_cast<double>(k) - mx;
    sxy += dx * (static_cast<double>(samples[k].rss_kb) - my);
    sxx += dx * dx;
  }
  return sxx > 0 ? sxy / sxx : 0.0;
}

TEST(StationSoak, ConsecutiveRunsWithParallelQueriesAllPassWithFlatMemoryAndNoDescriptorLeak) {
  const int n = test_support::test_count("IMUCAL_SOAK_RUNS", 12, 1000);
  ASSERT_GE(n, 12) << "IMUCAL_SOAK_RUNS below 12 cannot show a trend after the warm-up";
  const int units = test_support::test_count("IMUCAL_SOAK_UNITS", 3, 50);
  ASSERT_GE(units, 2) << "IMUCAL_SOAK_UNITS: the querier reads SIM-SOAK-1's history";
  std::FILE* log = nullptr;
  if (const char* path = std::getenv("IMUCAL_SOAK_LOG"); path && *path) {
    log = std::fopen(path, "we");  // not inherited by the stationctl children
    ASSERT_NE(log, nullptr) << "cannot write IMUCAL_SOAK_LOG=" << path;
    std::fprintf(log,
                 "run,run_id,verdict,rss_kb,fds,db_bytes,wal_bytes,run_s,history_ms,"
                 "q_history_n,q_history_median_ms,q_history_max_ms,q_export_n,q_export_median_ms,"
                 "q_export_max_ms\n");
    std::fflush(log);
  }
  const std::unique_ptr<std::FILE, int (*)(std::FILE*)> log_closer(
      log, [](std::FILE* f) { return f ? std::fclose(f) : 0; });
  const auto t_start = Clock::now();
  Station st;
  ASSERT_TRUE(st.start(SimOptions{env_double("IMUCAL_SOAK_SPEED", 400.0),
                                  static_cast<uint64_t>(env_int_station_soak("IMUCAL_SOAK_SEED", 41)),
                                  {}}));
  const pid_t daemon = st.daemon().pid();
  std::vector<Sample> samples;
  std::vector<double> history_after_ms;
  std::deque<std::string> archives;  // the newest run archives, kept
  const Sample at_start{rss_kb(daemon), fd_count(daemon)};
  int passed = 0;
  {
    Querier q(st);
    for (int i = 0; i < n; ++i) {
      const std::string serial = "SIM-SOAK-" + std::to_string(i % units);
      const auto t_run = Clock::now();
      const CmdResult r =
          st.ctl({"run", "start", "--serial", serial, "--sequence", "short", "--wait"}, 300s);
      const double run_s = ms_since(t_run) / 1000.0;
      EXPECT_EQ(r.exit_code, 0) << "run " << i << " did not PASS:\n"
                                << r.describe() << st.daemon_log();
      if (r.exit_code == 0) ++passed;
      q.pause();  // no client connected: the daemon's own descriptors only
      std::this_thread::sleep_for(200ms);
      samples.push_back({rss_kb(daemon), fd_count(daemon)});
      // One history query through the daemon right after the run, nothing else beside it.
      const Timed after = timed_ctl(st, {"--json", "history", serial}, st.path("after-run"), 60s);
      const CmdResult& h = after.r;
      history_after_ms.push_back(after.ms);
      EXPECT_EQ(h.exit_code, 0) << h.describe();
      long long run_id = -1;
      std::string verdict = "?", archive;
      if (h.exit_code == 0) {
        const json runs = h.json_out().value("runs", json::array());
        if (!runs.empty()) {  // newest first
          run_id = runs[0].value("run_id", -1LL);
          if (runs[0].contains("verdict") && runs[0]["verdict"].is_string())
            verdict = runs[0]["verdict"].get<std::string>();
          archive = runs[0].value("archive_path", "");
        }
      }
      prune_storage(st, archives, archive);
      q.resume();
      const auto [qh, qe] = q.take_latencies();
      const LatencyStats sh = stats_of(qh), se = stats_of(qe);
      if (log) {
        std::fprintf(log, "%d,%lld,%s,%ld,%ld,%lld,%lld,%.2f,%.1f,%zu,%.1f,%.1f,%zu,%.1f,%.1f\n",
                     i + 1, run_id, verdict.c_str(), samples.back().rss_kb, samples.back().fds,
                     file_bytes(st.db_path()), file_bytes(st.db_path() + "-wal"), run_s,
                     history_after_ms.back(), sh.n, sh.median_ms, sh.max_ms, se.n, se.median_ms,
                     se.max_ms);
        std::fflush(log);
      }
      std::fprintf(stderr,
                   "[soak] run %d: exit %d, daemon RSS %ld kB, %ld fds, history %.0f ms, %d "
                   "queries so far\n",
                   i + 1, r.exit_code, samples.back().rss_kb, samples.back().fds,
                   history_after_ms.back(), q.queries());
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
  // And the trend over the second half: a creep of a few kB a run shows over a long soak.
  const std::size_t half = samples.size() / 2;
  const double fitted = static_cast<double>(samples.size() - half);
  const double slope = rss_slope(samples, half);
  const double slope_bound = kSlopeBoundKbPerRun + 1.5 * kStepAllowanceKb / fitted;
  std::fprintf(stderr,
               "[soak] daemon RSS: start %ld kB, warmed-up %.0f kB, last %.0f kB (%+.1f %%), slope "
               "over runs %zu-%zu %+.2f kB/run (bound %.1f); fds %ld -> %ld; %.0f s wall\n",
               at_start.rss_kb, warm, last, 100.0 * (last - warm) / warm, half + 1, samples.size(),
               slope, slope_bound, samples[warm_from].fds, samples.back().fds,
               ms_since(t_start) / 1000.0);
  if (kUnderAddressSanitizer) {
    // ASan's allocator keeps freed blocks in quarantine (256 MB) and never returns them at the
    // daemon's trim: its resident size says nothing about the release build's (the RSS figures are
    // printed above; the release suite and tools/bench_soak.sh judge them).
    std::fprintf(stderr, "[soak] under AddressSanitizer: the RSS bounds are not judged\n");
  } else {
    EXPECT_LE(last, 1.10 * warm) << "the daemon's resident memory grew over the soak";
    EXPECT_LE(slope, slope_bound) << "the daemon's resident memory creeps: " << slope
                                  << " kB per run over runs " << half + 1 << "-" << samples.size();
  }
  // Descriptors: after the warm-up every run ends with the same open set (idle, no client).
  EXPECT_LE(samples.back().fds, samples[warm_from].fds)
      << "descriptors leak: " << samples[warm_from].fds << " -> " << samples.back().fds;
}

}  // namespace
}  // namespace imucal::e2e
