#include "drivers/imu/dbc_codec.hpp"

#include <cstring>

namespace imucal::drivers::imu {

std::vector<int> dbc_signal_bits(const DbcSignal& s) {
  std::vector<int> bits;
  bits.reserve(static_cast<size_t>(s.length));
  int pos = s.start_bit;
  for (int i = 0; i < s.length; ++i) {
    bits.push_back(pos);
    if (s.order == DbcSignal::ByteOrder::kIntel)
      ++pos;
    else
      pos = pos % 8 == 0 ? pos + 15 : pos - 1;  // bit 0 of a byte -> bit 7 of the next
  }
  return bits;
}

namespace {

bool bit_at(const uint8_t* data, int pos) { return ((data[pos / 8] >> (pos % 8)) & 1U) != 0; }

}  // namespace

namespace {

/// A classic frame's signal by shifts of its 8 bytes read as one integer (the hot path of the
/// station's decoder); false when the signal does not lie within those 64 bits.
bool extract_from_word(const DbcSignal& s, const uint8_t* data, size_t size, uint64_t& raw) {
  if (size > 8) return false;
  uint8_t b[8] = {0, 0, 0, 0, 0, 0, 0, 0};
  std::memcpy(b, data, size);
  const uint64_t all = s.length >= 64 ? ~uint64_t{0} : (uint64_t{1} << s.length) - 1;
  if (s.order == DbcSignal::ByteOrder::kIntel) {
    if (s.start_bit + s.length > 64) return false;
    uint64_t le = 0;
    for (int i = 7; i >= 0; --i) le = (le << 8) | b[i];
    raw = (le >> s.start_bit) & all;
    return true;
  }
  // Motorola: the start bit is the most significant; in the frame read big-endian it sits at
  // index (from the top) byte × 8 + (7 − bit).
  const int top = (s.start_bit / 8) * 8 + (7 - s.start_bit % 8);
  if (top + s.length > 64) return false;
  uint64_t be = 0;
  for (int i = 0; i < 8; ++i) be = (be << 8) | b[i];
  raw = (be << top) >> (64 - s.length);
  return true;
}

}  // namespace

uint64_t dbc_extract_raw(const DbcSignal& s, const uint8_t* data, size_t size) {
  uint64_t raw = 0;
  if (extract_from_word(s, data, size, raw)) return raw;
  int pos = s.start_bit;
  for (int i = 0; i < s.length; ++i) {
    if (pos < 0 || static_cast<size_t>(pos / 8) >= size) return raw;  // checked by the caller
    if (s.order == DbcSignal::ByteOrder::kIntel) {
      raw |= static_cast<uint64_t>(bit_at(data, pos)) << i;
      ++pos;
    } else {
      raw = (raw << 1) | static_cast<uint64_t>(bit_at(data, pos));
      pos = pos % 8 == 0 ? pos + 15 : pos - 1;
    }
  }
  return raw;
}

void dbc_insert_raw(const DbcSignal& s, uint64_t raw, uint8_t* data, size_t size) {
  const std::vector<int> bits = dbc_signal_bits(s);
  for (int i = 0; i < s.length; ++i) {
    // Intel walks from the least significant bit, Motorola from the most significant.
    const int value_bit = s.order == DbcSignal::ByteOrder::kIntel ? i : s.length - 1 - i;
    const int pos = bits[static_cast<size_t>(i)];
    if (pos < 0 || static_cast<size_t>(pos / 8) >= size) continue;
    const uint8_t mask = static_cast<uint8_t>(1U << (pos % 8));
    if ((raw >> value_bit) & 1U)
      data[pos / 8] |= mask;
    else
      data[pos / 8] &= static_cast<uint8_t>(~mask);
  }
}

int64_t dbc_raw_integer(const DbcSignal& s, uint64_t raw) {
  if (!s.is_signed || s.length >= 64) return static_cast<int64_t>(raw);
  const uint64_t sign = uint64_t{1} << (s.length - 1);
  return static_cast<int64_t>((raw ^ sign) - sign);  // two's complement of a length-bit field
}

double dbc_physical(const DbcSignal& s, uint64_t raw) {
  double v = 0.0;
  if (s.type == DbcSignal::ValueType::kFloat32) {
    const uint32_t bits = static_cast<uint32_t>(raw);
    float f = 0.0F;
    std::memcpy(&f, &bits, sizeof f);
    v = f;
  } else if (s.type == DbcSignal::ValueType::kFloat64) {
    std::memcpy(&v, &raw, sizeof v);
  } else if (s.is_signed) {
    v = static_cast<double>(dbc_raw_integer(s, raw));
  } else {
    v = static_cast<double>(raw);
  }
  return v * s.factor + s.offset;
}

}  // namespace imucal::drivers::imu
