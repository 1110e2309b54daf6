#include "tools/stationctl/export_output.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <filesystem>
#include <streambuf>
#include <vector>

namespace imucal::tools::stationctl {

namespace fs = std::filesystem;

/// A write-only stream buffer over a file descriptor that keeps the errno of a failed write
/// (std::ofstream does not say why it failed).
class ExportOutput::FdBuf : public std::streambuf {
 public:
  explicit FdBuf(int fd) : fd_(fd), buf_(64 * 1024) {
    setp(buf_.data(), buf_.data() + buf_.size());
  }
  int error() const { return error_; }

 protected:
  int_type overflow(int_type ch) override {
    if (!drain()) return traits_type::eof();
    if (!traits_type::eq_int_type(ch, traits_type::eof())) {
      *pptr() = traits_type::to_char_type(ch);
      pbump(1);
    }
    return traits_type::not_eof(ch);
  }
  int sync() override { return drain() ? 0 : -1; }

 private:
  /// Writes the buffered bytes; false (errno kept) on an error.
  bool drain() {
    const char* p = pbase();
    while (p < pptr()) {
      const ssize_t n = ::write(fd_, p, static_cast<size_t>(pptr() - p));
      if (n < 0) {
        if (errno == EINTR) continue;
        error_ = errno;
        return false;
      }
      p += n;
    }
    setp(buf_.data(), buf_.data() + buf_.size());
    return true;
  }

  int fd_;
  std::vector<char> buf_;
  int error_ = 0;
};

namespace {

bool starts_with(const std::string& s, const char* prefix) { return s.rfind(prefix, 0) == 0; }

/// The final target of a chain of symbolic links (the path itself if it is none); a link's
/// relative target is taken from the link's directory, as the kernel does.
std::string follow_links(const std::string& path) {
  std::string p = path;
  for (int hops = 0;; ++hops) {
    struct stat l {};
    if (::lstat(p.c_str(), &l) != 0 || !S_ISLNK(l.st_mode)) return p;
    if (hops == 40) {
      errno = ELOOP;
      return "";
    }
    std::error_code ec;
    const fs::path t = fs::read_symlink(p, ec);
    if (ec) {
      errno = ec.value();
      return "";
    }
    p = (t.is_absolute() ? t : fs::path(p).parent_path() / t).string();
  }
}

/// The descriptor a path of the process's own standard streams names (/dev/stdout, /dev/fd/1,
/// /proc/self/fd/1, ...), or -1: written through a duplicate, so the shell's redirection (its
/// offset, its append mode) holds.
int own_stream_fd(const std::string& path) {
  if (path == "/dev/stdout") return 1;
  if (path == "/dev/stderr") return 2;
  for (const char* prefix : {"/dev/fd/", "/proc/self/fd/"}) {
    if (!starts_with(path, prefix)) continue;
    const std::string n = path.substr(std::strlen(prefix));
    if (n.empty() || n.find_first_not_of("0123456789") != std::string::npos) return -1;
    return std::stoi(n);
  }
  return -1;
}

mode_t current_umask() {
  const mode_t m = ::umask(0);
  ::umask(m);
  return m;
}

}  // namespace

void ExportOutput::fail(int err) const {
  throw ExportOutputError("cannot write " +
                          (path_.empty() ? std::string("standard output") : path_) + ": " +
                          std::strerror(err));
}

ExportOutput::ExportOutput(const std::string& path) : path_(path) {
  if (path_.empty()) {
    mode_ = Mode::kStdout;
    fd_ = 1;
  } else if (const int own = own_stream_fd(path_); own >= 0) {
    mode_ = Mode::kDirect;
    fd_ = ::fcntl(own, F_DUPFD_CLOEXEC, 3);
    if (fd_ < 0) fail(errno);
  } else {
    struct stat st {};
    const bool exists = ::stat(path_.c_str(), &st) == 0;
    if (!exists && errno != ENOENT) fail(errno);
    if (exists && S_ISDIR(st.st_mode))
      throw ExportOutputError("cannot write " + path_ + ": it is a directory (name a file in it)");
    if (exists && S_ISSOCK(st.st_mode))
      throw ExportOutputError("cannot write " + path_ + ": it is a socket");
    // A device or a pipe is written in place, never replaced; so is a new name under /proc (which
    // holds no files of ours: the open fails there, naming the path and the reason).
    if ((exists && !S_ISREG(st.st_mode)) || (!exists && starts_with(path_, "/proc/"))) {
      mode_ = Mode::kDirect;
      fd_ = ::open(path_.c_str(), O_WRONLY | O_CLOEXEC);
      if (fd_ < 0) fail(errno);
    } else {
      mode_ = Mode::kReplaceFile;
      target_ = follow_links(path_);
      if (target_.empty()) fail(errno);
      const fs::path t(target_);
      const fs::path dir = t.has_parent_path() ? t.parent_path() : fs::path(".");
      std::string templ = (dir / ("." + t.filename().string() + ".XXXXXX")).string();
      fd_ = ::mkostemp(templ.data(), O_CLOEXEC);
      if (fd_ < 0) fail(errno);
      tmp_ = templ;
      // The replacement keeps the old file's permissions (and owner, where allowed); a new file
      // gets what a shell redirection would give it.
      struct stat old {};
      if (exists && ::stat(target_.c_str(), &old) == 0) {
        (void)::fchown(fd_, old.st_uid, old.st_gid);
        if (::fchmod(fd_, old.st_mode & 07777) != 0) fail(errno);
      } else if (::fchmod(fd_, 0666 & ~current_umask()) != 0) {
        fail(errno);
      }
    }
  }
  buf_ = std::make_unique<FdBuf>(fd_);
  stream_ = std::make_unique<std::ostream>(buf_.get());
}

ExportOutput::~ExportOutput() {
  if (committed_) return;
  if (mode_ != Mode::kStdout && fd_ >= 0) ::close(fd_);
  if (!tmp_.empty()) ::unlink(tmp_.c_str());
}

std::ostream& ExportOutput::stream() { return *stream_; }

void ExportOutput::check() const {
  if (!*stream_) fail(buf_->error() ? buf_->error() : EIO);
}

void ExportOutput::write(std::string_view bytes) {
  stream_->write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  check();
}

void ExportOutput::commit() {
  stream_->flush();
  check();
  if (mode_ == Mode::kStdout) {
    committed_ = true;
    return;
  }
  // The content reaches the disk before the rename makes it the file's (a crash leaves the old
  // file or the new one, never a truncated one).
  if (mode_ == Mode::kReplaceFile && ::fsync(fd_) != 0) fail(errno);
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) {
    const int err = errno;
    if (!tmp_.empty()) ::unlink(tmp_.c_str());
    fail(err);
  }
  if (mode_ == Mode::kReplaceFile) {
    if (::rename(tmp_.c_str(), target_.c_str()) != 0) {
      const int err = errno;
      ::unlink(tmp_.c_str());
      fail(err);
    }
    tmp_.clear();
    const fs::path dir =
        fs::path(target_).has_parent_path() ? fs::path(target_).parent_path() : fs::path(".");
    const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dfd >= 0) {  // the rename itself made durable; best effort (some file systems refuse)
      (void)::fsync(dfd);
      ::close(dfd);
    }
  }
  committed_ = true;
}

}  // namespace imucal::tools::stationctl
