#include "drivers/imu/imu_codec.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <stdexcept>
#include <string>

#include "drivers/imu/dbc_codec.hpp"
#include "drivers/imu/imu_sample_codec.hpp"

namespace imucal::drivers::imu {

std::shared_ptr<const ImuProtocolMap> resolve_protocol(
    std::shared_ptr<const ImuProtocolMap> protocol, std::optional<uint32_t> base_id) {
  if (!protocol) protocol = builtin_protocol_map();
  if (base_id) protocol = std::make_shared<const ImuProtocolMap>(with_base_id(*protocol, *base_id));
  const std::string why = station_unsupported(*protocol);
  if (!why.empty()) throw std::invalid_argument(why);
  return protocol;
}

namespace {

uint32_t mask_of(int bits) {
  return bits >= 32 ? UINT32_MAX : static_cast<uint32_t>((uint64_t{1} << bits) - 1);
}

}  // namespace

// ----------------------------------------------------------------------------------------- encoder

ImuFrameEncoder::ImuFrameEncoder(uint32_t base_id, bool carry_remainder)
    : ImuFrameEncoder(nullptr, base_id, carry_remainder) {}

ImuFrameEncoder::ImuFrameEncoder(std::shared_ptr<const ImuProtocolMap> protocol,
                                 std::optional<uint32_t> base_id, bool carry_remainder)
    : map_(resolve_protocol(std::move(protocol), base_id)), carry_remainder_(carry_remainder) {
  base_id_ = lowest_id(*map_);
}

void ImuFrameEncoder::restart() {
  counter_ = 0;
  startup_left_ = kStartupSamples;
  carry_dtheta_rad_ = {};
  carry_dv_mps_ = {};
}

double ImuFrameEncoder::quantise(double increment, const DbcSignal& s, double scale, double dt_s,
                                 double& carry, bool& clipped) const {
  const bool rates = map_->quantity == ImuProtocolMap::Quantity::kRates;
  const double total = increment + (carry_remainder_ ? carry : 0.0);
  bool clip = false;
  const double sent = sent_value(s, (rates ? total / dt_s : total) / scale, clip) * scale;
  if (clip) {
    // Clipped: the remainder would be meaningless (and grow without bound), so it is dropped.
    clipped = true;
    carry = 0.0;
  } else {
    carry = total - (rates ? sent * dt_s : sent);
  }
  return sent;
}

uint32_t ImuFrameEncoder::flags_for(uint16_t st, bool gyro_clip, bool accel_clip) const {
  using C = ImuProtocolMap::Condition;
  uint32_t flags = 0;
  // The index-th flag of a condition's list (the first when the list is shorter).
  auto raise = [&](C c, size_t index) {
    int first = -1, chosen = -1;
    size_t k = 0;
    for (size_t i = 0; i < map_->flags.size(); ++i) {
      if (map_->flags[i].condition != c) continue;
      if (first < 0) first = static_cast<int>(i);
      if (k++ == index) chosen = static_cast<int>(i);
    }
    if (chosen < 0) chosen = first;
    if (chosen >= 0) flags |= 1U << chosen;
  };
  if (st & status::kGyroFault) raise(C::kFault, 0);
  if (st & status::kAccelFault) raise(C::kFault, 1);
  if (st & status::kBitFail) raise(C::kFault, 2);
  if ((st & status::kGyroSaturated) || gyro_clip) raise(C::kSaturation, 0);
  if ((st & status::kAccelSaturated) || accel_clip) raise(C::kSaturation, 1);
  if (st & status::kStartup) raise(C::kStartup, 0);
  if (st & status::kTempInvalid) raise(C::kTemperatureInvalid, 0);
  return flags;
}

std::vector<CanFrame> ImuFrameEncoder::encode(const calib::core::ImuIncrement& inc,
                                              uint16_t status_flags) {
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(inc.dtheta_rad(i)) || !std::isfinite(inc.dv_mps(i)))
      throw std::invalid_argument("ImuFrameEncoder: non-finite increment component " + std::to_string(i) +
                                  " at t_s=" + std::to_string(inc.t_s));
  ProtocolSample s;
  bool gyro_clip = false, accel_clip = false;
  for (size_t i = 0; i < 3; ++i) {
    s.angular[i] = quantise(inc.dtheta_rad(static_cast<int>(i)), map_->signal(map_->angular[i]),
                            map_->angular_scale, inc.dt_s, carry_dtheta_rad_[i], gyro_clip);
    s.velocity[i] = quantise(inc.dv_mps(static_cast<int>(i)), map_->signal(map_->velocity[i]),
                             map_->velocity_scale, inc.dt_s, carry_dv_mps_[i], accel_clip);
  }
  if (startup_left_ > 0) {
    status_flags |= status::kStartup;
    --startup_left_;
  }
  s.temperature_c = inc.temp_c;
  if (!std::isfinite(inc.temp_c)) status_flags |= status::kTempInvalid;
  s.counter = counter_;
  s.flags = flags_for(status_flags, gyro_clip, accel_clip);
  counter_ = (counter_ + 1) & mask_of(map_->counter_bits);
  std::vector<CanFrame> frames;
  for (const ProtocolFrame& p : encode_sample(*map_, s)) {
    CanFrame f;
    f.can_id = p.id | (p.extended ? kCanEffFlag : 0U);
    f.len = static_cast<uint8_t>(p.length);
    std::memcpy(f.data.data(), p.data.data(), f.len);
    frames.push_back(f);
  }
  return frames;
}

// ----------------------------------------------------------------------------------------- decoder

ImuFrameDecoder::ImuFrameDecoder(const DecoderOptions& options)
    : options_(options), map_(resolve_protocol(options.protocol, options.base_id)) {
  if (!(options.sample_rate_hz > 0.0) || !std::isfinite(options.sample_rate_hz))
    throw std::invalid_argument("ImuFrameDecoder: sample_rate_hz must be positive, got " +
                                std::to_string(options.sample_rate_hz));
  if (options.reorder_window_frames < 1)
    throw std::invalid_argument("ImuFrameDecoder: reorder_window_frames must be >= 1");
  parts_ = static_cast<int>(map_->messages.size());
  dt_s_ = 1.0 / options.sample_rate_hz;
  to_increment_ = map_->quantity == ImuProtocolMap::Quantity::kRates ? dt_s_ : 1.0;
  counter_mask_ = mask_of(map_->counter_bits);
  tie_mask_ = mask_of(map_->counter.front().bits);
  const uint64_t half = (uint64_t{counter_mask_} + 1) / 2;
  late_window_ = static_cast<uint32_t>(std::min<uint64_t>(256, half / 2));
  restart_jump_ = static_cast<uint32_t>(std::min<uint64_t>(64, half / 2));
  hold_span_ = static_cast<uint32_t>(std::min<uint64_t>(256, uint64_t{tie_mask_} + 1));
  last_temperature_c_ = std::numeric_limits<double>::quiet_NaN();
  held_.reserve(kMaxHeld + 1);
}

std::string ImuFrameDecoder::flag_names(uint32_t flags, uint8_t conditions) const {
  std::string s;
  for (size_t i = 0; i < map_->flags.size(); ++i) {
    const uint8_t c = static_cast<uint8_t>(1U << static_cast<int>(map_->flags[i].condition));
    if (((flags >> i) & 1U) && (c & conditions))
      s += (s.empty() ? "" : ", ") + map_->flags[i].ref.text;
  }
  return s;
}

int ImuFrameDecoder::part_of(const CanFrame& f) const {
  const uint32_t id = f.id();
  for (int p = 0; p < parts_; ++p) {
    const DbcMessage& m = map_->message(map_->messages[static_cast<size_t>(p)]);
    if (m.id == id && m.extended == f.is_extended()) return p;
  }
  return -1;
}

uint32_t ImuFrameDecoder::tie_of(int part, const Data& data) const {
  const DbcSignalRef& t = map_->tie[static_cast<size_t>(part)];
  return static_cast<uint32_t>(dbc_extract_raw(map_->signal(t), data.data(), data.size())) &
         tie_mask_;
}

bool ImuFrameDecoder::slot_complete(const Slot& s) const {
  for (int p = 0; p < parts_; ++p)
    if (s.n[static_cast<size_t>(p)] == 0) return false;
  return true;
}

int ImuFrameDecoder::slot_total(const Slot& s) const {
  int t = 0;
  for (int p = 0; p < parts_; ++p) t += s.n[static_cast<size_t>(p)];
  return t;
}

bool ImuFrameDecoder::is_recent_duplicate(int part, const Data& data) const {
  const auto p = static_cast<std::size_t>(part);
  const Recent& r = recent_[tie_of(part, data) & 0xFF];
  if (r.valid && counters_.samples_decoded - r.decoded_no < kRecentSamples && r.data[p] == data)
    return true;
  for (const Verified& v : held_)
    if (v.data[p] == data) return true;
  return false;
}

void ImuFrameDecoder::push(const ReceivedFrame& rf, std::vector<DecodedSample>& out) {
  const CanFrame& f = rf.frame;
  const uint64_t arrival = ++counters_.frames_in;
  [&] {
    if (f.is_error()) {
      ++counters_.error_frames;
      return;
    }
    const int part = part_of(f);
    if (part < 0) {
      ++counters_.foreign_frames;
      return;
    }
    const auto p = static_cast<std::size_t>(part);
    if (f.is_remote() || f.len != map_->message(map_->messages[p]).length) {
      ++counters_.malformed_frames;
      return;
    }
    const uint32_t tie = tie_of(part, f.data);
    Slot* slot = nullptr;
    for (Slot& s : slots_)
      if (s.live && s.tie == tie) slot = &s;
    if (slot) {
      for (int i = 0; i < slot->n[p]; ++i)
        if (slot->cand[p][static_cast<std::size_t>(i)].data == f.data) {
          ++counters_.duplicate_frames;
          return;
        }
      if (slot->n[p] == 2) {  // a third different frame for one part: keep the first two
        ++counters_.discarded_frames;
        return;
      }
    } else {
      if (is_recent_duplicate(part, f.data)) {
        ++counters_.duplicate_frames;
        return;
      }
      for (Slot& s : slots_)
        if (!s.live) {
          slot = &s;
          break;
        }
      if (!slot) {  // all slots busy (heavy corruption): give up the oldest
        slot = &*std::min_element(slots_.begin(), slots_.end(), [](const Slot& a, const Slot& b) {
          return a.created_arrival < b.created_arrival;
        });
        abandon(*slot);
      }
      *slot = Slot{};
      slot->live = true;
      slot->tie = tie;
      slot->created_arrival = arrival;
    }
    slot->cand[p][static_cast<std::size_t>(slot->n[p]++)] = Candidate{f.data, arrival, rf.rx_time_ns};
    if (slot_complete(*slot)) complete(*slot, out);
  }();
  // Give up samples that have waited too long for missing frames (or a check-consistent candidate).
  for (Slot& s : slots_)
    if (s.live && arrival - s.created_arrival >= static_cast<uint64_t>(options_.reorder_window_frames))
      abandon(s);
  release(out, false);
}

void ImuFrameDecoder::abandon(Slot& slot) {
  if (slot_complete(slot))
    ++counters_.samples_corrupt;  // every frame arrived but no combination passed the check
  else
    ++counters_.samples_incomplete;
  counters_.discarded_frames += static_cast<uint64_t>(slot_total(slot));
  slot.live = false;
}

bool ImuFrameDecoder::verify(const Slot& slot, const std::array<int, kMaxParts>& pick,
                             Verified& v) {
  std::array<const uint8_t*, kMaxParts> ptr{};
  std::array<const Candidate*, kMaxParts> c{};
  for (size_t p = 0; p < static_cast<size_t>(parts_); ++p) {
    c[p] = &slot.cand[p][static_cast<size_t>(pick[p])];
    ptr[p] = c[p]->data.data();
  }
  const SampleReading r = decode_sample(*map_, ptr.data());
  if (!r.ok) return false;
  v.completed_at = counters_.frames_in;
  v.tie = slot.tie;
  for (size_t p = 0; p < static_cast<size_t>(parts_); ++p) {
    v.data[p] = c[p]->data;
    v.arrival[p] = c[p]->arrival;
  }
  DecodedSample& d = v.sample;
  d.counter = r.sample.counter;
  d.flags = r.sample.flags;
  d.conditions =
      static_cast<uint8_t>((r.sample.fault ? condition::kFault : 0) |
                           (r.sample.saturation ? condition::kSaturation : 0) |
                           (r.sample.startup ? condition::kStartup : 0) |
                           (r.sample.temperature_invalid ? condition::kTemperatureInvalid : 0));
  d.rx_time_ns = c[static_cast<size_t>(parts_ - 1)]->rx_time_ns;
  for (int a = 0; a < 3; ++a) {
    d.increment.dtheta_rad(a) = r.sample.angular[static_cast<size_t>(a)] * to_increment_;
    d.increment.dv_mps(a) = r.sample.velocity[static_cast<size_t>(a)] * to_increment_;
  }
  d.increment.dt_s = dt_s_;
  if (r.sample.temperature_carried) last_temperature_c_ = r.sample.temperature_c;
  d.increment.temp_c = last_temperature_c_;
  return true;
}

void ImuFrameDecoder::complete(Slot& slot, std::vector<DecodedSample>& out) {
  // A frame whose counter copy was corrupted can land in this slot as a second candidate for one
  // part; the check picks the consistent combination (at most 2^parts tries).
  std::array<int, kMaxParts> pick{};
  for (;;) {
    Verified v;
    if (verify(slot, pick, v)) {
      counters_.discarded_frames += static_cast<uint64_t>(slot_total(slot) - parts_);
      slot.live = false;
      accept(std::move(v), out);
      return;
    }
    int p = 0;  // next combination (odometer over the parts' candidates)
    for (; p < parts_; ++p) {
      const auto q = static_cast<size_t>(p);
      if (++pick[q] < slot.n[q]) break;
      pick[q] = 0;
    }
    if (p == parts_) break;
  }
  // No consistent combination yet: keep the slot; a later candidate may complete it, otherwise it
  // expires as corrupt.
}

void ImuFrameDecoder::accept(Verified&& v, std::vector<DecodedSample>& out) {
  const uint32_t c = v.sample.counter;
  const auto parts = static_cast<uint64_t>(parts_);
  for (const Verified& h : held_)
    if (h.sample.counter == c) {
      counters_.duplicate_frames += parts;
      return;
    }
  if (!have_last_) {
    emit(v, false, out);
    return;
  }
  const uint32_t d = fwd(c, last_counter_);
  const bool startup = (v.sample.conditions & condition::kStartup) != 0;
  if (startup && (!(last_conditions_ & condition::kStartup) || d == 0 || d > restart_jump_)) {
    // The counter restarted with the startup flag: the IMU was reset. Output what is held first.
    release(out, true);
    ++counters_.imu_resets;
    emit(v, true, out);
    return;
  }
  if (d == 0) {
    counters_.duplicate_frames += parts;
    return;
  }
  const uint64_t range = uint64_t{counter_mask_} + 1;
  if (d < range / 2) {
    held_.push_back(std::move(v));
    release(out, false);
    return;
  }
  if (range - d <= late_window_) {
    ++counters_.samples_late;
    counters_.discarded_frames += parts;
    return;
  }
  release(out, true);
  ++counters_.resyncs;
  emit(v, true, out);
}

void ImuFrameDecoder::release(std::vector<DecodedSample>& out, bool all) {
  while (!held_.empty()) {
    auto head =
        std::min_element(held_.begin(), held_.end(), [&](const Verified& a, const Verified& b) {
          return fwd(a.sample.counter, last_counter_) < fwd(b.sample.counter, last_counter_);
        });
    const uint32_t dh = fwd(head->sample.counter, last_counter_);
    if (!all && dh > 1 && dh < hold_span_ && held_.size() <= kMaxHeld) {
      // A gap before it: hold it for the reorder window (the missing samples' frames may still come),
      // and while an incomplete sample between the last output and it may still complete.
      bool blocked = counters_.frames_in - head->completed_at < static_cast<uint64_t>(options_.reorder_window_frames);
      for (const Slot& s : slots_)
        if (s.live) {
          const uint32_t ds = (s.tie - last_counter_) & tie_mask_;
          if (ds > 0 && ds < dh) blocked = true;
        }
      if (blocked) return;
    }
    Verified v = std::move(*head);
    held_.erase(head);
    emit(v, false, out);
  }
}

void ImuFrameDecoder::emit(Verified& v, bool discontinuity, std::vector<DecodedSample>& out) {
  DecodedSample& s = v.sample;
  uint64_t index = 0;
  if (have_last_) {
    if (discontinuity) {
      // The counter says nothing about the time lost in a reset; the receive times do.
      const double gap = std::round(static_cast<double>(s.rx_time_ns - last_rx_ns_) * 1e-9 / dt_s_);
      index = last_index_ + static_cast<uint64_t>(std::max(1.0, std::isfinite(gap) ? gap : 1.0));
    } else {
      const uint32_t d = fwd(s.counter, last_counter_);
      counters_.samples_lost += static_cast<uint64_t>(d - 1);
      index = last_index_ + d;
    }
  }
  s.sample_index = index;
  s.discontinuity = discontinuity;
  s.increment.t_s = static_cast<double>(index + 1) * dt_s_;
  for (std::size_t p = 0; p < static_cast<size_t>(parts_); ++p) {
    if (v.arrival[p] < max_arrival_out_) ++counters_.out_of_order_frames;
    max_arrival_out_ = std::max(max_arrival_out_, v.arrival[p]);
  }
  counters_.frames_used += static_cast<uint64_t>(parts_);
  ++counters_.samples_decoded;
  Recent& r = recent_[v.tie & 0xFF];
  r.valid = true;
  r.decoded_no = counters_.samples_decoded;
  r.data = v.data;
  have_last_ = true;
  last_counter_ = s.counter;
  last_conditions_ = s.conditions;
  last_rx_ns_ = s.rx_time_ns;
  last_index_ = index;
  out.push_back(s);
}

void ImuFrameDecoder::flush(std::vector<DecodedSample>& out) {
  for (Slot& s : slots_)
    if (s.live) abandon(s);
  release(out, true);
}

}  // namespace imucal::drivers::imu
