#pragma once
// One IMU sample in the terms of a protocol file (drivers/imu/imu_protocol_map.hpp; issue #27):
// its frames built from the sample's fields, and the fields read back from one complete set of
// its frames with the protocol's check verified. The reassembly of samples from a frame stream
// (order, loss, duplicates, resets) is the decoder's, built on these two.
#include <array>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "drivers/imu/imu_protocol_map.hpp"

namespace imucal::imu {

struct ProtocolSample {
  /// SI, as the protocol carries them: increments (rad, m/s) or rates (rad/s, m/s²).
  std::array<double, 3> angular{}, velocity{};
  uint32_t counter = 0;  ///< modulo 2^counter_bits
  bool fault = false, saturation = false, startup = false;
};

/// One frame's data as the protocol sends it (up to 64 bytes; `length` of them are used).
struct ProtocolFrame {
  int message = -1;  ///< index into the map's DBC messages
  uint32_t id = 0;
  bool extended = false;
  int length = 8;
  std::array<uint8_t, 64> data{};
};

/// The sample's frames in the order sent. Channel values are rounded to their signal's resolution
/// and clipped to its raw range (a clipped channel sets `saturation` in the frames); a multiplexed
/// flag's frame carries the flag's multiplexor value. The check is computed last.
std::vector<ProtocolFrame> encode_sample(const ImuProtocolMap& map, const ProtocolSample& s);

struct SampleReading {
  bool ok = false;
  std::string why;  ///< when not ok: "check failed", "counter copies differ", ...
  ProtocolSample sample;
};

/// Reads one sample from its frames' data, in the map's message order (`frames[i]` is message
/// map.messages[i]). A flag in a multiplexed frame whose multiplexor has another value reads as
/// not set.
SampleReading decode_sample(const ImuProtocolMap& map,
                            const std::vector<std::array<uint8_t, 64>>& frames);

/// CRC-8/SAE-J1850 (poly 0x1D, init 0xFF, xorout 0xFF; "123456789" -> 0x4B).
uint8_t crc8_sae_j1850(const uint8_t* bytes, size_t len);

}  // namespace imucal::imu
