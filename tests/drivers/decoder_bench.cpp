// Benchmark of the IMU stream decoder alone (issue #27: "CPU within 1.5× of today's hard-wired
// decoder"): a recorded frame stream decoded from memory, so that a whole-process CPU time is the
// decoder's. The same source builds against the protocol-driven decoder (the default) and, with
// -DIMUCAL_BENCH_OLD_DECODER, against the hard-wired decoder of before issue #27 (its
// imu_codec.{hpp,cpp} and imu_protocol.{hpp,cpp} from git, first on the include path); README,
// "Benchmarks", has the commands and the figures. Not a test.
//
//   bench_decoder write FILE SECONDS [PROTOCOL.toml]   a stream of 8 000 frames/s, 13 bytes a frame
//   bench_decoder decode FILE REPEATS [PROTOCOL.toml]  decodes it REPEATS times, prints the counts
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "drivers/imu/imu_codec.hpp"

namespace {

using namespace imucal;

#ifndef IMUCAL_BENCH_OLD_DECODER
std::shared_ptr<const drivers::imu::ImuProtocolMap> protocol_arg(int argc, char** argv, int at) {
  if (argc <= at) return nullptr;
  return std::make_shared<const drivers::imu::ImuProtocolMap>(
      drivers::imu::read_protocol_map(argv[at]));
}
#endif

int write_stream(const std::string& path, double seconds, int argc, char** argv) {
#ifdef IMUCAL_BENCH_OLD_DECODER
  (void)argc;
  (void)argv;
  drivers::imu::ImuFrameEncoder enc;
  const double frames_per_sample = 4.0;
#else
  drivers::imu::ImuFrameEncoder enc(protocol_arg(argc, argv, 4), std::nullopt);
  const double frames_per_sample = enc.frames_per_sample();
#endif
  const double rate_hz = 8000.0 / frames_per_sample;
  const auto n = static_cast<size_t>(seconds * rate_hz);
  std::mt19937_64 rng(1);
  std::normal_distribution<double> g(0.0, 1.0);
  std::ofstream out(path, std::ios::binary);
  for (size_t k = 0; k < n; ++k) {
    calib::core::ImuIncrement inc;  // a unit at rest with noise, as the capture benchmark's
    inc.dt_s = 1.0 / rate_hz;
    inc.dtheta_rad =
        Eigen::Vector3d(4e-8, 0.0, -6e-8) + 2e-7 * Eigen::Vector3d(g(rng), g(rng), g(rng));
    inc.dv_mps =
        Eigen::Vector3d(0.0, 0.0, -9.81 / rate_hz) + 1e-5 * Eigen::Vector3d(g(rng), g(rng), g(rng));
    inc.temp_c = 30.0;
    for (const drivers::imu::CanFrame& f : enc.encode(inc)) {
      out.write(reinterpret_cast<const char*>(&f.can_id), 4);
      out.put(static_cast<char>(f.len));
      out.write(reinterpret_cast<const char*>(f.data.data()), 8);
    }
  }
  std::printf("%zu samples, %.0f Hz, written to %s\n", n, rate_hz, path.c_str());
  return out ? 0 : 1;
}

int decode_stream(const std::string& path, int repeats, int argc, char** argv) {
  std::ifstream in(path, std::ios::binary);
  std::vector<drivers::imu::ReceivedFrame> frames;
  char rec[13];
  while (in.read(rec, 13)) {
    drivers::imu::ReceivedFrame f;
    std::memcpy(&f.frame.can_id, rec, 4);
    f.frame.len = static_cast<uint8_t>(rec[4]);
    std::memcpy(f.frame.data.data(), rec + 5, 8);
    frames.push_back(f);
  }
  drivers::imu::DecoderOptions o;
#ifdef IMUCAL_BENCH_OLD_DECODER
  (void)argc;
  (void)argv;
#else
  o.protocol = protocol_arg(argc, argv, 4);
#endif
  uint64_t decoded = 0, lost = 0;
  std::vector<drivers::imu::DecodedSample> out;
  out.reserve(64);
  for (int r = 0; r < repeats; ++r) {
    drivers::imu::ImuFrameDecoder dec(o);
    for (const drivers::imu::ReceivedFrame& f : frames) {
      dec.push(f, out);
      decoded += out.size();
      out.clear();
    }
    dec.flush(out);
    decoded += out.size();
    out.clear();
    lost += dec.counters().samples_lost + dec.counters().samples_corrupt;
  }
  std::printf("%zu frames x %d: %llu samples decoded, %llu lost\n", frames.size(), repeats,
              static_cast<unsigned long long>(decoded), static_cast<unsigned long long>(lost));
  return lost == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  const std::string mode = argc > 1 ? argv[1] : "";
  if (argc >= 4 && mode == "write") return write_stream(argv[2], std::stod(argv[3]), argc, argv);
  if (argc >= 4 && mode == "decode") return decode_stream(argv[2], std::stoi(argv[3]), argc, argv);
  std::fprintf(stderr,
               "usage: bench_decoder write FILE SECONDS [PROTOCOL.toml]\n"
               "       bench_decoder decode FILE REPEATS [PROTOCOL.toml]\n");
  return 2;
}
