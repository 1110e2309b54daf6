// stationd's configuration file (station/config/stationd.example.toml), as --check-config reads it.
#include "station/config/config.hpp"
#include "tests/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return imucal::fuzz::refused_cleanly_or_ok([&] {
    (void)imucal::station::config::parse_config(imucal::fuzz::text_of(data, size), "fuzz.toml",
                                                "/tmp");
  });
}
