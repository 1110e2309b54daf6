#pragma once
// Strict numeric CSV, the table format of the run archive (ARCHITECTURE §5, db/archive/FORMAT.md).
//
// Reader rules (each violation is an ArchiveError naming file, 1-based line — header = line 1 —
// and, for a cell, the column):
//  * a header row with exactly the expected column names in order, optionally followed by a prefix
//    of the caller's optional trailing columns (e.g. temp_c); nothing else;
//  * every data row has the header's column count; lines end in "\n" (a "\r\n" ending is accepted);
//    no blank lines; the last line may lack its newline only if it is complete, otherwise it is
//    reported as truncated;
//  * every cell is a decimal number consumed completely by std::from_chars (no whitespace, no "+",
//    no "1.2x", no empty cells); NaN and Inf are rejected; out-of-range values are rejected;
//  * optionally the first column (time) is strictly increasing.
// Large texts are parsed in two chunks, split at a line end, on two threads; the rows, the error
// and its line are those of a parse from the top (the first error in file order wins). Files are
// read a block at a time, never whole.
// Writer: shortest round-trip decimal (std::to_chars), so write-then-read is bit-exact.
#include <cstddef>
#include <initializer_list>
#include <string>
#include <string_view>
#include <vector>

#include "db/archive/io_util.hpp"

namespace imucal::db::archive {

struct CsvSpec {
  std::vector<std::string> columns;  ///< required, in this order
  std::vector<std::string>
      optional_columns;                 ///< may follow the required ones, as a prefix, in order
  bool increasing_first_column = true;  ///< first column is time: strictly increasing
};

struct CsvTable {
  std::string file;                  ///< origin used in error messages
  std::vector<std::string> columns;  ///< the header actually present
  std::size_t num_rows = 0;
  std::vector<double> values;  ///< row-major, num_rows * columns.size()

  std::size_t num_cols() const { return columns.size(); }
  double at(std::size_t row, std::size_t col) const { return values[row * columns.size() + col]; }
  /// File line of data row `row` (0-based): the header is line 1 and blank lines are not allowed.
  static std::size_t line_of_row(std::size_t row) { return row + 2; }
};

/// Parse CSV text; `origin` names the source in errors (usually the path).
CsvTable parse_csv(std::string_view text, const std::string& origin, const CsvSpec& spec);
/// Read and parse a CSV file.
CsvTable read_csv(const std::string& path, const CsvSpec& spec);

/// Takes the data rows of a CSV text straight into the caller's storage (a 35 MB imu.csv would
/// otherwise exist three times: text, CsvTable, the caller's rows).
class CsvRowSink {
 public:
  virtual ~CsvRowSink() = default;
  /// Called once before any row: the header present and the number of data rows (exact for a text
  /// that parses; row indices never reach it either way).
  virtual void begin(const std::vector<std::string>& columns, std::size_t num_rows) = 0;
  /// Data row `row` (0-based; file line CsvTable::line_of_row(row)) with columns.size() values.
  /// Two threads call it at once for different rows (each row at most once), so it may only write
  /// the storage of its own row, and it must not throw: report bad values after the parse, in row
  /// order, as a parse followed by a check over the rows would.
  virtual void row(std::size_t row, const double* values) = 0;
};

/// How parse_csv_rows and read_csv_rows split the data rows between their two threads.
struct CsvChunking {
  static constexpr std::size_t kMiddle = static_cast<std::size_t>(-1);
  /// Less data than this (bytes after the header) is parsed on the calling thread alone: starting
  /// a thread costs about as much as parsing 20 kB.
  std::size_t min_parallel_bytes = 256 * 1024;
  /// The second chunk starts after the first '\n' at or after this offset into the data (tests
  /// move the boundary through the text); kMiddle: half the data.
  std::size_t split_at = kMiddle;
  /// read_csv_rows() reads a file through one buffer of this size per thread (grown for a longer
  /// line) rather than whole: no 35 MB text next to the rows, no page faults for it.
  std::size_t block_bytes = 256 * 1024;
};

/// parse_csv() into a sink: the same rules, the same errors.
void parse_csv_rows(std::string_view text, const std::string& origin, const CsvSpec& spec,
                    CsvRowSink& sink, const CsvChunking& chunking = {});
/// read_csv() into a sink, a block at a time. A file that shrinks or changes while it is read is
/// an ArchiveError (as a read error, or "changed while it was being read").
void read_csv_rows(const std::string& path, const CsvSpec& spec, CsvRowSink& sink,
                   const CsvChunking& chunking = {});

/// Streaming CSV writer with the same rules as the reader: it refuses NaN/Inf and (if requested)
/// non-increasing time, so it never writes a file the reader would reject. close() makes the file
/// durable (fsync); a writer destroyed without close() leaves an incomplete file for the caller to
/// remove.
class CsvWriter {
 public:
  CsvWriter(const std::string& path, std::vector<std::string> columns,
            bool increasing_first_column = true);
  void write_row(const double* values, std::size_t n);
  void write_row(std::initializer_list<double> values) { write_row(values.begin(), values.size()); }
  void close();
  std::size_t rows_written() const { return rows_; }

 private:
  DurableFile file_;
  std::vector<std::string> columns_;
  bool increasing_;
  std::size_t rows_ = 0;
  double last_t_ = 0.0;
};

}  // namespace imucal::db::archive
