// The raw recording reader of `imucal import` (db/archive/raw_recording.hpp): any text as one
// file with every channel, in the default column order and in a logger's own (a column ignored).
#include "db/archive/raw_recording.hpp"
#include "tests/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string text = imucal::fuzz::text_of(data, size);
  imucal::db::archive::RawImportOptions plain;
  imucal::fuzz::refused_cleanly_or_ok(
      [&] { (void)imucal::db::archive::parse_raw_recording(text, "rec.txt", plain); });
  imucal::db::archive::RawImportOptions logger;
  logger.columns = {"-", "t", "ax", "ay", "az", "gx", "gy", "gz"};
  logger.seconds_per_time_unit = 1e-3;
  logger.quantity = imucal::db::archive::RawQuantity::kIncrements;
  return imucal::fuzz::refused_cleanly_or_ok(
      [&] { (void)imucal::db::archive::parse_raw_recording(text, "log.csv", logger); });
}
