// Strict numeric CSV reader/writer (db/archive/csv.hpp): bit-exact round trip and one test per
// class of bad input, each checking that the error names the file, the line and the column.
#include "db/archive/csv.hpp"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <random>

#include "db/archive/archive_error.hpp"
#include "tests/support/temp_dir.hpp"

namespace imucal::db::archive {
namespace {

namespace fs = std::filesystem;

const CsvSpec kImuSpecCsv{
    {"t_s", "dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad", "dv_x_mps", "dv_y_mps", "dv_z_mps"},
    {"temp_c"},
    true};
const std::string kHeader =
    "t_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps\n";

// Expect parse_csv to fail; returns the error for further checks.
ArchiveError parse_error(const std::string& text, const CsvSpec& spec = kImuSpecCsv) {
  try {
    parse_csv(text, "dir/imu.csv", spec);
  } catch (const ArchiveError& e) {
    return e;
  }
  ADD_FAILURE() << "no ArchiveError for:\n" << text;
  return ArchiveError("none", "none");
}

bool same_bits_csv(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }

TEST(Csv, WriteReadRoundTripIsBitExact) {
  test_support::ScopedTempDir dir("imucal_csv_test");
  const std::string path = dir.sub("imu.csv");
  std::mt19937_64 rng(42);
  std::uniform_real_distribution<double> mant(-1.0, 1.0);
  std::uniform_int_distribution<int> expo(-320, 300);
  std::vector<std::vector<double>> rows;
  double t = 0.0;
  for (int k = 0; k < 2000; ++k) {
    t += 0.01 * (1.0 + 0.3 * std::fabs(mant(rng)));  // irregular, non-representable time steps
    std::vector<double> r{t};
    for (int c = 0; c < 7; ++c) r.push_back(std::ldexp(mant(rng), expo(rng)));
    rows.push_back(r);
  }
  // Special values that a sloppy formatter loses: -0, subnormal, max, min normal, 1/3.
  rows[5][1] = -0.0;
  rows[6][2] = std::numeric_limits<double>::denorm_min();
  rows[7][3] = std::numeric_limits<double>::max();
  rows[8][4] = std::numeric_limits<double>::min();
  rows[9][5] = 1.0 / 3.0;
  {
    CsvWriter w(path, {"t_s", "dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad", "dv_x_mps",
                       "dv_y_mps", "dv_z_mps", "temp_c"});
    for (const auto& r : rows) w.write_row(r.data(), r.size());
    w.close();
  }
  const CsvTable tab = read_csv(path, kImuSpecCsv);
  ASSERT_EQ(tab.num_rows, rows.size());
  ASSERT_EQ(tab.num_cols(), 8u);
  EXPECT_EQ(tab.columns.back(), "temp_c");
  for (size_t k = 0; k < rows.size(); ++k)
    for (size_t c = 0; c < 8; ++c)
      ASSERT_TRUE(same_bits_csv(tab.at(k, c), rows[k][c])) << "row " << k << " col " << c;
}

TEST(Csv, AcceptsValidVariants) {
  // Optional trailing column absent, CRLF line endings, last line complete without newline.
  const CsvTable a =
      parse_csv(kHeader + "0.01,1,2,3,4,5,6\r\n0.02,1e-9,-2.5,.5,4,5,6", "x.csv", kImuSpecCsv);
  ASSERT_EQ(a.num_rows, 2u);
  EXPECT_EQ(a.num_cols(), 7u);
  EXPECT_EQ(a.at(1, 1), 1e-9);
  EXPECT_EQ(a.at(1, 3), 0.5);
  EXPECT_EQ(a.at(1, 6), 6.0);
  // Header only: zero rows is a valid CSV (the archive decides whether that is acceptable).
  EXPECT_EQ(parse_csv(kHeader, "x.csv", kImuSpecCsv).num_rows, 0u);
  EXPECT_EQ(CsvTable::line_of_row(0), 2u);
}

TEST(Csv, MissingColumnNamesColumnAndLine1) {
  const ArchiveError e =
      parse_error("t_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps\n0.01,1,2,3,4,5\n");
  EXPECT_EQ(e.file(), "dir/imu.csv");
  EXPECT_EQ(e.line(), 1u);
  EXPECT_EQ(e.field(), "dv_z_mps");
  EXPECT_NE(std::string(e.what()).find("dir/imu.csv:1:"), std::string::npos) << e.what();
  EXPECT_NE(std::string(e.what()).find("missing column"), std::string::npos) << e.what();
  // Misspelt column in the middle.
  const ArchiveError e2 =
      parse_error("t_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dvx_mps,dv_y_mps,dv_z_mps\n");
  EXPECT_EQ(e2.line(), 1u);
  EXPECT_EQ(e2.field(), "dv_x_mps");
}

TEST(Csv, ExtraOrReorderedColumnRejected) {
  const ArchiveError e = parse_error(
      "t_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps,pressure_pa\n");
  EXPECT_EQ(e.line(), 1u);
  EXPECT_EQ(e.field(), "pressure_pa");
  EXPECT_NE(std::string(e.what()).find("extra column"), std::string::npos) << e.what();
  const ArchiveError e2 =
      parse_error("t_s,dtheta_y_rad,dtheta_x_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps\n");
  EXPECT_EQ(e2.line(), 1u);
  EXPECT_EQ(e2.field(), "dtheta_y_rad");
}

TEST(Csv, NanAndInfRejectedWithLineAndColumn) {
  for (const char* bad : {"nan", "NaN", "inf", "-inf", "Infinity"}) {
    const ArchiveError e = parse_error(kHeader + "0.01,1,2,3,4,5,6\n0.02,1,2,3," + bad + ",5,6\n");
    EXPECT_EQ(e.line(), 3u) << bad;
    EXPECT_EQ(e.field(), "dv_x_mps") << bad;
    EXPECT_NE(std::string(e.what()).find("NaN or Inf"), std::string::npos) << e.what();
  }
}

TEST(Csv, MalformedNumbersRejected) {
  struct Case {
    const char* cell;
    const char* expect;
  };
  for (const Case c :
       {Case{"1.2x", "not a number"}, Case{"", "empty field"}, Case{" 1.0", "not a number"},
        Case{"1.0 ", "not a number"}, Case{"+1", "not a number"}, Case{"0x10", "not a number"},
        Case{"abc", "not a number"}, Case{"1e400", "out of double range"}}) {
    const ArchiveError e = parse_error(kHeader + "0.01,1,2," + c.cell + ",4,5,6\n");
    EXPECT_EQ(e.line(), 2u) << c.cell;
    EXPECT_EQ(e.field(), "dtheta_z_rad") << c.cell;
    EXPECT_NE(std::string(e.what()).find(c.expect), std::string::npos) << e.what();
  }
}

TEST(Csv, NonMonotonicTimeRejected) {
  const ArchiveError eq =
      parse_error(kHeader + "0.01,1,2,3,4,5,6\n0.02,1,2,3,4,5,6\n0.02,1,2,3,4,5,6\n");
  EXPECT_EQ(eq.line(), 4u);
  EXPECT_EQ(eq.field(), "t_s");
  EXPECT_NE(std::string(eq.what()).find("strictly increasing"), std::string::npos) << eq.what();
  const ArchiveError back = parse_error(kHeader + "0.01,1,2,3,4,5,6\n0.005,1,2,3,4,5,6\n");
  EXPECT_EQ(back.line(), 3u);
  // Without the time rule the same data is fine.
  CsvSpec no_time = kImuSpecCsv;
  no_time.increasing_first_column = false;
  EXPECT_EQ(parse_csv(kHeader + "0.01,1,2,3,4,5,6\n0.005,1,2,3,4,5,6\n", "x", no_time).num_rows,
            2u);
}

TEST(Csv, TruncatedLastLineReported) {
  const ArchiveError e = parse_error(kHeader + "0.01,1,2,3,4,5,6\n0.02,1,2,3,4");
  EXPECT_EQ(e.line(), 3u);
  EXPECT_NE(std::string(e.what()).find("truncated last line"), std::string::npos) << e.what();
  EXPECT_NE(std::string(e.what()).find("5 of 7"), std::string::npos) << e.what();
  // Cut right after a comma.
  const ArchiveError e2 = parse_error(kHeader + "0.01,1,2,3,");
  EXPECT_EQ(e2.line(), 2u);
  EXPECT_NE(std::string(e2.what()).find("truncated last line"), std::string::npos) << e2.what();
}

TEST(Csv, WrongColumnCountInARow) {
  const ArchiveError few =
      parse_error(kHeader + "0.01,1,2,3,4,5,6\n0.02,1,2,3,4\n0.03,1,2,3,4,5,6\n");
  EXPECT_EQ(few.line(), 3u);
  EXPECT_NE(std::string(few.what()).find("expected 7 columns, found 5"), std::string::npos)
      << few.what();
  const ArchiveError many = parse_error(kHeader + "0.01,1,2,3,4,5,6,7,8\n");
  EXPECT_EQ(many.line(), 2u);
  EXPECT_NE(std::string(many.what()).find("expected 7 columns, found 9"), std::string::npos)
      << many.what();
  // A row with temp_c while the header has none is an extra column, too.
  const ArchiveError temp = parse_error(kHeader + "0.01,1,2,3,4,5,6,25.0\n");
  EXPECT_EQ(temp.line(), 2u);
}

TEST(Csv, BlankLineEmptyFileAndBomRejected) {
  const ArchiveError blank = parse_error(kHeader + "0.01,1,2,3,4,5,6\n\n0.02,1,2,3,4,5,6\n");
  EXPECT_EQ(blank.line(), 3u);
  EXPECT_NE(std::string(blank.what()).find("blank line"), std::string::npos) << blank.what();
  const ArchiveError empty = parse_error("");
  EXPECT_EQ(empty.line(), 1u);
  EXPECT_NE(std::string(empty.what()).find("empty file"), std::string::npos);
  const ArchiveError bom = parse_error("\xEF\xBB\xBF" + kHeader);
  EXPECT_EQ(bom.line(), 1u);
  EXPECT_NE(std::string(bom.what()).find("byte-order mark"), std::string::npos);
}

TEST(Csv, MissingFileNamesPath) {
  try {
    read_csv("/nonexistent/dir/imu.csv", kImuSpecCsv);
    FAIL() << "no error";
  } catch (const ArchiveError& e) {
    EXPECT_EQ(e.file(), "/nonexistent/dir/imu.csv");
    EXPECT_NE(std::string(e.what()).find("cannot open"), std::string::npos);
  }
}

TEST(Csv, WriterRefusesWhatTheReaderWouldReject) {
  test_support::ScopedTempDir dir("imucal_csv_test");
  CsvWriter w(dir.sub("t.csv"), {"t_s", "x"});
  w.write_row({0.0, 1.0});
  try {
    w.write_row({0.1, std::nan("")});
    FAIL() << "NaN written";
  } catch (const ArchiveError& e) {
    EXPECT_EQ(e.line(), 3u);
    EXPECT_EQ(e.field(), "x");
  }
  EXPECT_THROW(w.write_row({0.1, std::numeric_limits<double>::infinity()}), ArchiveError);
  EXPECT_THROW(w.write_row({0.0, 1.0}), ArchiveError);  // time not increasing
  EXPECT_THROW(w.write_row({0.2}), ArchiveError);       // wrong count
  w.write_row({0.2, 2.0});
  w.close();
  const CsvTable t = read_csv(dir.sub("t.csv"), CsvSpec{{"t_s", "x"}, {}, true});
  ASSERT_EQ(t.num_rows, 2u);
  EXPECT_EQ(t.at(1, 1), 2.0);
}

}  // namespace
}  // namespace imucal::db::archive
