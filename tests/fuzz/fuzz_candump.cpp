// candump log lines (capture.log, `candump -l`), as the archive's capture log and the candump:
// CAN channel read them; a line that parses must format back to a line that parses the same.
#include "drivers/imu/candump_log.hpp"
#include "tests/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace imucal::drivers::imu;
  const std::string text = imucal::fuzz::text_of(data, size);
  size_t start = 0;
  while (start <= text.size()) {
    const size_t nl = std::min(text.find('\n', start), text.size());
    const std::string_view line(text.data() + start, nl - start);
    imucal::fuzz::refused_cleanly_or_ok([&] {
      const CandumpRecord r = parse_candump_line(line);
      const CandumpRecord back = parse_candump_line(format_candump_line(r.frame, r.interface));
      if (back.frame.frame != r.frame.frame || back.interface != r.interface) __builtin_trap();
    });
    start = nl + 1;
  }
  return 0;
}
