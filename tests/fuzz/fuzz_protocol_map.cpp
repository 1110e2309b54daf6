// IMU protocol files (drivers/imu/imu_protocol_map.hpp; issue #27) with their DBC: the input is
// the protocol file's text, a line "#@dbc", then the DBC's text. Refused with std::invalid_argument
// or read; a protocol the station can carry then encodes samples (imu_codec.hpp's encoder) and its
// stream decoder reads them back, in counter order, without a crash. A mapping may legitimately
// name one signal for two roles, so the values themselves are not compared here (the unit tests
// do that for sound protocols).
#include <cstring>
#include <vector>

#include "drivers/imu/imu_codec.hpp"
#include "drivers/imu/imu_protocol_map.hpp"
#include "tests/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace imucal::drivers::imu;
  return imucal::fuzz::refused_cleanly_or_ok([&] {
    const std::string text = imucal::fuzz::text_of(data, size);
    const size_t cut = text.find("\n#@dbc\n");
    const std::string dbc = cut == std::string::npos ? std::string() : text.substr(cut + 7);
    const auto map = std::make_shared<const ImuProtocolMap>(
        parse_protocol_map(text.substr(0, cut), "fuzz.toml", &dbc));
    if (!station_unsupported(*map).empty()) return;
    ImuFrameEncoder enc(map, std::nullopt);
    DecoderOptions o;
    o.protocol = map;
    ImuFrameDecoder dec(o);
    std::vector<DecodedSample> out;
    imucal::calib::core::ImuIncrement inc;
    inc.dt_s = 0.01;
    inc.temp_c = 21.5;
    for (int k = 0; k < 40; ++k) {
      inc.dtheta_rad = Eigen::Vector3d(1e-4 * k, -2e-5, 3e-6 * (k % 7));
      inc.dv_mps = Eigen::Vector3d(-0.098, 1e-3 * (k % 3), 0.0);
      for (const CanFrame& f : enc.encode(inc, k == 9 ? 0x1 : 0)) dec.push({f, 1000000LL * k}, out);
    }
    dec.flush(out);
    for (size_t i = 1; i < out.size(); ++i)
      if (out[i].sample_index < out[i - 1].sample_index && !out[i].discontinuity) __builtin_trap();
  });
}
