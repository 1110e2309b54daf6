#pragma once
// Small I/O and number-formatting helpers shared by the archive readers and writers.
// Every failure is an ArchiveError naming the file and the OS reason.
#include <cstddef>
#include <exception>
#include <memory>
#include <string>
#include <string_view>
#include <system_error>
#include <thread>

#include "calib/core/run_concurrently.hpp"

namespace imucal::db::archive {

/// Whole file as bytes (read_file_bytes() copied into a string: for the small files). Throws
/// ArchiveError("<path>: cannot open: <reason>") on failure.
std::string read_text_file(const std::string& path);

/// A whole file's bytes in a heap buffer that nothing writes before read(2) does (std::string's
/// resize() zero-fills first: a third of the time of reading a 35 MB imu.csv that way). Move-only.
class FileBytes {
 public:
  FileBytes() = default;
  std::string_view view() const { return {data_.get(), size_}; }
  std::size_t size() const { return size_; }

 private:
  friend class ReadableFile;
  std::unique_ptr<char[]> data_;
  std::size_t size_ = 0;
};

/// A whole file, without a copy into a std::string. Files that report no size (pipes, /proc) are
/// read until EOF as well.
FileBytes read_file_bytes(const std::string& path);

/// A file open for reading, closed by the destructor; opening fails with read_text_file()'s errors.
/// For reading a large file piece by piece from two threads (pread).
class ReadableFile {
 public:
  explicit ReadableFile(const std::string& path);
  ~ReadableFile();
  ReadableFile(const ReadableFile&) = delete;
  ReadableFile& operator=(const ReadableFile&) = delete;

  /// A regular file with a size: read_at() can read it. Otherwise (pipes, /proc files, which
  /// report size 0) only read_file_bytes() can.
  bool has_size() const { return size_ > 0; }
  std::size_t size_bytes() const { return size_; }
  /// Exactly n bytes at `offset` (thread-safe). ArchiveError on a read error, and when the file
  /// ends before offset + n: it shrank after it was opened.
  void read_at(std::size_t offset, char* buf, std::size_t n) const;
  /// Everything from the current position to EOF (read_file_bytes()); once.
  FileBytes read_all() const;

 private:
  std::string path_;
  int fd_ = -1;
  std::size_t size_ = 0;
};

/// Two independent tasks at once, the first one's error first (calib/core/run_concurrently.hpp).
using calib::core::run_concurrently;

/// Writes a file durably: open (O_CREAT|O_EXCL unless overwrite), write all, fsync, close.
/// Buffered; every error (ENOSPC, EIO, ...) is an ArchiveError naming the path.
class DurableFile {
 public:
  explicit DurableFile(std::string path, bool overwrite = false);
  ~DurableFile();  ///< closes without throwing; an unclosed file is incomplete (callers clean up)
  DurableFile(const DurableFile&) = delete;
  DurableFile& operator=(const DurableFile&) = delete;

  void append(std::string_view bytes);
  /// Direct access to the buffer for fast formatting; call maybe_flush() after appending.
  std::string& buffer() { return buf_; }
  void maybe_flush() {
    if (buf_.size() >= kFlushBytes) flush();
  }
  /// Flush, fsync and close; throws on any I/O error.
  void close();
  const std::string& path() const { return path_; }

 private:
  static constexpr std::size_t kFlushBytes = 1 << 20;
  void flush();
  std::string path_;
  int fd_ = -1;
  std::string buf_;
};

/// Write a whole file durably (DurableFile in one call).
void write_file_durable(const std::string& path, std::string_view content, bool overwrite = false);

/// Atomically replace `path` with `content`: write a temporary sibling, fsync, rename, fsync the
/// directory. Readers see either the old or the new file, never a partial one.
void write_file_atomic(const std::string& path, std::string_view content);

/// fsync a directory so that renames/creations inside it survive a crash.
void fsync_directory(const std::string& dir);

/// Shortest decimal text that parses back (std::from_chars / strtod) to exactly v.
std::string format_double(double v);
/// Appends format_double(v) to out (no allocation beyond the string's growth).
void append_double(std::string& out, double v);

/// Human-unit value h for an SI value, such that to_si(h) == si exactly if such an h exists near
/// approx_human, otherwise the h whose to_si(h) is nearest to si. Among several such h (the
/// conversion can be many-to-one) the one with the shortest decimal text, then the smallest, wins,
/// so the choice depends only on the SI value reached: writing what was read reproduces the text.
/// The readers convert human units to SI with one fixed expression; the writers use this so that
/// write-then-read of SI values is bit-exact wherever the conversion can reach the value.
template <typename ToSi>
double human_for_si(double si, double approx_human, ToSi to_si);

}  // namespace imucal::db::archive

#include <cmath>

namespace imucal::db::archive {

template <typename ToSi>
double human_for_si(double si, double approx_human, ToSi to_si) {
  if (!std::isfinite(approx_human) || !std::isfinite(si)) return approx_human;
  if (si == 0.0) return si;  // ±0 maps to itself (keeps the sign)
  // The conversions are one or two roundings, so every relevant h lies within a few ulps.
  constexpr int kHalf = 4;
  double cand[2 * kHalf + 1];
  cand[kHalf] = approx_human;
  for (int i = 1; i <= kHalf; ++i) {
    cand[kHalf + i] = std::nextafter(cand[kHalf + i - 1], INFINITY);
    cand[kHalf - i] = std::nextafter(cand[kHalf - i + 1], -INFINITY);
  }
  // The reachable SI value nearest to si (ties: the smaller one).
  double best_si = to_si(cand[0]);
  for (double h : cand) {
    const double v = to_si(h);
    const double e = std::fabs(v - si), be = std::fabs(best_si - si);
    if (e < be || (e == be && v < best_si)) best_si = v;
  }
  // Among its preimages: shortest text, then smallest value.
  double pre[2 * kHalf + 1];
  int n_pre = 0;
  for (double h : cand)
    if (to_si(h) == best_si) pre[n_pre++] = h;
  if (n_pre == 1) return pre[0];
  double best_h = pre[0];
  size_t best_len = format_double(pre[0]).size();
  for (int i = 1; i < n_pre; ++i) {
    const size_t len = format_double(pre[i]).size();
    if (len < best_len || (len == best_len && pre[i] < best_h)) {
      best_h = pre[i];
      best_len = len;
    }
  }
  return best_h;
}

}  // namespace imucal::db::archive
