// unixcan transport (AF_UNIX SOCK_SEQPACKET carrying struct can_frame) and the simulated IMU CAN node:
// frame fidelity, receive timestamps, the bus-side listener, 10 000 truth-simulator samples end to
// end with zero loss, and 1 % injected frame loss counted exactly. Also the socketcan transport's
// behaviour on this kernel (no AF_CAN: a clear error) or, on a kernel with vcan0, a real round trip.
#include <gtest/gtest.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <fstream>
#include <thread>

#include "calib/core/earth.hpp"
#include "calib/core/table_model.hpp"
#include "calib/sim/truth_sim.hpp"
#include "drivers/imu/can_channel.hpp"
#include "drivers/imu/imu_codec.hpp"
#include "drivers/simulated/imu_can_node.hpp"
#include "tests/support/hand_profile.hpp"

namespace imucal::drivers::imu {
namespace {

int64_t now_ns() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
      .count();
}

std::string temp_socket_path(const std::string& tag) {
  return "/tmp/imucal-can-" + tag + "-" + std::to_string(::getpid()) + ".sock";
}

/// Reads from ch until `want` frames arrived or timeout_ms passed without progress.
std::vector<ReceivedFrame> read_n(CanChannel& ch, std::size_t want, int timeout_ms = 2000) {
  std::vector<ReceivedFrame> got;
  while (got.size() < want) {
    if (!ch.wait_readable(timeout_ms)) break;
    if (ch.read(got, want - got.size()) == 0 && ch.at_end()) break;
  }
  return got;
}

std::vector<CanFrame> assorted_frames() {
  std::vector<CanFrame> v;
  for (uint8_t len = 0; len <= 8; ++len) {
    CanFrame f;
    f.can_id = 0x100u + len;
    f.len = len;
    for (uint8_t i = 0; i < len; ++i) f.data[i] = static_cast<uint8_t>(0x11 * (i + 1) + len);
    v.push_back(f);
  }
  CanFrame ext;
  ext.can_id = 0x1ABCDEF0 | kCanEffFlag;
  ext.len = 3;
  ext.data = {1, 2, 3};
  v.push_back(ext);
  CanFrame rtr;
  rtr.can_id = 0x7FF | kCanRtrFlag;
  rtr.len = 4;
  v.push_back(rtr);
  CanFrame err;
  err.can_id = kCanErrFlag | 0x04;
  err.len = 8;
  err.data = {0, 0x10, 0, 0, 0, 0, 0, 0};
  v.push_back(err);
  return v;
}

TEST(UnixCan, PairCarriesEveryFrameKindWithReceiveTimestamps) {
  auto [a, b] = CanChannel::unix_pair();
  const auto frames = assorted_frames();
  const int64_t before = now_ns();
  ASSERT_EQ(a->write(frames.data(), frames.size()), frames.size());
  const auto got = read_n(*b, frames.size());
  const int64_t after = now_ns();
  ASSERT_EQ(got.size(), frames.size());
  for (std::size_t i = 0; i < frames.size(); ++i) {
    EXPECT_EQ(got[i].frame, frames[i]) << i;
    // SO_TIMESTAMP has microsecond resolution: allow the truncation.
    EXPECT_GE(got[i].rx_time_ns, before - 1000);
    EXPECT_LE(got[i].rx_time_ns, after);
  }
  EXPECT_EQ(a->counters().tx_frames, frames.size());
  EXPECT_EQ(b->counters().rx_frames, frames.size());
  EXPECT_EQ(b->counters().rx_error_frames, 1U);
  EXPECT_EQ(b->counters().rx_malformed, 0U);
  // Closing one side ends the other.
  a.reset();
  std::vector<ReceivedFrame> more;
  ASSERT_TRUE(b->wait_readable(1000));
  EXPECT_EQ(b->read(more), 0U);
  EXPECT_TRUE(b->at_end());
}

TEST(UnixCan, ListenerIsABusForAllPeers) {
  const std::string path = temp_socket_path("bus");
  CanOpenOptions lo;
  lo.listen = true;
  auto bus = CanChannel::open("unixcan:" + path, lo);
  auto p1 = CanChannel::open("unixcan:" + path);
  auto p2 = CanChannel::open("unixcan:" + path);
  std::vector<ReceivedFrame> none;
  bus->read(none);  // accepts both peers
  EXPECT_EQ(bus->counters().peers_connected, 2U);
  // A second listener on a live path is refused (its probe connection is a short-lived peer).
  EXPECT_THROW(CanChannel::open("unixcan:" + path, lo), CanChannelError);
  const auto frames = assorted_frames();
  bus->write(frames.data(), frames.size());
  for (CanChannel* p : {p1.get(), p2.get()}) {
    const auto got = read_n(*p, frames.size());
    ASSERT_EQ(got.size(), frames.size());
    for (std::size_t i = 0; i < frames.size(); ++i) EXPECT_EQ(got[i].frame, frames[i]);
  }
  // What peer 1 writes reaches the bus side and peer 2, not peer 1 itself.
  p1->write(frames[3]);
  const auto at_bus = read_n(*bus, 1);
  ASSERT_EQ(at_bus.size(), 1U);
  EXPECT_EQ(at_bus[0].frame, frames[3]);
  const auto at_p2 = read_n(*p2, 1);
  ASSERT_EQ(at_p2.size(), 1U);
  EXPECT_EQ(at_p2[0].frame, frames[3]);
  EXPECT_FALSE(p1->wait_readable(50));
  // The listener removes its socket file; a peer sees the end.
  bus.reset();
  EXPECT_NE(::access(path.c_str(), F_OK), 0);
  read_n(*p1, 1, 1000);
  EXPECT_TRUE(p1->at_end());
}

TEST(UnixCan, ClearErrors) {
  try {
    CanChannel::open("unixcan:/tmp/imucal-no-such-dir/bus.sock");
    FAIL() << "connect to a missing path must throw";
  } catch (const CanChannelError& e) {
    EXPECT_NE(std::string(e.what()).find("/tmp/imucal-no-such-dir/bus.sock"), std::string::npos) << e.what();
  }
  const std::string file = temp_socket_path("plainfile");
  std::ofstream(file) << "not a socket\n";
  CanOpenOptions lo;
  lo.listen = true;
  EXPECT_THROW(CanChannel::open("unixcan:" + file, lo), CanChannelError);
  EXPECT_EQ(::access(file.c_str(), F_OK), 0) << "a regular file must not be replaced";
  ::unlink(file.c_str());
  EXPECT_THROW(CanChannel::open("unixcan:" + std::string(200, 'x')), CanChannelError);
  EXPECT_THROW(CanChannel::open("udpcan:foo"), CanChannelError);
  EXPECT_THROW(CanChannel::open("unixcan:"), CanChannelError);
  EXPECT_THROW(CanChannel::open("vcan0"), CanChannelError);
}

TEST(SocketCan, OpensOrFailsWithAClearMessage) {
  // This machine's kernel has no AF_CAN: opening must fail naming the URI and the reason. On a kernel
  // with vcan0 (the qemu test) the transport must round-trip a frame between two sockets.
  std::unique_ptr<CanChannel> a;
  try {
    a = CanChannel::open("socketcan:vcan0");
  } catch (const CanChannelError& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("socketcan:vcan0"), std::string::npos) << m;
    EXPECT_TRUE(m.find("no SocketCAN support") != std::string::npos || m.find("no CAN interface") != std::string::npos)
        << m;
    return;
  }
  auto b = CanChannel::open("socketcan:vcan0");
  const auto frames = assorted_frames();
  const std::vector<CanFrame> data_frames(frames.begin(), frames.end() - 1);  // no error frame on TX
  ASSERT_EQ(a->write(data_frames.data(), data_frames.size()), data_frames.size());
  const auto got = read_n(*b, data_frames.size());
  ASSERT_EQ(got.size(), data_frames.size());
  for (std::size_t i = 0; i < got.size(); ++i) EXPECT_EQ(got[i].frame, data_frames[i]);
}

/// 10 000 samples of a truth-simulated unit on a hand-made profile (100 Hz, 100 s).
calib::core::ImuSeries simulated_series() {
  const sequences::MotionProfile profile = test_support::HandProfile()
                                                .rest(20.0)
                                                .rotate(true, 90.0)
                                                .rest(20.0)
                                                .rotate(false, -90.0)
                                                .rest(100.0)
                                                .build();
  calib::core::Site site;
  site.lat_rad = 55.7 * kDegToRad;
  calib::sim::SimOptions so;
  so.rate_hz = 100.0;
  so.seed = 4;
  calib::sim::SimResult r = calib::sim::simulate(profile, calib::core::TableGeometry{}, site,
                                                 calib::effects::default_unit(), so);
  r.imu.resize(10000);
  return r.imu;
}

TEST(ImuCanNode, TenThousandSimulatedSamplesArriveWithoutLoss) {
  const calib::core::ImuSeries series = simulated_series();
  ASSERT_EQ(series.size(), 10000U);
  drivers::simulated::ImuCanNodeOptions o;
  o.speed_factor = 0.0;
  const std::string path = temp_socket_path("lossless");
  CanOpenOptions lo;
  lo.listen = true;
  lo.write_timeout_ms = 5000;  // unpaced node: wait for the reader instead of losing frames
  auto bus = CanChannel::open("unixcan:" + path, lo);
  auto reader = CanChannel::open("unixcan:" + path);
  std::vector<ReceivedFrame> none;
  bus->read(none);
  drivers::simulated::ImuCanNode node(*bus, o);
  std::thread sender([&] { node.run(series); });
  ImuFrameDecoder dec;
  std::vector<DecodedSample> out;
  std::vector<ReceivedFrame> batch;
  std::size_t frames_read = 0;
  while (frames_read < 40000 && reader->wait_readable(5000)) {
    batch.clear();
    frames_read += reader->read(batch, 512);
    for (const ReceivedFrame& f : batch) dec.push(f, out);
  }
  sender.join();
  dec.flush(out);
  ASSERT_EQ(out.size(), 10000U);
  EXPECT_EQ(dec.counters().samples_lost, 0U);
  EXPECT_EQ(dec.counters().frames_in, 40000U);
  EXPECT_EQ(dec.counters().frames_used, 40000U);
  EXPECT_EQ(dec.counters().out_of_order_frames + dec.counters().duplicate_frames +
                dec.counters().discarded_frames + dec.counters().samples_corrupt,
            0U);
  EXPECT_EQ(reader->counters().rx_frames, 40000U);
  EXPECT_EQ(reader->counters().rx_overflow, 0U);
  EXPECT_EQ(bus->counters().tx_frames, 40000U);
  EXPECT_EQ(node.stats().frames_refused, 0U);
  // Each decoded increment is the true one to within one LSB (quantisation with carry), and the
  // sums agree to within one LSB.
  Eigen::Vector3d sum_err_dth = Eigen::Vector3d::Zero(), sum_err_dv = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < out.size(); ++k) {
    ASSERT_EQ(out[k].counter, k);
    const Eigen::Vector3d e_dth = out[k].increment.dtheta_rad - series[k].dtheta_rad;
    const Eigen::Vector3d e_dv = out[k].increment.dv_mps - series[k].dv_mps;
    ASSERT_LE(e_dth.cwiseAbs().maxCoeff(), 1e-9 * (1 + 1e-6)) << k;
    ASSERT_LE(e_dv.cwiseAbs().maxCoeff(), 1e-7 * (1 + 1e-6)) << k;
    sum_err_dth += e_dth;
    sum_err_dv += e_dv;
    EXPECT_NEAR(out[k].increment.t_s, series[k].t_s, 1e-9);
  }
  EXPECT_LE(sum_err_dth.cwiseAbs().maxCoeff(), 1e-9);
  EXPECT_LE(sum_err_dv.cwiseAbs().maxCoeff(), 1e-7);
  ::unlink(path.c_str());
}

TEST(ImuCanNode, InjectedFrameLossIsCountedExactly) {
  const calib::core::ImuSeries series = simulated_series();
  drivers::simulated::ImuCanNodeOptions o;
  o.speed_factor = 0.0;
  o.frame_loss_probability = 0.01;
  o.seed = 99;
  const std::string path = temp_socket_path("loss");
  CanOpenOptions lo;
  lo.listen = true;
  lo.write_timeout_ms = 5000;  // unpaced node: wait for the reader instead of losing frames
  auto bus = CanChannel::open("unixcan:" + path, lo);
  auto reader = CanChannel::open("unixcan:" + path);
  std::vector<ReceivedFrame> none;
  bus->read(none);
  drivers::simulated::ImuCanNode node(*bus, o);
  std::vector<drivers::simulated::SampleFate> fates(series.size());
  std::thread sender([&] {
    node.run(series, nullptr,
             [&](std::size_t k, const drivers::simulated::SampleFate& f) { fates[k] = f; });
  });
  ImuFrameDecoder dec;
  std::vector<DecodedSample> out;
  std::vector<ReceivedFrame> batch;
  // Read until the node has finished and the socket is drained.
  bool done = false;
  while (true) {
    const bool readable = reader->wait_readable(200);
    if (!readable && done) break;
    if (!readable) {
      continue;
    }
    batch.clear();
    reader->read(batch, 512);
    for (const ReceivedFrame& f : batch) dec.push(f, out);
    if (!done && node.stats().increments_in == series.size()) done = true;
  }
  sender.join();
  batch.clear();
  reader->read(batch, 1 << 20);
  for (const ReceivedFrame& f : batch) dec.push(f, out);
  dec.flush(out);

  // Expectations from the injection record alone.
  std::size_t intact = 0, faulted_between = 0, incomplete = 0, last_intact = 0;
  uint64_t lost_frames = 0, discarded = 0;
  for (std::size_t k = 0; k < fates.size(); ++k)
    if (fates[k].intact()) last_intact = k;
  bool seen_intact = false;
  for (std::size_t k = 0; k < fates.size(); ++k) {
    const drivers::simulated::SampleFate& f = fates[k];
    ASSERT_TRUE(f.transmitted);
    lost_frames += static_cast<uint64_t>(f.frames_lost);
    if (f.intact()) {
      ++intact;
      seen_intact = true;
      continue;
    }
    if (seen_intact && k < last_intact) ++faulted_between;
    if (f.frames_lost < 4) {
      ++incomplete;
      discarded += static_cast<uint64_t>(4 - f.frames_lost);
    }
  }
  ASSERT_GT(lost_frames, 300U);  // ~1 % of 40 000
  ASSERT_LT(lost_frames, 500U);
  EXPECT_EQ(node.stats().frames_lost, lost_frames);
  EXPECT_EQ(dec.counters().frames_in, 40000U - lost_frames);
  EXPECT_EQ(out.size(), intact);
  EXPECT_EQ(dec.counters().samples_decoded, intact);
  EXPECT_EQ(dec.counters().samples_lost, faulted_between);
  EXPECT_EQ(dec.counters().samples_incomplete, incomplete);
  EXPECT_EQ(dec.counters().discarded_frames, discarded);
  EXPECT_EQ(dec.counters().samples_corrupt, 0U);
  // Every decoded sample is exactly the one the node encoded under that counter.
  for (const DecodedSample& d : out) {
    const drivers::simulated::SampleFate& f = fates[d.counter];
    ASSERT_TRUE(f.intact());
    for (int a = 0; a < 3; ++a) {
      EXPECT_EQ(d.increment.dtheta_rad(a), unpack_axis(f.clean[static_cast<std::size_t>(a)].data).dtheta_count * 1e-9);
      EXPECT_EQ(d.increment.dv_mps(a), unpack_axis(f.clean[static_cast<std::size_t>(a)].data).dv_count * 1e-7);
    }
  }
  ::unlink(path.c_str());
}

TEST(ImuCanNode, CorruptionAndResetAreCountedAndNeverDecodeWrong) {
  const calib::core::ImuSeries series = simulated_series();
  auto [tx, rx] = CanChannel::unix_pair();
  drivers::simulated::ImuCanNodeOptions o;
  o.speed_factor = 0.0;
  o.corruption_probability = 0.005;
  o.reset_at_s = {50.0};
  o.reset_lost_samples = 7;
  o.seed = 5;
  drivers::simulated::ImuCanNode node(*tx, o);
  ImuFrameDecoder dec;
  std::vector<DecodedSample> out;
  std::vector<drivers::simulated::SampleFate> fates;
  std::vector<ReceivedFrame> batch;
  std::size_t read = 0;
  auto drain = [&] {
    batch.clear();
    read += rx->read(batch, 4096);
    for (const ReceivedFrame& f : batch) dec.push(f, out);
  };
  for (std::size_t k = 0; k < 6000; ++k) {  // 60 s with the reset at 50 s
    fates.push_back(node.send(series[k]));
    drain();
  }
  while (read < node.stats().frames_sent && rx->wait_readable(1000)) drain();
  dec.flush(out);
  EXPECT_EQ(node.stats().resets, 1U);
  EXPECT_EQ(node.stats().increments_lost_in_reset, 7U);
  EXPECT_EQ(dec.counters().imu_resets, 1U);
  std::size_t intact = 0;
  for (const auto& f : fates) intact += f.intact();
  EXPECT_GT(node.stats().frames_corrupted, 50U);
  // Every corrupted sample is lost, every intact one decoded.
  EXPECT_EQ(out.size(), intact);
  // Decoded samples equal what was encoded (before and after the reset the counters repeat, so
  // match by order of intact samples).
  std::size_t j = 0;
  for (const auto& f : fates) {
    if (!f.intact()) continue;
    ASSERT_LT(j, out.size());
    EXPECT_EQ(out[j].counter, f.counter);
    for (int a = 0; a < 3; ++a)
      ASSERT_EQ(out[j].increment.dtheta_rad(a), unpack_axis(f.clean[static_cast<std::size_t>(a)].data).dtheta_count * 1e-9);
    ++j;
  }
}

}  // namespace
}  // namespace imucal::drivers::imu
