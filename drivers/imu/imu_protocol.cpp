#include "drivers/imu/imu_protocol.hpp"

namespace imucal::drivers::imu {
namespace {

uint64_t load_le64(const std::array<uint8_t, 8>& d) {
  uint64_t w = 0;
  for (int i = 7; i >= 0; --i) w = (w << 8) | d[static_cast<std::size_t>(i)];
  return w;
}

std::array<uint8_t, 8> store_le64(uint64_t w) {
  std::array<uint8_t, 8> d{};
  for (std::size_t i = 0; i < 8; ++i) d[i] = static_cast<uint8_t>(w >> (8 * i));
  return d;
}

/// Sign-extends the low `bits` bits of v (two's complement field).
int64_t sign_extend(uint64_t v, int bits) {
  const uint64_t m = uint64_t{1} << (bits - 1);
  v &= (uint64_t{1} << bits) - 1;
  return static_cast<int64_t>(v ^ m) - static_cast<int64_t>(m);
}

uint64_t field(int64_t v, int bits) {
  return static_cast<uint64_t>(v) & ((uint64_t{1} << bits) - 1);
}

}  // namespace

namespace {

/// CRC-16/CCITT-FALSE one byte at a time (the station decodes up to 8 000 frames/s; a table makes
/// the check a small part of it).
constexpr std::array<uint16_t, 256> crc16_table() {
  std::array<uint16_t, 256> t{};
  for (unsigned i = 0; i < 256; ++i) {
    uint16_t crc = static_cast<uint16_t>(i << 8);
    for (int b = 0; b < 8; ++b)
      crc = (crc & 0x8000U) ? static_cast<uint16_t>((crc << 1) ^ 0x1021U)
                            : static_cast<uint16_t>(crc << 1);
    t[i] = crc;
  }
  return t;
}
constexpr std::array<uint16_t, 256> kCrc16Table = crc16_table();

}  // namespace

uint16_t crc16_ccitt_false(const uint8_t* bytes, std::size_t len, uint16_t crc) {
  for (std::size_t i = 0; i < len; ++i)
    crc = static_cast<uint16_t>((crc << 8) ^ kCrc16Table[((crc >> 8) ^ bytes[i]) & 0xFFU]);
  return crc;
}

std::array<uint8_t, 8> pack_axis(const AxisFields& f) {
  const uint64_t w = uint64_t{f.counter_lo} | (field(f.dtheta_count, kDthetaBits) << 8) |
                     (field(f.dv_count, kDvBits) << (8 + kDthetaBits));
  return store_le64(w);
}

AxisFields unpack_axis(const std::array<uint8_t, 8>& data) {
  const uint64_t w = load_le64(data);
  AxisFields f;
  f.counter_lo = static_cast<uint8_t>(w & 0xFF);
  f.dtheta_count = static_cast<int32_t>(sign_extend(w >> 8, kDthetaBits));
  f.dv_count = static_cast<int32_t>(sign_extend(w >> (8 + kDthetaBits), kDvBits));
  return f;
}

std::array<uint8_t, 8> pack_status(const StatusFields& f) {
  const uint64_t w = uint64_t{static_cast<uint8_t>(f.counter & 0xFF)} | (uint64_t{f.status} << 8) |
                     (uint64_t{static_cast<uint16_t>(f.temperature_count)} << 24) |
                     (uint64_t{static_cast<uint8_t>(f.counter >> 8)} << 40) | (uint64_t{f.crc} << 48);
  return store_le64(w);
}

StatusFields unpack_status(const std::array<uint8_t, 8>& data) {
  const uint64_t w = load_le64(data);
  StatusFields f;
  f.counter = static_cast<uint16_t>((w & 0xFF) | (((w >> 40) & 0xFF) << 8));
  f.status = static_cast<uint16_t>((w >> 8) & 0xFFFF);
  f.temperature_count = static_cast<int16_t>(static_cast<uint16_t>((w >> 24) & 0xFFFF));
  f.crc = static_cast<uint16_t>(w >> 48);
  return f;
}

}  // namespace imucal::drivers::imu
