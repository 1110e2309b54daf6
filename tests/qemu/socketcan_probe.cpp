// socketcan_probe: the SocketCAN transport (drivers::imu::CanChannel "socketcan:IFACE") against a
// real Linux kernel's CAN stack. Meant to run as root inside the QEMU guest that
// run_socketcan_probe.sh boots (this host's kernel has no AF_CAN, ARCHITECTURE §4), on a vcan
// interface that already exists and is up.
//
// Phases, each checked against what the sender itself recorded (SampleFate, the series' truth):
//   1. round trip   a simulated IMU node (drivers::simulated::ImuCanNode) sends N samples on one
//   socketcan channel,
//                   another channel on the same interface receives them: every frame bit-exact and
//                   in order, every sample decoded (drivers::imu::ImuFrameDecoder) with its
//                   counter, status and the encoder's exact counts, within one LSB of the true
//                   increment (and the sum of all increments within one LSB: quantisation carry
//                   survives the bus).
//   2. timestamps   SO_TIMESTAMP receive times lie between the send and the read, never decrease,
//   and
//                   come from the kernel: frames read 50 ms after they were sent carry their
//                   arrival time, not the read time (the channel's fallback when no timestamp
//                   arrives).
//   3. error frames the channel installs CAN_RAW_ERR_FILTER = CAN_ERR_MASK (read back with
//   getsockopt);
//                   an error frame on the bus reaches the channel as an error frame, while a raw
//                   socket with the kernel's default (empty) error filter sees the data frames but
//                   not it.
//   4. overflow     a channel with a tiny SO_RCVBUF is not read during a burst: it holds exactly
//   the
//                   first R frames, and after a marker sample its rx_overflow (SO_RXQ_OVFL) equals
//                   the burst size minus R, while a deep-buffered reader got the whole burst.
//   5. capture      the daemon's own station::run::Capture (the code stationd runs) on a socketcan
//                   channel, writing a run archive: every sample the node sent becomes a row whose
//                   increments are the transmitted counts; an error flood (protocol errors,
//                   error-passive, interleaved with samples) is counted and logged but stops
//                   nothing; an error frame of class bus-off is a fault naming it, after which no
//                   row is written; the archive reads back with every frame in capture.log.
// Prints one JSON line (stdout) and exits 0 only if every check passed.
//
// Usage: socketcan_probe [--iface vcan0] [--samples 4000] [--burst-samples 400]
//                        [--capture-samples 1000]
#include <linux/can.h>
#include <linux/can/error.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/utsname.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <ctime>
#include <filesystem>
#include <functional>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <random>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "calib/core/site_presets.hpp"
#include "db/archive/run_archive.hpp"
#include "drivers/imu/can_channel.hpp"
#include "drivers/imu/candump_log.hpp"
#include "drivers/imu/imu_codec.hpp"
#include "drivers/imu/imu_protocol.hpp"
#include "drivers/simulated/imu_can_node.hpp"
#include "station/run/archive_writer.hpp"
#include "station/run/capture.hpp"

namespace {

using namespace imucal;
using drivers::imu::CanChannel;
using drivers::imu::CanFrame;
using drivers::imu::ReceivedFrame;
using nlohmann::json;

constexpr double kRate_hz = 100.0;

int64_t realtime_ns() {
  timespec ts{};
  ::clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

/// SO_TIMESTAMP has microsecond resolution: a kernel time taken after `t_ns` is >= t_ns truncated.
int64_t floor_us(int64_t t_ns) { return t_ns - t_ns % 1000; }

struct Failures {
  std::vector<std::string> list;
  bool check(bool ok, const std::string& what) {
    if (!ok && list.size() < 50) list.push_back(what);
    return ok;
  }
};

/// A deterministic series that exercises the whole field ranges: every 4th sample is uniform over
/// ±0.5 rad / ±3.3 m/s (near the ±0.537 rad / ±3.355 m/s limits, both signs), the others are a unit
/// at rest with noise; temperatures vary, every 97th is unknown (NaN).
calib::core::ImuSeries make_series(std::size_t n, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::normal_distribution<double> g(0.0, 1.0);
  calib::core::ImuSeries s(n);
  for (std::size_t k = 0; k < n; ++k) {
    calib::core::ImuIncrement& inc = s[k];
    inc.t_s = static_cast<double>(k + 1) / kRate_hz;
    inc.dt_s = 1.0 / kRate_hz;
    if (k % 4 == 0) {
      inc.dtheta_rad = 0.5 * Eigen::Vector3d(u(rng), u(rng), u(rng));
      inc.dv_mps = 3.3 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    } else {
      inc.dtheta_rad =
          Eigen::Vector3d(4e-7, -1e-7, 6e-7) + 3e-8 * Eigen::Vector3d(g(rng), g(rng), g(rng));
      inc.dv_mps = Eigen::Vector3d(0.0, 0.0, -9.81 / kRate_hz) +
                   2e-5 * Eigen::Vector3d(g(rng), g(rng), g(rng));
    }
    inc.temp_c = k % 97 == 5 ? std::numeric_limits<double>::quiet_NaN() : 25.0 + 10.0 * u(rng);
  }
  return s;
}

/// Reads from `ch` until `out` holds `want` frames or nothing arrives for `quiet_ms`.
void read_until(CanChannel& ch, std::vector<ReceivedFrame>& out, std::size_t want, int quiet_ms) {
  while (out.size() < want) {
    if (ch.read(out, want - out.size()) > 0) continue;
    if (!ch.wait_readable(quiet_ms)) return;
  }
}

/// Reads whatever arrives until the channel stays quiet for `quiet_ms`.
void drain(CanChannel& ch, std::vector<ReceivedFrame>& out, int quiet_ms) {
  for (;;) {
    if (ch.read(out, 1024) > 0) continue;
    if (!ch.wait_readable(quiet_ms)) return;
  }
}

/// A plain CAN_RAW socket bound to `iface` with the kernel's default options (no error filter): the
/// control that shows the channel's error filter is what delivers error frames.
int open_plain_raw_socket(const std::string& iface) {
  const int s = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC | SOCK_NONBLOCK, CAN_RAW);
  if (s < 0)
    throw std::runtime_error("control socket: socket(PF_CAN): " +
                             std::string(std::strerror(errno)));
  struct ifreq ifr {};
  std::strncpy(ifr.ifr_name, iface.c_str(), IFNAMSIZ - 1);
  if (::ioctl(s, SIOCGIFINDEX, &ifr) != 0)
    throw std::runtime_error("control socket: SIOCGIFINDEX " + iface);
  struct sockaddr_can addr {};
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifr.ifr_ifindex;
  if (::bind(s, reinterpret_cast<sockaddr*>(&addr), sizeof addr) != 0)
    throw std::runtime_error("control socket: bind: " + std::string(std::strerror(errno)));
  return s;
}

std::vector<struct can_frame> read_plain(int s) {
  std::vector<struct can_frame> got;
  struct can_frame f {};
  while (::recv(s, &f, sizeof f, MSG_DONTWAIT) == static_cast<ssize_t>(sizeof f)) got.push_back(f);
  return got;
}

std::string hex(uint64_t v) {
  std::ostringstream o;
  o << "0x" << std::hex << v;
  return o.str();
}

struct Args {
  std::string iface = "vcan0";
  std::size_t samples = 4000;
  std::size_t burst_samples = 400;
  std::size_t capture_samples = 1000;
};

Args parse_args(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (i + 1 >= argc) throw std::invalid_argument("option " + k + " needs a value");
    const std::string v = argv[++i];
    if (k == "--iface") {
      a.iface = v;
    } else if (k == "--samples" || k == "--burst-samples" || k == "--capture-samples") {
      std::size_t pos = 0;
      const unsigned long n = std::stoul(v, &pos);
      if (pos != v.size() || n < 20 || n > 60000)
        throw std::invalid_argument(k + " must be an integer in [20, 60000], got '" + v + "'");
      (k == "--samples"         ? a.samples
       : k == "--burst-samples" ? a.burst_samples
                                : a.capture_samples) = n;
    } else {
      throw std::invalid_argument(
          "unknown option " + k +
          " (expected --iface, --samples, --burst-samples, --capture-samples)");
    }
  }
  return a;
}

/// Phases 1 and 2: the lossless round trip with timestamp checks.
json round_trip(CanChannel& tx, CanChannel& rx, drivers::simulated::ImuCanNode& node,
                const calib::core::ImuSeries& series, Failures& fail) {
  const std::size_t n = series.size();
  std::vector<drivers::simulated::SampleFate> fates(n);
  std::vector<ReceivedFrame> got;
  got.reserve(4 * n);
  std::vector<int64_t> sent_before_ns(n);  // realtime just before each sample's frames were written
  constexpr std::size_t kChunk = 8;        // samples per write/read cycle
  for (std::size_t k0 = 0; k0 < n; k0 += kChunk) {
    const std::size_t k1 = std::min(n, k0 + kChunk);
    for (std::size_t k = k0; k < k1; ++k) {
      sent_before_ns[k] = realtime_ns();
      fates[k] = node.send(series[k]);
    }
    const std::size_t before = got.size();
    read_until(rx, got, 4 * k1, 2000);
    const int64_t after_ns = realtime_ns();
    for (std::size_t i = before; i < got.size(); ++i)
      fail.check(got[i].rx_time_ns <= after_ns,
                 "frame " + std::to_string(i) + " timestamp after its read returned");
    if (!fail.check(got.size() == 4 * k1, "round trip: after sample " + std::to_string(k1) +
                                              " received " + std::to_string(got.size()) +
                                              " frames, expected " + std::to_string(4 * k1)))
      break;
  }

  // Every frame bit-exact, in transmission order; timestamps within [send, read] and
  // non-decreasing.
  std::size_t frame_mismatch = 0, ts_early = 0, ts_backwards = 0, ts_zero = 0;
  for (std::size_t i = 0; i < got.size() && i < 4 * n; ++i) {
    const std::size_t k = i / 4;
    if (got[i].frame != fates[k].clean[i % 4]) ++frame_mismatch;
    if (got[i].rx_time_ns <= 0) ++ts_zero;
    if (got[i].rx_time_ns < floor_us(sent_before_ns[k])) ++ts_early;
    if (i > 0 && got[i].rx_time_ns < got[i - 1].rx_time_ns) ++ts_backwards;
  }
  fail.check(frame_mismatch == 0,
             "round trip: " + std::to_string(frame_mismatch) + " frames differ from those sent");
  fail.check(ts_zero == 0,
             "timestamps: " + std::to_string(ts_zero) + " frames without a receive time");
  fail.check(ts_early == 0,
             "timestamps: " + std::to_string(ts_early) + " frames stamped before they were sent");
  fail.check(ts_backwards == 0, "timestamps: " + std::to_string(ts_backwards) + " times decrease");

  // Decode: every sample, in order, exactly the encoder's counts; within 1 LSB of the truth.
  drivers::imu::ImuFrameDecoder dec;
  std::vector<drivers::imu::DecodedSample> out;
  for (const ReceivedFrame& f : got) dec.push(f, out);
  dec.flush(out);
  fail.check(out.size() == n,
             "decoder: " + std::to_string(out.size()) + " samples decoded of " + std::to_string(n));
  const drivers::imu::DecoderCounters& c = dec.counters();
  fail.check(c.samples_lost + c.samples_incomplete + c.samples_corrupt + c.samples_late +
                     c.duplicate_frames + c.out_of_order_frames + c.discarded_frames +
                     c.error_frames + c.foreign_frames ==
                 0,
             "decoder: anomalies counted on a lossless bus");
  std::size_t count_mismatch = 0, truth_violations = 0, temp_mismatch = 0;
  double max_err_dtheta_lsb = 0.0, max_err_dv_lsb = 0.0;
  Eigen::Vector3d sum_err_dtheta = Eigen::Vector3d::Zero(), sum_err_dv = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < out.size() && k < n; ++k) {
    const drivers::imu::DecodedSample& d = out[k];
    const drivers::simulated::SampleFate& f = fates[k];
    const drivers::imu::StatusFields st = drivers::imu::unpack_status(f.clean[3].data);
    bool same = d.counter == f.counter && d.counter == static_cast<uint16_t>(k) &&
                d.sample_index == k &&
                ((d.conditions & drivers::imu::condition::kStartup) != 0) ==
                    ((st.status & drivers::imu::status::kStartup) != 0) &&
                4 * k + 3 < got.size() && d.rx_time_ns == got[4 * k + 3].rx_time_ns &&
                std::abs(d.increment.t_s - series[k].t_s) < 1e-9;
    for (int a = 0; a < 3; ++a) {
      const drivers::imu::AxisFields ax =
          drivers::imu::unpack_axis(f.clean[static_cast<std::size_t>(a)].data);
      same = same && d.increment.dtheta_rad(a) == ax.dtheta_count * drivers::imu::kDthetaLsb_rad &&
             d.increment.dv_mps(a) == ax.dv_count * drivers::imu::kDvLsb_mps;
    }
    if (!same) ++count_mismatch;
    const Eigen::Vector3d e_dth = d.increment.dtheta_rad - series[k].dtheta_rad;
    const Eigen::Vector3d e_dv = d.increment.dv_mps - series[k].dv_mps;
    sum_err_dtheta += e_dth;
    sum_err_dv += e_dv;
    max_err_dtheta_lsb =
        std::max(max_err_dtheta_lsb, e_dth.cwiseAbs().maxCoeff() / drivers::imu::kDthetaLsb_rad);
    max_err_dv_lsb =
        std::max(max_err_dv_lsb, e_dv.cwiseAbs().maxCoeff() / drivers::imu::kDvLsb_mps);
    // Quantisation with carry: each increment within one LSB of the truth (plus rounding of the
    // double arithmetic).
    if (e_dth.cwiseAbs().maxCoeff() > drivers::imu::kDthetaLsb_rad * (1 + 1e-6) ||
        e_dv.cwiseAbs().maxCoeff() > drivers::imu::kDvLsb_mps * (1 + 1e-6))
      ++truth_violations;
    const double t_true = series[k].temp_c;
    const bool temp_ok = std::isnan(t_true)
                             ? std::isnan(d.increment.temp_c) &&
                                   (d.conditions & drivers::imu::condition::kTemperatureInvalid)
                             : std::abs(d.increment.temp_c - t_true) <=
                                   0.5 * drivers::imu::kTemperatureLsb_degc + 1e-9;
    if (!temp_ok) ++temp_mismatch;
  }
  fail.check(count_mismatch == 0, "decoder: " + std::to_string(count_mismatch) +
                                      " samples differ from the encoded counts/counter/status");
  fail.check(truth_violations == 0, "decoder: " + std::to_string(truth_violations) +
                                        " increments off the truth by > 1 LSB");
  fail.check(temp_mismatch == 0,
             "decoder: " + std::to_string(temp_mismatch) + " temperatures wrong");
  const double sum_dth_lsb = sum_err_dtheta.cwiseAbs().maxCoeff() / drivers::imu::kDthetaLsb_rad;
  const double sum_dv_lsb = sum_err_dv.cwiseAbs().maxCoeff() / drivers::imu::kDvLsb_mps;
  // The remainder carry keeps the summed error within half an LSB (plus double rounding on n sums
  // of values up to 0.5 rad: ~n × 1e-16 rad, far below 1e-9).
  fail.check(sum_dth_lsb <= 0.5 + 1e-3 && sum_dv_lsb <= 0.5 + 1e-3,
             "decoder: summed increments drift by more than 1/2 LSB");
  fail.check(tx.counters().tx_frames == 4 * n && tx.counters().tx_overflow == 0 &&
                 node.stats().frames_refused == 0,
             "sender: frames refused or miscounted");
  fail.check(rx.counters().rx_frames == got.size() && rx.counters().rx_overflow == 0 &&
                 rx.counters().rx_malformed == 0,
             "receiver: counters disagree with the frames read");

  const uint64_t frames_sent = tx.counters().tx_frames;

  // Phase 2b: timestamps come from the kernel. Send one sample, read it 50 ms later: its frames
  // must carry times from before the read (the fallback would be the read time).
  int64_t min_age_us = std::numeric_limits<int64_t>::max();
  for (int rep = 0; rep < 3; ++rep) {
    const int64_t t_send = realtime_ns();
    calib::core::ImuIncrement inc = series[static_cast<std::size_t>(rep)];
    node.send(inc);
    const int64_t t_sent = realtime_ns();
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
    const int64_t t_read = realtime_ns();
    std::vector<ReceivedFrame> late;
    read_until(rx, late, 4, 2000);
    fail.check(late.size() == 4, "delayed read: " + std::to_string(late.size()) + " of 4 frames");
    for (const ReceivedFrame& f : late) {
      fail.check(f.rx_time_ns >= floor_us(t_send) && f.rx_time_ns <= t_sent,
                 "delayed read: receive time " + std::to_string(f.rx_time_ns) +
                     " not within the write call [" + std::to_string(t_send) + ", " +
                     std::to_string(t_sent) + "]");
      min_age_us = std::min(min_age_us, (t_read - f.rx_time_ns) / 1000);
    }
  }
  fail.check(min_age_us >= 40000, "delayed read: frames look stamped at read time (age " +
                                      std::to_string(min_age_us) + " us)");

  json j;
  j["samples"] = n;
  j["frames_sent"] = frames_sent;
  j["frames_received"] = got.size();
  j["samples_decoded"] = out.size();
  j["frames_differing"] = frame_mismatch;
  j["samples_differing"] = count_mismatch;
  j["max_err_dtheta_lsb"] = max_err_dtheta_lsb;
  j["max_err_dv_lsb"] = max_err_dv_lsb;
  j["sum_err_dtheta_lsb"] = sum_dth_lsb;
  j["sum_err_dv_lsb"] = sum_dv_lsb;
  j["timestamps"] = {{"zero", ts_zero},
                     {"before_send", ts_early},
                     {"decreasing", ts_backwards},
                     {"span_ms", got.empty() ? 0.0
                                             : 1e-6 * static_cast<double>(got.back().rx_time_ns -
                                                                          got.front().rx_time_ns)},
                     {"delayed_read_min_age_us", min_age_us}};
  return j;
}

/// Phase 3: error frames.
json error_frames(const Args& args, CanChannel& tx, CanChannel& rx, Failures& fail) {
  can_err_mask_t mask = 0;
  socklen_t len = sizeof mask;
  const bool got_mask = ::getsockopt(rx.fd(), SOL_CAN_RAW, CAN_RAW_ERR_FILTER, &mask, &len) == 0;
  fail.check(got_mask && mask == CAN_ERR_MASK, "error filter: CAN_RAW_ERR_FILTER reads " +
                                                   hex(mask) + ", expected CAN_ERR_MASK " +
                                                   hex(CAN_ERR_MASK));

  const int plain = open_plain_raw_socket(args.iface);
  std::vector<ReceivedFrame> none;
  drain(rx, none, 20);  // nothing pending before the test frames
  CanFrame err;
  err.can_id = drivers::imu::kCanErrFlag | CAN_ERR_BUSOFF;
  err.len = CAN_ERR_DLC;
  CanFrame data;
  data.can_id = 0x7A5;
  data.len = 3;
  data.data = {0xDE, 0xAD, 0x01, 0, 0, 0, 0, 0};
  const uint64_t err_before = rx.counters().rx_error_frames;
  const CanFrame seq[] = {data, err, data};
  const std::size_t written = tx.write(seq, 3);
  fail.check(written == 3,
             "error frames: the kernel accepted " + std::to_string(written) + " of 3 frames");
  std::vector<ReceivedFrame> got;
  read_until(rx, got, 3, 2000);
  std::this_thread::sleep_for(std::chrono::milliseconds(20));
  const std::vector<struct can_frame> plain_got = read_plain(plain);
  ::close(plain);
  const bool order_ok =
      got.size() == 3 && got[0].frame == data && got[1].frame == err && got[2].frame == data;
  fail.check(order_ok, "error frames: channel received " + std::to_string(got.size()) +
                           " frames, expected data, error, data");
  fail.check(rx.counters().rx_error_frames == err_before + 1,
             "error frames: rx_error_frames did not count the error frame");
  std::size_t plain_err = 0;
  for (const auto& f : plain_got) plain_err += (f.can_id & CAN_ERR_FLAG) ? 1 : 0;
  fail.check(plain_got.size() == 2 && plain_err == 0,
             "error frames: control socket (no error filter) got " +
                 std::to_string(plain_got.size()) + " frames, " + std::to_string(plain_err) +
                 " error frames; expected 2 data frames only");
  return {{"filter_mask", hex(mask)},
          {"delivered_to_channel", got.size() == 3 && got[1].frame.is_error() ? 1 : 0},
          {"rx_error_frames", rx.counters().rx_error_frames},
          {"control_socket_frames", plain_got.size()},
          {"control_socket_error_frames", plain_err}};
}

/// Phase 4: kernel receive-queue overflow on a tiny SO_RCVBUF.
json overflow(const Args& args, CanChannel& rx, drivers::simulated::ImuCanNode& node,
              const calib::core::ImuSeries& series, Failures& fail) {
  drivers::imu::CanOpenOptions small_opt;
  small_opt.socket_buffer_bytes = 4096;  // the kernel doubles it and enforces its minimum
  auto small = CanChannel::open("socketcan:" + args.iface, small_opt);
  int rcvbuf = 0;
  socklen_t len = sizeof rcvbuf;
  ::getsockopt(small->fd(), SOL_SOCKET, SO_RCVBUF, &rcvbuf, &len);

  const std::size_t b = args.burst_samples;
  std::vector<CanFrame> sent;
  std::vector<ReceivedFrame> deep;  // the deep-buffered reader, read between chunks
  for (std::size_t k = 0; k < b; ++k) {
    const drivers::simulated::SampleFate f = node.send(series[k % series.size()]);
    sent.insert(sent.end(), f.clean.begin(), f.clean.end());
    if (k % 8 == 7) read_until(rx, deep, sent.size(), 2000);
  }
  read_until(rx, deep, sent.size(), 2000);
  std::vector<ReceivedFrame> kept;
  drain(*small, kept, 50);
  const std::size_t r = kept.size();
  const uint64_t ovfl_before_marker = small->counters().rx_overflow;
  // The drop count travels with frames queued after the drops: send a marker sample.
  const drivers::simulated::SampleFate marker = node.send(series[0]);
  std::vector<ReceivedFrame> after;
  read_until(*small, after, 4, 2000);
  read_until(rx, deep, sent.size() + 4, 2000);
  const uint64_t ovfl = small->counters().rx_overflow;

  const std::size_t burst_frames = 4 * b;
  fail.check(deep.size() == burst_frames + 4, "overflow: deep reader got " +
                                                  std::to_string(deep.size()) + " of " +
                                                  std::to_string(burst_frames + 4) + " frames");
  fail.check(rx.counters().rx_overflow == 0, "overflow: deep reader reports kernel drops");
  fail.check(r > 0 && r < burst_frames, "overflow: not provoked (small queue kept " +
                                            std::to_string(r) + " of " +
                                            std::to_string(burst_frames) + " frames)");
  bool prefix =
      true;  // nobody read the small queue: it filled with the first frames and dropped the rest
  for (std::size_t i = 0; i < r && i < sent.size(); ++i)
    prefix = prefix && kept[i].frame == sent[i];
  fail.check(prefix, "overflow: the small queue does not hold the first frames of the burst");
  fail.check(ovfl_before_marker == 0,
             "overflow: drops reported with frames queued before any drop");
  fail.check(after.size() == 4,
             "overflow: marker sample: " + std::to_string(after.size()) + " of 4 frames");
  for (std::size_t i = 0; i < after.size(); ++i)
    fail.check(after[i].frame == marker.clean[i],
               "overflow: marker frame " + std::to_string(i) + " differs");
  fail.check(ovfl == burst_frames - r, "overflow: rx_overflow " + std::to_string(ovfl) +
                                           " != frames missed " + std::to_string(burst_frames - r));
  // The decoder's view of the small reader: floor(R/4) whole samples, then the marker after a gap
  // of exactly the samples it never completed.
  drivers::imu::ImuFrameDecoder dec;
  std::vector<drivers::imu::DecodedSample> out;
  for (const ReceivedFrame& f : kept) dec.push(f, out);
  for (const ReceivedFrame& f : after) dec.push(f, out);
  dec.flush(out);
  const std::size_t whole = r / 4;
  fail.check(out.size() == whole + 1, "overflow: decoder output " + std::to_string(out.size()) +
                                          " samples, expected " + std::to_string(whole + 1));
  fail.check(whole == 0 || dec.counters().samples_lost == b - whole,
             "overflow: decoder samples_lost " + std::to_string(dec.counters().samples_lost) +
                 ", expected " + std::to_string(b - whole));
  return {{"rcvbuf_bytes", rcvbuf},
          {"burst_frames", burst_frames},
          {"kept_frames", r},
          {"rx_overflow", ovfl},
          {"missed_frames", burst_frames - r},
          {"decoded_samples", out.size()},
          {"decoder_samples_lost", dec.counters().samples_lost}};
}

/// Waits (bounded) until `pred` holds.
bool wait_for(const std::function<bool()>& pred, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (pred()) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  return pred();
}

/// Phase 5: stationd's Capture on the real kernel's CAN stack, with an error flood and bus-off.
json daemon_capture(const Args& args, Failures& fail) {
  using namespace std::chrono_literals;
  const std::string dir = "/tmp/imucal-capture-run";
  std::filesystem::remove_all(dir);
  db::archive::RunInfo info;
  info.serial = "QEMU-0001";
  info.site = calib::core::demo_factory_site();
  info.imu_rate_hz = kRate_hz;
  station::run::ArchiveWriter writer(dir, info);
  station::run::CaptureOptions co;
  co.decoder.sample_rate_hz = kRate_hz;
  co.flush_period = 50ms;
  station::run::Capture cap(CanChannel::open("socketcan:" + args.iface), co);
  cap.start();
  auto tx = CanChannel::open("socketcan:" + args.iface);
  drivers::simulated::ImuCanNodeOptions no;
  no.rate_hz = kRate_hz;
  no.speed_factor = 0.0;
  drivers::simulated::ImuCanNode node(*tx, no);
  const calib::core::ImuSeries series = make_series(args.capture_samples + 20, 20261125);
  std::vector<std::vector<CanFrame>> sent;
  auto send = [&](std::size_t k) { sent.push_back(node.send(series[k]).clean); };
  auto error_frame = [](uint32_t cls) {
    CanFrame e;
    e.can_id = drivers::imu::kCanErrFlag | cls;
    e.len = 8;
    return e;
  };

  cap.attach(&writer);
  // Samples with an error flood woven in: every sample is followed by `flood_per_sample` errors.
  const std::size_t n = args.capture_samples;
  const int per_sample = 5;
  std::size_t errors = 0;
  for (std::size_t k = 0; k < n; ++k) {
    send(k);
    for (int i = 0; i < per_sample; ++i, ++errors)
      fail.check(
          tx->write(error_frame(i % 2 ? drivers::imu::kCanErrProt : drivers::imu::kCanErrCrtl)),
          "capture: error frame write");
    if (k % 50 == 49)
      wait_for([&] { return cap.rows() >= k + 1; }, 5s);  // no kernel queue overflow
  }
  // The last sample completes row n before its own error frames are read: wait for every frame
  // sent, not only the rows, or the count below races the reader (CI saw 4996 of 5000).
  const uint64_t frames_before_bus_off = 4 * n + errors;
  const bool all_rows = wait_for(
      [&] { return cap.rows() >= n && cap.stats().frames_received >= frames_before_bus_off; }, 10s);
  const station::run::CaptureStats during = cap.stats();
  fail.check(all_rows && cap.rows() == n, "capture: " + std::to_string(cap.rows()) + " rows of " +
                                              std::to_string(n) +
                                              " samples sent through the error flood");
  fail.check(!cap.fault(),
             "capture: the error flood faulted the capture: " + cap.fault().value_or(""));
  fail.check(during.frames_error == errors, "capture: frames_error " +
                                                std::to_string(during.frames_error) + ", sent " +
                                                std::to_string(errors));
  fail.check(during.samples_decoded == n && during.samples_lost == 0 && during.rx_overflow == 0,
             "capture: decoded " + std::to_string(during.samples_decoded) + ", lost " +
                 std::to_string(during.samples_lost) + ", rx_overflow " +
                 std::to_string(during.rx_overflow));

  // Bus-off, then more samples: a fault naming it, and no row after it.
  fail.check(tx->write(error_frame(drivers::imu::kCanErrBusOff)), "capture: bus-off frame write");
  const bool faulted = wait_for([&] { return cap.fault().has_value(); }, 5s);
  const std::string fault = cap.fault().value_or("");
  fail.check(faulted && fault.find("bus-off") != std::string::npos &&
                 fault.find(args.iface) != std::string::npos,
             "capture: bus-off not reported as such: \"" + fault + "\"");
  const uint64_t rows_at_fault = cap.rows();
  for (std::size_t k = n; k < n + 20; ++k) send(k);
  const uint64_t frames_total = 4 * (n + 20) + errors + 1;
  wait_for([&] { return cap.stats().frames_received >= frames_total; }, 5s);
  fail.check(cap.rows() == rows_at_fault, "capture: rows written after bus-off");
  cap.detach();
  const station::run::CaptureStats end = cap.stats();
  cap.stop();
  fail.check(end.frames_received == frames_total && end.frames_logged == frames_total,
             "capture: received " + std::to_string(end.frames_received) + ", logged " +
                 std::to_string(end.frames_logged) + ", sent " + std::to_string(frames_total));

  // The archive: rows equal to the transmitted counts of every sample, the log holds every frame.
  db::archive::RunInfo fin = info;
  fin.capture = station::run::to_capture_info(end, false);
  writer.finish(fin);
  const db::archive::RunArchive a = db::archive::read_archive(dir);
  std::size_t row_mismatch = 0;
  for (std::size_t k = 0; k < std::min<std::size_t>(a.imu.size(), n); ++k) {
    for (int ax = 0; ax < 3; ++ax) {
      const drivers::imu::AxisFields f =
          drivers::imu::unpack_axis(sent[k][static_cast<std::size_t>(ax)].data);
      if (a.imu[k].dtheta_rad(ax) !=
              static_cast<double>(f.dtheta_count) * drivers::imu::kDthetaLsb_rad ||
          a.imu[k].dv_mps(ax) != static_cast<double>(f.dv_count) * drivers::imu::kDvLsb_mps)
        ++row_mismatch;
    }
  }
  fail.check(a.imu.size() == n && row_mismatch == 0,
             "capture: archive has " + std::to_string(a.imu.size()) + " rows, " +
                 std::to_string(row_mismatch) + " axis values differ from the transmitted counts");
  drivers::imu::CandumpReader log(dir + "/capture.log");
  drivers::imu::CandumpRecord rec;
  std::size_t logged = 0, logged_errors = 0;
  while (log.next(rec)) {
    ++logged;
    if (rec.frame.frame.is_error()) ++logged_errors;
  }
  fail.check(logged == frames_total && logged_errors == errors + 1,
             "capture: capture.log holds " + std::to_string(logged) + " frames (" +
                 std::to_string(logged_errors) + " error frames)");
  return {{"samples", n},           {"rows", a.imu.size()},
          {"error_frames", errors}, {"frames_error", during.frames_error},
          {"fault", fault},         {"rows_after_bus_off", cap.rows() - rows_at_fault},
          {"frames_logged", logged}};
}

}  // namespace

int main(int argc, char** argv) {
  Failures fail;
  json summary;
  summary["probe"] = "socketcan";
  struct utsname u {};
  if (::uname(&u) == 0) summary["kernel"] = u.release;
  const auto t0 = std::chrono::steady_clock::now();
  try {
    const Args args = parse_args(argc, argv);
    summary["iface"] = args.iface;
    auto tx = CanChannel::open("socketcan:" + args.iface);
    auto rx = CanChannel::open("socketcan:" + args.iface);
    const calib::core::ImuSeries series = make_series(args.samples, 20240611);
    drivers::simulated::ImuCanNodeOptions no;
    no.rate_hz = kRate_hz;
    no.speed_factor = 0.0;
    drivers::simulated::ImuCanNode node(*tx, no);
    summary["round_trip"] = round_trip(*tx, *rx, node, series, fail);
    summary["error_frames"] = error_frames(args, *tx, *rx, fail);
    summary["overflow"] = overflow(args, *rx, node, series, fail);
    summary["capture"] = daemon_capture(args, fail);
  } catch (const std::exception& e) {
    fail.list.push_back(std::string("exception: ") + e.what());
  }
  summary["elapsed_s"] =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  summary["failures"] = fail.list;
  summary["ok"] = fail.list.empty();
  std::cout << summary.dump() << std::endl;
  return fail.list.empty() ? 0 : 1;
}
