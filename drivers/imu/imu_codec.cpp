#include "drivers/imu/imu_codec.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace imucal::imu {
namespace {

CanFrame make_frame(uint32_t id, const std::array<uint8_t, 8>& data) {
  CanFrame f;
  f.can_id = id;
  f.len = 8;
  f.data = data;
  return f;
}

uint16_t fwd16(uint16_t to, uint16_t from) { return static_cast<uint16_t>(to - from); }

}  // namespace

// ----------------------------------------------------------------------------------------- encoder

ImuFrameEncoder::ImuFrameEncoder(uint32_t base_id, bool carry_remainder)
    : base_id_(base_id), carry_remainder_(carry_remainder) {
  if (base_id > kCanSffMask - (kFramesPerSample - 1))
    throw std::invalid_argument("ImuFrameEncoder: base_id 0x" + std::to_string(base_id) +
                                " leaves no room for 4 standard 11-bit identifiers");
}

void ImuFrameEncoder::restart() {
  counter_ = 0;
  startup_left_ = kStartupSamples;
  carry_dtheta_rad_ = {};
  carry_dv_mps_ = {};
}

int32_t ImuFrameEncoder::quantise(double x, double lsb, int64_t min_count, int64_t max_count,
                                  double& carry, bool& clipped) {
  const double total = x + (carry_remainder_ ? carry : 0.0);
  const double q = std::round(total / lsb);
  if (q > static_cast<double>(max_count) || q < static_cast<double>(min_count)) {
    // Clipped: the remainder would be meaningless (and grow without bound), so it is dropped.
    clipped = true;
    carry = 0.0;
    return static_cast<int32_t>(q > 0 ? max_count : min_count);
  }
  carry = total - q * lsb;
  return static_cast<int32_t>(q);
}

std::array<CanFrame, kFramesPerSample> ImuFrameEncoder::encode(const calib::ImuIncrement& inc,
                                                               uint16_t status_flags) {
  for (int i = 0; i < 3; ++i)
    if (!std::isfinite(inc.dtheta_rad(i)) || !std::isfinite(inc.dv_mps(i)))
      throw std::invalid_argument("ImuFrameEncoder: non-finite increment component " + std::to_string(i) +
                                  " at t_s=" + std::to_string(inc.t_s));
  bool gyro_clip = false, accel_clip = false;
  std::array<std::array<uint8_t, 8>, kFramesPerSample> data{};
  const uint8_t lo = static_cast<uint8_t>(counter_ & 0xFF);
  for (int i = 0; i < 3; ++i) {
    AxisFields a;
    a.counter_lo = lo;
    a.dtheta_count = quantise(inc.dtheta_rad(i), kDthetaLsb_rad, kDthetaMinCount, kDthetaMaxCount,
                              carry_dtheta_rad_[static_cast<std::size_t>(i)], gyro_clip);
    a.dv_count = quantise(inc.dv_mps(i), kDvLsb_mps, kDvMinCount, kDvMaxCount,
                          carry_dv_mps_[static_cast<std::size_t>(i)], accel_clip);
    data[static_cast<std::size_t>(i)] = pack_axis(a);
  }
  StatusFields s;
  s.counter = counter_;
  s.status = status_flags;
  if (gyro_clip) s.status |= status::kGyroSaturated;
  if (accel_clip) s.status |= status::kAccelSaturated;
  if (startup_left_ > 0) {
    s.status |= status::kStartup;
    --startup_left_;
  }
  if (std::isfinite(inc.temp_c)) {
    const double t = std::clamp(std::round(inc.temp_c / kTemperatureLsb_degc), -32767.0, 32767.0);
    s.temperature_count = static_cast<int16_t>(t);
  } else {
    s.temperature_count = kTemperatureUnknown;
    s.status |= status::kTempInvalid;
  }
  data[3] = pack_status(s);  // CRC field still 0; bytes 0-5 are final
  s.crc = sample_crc(data[0], data[1], data[2], data[3]);
  data[3] = pack_status(s);
  ++counter_;
  std::array<CanFrame, kFramesPerSample> frames;
  for (std::size_t p = 0; p < frames.size(); ++p)
    frames[p] = make_frame(base_id_ + static_cast<uint32_t>(p), data[p]);
  return frames;
}

// ----------------------------------------------------------------------------------------- decoder

ImuFrameDecoder::ImuFrameDecoder(const DecoderOptions& options) : options_(options) {
  if (!(options.sample_rate_hz > 0.0) || !std::isfinite(options.sample_rate_hz))
    throw std::invalid_argument("ImuFrameDecoder: sample_rate_hz must be positive, got " +
                                std::to_string(options.sample_rate_hz));
  if (options.reorder_window_frames < 1)
    throw std::invalid_argument("ImuFrameDecoder: reorder_window_frames must be >= 1");
  if (options.base_id > kCanSffMask - (kFramesPerSample - 1))
    throw std::invalid_argument("ImuFrameDecoder: base_id leaves no room for 4 standard identifiers");
  dt_s_ = 1.0 / options.sample_rate_hz;
  held_.reserve(kMaxHeld + 1);
}

bool ImuFrameDecoder::is_recent_duplicate(int part, const std::array<uint8_t, 8>& data) const {
  const Recent& r = recent_[data[0]];
  if (r.valid && counters_.samples_decoded - r.decoded_no < kRecentSamples &&
      r.data[static_cast<std::size_t>(part)] == data)
    return true;
  for (const Verified& v : held_)
    if (v.data[static_cast<std::size_t>(part)] == data) return true;
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
    const uint32_t id = f.id();
    if (f.is_extended() || id < options_.base_id || id >= options_.base_id + kFramesPerSample) {
      ++counters_.foreign_frames;
      return;
    }
    if (f.is_remote() || f.len != 8) {
      ++counters_.malformed_frames;
      return;
    }
    const int part = static_cast<int>(id - options_.base_id);
    const auto p = static_cast<std::size_t>(part);
    const uint8_t lo = f.data[0];
    Slot* slot = nullptr;
    for (Slot& s : slots_)
      if (s.live && s.counter_lo == lo) slot = &s;
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
      slot->counter_lo = lo;
      slot->created_arrival = arrival;
    }
    slot->cand[p][static_cast<std::size_t>(slot->n[p]++)] = Candidate{f.data, arrival, rf.rx_time_ns};
    if (slot->n[0] > 0 && slot->n[1] > 0 && slot->n[2] > 0 && slot->n[3] > 0) complete(*slot, out);
  }();
  // Give up samples that have waited too long for missing frames (or a CRC-consistent candidate).
  for (Slot& s : slots_)
    if (s.live && arrival - s.created_arrival >= static_cast<uint64_t>(options_.reorder_window_frames))
      abandon(s);
  release(out, false);
}

void ImuFrameDecoder::abandon(Slot& slot) {
  const bool all_parts = slot.n[0] > 0 && slot.n[1] > 0 && slot.n[2] > 0 && slot.n[3] > 0;
  if (all_parts)
    ++counters_.samples_corrupt;  // every frame arrived but no combination passed the CRC
  else
    ++counters_.samples_incomplete;
  counters_.discarded_frames += static_cast<uint64_t>(slot.total());
  slot.live = false;
}

void ImuFrameDecoder::complete(Slot& slot, std::vector<DecodedSample>& out) {
  // A frame whose counter byte was corrupted can land in this slot as a second candidate for one
  // part; the CRC picks the consistent combination (at most 2^4 tries).
  for (int i0 = 0; i0 < slot.n[0]; ++i0)
    for (int i1 = 0; i1 < slot.n[1]; ++i1)
      for (int i2 = 0; i2 < slot.n[2]; ++i2)
        for (int i3 = 0; i3 < slot.n[3]; ++i3) {
          const std::array<const Candidate*, 4> c{&slot.cand[0][static_cast<std::size_t>(i0)],
                                                  &slot.cand[1][static_cast<std::size_t>(i1)],
                                                  &slot.cand[2][static_cast<std::size_t>(i2)],
                                                  &slot.cand[3][static_cast<std::size_t>(i3)]};
          const StatusFields st = unpack_status(c[3]->data);
          if (st.crc != sample_crc(c[0]->data, c[1]->data, c[2]->data, c[3]->data)) continue;
          Verified v;
          v.completed_at = counters_.frames_in;
          for (std::size_t p = 0; p < 4; ++p) {
            v.data[p] = c[p]->data;
            v.arrival[p] = c[p]->arrival;
          }
          DecodedSample& d = v.sample;
          d.counter = st.counter;
          d.status = st.status;
          d.rx_time_ns = c[3]->rx_time_ns;
          for (int a = 0; a < 3; ++a) {
            const AxisFields ax = unpack_axis(c[static_cast<std::size_t>(a)]->data);
            d.increment.dtheta_rad(a) = static_cast<double>(ax.dtheta_count) * kDthetaLsb_rad;
            d.increment.dv_mps(a) = static_cast<double>(ax.dv_count) * kDvLsb_mps;
          }
          d.increment.dt_s = dt_s_;
          d.increment.temp_c = (st.temperature_count == kTemperatureUnknown || (st.status & status::kTempInvalid))
                                   ? std::numeric_limits<double>::quiet_NaN()
                                   : static_cast<double>(st.temperature_count) * kTemperatureLsb_degc;
          counters_.discarded_frames += static_cast<uint64_t>(slot.total() - 4);
          slot.live = false;
          accept(std::move(v), out);
          return;
        }
  // No consistent combination yet: keep the slot; a later candidate may complete it, otherwise it
  // expires as corrupt.
}

void ImuFrameDecoder::accept(Verified&& v, std::vector<DecodedSample>& out) {
  const uint16_t c = v.sample.counter;
  for (const Verified& h : held_)
    if (h.sample.counter == c) {
      counters_.duplicate_frames += kFramesPerSample;
      return;
    }
  if (!have_last_) {
    emit(v, false, out);
    return;
  }
  const uint16_t d = fwd16(c, last_counter_);
  const bool startup = (v.sample.status & status::kStartup) != 0;
  if (startup && (!(last_status_ & status::kStartup) || d == 0 || d > 64)) {
    // The counter restarted with the startup flag: the IMU was reset. Output what is held first.
    release(out, true);
    ++counters_.imu_resets;
    emit(v, true, out);
    return;
  }
  if (d == 0) {
    counters_.duplicate_frames += kFramesPerSample;
    return;
  }
  if (d < 0x8000) {
    held_.push_back(std::move(v));
    release(out, false);
    return;
  }
  if (0x10000U - d <= kLateWindow) {
    ++counters_.samples_late;
    counters_.discarded_frames += kFramesPerSample;
    return;
  }
  release(out, true);
  ++counters_.resyncs;
  emit(v, true, out);
}

void ImuFrameDecoder::release(std::vector<DecodedSample>& out, bool all) {
  while (!held_.empty()) {
    auto head = std::min_element(held_.begin(), held_.end(), [&](const Verified& a, const Verified& b) {
      return fwd16(a.sample.counter, last_counter_) < fwd16(b.sample.counter, last_counter_);
    });
    const uint16_t dh = fwd16(head->sample.counter, last_counter_);
    if (!all && dh > 1 && dh < 256 && held_.size() <= kMaxHeld) {
      // A gap before it: hold it for the reorder window (the missing samples' frames may still come),
      // and while an incomplete sample between the last output and it may still complete.
      bool blocked = counters_.frames_in - head->completed_at < static_cast<uint64_t>(options_.reorder_window_frames);
      for (const Slot& s : slots_)
        if (s.live) {
          const uint8_t ds = static_cast<uint8_t>(s.counter_lo - static_cast<uint8_t>(last_counter_));
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
      const uint16_t d = fwd16(s.counter, last_counter_);
      counters_.samples_lost += static_cast<uint64_t>(d - 1);
      index = last_index_ + d;
    }
  }
  s.sample_index = index;
  s.discontinuity = discontinuity;
  s.increment.t_s = static_cast<double>(index + 1) * dt_s_;
  for (std::size_t p = 0; p < 4; ++p) {
    if (v.arrival[p] < max_arrival_out_) ++counters_.out_of_order_frames;
    max_arrival_out_ = std::max(max_arrival_out_, v.arrival[p]);
  }
  counters_.frames_used += kFramesPerSample;
  ++counters_.samples_decoded;
  Recent& r = recent_[static_cast<uint8_t>(s.counter & 0xFF)];
  r.valid = true;
  r.decoded_no = counters_.samples_decoded;
  r.data = v.data;
  have_last_ = true;
  last_counter_ = s.counter;
  last_status_ = s.status;
  last_rx_ns_ = s.rx_time_ns;
  last_index_ = index;
  out.push_back(s);
}

void ImuFrameDecoder::flush(std::vector<DecodedSample>& out) {
  for (Slot& s : slots_)
    if (s.live) abandon(s);
  release(out, true);
}

}  // namespace imucal::imu
