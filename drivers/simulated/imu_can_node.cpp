#include "drivers/simulated/imu_can_node.hpp"

#include <time.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <stdexcept>
#include <string>

namespace imucal::drivers::simulated {
namespace {

void check_probability(double p, const char* name) {
  if (!(p >= 0.0 && p <= 1.0))
    throw std::invalid_argument(std::string("ImuCanNode: ") + name + " must be in [0, 1], got " +
                                std::to_string(p));
}

}  // namespace

ImuCanNode::ImuCanNode(drivers::imu::CanChannel& channel, const ImuCanNodeOptions& options)
    : channel_(channel),
      options_(options),
      encoder_(options.protocol, options.base_id),
      rng_(options.seed) {
  check_probability(options.frame_loss_probability, "frame_loss_probability");
  check_probability(options.corruption_probability, "corruption_probability");
  if (!(options.rate_hz > 0.0) || !std::isfinite(options.rate_hz))
    throw std::invalid_argument("ImuCanNode: rate_hz must be positive");
  if (!(options.speed_factor >= 0.0) || !std::isfinite(options.speed_factor))
    throw std::invalid_argument("ImuCanNode: speed_factor must be >= 0 (0 = unpaced)");
  if (options.reset_lost_samples < 0)
    throw std::invalid_argument("ImuCanNode: reset_lost_samples must be >= 0");
  std::sort(options_.reset_at_s.begin(), options_.reset_at_s.end());
}

int64_t ImuCanNode::monotonic_ns() {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<int64_t>(ts.tv_sec) * 1000000000 + ts.tv_nsec;
}

void ImuCanNode::pace(std::size_t k, int64_t start_ns) const {
  if (options_.speed_factor <= 0.0) return;
  const int64_t due =
      start_ns + static_cast<int64_t>(std::llround(static_cast<double>(k) * 1e9 /
                                                   (options_.rate_hz * options_.speed_factor)));
  timespec ts{};
  ts.tv_sec = static_cast<time_t>(due / 1000000000);
  ts.tv_nsec = static_cast<long>(due % 1000000000);
  while (::clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, nullptr) == EINTR) {
  }
}

SampleFate ImuCanNode::send(const calib::core::ImuIncrement& inc, uint16_t status_flags) {
  ++stats_.increments_in;
  SampleFate fate;
  while (next_scheduled_reset_ < options_.reset_at_s.size() &&
         inc.t_s >= options_.reset_at_s[next_scheduled_reset_]) {
    reset_requested_.store(true);
    ++next_scheduled_reset_;
  }
  if (reset_requested_.exchange(false)) {
    ++stats_.resets;
    swallow_left_ = options_.reset_lost_samples;
    encoder_.restart();  // the counter restarts at 0 after the boot, with the startup flag
  }
  if (swallow_left_ > 0) {
    --swallow_left_;
    ++stats_.increments_lost_in_reset;
    return fate;
  }
  fate.transmitted = true;
  fate.counter = encoder_.next_counter();
  fate.clean = encoder_.encode(inc, status_flags);
  std::vector<drivers::imu::CanFrame> out(fate.clean.size());
  std::size_t n = 0;
  for (const drivers::imu::CanFrame& f : fate.clean) {
    if (options_.frame_loss_probability > 0.0 && uniform_(rng_) < options_.frame_loss_probability) {
      ++fate.frames_lost;
      continue;
    }
    drivers::imu::CanFrame g = f;
    if (options_.corruption_probability > 0.0 && uniform_(rng_) < options_.corruption_probability) {
      const auto bit = static_cast<unsigned>(rng_() % (8U * g.len));
      g.data[bit / 8] = static_cast<uint8_t>(g.data[bit / 8] ^ (1U << (bit % 8)));
      ++fate.frames_corrupted;
    }
    out[n++] = g;
  }
  const std::size_t sent = channel_.write(out.data(), n);
  fate.frames_refused = static_cast<int>(n - sent);
  stats_.frames_sent += sent;
  stats_.frames_lost += static_cast<uint64_t>(fate.frames_lost);
  stats_.frames_corrupted += static_cast<uint64_t>(fate.frames_corrupted);
  stats_.frames_refused += static_cast<uint64_t>(fate.frames_refused);
  ++stats_.samples_transmitted;
  if (!fate.intact()) ++stats_.samples_faulted;
  return fate;
}

}  // namespace imucal::drivers::simulated
