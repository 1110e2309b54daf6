#pragma once
// float32 <-> two 16-bit Modbus registers.
//
// Modbus registers are big-endian 16-bit words; a 32-bit float spans two consecutive registers and
// devices disagree on how its four bytes are laid out. Name the IEEE-754 bytes A B C D, A = most
// significant (sign + exponent), so 1.0f = 0x3F800000 has A=0x3F B=0x80 C=0x00 D=0x00. Then:
//   kABCD  "high word first" (big-endian, Modicon default):  reg[0] = 0xAABB, reg[1] = 0xCCDD
//   kCDAB  "low word first" (word-swapped):                  reg[0] = 0xCCDD, reg[1] = 0xAABB
//   kBADC  high word first, bytes swapped in each word:      reg[0] = 0xBBAA, reg[1] = 0xDDCC
//   kDCBA  fully little-endian:                              reg[0] = 0xDDCC, reg[1] = 0xBBAA
// These helpers are written here on purpose instead of libmodbus' modbus_get/set_float_*: in
// bookworm's libmodbus 3.1.6 those names do not match the byte orders they implement (ARCHITECTURE
// §4).
//
// The bit pattern is carried unchanged in both directions, so NaN payloads and signed zeros survive
// a round trip; deciding whether a non-finite value is acceptable is the caller's job.
#include <array>
#include <cstdint>
#include <optional>
#include <string_view>

namespace imucal::drivers::turntable {

enum class WordOrder { kABCD, kCDAB, kBADC, kDCBA };

/// Canonical spelling used in register-map files: "ABCD", "CDAB", "BADC", "DCBA".
std::string_view to_string(WordOrder order);
/// Parses the canonical spelling (upper case only); nullopt for anything else.
std::optional<WordOrder> parse_word_order(std::string_view text);

/// Packs `value` into two registers (reg[0] at the lower address).
std::array<uint16_t, 2> encode_float(float value, WordOrder order);
/// Unpacks two registers (reg0 at the lower address) into a float.
float decode_float(uint16_t reg0, uint16_t reg1, WordOrder order);

/// Pointer forms for register images: writes regs[0], regs[1] / reads them.
void encode_float(float value, WordOrder order, uint16_t* regs);
float decode_float(const uint16_t* regs, WordOrder order);

}  // namespace imucal::drivers::turntable
