#include "drivers/imu/imu_sample_codec.hpp"

#include <algorithm>
#include <cmath>

#include "drivers/imu/dbc_codec.hpp"
#include "drivers/imu/imu_protocol.hpp"

namespace imucal::imu {

uint8_t crc8_sae_j1850(const uint8_t* bytes, size_t len) {
  uint8_t crc = 0xFF;
  for (size_t i = 0; i < len; ++i) {
    crc ^= bytes[i];
    for (int b = 0; b < 8; ++b)
      crc = static_cast<uint8_t>((crc & 0x80) ? (crc << 1) ^ 0x1D : crc << 1);
  }
  return static_cast<uint8_t>(crc ^ 0xFF);
}

namespace {

/// Where message index `m` sits in the sample (its position in map.messages).
size_t position(const ImuProtocolMap& map, int m) {
  return static_cast<size_t>(std::find(map.messages.begin(), map.messages.end(), m) -
                             map.messages.begin());
}

int64_t raw_min(const DbcSignal& s) {
  if (!s.is_signed) return 0;
  return s.length >= 64 ? INT64_MIN : -(int64_t{1} << (s.length - 1));
}
int64_t raw_max(const DbcSignal& s) {
  if (s.length >= 63) return INT64_MAX;
  return s.is_signed ? (int64_t{1} << (s.length - 1)) - 1 : (int64_t{1} << s.length) - 1;
}

/// The raw field for a physical value; `clipped` when it is beyond the field's range.
uint64_t raw_of(const DbcSignal& s, double physical, bool& clipped) {
  const double counts = std::round((physical - s.offset) / s.factor);
  const double lo = static_cast<double>(raw_min(s)), hi = static_cast<double>(raw_max(s));
  clipped = !(counts >= lo && counts <= hi);
  const double c = std::isfinite(counts) ? std::clamp(counts, lo, hi) : 0.0;
  return static_cast<uint64_t>(static_cast<int64_t>(c));
}

/// The bytes the check covers, in order.
std::vector<uint8_t> covered(const ImuProtocolMap& map,
                             const std::vector<std::array<uint8_t, 64>>& frames) {
  std::vector<uint8_t> out;
  for (const ImuProtocolMap::ByteRange& r : map.check_covers) {
    const auto& d = frames[position(map, r.message)];
    out.insert(out.end(), d.begin() + r.first, d.begin() + r.last + 1);
  }
  return out;
}

uint64_t check_value(const ImuProtocolMap& map, const std::vector<uint8_t>& bytes) {
  if (map.check == ImuProtocolMap::Check::kCrc8SaeJ1850)
    return crc8_sae_j1850(bytes.data(), bytes.size());
  return crc16_ccitt_false(bytes.data(), bytes.size());
}

struct Writer {
  const ImuProtocolMap& map;
  std::vector<std::array<uint8_t, 64>>& data;
  void put(const DbcSignalRef& r, uint64_t raw) {
    const DbcSignal& s = map.signal(r);
    auto& d = data[position(map, r.message)];
    dbc_insert_raw(s, raw, d.data(), static_cast<size_t>(map.message(r.message).length));
    // A multiplexed signal is present only with its multiplexor's value.
    if (s.multiplex_value)
      dbc_insert_raw(*map.message(r.message).multiplexor(),
                     static_cast<uint64_t>(*s.multiplex_value), d.data(),
                     static_cast<size_t>(map.message(r.message).length));
  }
};

}  // namespace

std::vector<ProtocolFrame> encode_sample(const ImuProtocolMap& map, const ProtocolSample& s) {
  std::vector<std::array<uint8_t, 64>> data(map.messages.size());
  Writer w{map, data};
  bool clipped_any = false;
  for (int i = 0; i < 3; ++i) {
    bool clipped = false;
    w.put(map.angular[i],
          raw_of(map.signal(map.angular[i]), s.angular[i] / map.angular_scale, clipped));
    clipped_any = clipped_any || clipped;
    w.put(map.velocity[i],
          raw_of(map.signal(map.velocity[i]), s.velocity[i] / map.velocity_scale, clipped));
    clipped_any = clipped_any || clipped;
  }
  for (const ImuProtocolMap::CounterPart& p : map.counter)
    w.put(p.ref, (s.counter >> p.shift) & ((uint64_t{1} << p.bits) - 1));
  const uint64_t low = s.counter & ((uint64_t{1} << map.counter.front().bits) - 1);
  for (const DbcSignalRef& r : map.same_in) w.put(r, low);
  auto flags = [&](const std::vector<DbcSignalRef>& refs, bool on) {
    for (const DbcSignalRef& r : refs) w.put(r, on ? 1 : 0);
  };
  flags(map.fault, s.fault);
  flags(map.saturation, s.saturation || clipped_any);
  flags(map.startup, s.startup);
  if (map.check != ImuProtocolMap::Check::kNone)
    w.put(map.check_signal, check_value(map, covered(map, data)));
  std::vector<ProtocolFrame> out;
  for (size_t i = 0; i < map.messages.size(); ++i) {
    const DbcMessage& m = map.message(map.messages[i]);
    ProtocolFrame f;
    f.message = map.messages[i];
    f.id = m.id;
    f.extended = m.extended;
    f.length = m.length;
    f.data = data[i];
    out.push_back(f);
  }
  return out;
}

SampleReading decode_sample(const ImuProtocolMap& map,
                            const std::vector<std::array<uint8_t, 64>>& frames) {
  SampleReading r;
  if (frames.size() != map.messages.size()) {
    r.why = "a sample has " + std::to_string(map.messages.size()) + " frames, got " +
            std::to_string(frames.size());
    return r;
  }
  auto raw = [&](const DbcSignalRef& ref) {
    return dbc_extract_raw(map.signal(ref), frames[position(map, ref.message)].data(),
                           static_cast<size_t>(map.message(ref.message).length));
  };
  if (map.check != ImuProtocolMap::Check::kNone &&
      raw(map.check_signal) != check_value(map, covered(map, frames))) {
    r.why = "check failed";
    return r;
  }
  for (const ImuProtocolMap::CounterPart& p : map.counter)
    r.sample.counter |=
        static_cast<uint32_t>((raw(p.ref) & ((uint64_t{1} << p.bits) - 1)) << p.shift);
  const uint64_t low_mask = (uint64_t{1} << map.counter.front().bits) - 1;
  for (const DbcSignalRef& c : map.same_in)
    if ((raw(c) & low_mask) != (r.sample.counter & low_mask)) {
      r.why = "counter copies differ (" + c.text + ")";
      return r;
    }
  for (int i = 0; i < 3; ++i) {
    r.sample.angular[i] =
        dbc_physical(map.signal(map.angular[i]), raw(map.angular[i])) * map.angular_scale;
    r.sample.velocity[i] =
        dbc_physical(map.signal(map.velocity[i]), raw(map.velocity[i])) * map.velocity_scale;
  }
  // A flag in a multiplexed frame is reported only when the frame carries its page.
  auto present = [&](const DbcSignalRef& ref) {
    const DbcSignal& s = map.signal(ref);
    if (!s.multiplex_value) return true;
    const DbcSignal& mux = *map.message(ref.message).multiplexor();
    const uint64_t page = dbc_extract_raw(mux, frames[position(map, ref.message)].data(),
                                          static_cast<size_t>(map.message(ref.message).length));
    return dbc_raw_integer(mux, page) == *s.multiplex_value;
  };
  auto any = [&](const std::vector<DbcSignalRef>& refs) {
    for (const DbcSignalRef& ref : refs)
      if (present(ref) && raw(ref) != 0) return true;
    return false;
  };
  r.sample.fault = any(map.fault);
  r.sample.saturation = any(map.saturation);
  r.sample.startup = any(map.startup);
  r.ok = true;
  return r;
}

}  // namespace imucal::imu
