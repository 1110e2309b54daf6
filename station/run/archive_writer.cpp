#include "station/run/archive_writer.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <vector>

#include "calib/core/conventions.hpp"
#include "db/archive/archive_error.hpp"
#include "db/archive/csv.hpp"
#include "db/archive/io_util.hpp"
#include "drivers/imu/candump_log.hpp"
#include "drivers/imu/imu_codec.hpp"
#include "sequences/library.hpp"
#include "station/run/capture_stats.hpp"

namespace imucal::station::run {

namespace fs = std::filesystem;

namespace {

// The archive's column sets (db/archive/FORMAT.md); imu.csv without the optional temp_c.
const std::vector<std::string> kImuColumns = {
    "t_s", "dtheta_x_rad", "dtheta_y_rad", "dtheta_z_rad", "dv_x_mps", "dv_y_mps", "dv_z_mps"};
const std::vector<std::string> kTableColumns = {"t_s", "outer_deg", "inner_deg", "at_rest"};

constexpr std::size_t kAutoFlushBytes = 256 * 1024;

std::string header_line(const std::vector<std::string>& cols) {
  std::string s;
  for (std::size_t i = 0; i < cols.size(); ++i) {
    if (i) s += ',';
    s += cols[i];
  }
  s += '\n';
  return s;
}

std::string sys_reason() { return std::strerror(errno); }

std::string join(const std::string& dir, const char* name) { return dir + "/" + name; }

// The reader turns degrees into radians with deg * kDegToRad (db/archive/run_archive.cpp); the
// degree text written is the one that maps back to exactly this radian value (human_for_si).
double deg_to_rad(double d) { return d * kDegToRad; }
double rad_to_deg_exact(double r) {
  return db::archive::human_for_si(r, r * kRadToDeg, deg_to_rad);
}

void fsync_path(const std::string& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw std::runtime_error(path + ": cannot open for fsync: " + sys_reason());
  const int rc = ::fsync(fd);
  const std::string why = sys_reason();
  ::close(fd);
  if (rc != 0) throw std::runtime_error(path + ": fsync failed: " + why);
}

}  // namespace

void ArchiveWriter::File::write_out() {
  if (fd < 0) throw std::runtime_error(path + ": write after close");
  std::size_t off = 0;
  while (off < buf.size()) {
    const ssize_t n = ::write(fd, buf.data() + off, buf.size() - off);
    if (n < 0) {
      if (errno == EINTR) continue;
      const std::string why = sys_reason();
      buf.erase(0, off);
      throw std::runtime_error(path + ": write error: " + why);
    }
    off += static_cast<std::size_t>(n);
  }
  buf.clear();
}

ArchiveWriter::ArchiveWriter(const std::string& dir_in, const db::archive::RunInfo& info) {
  dir_ = dir_in;
  while (dir_.size() > 1 && dir_.back() == '/') dir_.pop_back();
  if (dir_.empty()) throw std::runtime_error("run archive: empty directory name");
  if (info.reference != db::archive::ReferenceKind::kTable)
    throw std::runtime_error(dir_ +
                             ": the station writes table.csv; RunInfo.reference must be table");

  std::error_code ec;
  bool created_dir = false;
  if (fs::exists(dir_, ec)) {
    if (!fs::is_directory(dir_, ec))
      throw std::runtime_error(dir_ + ": exists and is not a directory");
    if (!fs::is_empty(dir_, ec))
      throw std::runtime_error(dir_ +
                               ": exists and is not empty; refusing to write a run archive "
                               "over another");
  } else {
    fs::create_directories(dir_, ec);
    if (ec) throw std::runtime_error(dir_ + ": cannot create directory: " + ec.message());
    created_dir = true;
  }

  std::vector<std::string> created;
  try {
    // run.toml, self-checked: the reader must accept exactly what is written.
    const std::string run_toml = join(dir_, "run.toml");
    const std::string text = db::archive::run_info_text(info);
    db::archive::parse_run_info(text, run_toml + " (as being written)");
    created.push_back(run_toml);
    db::archive::write_file_atomic(run_toml, text);

    imu_.path = join(dir_, "imu.csv");
    table_.path = join(dir_, "table.csv");
    for (File* f : {&imu_, &table_}) {
      f->fd = ::open(f->path.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
      if (f->fd < 0) throw std::runtime_error(f->path + ": cannot create: " + sys_reason());
      created.push_back(f->path);
    }
    imu_.buf = header_line(kImuColumns);
    table_.buf = header_line(kTableColumns);
    const std::string log = join(dir_, "capture.log");
    created.push_back(log);
    capture_ = std::make_unique<drivers::imu::CandumpWriter>(log);
    // The skeleton (headers included) is durable before the first row.
    sync();
    db::archive::fsync_directory(dir_);
    const fs::path parent = fs::path(dir_).parent_path();
    if (created_dir) db::archive::fsync_directory(parent.empty() ? "." : parent.string());
  } catch (...) {
    close_files();
    capture_.reset();
    if (created_dir) {
      fs::remove_all(dir_, ec);
    } else {
      for (const auto& p : created) fs::remove(p, ec);
    }
    throw;
  }
}

ArchiveWriter::~ArchiveWriter() {
  if (!finished_) {
    try {
      flush();
    } catch (const std::exception&) {
      // A destructor cannot report; what reached the files is what recover_archive() sees.
    }
  }
  close_files();
}

void ArchiveWriter::close_files() {
  for (File* f : {&imu_, &table_})
    if (f->fd >= 0) {
      ::close(f->fd);
      f->fd = -1;
    }
}

uint64_t ArchiveWriter::frames() const { return capture_ ? capture_->frames_written() : 0; }

void ArchiveWriter::append_row(const calib::core::ImuIncrement& inc,
                               const calib::core::TableSample& table) {
  if (finished_) throw std::logic_error(dir_ + ": append_row after finish()");
  const std::string where = dir_ + ": row " + std::to_string(rows_ + 1);
  if (!std::isfinite(inc.t_s) || inc.t_s != table.t_s)
    throw std::invalid_argument(where + ": imu t_s " + db::archive::format_double(inc.t_s) +
                                " and table t_s " + db::archive::format_double(table.t_s) +
                                " must be equal and finite");
  if (rows_ > 0 && !(inc.t_s > last_t_s_))
    throw std::invalid_argument(where + ": t_s " + db::archive::format_double(inc.t_s) +
                                " is not after the previous row's " +
                                db::archive::format_double(last_t_s_));
  if (!inc.dtheta_rad.allFinite() || !inc.dv_mps.allFinite() || !std::isfinite(table.outer_rad) ||
      !std::isfinite(table.inner_rad))
    throw std::invalid_argument(where + " (t_s " + db::archive::format_double(inc.t_s) +
                                "): NaN or Inf in the increments or angles");

  std::string& a = imu_.buf;
  db::archive::append_double(a, inc.t_s);
  for (int i = 0; i < 3; ++i) {
    a += ',';
    db::archive::append_double(a, inc.dtheta_rad(i));
  }
  for (int i = 0; i < 3; ++i) {
    a += ',';
    db::archive::append_double(a, inc.dv_mps(i));
  }
  a += '\n';
  std::string& b = table_.buf;
  db::archive::append_double(b, table.t_s);
  b += ',';
  db::archive::append_double(b, rad_to_deg_exact(table.outer_rad));
  b += ',';
  db::archive::append_double(b, rad_to_deg_exact(table.inner_rad));
  b += table.at_rest ? ",1\n" : ",0\n";
  ++rows_;
  rest_rows_ += table.at_rest ? 1 : 0;
  last_t_s_ = inc.t_s;
  if (imu_.buf.size() + table_.buf.size() >= kAutoFlushBytes) flush();
}

void ArchiveWriter::append_frame(const drivers::imu::ReceivedFrame& frame,
                                 std::string_view interface) {
  if (finished_) throw std::logic_error(dir_ + ": append_frame after finish()");
  capture_->write(frame, interface);
}

void ArchiveWriter::flush() {
  if (finished_) return;
  // Both buffers hold the same number of complete rows; writing both keeps the files in lockstep
  // (a crash between the two writes leaves imu.csv ahead, which recover_archive() cuts back).
  imu_.write_out();
  table_.write_out();
  capture_->flush();
}

void ArchiveWriter::sync() {
  flush();
  for (File* f : {&imu_, &table_})
    if (::fdatasync(f->fd) != 0)
      throw std::runtime_error(f->path + ": fdatasync failed: " + sys_reason());
  capture_->sync();
}

void ArchiveWriter::finish(const db::archive::RunInfo& final_info) {
  if (finished_) throw std::logic_error(dir_ + ": finish() called twice");
  if (final_info.reference != db::archive::ReferenceKind::kTable)
    throw std::runtime_error(dir_ + ": RunInfo.reference must be table");
  const std::string run_toml = join(dir_, "run.toml");
  const std::string text = db::archive::run_info_text(final_info);
  db::archive::parse_run_info(text, run_toml + " (as being written)");
  sync();
  for (File* f : {&imu_, &table_}) {
    const int fd = f->fd;
    f->fd = -1;
    if (::close(fd) != 0) throw std::runtime_error(f->path + ": close failed: " + sys_reason());
  }
  capture_->close();
  finished_ = true;
  db::archive::write_file_atomic(run_toml, text);
}

// ------------------------------------------------------------------------------------ recovery

namespace {

struct CsvPrefix {
  std::size_t rows = 0;
  std::vector<std::size_t> line_end;  ///< byte offset after the '\n' of line i (0 = header)
  db::archive::CsvTable table;
};

// The longest prefix of complete lines that parses as the archive CSV (header included).
// A missing file or one without a complete header counts as header-only (0 rows).
CsvPrefix usable_prefix(const std::string& path, const std::vector<std::string>& cols,
                        bool& rewrite_header) {
  CsvPrefix p;
  std::string text;
  std::error_code ec;
  rewrite_header = false;
  if (fs::exists(path, ec)) text = db::archive::read_text_file(path);
  for (std::size_t i = 0; i < text.size(); ++i)
    if (text[i] == '\n') p.line_end.push_back(i + 1);
  if (p.line_end.empty()) {
    rewrite_header = true;
    p.line_end.push_back(header_line(cols).size());
    return p;
  }
  std::size_t n_lines = p.line_end.size();
  const db::archive::CsvSpec spec{cols, {}, true};
  for (;;) {
    try {
      p.table = db::archive::parse_csv(std::string_view(text.data(), p.line_end[n_lines - 1]), path,
                                       spec);
      break;
    } catch (const db::archive::ArchiveError& e) {
      // A bad data line (torn or zero-filled by a crash): keep the lines before it.
      if (e.line() < 2 || e.line() > n_lines) throw;
      n_lines = e.line() - 1;
    }
  }
  p.rows = n_lines - 1;
  p.line_end.resize(n_lines);
  return p;
}

void cut_file(const std::string& path, const std::vector<std::string>& cols, bool rewrite_header,
              std::size_t keep_bytes) {
  if (rewrite_header) {
    db::archive::write_file_atomic(path, header_line(cols));
    return;
  }
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0)
    throw std::runtime_error(path + ": cannot stat: " + sys_reason());
  if (static_cast<std::size_t>(st.st_size) != keep_bytes) {
    if (::truncate(path.c_str(), static_cast<off_t>(keep_bytes)) != 0)
      throw std::runtime_error(path + ": cannot truncate: " + sys_reason());
    fsync_path(path);
  }
}

/// The capture counters capture.log can give back: its frames (every frame the capture received
/// was logged) replayed through the IMU frame decoder, as the live capture decoded them. A torn
/// last line is skipped by the reader; a damaged line ends the count (raw data stays as it is).
db::archive::CaptureInfo recount_capture_log(const std::string& log,
                                             const drivers::imu::DecoderOptions& decoder) {
  CaptureStats stats;
  std::error_code ec;
  if (!fs::exists(log, ec)) return to_capture_info(stats, false);
  drivers::imu::ImuFrameDecoder dec(decoder);
  std::vector<drivers::imu::DecodedSample> samples;
  bool have_prev = false;
  uint64_t prev_index = 0;
  auto take = [&] {
    for (const drivers::imu::DecodedSample& s : samples) {
      if (have_prev && !s.discontinuity && s.sample_index > prev_index + 1)
        stats.max_gap_samples =
            std::max<uint64_t>(stats.max_gap_samples, s.sample_index - prev_index - 1);
      have_prev = true;
      prev_index = s.sample_index;
    }
    samples.clear();
  };
  try {
    drivers::imu::CandumpReader reader(log);
    drivers::imu::CandumpRecord rec;
    while (reader.next(rec)) {
      ++stats.frames_logged;
      dec.push(rec.frame, samples);
      take();
    }
  } catch (const drivers::imu::CandumpParseError&) {
  }
  dec.flush(samples);
  take();
  stats.frames_received = stats.frames_logged;
  set_decoder_counters(stats, dec.counters());
  return to_capture_info(stats, false);
}

}  // namespace

uint64_t recover_archive(const std::string& dir_in, const std::string& end_time_iso,
                         const drivers::imu::DecoderOptions& decoder) {
  std::string dir = dir_in;
  while (dir.size() > 1 && dir.back() == '/') dir.pop_back();
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw db::archive::ArchiveError(dir, "no such run archive directory");

  // Leftovers of an interrupted atomic rewrite (write_file_atomic's "<name>.tmp-XXXXXX").
  for (const auto& e : fs::directory_iterator(dir, ec)) {
    const std::string name = e.path().filename().string();
    if (name.rfind("run.toml.tmp-", 0) == 0 || name.rfind("imu.csv.tmp-", 0) == 0 ||
        name.rfind("table.csv.tmp-", 0) == 0)
      fs::remove(e.path(), ec);
  }

  const std::string run_toml = join(dir, "run.toml");
  if (!fs::exists(run_toml, ec))
    throw db::archive::ArchiveError(run_toml, "missing: cannot recover the run archive");
  db::archive::RunInfo info =
      db::archive::parse_run_info(db::archive::read_text_file(run_toml), run_toml);

  const std::string imu_path = join(dir, "imu.csv");
  const std::string table_path = join(dir, "table.csv");
  bool imu_hdr = false, table_hdr = false;
  CsvPrefix imu = usable_prefix(imu_path, kImuColumns, imu_hdr);
  CsvPrefix tab = usable_prefix(table_path, kTableColumns, table_hdr);
  std::size_t n = std::min(imu.rows, tab.rows);
  for (std::size_t k = 0; k < n; ++k)
    if (std::fabs(imu.table.at(k, 0) - tab.table.at(k, 0)) > db::archive::kTimeMatchTolerance_s) {
      n = k;
      break;
    }
  uint64_t rest = 0;
  for (std::size_t k = 0; k < n; ++k) rest += tab.table.at(k, 3) == 1.0 ? 1 : 0;

  auto size_of = [](const std::string& path) -> std::size_t {
    struct stat st {};
    return ::stat(path.c_str(), &st) == 0 ? static_cast<std::size_t>(st.st_size) : 0;
  };
  const bool files_intact = !imu_hdr && !table_hdr && size_of(imu_path) == imu.line_end[n] &&
                            size_of(table_path) == tab.line_end[n];
  // A finished archive whose files agree with its run.toml: nothing to do.
  if (info.capture && info.capture->complete && files_intact && info.capture->rows_written == n)
    return n;
  cut_file(imu_path, kImuColumns, imu_hdr, imu.line_end[n]);
  cut_file(table_path, kTableColumns, table_hdr, tab.line_end[n]);

  db::archive::CaptureInfo ci = recount_capture_log(join(dir, "capture.log"), decoder);
  ci.complete = false;
  ci.rows_written = n;
  ci.rest_samples = rest;
  info.capture = ci;
  info.end_time = end_time_iso;
  const std::string text = db::archive::run_info_text(info);
  db::archive::parse_run_info(text, run_toml + " (as being recovered)");
  db::archive::write_file_atomic(run_toml, text);
  db::archive::fsync_directory(dir);
  return n;
}

std::string archive_digest(const std::string& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec))
    throw std::runtime_error(dir + ": not a directory (archive digest)");
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir, ec))
    if (e.is_regular_file(ec)) names.push_back(e.path().filename().string());
  if (ec) throw std::runtime_error(dir + ": cannot list directory: " + ec.message());
  std::sort(names.begin(), names.end());
  std::string manifest;
  for (const auto& name : names)
    manifest += name + "  " +
                sequences::sha256_hex(db::archive::read_text_file(join(dir, name.c_str()))) + "\n";
  return sequences::sha256_hex(manifest);
}

}  // namespace imucal::station::run
