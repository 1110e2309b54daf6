// station::run::Capture over a real unixcan socket pair, fed by the simulated IMU CAN node (or by
// the protocol encoder directly where the test needs exact control of which frames are lost): rows
// equal the transmitted increments to the LSB on the archive's time axis; lost samples are filled
// by linear interpolation between the decoded neighbours and counted; longer gaps, IMU resets,
// stream timeouts, IMU failure bits and motion inside a counted rest are faults that stop the rows
// but not the frame log; rest marking is guard-then-exactly-N rows; capture.log holds every frame
// received and parses with the candump reader.
#include "station/run/capture.hpp"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <functional>
#include <random>
#include <thread>

#include "calib/core/conventions.hpp"
#include "calib/core/site_presets.hpp"
#include "db/archive/run_archive.hpp"
#include "drivers/imu/can_channel.hpp"
#include "drivers/imu/candump_log.hpp"
#include "drivers/imu/imu_codec.hpp"
#include "drivers/imu/imu_protocol.hpp"
#include "drivers/simulated/imu_can_node.hpp"
#include "station/run/archive_writer.hpp"
#include "station/run/capture_stats.hpp"
#include "tests/support/temp_dir.hpp"

namespace imucal::station {
using namespace imucal::station::run;
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

constexpr double kRate_hzCapture = 100.0;
constexpr double kDt_s = 1.0 / kRate_hzCapture;

/// This file's temporary directories.
class TempDirCapture : public test_support::ScopedTempDir {
 public:
  TempDirCapture() : ScopedTempDir("imucal_capture_test") {}
};

db::archive::RunInfo make_info_capture() {
  db::archive::RunInfo ri;
  ri.serial = "SIM-0001";
  ri.site = calib::core::demo_factory_site();
  ri.imu_rate_hz = kRate_hzCapture;
  return ri;
}

CaptureOptions default_options() {
  CaptureOptions o;
  o.decoder.sample_rate_hz = kRate_hzCapture;
  o.settle_guard_samples = 20;
  o.flush_period = 50ms;
  return o;
}

bool wait_until(const std::function<bool()>& pred, std::chrono::milliseconds timeout = 10s) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (std::chrono::steady_clock::now() < deadline) {
    if (pred()) return true;
    std::this_thread::sleep_for(2ms);
  }
  return pred();
}

// Member order matters: the capture (declared last) stops before the writer and the sending side
// go away.
struct Rig {
  TempDirCapture tmp;
  std::unique_ptr<drivers::imu::CanChannel> tx;
  std::unique_ptr<ArchiveWriter> writer;
  std::unique_ptr<Capture> cap;
  std::string dir;

  explicit Rig(CaptureOptions opt = default_options()) : dir(tmp.sub("run")) {
    drivers::imu::CanOpenOptions co;
    co.write_timeout_ms = 5000;  // lossless back-pressure: injected loss is the only loss
    auto pair = drivers::imu::CanChannel::unix_pair(co);
    tx = std::move(pair.first);
    writer = std::make_unique<ArchiveWriter>(dir, make_info_capture());
    cap = std::make_unique<Capture>(std::move(pair.second), opt);
    cap->start();
  }
  ~Rig() {
    if (cap) cap->stop();
  }
  bool wait_rows(uint64_t n) {
    return wait_until([&] { return cap->rows() >= n; });
  }
  /// Detach, finish the archive with the capture's counters, read it back.
  db::archive::RunArchive finish() {
    cap->detach();
    db::archive::RunInfo fin = make_info_capture();
    fin.capture = to_capture_info(cap->stats(), true);
    writer->finish(fin);
    return db::archive::read_archive(dir);
  }
  /// All records of capture.log.
  std::vector<drivers::imu::CandumpRecord> log() const {
    std::vector<drivers::imu::CandumpRecord> v;
    drivers::imu::CandumpReader r(dir + "/capture.log");
    drivers::imu::CandumpRecord rec;
    while (r.next(rec)) v.push_back(rec);
    EXPECT_EQ(r.truncated_lines(), 0u);
    return v;
  }
};

// Increments: a unit resting level (gravity up on body z, earth rate) or turning about z.
calib::core::ImuIncrement still_increment(uint64_t k) {
  calib::core::ImuIncrement s;
  s.dt_s = kDt_s;
  s.dtheta_rad = Eigen::Vector3d(4.1e-7, 1.3e-8, -6.03e-7 + 1e-10 * static_cast<double>(k % 5));
  s.dv_mps = Eigen::Vector3d(2e-5, -3e-5, -9.8153 * kDt_s);
  return s;
}
calib::core::ImuIncrement moving_increment(double rate_dps) {
  calib::core::ImuIncrement s = still_increment(0);
  s.dtheta_rad(2) = rate_dps * kDegToRad * kDt_s;
  return s;
}

drivers::simulated::ImuCanNodeOptions node_options() {
  drivers::simulated::ImuCanNodeOptions o;
  o.rate_hz = kRate_hzCapture;
  o.speed_factor = 0.0;
  return o;
}

// The value the IMU transmitted for each axis of a sample: counts × LSB from the frames.
struct Transmitted {
  Eigen::Vector3d dtheta_rad, dv_mps;
};
Transmitted transmitted(const std::vector<drivers::imu::CanFrame>& frames) {
  Transmitted t;
  for (int a = 0; a < 3; ++a) {
    const drivers::imu::AxisFields f =
        drivers::imu::unpack_axis(frames[static_cast<std::size_t>(a)].data);
    t.dtheta_rad(a) = static_cast<double>(f.dtheta_count) * drivers::imu::kDthetaLsb_rad;
    t.dv_mps(a) = static_cast<double>(f.dv_count) * drivers::imu::kDvLsb_mps;
  }
  return t;
}

// ------------------------------------------------------------------------------------------------

TEST(Capture, RowsEqualTheSentIncrementsToTheLsb) {
  Rig rig;
  drivers::simulated::ImuCanNode node(*rig.tx, node_options());
  // Before attach: decoded (the stream is live) but nothing written.
  for (uint64_t k = 0; k < 20; ++k) node.send(still_increment(k));
  ASSERT_TRUE(wait_until([&] { return rig.cap->stats().samples_decoded == 20; }));
  EXPECT_EQ(rig.writer->rows(), 0u);
  rig.cap->attach(rig.writer.get());
  rig.cap->table_moving(10.5, -20.25);

  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const uint64_t n = 400;
  std::vector<calib::core::ImuIncrement> sent;
  std::vector<drivers::imu::CanFrame> frames;
  for (uint64_t k = 0; k < n; ++k) {
    calib::core::ImuIncrement s;
    s.dt_s = kDt_s;
    s.dtheta_rad = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 1e-3;  // up to ~6 deg/s per axis
    s.dv_mps = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 0.15;
    sent.push_back(s);
    const drivers::simulated::SampleFate fate = node.send(s);
    ASSERT_TRUE(fate.intact());
    frames.insert(frames.end(), fate.clean.begin(), fate.clean.end());
  }
  ASSERT_TRUE(rig.wait_rows(n));
  const db::archive::RunArchive a = rig.finish();
  ASSERT_EQ(a.imu.size(), n);
  Eigen::Vector3d sum_row_dth = Eigen::Vector3d::Zero(), sum_sent_dth = Eigen::Vector3d::Zero();
  Eigen::Vector3d sum_row_dv = Eigen::Vector3d::Zero(), sum_sent_dv = Eigen::Vector3d::Zero();
  for (uint64_t k = 0; k < n; ++k) {
    const calib::core::ImuIncrement& r = a.imu[k];
    EXPECT_EQ(r.t_s, static_cast<double>(k + 1) / kRate_hzCapture) << "row " << k;
    for (int i = 0; i < 3; ++i) {
      // Quantised with the remainder carried: each sample within 1 LSB of what was sent, and an
      // integer number of LSBs.
      EXPECT_LE(std::fabs(r.dtheta_rad(i) - sent[k].dtheta_rad(i)),
                drivers::imu::kDthetaLsb_rad * 1.000001);
      EXPECT_LE(std::fabs(r.dv_mps(i) - sent[k].dv_mps(i)), drivers::imu::kDvLsb_mps * 1.000001);
      const double cth = r.dtheta_rad(i) / drivers::imu::kDthetaLsb_rad,
                   cdv = r.dv_mps(i) / drivers::imu::kDvLsb_mps;
      EXPECT_NEAR(cth, std::round(cth), 1e-4);
      EXPECT_NEAR(cdv, std::round(cdv), 1e-4);
    }
    sum_row_dth += r.dtheta_rad;
    sum_sent_dth += sent[k].dtheta_rad;
    sum_row_dv += r.dv_mps;
    sum_sent_dv += sent[k].dv_mps;
    EXPECT_EQ(a.table[k].outer_rad, 10.5 * kDegToRad);
    EXPECT_EQ(a.table[k].inner_rad, -20.25 * kDegToRad);
    EXPECT_FALSE(a.table[k].at_rest);
  }
  // The carried remainder keeps the sums within one LSB (the carry at attach plus at the end).
  for (int i = 0; i < 3; ++i) {
    EXPECT_LE(std::fabs(sum_row_dth(i) - sum_sent_dth(i)), 1.01 * drivers::imu::kDthetaLsb_rad);
    EXPECT_LE(std::fabs(sum_row_dv(i) - sum_sent_dv(i)), 1.01 * drivers::imu::kDvLsb_mps);
  }
  const CaptureStats st = rig.cap->stats();
  EXPECT_EQ(st.samples_decoded, n);
  EXPECT_EQ(st.frames_received, 4 * n);
  EXPECT_EQ(st.frames_logged, 4 * n);
  EXPECT_EQ(st.rows_written, n);
  EXPECT_EQ(st.samples_filled, 0u);
  EXPECT_EQ(st.samples_lost, 0u);
  EXPECT_FALSE(rig.cap->fault().has_value());
  ASSERT_TRUE(a.info.capture.has_value());
  EXPECT_EQ(a.info.capture->rows_written, n);

  // capture.log: exactly the frames on the bus since attach, in order.
  const auto log = rig.log();
  ASSERT_EQ(log.size(), st.frames_logged);
  for (std::size_t j = 0; j < log.size(); ++j) {
    ASSERT_EQ(log[j].frame.frame, frames[j]) << "frame " << j;
    EXPECT_EQ(log[j].interface, rig.tx->interface_name());
  }
}

TEST(Capture, LostSamplesAreFilledByLinearInterpolationAndCounted) {
  Rig rig;
  rig.cap->attach(rig.writer.get());
  drivers::imu::ImuFrameEncoder enc;
  const uint64_t n = 120;
  std::vector<Transmitted> tx(n);
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  // Lost: samples 40-42 (3 in a row), 70, and one frame of 55 (incomplete: lost as a sample).
  auto lost = [](uint64_t k) { return (k >= 40 && k <= 42) || k == 70; };
  for (uint64_t k = 0; k < n; ++k) {
    calib::core::ImuIncrement s;
    s.dtheta_rad = Eigen::Vector3d(u(rng), u(rng), u(rng)) * 1e-4;
    s.dv_mps = Eigen::Vector3d(u(rng), u(rng), -9.81 * kDt_s);
    const auto frames = enc.encode(s);
    tx[k] = transmitted(frames);
    if (lost(k)) continue;
    for (int p = 0; p < drivers::imu::kFramesPerSample; ++p) {
      if (k == 55 && p == 1) continue;
      ASSERT_TRUE(rig.tx->write(frames[static_cast<std::size_t>(p)]));
    }
  }
  ASSERT_TRUE(rig.wait_rows(n));
  const db::archive::RunArchive a = rig.finish();
  ASSERT_EQ(a.imu.size(), n);
  auto interp = [&](uint64_t before, uint64_t after, uint64_t k, int axis, bool dth) {
    const double va = dth ? tx[before].dtheta_rad(axis) : tx[before].dv_mps(axis);
    const double vb = dth ? tx[after].dtheta_rad(axis) : tx[after].dv_mps(axis);
    return va + (vb - va) * static_cast<double>(k - before) / static_cast<double>(after - before);
  };
  for (uint64_t k = 0; k < n; ++k) {
    uint64_t before = k, after = k;
    if (lost(k) || k == 55) {
      before = k - 1;
      while (lost(before) || before == 55) --before;
      after = k + 1;
      while (lost(after) || after == 55) ++after;
    }
    for (int i = 0; i < 3; ++i) {
      if (before == k) {  // decoded: exactly what was transmitted
        EXPECT_EQ(a.imu[k].dtheta_rad(i), tx[k].dtheta_rad(i)) << "row " << k;
        EXPECT_EQ(a.imu[k].dv_mps(i), tx[k].dv_mps(i)) << "row " << k;
      } else {
        EXPECT_NEAR(a.imu[k].dtheta_rad(i), interp(before, after, k, i, true), 1e-18)
            << "row " << k;
        EXPECT_NEAR(a.imu[k].dv_mps(i), interp(before, after, k, i, false), 1e-15) << "row " << k;
      }
    }
    EXPECT_EQ(a.imu[k].t_s, static_cast<double>(k + 1) / kRate_hzCapture);
  }
  const CaptureStats st = rig.cap->stats();
  EXPECT_EQ(st.samples_filled, 5u);
  EXPECT_EQ(st.samples_lost, 5u);
  EXPECT_EQ(st.max_gap_samples, 3u);
  EXPECT_EQ(st.samples_incomplete, 1u);
  EXPECT_EQ(st.rows_written, n);
  EXPECT_EQ(st.frames_received, 4 * (n - 4) - 1);
  EXPECT_EQ(st.frames_logged, st.frames_received);
  EXPECT_FALSE(rig.cap->fault().has_value());
  EXPECT_EQ(rig.log().size(), st.frames_logged);
}

TEST(Capture, RandomLossAndCorruptionAreFilledAndCounted) {
  Rig rig;
  rig.cap->attach(rig.writer.get());
  drivers::simulated::ImuCanNodeOptions no = node_options();
  no.frame_loss_probability = 0.01;
  no.corruption_probability = 0.005;
  no.seed = 3;
  drivers::simulated::ImuCanNode node(*rig.tx, no);
  const uint64_t n = 3000;
  for (uint64_t k = 0; k < n; ++k) node.send(still_increment(k));
  ASSERT_TRUE(
      wait_until([&] { return rig.cap->stats().frames_received == node.stats().frames_sent; }));
  std::this_thread::sleep_for(50ms);  // the decoder may still hold the last samples for reordering
  const CaptureStats st = rig.cap->stats();
  EXPECT_FALSE(rig.cap->fault().has_value()) << *rig.cap->fault();
  EXPECT_GT(st.samples_lost, 50u);  // 1 - 0.99^4 + corruption: about 6 % of the samples
  EXPECT_EQ(st.samples_filled, st.samples_lost);
  EXPECT_EQ(st.rows_written, st.samples_decoded + st.samples_filled);
  EXPECT_LE(st.rows_written, n);
  EXPECT_GE(st.rows_written, n - 10);  // only a faulted tail may be missing
  EXPECT_GT(st.samples_corrupt, 0u);
  EXPECT_EQ(st.frames_logged, st.frames_received);
  EXPECT_EQ(rig.cap->rows(), st.rows_written);
}

TEST(Capture, GapLongerThanTheLimitIsAFaultButFramesAreStillLogged) {
  CaptureOptions opt = default_options();
  opt.max_gap_samples = 10;
  Rig rig(opt);
  rig.cap->attach(rig.writer.get());
  drivers::imu::ImuFrameEncoder enc;
  uint64_t frames_sent = 0;
  for (uint64_t k = 0; k < 80; ++k) {
    const auto frames = enc.encode(still_increment(k));
    if (k >= 30 && k < 41) continue;  // 11 samples lost after row 30
    for (const auto& f : frames) ASSERT_TRUE(rig.tx->write(f));
    frames_sent += 4;
  }
  ASSERT_TRUE(wait_until([&] { return rig.cap->stats().frames_received == frames_sent; }));
  ASSERT_TRUE(wait_until([&] { return rig.cap->fault().has_value(); }));
  const std::string f = *rig.cap->fault();
  EXPECT_NE(f.find("11 consecutive IMU samples lost after row 30 (t = 0.30 s)"), std::string::npos)
      << f;
  EXPECT_EQ(f.find('\n'), std::string::npos);
  EXPECT_EQ(rig.cap->rows(), 30u);
  const CaptureStats st = rig.cap->stats();
  EXPECT_EQ(st.frames_logged, frames_sent);
  rig.cap->detach();
  EXPECT_EQ(rig.log().size(), frames_sent);
}

TEST(Capture, ImuResetIsAFault) {
  Rig rig;
  rig.cap->attach(rig.writer.get());
  drivers::simulated::ImuCanNode node(*rig.tx, node_options());
  for (uint64_t k = 0; k < 50; ++k) node.send(still_increment(k));
  ASSERT_TRUE(rig.wait_rows(50));
  node.reset();
  for (uint64_t k = 50; k < 90; ++k) node.send(still_increment(k));
  ASSERT_TRUE(wait_until([&] { return rig.cap->fault().has_value(); }));
  const std::string f = *rig.cap->fault();
  EXPECT_NE(f.find("IMU reset"), std::string::npos) << f;
  EXPECT_NE(f.find("row 50 (t = 0.50 s)"), std::string::npos) << f;
  ASSERT_TRUE(
      wait_until([&] { return rig.cap->stats().frames_received == node.stats().frames_sent; }));
  const CaptureStats st = rig.cap->stats();
  EXPECT_EQ(st.imu_resets, 1u);
  EXPECT_EQ(st.rows_written, 50u);
  EXPECT_EQ(st.frames_logged, node.stats().frames_sent);
}

TEST(Capture, ImuFailureBitsAreAFault) {
  Rig rig;
  rig.cap->attach(rig.writer.get());
  drivers::simulated::ImuCanNode node(*rig.tx, node_options());
  for (uint64_t k = 0; k < 10; ++k) node.send(still_increment(k));
  node.send(still_increment(10), drivers::imu::status::kGyroFault);
  ASSERT_TRUE(wait_until([&] { return rig.cap->fault().has_value(); }));
  EXPECT_NE(rig.cap->fault()->find("IMU reports fault (IMU_STATUS.GyroFault) at row 11"),
            std::string::npos)
      << *rig.cap->fault();
  EXPECT_EQ(rig.cap->rows(), 10u);
}

TEST(Capture, RestIsGuardThenExactlyTheCountedSamples) {
  Rig rig;  // settle_guard_samples = 20
  rig.cap->attach(rig.writer.get());
  drivers::simulated::ImuCanNode node(*rig.tx, node_options());
  rig.cap->table_moving(0.0, 0.0);
  for (int k = 0; k < 30; ++k) node.send(moving_increment(10.0));
  ASSERT_TRUE(rig.wait_rows(30));
  rig.cap->begin_rest(90.0, 45.0, 100);
  EXPECT_FALSE(rig.cap->wait_rest_done(30ms));  // no samples yet
  // Still settling (moving), a few still ones, one more jolt: the guard starts after the jolt.
  for (int k = 0; k < 10; ++k) node.send(moving_increment(2.0));
  for (int k = 0; k < 5; ++k) node.send(still_increment(static_cast<uint64_t>(k)));
  node.send(moving_increment(0.06));  // just above the 0.05 deg/s threshold
  for (int k = 0; k < 200; ++k) node.send(still_increment(static_cast<uint64_t>(k)));
  EXPECT_TRUE(rig.cap->wait_rest_done(10s));
  ASSERT_TRUE(rig.wait_rows(246));
  EXPECT_EQ(rig.cap->rest_rows_done(), 100u);
  const db::archive::RunArchive a = rig.finish();
  ASSERT_EQ(a.table.size(), 246u);
  // rows 0-29 moving at (0, 0); 30-45 settling; 46-65 guard; 66-165 counted rest; 166-245 after.
  for (std::size_t k = 0; k < a.table.size(); ++k) {
    const bool rest = k >= 66 && k < 166;
    EXPECT_EQ(a.table[k].at_rest, rest) << "row " << k;
    const double outer = k < 30 ? 0.0 : 90.0, inner = k < 30 ? 0.0 : 45.0;
    EXPECT_EQ(a.table[k].outer_rad, outer * kDegToRad) << "row " << k;
    EXPECT_EQ(a.table[k].inner_rad, inner * kDegToRad) << "row " << k;
  }
  EXPECT_EQ(rig.cap->stats().rest_samples, 100u);
  ASSERT_TRUE(a.info.capture.has_value());
  EXPECT_EQ(a.info.capture->rest_samples, 100u);
  EXPECT_FALSE(rig.cap->fault().has_value());
}

TEST(Capture, RestAfterACommandedMoveWaitsForTheMoveInTheImuStream) {
  // The IMU stream lags the Modbus readings: when the table already reports in position at the
  // new pose, the samples still queued were recorded before the move (still, at the OLD pose).
  // They must not be counted as the new rest; counting starts only after the move was seen.
  Rig rig;  // settle_guard_samples = 20
  rig.cap->attach(rig.writer.get());
  drivers::simulated::ImuCanNode node(*rig.tx, node_options());
  rig.cap->move_commanded();
  rig.cap->table_moving(0.0, 0.0);
  rig.cap->begin_rest(90.0, 0.0, 50);
  for (int k = 0; k < 60; ++k) node.send(still_increment(static_cast<uint64_t>(k)));  // backlog
  EXPECT_FALSE(rig.cap->wait_rest_done(50ms)) << "still samples before the move were counted";
  for (int k = 0; k < 25; ++k) node.send(moving_increment(10.0));  // the move itself
  for (int k = 0; k < 100; ++k) node.send(still_increment(static_cast<uint64_t>(k)));
  EXPECT_TRUE(rig.cap->wait_rest_done(10s));
  ASSERT_TRUE(rig.wait_rows(185));
  const db::archive::RunArchive a = rig.finish();
  ASSERT_EQ(a.table.size(), 185u);
  // rows 0-59 backlog, 60-84 the move, 85-104 guard, 105-154 counted rest, 155-184 after.
  for (std::size_t k = 0; k < a.table.size(); ++k)
    EXPECT_EQ(a.table[k].at_rest, k >= 105 && k < 155) << "row " << k;
  EXPECT_FALSE(rig.cap->fault().has_value());
}

TEST(Capture, MotionInsideACountedRestIsAFault) {
  CaptureOptions opt = default_options();
  opt.settle_guard_samples = 5;
  Rig rig(opt);
  rig.cap->attach(rig.writer.get());
  drivers::simulated::ImuCanNode node(*rig.tx, node_options());
  rig.cap->begin_rest(0.0, 180.0, 100);
  for (int k = 0; k < 15; ++k) node.send(still_increment(static_cast<uint64_t>(k)));
  node.send(moving_increment(1.0));  // row 16 = 11th counted rest sample
  for (int k = 0; k < 20; ++k) node.send(still_increment(static_cast<uint64_t>(k)));
  EXPECT_FALSE(rig.cap->wait_rest_done(10s));
  ASSERT_TRUE(rig.cap->fault().has_value());
  const std::string f = *rig.cap->fault();
  EXPECT_NE(f.find("moved during a rest"), std::string::npos) << f;
  EXPECT_NE(f.find("row 16 (t = 0.16 s)"), std::string::npos) << f;
  EXPECT_NE(f.find("rest sample 11 of 100"), std::string::npos) << f;
  ASSERT_TRUE(wait_until([&] { return rig.cap->stats().frames_received == 36u * 4; }));
  EXPECT_EQ(rig.cap->rows(), 15u);
  EXPECT_EQ(rig.cap->stats().rest_samples, 10u);
  EXPECT_EQ(rig.cap->stats().frames_logged, 36u * 4);
}

TEST(Capture, StreamTimeoutIsAFaultOnlyWhileAttached) {
  CaptureOptions opt = default_options();
  opt.stream_timeout = 300ms;
  Rig rig(opt);
  // Not attached: silence is not a fault.
  std::this_thread::sleep_for(500ms);
  EXPECT_FALSE(rig.cap->fault().has_value());
  rig.cap->attach(rig.writer.get());
  drivers::simulated::ImuCanNode node(*rig.tx, node_options());
  for (uint64_t k = 0; k < 10; ++k) node.send(still_increment(k));
  ASSERT_TRUE(rig.wait_rows(10));
  const auto t0 = std::chrono::steady_clock::now();
  ASSERT_TRUE(wait_until([&] { return rig.cap->fault().has_value(); }, 3s));
  const double waited_s =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_GT(waited_s, 0.2);
  EXPECT_LT(waited_s, 1.5);
  EXPECT_NE(rig.cap->fault()->find("stream timeout"), std::string::npos) << *rig.cap->fault();
  EXPECT_NE(rig.cap->fault()->find("row 10 (t = 0.10 s)"), std::string::npos) << *rig.cap->fault();
}

TEST(Capture, WaitForStreamRateAndPromptStop) {
  Rig rig;
  EXPECT_FALSE(rig.cap->wait_for_stream(100ms));
  drivers::simulated::ImuCanNodeOptions no = node_options();
  no.rate_hz = 200.0;
  no.speed_factor = 1.0;  // paced: 200 samples per wall second
  std::atomic<bool> stop{false};
  calib::core::ImuSeries series(1000, still_increment(0));
  std::thread sender([&] {
    drivers::simulated::ImuCanNode node(*rig.tx, no);
    node.run(series, &stop);
  });
  EXPECT_TRUE(rig.cap->wait_for_stream(2s));
  std::this_thread::sleep_for(2500ms);  // the 2 s rate window lies inside the stream
  const double rate = rig.cap->sample_rate_observed_hz();
  stop = true;
  sender.join();
  EXPECT_NEAR(rate, 200.0, 30.0);
  const auto t0 = std::chrono::steady_clock::now();
  rig.cap->stop();
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 0.5);
}

TEST(Capture, ForeignFramesAreCountedAndLogged) {
  Rig rig;
  rig.cap->attach(rig.writer.get());
  drivers::simulated::ImuCanNode node(*rig.tx, node_options());
  for (uint64_t k = 0; k < 5; ++k) node.send(still_increment(k));
  drivers::imu::CanFrame foreign;
  foreign.can_id = 0x200;
  foreign.len = 2;
  ASSERT_TRUE(rig.tx->write(foreign));
  for (uint64_t k = 5; k < 10; ++k) node.send(still_increment(k));
  ASSERT_TRUE(rig.wait_rows(10));
  const CaptureStats st = rig.cap->stats();
  EXPECT_EQ(st.frames_foreign, 1u);
  EXPECT_EQ(st.frames_received, 41u);
  EXPECT_EQ(st.frames_logged, 41u);
  rig.cap->detach();
  const auto log = rig.log();
  ASSERT_EQ(log.size(), 41u);
  EXPECT_EQ(log[20].frame.frame, foreign);
}

// Issue #19 item 11: an aborted run's counters did not add up (384 196 logged of 384 197
// received): frames arriving between the archive's end (detach) and the capture's stop were
// counted as received. A run's counters end with its archive.
TEST(Capture, CountersEndWithTheArchiveFramesAfterDetachAreNoRunsFrames) {
  Rig rig;
  rig.cap->attach(rig.writer.get());
  drivers::simulated::ImuCanNode node(*rig.tx, node_options());
  for (uint64_t k = 0; k < 10; ++k) node.send(still_increment(k));
  ASSERT_TRUE(rig.wait_rows(10));
  rig.cap->detach();
  for (uint64_t k = 10; k < 15; ++k) node.send(still_increment(k));
  std::this_thread::sleep_for(300ms);  // the capture thread reads them within milliseconds
  rig.cap->stop();
  const CaptureStats st = rig.cap->stats();
  EXPECT_EQ(st.frames_received, 40u);
  EXPECT_EQ(st.frames_logged, st.frames_received);
  EXPECT_EQ(st.samples_decoded, 10u);
  EXPECT_EQ(rig.log().size(), 40u);
}

// Issue #10 item 7: an error flood (protocol errors, error-passive) is counted and logged while the
// rows go on; the controller going bus-off is a fault with its own reason, and no row is written
// after it (the stream has a hole of unknown length).
TEST(Capture, ErrorFloodIsCountedBusOffIsAFault) {
  Rig rig;
  rig.cap->attach(rig.writer.get());
  drivers::simulated::ImuCanNode node(*rig.tx, node_options());
  auto error_frame = [](uint32_t cls) {
    drivers::imu::CanFrame e;
    e.can_id = drivers::imu::kCanErrFlag | cls;
    e.len = 8;
    return e;
  };
  uint64_t k = 0;
  for (; k < 20; ++k) node.send(still_increment(k));
  for (int i = 0; i < 300; ++i) {  // the flood, interleaved with the IMU's samples
    ASSERT_TRUE(
        rig.tx->write(error_frame(i % 2 ? drivers::imu::kCanErrProt : drivers::imu::kCanErrCrtl)));
    if (i % 10 == 0) node.send(still_increment(k++));
  }
  ASSERT_TRUE(rig.wait_rows(k));
  // The last 9 error frames follow the last sample: the rows can be there before them (seen under
  // ThreadSanitizer: 297 of 300 counted at that moment).
  ASSERT_TRUE(wait_until([&] { return rig.cap->stats().frames_error >= 300u; }));
  EXPECT_FALSE(rig.cap->fault().has_value()) << *rig.cap->fault();
  EXPECT_EQ(rig.cap->stats().frames_error, 300u);

  ASSERT_TRUE(rig.tx->write(error_frame(drivers::imu::kCanErrBusOff)));
  ASSERT_TRUE(wait_until([&] { return rig.cap->fault().has_value(); }));
  const std::string fault = *rig.cap->fault();
  EXPECT_NE(fault.find("bus-off"), std::string::npos) << fault;
  EXPECT_NE(fault.find("300 error frames"), std::string::npos) << fault;
  EXPECT_NE(fault.find("row " + std::to_string(k + 1)), std::string::npos) << fault;
  const uint64_t rows_at_fault = rig.cap->rows();
  for (int i = 0; i < 10; ++i) node.send(still_increment(k++));
  ASSERT_TRUE(wait_until([&] { return rig.cap->stats().frames_received >= 4 * k + 301; }));
  EXPECT_EQ(rig.cap->rows(), rows_at_fault) << "rows written after bus-off";
  rig.cap->detach();
  EXPECT_EQ(rig.log().size(), 4 * k + 301)
      << "every frame, the error frames too, is in capture.log";
}

TEST(CaptureStatsJson, RoundTripAndStrictParsing) {
  CaptureStats s;
  s.frames_received = 123456789012ULL;
  s.samples_filled = 7;
  s.rest_samples = 42;
  s.max_gap_samples = 3;
  const nlohmann::json j = to_json(s);
  EXPECT_EQ(j.size(), db::archive::CaptureInfo::counters().size());
  EXPECT_EQ(j.at("frames_received").get<uint64_t>(), 123456789012ULL);
  EXPECT_EQ(j.at("rest_samples").get<uint64_t>(), 42u);
  EXPECT_EQ(capture_stats_from_json(j), s);
  EXPECT_EQ(capture_stats_from_json(nlohmann::json::parse(j.dump())), s);

  auto expect_error = [](const nlohmann::json& bad, const std::string& words) {
    try {
      capture_stats_from_json(bad);
      FAIL() << "accepted " << bad.dump();
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
    }
  };
  nlohmann::json extra = j;
  extra["frames_recieved"] = 1;
  expect_error(extra, "field 'frames_recieved': unknown member");
  nlohmann::json missing = j;
  missing.erase("rows_written");
  expect_error(missing, "field 'rows_written': missing");
  nlohmann::json negative = j;
  negative["imu_resets"] = -1;
  expect_error(negative, "field 'imu_resets': must be >= 0");
  nlohmann::json text = j;
  text["imu_resets"] = "1";
  expect_error(text, "field 'imu_resets': expected a non-negative integer");
  nlohmann::json fractional = j;
  fractional["imu_resets"] = 1.5;
  expect_error(fractional, "field 'imu_resets'");
  expect_error(nlohmann::json::array(), "expected a JSON object");
}

}  // namespace
}  // namespace imucal::station
