#pragma once
// The IMU CAN frame protocol (our own; ARCHITECTURE §4). Normative description:
// drivers/imu/PROTOCOL.md and drivers/imu/imu.dbc — this header is its single source in code.
//
// One IMU sample = 4 classic CAN frames, 11-bit identifiers base_id + 0..3 (default base 0x100),
// 8 data bytes each, all signals little-endian (DBC "@1", Intel), sent in this order:
//   base+0 IMU_AXIS_X   bits 0-7 counter_lo | bits 8-37 dθx s30 | bits 38-63 dvx s26
//   base+1 IMU_AXIS_Y   same layout for y
//   base+2 IMU_AXIS_Z   same layout for z
//   base+3 IMU_STATUS   bits 0-7 counter_lo | 8-23 status u16 | 24-39 temperature s16 |
//                       40-47 counter_hi | 48-63 CRC-16
// counter = 16-bit rolling sample counter (counter_hi:counter_lo); its low byte in every frame ties
// the frames of one sample together, the high byte in the status frame extends gap detection to
// 65 536 samples. The CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no reflection, xorout 0) runs
// over the 24 data bytes of X, Y, Z then status bytes 0-5, so it also covers every counter byte.
//
// LSBs: dθ 1e-9 rad (range ±0.536870912 rad = ±3076 °/s at 100 Hz), dv 1e-7 m/s (range
// ±3.3554432 m/s = ±34.2 g at 100 Hz), temperature 0.01 °C (-32768 = unknown).
// Bus load: 4 frames/sample; 2000 Hz = 8000 frames/s fills a 1 Mbit/s bus; 100-400 Hz uses 5-20 %.
#include <array>
#include <cstddef>
#include <cstdint>

#include "drivers/imu/can_frame.hpp"

namespace imucal::drivers::imu {

constexpr uint32_t kDefaultImuBaseId = 0x100;
constexpr int kFramesPerSample = 4;
enum class ImuFramePart : int { kAxisX = 0, kAxisY = 1, kAxisZ = 2, kStatus = 3 };

constexpr double kDthetaLsb_rad = 1e-9;
constexpr double kDvLsb_mps = 1e-7;
constexpr double kTemperatureLsb_degc = 0.01;
constexpr int kDthetaBits = 30;
constexpr int kDvBits = 26;
constexpr int64_t kDthetaMaxCount = (int64_t{1} << (kDthetaBits - 1)) - 1;
constexpr int64_t kDthetaMinCount = -(int64_t{1} << (kDthetaBits - 1));
constexpr int64_t kDvMaxCount = (int64_t{1} << (kDvBits - 1)) - 1;
constexpr int64_t kDvMinCount = -(int64_t{1} << (kDvBits - 1));
constexpr int16_t kTemperatureUnknown = INT16_MIN;

/// Status word bits (IMU_STATUS bits 8-23). A set bit reports a condition; reserved bits are 0.
namespace status {
constexpr uint16_t kGyroFault = 1U << 0;       ///< gyro channel failed its self-monitoring
constexpr uint16_t kAccelFault = 1U << 1;      ///< accelerometer channel failed its self-monitoring
constexpr uint16_t kGyroSaturated = 1U << 2;   ///< a dθ component was clipped to the field range
constexpr uint16_t kAccelSaturated = 1U << 3;  ///< a dv component was clipped to the field range
constexpr uint16_t kTempInvalid = 1U << 4;     ///< temperature unknown (field = -32768)
constexpr uint16_t kStartup = 1U << 5;         ///< one of the first kStartupSamples after power-up/reset
constexpr uint16_t kBitFail = 1U << 6;         ///< built-in test failed
constexpr uint16_t kDefinedMask = 0x007F;
}  // namespace status

/// Samples after power-up/reset that carry status::kStartup; a receiver recognises an IMU reset by
/// the counter restarting together with this bit, even if the first samples after the reset are lost.
constexpr int kStartupSamples = 16;

/// One axis frame's fields as integers (counts of the LSB).
struct AxisFields {
  uint8_t counter_lo = 0;
  int32_t dtheta_count = 0;  ///< kDthetaMinCount..kDthetaMaxCount
  int32_t dv_count = 0;      ///< kDvMinCount..kDvMaxCount
};

struct StatusFields {
  uint16_t counter = 0;  ///< full 16-bit counter (hi byte at bits 40-47, lo byte at bits 0-7)
  uint16_t status = 0;
  int16_t temperature_count = kTemperatureUnknown;
  uint16_t crc = 0;
};

/// CRC-16/CCITT-FALSE over `len` bytes (check value for "123456789" is 0x29B1).
uint16_t crc16_ccitt_false(const uint8_t* bytes, std::size_t len, uint16_t crc = 0xFFFF);

std::array<uint8_t, 8> pack_axis(const AxisFields& f);
AxisFields unpack_axis(const std::array<uint8_t, 8>& data);
/// Packs the status frame; crc is written as given.
std::array<uint8_t, 8> pack_status(const StatusFields& f);
StatusFields unpack_status(const std::array<uint8_t, 8>& data);

}  // namespace imucal::drivers::imu
