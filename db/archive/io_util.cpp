#include "db/archive/io_util.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <system_error>
#include <utility>

#include "db/archive/archive_error.hpp"

namespace imucal::db::archive {

namespace {

std::string os_reason(int err) { return std::strerror(err); }

// Opens a file for reading; its size as stat reports it (0 for pipes and /proc files).
int open_for_reading(const std::string& path, std::size_t& size_bytes, bool* regular = nullptr) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) throw ArchiveError(path, "cannot open: " + os_reason(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int e = errno;
    ::close(fd);
    throw ArchiveError(path, "cannot stat: " + os_reason(e));
  }
  if (S_ISDIR(st.st_mode)) {
    ::close(fd);
    throw ArchiveError(path, "is a directory, expected a file");
  }
  size_bytes = static_cast<std::size_t>(st.st_size);
  if (regular) *regular = S_ISREG(st.st_mode);
  return fd;
}

// read(2) into buf[got, capacity) until it is full or at EOF; returns the new fill level.
std::size_t read_some(int fd, const std::string& path, char* buf, std::size_t got,
                      std::size_t capacity) {
  while (got < capacity) {
    const ssize_t n = ::read(fd, buf + got, capacity - got);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw ArchiveError(path, "read error: " + os_reason(errno));
    }
    if (n == 0) break;
    got += static_cast<std::size_t>(n);
  }
  return got;
}

}  // namespace

std::string read_text_file(const std::string& path) {
  // The small files (run.toml, JSON): one copy of read_file_bytes' buffer is nothing next to the
  // read, and the growth loop for pipes and /proc files stays in one place.
  return std::string(read_file_bytes(path).view());
}

ReadableFile::ReadableFile(const std::string& path) : path_(path) {
  std::size_t size_bytes = 0;
  bool regular = false;
  fd_ = open_for_reading(path, size_bytes, &regular);
  size_ = regular ? size_bytes : 0;
}

ReadableFile::~ReadableFile() { ::close(fd_); }

FileBytes ReadableFile::read_all() const {
  // new char[] leaves the bytes uninitialised: read(2) is the only write. One byte more than stat
  // says, so that a file that grew shows up as a full buffer.
  std::size_t capacity = size_ + 1;
  std::unique_ptr<char[]> buf(new char[capacity]);
  std::size_t got = 0;
  for (;;) {
    got = read_some(fd_, path_, buf.get(), got, capacity);
    if (got < capacity) break;  // EOF
    // File grew or reported no size (pipes): grow geometrically and read on.
    const std::size_t bigger = capacity * 2 + 65536;
    std::unique_ptr<char[]> grown(new char[bigger]);
    std::memcpy(grown.get(), buf.get(), got);
    buf = std::move(grown);
    capacity = bigger;
  }
  FileBytes out;
  out.data_ = std::move(buf);
  out.size_ = got;
  return out;
}

FileBytes read_file_bytes(const std::string& path) { return ReadableFile(path).read_all(); }

void ReadableFile::read_at(std::size_t offset, char* buf, std::size_t n) const {
  while (n > 0) {
    const ssize_t got = ::pread(fd_, buf, n, static_cast<off_t>(offset));
    if (got < 0) {
      if (errno == EINTR) continue;
      throw ArchiveError(path_, "read error: " + os_reason(errno));
    }
    if (got == 0) throw ArchiveError(path_, "read error: the file shrank while it was being read");
    buf += got;
    offset += static_cast<std::size_t>(got);
    n -= static_cast<std::size_t>(got);
  }
}

DurableFile::DurableFile(std::string path, bool overwrite) : path_(std::move(path)) {
  const int flags = O_WRONLY | O_CREAT | O_CLOEXEC | (overwrite ? O_TRUNC : O_EXCL);
  fd_ = ::open(path_.c_str(), flags, 0644);
  if (fd_ < 0) throw ArchiveError(path_, "cannot create: " + os_reason(errno));
  buf_.reserve(kFlushBytes + 4096);
}

DurableFile::~DurableFile() {
  if (fd_ >= 0) ::close(fd_);
}

void DurableFile::append(std::string_view bytes) {
  buf_.append(bytes);
  maybe_flush();
}

void DurableFile::flush() {
  if (fd_ < 0) throw ArchiveError(path_, "write after close");
  const char* p = buf_.data();
  size_t left = buf_.size();
  while (left > 0) {
    const ssize_t n = ::write(fd_, p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      throw ArchiveError(path_, "write error: " + os_reason(errno));
    }
    p += n;
    left -= static_cast<size_t>(n);
  }
  buf_.clear();
}

void DurableFile::close() {
  flush();
  if (::fsync(fd_) != 0) throw ArchiveError(path_, "fsync failed: " + os_reason(errno));
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) throw ArchiveError(path_, "close failed: " + os_reason(errno));
}

void write_file_durable(const std::string& path, std::string_view content, bool overwrite) {
  DurableFile f(path, overwrite);
  f.append(content);
  f.close();
}

void write_file_atomic(const std::string& path, std::string_view content) {
  std::string tmpl = path + ".tmp-XXXXXX";
  const int fd = ::mkstemp(tmpl.data());
  if (fd < 0) throw ArchiveError(path, "cannot create temporary file: " + os_reason(errno));
  ::fchmod(fd, 0644);  // mkstemp creates 0600; archive files are world-readable like any other
  ::close(fd);
  try {
    write_file_durable(tmpl, content, /*overwrite=*/true);
    if (::rename(tmpl.c_str(), path.c_str()) != 0)
      throw ArchiveError(path, "cannot rename temporary file into place: " + os_reason(errno));
  } catch (...) {
    ::unlink(tmpl.c_str());
    throw;
  }
  const size_t slash = path.find_last_of('/');
  fsync_directory(slash == std::string::npos ? "." : (slash == 0 ? "/" : path.substr(0, slash)));
}

void fsync_directory(const std::string& dir) {
  const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (fd < 0) throw ArchiveError(dir, "cannot open directory for fsync: " + os_reason(errno));
  const int rc = ::fsync(fd);
  const int e = errno;
  ::close(fd);
  if (rc != 0) throw ArchiveError(dir, "directory fsync failed: " + os_reason(e));
}

void append_double(std::string& out, double v) {
  char buf[32];
  const auto res = std::to_chars(buf, buf + sizeof buf, v);  // shortest round-trip form
  out.append(buf, res.ptr);
}

std::string format_double(double v) {
  std::string s;
  append_double(s, v);
  return s;
}

}  // namespace imucal::db::archive
