// Unit files (db/archive/units/*.toml) and truth.json, as `imucal simulate --unit` reads them.
#include "db/archive/unit_file.hpp"
#include "tests/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text = imucal::fuzz::text_of(data, size);
  imucal::fuzz::refused_cleanly_or_ok(
      [&] { (void)imucal::db::archive::parse_unit_file(text, "unit.toml"); });
  return imucal::fuzz::refused_cleanly_or_ok(
      [&] { (void)imucal::db::archive::parse_truth_json(text, "truth.json"); });
}
