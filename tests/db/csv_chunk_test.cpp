// The two-thread CSV reader (db/archive/csv.hpp parse_csv_rows): whatever line the text is split
// at, the rows are those of a parse from the top, bit for bit, and an error is the one a parse from
// the top meets first, with its line. Also the file reader without zero-fill (io_util.hpp
// read_file_bytes) and run_concurrently's error order.
#include <gtest/gtest.h>
#include <stdlib.h>
#include <sys/stat.h>
#include <unistd.h>

#include <charconv>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <random>
#include <regex>
#include <set>
#include <stdexcept>
#include <thread>

#include "db/archive/archive_error.hpp"
#include "db/archive/csv.hpp"
#include "db/archive/io_util.hpp"
#include "tests/support/temp_dir.hpp"

namespace imucal::db::archive {
namespace {

namespace fs = std::filesystem;

const CsvSpec kImuSpec{
    {"t_s", "dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad", "dv_x_mps", "dv_y_mps", "dv_z_mps"},
    {"temp_c"},
    true};

// What a sink received: the header, the row count, the values, and how often and on which thread
// each row arrived.
struct Collected {
  std::vector<std::string> columns;
  size_t num_rows = 0;
  std::vector<double> values;
  std::vector<int> calls;
  std::vector<std::thread::id> threads;
};

class CollectingSink final : public CsvRowSink {
 public:
  explicit CollectingSink(Collected& c) : c_(c) {}
  void begin(const std::vector<std::string>& columns, size_t num_rows) override {
    c_.columns = columns;
    c_.num_rows = num_rows;
    c_.values.assign(num_rows * columns.size(), 0.0);
    c_.calls.assign(num_rows, 0);
    c_.threads.assign(num_rows, std::thread::id());
  }
  void row(size_t row, const double* values) override {
    const size_t n = c_.columns.size();
    std::copy(values, values + n, c_.values.begin() + static_cast<long>(row * n));
    ++c_.calls[row];
    c_.threads[row] = std::this_thread::get_id();
  }

 private:
  Collected& c_;
};

// One chunk, on the calling thread: the reference.
const CsvChunking kWhole{std::numeric_limits<size_t>::max(), CsvChunking::kMiddle};
// Always two chunks (when the text has a line end at or after `offset` with data behind it).
CsvChunking split_at(size_t offset) { return CsvChunking{0, offset}; }

Collected parse_with(const std::string& text, const CsvChunking& chunking,
                     const CsvSpec& spec = kImuSpec) {
  Collected c;
  CollectingSink sink(c);
  parse_csv_rows(text, "dir/imu.csv", spec, sink, chunking);
  return c;
}

// The error's what() (file, line, column, message), or "" when the text parses.
std::string error_with(const std::string& text, const CsvChunking& chunking,
                       const CsvSpec& spec = kImuSpec) {
  try {
    parse_with(text, chunking, spec);
  } catch (const ArchiveError& e) {
    return e.what();
  }
  return "";
}

// The same through a file, read block by block (read_csv_rows).
Collected read_with(const std::string& path, const CsvChunking& chunking,
                    const CsvSpec& spec = kImuSpec) {
  Collected c;
  CollectingSink sink(c);
  read_csv_rows(path, spec, sink, chunking);
  return c;
}

std::string read_error_with(const std::string& path, const CsvChunking& chunking,
                            const CsvSpec& spec = kImuSpec) {
  try {
    read_with(path, chunking, spec);
  } catch (const ArchiveError& e) {
    return e.what();
  }
  return "";
}

// Tiny buffers: lines longer than a block, blocks ending anywhere in a line.
CsvChunking file_split_at(size_t offset, size_t block_bytes) {
  return CsvChunking{0, offset, block_bytes};
}

bool same_bits_csv_chunk(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0;
}

size_t data_bytes(const std::string& text) { return text.size() - (text.find('\n') + 1); }

std::string shortest(double v) {
  char buf[32];
  return std::string(buf, std::to_chars(buf, buf + sizeof buf, v).ptr);
}

// An imu.csv text of `rows` random rows (every kind of number the writer produces), with the
// given line ending and with or without the last newline.
std::string imu_text(size_t rows, bool temp, const char* eol, bool last_newline,
                     unsigned seed = 1) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> mant(-1.0, 1.0);
  std::uniform_int_distribution<int> exp10(-12, 3);
  std::string s = "t_s,dtheta_x_rad,dtheta_y_rad,dtheta_z_rad,dv_x_mps,dv_y_mps,dv_z_mps";
  s += temp ? ",temp_c" : "";
  s += eol;
  for (size_t k = 0; k < rows; ++k) {
    s += shortest(0.01 * static_cast<double>(k + 1));
    for (int c = 0; c < (temp ? 7 : 6); ++c)
      s += "," + shortest(c == 2 ? 0.0 : mant(rng) * std::pow(10.0, exp10(rng)));
    if (k + 1 < rows || last_newline) s += eol;
  }
  return s;
}

TEST(CsvChunks, SameRowsWhereverTheTextIsSplit) {
  for (const size_t rows : {1u, 2u, 3u, 7u, 20u})
    for (const char* eol : {"\n", "\r\n"})
      for (const bool last_newline : {true, false})
        for (const bool temp : {false, true}) {
          const std::string text = imu_text(rows, temp, eol, last_newline, 7 + rows);
          const Collected whole = parse_with(text, kWhole);
          ASSERT_EQ(whole.num_rows, rows);
          for (size_t at = 0; at <= data_bytes(text) + 1; ++at) {
            SCOPED_TRACE(::testing::Message()
                         << rows << " rows, eol " << (eol[0] == '\r' ? "CRLF" : "LF")
                         << ", last newline " << last_newline << ", split at " << at);
            const Collected split = parse_with(text, split_at(at));
            ASSERT_EQ(split.num_rows, whole.num_rows);
            ASSERT_EQ(split.columns, whole.columns);
            ASSERT_TRUE(same_bits_csv_chunk(split.values, whole.values));
            ASSERT_EQ(split.calls, std::vector<int>(rows, 1));  // every row once
          }
        }
}

TEST(CsvChunks, HeaderOnlyAndEmptyDataGiveNoRows) {
  for (const std::string text : {"t_s,a\n", "t_s,a", "t_s,a\r\n"})
    for (const size_t at : {0u, 1u, 5u}) {
      const Collected c = parse_with(text, split_at(at), CsvSpec{{"t_s", "a"}, {}, true});
      EXPECT_EQ(c.num_rows, 0u) << text;
    }
}

TEST(CsvChunks, LargeTextIsParsedOnTwoThreadsWithTheSameResult) {
  const std::string text = imu_text(20000, true, "\n", true, 3);
  ASSERT_GT(data_bytes(text), CsvChunking{}.min_parallel_bytes);
  const Collected whole = parse_with(text, kWhole);
  const Collected two = parse_with(text, CsvChunking{});
  EXPECT_TRUE(same_bits_csv_chunk(two.values, whole.values));
  EXPECT_EQ(two.calls, std::vector<int>(20000, 1));
  const std::set<std::thread::id> ids(two.threads.begin(), two.threads.end());
  EXPECT_EQ(ids.size(), 2u) << "the default chunking should use two threads for " << text.size()
                            << " bytes";
  EXPECT_EQ(two.threads.front(), std::this_thread::get_id());  // first chunk: the caller
  // parse_csv (CsvTable) goes the same way.
  const CsvTable t = parse_csv(text, "dir/imu.csv", kImuSpec);
  EXPECT_EQ(t.num_rows, 20000u);
  EXPECT_TRUE(same_bits_csv_chunk(t.values, whole.values));
}

// Replaces the text of data row `row` (0-based) with `line`.
std::string with_row(std::string text, size_t row, const std::string& line) {
  size_t start = text.find('\n') + 1;
  for (size_t k = 0; k < row; ++k) start = text.find('\n', start) + 1;
  const size_t end = text.find('\n', start);
  return text.replace(start, (end == std::string::npos ? text.size() : end) - start, line);
}

// Every split offset must give the error a parse from the top gives.
void expect_same_error_everywhere(const std::string& text, const std::string& what) {
  const std::string whole = error_with(text, kWhole);
  ASSERT_NE(whole, "") << what << ": the text should not parse";
  for (size_t at = 0; at <= data_bytes(text); ++at)
    ASSERT_EQ(error_with(text, split_at(at)), whole) << what << ", split at " << at;
}

TEST(CsvChunks, EarliestErrorWinsWithItsLine) {
  const std::string good = imu_text(30, false, "\n", true, 5);
  // A bad cell in each half: the first one is reported wherever the split falls.
  const std::string two_bad =
      with_row(with_row(good, 3, "0.04,1,2x,3,4,5,6"), 25, "0.26,1,2,3,4,nan,6");
  expect_same_error_everywhere(two_bad, "two bad cells");
  try {
    parse_with(two_bad, split_at(data_bytes(good) / 2));
    ADD_FAILURE() << "no error";
  } catch (const ArchiveError& e) {
    EXPECT_EQ(e.line(), 5u);  // data row 3
    EXPECT_EQ(e.field(), "dtheta_y_rad");
    EXPECT_EQ(e.message(), "not a number: '2x'");
  }
  // Only the late one: its own line.
  const std::string late = with_row(good, 25, "0.26,1,2,3,4,nan,6");
  expect_same_error_everywhere(late, "one late bad cell");
  EXPECT_NE(error_with(late, split_at(10)).find("dir/imu.csv:27: column 'dv_y_mps'"),
            std::string::npos);
}

TEST(CsvChunks, EveryKindOfErrorIsTheSameWhereverTheSplitFalls) {
  const std::string good = imu_text(12, true, "\r\n", true, 9);
  const std::string lf = imu_text(12, false, "\n", true, 11);
  expect_same_error_everywhere(with_row(lf, 6, "0.05,1,2,3,4,5,6"), "time going back");
  expect_same_error_everywhere(with_row(lf, 6, "0.06,1,2,3,4,5,6"), "time repeated");
  expect_same_error_everywhere(with_row(lf, 9, "0.01,1,2,3,4,5,6"), "time far back");
  expect_same_error_everywhere(with_row(lf, 6, "0.07x,1,2,3,4,5,6"), "bad time cell");
  expect_same_error_everywhere(with_row(lf, 6, ""), "blank line");
  expect_same_error_everywhere(with_row(lf, 6, "0.07,1,2,3,4,5"), "too few columns");
  expect_same_error_everywhere(with_row(lf, 6, "0.07,1,2,3,4,5,6,7"), "too many columns");
  expect_same_error_everywhere(with_row(lf, 6, "0.07,1,,3,4,5,6"), "empty field");
  expect_same_error_everywhere(with_row(lf, 6, "0.07,1,2\r3,4,5,6"), "lone CR");
  expect_same_error_everywhere(with_row(lf, 6, "0.05,1,2,x,4,5,6"), "time error before a bad cell");
  expect_same_error_everywhere(with_row(lf, 6, "0.07,1,2,3,4,5,1e999"), "out of range");
  expect_same_error_everywhere(lf.substr(0, lf.rfind(',')), "truncated last line");
  expect_same_error_everywhere(with_row(good, 11, "0.12,1,2,3"), "short CRLF last line");
  expect_same_error_everywhere(
      with_row(with_row(lf, 2, "0.03,1,2,3,4,5,6,7"), 9, "0.01,1,2,3,4,5,6"),
      "too many columns before a time error");
  // Time that only goes back across a boundary with the check off: no error, same rows.
  const CsvSpec no_time{kImuSpec.columns, {}, false};
  const std::string back = with_row(lf, 6, "0.001,1,2,3,4,5,6");
  const Collected whole = parse_with(back, kWhole, no_time);
  for (size_t at = 0; at <= data_bytes(back); ++at)
    ASSERT_TRUE(same_bits_csv_chunk(parse_with(back, split_at(at), no_time).values, whole.values)) << at;
}

void write_file(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary | std::ios::trunc) << text;
}

TEST(CsvChunks, FileReadBlockByBlockGivesTheSameRows) {
  test_support::ScopedTempDir dir("imucal_csv_chunk_test");
  const std::string path = dir.sub("imu.csv");
  for (const std::string& text :
       {imu_text(12, true, "\r\n", false, 21), imu_text(12, false, "\n", true, 22),
        imu_text(1, false, "\n", false, 23), imu_text(2, true, "\r\n", true, 24)}) {
    write_file(path, text);
    const Collected whole = parse_with(text, kWhole);
    for (const size_t block : {1u, 3u, 16u, 64u, 100000u})
      for (size_t at = 0; at <= data_bytes(text) + 1; at += block == 16 ? 1 : 7) {
        SCOPED_TRACE(::testing::Message()
                     << whole.num_rows << " rows, block " << block << ", split at " << at);
        const Collected c = read_with(path, file_split_at(at, block));
        ASSERT_EQ(c.num_rows, whole.num_rows);
        ASSERT_EQ(c.columns, whole.columns);
        ASSERT_TRUE(same_bits_csv_chunk(c.values, whole.values));
        ASSERT_EQ(c.calls, std::vector<int>(whole.num_rows, 1));
      }
    // The defaults: one block, one thread for a small file.
    EXPECT_TRUE(same_bits_csv_chunk(read_with(path, CsvChunking{}).values, whole.values));
  }
}

TEST(CsvChunks, FileReadBlockByBlockGivesTheSameErrors) {
  test_support::ScopedTempDir dir("imucal_csv_chunk_test");
  const std::string path = dir.sub("imu.csv");
  const std::string lf = imu_text(12, false, "\n", true, 31);
  for (const std::string& text :
       {with_row(with_row(lf, 3, "0.04,1,2x,3,4,5,6"), 9, "0.1,1,2,3,4,nan,6"),
        with_row(lf, 6, "0.05,1,2,x,4,5,6"), with_row(lf, 6, ""), lf.substr(0, lf.rfind(',')),
        with_row(lf, 6, "0.07,1,2,3,4,5,6,7"), std::string("t_s,a\n1,2\n"),
        std::string("\xEF\xBB\xBFt_s,dtheta_x_rad\n1,2\n"), std::string("t_s,dtheta_x_rad")}) {
    write_file(path, text);
    const std::string whole = error_with(text, kWhole);
    ASSERT_NE(whole, "") << text;
    for (const size_t block : {1u, 16u, 4096u})
      for (size_t at = 0; at <= data_bytes(text); at += block == 16 ? 1 : 5)
        ASSERT_EQ(read_error_with(path, file_split_at(at, block)),
                  std::regex_replace(whole, std::regex("^dir/imu.csv"), path))
            << "block " << block << ", split at " << at;
  }
  // Empty: read whole (no size to split), the parser's message.
  write_file(path, "");
  EXPECT_NE(read_error_with(path, CsvChunking{}).find("imu.csv:1: empty file"), std::string::npos);
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const ArchiveError& e) {
    return e.what();
  }
  return "";
}

TEST(FileBytes, SameBytesAndErrorsAsReadTextFile) {
  test_support::ScopedTempDir dir("imucal_csv_chunk_test");
  const std::string text = imu_text(3000, true, "\n", false, 2);
  for (const auto& [name, content] :
       {std::pair<std::string, std::string>{"a.csv", text}, {"empty.csv", ""}, {"one.csv", "x"}}) {
    std::ofstream(dir.sub(name), std::ios::binary) << content;
    const FileBytes b = read_file_bytes(dir.sub(name));
    EXPECT_EQ(b.view(), content) << name;
    EXPECT_EQ(b.view(), read_text_file(dir.sub(name))) << name;
  }
  // A file that reports no size: read until EOF.
  EXPECT_EQ(read_file_bytes("/proc/self/status").view().substr(0, 5), "Name:");
  for (const std::string& bad : {dir.sub("missing.csv"), dir.sub("")}) {
    const std::string e = error_of([&] { read_file_bytes(bad); });
    EXPECT_NE(e, "") << bad;
    EXPECT_EQ(e, error_of([&] { read_text_file(bad); }));
  }
}

TEST(FileBytes, ReadAtNamesAFileThatShrankWhileOpen) {
  test_support::ScopedTempDir dir("imucal_csv_chunk_test");
  const std::string path = dir.sub("imu.csv");
  std::ofstream(path, std::ios::binary) << "0123456789";
  const ReadableFile file(path);
  ASSERT_TRUE(file.has_size());
  char buf[4];
  file.read_at(6, buf, 4);
  EXPECT_EQ(std::string(buf, 4), "6789");
  fs::resize_file(path, 8);
  const std::string e = error_of([&] { file.read_at(6, buf, 4); });
  EXPECT_EQ(e, path + ": read error: the file shrank while it was being read");
}

TEST(FileBytes, PipeLongerThanOneBufferIsReadWhole) {
  test_support::ScopedTempDir dir("imucal_csv_chunk_test");
  const std::string fifo = dir.sub("pipe");
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string text = imu_text(5000, true, "\n", true, 4);  // several 64 kB pipe buffers
  std::thread writer([&] { std::ofstream(fifo, std::ios::binary) << text; });
  const FileBytes b = read_file_bytes(fifo);
  writer.join();
  EXPECT_EQ(b.view(), text);
  // And the CSV reader on it.
  std::thread writer2([&] { std::ofstream(fifo, std::ios::binary) << text; });
  const CsvTable t = read_csv(fifo, kImuSpec);
  writer2.join();
  EXPECT_EQ(t.num_rows, 5000u);
}

TEST(RunConcurrently, RunsBothAndReportsTheFirstFunctionsErrorFirst) {
  int a = 0, b = 0;
  run_concurrently([&] { a = 1; }, [&] { b = 2; });
  EXPECT_EQ(a + b, 3);
  auto fail = [](const char* m) { return [m] { throw std::runtime_error(m); }; };
  auto what = [](const std::function<void()>& f) {
    try {
      f();
    } catch (const std::runtime_error& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(what([&] { run_concurrently(fail("first"), fail("second")); }), "first");
  EXPECT_EQ(what([&] { run_concurrently([] {}, fail("second")); }), "second");
  EXPECT_EQ(what([&] { run_concurrently(fail("first"), [] {}); }), "first");
  // The other function still ran to its end.
  b = 0;
  EXPECT_EQ(what([&] { run_concurrently(fail("first"), [&] { b = 5; }); }), "first");
  EXPECT_EQ(b, 5);
}

}  // namespace
}  // namespace imucal::db::archive
