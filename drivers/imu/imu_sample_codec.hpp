#pragma once
// One IMU sample in the terms of a protocol file (drivers/imu/imu_protocol_map.hpp; issue #27):
// its frames built from the sample's fields, and the fields read back from one complete set of
// its frames with the protocol's check verified. The reassembly of samples from a frame stream
// (order, loss, duplicates, resets) is the decoder's, built on these two.
#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

#include "drivers/imu/imu_protocol_map.hpp"

namespace imucal::drivers::imu {

struct ProtocolSample {
  /// SI, as the protocol carries them: increments (rad, m/s) or rates (rad/s, m/s²).
  std::array<double, 3> angular{}, velocity{};
  uint32_t counter = 0;  ///< modulo 2^counter_bits
  /// Conditions. Encoding raises each through the first signal of its list in the map (and every
  /// signal whose bit is set in `flags`); decoding reports any signal of the list.
  bool fault = false, saturation = false, startup = false;
  bool temperature_invalid = false;  ///< decoding: a temperature_invalid flag is set
  uint32_t flags = 0;  ///< bit i: the map's flags[i] is set
  /// °C; NaN = unknown (encoded as temperature_unknown and the temperature_invalid flag).
  double temperature_c = std::numeric_limits<double>::quiet_NaN();
  /// Decoding: the sample's frames carried the temperature (a multiplexed temperature is only in
  /// the frames of its page).
  bool temperature_carried = false;
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
/// and clipped to its raw range (a clipped channel sets `saturation` in the frames). A multiplexed
/// frame carries the page of its raised flags when it has any, otherwise the pages its mapped
/// signals use in turn (by the counter); signals of other pages are not written. The check is
/// computed last.
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
/// The same from one pointer per message position (each to at least the message's length): the
/// stream decoder's allocation-free path.
SampleReading decode_sample(const ImuProtocolMap& map, const uint8_t* const* frames);

/// The value that `physical` is sent as: rounded to the signal's resolution and clipped to its raw
/// range (`clipped` then), in the signal's physical unit.
double sent_value(const DbcSignal& s, double physical, bool& clipped);

/// CRC-8/SAE-J1850 (poly 0x1D, init 0xFF, xorout 0xFF; "123456789" -> 0x4B).
uint8_t crc8_sae_j1850(const uint8_t* bytes, size_t len);
/// The same over several pieces: start with crc = 0xFF, feed each, finish with ^ 0xFF.
uint8_t crc8_sae_j1850_update(uint8_t crc, const uint8_t* bytes, size_t len);

}  // namespace imucal::drivers::imu
