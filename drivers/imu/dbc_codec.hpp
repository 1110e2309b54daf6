#pragma once
// A DBC signal's bits in a frame's data (drivers/imu/dbc_database.hpp for the numbering): where
// they are, the raw integer they hold, and its physical value (two's complement when signed, IEEE
// float when the DBC says so, then × factor + offset).
#include <cstddef>
#include <cstdint>
#include <vector>

#include "drivers/imu/dbc_database.hpp"

namespace imucal::drivers::imu {

/// The bits the signal occupies as linear positions (byte × 8 + bit), from its least significant
/// bit (Intel) or its most significant bit (Motorola), in the order the format walks them.
std::vector<int> dbc_signal_bits(const DbcSignal& s);

/// The raw (unsigned) field of `s` in `data` (`size` bytes). The caller has checked that the
/// signal lies within the data (DbcMessage length <= size).
uint64_t dbc_extract_raw(const DbcSignal& s, const uint8_t* data, size_t size);

/// Writes the low `s.length` bits of `raw` into the signal's field, leaving every other bit.
void dbc_insert_raw(const DbcSignal& s, uint64_t raw, uint8_t* data, size_t size);

/// The raw field as an integer: sign-extended when the signal is signed.
int64_t dbc_raw_integer(const DbcSignal& s, uint64_t raw);

/// The physical value: raw (as integer or IEEE float) × factor + offset.
double dbc_physical(const DbcSignal& s, uint64_t raw);

}  // namespace imucal::drivers::imu
