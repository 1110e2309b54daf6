#include "drivers/turntable/float_codec.hpp"

#include <cstring>

namespace imucal::drivers::turntable {
namespace {

uint16_t swap_bytes(uint16_t w) { return static_cast<uint16_t>((w >> 8) | (w << 8)); }

uint32_t bits_of(float v) {
  uint32_t u;
  static_assert(sizeof u == sizeof v, "float must be 32 bits");
  std::memcpy(&u, &v, sizeof u);
  return u;
}

float float_of(uint32_t u) {
  float v;
  std::memcpy(&v, &u, sizeof v);
  return v;
}

}  // namespace

std::string_view to_string(WordOrder order) {
  switch (order) {
    case WordOrder::kABCD: return "ABCD";
    case WordOrder::kCDAB: return "CDAB";
    case WordOrder::kBADC: return "BADC";
    case WordOrder::kDCBA: return "DCBA";
  }
  return "?";
}

std::optional<WordOrder> parse_word_order(std::string_view text) {
  if (text == "ABCD") return WordOrder::kABCD;
  if (text == "CDAB") return WordOrder::kCDAB;
  if (text == "BADC") return WordOrder::kBADC;
  if (text == "DCBA") return WordOrder::kDCBA;
  return std::nullopt;
}

std::array<uint16_t, 2> encode_float(float value, WordOrder order) {
  const uint32_t u = bits_of(value);
  const auto hi = static_cast<uint16_t>(u >> 16);      // 0xAABB
  const auto lo = static_cast<uint16_t>(u & 0xFFFFu);  // 0xCCDD
  switch (order) {
    case WordOrder::kABCD: return {hi, lo};
    case WordOrder::kCDAB: return {lo, hi};
    case WordOrder::kBADC: return {swap_bytes(hi), swap_bytes(lo)};
    case WordOrder::kDCBA: return {swap_bytes(lo), swap_bytes(hi)};
  }
  return {hi, lo};
}

float decode_float(uint16_t reg0, uint16_t reg1, WordOrder order) {
  uint16_t hi = reg0, lo = reg1;
  switch (order) {
    case WordOrder::kABCD: hi = reg0; lo = reg1; break;
    case WordOrder::kCDAB: hi = reg1; lo = reg0; break;
    case WordOrder::kBADC: hi = swap_bytes(reg0); lo = swap_bytes(reg1); break;
    case WordOrder::kDCBA: hi = swap_bytes(reg1); lo = swap_bytes(reg0); break;
  }
  return float_of((static_cast<uint32_t>(hi) << 16) | lo);
}

void encode_float(float value, WordOrder order, uint16_t* regs) {
  const auto r = encode_float(value, order);
  regs[0] = r[0];
  regs[1] = r[1];
}

float decode_float(const uint16_t* regs, WordOrder order) { return decode_float(regs[0], regs[1], order); }

}  // namespace imucal::drivers::turntable
