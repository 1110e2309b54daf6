#include "db/archive/csv.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <system_error>

#include "db/archive/archive_error.hpp"

namespace imucal::archive {

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

bool CsvTable::has_column(std::string_view name) const {
  return std::find(columns.begin(), columns.end(), name) != columns.end();
}

size_t CsvTable::column_index(std::string_view name) const {
  const auto it = std::find(columns.begin(), columns.end(), name);
  if (it == columns.end())
    throw ArchiveError::column_error(file, 1, std::string(name), "missing column");
  return static_cast<size_t>(it - columns.begin());
}

CsvTable parse_csv(std::string_view text, const std::string& origin, const CsvSpec& spec) {
  CsvTable t;
  t.file = origin;
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
  t.columns = split_header(header);
  check_header(t.columns, spec, origin);

  const size_t ncol = t.columns.size();
  const char* p = nl < end ? nl + 1 : end;
  t.values.reserve(static_cast<size_t>(std::count(p, end, '\n') + 1) * ncol);

  size_t line = 2;
  double last_t = 0.0;
  while (p < end) {
    for (size_t c = 0; c < ncol; ++c) {
      const std::string& col = t.columns[c];
      if (p == end || *p == '\n' || *p == '\r' || *p == ',') {
        if (c == 0 && is_newline_at(p, end))
          throw ArchiveError(origin, line,
                             "blank line (expected " + std::to_string(ncol) + " columns)");
        if (p < end && *p == ',')
          throw ArchiveError::column_error(origin, line, col, "empty field");
        if (p == end)
          throw ArchiveError(origin, line,
                             "truncated last line: no trailing newline and only " +
                                 std::to_string(c) + " of " + std::to_string(ncol) + " columns");
        throw ArchiveError(
            origin, line,
            "expected " + std::to_string(ncol) + " columns, found " + std::to_string(c));
      }
      double v;
      const auto res = std::from_chars(p, end, v);
      if (res.ec == std::errc::result_out_of_range)
        throw ArchiveError::column_error(origin, line, col,
                                         "number out of double range: '" + cell_text(p, end) + "'");
      if (res.ec != std::errc())
        throw ArchiveError::column_error(origin, line, col,
                                         "not a number: '" + cell_text(p, end) + "'");
      if (!std::isfinite(v))
        throw ArchiveError::column_error(origin, line, col,
                                         "NaN or Inf is not allowed: '" + cell_text(p, end) + "'");
      const char* q = res.ptr;
      if (c + 1 < ncol) {
        if (q < end && *q == ',') {
          p = q + 1;
        } else if (q == end || is_newline_at(q, end)) {
          if (q == end)
            throw ArchiveError(origin, line,
                               "truncated last line: no trailing newline and only " +
                                   std::to_string(c + 1) + " of " + std::to_string(ncol) +
                                   " columns");
          throw ArchiveError(
              origin, line,
              "expected " + std::to_string(ncol) + " columns, found " + std::to_string(c + 1));
        } else {
          throw ArchiveError::column_error(origin, line, col,
                                           "not a number: '" + cell_text(p, end) + "'");
        }
      } else {
        if (q == end) {
          p = q;
        } else if (*q == '\n') {
          p = q + 1;
        } else if (*q == '\r' && q + 1 < end && q[1] == '\n') {
          p = q + 2;
        } else if (*q == ',') {
          const char* line_start = q;
          while (line_start > begin && line_start[-1] != '\n') --line_start;
          throw ArchiveError(origin, line,
                             "expected " + std::to_string(ncol) + " columns, found " +
                                 std::to_string(count_fields(line_start, end)));
        } else {
          throw ArchiveError::column_error(origin, line, col,
                                           "not a number: '" + cell_text(p, end) + "'");
        }
      }
      if (c == 0 && spec.increasing_first_column) {
        if (t.num_rows > 0 && !(v > last_t))
          throw ArchiveError::column_error(
              origin, line, col,
              "time " + format_double(v) + " is not after " + format_double(last_t) + " on line " +
                  std::to_string(line - 1) + " (time must be strictly increasing)");
        last_t = v;
      }
      t.values.push_back(v);
    }
    ++t.num_rows;
    ++line;
  }
  return t;
}

CsvTable read_csv(const std::string& path, const CsvSpec& spec) {
  return parse_csv(read_text_file(path), path, spec);
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

}  // namespace imucal::archive
