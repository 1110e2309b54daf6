#include "db/archive/csv.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <exception>
#include <optional>
#include <system_error>

#include "db/archive/archive_error.hpp"

namespace imucal::db::archive {

namespace {

std::string join(const std::vector<std::string>& v) {
  std::string s;
  for (size_t i = 0; i < v.size(); ++i) {
    if (i) s += ',';
    s += v[i];
  }
  return s;
}

std::string expected_header(const CsvSpec& spec) {
  std::string s = join(spec.columns);
  if (!spec.optional_columns.empty()) s += "[," + join(spec.optional_columns) + "]";
  return s;
}

bool is_newline_at(const char* p, const char* end) {
  return p < end && (*p == '\n' || (*p == '\r' && p + 1 < end && p[1] == '\n'));
}

// The raw text of the cell starting at p (up to the next ',' or line end), for messages.
std::string cell_text(const char* p, const char* end) {
  const char* q = p;
  while (q < end && *q != ',' && *q != '\n' && *q != '\r') ++q;
  std::string s(p, q);
  if (s.size() > 40) s = s.substr(0, 40) + "...";
  return s;
}

// Number of comma-separated fields on the line starting at p.
size_t count_fields(const char* p, const char* end) {
  size_t n = 1;
  while (p < end && *p != '\n') {
    if (*p == ',') ++n;
    ++p;
  }
  return n;
}

std::vector<std::string> split_header(std::string_view line) {
  std::vector<std::string> out;
  size_t start = 0;
  for (;;) {
    const size_t comma = line.find(',', start);
    if (comma == std::string_view::npos) {
      out.emplace_back(line.substr(start));
      return out;
    }
    out.emplace_back(line.substr(start, comma - start));
    start = comma + 1;
  }
}

void check_header(const std::vector<std::string>& hdr, const CsvSpec& spec,
                  const std::string& origin) {
  const std::string expect = " (expected header: " + expected_header(spec) + ")";
  for (size_t i = 0; i < spec.columns.size(); ++i) {
    const std::string& want = spec.columns[i];
    if (i >= hdr.size())
      throw ArchiveError::column_error(origin, 1, want, "missing column" + expect);
    if (hdr[i] == want) continue;
    const bool want_later =
        std::find(hdr.begin() + static_cast<long>(i), hdr.end(), want) != hdr.end();
    if (!want_later)
      throw ArchiveError::column_error(origin, 1, want,
                                       "missing column (found '" + hdr[i] + "' in position " +
                                           std::to_string(i + 1) + ")" + expect);
    throw ArchiveError::column_error(origin, 1, hdr[i],
                                     "unexpected column in position " + std::to_string(i + 1) +
                                         ", expected '" + want + "'" + expect);
  }
  for (size_t j = spec.columns.size(); j < hdr.size(); ++j) {
    const size_t k = j - spec.columns.size();
    if (k < spec.optional_columns.size() && hdr[j] == spec.optional_columns[k]) continue;
    throw ArchiveError::column_error(origin, 1, hdr[j], "extra column" + expect);
  }
}

}  // namespace

namespace {

// The header line: checked against the spec; returns where the data rows start.
const char* parse_header(std::string_view text, const std::string& origin, const CsvSpec& spec,
                         std::vector<std::string>& columns) {
  const std::string expect = "expected header: " + expected_header(spec);
  if (text.empty()) throw ArchiveError(origin, 1, "empty file, " + expect);
  if (text.size() >= 3 && text.substr(0, 3) == "\xEF\xBB\xBF")
    throw ArchiveError(origin, 1, "file starts with a UTF-8 byte-order mark; save it without BOM");
  const char* const begin = text.data();
  const char* const end = begin + text.size();
  const char* nl = std::find(begin, end, '\n');
  std::string_view header(begin, static_cast<size_t>(nl - begin));
  if (!header.empty() && header.back() == '\r') header.remove_suffix(1);
  if (header.empty()) throw ArchiveError(origin, 1, "empty header line, " + expect);
  columns = split_header(header);
  check_header(columns, spec, origin);
  return nl < end ? nl + 1 : end;
}

// Number of '\n' in [p, end). Byte compares summed in 16 8-bit lanes, which the compiler turns
// into vector code: about 8x std::count, which sums into a size_t per byte.
size_t count_newlines(const char* p, const char* end) {
  size_t n = 0;
  while (end - p >= 16) {
    // 255 blocks of 16 bytes at most, so that no 8-bit lane overflows.
    const char* stop = p + std::min<std::ptrdiff_t>((end - p) / 16, 255) * 16;
    unsigned char lanes[16] = {};
    for (; p < stop; p += 16)
      for (int i = 0; i < 16; ++i) lanes[i] += p[i] == '\n' ? 1 : 0;
    for (unsigned char l : lanes) n += l;
  }
  for (; p < end; ++p) n += *p == '\n' ? 1 : 0;
  return n;
}

// A run of whole lines of the data: one thread's part, or a block of it read from a file.
struct Chunk {
  const char* begin;  ///< a line start
  const char* end;    ///< after a '\n', or the end of the text
  size_t first_line;  ///< file line of its first row
  size_t first_row;   ///< data row index of its first row
  /// Time of the row before the chunk, for the strictly-increasing check of its first row; none
  /// for the first chunk, and for the second one until the first is parsed.
  std::optional<double> prev_t;
  /// Rows the sink has room for from first_row on (counted before): more means the file changed.
  size_t row_limit;
};

struct ChunkResult {
  size_t rows = 0;
  double first_t = 0.0;  ///< first column of the first and of the last row
  double last_t = 0.0;
};

// The row and cell rules. The messages are those of the reader since its first version: tests and
// users match on them.
struct ChunkParser {
  const std::string& origin;
  const std::vector<std::string>& columns;
  bool increasing;

  ChunkResult parse(const Chunk& c, CsvRowSink* sink) const;
  /// A file whose rows do not match the count made just before.
  [[noreturn]] void throw_changed() const {
    throw ArchiveError(origin, "changed while it was being read (read it again)");
  }

 private:
  const char* cell(const char* p, const Chunk& c, size_t line, size_t col, double& v) const;
  [[noreturn]] void throw_missing_cell(const char* p, const char* end, size_t line,
                                       size_t col) const;
  [[noreturn]] void throw_cell(const char* p, const char* end, size_t line, size_t col,
                               const char* what) const;
  [[noreturn]] void throw_columns(size_t line, size_t found) const;
  [[noreturn]] void throw_truncated(size_t line, size_t found) const;
};

ChunkResult ChunkParser::parse(const Chunk& c, CsvRowSink* sink) const {
  const size_t ncol = columns.size();
  std::vector<double> values(ncol);
  ChunkResult r;
  std::optional<double> prev_t = c.prev_t;
  size_t line = c.first_line;
  for (const char* p = c.begin; p < c.end; ++line) {
    for (size_t col = 0; col < ncol; ++col) {
      p = cell(p, c, line, col, values[col]);
      if (col != 0 || !increasing) continue;
      if (prev_t && !(values[0] > *prev_t))
        throw ArchiveError::column_error(
            origin, line, columns[0],
            "time " + format_double(values[0]) + " is not after " + format_double(*prev_t) +
                " on line " + std::to_string(line - 1) + " (time must be strictly increasing)");
      prev_t = values[0];
    }
    if (r.rows == 0) r.first_t = values[0];
    r.last_t = values[0];
    if (r.rows == c.row_limit) throw_changed();
    if (sink) sink->row(c.first_row + r.rows, values.data());
    ++r.rows;
  }
  return r;
}

// Cell `col` of a row, starting at p: the number and what follows it. Returns the start of the
// next cell, or of the next line after the last cell.
const char* ChunkParser::cell(const char* p, const Chunk& c, size_t line, size_t col,
                              double& v) const {
  const char* const end = c.end;
  if (p == end || *p == '\n' || *p == '\r' || *p == ',') throw_missing_cell(p, end, line, col);
  const auto res = std::from_chars(p, end, v);
  if (res.ec == std::errc::result_out_of_range)
    throw_cell(p, end, line, col, "number out of double range");
  if (res.ec != std::errc()) throw_cell(p, end, line, col, "not a number");
  if (!std::isfinite(v)) throw_cell(p, end, line, col, "NaN or Inf is not allowed");
  const char* q = res.ptr;
  if (col + 1 < columns.size()) {
    if (q < end && *q == ',') return q + 1;
    if (q == end) throw_truncated(line, col + 1);
    if (is_newline_at(q, end)) throw_columns(line, col + 1);
    throw_cell(p, end, line, col, "not a number");
  }
  if (q == end) return q;
  if (*q == '\n') return q + 1;
  if (*q == '\r' && q + 1 < end && q[1] == '\n') return q + 2;
  if (*q == ',') {
    const char* line_start = q;  // c.begin is a line start: the walk stays in this chunk
    while (line_start > c.begin && line_start[-1] != '\n') --line_start;
    throw_columns(line, count_fields(line_start, end));
  }
  throw_cell(p, end, line, col, "not a number");
}

void ChunkParser::throw_missing_cell(const char* p, const char* end, size_t line,
                                     size_t col) const {
  const size_t ncol = columns.size();
  if (col == 0 && is_newline_at(p, end))
    throw ArchiveError(origin, line, "blank line (expected " + std::to_string(ncol) + " columns)");
  if (p < end && *p == ',')
    throw ArchiveError::column_error(origin, line, columns[col], "empty field");
  if (p == end) throw_truncated(line, col);
  throw_columns(line, col);
}

void ChunkParser::throw_cell(const char* p, const char* end, size_t line, size_t col,
                             const char* what) const {
  throw ArchiveError::column_error(origin, line, columns[col],
                                   std::string(what) + ": '" + cell_text(p, end) + "'");
}

void ChunkParser::throw_columns(size_t line, size_t found) const {
  throw ArchiveError(
      origin, line,
      "expected " + std::to_string(columns.size()) + " columns, found " + std::to_string(found));
}

void ChunkParser::throw_truncated(size_t line, size_t found) const {
  throw ArchiveError(origin, line,
                     "truncated last line: no trailing newline and only " + std::to_string(found) +
                         " of " + std::to_string(columns.size()) + " columns");
}

// Sink of parse_csv(): the rows into CsvTable::values.
class TableSink final : public CsvRowSink {
 public:
  explicit TableSink(CsvTable& t) : t_(t) {}
  void begin(const std::vector<std::string>& columns, size_t num_rows) override {
    t_.columns = columns;
    t_.num_rows = num_rows;
    t_.values.resize(num_rows * columns.size());
  }
  void row(size_t row, const double* values) override {
    const size_t ncol = t_.columns.size();
    std::copy(values, values + ncol, t_.values.begin() + static_cast<long>(row * ncol));
  }

 private:
  CsvTable& t_;
};

// The data rows' text: a string in memory (parse_csv), or a file read a block at a time by each
// thread into its own buffer (read_csv_rows), so that the 35 MB of an hour's imu.csv are never in
// memory whole and the two threads share the copying.
class CsvText {
 public:
  explicit CsvText(std::string_view text) : text_(text) {}
  CsvText(const ReadableFile& file, size_t block_bytes)
      : file_(&file), block_bytes_(std::max<size_t>(block_bytes, 1)) {}
  size_t size() const { return file_ ? file_->size_bytes() : text_.size(); }

  /// Calls piece(begin, end) on consecutive pieces of [lo, hi) that each end after a '\n', except
  /// a last one that ends at hi. Pieces start at a line start if lo does.
  template <typename Piece>
  void for_each_piece(size_t lo, size_t hi, Piece&& piece) const;
  /// The offset after the first '\n' in [from, hi), else hi.
  size_t after_newline(size_t from, size_t hi) const;

 private:
  std::string_view text_;
  const ReadableFile* file_ = nullptr;
  size_t block_bytes_ = 0;
};

template <typename Piece>
void CsvText::for_each_piece(size_t lo, size_t hi, Piece&& piece) const {
  if (!file_) {
    if (lo < hi) piece(text_.data() + lo, text_.data() + hi);
    return;
  }
  std::vector<char> buf(std::min(block_bytes_, hi - lo));
  size_t kept = 0;  // the start of a line, carried over from the last block
  for (size_t off = lo; off < hi;) {
    if (kept == buf.size()) buf.resize(buf.size() * 2);  // a line longer than the buffer
    const size_t n = std::min(buf.size() - kept, hi - off);
    file_->read_at(off, buf.data() + kept, n);
    off += n;
    const char* const begin = buf.data();
    const char* const end = begin + kept + n;
    const char* cut = end;  // up to the last line end, or everything at hi
    if (off < hi)
      while (cut > begin && cut[-1] != '\n') --cut;
    if (cut > begin) piece(begin, cut);
    kept = static_cast<size_t>(end - cut);
    std::memmove(buf.data(), cut, kept);
  }
}

size_t CsvText::after_newline(size_t from, size_t hi) const {
  if (!file_) {
    const void* nl = std::memchr(text_.data() + from, '\n', hi - from);
    return nl ? static_cast<size_t>(static_cast<const char*>(nl) - text_.data()) + 1 : hi;
  }
  char buf[4096];
  for (size_t off = from; off < hi; off += sizeof buf) {
    const size_t n = std::min(sizeof buf, hi - off);
    file_->read_at(off, buf, n);
    if (const void* nl = std::memchr(buf, '\n', n))
      return off + static_cast<size_t>(static_cast<const char*>(nl) - buf) + 1;
  }
  return hi;
}

// Where the second chunk starts: after the first line end at or after the chunking offset into
// the data [lo, hi); hi when the text stays in one piece.
size_t split_offset(const CsvText& text, size_t lo, size_t hi, const CsvChunking& chunking) {
  const size_t n = hi - lo;
  if (n == 0 || n < chunking.min_parallel_bytes) return hi;
  const size_t at =
      chunking.split_at == CsvChunking::kMiddle ? n / 2 : std::min(chunking.split_at, n);
  return text.after_newline(lo + at, hi);
}

// One thread's share of the data rows: [lo, hi) of the text, `rows` of them by the count.
struct Part {
  size_t lo, hi;
  size_t first_row;
  size_t rows;
};

// Rows in [lo, hi): one per line end, and a last line without one.
size_t count_rows(const CsvText& text, size_t lo, size_t hi) {
  size_t n = 0;
  char last = '\n';
  text.for_each_piece(lo, hi, [&](const char* b, const char* e) {
    n += count_newlines(b, e);
    last = e[-1];
  });
  return n + (last != '\n' ? 1 : 0);  // a last line without '\n' is a row too
}

// A part, block by block; prev_t as for Chunk.
ChunkResult parse_part(const ChunkParser& parser, const CsvText& text, const Part& part,
                       std::optional<double> prev_t, CsvRowSink* sink) {
  ChunkResult total;
  text.for_each_piece(part.lo, part.hi, [&](const char* b, const char* e) {
    const size_t row = part.first_row + total.rows;
    const Chunk c{b, e, CsvTable::line_of_row(row), row, prev_t, part.rows - total.rows};
    const ChunkResult r = parser.parse(c, sink);
    if (r.rows == 0) return;
    if (total.rows == 0) total.first_t = r.first_t;
    total.last_t = prev_t.emplace(r.last_t);
    total.rows += r.rows;
  });
  return total;
}

// The data rows of `text` from data_lo on, in two parts on two threads when large enough.
void parse_data(const CsvText& text, size_t data_lo, const ChunkParser& parser, CsvRowSink& sink,
                const CsvChunking& chunking) {
  const size_t data_hi = text.size();
  const size_t split = split_offset(text, data_lo, data_hi, chunking);
  Part first{data_lo, split, 0, 0}, second{split, data_hi, 0, 0};
  if (split == data_hi) {
    first.rows = count_rows(text, first.lo, first.hi);
    sink.begin(parser.columns, first.rows);
    if (parse_part(parser, text, first, std::nullopt, &sink).rows != first.rows)
      parser.throw_changed();
    return;
  }
  run_concurrently([&] { first.rows = count_rows(text, first.lo, first.hi); },
                   [&] { second.rows = count_rows(text, second.lo, second.hi); });
  second.first_row = first.rows;  // every row of the first part ends in '\n'
  sink.begin(parser.columns, first.rows + second.rows);
  // The second part first runs without the time of the row before it (not known yet).
  ChunkResult r1, r2;
  std::exception_ptr second_error;
  run_concurrently([&] { r1 = parse_part(parser, text, first, std::nullopt, &sink); },
                   [&] {
                     try {
                       r2 = parse_part(parser, text, second, std::nullopt, &sink);
                     } catch (...) {
                       second_error = std::current_exception();
                     }
                   });
  // The first part parsed (else run_concurrently threw its error: the earliest). If the second
  // failed, or its first time does not follow the first part's last, parse it again knowing that
  // time: that throws exactly the error a parse from the top meets first.
  if (r1.rows != first.rows) parser.throw_changed();
  const bool time_breaks = parser.increasing && r2.rows > 0 && !(r2.first_t > r1.last_t);
  if (second_error || time_breaks) {
    parse_part(parser, text, second, r1.last_t, nullptr);
    if (second_error) std::rethrow_exception(second_error);  // not reached: the parse threw
  }
  if (r2.rows != second.rows) parser.throw_changed();
}

}  // namespace

void parse_csv_rows(std::string_view text, const std::string& origin, const CsvSpec& spec,
                    CsvRowSink& sink, const CsvChunking& chunking) {
  std::vector<std::string> columns;
  const char* const data = parse_header(text, origin, spec, columns);
  const ChunkParser parser{origin, columns, spec.increasing_first_column};
  parse_data(CsvText(text), static_cast<size_t>(data - text.data()), parser, sink, chunking);
}

CsvTable parse_csv(std::string_view text, const std::string& origin, const CsvSpec& spec) {
  CsvTable t;
  t.file = origin;
  TableSink sink(t);
  parse_csv_rows(text, origin, spec, sink);
  return t;
}

void read_csv_rows(const std::string& path, const CsvSpec& spec, CsvRowSink& sink,
                   const CsvChunking& chunking) {
  const ReadableFile file(path);
  if (!file.has_size()) {  // pipes, /proc files, empty files: read whole until EOF
    const FileBytes bytes = file.read_all();
    parse_csv_rows(bytes.view(), path, spec, sink, chunking);
    return;
  }
  const CsvText text(file, chunking.block_bytes);
  std::string header(text.after_newline(0, text.size()), '\0');  // the first line, with its '\n'
  file.read_at(0, header.data(), header.size());
  std::vector<std::string> columns;
  parse_header(header, path, spec, columns);
  const ChunkParser parser{path, columns, spec.increasing_first_column};
  parse_data(text, header.size(), parser, sink, chunking);
}

CsvTable read_csv(const std::string& path, const CsvSpec& spec) {
  CsvTable t;
  t.file = path;
  TableSink sink(t);
  read_csv_rows(path, spec, sink);
  return t;
}

CsvWriter::CsvWriter(const std::string& path, std::vector<std::string> columns,
                     bool increasing_first_column)
    : file_(path), columns_(std::move(columns)), increasing_(increasing_first_column) {
  if (columns_.empty()) throw ArchiveError(path, "CSV writer needs at least one column");
  std::string& b = file_.buffer();
  for (size_t i = 0; i < columns_.size(); ++i) {
    if (i) b += ',';
    b += columns_[i];
  }
  b += '\n';
}

void CsvWriter::write_row(const double* values, size_t n) {
  const size_t line = rows_ + 2;
  if (n != columns_.size())
    throw ArchiveError(file_.path(), line,
                       "writer got " + std::to_string(n) + " values for " +
                           std::to_string(columns_.size()) + " columns");
  for (size_t c = 0; c < n; ++c)
    if (!std::isfinite(values[c]))
      throw ArchiveError::column_error(file_.path(), line, columns_[c],
                                       "cannot write NaN or Inf (the format forbids them)");
  if (increasing_ && rows_ > 0 && !(values[0] > last_t_))
    throw ArchiveError::column_error(file_.path(), line, columns_[0],
                                     "time " + format_double(values[0]) + " is not after " +
                                         format_double(last_t_) + " (must be strictly increasing)");
  last_t_ = values[0];
  std::string& b = file_.buffer();
  for (size_t c = 0; c < n; ++c) {
    if (c) b += ',';
    append_double(b, values[c]);
  }
  b += '\n';
  ++rows_;
  file_.maybe_flush();
}

void CsvWriter::close() { file_.close(); }

}  // namespace imucal::db::archive
