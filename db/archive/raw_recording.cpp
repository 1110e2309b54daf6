#include "db/archive/raw_recording.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstring>
#include <fstream>
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
  std::size_t header_lines = 0;
  std::string source;  ///< the file, for errors found after reading
  std::size_t size() const { return line.size(); }
  double at(std::size_t r, std::size_t c) const { return values[r * num_cols + c]; }
};

bool parse_number(std::string_view s, double& out) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && end == s.data() + s.size() && std::isfinite(out);
}

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t')) s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r'))
    s.remove_suffix(1);
  return s;
}

/// Cells of one line: split at commas or semicolons if it has any, else at runs of whitespace.
std::vector<std::string_view> split_cells(std::string_view line) {
  std::vector<std::string_view> cells;
  if (line.find_first_of(",;") != std::string_view::npos) {
    std::size_t start = 0;
    for (std::size_t i = 0; i <= line.size(); ++i)
      if (i == line.size() || line[i] == ',' || line[i] == ';') {
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

std::string column_label(std::size_t c, const std::vector<std::string>& names) {
  return std::to_string(c + 1) + (c < names.size() && names[c] != "-" ? " (" + names[c] + ")" : "");
}

/// The rows of `f`; `path` names it in errors.
Rows read_rows(std::istream& f, const std::string& path, std::size_t num_cols,
               const std::vector<std::string>& names) {
  Rows rows;
  rows.num_cols = num_cols;
  rows.source = path;
  std::string text;
  std::size_t line_no = 0;
  while (std::getline(f, text)) {
    ++line_no;
    const std::string_view line = trim(text);
    if (line.empty() || line.front() == '#' || line.front() == '%') continue;
    const std::vector<std::string_view> cells = split_cells(line);
    std::vector<double> row(cells.size());
    std::size_t bad = cells.size();
    for (std::size_t c = 0; c < cells.size() && bad == cells.size(); ++c)
      if (!parse_number(cells[c], row[c])) bad = c;
    if (bad < cells.size() && rows.size() == 0 && rows.header_lines == 0) {
      rows.header_lines = 1;  // a header: the first line with a cell that is not a number
      continue;
    }
    if (cells.size() != num_cols)
      throw ArchiveError(
          path, line_no,
          std::to_string(cells.size()) + " columns, expected " + std::to_string(num_cols));
    if (bad < cells.size())
      throw ArchiveError::column_error(
          path, line_no, column_label(bad, names),
          cells[bad].empty() ? "empty cell"
                             : "'" + std::string(cells[bad]) + "' is not a finite decimal number");
    rows.values.insert(rows.values.end(), row.begin(), row.end());
    rows.line.push_back(line_no);
  }
  if (f.bad()) throw ArchiveError(path, "read error");
  if (rows.size() < 2)
    throw ArchiveError(
        path, std::to_string(rows.size()) + " data rows: a recording needs at least two samples");
  return rows;
}

Rows read_rows(const std::string& path, std::size_t num_cols,
               const std::vector<std::string>& names) {
  std::ifstream f(path);
  if (!f) throw ArchiveError(path, std::string("cannot open: ") + std::strerror(errno));
  return read_rows(f, path, num_cols, names);
}

/// The uniform grid t_k = t0 + k T fitted to the stamps (least squares), after checking that
/// they increase and leave no gap.
struct Grid {
  double t0 = 0.0, T = 0.0, rms = 0.0, max = 0.0;
};

std::string fmt_s(double s) {
  std::ostringstream os;
  os.precision(6);
  os << s;
  return os.str();
}

Grid fit_grid(const std::vector<double>& t, const Rows& rows, const std::string& path) {
  const std::size_t n = t.size();
  std::vector<double> dt;
  for (std::size_t k = 1; k < n; ++k) {
    if (!(t[k] > t[k - 1]))
      throw ArchiveError(path, rows.line[k],
                         "time " + fmt_s(t[k]) + " s does not increase (previous sample " +
                             fmt_s(t[k - 1]) + " s)");
    dt.push_back(t[k] - t[k - 1]);
  }
  std::vector<double> sorted = dt;
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<long>(sorted.size() / 2),
                   sorted.end());
  const double median = sorted[sorted.size() / 2];
  for (std::size_t k = 1; k < n; ++k)
    if (dt[k - 1] > 1.5 * median)
      throw ArchiveError(path, rows.line[k],
                         "a gap of " + fmt_s(dt[k - 1]) + " s after a typical step of " +
                             fmt_s(median) +
                             " s: dropped samples; the importer does not invent data (cut the "
                             "recording here, or fill the gap at its source)");
  double kbar = 0.5 * static_cast<double>(n - 1), tbar = 0.0;
  for (double v : t) tbar += v;
  tbar /= static_cast<double>(n);
  double sxy = 0.0, sxx = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    sxy += (static_cast<double>(k) - kbar) * (t[k] - tbar);
    sxx += (static_cast<double>(k) - kbar) * (static_cast<double>(k) - kbar);
  }
  Grid g;
  g.T = sxy / sxx;
  if (!(std::isfinite(g.T) && g.T > 0.0))
    throw ArchiveError(path, "the time stamps give no finite sampling period");
  g.t0 = tbar - g.T * kbar;
  std::size_t worst = 0;
  double ss = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    const double r = std::abs(t[k] - (g.t0 + g.T * static_cast<double>(k)));
    ss += r * r;
    if (r > g.max) {
      g.max = r;
      worst = k;
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

void check_options(const RawImportOptions& o) {
  if (!(std::isfinite(o.seconds_per_time_unit) && o.seconds_per_time_unit > 0.0))
    throw std::invalid_argument("the time unit must be a positive number of seconds");
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
  const double per_sample = o.quantity == RawQuantity::kRates ? grid.T : 1.0;
  out.imu.resize(g.size());
  for (std::size_t k = 0; k < g.size(); ++k) {
    calib::core::ImuIncrement& s = out.imu[k];
    s.t_s = grid.t0 + grid.T * static_cast<double>(k);
    s.dt_s = grid.T;
    s.temp_c = std::nan("");  // a raw recording has no temperature column
    s.dtheta_rad = scaled(g, k, gcols, o.gyro) * per_sample;
    s.dv_mps = scaled(a, k, acols, o.accel) * per_sample;
    if (!s.dtheta_rad.allFinite() || !std::isfinite(s.t_s))
      throw ArchiveError(g.source, g.line[k], "a value overflows once scaled to SI");
    if (!s.dv_mps.allFinite())
      throw ArchiveError(a.source, a.line[k], "a value overflows once scaled to SI");
  }
  return out;
}

}  // namespace

namespace {

/// Each of t, gx, gy, gz, ax, ay, az exactly once, "-" for the columns to ignore, nothing else.
void check_raw_columns(const std::vector<std::string>& cols) {
  auto fail = [&](const std::string& what) {
    std::string list;
    for (const auto& c : cols) list += (list.empty() ? "" : ",") + c;
    throw std::invalid_argument("columns \"" + list + "\": " + what +
                                " (names: t, gx, gy, gz, ax, ay, az, - to ignore a column)");
  };
  for (const char* need : {"t", "gx", "gy", "gz", "ax", "ay", "az"})
    if (std::count(cols.begin(), cols.end(), need) != 1)
      fail(std::string("'") + need + "' must appear exactly once");
  const std::vector<std::string> known = {"-", "t", "gx", "gy", "gz", "ax", "ay", "az"};
  for (const std::string& name : cols)
    if (std::find(known.begin(), known.end(), name) == known.end())
      fail("unknown name '" + name + "'");
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

RawRecording one_file(const Rows& rows, const std::vector<std::string>& cols,
                      const std::string& path, const RawImportOptions& o) {
  auto index = [&](const char* name) {
    return static_cast<std::size_t>(std::find(cols.begin(), cols.end(), name) - cols.begin());
  };
  const std::size_t tc = index("t");
  std::vector<double> t(rows.size());
  for (std::size_t k = 0; k < rows.size(); ++k) t[k] = rows.at(k, tc) * o.seconds_per_time_unit;
  const Grid grid = fit_grid(t, rows, path);
  const std::size_t gcols[3] = {index("gx"), index("gy"), index("gz")};
  const std::size_t acols[3] = {index("ax"), index("ay"), index("az")};
  RawRecording out = assemble(rows, gcols, rows, acols, grid, o);
  out.header_lines = rows.header_lines;
  return out;
}

}  // namespace

RawRecording parse_raw_recording(const std::string& text, const std::string& origin,
                                 const RawImportOptions& o) {
  check_options(o);
  check_raw_columns(o.columns);
  std::istringstream in(text);
  return one_file(read_rows(in, origin, o.columns.size(), o.columns), o.columns, origin, o);
}

RawRecording read_raw_recording(const std::string& path, const RawImportOptions& o) {
  check_options(o);
  check_raw_columns(o.columns);
  return one_file(read_rows(path, o.columns.size(), o.columns), o.columns, path, o);
}

RawRecording read_raw_recording_pair(const std::string& gyro_path, const std::string& accel_path,
                                     const RawImportOptions& o) {
  check_options(o);
  const Rows g = read_rows(gyro_path, 4, {"t", "x", "y", "z"});
  const Rows a = read_rows(accel_path, 4, {"t", "x", "y", "z"});
  if (a.size() != g.size())
    throw ArchiveError(accel_path, std::to_string(a.size()) + " data rows, the gyro file " +
                                       gyro_path + " has " + std::to_string(g.size()) +
                                       ": one file per sensor needs the same samples");
  std::vector<double> t(g.size());
  for (std::size_t k = 0; k < g.size(); ++k) t[k] = g.at(k, 0) * o.seconds_per_time_unit;
  const Grid grid = fit_grid(t, g, gyro_path);
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
  return out;
}

}  // namespace imucal::db::archive
