// One control-socket request line (station/control/control_protocol.hpp), as the daemon's control
// server parses it from any local user; and the name/reason rule on arbitrary text.
#include "station/control/control_protocol.hpp"
#include "tests/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace imucal::station;
  using namespace imucal::station::control;
  const std::string text = imucal::fuzz::text_of(data, size);
  (void)text_field_error(text, kMaxReasonChars);
  return imucal::fuzz::refused_cleanly_or_ok([&] {
    const Request r = parse_request(text);
    // What the server echoes back must serialise (invalid UTF-8 is replaced, never thrown).
    (void)reply_line(ok_reply(r.id, r.args));
  });
}
