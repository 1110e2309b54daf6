// The archive's CSV reader (db/archive/csv.hpp) with imu.csv's columns (temperature optional)
// and table.csv's, as read_archive reads them.
#include "db/archive/csv.hpp"
#include "tests/fuzz/fuzz_support.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  using imucal::db::archive::CsvSpec;
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  static const CsvSpec imu{
      {"t_s", "dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad", "dv_x_mps", "dv_y_mps", "dv_z_mps"},
      {"temp_c"},
      true};
  static const CsvSpec table{{"t_s", "outer_deg", "inner_deg", "at_rest"}, {}, true};
  imucal::fuzz::refused_cleanly_or_ok(
      [&] { (void)imucal::db::archive::parse_csv(text, "imu.csv", imu); });
  return imucal::fuzz::refused_cleanly_or_ok(
      [&] { (void)imucal::db::archive::parse_csv(text, "table.csv", table); });
}
