#include "station/run/capture.hpp"

#include <poll.h>

#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <stdexcept>

#include "calib/core/conventions.hpp"
#include "calib/core/readable_number.hpp"
#include "drivers/imu/imu_protocol.hpp"

namespace imucal::station::run {

namespace {

/// A number in a message a person reads, to `format`'s precision (issue #50 item 5: the shortest
/// round-trip form printed "0.30000000000000004 deg/s").
std::string rounded(const char* format, double v) {
  char buf[48];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

// IMU conditions that make the data unusable for a calibration.
constexpr uint8_t kFailureConditions =
    drivers::imu::condition::kFault | drivers::imu::condition::kSaturation;

/// "fault (IMU_STATUS.GyroFault), saturation (...)": the conditions and the protocol's signals.
std::string failure_names(const drivers::imu::ImuFrameDecoder& dec,
                          const drivers::imu::DecodedSample& s) {
  std::string out;
  auto add = [&](uint8_t c, const char* name) {
    if (!(s.conditions & c)) return;
    out += (out.empty() ? "" : ", ") + std::string(name) + " (" + dec.flag_names(s.flags, c) + ")";
  };
  add(drivers::imu::condition::kFault, "fault");
  add(drivers::imu::condition::kSaturation, "saturation");
  return out;
}

constexpr auto kRateWindow = std::chrono::seconds(2);
constexpr auto kRateStep = std::chrono::milliseconds(100);

}  // namespace

Capture::Capture(std::unique_ptr<drivers::imu::CanChannel> channel, CaptureOptions options)
    : channel_(std::move(channel)),
      options_(std::move(options)),
      decoder_(options_.decoder),
      dt_s_(1.0 / options_.decoder.sample_rate_hz) {
  if (!channel_) throw std::invalid_argument("Capture: no CAN channel");
  if (!(options_.rest_rate_threshold_dps > 0.0))
    throw std::invalid_argument("Capture: rest_rate_threshold_dps must be > 0");
  if (options_.stream_timeout.count() <= 0 || options_.flush_period.count() <= 0 ||
      options_.poll_timeout.count() <= 0)
    throw std::invalid_argument(
        "Capture: stream_timeout, flush_period and poll_timeout must be > 0");
}

Capture::~Capture() { stop(); }

void Capture::start() {
  if (running_) return;
  stop_.store(false);
  running_ = true;
  thread_ = std::thread([this] { run(); });
}

void Capture::stop() {
  if (!running_) return;
  stop_.store(true);
  if (thread_.joinable()) thread_.join();
  running_ = false;
  std::lock_guard<std::mutex> lk(mu_);
  cv_.notify_all();
}

void Capture::run() {
  std::vector<drivers::imu::ReceivedFrame> frames;
  frames.reserve(256);
  Clock::time_point last_flush = Clock::now();
  const int poll_ms = static_cast<int>(options_.poll_timeout.count());
  while (!stop_.load()) {
    bool eof = false;
    frames.clear();
    try {
      if (channel_->at_end()) {
        eof = true;  // peer gone / log replayed: nothing more can arrive; a hung-up fd polls hot
      } else {
        pollfd p{channel_->fd(), POLLIN, 0};
        const int rc = ::poll(&p, 1, poll_ms);
        if (rc < 0 && errno != EINTR)
          throw drivers::imu::CanChannelError(channel_->uri() +
                                              ": poll failed: " + std::strerror(errno));
        if (rc > 0) channel_->read(frames, 512);
      }
    } catch (const std::exception& e) {
      std::lock_guard<std::mutex> lk(mu_);
      if (writer_ && !fault_)
        set_fault(std::string("CAN channel error: ") + e.what(), /*station=*/true);
      eof = true;
    }
    if (eof) std::this_thread::sleep_for(options_.poll_timeout);

    const Clock::time_point now = Clock::now();
    std::lock_guard<std::mutex> lk(mu_);
    rx_overflow_ = channel_->counters().rx_overflow;
    if (!frames.empty()) on_frames(frames, now);

    if (writer_ && !fault_ && now - last_sample_time_ > options_.stream_timeout) {
      const auto ms =
          std::chrono::duration_cast<std::chrono::milliseconds>(now - last_sample_time_);
      set_fault("IMU stream timeout: no sample for " + std::to_string(ms.count()) + " ms after " +
                    (rows_ ? row_label(rows_ - 1) : std::string("attach (no row yet)")) +
                    (eof ? "; the CAN channel is closed" : ""),
                /*station=*/eof);
    }
    if (rate_window_.empty() || now - rate_window_.back().first >= kRateStep) {
      rate_window_.emplace_back(now, slots_seen_);
      while (rate_window_.size() > 2 && now - rate_window_.front().first > kRateWindow)
        rate_window_.pop_front();
    }
    if (now - last_flush >= options_.flush_period) {
      last_flush = now;
      if (writer_ && !writes_disabled_) {
        try {
          writer_->flush();
        } catch (const std::exception& e) {
          writer_failed(e);
        }
      }
    }
  }
}

void Capture::on_frames(const std::vector<drivers::imu::ReceivedFrame>& frames,
                        Clock::time_point now) {
  std::vector<drivers::imu::DecodedSample> samples;
  for (const drivers::imu::ReceivedFrame& f : frames) {
    ++frames_received_;
    if (writer_ && !writes_disabled_) {
      try {
        writer_->append_frame(f, channel_->interface_name());
        ++frames_logged_;
      } catch (const std::exception& e) {
        writer_failed(e);
      }
    }
    if (f.frame.is_error() && (f.frame.can_id & drivers::imu::kCanErrBusOff)) on_bus_off();
    samples.clear();
    decoder_.push(f, samples);
    dec_ = decoder_.counters();
    for (const drivers::imu::DecodedSample& s : samples) on_sample(s, now);
  }
}

void Capture::on_bus_off() {
  // The controller has left the bus: frames are lost until it restarts, so the run's stream has a
  // hole of unknown length. A fault with its own reason (not a later "no sample" or gap fault).
  if (!writer_ || writes_disabled_ || fault_) return;
  const uint64_t errors = dec_.error_frames - baseline_.frames_error;
  set_fault("CAN controller " + channel_->interface_name() + " went bus-off at " +
                row_label(rows_) + " (after " + std::to_string(errors) +
                " error frames in this run): the IMU stream has a hole; check the bus wiring and "
                "termination",
            /*station=*/true);
}

void Capture::on_sample(const drivers::imu::DecodedSample& s, Clock::time_point now) {
  ++samples_seen_;
  last_sample_time_ = now;
  if (have_prev_any_) {
    const uint64_t step = s.sample_index - prev_index_any_;
    slots_seen_ += step;
    if (!s.discontinuity && step > 1) max_gap_ = std::max<uint64_t>(max_gap_, step - 1);
  } else {
    slots_seen_ += 1;
  }
  have_prev_any_ = true;
  prev_index_any_ = s.sample_index;
  cv_.notify_all();  // wait_for_stream
  // The commanded move reaches the IMU stream: from here on still samples are after the move.
  if (motion_pending_ && is_moving(s.increment)) motion_pending_ = false;
  // Only samples the kernel received after the rest began count: a starved capture thread still
  // reads a backlog of samples from before and during the move, which prove nothing (seen under
  // ThreadSanitizer on a busy CPU as a false "the unit did not move with the table").
  if (motion_pending_ && phase_ != Phase::kMoving && s.rx_time_ns >= rest_begun_ns_)
    ++unseen_move_samples_;

  if (!writer_ || writes_disabled_ || fault_) return;
  if (s.conditions & kFailureConditions) {
    set_fault("IMU reports " + failure_names(decoder_, s) + " at " + row_label(rows_));
    return;
  }
  if (!have_prev_row_) {
    have_prev_row_ = true;
    prev_row_index_ = s.sample_index;
    prev_row_inc_ = s.increment;
    emit_row(s.increment);
    return;
  }
  if (s.discontinuity) {
    set_fault((dec_.imu_resets > baseline_.imu_resets
                   ? std::string("IMU reset (sample counter restarted with the start-up flag)")
                   : std::string("IMU sample counter jumped (resync)")) +
              " after " + row_label(rows_ - 1));
    return;
  }
  const uint64_t gap = s.sample_index - prev_row_index_ - 1;
  if (gap > options_.max_gap_samples) {
    set_fault(std::to_string(gap) + " consecutive IMU samples lost after " + row_label(rows_ - 1) +
              " (more than max_gap_samples = " + std::to_string(options_.max_gap_samples) + ")");
    return;
  }
  // Linear interpolation across the lost slots between the two decoded neighbours.
  const calib::core::ImuIncrement a = prev_row_inc_;
  for (uint64_t j = 1; j <= gap; ++j) {
    const double w = static_cast<double>(j) / static_cast<double>(gap + 1);
    calib::core::ImuIncrement fill;
    fill.dtheta_rad = a.dtheta_rad + (s.increment.dtheta_rad - a.dtheta_rad) * w;
    fill.dv_mps = a.dv_mps + (s.increment.dv_mps - a.dv_mps) * w;
    if (!emit_row(fill)) return;
    ++samples_filled_;
  }
  prev_row_index_ = s.sample_index;
  prev_row_inc_ = s.increment;
  emit_row(s.increment);
}

bool Capture::is_moving(const calib::core::ImuIncrement& in) const {
  return !(rate_dps(in) <= options_.rest_rate_threshold_dps);
}

double Capture::rate_dps(const calib::core::ImuIncrement& in) const {
  return in.dtheta_rad.norm() / dt_s_ * kRadToDeg;
}

bool Capture::emit_row(const calib::core::ImuIncrement& in) {
  const uint64_t row = rows_;
  const double rate_dps = this->rate_dps(in);
  const bool moving = is_moving(in);
  bool at_rest = false;
  switch (phase_) {
    case Phase::kIdle:
    case Phase::kMoving:
    case Phase::kRestDone:
      break;
    case Phase::kSettling:
      still_run_ = (moving || motion_pending_) ? 0 : still_run_ + 1;
      if (!motion_pending_ && still_run_ >= options_.settle_guard_samples) {
        // This row completes the guard; the counted rest starts with the next one.
        phase_ = rest_left_ > 0 ? Phase::kResting : Phase::kRestDone;
        if (phase_ == Phase::kRestDone) {
          rest_done_ = true;
          cv_.notify_all();
        }
      }
      break;
    case Phase::kResting:
      if (moving) {
        set_fault("unit moved during a rest: |rate| = " + rounded("%.3g", rate_dps) + " deg/s > " +
                  rounded("%.3g", options_.rest_rate_threshold_dps) + " deg/s at " +
                  row_label(row) + ", rest sample " + std::to_string(rest_done_rows_ + 1) + " of " +
                  std::to_string(rest_done_rows_ + rest_left_) + " at outer " +
                  rounded("%.3f", outer_deg_) + " deg, inner " + rounded("%.3f", inner_deg_) +
                  " deg");
        return false;
      }
      at_rest = true;
      break;
  }
  calib::core::ImuIncrement inc = in;
  inc.t_s =
      static_cast<double>(row + 1) / options_.decoder.sample_rate_hz;  // contract: (row+1)/rate
  inc.dt_s = dt_s_;
  const calib::core::TableSample table{inc.t_s, outer_deg_ * kDegToRad, inner_deg_ * kDegToRad,
                                       at_rest};
  try {
    writer_->append_row(inc, table);
  } catch (const std::exception& e) {
    writer_failed(e);
    return false;
  }
  ++rows_;
  if (at_rest) {
    ++rest_rows_;
    ++rest_done_rows_;
    if (--rest_left_ == 0) {
      phase_ = Phase::kRestDone;
      rest_done_ = true;
      cv_.notify_all();
    }
  }
  return true;
}

void Capture::set_fault(std::string reason, bool station) {
  if (fault_) return;
  fault_ = std::move(reason);
  fault_is_station_ = station;
  cv_.notify_all();
}

void Capture::writer_failed(const std::exception& e) {
  writes_disabled_ = true;
  set_fault(std::string("run archive write failed: ") + e.what(), /*station=*/true);
}

std::string Capture::row_label(uint64_t row) const {
  return "row " + std::to_string(row + 1) + " (" +
         calib::core::instant_text(static_cast<double>(row + 1) / options_.decoder.sample_rate_hz) +
         ")";
}

uint64_t Capture::unseen_move_samples() const {
  std::lock_guard<std::mutex> lk(mu_);
  return motion_pending_ ? unseen_move_samples_ : 0;
}

bool Capture::wait_for_stream(std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lk(mu_);
  const uint64_t seen = samples_seen_;
  return cv_.wait_for(lk, timeout, [&] { return samples_seen_ > seen; });
}

void Capture::attach(ArchiveWriter* writer) {
  std::lock_guard<std::mutex> lk(mu_);
  writer_ = writer;
  writes_disabled_ = false;
  fault_.reset();
  end_counters_.reset();
  baseline_ = raw_counters();
  rows_ = 0;
  max_gap_ = 0;
  have_prev_row_ = false;
  last_sample_time_ = Clock::now();
  rest_done_rows_ = 0;
}

void Capture::detach() {
  std::lock_guard<std::mutex> lk(mu_);
  if (writer_ && !writes_disabled_) {
    try {
      writer_->flush();
    } catch (const std::exception& e) {
      writer_failed(e);
    }
  }
  if (writer_) end_counters_ = raw_counters();
  writer_ = nullptr;
}

void Capture::table_moving(double outer_deg, double inner_deg) {
  std::lock_guard<std::mutex> lk(mu_);
  outer_deg_ = outer_deg;
  inner_deg_ = inner_deg;
  phase_ = Phase::kMoving;
  rest_done_ = false;
}

void Capture::move_commanded() {
  std::lock_guard<std::mutex> lk(mu_);
  motion_pending_ = true;
}

void Capture::begin_rest(double outer_deg, double inner_deg, uint64_t rest_samples) {
  std::lock_guard<std::mutex> lk(mu_);
  outer_deg_ = outer_deg;
  inner_deg_ = inner_deg;
  phase_ = Phase::kSettling;
  still_run_ = 0;
  rest_left_ = rest_samples;
  rest_done_rows_ = 0;
  rest_done_ = false;
  ++rest_generation_;
  unseen_move_samples_ = 0;
  rest_begun_ns_ = drivers::imu::receive_clock_now_ns();
  if (options_.settle_guard_samples == 0 && !motion_pending_) {
    phase_ = rest_samples > 0 ? Phase::kResting : Phase::kRestDone;
    rest_done_ = rest_samples == 0;
  }
}

bool Capture::wait_rest_done(std::chrono::milliseconds timeout) {
  std::unique_lock<std::mutex> lk(mu_);
  const uint64_t gen = rest_generation_;
  cv_.wait_for(lk, timeout, [&] {
    return rest_done_ || fault_.has_value() || gen != rest_generation_ || stop_.load();
  });
  return rest_done_ && gen == rest_generation_ && !fault_;
}

CaptureStats Capture::raw_counters() const {
  CaptureStats s;
  s.frames_received = frames_received_;
  s.frames_logged = frames_logged_;
  set_decoder_counters(s, dec_);
  s.rx_overflow = rx_overflow_;
  s.samples_filled = samples_filled_;
  s.max_gap_samples = max_gap_;
  s.rows_written = rows_;
  s.rest_samples = rest_rows_;
  return s;
}

CaptureStats Capture::stats() const {
  std::lock_guard<std::mutex> lk(mu_);
  CaptureStats s = end_counters_ ? *end_counters_ : raw_counters();
  const CaptureStats& b = baseline_;
  s.frames_received -= b.frames_received;
  s.frames_logged -= b.frames_logged;
  s.frames_foreign -= b.frames_foreign;
  s.frames_error -= b.frames_error;
  s.frames_malformed -= b.frames_malformed;
  s.frames_duplicate -= b.frames_duplicate;
  s.frames_out_of_order -= b.frames_out_of_order;
  s.frames_discarded -= b.frames_discarded;
  s.rx_overflow -= b.rx_overflow;
  s.samples_decoded -= b.samples_decoded;
  s.samples_lost -= b.samples_lost;
  s.samples_corrupt -= b.samples_corrupt;
  s.samples_incomplete -= b.samples_incomplete;
  s.samples_late -= b.samples_late;
  s.samples_filled -= b.samples_filled;
  s.imu_resets -= b.imu_resets;
  s.rest_samples -= b.rest_samples;
  // max_gap_samples: the longest gap since attach (reset there); rows_written: since attach.
  return s;
}

std::optional<std::string> Capture::fault() const {
  std::lock_guard<std::mutex> lk(mu_);
  return fault_;
}

bool Capture::fault_is_station() const {
  std::lock_guard<std::mutex> lk(mu_);
  return fault_ && fault_is_station_;
}

double Capture::sample_rate_observed_hz() const {
  std::lock_guard<std::mutex> lk(mu_);
  if (rate_window_.size() < 2) return 0.0;
  const double dt =
      std::chrono::duration<double>(rate_window_.back().first - rate_window_.front().first).count();
  if (!(dt > 0.0)) return 0.0;
  return static_cast<double>(rate_window_.back().second - rate_window_.front().second) / dt;
}

uint64_t Capture::rows() const {
  std::lock_guard<std::mutex> lk(mu_);
  return rows_;
}

uint64_t Capture::rest_rows_done() const {
  std::lock_guard<std::mutex> lk(mu_);
  return rest_done_rows_;
}

}  // namespace imucal::station::run
