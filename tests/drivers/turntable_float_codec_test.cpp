// float32 <-> two Modbus registers: hand-computed IEEE-754 patterns for every word order.
// Patterns: 1.0f = 0x3F800000; -2.5f = sign 1, exponent 128 (0x80), mantissa 0.25 -> 0xC0200000;
// 123.456f = 0x42F6E979 (exponent 133 = 2^6, 123.456/64 = 1.929 -> mantissa 0x76E979).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include "drivers/turntable/float_codec.hpp"

namespace imucal::drivers::turntable {
namespace {

using Regs = std::array<uint16_t, 2>;

uint32_t bits(float f) {
  uint32_t u;
  std::memcpy(&u, &f, 4);
  return u;
}

TEST(FloatCodec, OneInEveryOrder) {
  EXPECT_EQ(encode_float(1.0f, WordOrder::kABCD), (Regs{0x3F80, 0x0000}));
  EXPECT_EQ(encode_float(1.0f, WordOrder::kCDAB), (Regs{0x0000, 0x3F80}));
  EXPECT_EQ(encode_float(1.0f, WordOrder::kBADC), (Regs{0x803F, 0x0000}));
  EXPECT_EQ(encode_float(1.0f, WordOrder::kDCBA), (Regs{0x0000, 0x803F}));
}

TEST(FloatCodec, MinusTwoPointFive) {
  EXPECT_EQ(encode_float(-2.5f, WordOrder::kABCD), (Regs{0xC020, 0x0000}));
  EXPECT_EQ(encode_float(-2.5f, WordOrder::kCDAB), (Regs{0x0000, 0xC020}));
  EXPECT_EQ(decode_float(0xC020, 0x0000, WordOrder::kABCD), -2.5f);
  EXPECT_EQ(decode_float(0x0000, 0xC020, WordOrder::kCDAB), -2.5f);
  EXPECT_EQ(decode_float(0x20C0, 0x0000, WordOrder::kBADC), -2.5f);
  EXPECT_EQ(decode_float(0x0000, 0x20C0, WordOrder::kDCBA), -2.5f);
}

TEST(FloatCodec, OneTwoThreePointFourFiveSix) {
  EXPECT_EQ(encode_float(123.456f, WordOrder::kABCD), (Regs{0x42F6, 0xE979}));
  EXPECT_EQ(encode_float(123.456f, WordOrder::kCDAB), (Regs{0xE979, 0x42F6}));
  EXPECT_EQ(encode_float(123.456f, WordOrder::kBADC), (Regs{0xF642, 0x79E9}));
  EXPECT_EQ(encode_float(123.456f, WordOrder::kDCBA), (Regs{0x79E9, 0xF642}));
  EXPECT_EQ(decode_float(0x42F6, 0xE979, WordOrder::kABCD), 123.456f);
  EXPECT_EQ(decode_float(0xE979, 0x42F6, WordOrder::kCDAB), 123.456f);
  EXPECT_EQ(decode_float(0xF642, 0x79E9, WordOrder::kBADC), 123.456f);
  EXPECT_EQ(decode_float(0x79E9, 0xF642, WordOrder::kDCBA), 123.456f);
}

TEST(FloatCodec, WrongWordOrderGivesADifferentValue) {
  // Reading an ABCD-packed 123.456f as CDAB gives 0xE97942F6, a large negative number: the kind of
  // silent error a wrong register-map word_order produces.
  const auto r = encode_float(123.456f, WordOrder::kABCD);
  const float wrong = decode_float(r[0], r[1], WordOrder::kCDAB);
  EXPECT_EQ(bits(wrong), 0xE97942F6u);
  EXPECT_LT(wrong, -1e25f);
}

TEST(FloatCodec, SpecialValuesKeepTheirBits) {
  const float qnan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(encode_float(qnan, WordOrder::kABCD), (Regs{0x7FC0, 0x0000}));
  EXPECT_TRUE(std::isnan(decode_float(0x7FC0, 0x0000, WordOrder::kABCD)));
  // A NaN payload (signalling-style pattern) survives both directions unchanged.
  for (auto order : {WordOrder::kABCD, WordOrder::kCDAB, WordOrder::kBADC, WordOrder::kDCBA}) {
    uint32_t u = 0x7F800123u;
    float f;
    std::memcpy(&f, &u, 4);
    const auto r = encode_float(f, order);
    EXPECT_EQ(bits(decode_float(r[0], r[1], order)), 0x7F800123u) << to_string(order);
  }
  EXPECT_EQ(encode_float(std::numeric_limits<float>::infinity(), WordOrder::kABCD), (Regs{0x7F80, 0x0000}));
  EXPECT_EQ(encode_float(-0.0f, WordOrder::kABCD), (Regs{0x8000, 0x0000}));
  EXPECT_TRUE(std::signbit(decode_float(0x0000, 0x8000, WordOrder::kCDAB)));
  // Smallest subnormal 0x00000001.
  EXPECT_EQ(decode_float(0x0000, 0x0001, WordOrder::kABCD), std::numeric_limits<float>::denorm_min());
}

TEST(FloatCodec, RoundTripsRandomBitPatterns) {
  std::mt19937 rng(7);
  for (auto order : {WordOrder::kABCD, WordOrder::kCDAB, WordOrder::kBADC, WordOrder::kDCBA}) {
    for (int i = 0; i < 2000; ++i) {
      const uint32_t u = rng();
      float f;
      std::memcpy(&f, &u, 4);
      uint16_t regs[2];
      encode_float(f, order, regs);
      ASSERT_EQ(bits(decode_float(regs, order)), u) << to_string(order);
      // The two registers hold the four bytes exactly once each.
      const uint32_t bytes_sum = (regs[0] >> 8) + (regs[0] & 0xFF) + (regs[1] >> 8) + (regs[1] & 0xFF);
      ASSERT_EQ(bytes_sum, (u >> 24) + ((u >> 16) & 0xFF) + ((u >> 8) & 0xFF) + (u & 0xFF));
    }
  }
}

TEST(FloatCodec, WordOrderNames) {
  for (auto order : {WordOrder::kABCD, WordOrder::kCDAB, WordOrder::kBADC, WordOrder::kDCBA})
    EXPECT_EQ(parse_word_order(to_string(order)), order);
  EXPECT_FALSE(parse_word_order("abcd"));
  EXPECT_FALSE(parse_word_order("big"));
  EXPECT_FALSE(parse_word_order(""));
}

}  // namespace
}  // namespace imucal::drivers::turntable
