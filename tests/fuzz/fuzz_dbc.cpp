// DBC files (drivers/imu/dbc_database.hpp): refused with std::invalid_argument or read; a database
// that reads keeps every signal inside its message, so decoding a frame of its length touches
// only its bytes, and inserting a value then extracting it gives the value back.
#include "drivers/imu/dbc_codec.hpp"
#include "drivers/imu/dbc_database.hpp"
#include "tests/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using namespace imucal::drivers::imu;
  return imucal::fuzz::refused_cleanly_or_ok([&] {
    const DbcDatabase db = parse_dbc(imucal::fuzz::text_of(data, size), "fuzz.dbc");
    for (const DbcMessage& m : db.messages) {
      std::vector<uint8_t> frame(static_cast<size_t>(m.length), 0xA5);
      for (const DbcSignal& s : m.signals) {
        const uint64_t mask = s.length == 64 ? ~uint64_t{0} : (uint64_t{1} << s.length) - 1;
        const uint64_t v = 0x5A5A5A5A5A5A5A5AULL & mask;
        dbc_insert_raw(s, v, frame.data(), frame.size());
        if (dbc_extract_raw(s, frame.data(), frame.size()) != v) __builtin_trap();
        (void)dbc_physical(s, v);
      }
    }
  });
}
