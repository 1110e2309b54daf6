// Benchmark (not a test): QA read latency of the calibration history with 100 000 runs in the
// database (station issue: "`history` and `export` latency with 100 000 runs"). 1 000 serials x
// 100 runs, each run done with both calibrations (AINS, NLSQ) and a PASS cross-check, i.e.
// 100 000 runs, 200 000 calibration rows, 100 000 cross-checks.
//
// The database is built once (timed, reported on stderr) at $IMUCAL_BENCH_DB or
// /tmp/imucal-history-bench.db and reused while it holds the expected number of runs.
//
// Not built by CMake (only *_test.cpp files are globbed). Build by hand against a build tree:
//   see db/history/SCHEMA.md, section "Benchmark", for the command line.
#include <benchmark/benchmark.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <ostream>
#include <streambuf>

#include "db/history/export.hpp"
#include "db/history/sqlite_repository.hpp"
#include "tests/db/history_fixtures.hpp"

namespace {

using namespace imucal::db;

using namespace imucal::db::history;

constexpr int kSerials = 1000;
constexpr int kRunsPerSerial = 100;
constexpr long kRuns = static_cast<long>(kSerials) * kRunsPerSerial;
constexpr TimestampMs kT0 = 1704067200000;  // 2024-01-01T00:00:00Z
constexpr TimestampMs kMinute = 60000;

std::string serial_of(int s) {
  char buf[16];
  std::snprintf(buf, sizeof buf, "SIM-%05d", s);
  return buf;
}

/// Start time of run k (0..99) of serial s: serials interleave in time, one run a minute.
TimestampMs start_of(int s, int k) {
  return kT0 + (static_cast<TimestampMs>(k) * kSerials + s) * kMinute;
}

std::string db_path() {
  const char* p = std::getenv("IMUCAL_BENCH_DB");
  return p && *p ? p : "/tmp/imucal-history-bench.db";
}

/// Counts bytes, keeps none (the export's formatting cost without the disk's).
class CountingBuf : public std::streambuf {
 public:
  std::size_t bytes = 0;

 protected:
  std::streamsize xsputn(const char*, std::streamsize n) override {
    bytes += static_cast<std::size_t>(n);
    return n;
  }
  int overflow(int c) override {
    ++bytes;
    return c;
  }
};

void populate(const std::string& path) {
  std::filesystem::remove(path);
  std::filesystem::remove(path + "-wal");
  std::filesystem::remove(path + "-shm");
  SqliteRepository repo(path);
  const auto t0 = std::chrono::steady_clock::now();
  // One transaction per 1 000 runs (synchronous=FULL stays on; the bulk is what batches save).
  long n = 0;
  for (int k = 0; k < kRunsPerSerial; ++k) {
    repo.transaction([&] {
      for (int s = 0; s < kSerials; ++s) {
        const long seed = static_cast<long>(k) * kSerials + s;
        const RunId id = repo.create_run(test::new_run(serial_of(s), start_of(s, k)));
        repo.finish_run(id, test::pass_completion(seed, start_of(s, k) + 45 * kMinute));
        ++n;
      }
    });
  }
  const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  std::fprintf(stderr,
               "populated %ld runs (%d serials x %d) in %.1f s (%.0f runs/s, %d runs per "
               "transaction); file %.1f MiB\n",
               n, kSerials, kRunsPerSerial, secs, n / secs, kSerials,
               std::filesystem::file_size(path) / 1048576.0);
}

SqliteRepository& repo() {
  static SqliteRepository* r = [] {
    const std::string path = db_path();
    bool ok = false;
    if (std::filesystem::exists(path)) {
      try {
        SqliteOptions ro;
        ro.read_only = true;
        SqliteRepository probe(path, ro);
        long count = 0;
        probe.export_rows({std::string(serial_of(kSerials - 1)), std::nullopt, std::nullopt},
                          [&](const ExportRow&) { ++count; });
        ok = count == 2 * kRunsPerSerial;
      } catch (const std::exception&) {
        ok = false;
      }
    }
    if (!ok) populate(path);
    return new SqliteRepository(path);
  }();
  return *r;
}

void BM_History(benchmark::State& state) {
  SqliteRepository& r = repo();
  int s = 0;
  for (auto _ : state) {
    auto h = r.history(serial_of(s));
    benchmark::DoNotOptimize(h.data());
    if (h.size() != kRunsPerSerial) state.SkipWithError("wrong history size");
    s = (s + 37) % kSerials;
  }
  state.SetItemsProcessed(state.iterations() * kRunsPerSerial);
}
BENCHMARK(BM_History)->Unit(benchmark::kMicrosecond);

void BM_HistoryLast10(benchmark::State& state) {
  SqliteRepository& r = repo();
  int s = 0;
  for (auto _ : state) {
    auto h = r.history(serial_of(s), 10);
    benchmark::DoNotOptimize(h.data());
    s = (s + 37) % kSerials;
  }
}
BENCHMARK(BM_HistoryLast10)->Unit(benchmark::kMicrosecond);

void BM_ActiveParams(benchmark::State& state) {
  SqliteRepository& r = repo();
  int s = 0;
  for (auto _ : state) {
    auto a = r.active_params(serial_of(s));
    benchmark::DoNotOptimize(a.active.params.accel_bias_mps2.data());
    s = (s + 37) % kSerials;
  }
}
BENCHMARK(BM_ActiveParams)->Unit(benchmark::kMicrosecond);

void BM_Show(benchmark::State& state) {
  SqliteRepository& r = repo();
  RunId id = 1;
  for (auto _ : state) {
    auto d = r.show(id);
    benchmark::DoNotOptimize(d.calibrations.data());
    id = (id + 7919) % kRuns + 1;
  }
}
BENCHMARK(BM_Show)->Unit(benchmark::kMicrosecond);

/// stationctl with the daemon down: open read-only, read one history, close.
void BM_OpenReadOnlyAndHistory(benchmark::State& state) {
  repo();
  SqliteOptions ro;
  ro.read_only = true;
  int s = 0;
  for (auto _ : state) {
    SqliteRepository r(db_path(), ro);
    auto h = r.history(serial_of(s));
    benchmark::DoNotOptimize(h.data());
    s = (s + 37) % kSerials;
  }
}
BENCHMARK(BM_OpenReadOnlyAndHistory)->Unit(benchmark::kMicrosecond);

void BM_MarkInterruptedNoLiveRuns(benchmark::State& state) {
  SqliteRepository& r = repo();
  for (auto _ : state) {
    auto ids = r.mark_interrupted_runs(kT0);
    benchmark::DoNotOptimize(ids.data());
  }
}
BENCHMARK(BM_MarkInterruptedNoLiveRuns)->Unit(benchmark::kMicrosecond);

template <bool kJson>
void run_export(benchmark::State& state, const ExportFilter& filter) {
  SqliteRepository& r = repo();
  std::size_t rows = 0, bytes = 0;
  for (auto _ : state) {
    CountingBuf buf;
    std::ostream os(&buf);
    rows = kJson ? export_json(r, filter, os) : export_csv(r, filter, os);
    bytes = buf.bytes;
  }
  state.counters["rows"] = static_cast<double>(rows);
  state.counters["MiB"] = bytes / 1048576.0;
  state.SetItemsProcessed(state.iterations() * static_cast<long>(rows));
}

void BM_ExportCsvSerial(benchmark::State& state) {
  run_export<false>(state, {serial_of(500), std::nullopt, std::nullopt});
}
BENCHMARK(BM_ExportCsvSerial)->Unit(benchmark::kMillisecond);

void BM_ExportCsvSinceLast1Percent(benchmark::State& state) {
  run_export<false>(state, {std::nullopt, start_of(0, kRunsPerSerial - 1), std::nullopt});
}
BENCHMARK(BM_ExportCsvSinceLast1Percent)->Unit(benchmark::kMillisecond);

void BM_ExportCsvAll(benchmark::State& state) { run_export<false>(state, {}); }
BENCHMARK(BM_ExportCsvAll)->Unit(benchmark::kMillisecond)->Iterations(3);

void BM_ExportJsonAll(benchmark::State& state) { run_export<true>(state, {}); }
BENCHMARK(BM_ExportJsonAll)->Unit(benchmark::kMillisecond)->Iterations(3);

/// The repository's row decoding alone (no output formatting).
void BM_ExportRowsAll(benchmark::State& state) {
  SqliteRepository& r = repo();
  long rows = 0;
  for (auto _ : state) {
    rows = 0;
    r.export_rows({}, [&](const ExportRow& row) {
      benchmark::DoNotOptimize(&row);
      ++rows;
    });
  }
  state.counters["rows"] = static_cast<double>(rows);
  state.SetItemsProcessed(state.iterations() * rows);
}
BENCHMARK(BM_ExportRowsAll)->Unit(benchmark::kMillisecond)->Iterations(3);

}  // namespace

BENCHMARK_MAIN();
