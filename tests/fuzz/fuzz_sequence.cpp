// Sequence files (sequences/FORMAT.md): parse, validate against the station's limits, and — when
// valid and short — generate the motion profile, as `imucal simulate` and stationd do.
#include "sequences/parser.hpp"
#include "sequences/profile_generator.hpp"
#include "sequences/validator.hpp"
#include "tests/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace imucal::sequences;
  return imucal::fuzz::refused_cleanly_or_ok([&] {
    const Sequence seq = parse_sequence_string(imucal::fuzz::text_of(data, size), "fuzz.toml");
    if (!validate(seq, TableLimits{}).empty()) return;
    const MotionProfile p = generate_profile(seq);
    (void)p.duration_s();
  });
}
