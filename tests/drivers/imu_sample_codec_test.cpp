// One sample through a protocol file (drivers/imu/imu_sample_codec.hpp; issue #27): the built-in
// protocol's file reads what the hard-wired encoder sends, and what it writes the hard-wired
// decoder accepts with the same values; the second protocol round-trips to its resolution, and
// its check, counter copies and multiplexed flags behave as the file says.
#include "drivers/imu/imu_sample_codec.hpp"

#include <gtest/gtest.h>

#include <cstring>
#include <random>

#include "drivers/imu/dbc_codec.hpp"
#include "drivers/imu/imu_codec.hpp"
#include "drivers/imu/imu_protocol.hpp"

namespace imucal::drivers::imu {
namespace {

const std::string kSourceImuSampleCodec = IMUCAL_SOURCE_DIR;

ImuProtocolMap builtin() {
  return read_protocol_map(kSourceImuSampleCodec + "/drivers/imu/protocols/imucal-imu-1.toml");
}

TEST(ImuSampleCodec, Crc8SaeJ1850HasItsCheckValue) {
  const char* s = "123456789";
  EXPECT_EQ(crc8_sae_j1850(reinterpret_cast<const uint8_t*>(s), 9), 0x4B);
}

TEST(ImuSampleCodec, TheBuiltInFileReadsTheHardWiredEncodersFrames) {
  const ImuProtocolMap map = builtin();
  ImuFrameEncoder enc(kDefaultImuBaseId, /*carry_remainder=*/false);
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int k = 0; k < 300; ++k) {
    calib::core::ImuIncrement inc;
    for (int i = 0; i < 3; ++i) {
      inc.dtheta_rad(i) = 0.6 * u(rng);  // sometimes beyond the 30-bit range: saturates
      inc.dv_mps(i) = 3.5 * u(rng);
    }
    inc.temp_c = 20.0;
    const uint16_t flags = k % 5 == 0 ? status::kGyroFault : 0;
    const uint16_t counter = enc.next_counter();
    const auto frames = enc.encode(inc, flags);
    std::vector<std::array<uint8_t, 64>> data(4);
    for (int f = 0; f < 4; ++f) std::memcpy(data[f].data(), frames[f].data.data(), 8);
    const SampleReading r = decode_sample(map, data);
    ASSERT_TRUE(r.ok) << r.why;
    EXPECT_EQ(r.sample.counter, counter);
    const StatusFields st = unpack_status(frames[3].data);
    for (int i = 0; i < 3; ++i) {
      EXPECT_EQ(r.sample.angular[i], unpack_axis(frames[i].data).dtheta_count * kDthetaLsb_rad);
      EXPECT_EQ(r.sample.velocity[i], unpack_axis(frames[i].data).dv_count * kDvLsb_mps);
    }
    EXPECT_EQ(r.sample.fault,
              (st.status & (status::kGyroFault | status::kAccelFault | status::kBitFail)) != 0);
    EXPECT_EQ(r.sample.saturation,
              (st.status & (status::kGyroSaturated | status::kAccelSaturated)) != 0);
    EXPECT_EQ(r.sample.startup, (st.status & status::kStartup) != 0);
    EXPECT_EQ(r.sample.startup, k < kStartupSamples);
    data[1][3] ^= 0x10;  // one bit of Y's frame: the CRC must catch it
    EXPECT_EQ(decode_sample(map, data).why, "check failed");
  }
}

TEST(ImuSampleCodec, TheHardWiredDecoderAcceptsWhatTheBuiltInFileWrites) {
  const ImuProtocolMap map = builtin();
  ImuFrameDecoder dec;
  std::vector<DecodedSample> out;
  std::vector<ProtocolSample> sent;
  for (uint32_t k = 0; k < 50; ++k) {
    ProtocolSample s;
    s.counter = 1000 + k;
    for (int i = 0; i < 3; ++i) {
      s.angular[i] = (static_cast<int>(k) * 37 - 900 + i) * kDthetaLsb_rad;
      s.velocity[i] = (static_cast<int>(k) * -11 + 400 + i) * kDvLsb_mps;
    }
    s.fault = k == 7;
    sent.push_back(s);
    for (const ProtocolFrame& f : encode_sample(map, s)) {
      ReceivedFrame rf;
      rf.frame.can_id = f.id;
      rf.frame.len = 8;
      std::memcpy(rf.frame.data.data(), f.data.data(), 8);
      dec.push(rf, out);
    }
  }
  dec.flush(out);
  ASSERT_EQ(out.size(), sent.size());
  EXPECT_EQ(dec.counters().samples_corrupt, 0u);
  for (size_t k = 0; k < out.size(); ++k) {
    EXPECT_EQ(out[k].counter, sent[k].counter);
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(out[k].increment.dtheta_rad(i), sent[k].angular[i], 1e-15);
      EXPECT_NEAR(out[k].increment.dv_mps(i), sent[k].velocity[i], 1e-15);
    }
    EXPECT_EQ(dec.flag_names(out[k].flags, condition::kFault),
              sent[k].fault ? "IMU_STATUS.GyroFault" : "");
  }
}

TEST(ImuSampleCodec, TheSecondProtocolRoundTripsToItsResolution) {
  const ImuProtocolMap map = read_protocol_map(kSourceImuSampleCodec + "/tests/data/protocols/rates16.toml");
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> w(-5.0, 5.0), f(-150.0, 150.0);
  for (int k = 0; k < 200; ++k) {
    ProtocolSample s;
    s.counter = static_cast<uint32_t>(rng() & 0xFFFF);
    for (int i = 0; i < 3; ++i) {
      s.angular[i] = w(rng);   // rad/s (±5.7 rad/s is the 16-bit range at 0.01 °/s)
      s.velocity[i] = f(rng);  // m/s² (±321 m/s² at 1 mg)
    }
    s.startup = k % 3 == 0;
    const std::vector<ProtocolFrame> frames = encode_sample(map, s);
    ASSERT_EQ(frames.size(), 3u);
    EXPECT_TRUE(frames[0].extended);
    EXPECT_EQ(frames[2].id, 0x18FF1200u);
    std::vector<std::array<uint8_t, 64>> data;
    for (const ProtocolFrame& fr : frames) data.push_back(fr.data);
    const SampleReading r = decode_sample(map, data);
    ASSERT_TRUE(r.ok) << r.why;
    EXPECT_EQ(r.sample.counter, s.counter);
    for (int i = 0; i < 3; ++i) {
      EXPECT_NEAR(r.sample.angular[i], s.angular[i], 0.5 * map.angular_scale + 1e-12);
      EXPECT_NEAR(r.sample.velocity[i], s.velocity[i], 0.5 * map.velocity_scale + 1e-12);
    }
    EXPECT_EQ(r.sample.startup, s.startup);
    EXPECT_FALSE(r.sample.saturation);
    // Big-endian: RateX's most significant byte is byte 1 of the gyro frame.
    const int64_t x = std::llround(s.angular[0] / map.angular_scale);
    EXPECT_EQ(data[0][1], static_cast<uint8_t>((static_cast<uint64_t>(x) >> 8) & 0xFF));
    std::vector<std::array<uint8_t, 64>> copy = data;
    copy[0][0] ^= 0x01;  // the gyro frame's counter copy, covered by the CRC
    EXPECT_EQ(decode_sample(map, copy).why, "check failed");
  }
}

TEST(ImuSampleCodec, ClippingSetsSaturationAndAnotherPageHidesTheFlags) {
  const ImuProtocolMap map = read_protocol_map(kSourceImuSampleCodec + "/tests/data/protocols/rates16.toml");
  ProtocolSample s;
  s.angular = {100.0, 0.0, 0.0};  // far beyond ±5.7 rad/s
  s.fault = true;
  std::vector<std::array<uint8_t, 64>> data;
  for (const ProtocolFrame& fr : encode_sample(map, s)) data.push_back(fr.data);
  SampleReading r = decode_sample(map, data);
  ASSERT_TRUE(r.ok) << r.why;
  EXPECT_TRUE(r.sample.saturation);
  EXPECT_TRUE(r.sample.fault);
  EXPECT_NEAR(r.sample.angular[0], 32767 * map.angular_scale, 1e-12);
  // The status frame on its temperature page (1): the flags are not reported in it.
  const DbcMessage& st = map.message(map.completes_sample);
  dbc_insert_raw(*st.multiplexor(), 1, data[2].data(), 8);
  std::vector<uint8_t> bytes;  // the CRC recomputed for the changed page
  for (int m = 0; m < 2; ++m) bytes.insert(bytes.end(), data[m].begin(), data[m].begin() + 8);
  bytes.insert(bytes.end(), data[2].begin(), data[2].begin() + 7);
  data[2][7] = crc8_sae_j1850(bytes.data(), bytes.size());
  r = decode_sample(map, data);
  ASSERT_TRUE(r.ok) << r.why;
  EXPECT_FALSE(r.sample.fault);
  EXPECT_FALSE(r.sample.saturation);
}

}  // namespace
}  // namespace imucal::drivers::imu
