// The stream decoder and encoder driven by a protocol file (drivers/imu/imu_codec.hpp; issue #27)
// on the second protocol (tests/data/protocols/rates16: rates in 16-bit counts, three big-endian
// frames, 29-bit ids, a multiplexed status frame with the temperature on its own page, CRC-8): the
// quantisation carry keeps the integrated increments within one resolution step, frames lost,
// duplicated, reordered or corrupted lose at most their samples and never make a wrong one, an IMU
// reset is seen, the temperature holds between its pages, the ids move with base_id, and what the
// station cannot carry (CAN FD) is refused naming the message. The built-in protocol's file
// behaves as the compiled-in default (the same frames).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <random>

#include "drivers/imu/imu_codec.hpp"

namespace imucal::drivers::imu {
namespace {

const std::string kSourceProtocolStream = IMUCAL_SOURCE_DIR;

std::shared_ptr<const ImuProtocolMap> rates16() {
  return std::make_shared<const ImuProtocolMap>(
      read_protocol_map(kSourceProtocolStream + "/tests/data/protocols/rates16.toml"));
}

calib::core::ImuIncrement increment(std::mt19937_64& rng, int k) {
  std::normal_distribution<double> n(0.0, 1.0);
  calib::core::ImuIncrement inc;
  inc.dt_s = 0.01;
  for (int i = 0; i < 3; ++i) {
    inc.dtheta_rad(i) = (0.05 * std::sin(0.01 * k + i) + 1e-3 * n(rng)) * inc.dt_s;  // rad/s × dt
    inc.dv_mps(i) = ((i == 2 ? -9.81 : 0.3) + 0.02 * n(rng)) * inc.dt_s;
  }
  inc.temp_c = 25.0 + 0.001 * k;
  return inc;
}

struct Sent {
  std::vector<std::vector<CanFrame>> frames;  ///< per sample
  std::vector<calib::core::ImuIncrement> truth;
};

Sent send(const std::shared_ptr<const ImuProtocolMap>& map, int n, uint64_t seed = 1) {
  std::mt19937_64 rng(seed);
  ImuFrameEncoder enc(map, std::nullopt);
  Sent s;
  for (int k = 0; k < n; ++k) {
    s.truth.push_back(increment(rng, k));
    s.frames.push_back(enc.encode(s.truth.back()));
  }
  return s;
}

ImuFrameDecoder decoder(const std::shared_ptr<const ImuProtocolMap>& map) {
  DecoderOptions o;
  o.protocol = map;
  o.sample_rate_hz = 100.0;
  return ImuFrameDecoder(o);
}

TEST(ProtocolStream, RatesAreIntegratedAndTheCarryKeepsTheSumWithinOneStep) {
  const auto map = rates16();
  const Sent s = send(map, 70000);  // the 16-bit counter wraps once
  ASSERT_EQ(s.frames[0].size(), 3u);
  EXPECT_TRUE(s.frames[0][0].is_extended());
  EXPECT_EQ(s.frames[0][0].id(), 0x18FF1000u);
  ImuFrameDecoder dec = decoder(map);
  std::vector<DecodedSample> out;
  for (const auto& f : s.frames)
    for (const CanFrame& c : f) dec.push({c, 0}, out);
  dec.flush(out);
  ASSERT_EQ(out.size(), s.truth.size());
  EXPECT_EQ(dec.counters().samples_lost, 0u);
  const IncrementResolution q = increment_resolution(*map, 0.01);
  EXPECT_NEAR(q.dtheta_rad, 1.7453292519943295e-6, 1e-18);  // 0.01 °/s × 10 ms
  EXPECT_NEAR(q.dv_mps, 9.80665e-5, 1e-17);                 // 1 mg × 10 ms
  Eigen::Vector3d sum_th = Eigen::Vector3d::Zero(), sum_dv = Eigen::Vector3d::Zero();
  double worst_th = 0, worst_dv = 0;
  for (size_t k = 0; k < out.size(); ++k) {
    EXPECT_EQ(out[k].sample_index, k);
    sum_th += out[k].increment.dtheta_rad - s.truth[k].dtheta_rad;
    sum_dv += out[k].increment.dv_mps - s.truth[k].dv_mps;
    worst_th = std::max(worst_th, sum_th.cwiseAbs().maxCoeff());
    worst_dv = std::max(worst_dv, sum_dv.cwiseAbs().maxCoeff());
  }
  EXPECT_LE(worst_th, 0.5 * q.dtheta_rad * (1 + 1e-6));
  EXPECT_LE(worst_dv, 0.5 * q.dv_mps * (1 + 1e-6));
  // The temperature rides on page 1 every other sample and holds in between (0.0625 °C steps).
  for (size_t k = 20; k < out.size(); k += 997)
    EXPECT_NEAR(out[k].increment.temp_c, s.truth[k].temp_c, 0.0625 + 0.002) << k;
}

TEST(ProtocolStream, LossDuplicatesReorderAndCorruptionNeverMakeAWrongSample) {
  const auto map = rates16();
  const Sent s = send(map, 3000, 2);
  // The clean decode of each counter: what any decoded sample must equal.
  ImuFrameDecoder clean_dec = decoder(map);
  std::vector<DecodedSample> clean;
  for (const auto& f : s.frames)
    for (const CanFrame& c : f) clean_dec.push({c, 0}, clean);
  clean_dec.flush(clean);
  std::map<uint32_t, DecodedSample> by_counter;
  for (const DecodedSample& d : clean) by_counter[d.counter] = d;

  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> u(0, 1);
  std::vector<CanFrame> bus;
  uint64_t lost = 0, flipped = 0;
  for (const auto& f : s.frames)
    for (CanFrame c : f) {
      const double r = u(rng);
      if (r < 0.02) {
        ++lost;
        continue;
      }
      if (r < 0.03) {
        c.data[rng() % 8] ^= static_cast<uint8_t>(1U << (rng() % 8));
        ++flipped;
      }
      bus.push_back(c);
      if (u(rng) < 0.02) bus.push_back(c);  // duplicated
    }
  for (size_t i = 0; i + 1 < bus.size(); ++i)  // neighbours swapped
    if (u(rng) < 0.05) std::swap(bus[i], bus[i + 1]);
  ImuFrameDecoder dec = decoder(map);
  std::vector<DecodedSample> out;
  for (const CanFrame& c : bus) dec.push({c, 0}, out);
  dec.flush(out);
  ASSERT_GT(lost + flipped, 100u);
  EXPECT_GT(out.size(), 2500u);
  EXPECT_LT(out.size(), s.truth.size());
  for (size_t k = 0; k < out.size(); ++k) {
    const DecodedSample& want = by_counter.at(out[k].counter);
    EXPECT_EQ(out[k].increment.dtheta_rad, want.increment.dtheta_rad) << out[k].counter;
    EXPECT_EQ(out[k].increment.dv_mps, want.increment.dv_mps) << out[k].counter;
    EXPECT_EQ(out[k].sample_index, want.sample_index) << "the sample keeps its slot";
  }
  const DecoderCounters& c = dec.counters();
  EXPECT_EQ(c.samples_decoded + c.samples_lost, s.truth.size());
  EXPECT_GT(c.duplicate_frames, 0u);
  EXPECT_GT(c.samples_corrupt + c.samples_incomplete, 0u);
}

TEST(ProtocolStream, AResetIsSeenAndTheFlagsAreNamedFromTheProtocol) {
  const auto map = rates16();
  ImuFrameEncoder enc(map, std::nullopt);
  ImuFrameDecoder dec = decoder(map);
  std::vector<DecodedSample> out;
  std::mt19937_64 rng(3);
  int64_t t_ns = 0;
  auto push = [&](int k, uint16_t st) {
    t_ns += 10'000'000;
    for (const CanFrame& c : enc.encode(increment(rng, k), st)) dec.push({c, t_ns}, out);
  };
  for (int k = 0; k < 100; ++k) push(k, 0);
  push(100, status::kGyroSaturated);
  t_ns += 500'000'000;  // 50 samples swallowed by the reset
  enc.restart();
  for (int k = 0; k < 40; ++k) push(k, 0);
  dec.flush(out);
  ASSERT_EQ(out.size(), 141u);
  EXPECT_TRUE(out[0].conditions & condition::kStartup);
  EXPECT_FALSE(out[20].conditions & condition::kStartup);
  EXPECT_TRUE(out[100].conditions & condition::kSaturation);
  EXPECT_EQ(dec.flag_names(out[100].flags, condition::kSaturation), "R16_STATUS.Saturation");
  EXPECT_EQ(dec.counters().imu_resets, 1u);
  EXPECT_TRUE(out[101].discontinuity);
  EXPECT_EQ(out[101].counter, 0u);
  EXPECT_EQ(out[101].sample_index, 151u);
}

TEST(ProtocolStream, BaseIdMovesTheIdsAndTheBuiltInFileIsTheDefault) {
  const auto map = rates16();
  ImuFrameEncoder moved(map, 0x1234000u);
  calib::core::ImuIncrement inc;
  inc.dt_s = 0.01;
  const std::vector<CanFrame> f = moved.encode(inc);
  EXPECT_EQ(f[0].id(), 0x1234000u);
  EXPECT_EQ(f[2].id(), 0x1234200u);
  ImuFrameDecoder at_dbc_ids = decoder(map);
  std::vector<DecodedSample> out;
  for (const CanFrame& c : f) at_dbc_ids.push({c, 0}, out);
  EXPECT_TRUE(out.empty());
  EXPECT_EQ(at_dbc_ids.counters().foreign_frames, 3u);
  EXPECT_THROW(ImuFrameEncoder(map, 0x1FFFFF00u), std::invalid_argument);

  // The shipped built-in file and the compiled-in default write the same frames.
  const auto shipped = std::make_shared<const ImuProtocolMap>(
      read_protocol_map(kSourceProtocolStream + "/drivers/imu/protocols/imucal-imu-1.toml"));
  ImuFrameEncoder a(shipped, std::nullopt), b;
  std::mt19937_64 rng(4);
  for (int k = 0; k < 200; ++k) {
    calib::core::ImuIncrement i = increment(rng, k);
    if (k == 50) i.temp_c = std::nan("");
    EXPECT_EQ(a.encode(i, k == 70 ? status::kAccelFault : 0),
              b.encode(i, k == 70 ? status::kAccelFault : 0));
  }
}

TEST(ProtocolStream, ACanFdProtocolIsRefusedNamingTheMessage) {
  const std::string dbc =
      "VERSION \"\"\nNS_ :\nBS_:\nBU_: IMU\n"
      "BO_ 256 FD_SAMPLE: 64 IMU\n"
      " SG_ Counter : 0|8@1+ (1,0) [0|255] \"\" IMU\n"
      " SG_ Wx : 8|32@1- (1E-009,0) [0|0] \"\" IMU\n"
      " SG_ Wy : 40|32@1- (1E-009,0) [0|0] \"\" IMU\n"
      " SG_ Wz : 72|32@1- (1E-009,0) [0|0] \"\" IMU\n"
      " SG_ Ax : 104|32@1- (1E-007,0) [0|0] \"\" IMU\n"
      " SG_ Ay : 136|32@1- (1E-007,0) [0|0] \"\" IMU\n"
      " SG_ Az : 168|32@1- (1E-007,0) [0|0] \"\" IMU\n";
  const std::string toml =
      "[protocol]\nname = \"fd\"\ndbc = \"fd.dbc\"\nquantity = \"increments\"\n"
      "messages = [\"FD_SAMPLE\"]\ncompletes_sample = \"FD_SAMPLE\"\n"
      "[channels]\nangular = [\"FD_SAMPLE.Wx\", \"FD_SAMPLE.Wy\", \"FD_SAMPLE.Wz\"]\n"
      "velocity = [\"FD_SAMPLE.Ax\", \"FD_SAMPLE.Ay\", \"FD_SAMPLE.Az\"]\n"
      "[counter]\nparts = [{ signal = \"FD_SAMPLE.Counter\", bits = 8 }]\n";
  const auto map =
      std::make_shared<const ImuProtocolMap>(parse_protocol_map(toml, "fd.toml", &dbc));
  EXPECT_EQ(map->message(0).length, 64);
  try {
    ImuFrameDecoder d = decoder(map);
    ADD_FAILURE() << "a CAN FD protocol was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("FD_SAMPLE is a CAN FD frame of 64 bytes"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace imucal::drivers::imu
