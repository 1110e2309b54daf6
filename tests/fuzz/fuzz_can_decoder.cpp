// The IMU's CAN frame decoder (drivers/imu/PROTOCOL.md) on an arbitrary frame stream: 13 bytes
// per frame (identifier with flags, length, 8 data bytes), then the end-of-stream flush. It must
// never crash, and everything it outputs must come in counter order (its documented contract).
#include <cstring>
#include <vector>

#include "drivers/imu/imu_codec.hpp"
#include "tests/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace imucal::drivers::imu;
  return imucal::fuzz::refused_cleanly_or_ok([&] {
    ImuFrameDecoder dec;
    std::vector<DecodedSample> out;
    int64_t t_ns = 0;
    for (size_t at = 0; at + 13 <= size; at += 13) {
      ReceivedFrame f;
      std::memcpy(&f.frame.can_id, data + at, 4);
      f.frame.len = static_cast<uint8_t>(data[at + 4] % 9);
      std::memcpy(f.frame.data.data(), data + at + 5, 8);
      for (size_t i = f.frame.len; i < 8; ++i) f.frame.data[i] = 0;
      t_ns += 1000000;
      f.rx_time_ns = t_ns;
      dec.push(f, out);
    }
    dec.flush(out);
    for (size_t i = 1; i < out.size(); ++i)
      if (out[i].sample_index < out[i - 1].sample_index && !out[i].discontinuity)
        __builtin_trap();  // out of counter order without a declared discontinuity
  });
}
