// Benchmark (not a test): the calibration job of issue #11 item 2 — one hour of 100 Hz data
// calibrated both ways — and its parts, so a change shows where its time went.
//
//   build/bin/imucal simulate --sequence factory-60 --seed 42 --out var/runs/bench60
//   build/bin/calibration_bench [--benchmark_filter=...]     (archive: $IMUCAL_BENCH_ARCHIVE,
//                                                            default var/runs/bench60)
//
// Parts: reading the archive and building the input, the data checks, each method alone, each
// evaluation, and the whole pipeline with the methods one after the other and concurrently.
// Wall time is what matters (the pipeline runs on two threads): UseRealTime everywhere. Peak
// memory is the process's and so covers every benchmark run: measure it with `imucal bench`.
#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>

#include "calib/ains/ains.hpp"
#include "calib/checks/data_check.hpp"
#include "calib/checks/evaluation.hpp"
#include "calib/nlsq/nlsq.hpp"
#include "calib/pipeline/calibration_pipeline.hpp"
#include "db/archive/archive_input.hpp"
#include "db/archive/run_archive.hpp"

namespace {

using namespace imucal;

std::string archive_dir() {
  const char* env = std::getenv("IMUCAL_BENCH_ARCHIVE");
  return env && *env ? env : std::string(IMUCAL_SOURCE_DIR) + "/var/runs/bench60";
}

/// The input, read once for the benchmarks of the parts.
const calib::core::CalibrationInput& input() {
  static const calib::core::CalibrationInput in =
      db::archive::to_calibration_input(db::archive::read_archive(archive_dir()));
  return in;
}

/// Parameters to evaluate: NLSQ's estimate (the evaluation's cost does not depend on which).
const calib::core::ParamSet& estimate() {
  static const calib::core::ParamSet p = calib::nlsq::calibrate_nlsq(input()).params;
  return p;
}

void BM_ReadArchive(benchmark::State& state) {
  for (auto _ : state) {
    calib::core::CalibrationInput in =
        db::archive::to_calibration_input(db::archive::read_archive(archive_dir()));
    benchmark::DoNotOptimize(in.imu.data());
  }
  state.counters["samples"] = static_cast<double>(input().imu.size());
}

void BM_CheckData(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(calib::checks::check_data(input()));
}

void BM_Ains(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(calib::ains::calibrate_ains(input()));
}

void BM_Nlsq(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(calib::nlsq::calibrate_nlsq(input()));
}

void BM_Evaluate(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(calib::checks::evaluate(input(), estimate()));
}

/// The pipeline on the input in memory; range(0): 1 concurrent, 0 one method after the other.
void BM_Pipeline(benchmark::State& state) {
  calib::pipeline::PipelineOptions options;
  options.concurrent = state.range(0) != 0;
  for (auto _ : state) benchmark::DoNotOptimize(calib::pipeline::run_calibration(input(), options));
}

/// What `imucal calibrate --method all` and `imucal bench` do: archive to verdict.
void BM_ArchiveToVerdict(benchmark::State& state) {
  calib::pipeline::PipelineOptions options;
  options.concurrent = state.range(0) != 0;
  for (auto _ : state) {
    const calib::core::CalibrationInput in =
        db::archive::to_calibration_input(db::archive::read_archive(archive_dir()));
    benchmark::DoNotOptimize(calib::pipeline::run_calibration(in, options).pass());
  }
}

BENCHMARK(BM_ReadArchive)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_CheckData)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Ains)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Nlsq)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Evaluate)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_Pipeline)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_ArchiveToVerdict)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

int main(int argc, char** argv) {
  if (!std::filesystem::is_directory(archive_dir())) {
    std::fprintf(stderr,
                 "calibration_bench: no archive at %s\n  create it with: imucal simulate "
                 "--sequence factory-60 --seed 42 --out %s\n  (or set IMUCAL_BENCH_ARCHIVE)\n",
                 archive_dir().c_str(), archive_dir().c_str());
    return 2;
  }
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 2;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
