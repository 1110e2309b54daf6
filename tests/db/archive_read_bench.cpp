// Benchmark (not a test): wall time and peak memory of reading a run archive and turning it into
// the calibration input (issue #11 item 2), i.e. the archive part of `imucal bench`:
//   read_archive(dir) + to_calibration_input(archive)
//
// Usage: archive_read_bench [DIR] [--repeat N] [--move]
//   DIR        archive to read; default $IMUCAL_BENCH_ARCHIVE, else var/runs/bench60. Make it with
//              imucal simulate --sequence factory-60 --seed 42 --out var/runs/bench60
//   --repeat N repetitions (default 5); the minimum is the figure to quote
//   --move     convert with to_calibration_input(RunArchive&&) instead of the const& overload
// Prints each repetition (wall time, and the CPU time of both threads), the minimum, the process's
// peak RSS (getrusage ru_maxrss) after the first repetition and at the end, and a checksum of the
// CalibrationInput (bit patterns of every field) so that two builds can be compared for identical
// results. The first repetition of a process is the cold one (fresh heap); run it with
// --repeat 1 a few times for that figure.
// Built as build/bin/archive_read_bench (db/CMakeLists.txt, with the tests).
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "db/archive/archive_input.hpp"
#include "db/archive/run_archive.hpp"

namespace {

using namespace imucal;

// User + system CPU time of the whole process (both threads), s.
double cpu_s() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return static_cast<double>(ru.ru_utime.tv_sec + ru.ru_stime.tv_sec) +
         1e-6 * static_cast<double>(ru.ru_utime.tv_usec + ru.ru_stime.tv_usec);
}

double peak_rss_mb() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return static_cast<double>(ru.ru_maxrss) / 1024.0;  // Linux: kilobytes
}

// FNV-1a over the bit patterns of the values, a 64-bit word at a time: equal checksums <=> (almost
// surely) equal inputs.
struct Fnv {
  uint64_t h = 1469598103934665603ull;
  void word(uint64_t w) { h = (h ^ w) * 1099511628211ull; }
  void d(double v) {
    uint64_t w;
    std::memcpy(&w, &v, sizeof w);
    word(w);
  }
  void v3(const Eigen::Vector3d& v) {
    for (int i = 0; i < 3; ++i) d(v(i));
  }
};

uint64_t checksum(const calib::core::CalibrationInput& in) {
  Fnv f;
  f.word(static_cast<uint64_t>(in.setting));
  f.d(in.site.lat_rad);
  f.d(in.site.lon_rad);
  f.d(in.site.height_m);
  f.d(in.noise.arw_rad_per_sqrt_s);
  f.d(in.noise.vrw_mps_per_sqrt_s);
  for (const auto& s : in.imu) {
    f.d(s.t_s);
    f.d(s.dt_s);
    f.v3(s.dtheta_rad);
    f.v3(s.dv_mps);
    f.d(s.temp_c);
  }
  for (const auto& r : in.reference) {
    f.d(r.t_s);
    for (int i = 0; i < 9; ++i) f.d(r.C_bn_ref(i));
    f.word(r.at_rest ? 1 : 0);
    f.d(r.outer_rad);
    f.d(r.inner_rad);
  }
  for (const auto& g : in.gnss) {
    f.d(g.t_s);
    f.d(g.lat_rad);
    f.d(g.lon_rad);
    f.d(g.sigma_m);
  }
  return f.h;
}

struct Options {
  std::string dir;
  int repeat = 5;
  bool move = false;
};

bool parse_args(int argc, char** argv, Options& o) {
  const char* env = std::getenv("IMUCAL_BENCH_ARCHIVE");
  o.dir = env && *env ? env : "var/runs/bench60";
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (a == "--repeat" && i + 1 < argc) {
      o.repeat = std::max(1, std::atoi(argv[++i]));
    } else if (a == "--move") {
      o.move = true;
    } else if (!a.empty() && a[0] != '-') {
      o.dir = a;
    } else {
      std::fprintf(stderr, "usage: archive_read_bench [DIR] [--repeat N] [--move]\n");
      return false;
    }
  }
  return true;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  if (!parse_args(argc, argv, o)) return 2;
  std::error_code ec;
  if (!std::filesystem::is_directory(o.dir, ec)) {
    std::printf(
        "skipped: no archive at %s (make one: imucal simulate --sequence factory-60 --seed 42 "
        "--out var/runs/bench60, or set IMUCAL_BENCH_ARCHIVE)\n",
        o.dir.c_str());
    return 0;
  }
  using clock = std::chrono::steady_clock;
  double min_read = 1e9, min_conv = 1e9, min_total = 1e9, min_cpu = 1e9, rss_first = 0.0;
  uint64_t sum = 0;
  size_t samples = 0;
  for (int i = 0; i < o.repeat; ++i) {
    const double cpu0 = cpu_s();
    const auto t0 = clock::now();
    db::archive::RunArchive ar = db::archive::read_archive(o.dir);
    const auto t1 = clock::now();
    const calib::core::CalibrationInput in = o.move
                                                 ? db::archive::to_calibration_input(std::move(ar))
                                                 : db::archive::to_calibration_input(ar);
    const auto t2 = clock::now();
    const double cpu = cpu_s() - cpu0;
    const double read_s = std::chrono::duration<double>(t1 - t0).count();
    const double conv_s = std::chrono::duration<double>(t2 - t1).count();
    std::printf("run %d: read %.4f s  convert %.4f s  total %.4f s  (cpu %.4f s)\n", i + 1, read_s,
                conv_s, read_s + conv_s, cpu);
    min_cpu = std::min(min_cpu, cpu);
    min_read = std::min(min_read, read_s);
    min_conv = std::min(min_conv, conv_s);
    min_total = std::min(min_total, read_s + conv_s);
    if (i == 0) {
      rss_first = peak_rss_mb();
      sum = checksum(in);
      samples = in.imu.size();
    } else if (checksum(in) != sum) {
      std::printf("ERROR: repetition %d gave a different calibration input\n", i + 1);
      return 1;
    }
  }
  std::printf("archive %s: %zu samples, convert %s\n", o.dir.c_str(), samples,
              o.move ? "RunArchive&&" : "const RunArchive&");
  std::printf("min of %d: read %.4f s  convert %.4f s  total %.4f s  (cpu %.4f s)\n", o.repeat,
              min_read, min_conv, min_total, min_cpu);
  std::printf("peak RSS: %.1f MB after the first run, %.1f MB at the end\n", rss_first,
              peak_rss_mb());
  std::printf("checksum %016llx\n", static_cast<unsigned long long>(sum));
  return 0;
}
