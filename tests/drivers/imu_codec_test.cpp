// IMU CAN codec: LSB/range bounds of ARCHITECTURE §4, bit layout, round trips, quantisation carry,
// and the decoder's reassembly and counters under loss, corruption, reordering, duplication and
// resets.
#include "drivers/imu/imu_codec.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <set>
#include <vector>

#include "calib/core/conventions.hpp"

namespace imucal::drivers::imu {
namespace {

constexpr double kRate_hz = 100.0;

calib::core::ImuIncrement random_increment(std::mt19937_64& rng, double dth_max = 0.17,
                                           double dv_max = 1.9) {
  std::uniform_real_distribution<double> a(-dth_max, dth_max), v(-dv_max, dv_max), t(-40.0, 85.0);
  calib::core::ImuIncrement inc;
  inc.dt_s = 1.0 / kRate_hz;
  for (int i = 0; i < 3; ++i) {
    inc.dtheta_rad(i) = a(rng);
    inc.dv_mps(i) = v(rng);
  }
  inc.temp_c = t(rng);
  return inc;
}

/// Frames of n random samples (fresh encoder, carry on) plus the test's own expectation of every
/// transmitted value: an independent quantiser with carry (round half away from zero, like the
/// encoder's std::round).
struct Stream {
  std::vector<std::vector<CanFrame>> samples;
  std::vector<std::array<int64_t, 6>> expected_counts;  // dθ xyz, dv xyz in LSB counts
};

Stream make_stream(int n, uint64_t seed = 7) {
  std::mt19937_64 rng(seed);
  ImuFrameEncoder enc;
  Stream s;
  std::array<double, 6> carry{};
  for (int k = 0; k < n; ++k) {
    const calib::core::ImuIncrement inc = random_increment(rng);
    s.samples.push_back(enc.encode(inc));
    std::array<int64_t, 6> c{};
    for (int i = 0; i < 6; ++i) {
      const double lsb = i < 3 ? 1e-9 : 1e-7;
      const double x = i < 3 ? inc.dtheta_rad(i) : inc.dv_mps(i - 3);
      const double total = x + carry[static_cast<size_t>(i)];
      c[static_cast<size_t>(i)] = std::llround(total / lsb);
      carry[static_cast<size_t>(i)] = total - static_cast<double>(c[static_cast<size_t>(i)]) * lsb;
    }
    s.expected_counts.push_back(c);
  }
  return s;
}

std::vector<ReceivedFrame> flatten(const Stream& s) {
  std::vector<ReceivedFrame> out;
  int64_t t = 1'700'000'000'000'000'000;
  for (const auto& smp : s.samples) {
    for (const CanFrame& f : smp) out.push_back({f, t});
    t += static_cast<int64_t>(1e9 / kRate_hz);
  }
  return out;
}

struct DecodeRun {
  std::vector<DecodedSample> out;
  DecoderCounters counters;
};

DecodeRun decode(const std::vector<ReceivedFrame>& frames) {
  DecoderOptions o;
  o.sample_rate_hz = kRate_hz;
  ImuFrameDecoder dec(o);
  DecodeRun r;
  for (const ReceivedFrame& f : frames) dec.push(f, r.out);
  dec.flush(r.out);
  r.counters = dec.counters();
  return r;
}

/// Every decoded sample must carry exactly the values transmitted under its counter.
void expect_all_exact(const DecodeRun& r, const Stream& s) {
  uint16_t prev = 0;
  for (size_t k = 0; k < r.out.size(); ++k) {
    const DecodedSample& d = r.out[k];
    if (k > 0) {
      ASSERT_NE(d.counter, prev) << "sample output twice";
      ASSERT_LT(static_cast<uint16_t>(d.counter - prev), 0x8000) << "samples out of counter order";
    }
    prev = d.counter;
    ASSERT_LT(d.counter, s.expected_counts.size());
    const auto& c = s.expected_counts[d.counter];
    for (int i = 0; i < 3; ++i) {
      ASSERT_EQ(d.increment.dtheta_rad(i), static_cast<double>(c[static_cast<size_t>(i)]) * 1e-9) << "counter " << d.counter;
      ASSERT_EQ(d.increment.dv_mps(i), static_cast<double>(c[static_cast<size_t>(i + 3)]) * 1e-7) << "counter " << d.counter;
    }
  }
}

TEST(ImuProtocol, LsbAndRangeMeetTheDesignBounds) {
  EXPECT_LE(kDthetaLsb_rad, 1e-9);
  EXPECT_LE(kDvLsb_mps, 1e-7);
  // ±(1000 °/s · 0.01 s) and ±(20 g · 0.01 s) per increment at 100 Hz must fit the fields.
  const double dth_needed = 1000.0 * kDegToRad * 0.01;
  const double dv_needed = 20.0 * kStandardGravity_mps2 * 0.01;
  EXPECT_GE(static_cast<double>(kDthetaMaxCount) * kDthetaLsb_rad, dth_needed);
  EXPECT_GE(-static_cast<double>(kDthetaMinCount) * kDthetaLsb_rad, dth_needed);
  EXPECT_GE(static_cast<double>(kDvMaxCount) * kDvLsb_mps, dv_needed);
  EXPECT_GE(-static_cast<double>(kDvMinCount) * kDvLsb_mps, dv_needed);
  // Those extremes go through without the saturation bits.
  ImuFrameEncoder enc(kDefaultImuBaseId, false);
  calib::core::ImuIncrement inc;
  inc.dtheta_rad = Eigen::Vector3d(dth_needed, -dth_needed, dth_needed);
  inc.dv_mps = Eigen::Vector3d(-dv_needed, dv_needed, dv_needed);
  inc.temp_c = 25.0;
  const auto frames = enc.encode(inc);
  const StatusFields st = unpack_status(frames[3].data);
  EXPECT_EQ(st.status & (status::kGyroSaturated | status::kAccelSaturated), 0);
  EXPECT_EQ(unpack_axis(frames[1].data).dtheta_count, std::llround(-dth_needed / 1e-9));
  EXPECT_EQ(unpack_axis(frames[0].data).dv_count, std::llround(-dv_needed / 1e-7));
}

TEST(ImuProtocol, Crc16CheckValue) {
  // The catalogue check value of CRC-16/CCITT-FALSE (a.k.a. CRC-16/IBM-3740).
  const char* s = "123456789";
  EXPECT_EQ(crc16_ccitt_false(reinterpret_cast<const uint8_t*>(s), 9), 0x29B1);
}

TEST(ImuProtocol, BitLayoutMatchesTheDocumentedFields) {
  // Axis frame: counter bits 0-7, dθ s30 at bits 8-37, dv s26 at bits 38-63, little-endian.
  AxisFields a;
  a.counter_lo = 0xA5;
  a.dtheta_count = 1;
  a.dv_count = 0;
  EXPECT_EQ(pack_axis(a), (std::array<uint8_t, 8>{0xA5, 0x01, 0, 0, 0, 0, 0, 0}));
  a.dtheta_count = -1;  // 30 one-bits: bytes 1-3 full, low 6 bits of byte 4
  EXPECT_EQ(pack_axis(a), (std::array<uint8_t, 8>{0xA5, 0xFF, 0xFF, 0xFF, 0x3F, 0, 0, 0}));
  a.dtheta_count = 0;
  a.dv_count = 1;  // bit 38 = byte 4 bit 6
  EXPECT_EQ(pack_axis(a), (std::array<uint8_t, 8>{0xA5, 0, 0, 0, 0x40, 0, 0, 0}));
  a.dv_count = -1;  // bits 38-63
  EXPECT_EQ(pack_axis(a), (std::array<uint8_t, 8>{0xA5, 0, 0, 0, 0xC0, 0xFF, 0xFF, 0xFF}));
  a.dtheta_count = static_cast<int32_t>(kDthetaMinCount);
  a.dv_count = static_cast<int32_t>(kDvMaxCount);
  const AxisFields back = unpack_axis(pack_axis(a));
  EXPECT_EQ(back.dtheta_count, kDthetaMinCount);
  EXPECT_EQ(back.dv_count, kDvMaxCount);
  // Status frame: counter lo byte 0, status bytes 1-2, temperature bytes 3-4, counter hi byte 5,
  // CRC bytes 6-7, all little-endian.
  StatusFields s;
  s.counter = 0x1234;
  s.status = 0x0021;
  s.temperature_count = -2;
  s.crc = 0xBEEF;
  EXPECT_EQ(pack_status(s), (std::array<uint8_t, 8>{0x34, 0x21, 0x00, 0xFE, 0xFF, 0x12, 0xEF, 0xBE}));
  const StatusFields sb = unpack_status(pack_status(s));
  EXPECT_EQ(sb.counter, 0x1234);
  EXPECT_EQ(sb.status, 0x0021);
  EXPECT_EQ(sb.temperature_count, -2);
  EXPECT_EQ(sb.crc, 0xBEEF);
}

TEST(ImuCodec, RoundTripIsExactToTheLsb) {
  std::mt19937_64 rng(3);
  ImuFrameDecoder dec;
  std::vector<DecodedSample> out;
  for (int k = 0; k < 2000; ++k) {
    ImuFrameEncoder enc(kDefaultImuBaseId, false);  // no carry: each value is round(x / LSB)
    calib::core::ImuIncrement inc = random_increment(rng, 0.5, 3.3);
    const uint16_t flags = static_cast<uint16_t>(k % 2 ? status::kBitFail : 0);
    for (const CanFrame& f : enc.encode(inc, flags)) dec.push({f, 0}, out);
    // A fresh encoder restarts the counter at 0: the decoder sees a reset every time except the first.
    ASSERT_EQ(out.size(), static_cast<size_t>(k + 1));
    const DecodedSample& d = out.back();
    for (int i = 0; i < 3; ++i) {
      EXPECT_EQ(d.increment.dtheta_rad(i), std::round(inc.dtheta_rad(i) / 1e-9) * 1e-9);
      EXPECT_EQ(d.increment.dv_mps(i), std::round(inc.dv_mps(i) / 1e-7) * 1e-7);
    }
    EXPECT_EQ(d.increment.temp_c, std::round(inc.temp_c / 0.01) * 0.01);
    EXPECT_EQ((d.conditions & condition::kFault) != 0, flags != 0);
    EXPECT_EQ(dec.flag_names(d.flags, condition::kFault), flags ? "IMU_STATUS.BitFail" : "");
    EXPECT_TRUE(d.conditions & condition::kStartup);
  }
}

TEST(ImuCodec, SaturationClipsAndFlags) {
  ImuFrameEncoder enc;
  calib::core::ImuIncrement inc;
  inc.dtheta_rad = Eigen::Vector3d(1.0, 0.0, 0.0);  // beyond ±0.5369 rad
  inc.dv_mps = Eigen::Vector3d(0.0, -5.0, 0.0);     // beyond ±3.355 m/s
  inc.temp_c = std::nan("");
  const auto frames = enc.encode(inc);
  EXPECT_EQ(unpack_axis(frames[0].data).dtheta_count, kDthetaMaxCount);
  EXPECT_EQ(unpack_axis(frames[1].data).dv_count, kDvMinCount);
  const StatusFields st = unpack_status(frames[3].data);
  EXPECT_TRUE(st.status & status::kGyroSaturated);
  EXPECT_TRUE(st.status & status::kAccelSaturated);
  EXPECT_TRUE(st.status & status::kTempInvalid);
  EXPECT_EQ(st.temperature_count, kTemperatureUnknown);
  ImuFrameDecoder dec;
  std::vector<DecodedSample> out;
  for (const CanFrame& f : frames) dec.push({f, 0}, out);
  ASSERT_EQ(out.size(), 1U);
  EXPECT_TRUE(std::isnan(out[0].increment.temp_c));
  inc.dtheta_rad(0) = std::nan("");
  EXPECT_THROW(enc.encode(inc), std::invalid_argument);
}

TEST(ImuCodec, QuantisationCarryKeepsTheSumWithinOneLsb) {
  std::mt19937_64 rng(11);
  // Increments of a slowly turning, accelerating unit: small values where quantisation matters.
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (bool carry : {true, false}) {
    ImuFrameEncoder enc(kDefaultImuBaseId, carry);
    ImuFrameDecoder dec;
    std::vector<DecodedSample> out;
    Eigen::Vector3d true_dth = Eigen::Vector3d::Zero(), true_dv = Eigen::Vector3d::Zero();
    Eigen::Vector3d sum_dth = Eigen::Vector3d::Zero(), sum_dv = Eigen::Vector3d::Zero();
    for (int k = 0; k < 10000; ++k) {
      calib::core::ImuIncrement inc;
      for (int i = 0; i < 3; ++i) {
        inc.dtheta_rad(i) = 7.3e-7 + 3e-8 * u(rng);  // ~150 °/h with noise, a few hundred LSB
        inc.dv_mps(i) = 0.0980665 + 4e-6 * u(rng);   // ~1 g with noise
      }
      true_dth += inc.dtheta_rad;
      true_dv += inc.dv_mps;
      for (const CanFrame& f : enc.encode(inc)) dec.push({f, 0}, out);
    }
    ASSERT_EQ(out.size(), 10000U);
    // Sum in long double to keep the accumulation error far below an LSB.
    for (int i = 0; i < 3; ++i) {
      long double a = 0, v = 0;
      for (const auto& d : out) {
        a += d.increment.dtheta_rad(i);
        v += d.increment.dv_mps(i);
      }
      sum_dth(i) = static_cast<double>(a);
      sum_dv(i) = static_cast<double>(v);
    }
    const double err_dth = (sum_dth - true_dth).cwiseAbs().maxCoeff();
    const double err_dv = (sum_dv - true_dv).cwiseAbs().maxCoeff();
    if (carry) {
      EXPECT_LE(err_dth, 1e-9) << "dθ sum drifted";
      EXPECT_LE(err_dv, 1e-7) << "dv sum drifted";
    } else {
      // Without the carry the rounding errors random-walk: ~sqrt(10000/12) ≈ 29 LSB. This shows the
      // check above can fail.
      EXPECT_GT(err_dth + 1e2 * err_dv, 3e-9);
    }
  }
}

TEST(ImuDecoder, CleanStreamDecodesEverySampleIncludingCounterWraps) {
  const Stream s = make_stream(600);
  const DecodeRun r = decode(flatten(s));
  EXPECT_EQ(r.out.size(), 600U);
  expect_all_exact(r, s);
  EXPECT_EQ(r.counters.samples_lost, 0U);
  EXPECT_EQ(r.counters.frames_used, 2400U);
  EXPECT_EQ(r.counters.out_of_order_frames + r.counters.duplicate_frames + r.counters.discarded_frames, 0U);
  // Stream time: t = (index + 1) / rate.
  EXPECT_DOUBLE_EQ(r.out[599].increment.t_s, 600.0 / kRate_hz);
  EXPECT_EQ(r.out[599].sample_index, 599U);
}

TEST(ImuDecoder, SixteenBitCounterWrapIsNotALoss) {
  // 66 000 samples cross 0xFFFF -> 0: no loss, no resync, no reset.
  ImuFrameEncoder enc;
  ImuFrameDecoder dec;
  std::vector<DecodedSample> out;
  calib::core::ImuIncrement inc;
  inc.dtheta_rad.setConstant(1e-6);
  inc.dv_mps.setConstant(0.01);
  inc.temp_c = 30.0;
  for (int k = 0; k < 66000; ++k)
    for (const CanFrame& f : enc.encode(inc)) dec.push({f, 0}, out);
  dec.flush(out);
  EXPECT_EQ(out.size(), 66000U);
  EXPECT_EQ(dec.counters().samples_lost + dec.counters().resyncs + dec.counters().imu_resets, 0U);
  EXPECT_EQ(out.back().sample_index, 65999U);
}

TEST(ImuDecoder, DroppedFramesAreCountedAndNeverMisassembled) {
  const Stream s = make_stream(400);
  std::vector<ReceivedFrame> frames;
  std::mt19937_64 rng(5);
  std::set<int> damaged;         // samples with at least one frame dropped
  std::set<int> fully_dropped;   // all 4 frames dropped
  uint64_t dropped = 0;
  for (int k = 0; k < 400; ++k) {
    int lost_here = 0;
    for (int p = 0; p < 4; ++p) {
      const bool drop = (k % 50 == 10) || (k % 37 == 3 && p == (k % 4)) || (rng() % 100 == 0);
      if (drop && k != 0 && k != 399) {  // first and last intact: every loss is a gap between
        ++lost_here;
        ++dropped;
        continue;
      }
      frames.push_back({s.samples[static_cast<size_t>(k)][static_cast<size_t>(p)], 0});
    }
    if (lost_here) damaged.insert(k);
    if (lost_here == 4) fully_dropped.insert(k);
  }
  const DecodeRun r = decode(frames);
  expect_all_exact(r, s);
  EXPECT_EQ(r.out.size(), 400 - damaged.size());
  EXPECT_EQ(r.counters.samples_lost, damaged.size());
  EXPECT_EQ(r.counters.samples_incomplete, damaged.size() - fully_dropped.size());
  EXPECT_EQ(r.counters.discarded_frames, 4 * damaged.size() - dropped);
  EXPECT_EQ(r.counters.samples_corrupt, 0U);
  EXPECT_GE(fully_dropped.size(), 7U);  // the k % 50 == 10 samples
}

TEST(ImuDecoder, EveryPossibleSingleBitFlipLosesOnlyItsSample) {
  const Stream s = make_stream(24);
  const auto clean = flatten(s);
  const int victim = 12;
  for (int p = 0; p < 4; ++p)
    for (int bit = 0; bit < 64; ++bit) {
      auto frames = clean;
      auto& d = frames[static_cast<size_t>(victim * 4 + p)].frame.data;
      d[static_cast<size_t>(bit / 8)] = static_cast<uint8_t>(d[static_cast<size_t>(bit / 8)] ^ (1U << (bit % 8)));
      const DecodeRun r = decode(frames);
      SCOPED_TRACE("frame " + std::to_string(p) + " bit " + std::to_string(bit));
      expect_all_exact(r, s);  // never a wrong sample
      ASSERT_EQ(r.out.size(), 23U);
      EXPECT_EQ(r.counters.samples_lost, 1U);
      for (const auto& o : r.out) EXPECT_NE(o.counter, victim);
      if (bit >= 8) {
        // Payload flip: the sample is complete, and only the CRC can tell.
        EXPECT_EQ(r.counters.samples_corrupt, 1U);
        EXPECT_EQ(r.counters.samples_incomplete, 0U);
        EXPECT_EQ(r.counters.discarded_frames, 4U);
      } else {
        // Counter-byte flip: the frame is filed under another sample; the victim stays incomplete.
        EXPECT_GE(r.counters.samples_incomplete + r.counters.samples_corrupt, 1U);
      }
    }
}

TEST(ImuDecoder, ReorderingIsCountedAndRepaired) {
  const Stream s = make_stream(300);
  auto frames = flatten(s);
  // Swap adjacent frames at 20 places (inside a sample and across sample borders).
  int swaps = 0;
  for (size_t i = 5; i + 1 < frames.size() && swaps < 20; i += 53, ++swaps) std::swap(frames[i], frames[i + 1]);
  // Delay one frame by 3 positions: the 3 frames that overtake it are out of order.
  std::rotate(frames.begin() + 700, frames.begin() + 701, frames.begin() + 704);
  const DecodeRun r = decode(frames);
  expect_all_exact(r, s);
  EXPECT_EQ(r.out.size(), 300U);
  EXPECT_EQ(r.counters.samples_lost, 0U);
  EXPECT_EQ(r.counters.out_of_order_frames, static_cast<uint64_t>(swaps + 3));
  EXPECT_EQ(r.counters.duplicate_frames + r.counters.discarded_frames, 0U);
}

TEST(ImuDecoder, WholeSamplesSwappedAreReordered) {
  const Stream s = make_stream(50);
  auto frames = flatten(s);
  // Sample 20's frames arrive after sample 21's.
  std::rotate(frames.begin() + 80, frames.begin() + 84, frames.begin() + 88);
  const DecodeRun r = decode(frames);
  expect_all_exact(r, s);
  ASSERT_EQ(r.out.size(), 50U);
  for (size_t k = 0; k < 50; ++k) EXPECT_EQ(r.out[k].counter, k);
  EXPECT_EQ(r.counters.out_of_order_frames, 4U);
}

TEST(ImuDecoder, DuplicatesAreCountedAndIgnored) {
  const Stream s = make_stream(100);
  const auto clean = flatten(s);
  std::vector<ReceivedFrame> frames;
  uint64_t dups = 0;
  for (size_t i = 0; i < clean.size(); ++i) {
    frames.push_back(clean[i]);
    if (i % 13 == 0) {  // immediate repeat
      frames.push_back(clean[i]);
      ++dups;
    }
    if (i % 41 == 40 && i >= 20) {  // a repeat of a frame from 5 samples back (already decoded)
      frames.push_back(clean[i - 20]);
      ++dups;
    }
  }
  const DecodeRun r = decode(frames);
  expect_all_exact(r, s);
  EXPECT_EQ(r.out.size(), 100U);
  EXPECT_EQ(r.counters.duplicate_frames, dups);
  EXPECT_EQ(r.counters.samples_lost, 0U);
}

TEST(ImuDecoder, ImuResetIsDetectedAndTimeAdvancesByTheGap) {
  ImuFrameEncoder enc;
  DecoderOptions o;
  o.sample_rate_hz = kRate_hz;
  ImuFrameDecoder dec(o);
  std::vector<DecodedSample> out;
  calib::core::ImuIncrement inc;
  inc.dtheta_rad.setConstant(2e-7);
  inc.dv_mps.setConstant(0.098);
  const int64_t dt_ns = 10'000'000;
  int64_t t = 0;
  for (int k = 0; k < 300; ++k, t += dt_ns)
    for (const CanFrame& f : enc.encode(inc)) dec.push({f, t}, out);
  enc.restart();
  t += 5 * dt_ns;  // 5 samples not delivered while the IMU boots
  for (int k = 0; k < 30; ++k, t += dt_ns)
    for (const CanFrame& f : enc.encode(inc)) dec.push({f, t}, out);
  dec.flush(out);
  ASSERT_EQ(out.size(), 330U);
  EXPECT_EQ(dec.counters().imu_resets, 1U);
  EXPECT_EQ(dec.counters().samples_lost, 0U);  // the counter cannot tell; the index can
  EXPECT_TRUE(out[300].discontinuity);
  EXPECT_EQ(out[300].counter, 0);
  EXPECT_EQ(out[300].sample_index, 305U);
  EXPECT_EQ(out[329].sample_index, 334U);
  EXPECT_FALSE(out[301].discontinuity);
}

TEST(ImuDecoder, ResetStillDetectedWhenTheFirstSamplesAfterItAreLost) {
  ImuFrameEncoder enc;
  ImuFrameDecoder dec;
  std::vector<DecodedSample> out;
  calib::core::ImuIncrement inc;
  for (int k = 0; k < 1000; ++k)
    for (const CanFrame& f : enc.encode(inc)) dec.push({f, 0}, out);
  enc.restart();
  for (int k = 0; k < 40; ++k) {
    const auto frames = enc.encode(inc);
    if (k < 3) continue;  // samples 0-2 after the reset are lost on the bus
    for (const CanFrame& f : frames) dec.push({f, 0}, out);
  }
  dec.flush(out);
  EXPECT_EQ(out.size(), 1037U);
  EXPECT_EQ(dec.counters().imu_resets, 1U);
  EXPECT_EQ(out[1000].counter, 3);
}

TEST(ImuDecoder, ForeignMalformedAndErrorFramesAreCountedNotDecoded) {
  const Stream s = make_stream(10);
  auto frames = flatten(s);
  CanFrame other;
  other.can_id = 0x200;
  other.len = 8;
  CanFrame ext = s.samples[3][0];
  ext.can_id = 0x100 | kCanEffFlag;  // same number, extended: another message
  CanFrame shortf = s.samples[4][1];
  shortf.len = 7;
  CanFrame rtr = s.samples[4][2];
  rtr.can_id |= kCanRtrFlag;
  CanFrame err;
  err.can_id = kCanErrFlag | 0x80;
  err.len = 8;
  frames.insert(frames.begin() + 17, {{other, 0}, {ext, 0}, {shortf, 0}, {rtr, 0}, {err, 0}});
  const DecodeRun r = decode(frames);
  expect_all_exact(r, s);
  EXPECT_EQ(r.out.size(), 10U);
  EXPECT_EQ(r.counters.foreign_frames, 2U);
  EXPECT_EQ(r.counters.malformed_frames, 2U);
  EXPECT_EQ(r.counters.error_frames, 1U);
  EXPECT_EQ(r.counters.frames_in, 45U);
}

TEST(ImuDecoder, RejectsBadOptions) {
  DecoderOptions o;
  o.sample_rate_hz = 0.0;
  EXPECT_THROW(ImuFrameDecoder{o}, std::invalid_argument);
  o.sample_rate_hz = 100.0;
  o.reorder_window_frames = 0;
  EXPECT_THROW(ImuFrameDecoder{o}, std::invalid_argument);
  EXPECT_THROW(ImuFrameEncoder{0x7FE}, std::invalid_argument);
}

}  // namespace
}  // namespace imucal::drivers::imu
