// Benchmark of the IMU CAN capture path (issue 3, "Benchmarks"): encode + unixcan send (simulated
// IMU node on the bus side) + receive + decode (+ optionally the candump capture log), at 8000
// frames/s equivalent (2000 Hz × 4 frames = a 1 Mbit/s bus at full load) for 60 simulated seconds.
// Not a unit test (no *_test.cpp name). Build target: bench_can_path (wired by the lead).
//
//   BM_CanPathPaced/speed/log/protocol
//                               the node paced at 8000 frames/s × speed on CLOCK_MONOTONIC, no
//                               back-pressure (a full queue loses frames, as on a bus); speed 1 =
//                               real time (60 s). protocol 0: the built-in one (2000 Hz × 4
//                               frames); 1: tests/data/protocols/rates16 (2667 Hz × 3 frames; issue
//                               #27). Counters: frames, lost (must be 0), capture CPU share of one
//                               core at 8000 frames/s (the reader thread's CPU time ÷ simulated
//                               time), node CPU.
//   BM_CanPathUnpaced/log       as fast as possible with back-pressure: the path's ceiling in
//   frames/s.
#include <benchmark/benchmark.h>
#include <time.h>
#include <unistd.h>

#include <atomic>
#include <random>
#include <stdexcept>
#include <string>
#include <thread>

#include "drivers/imu/can_channel.hpp"
#include "drivers/imu/candump_log.hpp"
#include "drivers/imu/imu_codec.hpp"
#include "drivers/simulated/imu_can_node.hpp"

namespace {

using namespace imucal;

constexpr double kFramesPerSecond = 8000.0;
constexpr double kSimulated_s = 60.0;

std::shared_ptr<const drivers::imu::ImuProtocolMap> protocol_of(int64_t which) {
  if (which == 0) return drivers::imu::builtin_protocol_map();
  return std::make_shared<const drivers::imu::ImuProtocolMap>(drivers::imu::read_protocol_map(
      std::string(IMUCAL_SOURCE_DIR) + "/tests/data/protocols/rates16.toml"));
}

double thread_cpu_s() {
  timespec ts{};
  ::clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
  return static_cast<double>(ts.tv_sec) + 1e-9 * static_cast<double>(ts.tv_nsec);
}

calib::core::ImuSeries synthetic_series(std::size_t n, double rate_hz) {
  // A unit at rest with noise (values change every sample, as real data do).
  std::mt19937_64 rng(1);
  std::normal_distribution<double> g(0.0, 1.0);
  calib::core::ImuSeries s(n);
  for (std::size_t k = 0; k < n; ++k) {
    s[k].t_s = static_cast<double>(k + 1) / rate_hz;
    s[k].dt_s = 1.0 / rate_hz;
    s[k].dtheta_rad = Eigen::Vector3d(4e-8, 0.0, -6e-8) + 2e-9 * Eigen::Vector3d(g(rng), g(rng), g(rng));
    s[k].dv_mps =
        Eigen::Vector3d(0.0, 0.0, -9.81 / rate_hz) + 1e-6 * Eigen::Vector3d(g(rng), g(rng), g(rng));
    s[k].temp_c = 30.0;
  }
  return s;
}

struct PathResult {
  uint64_t frames_received = 0;
  uint64_t samples_decoded = 0;
  uint64_t samples_lost = 0;
  uint64_t frames_refused = 0;
  double reader_cpu_s = 0.0;
  double node_cpu_s = 0.0;
  double wall_s = 0.0;
};

PathResult run_path(double speed, bool write_log, int64_t protocol = 0) {
  const auto map = protocol_of(protocol);
  const double rate_hz = kFramesPerSecond / static_cast<double>(map->messages.size());
  const std::size_t n = static_cast<std::size_t>(rate_hz * kSimulated_s);
  const calib::core::ImuSeries series = synthetic_series(n, rate_hz);
  const std::string path = "/tmp/imucal-bench-can-" + std::to_string(::getpid()) + ".sock";
  const std::string log_path = "/tmp/imucal-bench-can-" + std::to_string(::getpid()) + ".log";
  drivers::imu::CanOpenOptions lo;
  lo.listen = true;
  lo.write_timeout_ms = speed <= 0.0 ? 5000 : 0;  // unpaced: back-pressure; paced: a bus loses frames
  auto bus = drivers::imu::CanChannel::open("unixcan:" + path, lo);
  auto reader = drivers::imu::CanChannel::open("unixcan:" + path);
  std::vector<drivers::imu::ReceivedFrame> none;
  bus->read(none);

  drivers::simulated::ImuCanNodeOptions o;
  o.rate_hz = rate_hz;
  o.speed_factor = speed;
  o.protocol = map;
  drivers::simulated::ImuCanNode node(*bus, o);
  std::atomic<bool> node_done{false};
  PathResult r;
  const auto wall0 = std::chrono::steady_clock::now();
  std::thread sender([&] {
    const double c0 = thread_cpu_s();
    node.run(series);
    r.node_cpu_s = thread_cpu_s() - c0;
    node_done.store(true);
  });

  // The capture side, as stationd's capture thread would do it: poll, read a batch, decode, log.
  const double c0 = thread_cpu_s();
  drivers::imu::DecoderOptions dopt;
  dopt.sample_rate_hz = rate_hz;
  dopt.protocol = map;
  drivers::imu::ImuFrameDecoder dec(dopt);
  std::unique_ptr<drivers::imu::CandumpWriter> log;
  if (write_log) log = std::make_unique<drivers::imu::CandumpWriter>(log_path);
  std::vector<drivers::imu::ReceivedFrame> batch;
  std::vector<drivers::imu::DecodedSample> out;
  batch.reserve(512);
  out.reserve(256);
  for (;;) {
    const bool readable = reader->wait_readable(100);
    if (!readable) {
      if (node_done.load()) break;
      continue;
    }
    batch.clear();
    reader->read(batch, 512);
    for (const drivers::imu::ReceivedFrame& f : batch) {
      dec.push(f, out);
      if (log) log->write(f, "can0");
    }
    r.samples_decoded += out.size();
    out.clear();
  }
  dec.flush(out);
  r.samples_decoded += out.size();
  if (log) log->close();
  r.reader_cpu_s = thread_cpu_s() - c0;
  sender.join();
  r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  r.frames_received = reader->counters().rx_frames;
  r.samples_lost = n - r.samples_decoded;
  r.frames_refused = node.stats().frames_refused;
  ::unlink(log_path.c_str());
  return r;
}

void report(benchmark::State& state, const PathResult& r) {
  state.counters["frames"] = static_cast<double>(r.frames_received);
  state.counters["lost_samples"] = static_cast<double>(r.samples_lost);
  state.counters["refused_frames"] = static_cast<double>(r.frames_refused);
  state.counters["capture_cpu_s"] = r.reader_cpu_s;
  state.counters["node_cpu_s"] = r.node_cpu_s;
  state.counters["wall_s"] = r.wall_s;
  state.counters["frames_per_s"] = static_cast<double>(r.frames_received) / r.wall_s;
  // CPU share of one core that capturing a full-load bus costs: capture CPU per simulated second.
  state.counters["capture_cpu_share_at_8000fps_pct"] = 100.0 * r.reader_cpu_s / kSimulated_s;
  state.counters["capture_us_per_frame"] = 1e6 * r.reader_cpu_s / static_cast<double>(r.frames_received);
  if (r.samples_lost != 0) state.SkipWithError("samples were lost on the CAN path");
}

void BM_CanPathPaced(benchmark::State& state) {
  const double speed = static_cast<double>(state.range(0));
  PathResult r;
  for (auto _ : state) r = run_path(speed, state.range(1) != 0, state.range(2));
  report(state, r);
}
BENCHMARK(BM_CanPathPaced)
    ->Args({10, 1, 0})
    ->Args({1, 1, 0})
    ->Args({10, 1, 1})
    ->Args({1, 1, 1})
    ->Iterations(1)
    ->Unit(benchmark::kSecond)
    ->UseRealTime();

void BM_CanPathUnpaced(benchmark::State& state) {
  PathResult r;
  for (auto _ : state) r = run_path(0.0, state.range(0) != 0);
  report(state, r);
}
BENCHMARK(BM_CanPathUnpaced)->Arg(0)->Arg(1)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
