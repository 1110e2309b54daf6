#include "db/archive/io_util.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <system_error>

#include "db/archive/archive_error.hpp"

namespace imucal::archive {

namespace {
std::string os_reason(int err) { return std::strerror(err); }
}  // namespace

std::string read_text_file(const std::string& path) {
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
  std::string out;
  out.resize(static_cast<size_t>(st.st_size));
  size_t got = 0;
  for (;;) {
    if (got == out.size()) out.resize(out.size() + 65536);  // file grew or st_size was 0 (pipes)
    const ssize_t n = ::read(fd, &out[got], out.size() - got);
    if (n < 0) {
      if (errno == EINTR) continue;
      const int e = errno;
      ::close(fd);
      throw ArchiveError(path, "read error: " + os_reason(e));
    }
    if (n == 0) break;
    got += static_cast<size_t>(n);
  }
  ::close(fd);
  out.resize(got);
  return out;
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

}  // namespace imucal::archive
