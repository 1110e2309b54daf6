#include "db/archive/raw_recording.hpp"

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <functional>
#include <optional>
#include <sstream>
#include <stdexcept>
#include <string_view>

#include "db/archive/archive_error.hpp"

namespace imucal::db::archive {

namespace {

/// The numeric cells of a text file, row-major, with each row's file line.
struct Rows {
  std::vector<double> values;
  std::vector<std::size_t> line;
  std::size_t num_cols = 0;
  std::size_t header_lines = 0;      ///< lines before the data skipped (preamble and header)
  std::vector<std::string> columns;  ///< what each column is (from the decision at the first row)
  std::string columns_from;
  bool decimal_comma = false;
  std::string source;  ///< the file, for errors found after reading
  std::size_t size() const { return line.size(); }
  double at(std::size_t r, std::size_t c) const { return values[r * num_cols + c]; }
};

bool parse_number(std::string_view s, double& out) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && end == s.data() + s.size() && std::isfinite(out);
}

/// A cell of a line split at semicolons may carry one decimal comma ("9,81"); `used` says so.
bool parse_cell(std::string_view s, bool semicolon_line, double& out, bool& used) {
  if (parse_number(s, out)) return true;
  const std::size_t comma = s.find(',');
  if (!semicolon_line || comma == std::string_view::npos ||
      s.find_first_of(".,", comma + 1) != std::string_view::npos ||
      s.find('.') != std::string_view::npos)
    return false;
  std::string dotted(s);
  dotted[comma] = '.';
  if (!parse_number(dotted, out)) return false;
  used = true;
  return true;
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r'))
    s.remove_suffix(1);
  return s;
}

/// Cells of one line: split at semicolons if it has any (its cells may then hold decimal commas),
/// else at commas if it has any, else at runs of whitespace.
std::vector<std::string_view> split_cells(std::string_view line) {
  std::vector<std::string_view> cells;
  const char sep = line.find(';') != std::string_view::npos   ? ';'
                   : line.find(',') != std::string_view::npos ? ','
                                                              : '\0';
  if (sep != '\0') {
    std::size_t start = 0;
    for (std::size_t i = 0; i <= line.size(); ++i)
      if (i == line.size() || line[i] == sep) {
        cells.push_back(trim(line.substr(start, i - start)));
        start = i + 1;
      }
    return cells;
  }
  std::size_t i = 0;
  while (i < line.size()) {
    while (i < line.size() && (line[i] == ' ' || line[i] == '\t')) ++i;
    const std::size_t start = i;
    while (i < line.size() && line[i] != ' ' && line[i] != '\t') ++i;
    if (i > start) cells.push_back(line.substr(start, i - start));
  }
  return cells;
}

/// One line's cells, read as numbers where they are.
struct ParsedLine {
  std::vector<std::string_view> cells;
  std::vector<double> values;
  std::size_t first_bad =
      0;  ///< index of the first cell that is not a number; cells.size() if none
  std::size_t numbers = 0;
  bool comma_used = false;
  bool all_numbers() const { return first_bad == cells.size(); }
  bool all_text() const { return numbers == 0; }
};

/// `skipped`: the columns marked "-" (not read, so a text column there is no bad cell).
ParsedLine parse_line(std::string_view line, const std::vector<std::string>& skipped = {}) {
  ParsedLine p;
  p.cells = split_cells(line);
  p.values.resize(p.cells.size());
  p.first_bad = p.cells.size();
  const bool semicolons = line.find(';') != std::string_view::npos;
  for (std::size_t c = 0; c < p.cells.size(); ++c) {
    if (c < skipped.size() && skipped[c] == "-" && skipped.size() == p.cells.size()) {
      p.values[c] = 0.0;
      ++p.numbers;
    } else if (parse_cell(p.cells[c], semicolons, p.values[c], p.comma_used))
      ++p.numbers;
    else if (p.first_bad == p.cells.size())
      p.first_bad = c;
  }
  return p;
}

std::string joined(const std::vector<std::string>& names) {
  std::string list;
  for (const auto& n : names) list += (list.empty() ? "" : ",") + n;
  return list;
}

std::string column_label(std::size_t c, const std::vector<std::string>& names) {
  return std::to_string(c + 1) + (c < names.size() && names[c] != "-" ? " (" + names[c] + ")" : "");
}

[[noreturn]] void throw_bad_cell(const std::string& path, std::size_t line_no, const ParsedLine& p,
                                 const std::vector<std::string>& names) {
  const std::string_view cell = p.cells[p.first_bad];
  throw ArchiveError::column_error(
      path, line_no, column_label(p.first_bad, names),
      cell.empty() ? "empty cell" : "'" + std::string(cell) + "' is not a finite decimal number");
}

/// What the columns are, decided at the first data row from the header (its cells; empty if none)
/// and that row's cell count; throws naming `line_no` if they cannot be.
struct ColumnDecision {
  std::vector<std::string> columns;
  std::string from;
};
using DecideColumns =
    std::function<ColumnDecision(const std::vector<std::string>& header, std::size_t header_line,
                                 std::size_t cells, std::size_t line_no)>;

/// A line before the first data row that may still turn out to be a bad data row (its text:
/// parsed once the data's cell count is known).
struct PendingLine {
  std::size_t line_no = 0;
  std::string text;
};

/// The lines before the first data row: preamble and header lines are skipped; one with the
/// data's cell count and some cells numbers is a bad data row.
void settle_preamble(std::vector<PendingLine>& pending, std::size_t data_cells,
                     const std::string& path, Rows& rows, std::vector<std::string>& header,
                     std::size_t& header_line) {
  for (const PendingLine& line : pending) {
    const ParsedLine p = parse_line(trim(line.text));
    if (p.cells.size() != data_cells) continue;  // a preamble line
    if (!p.all_text()) throw_bad_cell(path, line.line_no, p, {});
    header.assign(p.cells.begin(), p.cells.end());
    header_line = line.line_no;
  }
  rows.header_lines += pending.size();
}

/// The rows of `f`; `path` names it in errors. A data row holds at least `min_cells` cells (a
/// preamble's "key,value" line of numbers holds fewer).
Rows read_rows(std::istream& f, const std::string& path, std::size_t skip_lines,
               std::size_t min_cells, const DecideColumns& decide,
               const std::vector<std::string>& given = {}) {
  Rows rows;
  rows.source = path;
  std::vector<PendingLine> pending;
  std::string text;
  std::size_t line_no = 0;
  while (std::getline(f, text)) {
    ++line_no;
    if (line_no <= skip_lines) {
      ++rows.header_lines;
      continue;
    }
    const std::string_view line = trim(text);
    if (line.empty() || line.front() == '#' || line.front() == '%') continue;
    const ParsedLine p = parse_line(line, rows.size() == 0 ? given : rows.columns);
    if (rows.size() == 0 && !(p.all_numbers() && p.cells.size() >= min_cells)) {
      pending.push_back({line_no, text});
      continue;
    }
    if (rows.size() == 0) {
      std::vector<std::string> header;
      std::size_t header_line = 0;
      settle_preamble(pending, p.cells.size(), path, rows, header, header_line);
      ColumnDecision d = decide(header, header_line, p.cells.size(), line_no);
      rows.columns = std::move(d.columns);
      rows.columns_from = std::move(d.from);
      rows.num_cols = rows.columns.size();
    }
    if (p.cells.size() != rows.num_cols)
      throw ArchiveError(
          path, line_no,
          std::to_string(p.cells.size()) + " columns, expected " + std::to_string(rows.num_cols));
    if (!p.all_numbers()) throw_bad_cell(path, line_no, p, rows.columns);
    rows.decimal_comma = rows.decimal_comma || p.comma_used;
    rows.values.insert(rows.values.end(), p.values.begin(), p.values.end());
    rows.line.push_back(line_no);
  }
  if (f.bad()) throw ArchiveError(path, "read error");
  if (rows.size() == 0)  // no data row at all: the first line that looks like a bad one says why
    for (const PendingLine& line : pending) {
      const ParsedLine p = parse_line(trim(line.text));
      if (p.cells.size() >= min_cells && !p.all_text())
        throw_bad_cell(path, line.line_no, p, given);
    }
  if (rows.size() < 2)
    throw ArchiveError(
        path, std::to_string(rows.size()) + " data rows: a recording needs at least two samples");
  return rows;
}

Rows read_rows(const std::string& path, std::size_t skip_lines, std::size_t min_cells,
               const DecideColumns& decide) {
  std::ifstream f(path);
  if (!f) throw ArchiveError(path, std::string("cannot open: ") + std::strerror(errno));
  return read_rows(f, path, skip_lines, min_cells, decide, {});
}

/// The uniform grid t = t0 + slot · T fitted to the stamps (least squares). Each sample's slot
/// is its place on the grid: one more than the previous sample's, or as many more as a
/// dropped-sample gap spans.
struct Grid {
  double t0 = 0.0, T = 0.0, rms = 0.0, max = 0.0;
  std::vector<std::size_t> row;    ///< the row of each sample; empty: sample k is row k
  std::vector<std::int64_t> slot;  ///< each sample's place on the grid; empty: k
  std::size_t repeated_rows = 0, gaps = 0, samples_missing = 0;
  std::size_t row_of(std::size_t k) const { return row.empty() ? k : row[k]; }
  double slot_of(std::size_t k) const {
    return static_cast<double>(slot.empty() ? static_cast<std::int64_t>(k) : slot[k]);
  }
  std::size_t samples(std::size_t rows) const { return row.empty() ? rows : row.size(); }
};

std::string fmt_s(double s) {
  std::ostringstream os;
  os.precision(6);
  os << s;
  return os.str();
}

/// Every value of rows a and b equal (a column not read holds NaN in both).
bool same_row(const Rows& rows, std::size_t a, std::size_t b) {
  for (std::size_t c = 0; c < rows.num_cols; ++c) {
    const double x = rows.at(a, c), y = rows.at(b, c);
    if (!(x == y || (std::isnan(x) && std::isnan(y)))) return false;
  }
  return true;
}

/// The rows kept: each stamp after the previous one; a verbatim repeat dropped unless `strict`.
std::vector<std::size_t> increasing_rows(const std::vector<double>& t, const Rows& rows,
                                         const std::string& path, bool strict,
                                         std::size_t& repeats) {
  std::vector<std::size_t> kept = {0};
  for (std::size_t k = 1; k < t.size(); ++k) {
    const std::size_t prev = kept.back();
    if (t[k] > t[prev]) {
      kept.push_back(k);
      continue;
    }
    if (!strict && t[k] == t[prev] && same_row(rows, k, prev)) {
      ++repeats;
      continue;
    }
    throw ArchiveError(
        path, rows.line[k],
        "time " + fmt_s(t[k]) + " s does not increase (previous sample " + fmt_s(t[prev]) + " s" +
            (t[k] == t[prev]
                 ? (strict ? "; --strict-time refuses a repeated row" : ", with other values")
                 : "") +
            ")");
  }
  return kept;
}

double median_of(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

/// Each kept sample's slot: a step over 1.5 × the median is a gap of round(step / median) − 1
/// samples, refused under `strict`.
void place_on_grid(const std::vector<double>& t, const Rows& rows, const std::string& path,
                   bool strict, Grid& g) {
  std::vector<double> dt;
  for (std::size_t i = 1; i < g.row.size(); ++i) dt.push_back(t[g.row[i]] - t[g.row[i - 1]]);
  const double median = dt.empty() ? 0.0 : median_of(dt);
  g.slot.assign(g.row.size(), 0);
  for (std::size_t i = 1; i < g.row.size(); ++i) {
    const double step = dt[i - 1];
    std::int64_t advance = 1;
    if (step > 1.5 * median) {
      if (strict)
        throw ArchiveError(path, rows.line[g.row[i]],
                           "a gap of " + fmt_s(step) + " s after a typical step of " +
                               fmt_s(median) +
                               " s: dropped samples (--strict-time refuses them; without it the "
                               "gap is kept and the calibration leaves out what it falls in)");
      advance = std::max<std::int64_t>(2, std::llround(step / median));
      ++g.gaps;
      g.samples_missing += static_cast<std::size_t>(advance - 1);
    }
    g.slot[i] = g.slot[i - 1] + advance;
  }
}

/// The grid fitted to the stamps of the kept rows; every stamp within half a period of it.
Grid fit_grid(const std::vector<double>& t, const Rows& rows, const std::string& path,
              bool strict_repeats, bool strict_gaps) {
  Grid g;
  g.row = increasing_rows(t, rows, path, strict_repeats, g.repeated_rows);
  place_on_grid(t, rows, path, strict_gaps, g);
  const std::size_t n = g.row.size();
  double kbar = 0.0, tbar = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    kbar += g.slot_of(k);
    tbar += t[g.row[k]];
  }
  kbar /= static_cast<double>(n);
  tbar /= static_cast<double>(n);
  double sxy = 0.0, sxx = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    sxy += (g.slot_of(k) - kbar) * (t[g.row[k]] - tbar);
    sxx += (g.slot_of(k) - kbar) * (g.slot_of(k) - kbar);
  }
  g.T = sxy / sxx;
  if (!(std::isfinite(g.T) && g.T > 0.0))
    throw ArchiveError(path, "the time stamps give no finite sampling period");
  g.t0 = tbar - g.T * kbar;
  std::size_t worst = 0;
  double ss = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    const double r = std::abs(t[g.row[k]] - (g.t0 + g.T * g.slot_of(k)));
    ss += r * r;
    if (r > g.max) {
      g.max = r;
      worst = g.row[k];
    }
  }
  g.rms = std::sqrt(ss / static_cast<double>(n));
  if (g.max > 0.5 * g.T)
    throw ArchiveError(path, rows.line[worst],
                       "time stamp " + fmt_s(g.max) + " s off the fixed-rate grid (" +
                           fmt_s(1.0 / g.T) +
                           " Hz) fitted to the whole recording: the clock drifts or jumps; the "
                           "importer re-stamps a fixed-rate sensor's samples and cannot here");
  return g;
}

Eigen::Vector3d scaled(const Rows& rows, std::size_t r, const std::size_t cols[3],
                       const RawAxisScale& s) {
  Eigen::Vector3d v;
  for (int a = 0; a < 3; ++a) v(a) = (rows.at(r, cols[a]) - s.offset(a)) * s.scale(a);
  return v;
}

/// Whether the row's three cells are whole numbers (counts).
bool whole_numbers(const Rows& rows, std::size_t r, const std::size_t cols[3]) {
  for (int a = 0; a < 3; ++a)
    if (const double v = rows.at(r, cols[a]); v != std::trunc(v)) return false;
  return true;
}

void check_options(const RawImportOptions& o) {
  if (!(std::isfinite(o.seconds_per_time_unit) && o.seconds_per_time_unit > 0.0))
    throw std::invalid_argument("the time unit must be a positive number of seconds");
  if (!(std::isfinite(o.rate_hz) && o.rate_hz >= 0.0))
    throw std::invalid_argument("the sample rate must be a positive number of Hz");
  for (const RawAxisScale* s : {&o.gyro, &o.accel})
    if (!s->scale.allFinite() || !s->offset.allFinite() || (s->scale.array() == 0.0).any())
      throw std::invalid_argument("scales must be finite and non-zero, offsets finite");
}

/// Samples on the grid from the time column and the two sensors' columns of `g` and `a`.
RawRecording assemble(const Rows& g, const std::size_t gcols[3], const Rows& a,
                      const std::size_t acols[3], const Grid& grid, const RawImportOptions& o) {
  RawRecording out;
  out.rate_hz = 1.0 / grid.T;
  out.jitter_rms_s = grid.rms;
  out.jitter_max_s = grid.max;
  out.repeated_rows = grid.repeated_rows;
  out.gaps = grid.gaps;
  out.samples_missing = grid.samples_missing;
  const double per_sample = o.quantity == RawQuantity::kRates ? grid.T : 1.0;
  out.imu.resize(grid.samples(g.size()));
  bool gyro_counts = true, accel_counts = true;
  for (std::size_t k = 0; k < out.imu.size(); ++k) {
    const std::size_t r = grid.row_of(k);
    gyro_counts = gyro_counts && whole_numbers(g, r, gcols);
    accel_counts = accel_counts && whole_numbers(a, r, acols);
    calib::core::ImuIncrement& s = out.imu[k];
    s.t_s = grid.t0 + grid.T * grid.slot_of(k);
    // After a gap the interval covers the samples lost (the increment is its own sample's): what
    // the archive's reader computes from the stamps, and what marks the gap for the calibration.
    s.dt_s = k > 0 ? s.t_s - out.imu[k - 1].t_s : grid.T;
    s.temp_c = std::nan("");  // a raw recording has no temperature column
    s.dtheta_rad = scaled(g, r, gcols, o.gyro) * per_sample;
    s.dv_mps = scaled(a, r, acols, o.accel) * per_sample;
    if (!s.dtheta_rad.allFinite() || !std::isfinite(s.t_s))
      throw ArchiveError(g.source, g.line[r], "a value overflows once scaled to SI");
    if (!s.dv_mps.allFinite())
      throw ArchiveError(a.source, a.line[r], "a value overflows once scaled to SI");
  }
  // Divided by the rate rather than times the period: the same to an ulp, and run.toml then reads
  // 7.5e-07 rather than 7.499999999999999e-07 for 1.5e-4 at 200 Hz.
  const double per_rate = o.quantity == RawQuantity::kRates ? out.rate_hz : 1.0;
  if (gyro_counts) out.dtheta_count_rad = o.gyro.scale.cwiseAbs().maxCoeff() / per_rate;
  if (accel_counts) out.dv_count_mps = o.accel.scale.cwiseAbs().maxCoeff() / per_rate;
  return out;
}

}  // namespace

namespace {

/// The six channel names a one-file recording's columns must each hold once.
constexpr const char* kSensorColumns[] = {"gx", "gy", "gz", "ax", "ay", "az"};

/// Each sensor name exactly once, "t" at most once, "-" for the columns to ignore, nothing else.
void check_raw_columns(const std::vector<std::string>& cols) {
  auto fail = [&](const std::string& what) {
    throw std::invalid_argument("columns \"" + joined(cols) + "\": " + what +
                                " (names: t, gx, gy, gz, ax, ay, az, - to ignore a column)");
  };
  for (const char* need : kSensorColumns)
    if (std::count(cols.begin(), cols.end(), need) != 1)
      fail(std::string("'") + need + "' must appear exactly once");
  if (std::count(cols.begin(), cols.end(), "t") > 1) fail("'t' must appear at most once");
  const std::vector<std::string> known = {"-", "t", "gx", "gy", "gz", "ax", "ay", "az"};
  for (const std::string& name : cols)
    if (std::find(known.begin(), known.end(), name) == known.end())
      fail("unknown name '" + name + "'");
}

/// A header cell's column name if it is a recognisable one ("" if not): case aside, a unit in
/// brackets or after a last '_' ("gx_dps", "acc_x [g]", "t_ms") aside.
std::string recognised_name(std::string_view cell) {
  static const std::vector<std::pair<std::string, std::vector<std::string>>> kAliases = {
      {"t", {"t", "time", "timestamp", "stamp", "ts"}},
      {"gx", {"gx", "gyro_x", "gyr_x", "gyrox", "gyrx", "wx", "w_x", "omega_x", "gyroscope_x"}},
      {"gy", {"gy", "gyro_y", "gyr_y", "gyroy", "gyry", "wy", "w_y", "omega_y", "gyroscope_y"}},
      {"gz", {"gz", "gyro_z", "gyr_z", "gyroz", "gyrz", "wz", "w_z", "omega_z", "gyroscope_z"}},
      {"ax", {"ax", "acc_x", "accel_x", "accx", "a_x", "accelerometer_x"}},
      {"ay", {"ay", "acc_y", "accel_y", "accy", "a_y", "accelerometer_y"}},
      {"az", {"az", "acc_z", "accel_z", "accz", "a_z", "accelerometer_z"}}};
  std::string name;
  for (char c : cell.substr(0, cell.find_first_of("[( ")))
    name += static_cast<char>(std::tolower(c));
  for (int pass = 0; pass < 2; ++pass) {
    for (const auto& [column, aliases] : kAliases)
      if (std::find(aliases.begin(), aliases.end(), name) != aliases.end()) return column;
    const std::size_t last = name.rfind('_');
    if (last == std::string::npos) break;
    name.resize(last);  // a unit suffix: "gx_dps" -> "gx"
  }
  return "";
}

/// The columns a header names, if it names every sensor channel once ("-" for the others).
std::optional<std::vector<std::string>> header_columns(const std::vector<std::string>& header) {
  std::vector<std::string> cols;
  for (const std::string& cell : header) {
    const std::string name = recognised_name(cell);
    cols.push_back(name.empty() || std::count(cols.begin(), cols.end(), name) ? "-" : name);
  }
  for (const char* need : kSensorColumns)
    if (std::count(cols.begin(), cols.end(), need) != 1) return std::nullopt;
  return cols;
}

/// One file's columns at its first data row: given, else the header's, else the default; a
/// recognisable header that contradicts the given columns is an error naming both.
ColumnDecision decide_columns(const RawImportOptions& o, const std::string& path,
                              const std::vector<std::string>& header, std::size_t header_line,
                              std::size_t cells, std::size_t line_no) {
  const auto named = header_columns(header);
  ColumnDecision d;
  if (!o.columns.empty()) {
    d = {o.columns, "given"};
    if (named && *named != o.columns)
      throw ArchiveError(path, header_line,
                         "the header names the columns " + joined(*named) +
                             " but the columns given are " + joined(o.columns) +
                             ": drop the given columns to follow the header, or correct one");
  } else if (named) {
    d = {*named, "header"};
  } else {
    d.columns = {"t", "gx", "gy", "gz", "ax", "ay", "az"};
    if (o.rate_hz > 0.0 && cells == 6) d.columns.erase(d.columns.begin());
    d.from = "default";
  }
  if (cells != d.columns.size())
    throw ArchiveError(path, line_no,
                       std::to_string(cells) + " columns, expected " +
                           std::to_string(d.columns.size()) + " (" + joined(d.columns) + ")");
  return d;
}

}  // namespace

std::vector<std::string> parse_raw_columns(const std::string& text) {
  std::vector<std::string> cols;
  std::stringstream ss(text);
  for (std::string c; std::getline(ss, c, ',');) cols.emplace_back(trim(c));
  check_raw_columns(cols);
  return cols;
}

namespace {

/// The grid of a recording without a time column: its sample rate alone.
Grid rate_grid(double rate_hz) {
  Grid g;
  g.T = 1.0 / rate_hz;
  return g;
}

/// The stamps' grid, checked against a given sample rate (2 %).
Grid stamped_grid(const std::vector<double>& t, const Rows& rows, const std::string& path,
                  double rate_hz, bool strict_repeats, bool strict_gaps) {
  const Grid g = fit_grid(t, rows, path, strict_repeats, strict_gaps);
  if (rate_hz > 0.0 && std::abs(1.0 / g.T - rate_hz) > 0.02 * rate_hz)
    throw ArchiveError(path, "the time stamps give " + fmt_s(1.0 / g.T) +
                                 " Hz, the rate given is " + fmt_s(rate_hz) +
                                 " Hz: check the time unit or the rate");
  return g;
}

RawRecording one_file(const Rows& rows, const std::string& path, const RawImportOptions& o) {
  const std::vector<std::string>& cols = rows.columns;
  auto index = [&](const char* name) {
    return static_cast<std::size_t>(std::find(cols.begin(), cols.end(), name) - cols.begin());
  };
  const std::size_t tc = index("t");
  Grid grid;
  if (tc == cols.size()) {
    if (!(o.rate_hz > 0.0))
      throw ArchiveError(path, "no time column (columns " + joined(cols) +
                                   "): give the sensor's sample rate (--rate HZ)");
    grid = rate_grid(o.rate_hz);
  } else {
    std::vector<double> t(rows.size());
    for (std::size_t k = 0; k < rows.size(); ++k) t[k] = rows.at(k, tc) * o.seconds_per_time_unit;
    grid = stamped_grid(t, rows, path, o.rate_hz, o.strict_time, o.strict_time);
  }
  const std::size_t gcols[3] = {index("gx"), index("gy"), index("gz")};
  const std::size_t acols[3] = {index("ax"), index("ay"), index("az")};
  RawRecording out = assemble(rows, gcols, rows, acols, grid, o);
  out.header_lines = rows.header_lines;
  out.columns = rows.columns;
  out.columns_from = rows.columns_from;
  out.decimal_comma = rows.decimal_comma;
  return out;
}

/// One file's reading, its columns decided at the first data row.
template <typename Source>
RawRecording one_file_from(Source& source, const std::string& path, const RawImportOptions& o) {
  check_options(o);
  if (!o.columns.empty()) check_raw_columns(o.columns);
  const std::size_t min_cells = o.columns.empty() ? 4 : o.columns.size();
  const DecideColumns decide = [&](const std::vector<std::string>& header, std::size_t header_line,
                                   std::size_t cells, std::size_t line_no) {
    return decide_columns(o, path, header, header_line, cells, line_no);
  };
  return one_file(read_rows(source, path, o.skip_lines, min_cells, decide, o.columns), path, o);
}

/// One sensor's file of a pair: time x y z.
Rows sensor_rows(const std::string& path, const RawImportOptions& o) {
  const DecideColumns decide = [&](const std::vector<std::string>&, std::size_t, std::size_t cells,
                                   std::size_t line_no) {
    if (cells != 4)
      throw ArchiveError(path, line_no, std::to_string(cells) + " columns, expected 4");
    return ColumnDecision{{"t", "x", "y", "z"}, "given"};
  };
  return read_rows(path, o.skip_lines, 4, decide);
}

}  // namespace

RawRecording parse_raw_recording(const std::string& text, const std::string& origin,
                                 const RawImportOptions& o) {
  std::istringstream in(text);
  return one_file_from(in, origin, o);
}

RawRecording read_raw_recording(const std::string& path, const RawImportOptions& o) {
  std::ifstream f(path);
  if (!f) throw ArchiveError(path, std::string("cannot open: ") + std::strerror(errno));
  return one_file_from(f, path, o);
}

RawRecording read_raw_recording_pair(const std::string& gyro_path, const std::string& accel_path,
                                     const RawImportOptions& o) {
  check_options(o);
  const Rows g = sensor_rows(gyro_path, o);
  const Rows a = sensor_rows(accel_path, o);
  if (a.size() != g.size())
    throw ArchiveError(accel_path, std::to_string(a.size()) + " data rows, the gyro file " +
                                       gyro_path + " has " + std::to_string(g.size()) +
                                       ": one file per sensor needs the same samples");
  std::vector<double> t(g.size());
  for (std::size_t k = 0; k < g.size(); ++k) t[k] = g.at(k, 0) * o.seconds_per_time_unit;
  // A repeated row would have to be repeated in both files alike: refused (strict) here.
  const Grid grid = stamped_grid(t, g, gyro_path, o.rate_hz, true, o.strict_time);
  for (std::size_t k = 0; k < a.size(); ++k) {
    const double ta = a.at(k, 0) * o.seconds_per_time_unit;
    if (std::abs(ta - t[k]) > 0.5 * grid.T)
      throw ArchiveError(accel_path, a.line[k],
                         "time " + fmt_s(ta) + " s, the gyro file's sample " +
                             std::to_string(k + 1) + " is at " + fmt_s(t[k]) +
                             " s: one file per sensor needs the same samples");
  }
  const std::size_t cols[3] = {1, 2, 3};
  RawRecording out = assemble(g, cols, a, cols, grid, o);
  out.header_lines = g.header_lines + a.header_lines;
  out.decimal_comma = g.decimal_comma || a.decimal_comma;
  return out;
}

}  // namespace imucal::db::archive
