#include "drivers/imu/imu_sample_codec.hpp"

#include <algorithm>
#include <cmath>
#include <set>

#include "drivers/imu/dbc_codec.hpp"
#include "drivers/imu/imu_protocol.hpp"

namespace imucal::drivers::imu {

namespace {

constexpr std::array<uint8_t, 256> crc8_table() {
  std::array<uint8_t, 256> t{};
  for (unsigned i = 0; i < 256; ++i) {
    uint8_t crc = static_cast<uint8_t>(i);
    for (int b = 0; b < 8; ++b)
      crc = static_cast<uint8_t>((crc & 0x80) ? (crc << 1) ^ 0x1D : crc << 1);
    t[i] = crc;
  }
  return t;
}
constexpr std::array<uint8_t, 256> kCrc8Table = crc8_table();

}  // namespace

uint8_t crc8_sae_j1850_update(uint8_t crc, const uint8_t* bytes, size_t len) {
  for (size_t i = 0; i < len; ++i) crc = kCrc8Table[crc ^ bytes[i]];
  return crc;
}

uint8_t crc8_sae_j1850(const uint8_t* bytes, size_t len) {
  return static_cast<uint8_t>(crc8_sae_j1850_update(0xFF, bytes, len) ^ 0xFF);
}

namespace {

size_t position(const DbcSignalRef& r) { return static_cast<size_t>(r.position); }

int64_t raw_min(const DbcSignal& s) {
  if (!s.is_signed) return 0;
  return s.length >= 64 ? INT64_MIN : -(int64_t{1} << (s.length - 1));
}
int64_t raw_max(const DbcSignal& s) {
  if (s.length >= 63) return INT64_MAX;
  return s.is_signed ? (int64_t{1} << (s.length - 1)) - 1 : (int64_t{1} << s.length) - 1;
}

/// The raw integer for a physical value, clipped to [lo, hi]; `clipped` when it was beyond.
int64_t counts_of(const DbcSignal& s, double physical, int64_t lo, int64_t hi, bool& clipped) {
  const double counts = std::round((physical - s.offset) / s.factor);
  const double dlo = static_cast<double>(lo), dhi = static_cast<double>(hi);
  clipped = !(counts >= dlo && counts <= dhi);
  return static_cast<int64_t>(std::isfinite(counts) ? std::clamp(counts, dlo, dhi) : 0.0);
}

/// The check over the covered bytes, in order.
uint64_t check_value(const ImuProtocolMap& map, const uint8_t* const* frames) {
  const bool crc8 = map.check == ImuProtocolMap::Check::kCrc8SaeJ1850;
  uint16_t crc16 = 0xFFFF;
  uint8_t c8 = 0xFF;
  for (const ImuProtocolMap::ByteRange& r : map.check_covers) {
    const uint8_t* d = frames[static_cast<size_t>(r.position)] + r.first;
    const size_t n = static_cast<size_t>(r.last - r.first + 1);
    if (crc8)
      c8 = crc8_sae_j1850_update(c8, d, n);
    else
      crc16 = crc16_ccitt_false(d, n, crc16);
  }
  return crc8 ? static_cast<uint8_t>(c8 ^ 0xFF) : crc16;
}

/// The page (multiplexor value) a multiplexed message carries for this sample; nullopt for a
/// message without a multiplexor. Raised flags choose their page; otherwise the pages the map's
/// signals use take turns by the counter.
std::optional<int64_t> page_of(const ImuProtocolMap& map, int message, const ProtocolSample& s,
                               const std::vector<bool>& raised) {
  if (!map.message(message).multiplexor()) return std::nullopt;
  std::set<int64_t> pages;
  std::optional<int64_t> flagged;
  for (size_t i = 0; i < map.flags.size(); ++i) {
    const DbcSignalRef& r = map.flags[i].ref;
    const std::optional<int64_t>& v = map.signal(r).multiplex_value;
    if (r.message != message || !v) continue;
    pages.insert(*v);
    if (raised[i] && (!flagged || *v < *flagged)) flagged = *v;
  }
  if (map.temperature.message == message && map.signal(map.temperature).multiplex_value)
    pages.insert(*map.signal(map.temperature).multiplex_value);
  if (flagged) return flagged;
  if (pages.empty()) return int64_t{0};
  auto it = pages.begin();
  std::advance(it, static_cast<long>(s.counter % pages.size()));
  return *it;
}

struct Writer {
  const ImuProtocolMap& map;
  std::vector<std::array<uint8_t, 64>>& data;
  std::vector<std::optional<int64_t>> page;  ///< per position
  /// False when the signal's page is not the one its frame carries (nothing written).
  bool put(const DbcSignalRef& r, uint64_t raw) {
    const DbcSignal& s = map.signal(r);
    const size_t p = position(r);
    if (s.multiplex_value && page[p] && *s.multiplex_value != *page[p]) return false;
    dbc_insert_raw(s, raw, data[p].data(), static_cast<size_t>(map.message(r.message).length));
    return true;
  }
};

/// Which flags to raise: bit i of s.flags, and the first signal of each condition's list.
std::vector<bool> raised_flags(const ImuProtocolMap& map, const ProtocolSample& s, bool clipped,
                               bool temperature_unknown) {
  using C = ImuProtocolMap::Condition;
  std::vector<bool> on(map.flags.size(), false);
  bool first_done[4] = {false, false, false, false};
  for (size_t i = 0; i < map.flags.size(); ++i) {
    const C c = map.flags[i].condition;
    const bool cond =
        (c == C::kFault && s.fault) || (c == C::kSaturation && (s.saturation || clipped)) ||
        (c == C::kStartup && s.startup) || (c == C::kTemperatureInvalid && temperature_unknown);
    bool& first = first_done[static_cast<int>(c)];
    on[i] = ((s.flags >> i) & 1U) || (cond && !first);
    first = true;
  }
  return on;
}

/// The temperature's raw field: the unknown value for NaN, otherwise rounded and clipped to the
/// range without the unknown value.
uint64_t temperature_raw(const ImuProtocolMap& map, double temperature_c) {
  const DbcSignal& s = map.signal(map.temperature);
  int64_t lo = raw_min(s), hi = raw_max(s);
  if (!std::isfinite(temperature_c))
    return static_cast<uint64_t>(map.temperature_unknown.value_or(0));
  if (map.temperature_unknown == lo) ++lo;
  if (map.temperature_unknown == hi) --hi;
  bool clipped = false;
  return static_cast<uint64_t>(counts_of(s, temperature_c, lo, hi, clipped));
}

}  // namespace

double sent_value(const DbcSignal& s, double physical, bool& clipped) {
  const int64_t c = counts_of(s, physical, raw_min(s), raw_max(s), clipped);
  return static_cast<double>(c) * s.factor + s.offset;
}

std::vector<ProtocolFrame> encode_sample(const ImuProtocolMap& map, const ProtocolSample& s) {
  std::vector<std::array<uint8_t, 64>> data(map.messages.size());
  bool clipped_any = false;
  std::array<uint64_t, 3> ang_raw{}, vel_raw{};
  for (size_t i = 0; i < 3; ++i) {
    bool clipped = false;
    const DbcSignal& a = map.signal(map.angular[i]);
    ang_raw[i] = static_cast<uint64_t>(
        counts_of(a, s.angular[i] / map.angular_scale, raw_min(a), raw_max(a), clipped));
    clipped_any = clipped_any || clipped;
    const DbcSignal& v = map.signal(map.velocity[i]);
    vel_raw[i] = static_cast<uint64_t>(
        counts_of(v, s.velocity[i] / map.velocity_scale, raw_min(v), raw_max(v), clipped));
    clipped_any = clipped_any || clipped;
  }
  const bool has_temperature = map.temperature.message >= 0;
  const std::vector<bool> raised =
      raised_flags(map, s, clipped_any, has_temperature && !std::isfinite(s.temperature_c));
  Writer w{map, data, {}};
  for (const int m : map.messages) w.page.push_back(page_of(map, m, s, raised));
  for (size_t p = 0; p < map.messages.size(); ++p)
    if (w.page[p])
      dbc_insert_raw(*map.message(map.messages[p]).multiplexor(), static_cast<uint64_t>(*w.page[p]),
                     data[p].data(), static_cast<size_t>(map.message(map.messages[p]).length));
  for (size_t i = 0; i < 3; ++i) {
    w.put(map.angular[i], ang_raw[i]);
    w.put(map.velocity[i], vel_raw[i]);
  }
  for (const ImuProtocolMap::CounterPart& p : map.counter)
    w.put(p.ref, (s.counter >> p.shift) & ((uint64_t{1} << p.bits) - 1));
  const uint64_t low = s.counter & ((uint64_t{1} << map.counter.front().bits) - 1);
  for (const DbcSignalRef& r : map.same_in) w.put(r, low);
  for (size_t i = 0; i < map.flags.size(); ++i) w.put(map.flags[i].ref, raised[i] ? 1 : 0);
  if (has_temperature) w.put(map.temperature, temperature_raw(map, s.temperature_c));
  if (map.check != ImuProtocolMap::Check::kNone) {
    std::vector<const uint8_t*> ptr;
    for (const auto& d : data) ptr.push_back(d.data());
    w.put(map.check_signal, check_value(map, ptr.data()));
  }
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
  if (frames.size() != map.messages.size()) {
    SampleReading r;
    r.why = "a sample has " + std::to_string(map.messages.size()) + " frames, got " +
            std::to_string(frames.size());
    return r;
  }
  std::vector<const uint8_t*> ptr;
  for (const auto& d : frames) ptr.push_back(d.data());
  return decode_sample(map, ptr.data());
}

namespace {

/// Reads the mapped signals of one complete, checked set of frames.
struct Reader {
  const ImuProtocolMap& map;
  const uint8_t* const* frames;

  uint64_t raw(const DbcSignalRef& ref) const {
    return dbc_extract_raw(map.signal(ref), frames[position(ref)],
                           static_cast<size_t>(map.message(ref.message).length));
  }
  /// A multiplexed signal is in this sample only when its frame carries its page.
  bool present(const DbcSignalRef& ref) const {
    const DbcSignal& s = map.signal(ref);
    if (!s.multiplex_value) return true;
    const DbcSignal& mux = *map.message(ref.message).multiplexor();
    const uint64_t page = dbc_extract_raw(mux, frames[position(ref)],
                                          static_cast<size_t>(map.message(ref.message).length));
    return dbc_raw_integer(mux, page) == *s.multiplex_value;
  }
  void flags(ProtocolSample& out) const {
    using C = ImuProtocolMap::Condition;
    for (size_t i = 0; i < map.flags.size(); ++i) {
      const DbcSignalRef& ref = map.flags[i].ref;
      if (!present(ref) || raw(ref) == 0) continue;
      out.flags |= 1U << i;
      switch (map.flags[i].condition) {
        case C::kFault:
          out.fault = true;
          break;
        case C::kSaturation:
          out.saturation = true;
          break;
        case C::kStartup:
          out.startup = true;
          break;
        case C::kTemperatureInvalid:
          out.temperature_invalid = true;
          break;
      }
    }
  }
  void temperature(ProtocolSample& out) const {
    if (map.temperature.message < 0 || !present(map.temperature)) return;
    out.temperature_carried = true;
    const uint64_t r = raw(map.temperature);
    const DbcSignal& s = map.signal(map.temperature);
    if (out.temperature_invalid ||
        (map.temperature_unknown && dbc_raw_integer(s, r) == *map.temperature_unknown))
      return;
    out.temperature_c = dbc_physical(s, r);
  }
};

}  // namespace

SampleReading decode_sample(const ImuProtocolMap& map, const uint8_t* const* frames) {
  SampleReading r;
  const Reader rd{map, frames};
  if (map.check != ImuProtocolMap::Check::kNone &&
      rd.raw(map.check_signal) != check_value(map, frames)) {
    r.why = "check failed";
    return r;
  }
  for (const ImuProtocolMap::CounterPart& p : map.counter)
    r.sample.counter |=
        static_cast<uint32_t>((rd.raw(p.ref) & ((uint64_t{1} << p.bits) - 1)) << p.shift);
  const uint64_t low_mask = (uint64_t{1} << map.counter.front().bits) - 1;
  for (const DbcSignalRef& c : map.same_in)
    if ((rd.raw(c) & low_mask) != (r.sample.counter & low_mask)) {
      r.why = "counter copies differ (" + c.text + ")";
      return r;
    }
  for (size_t i = 0; i < 3; ++i) {
    r.sample.angular[i] =
        dbc_physical(map.signal(map.angular[i]), rd.raw(map.angular[i])) * map.angular_scale;
    r.sample.velocity[i] =
        dbc_physical(map.signal(map.velocity[i]), rd.raw(map.velocity[i])) * map.velocity_scale;
  }
  rd.flags(r.sample);
  rd.temperature(r.sample);
  r.ok = true;
  return r;
}

}  // namespace imucal::drivers::imu
