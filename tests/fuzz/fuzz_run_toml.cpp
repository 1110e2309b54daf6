// run.toml of a run archive (db/archive/FORMAT.md), as every tool reading an archive parses it.
#include "db/archive/run_archive.hpp"
#include "tests/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return imucal::fuzz::refused_cleanly_or_ok([&] {
    (void)imucal::db::archive::parse_run_info(imucal::fuzz::text_of(data, size), "run.toml");
  });
}
