#include "drivers/imu/candump_log.hpp"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <limits>
#include <utility>

namespace imucal::drivers::imu {
namespace {

constexpr char kHex[] = "0123456789ABCDEF";

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  return -1;
}

void put_hex(std::string& s, uint32_t v, int digits) {
  for (int i = digits - 1; i >= 0; --i) s.push_back(kHex[(v >> (4 * i)) & 0xF]);
}

std::string sys_error(const std::string& what, const std::string& path) {
  return what + " " + path + ": " + std::strerror(errno);
}

/// Splits off the next space-separated token (tabs count as spaces).
std::string_view next_token(std::string_view& rest) {
  std::size_t i = 0;
  while (i < rest.size() && (rest[i] == ' ' || rest[i] == '\t')) ++i;
  std::size_t j = i;
  while (j < rest.size() && rest[j] != ' ' && rest[j] != '\t') ++j;
  const std::string_view tok = rest.substr(i, j - i);
  rest.remove_prefix(j);
  return tok;
}

}  // namespace

CandumpParseError::CandumpParseError(std::string file, std::size_t line, const std::string& reason)
    : std::runtime_error(file + ":" + (line ? std::to_string(line) + ":" : std::string()) + " " +
                         reason),
      file_(std::move(file)),
      line_(line) {}

std::string format_candump_line(const ReceivedFrame& rf, std::string_view interface) {
  const CanFrame& f = rf.frame;
  if (rf.rx_time_ns < 0) throw std::invalid_argument("candump line: negative timestamp");
  if (interface.empty() || interface.find_first_of(" \t\n") != std::string_view::npos)
    throw std::invalid_argument("candump line: interface name '" + std::string(interface) +
                                "' is empty or contains white space");
  if (f.len > kCanMaxDataLength)
    throw std::invalid_argument("candump line: data length " + std::to_string(f.len) + " > 8");
  std::string s;
  s.reserve(48 + interface.size());
  char ts[40];
  std::snprintf(ts, sizeof ts, "(%010lld.%06lld) ",
                static_cast<long long>(rf.rx_time_ns / 1000000000),
                static_cast<long long>((rf.rx_time_ns % 1000000000) / 1000));
  s += ts;
  s += interface;
  s.push_back(' ');
  if (f.is_error())
    put_hex(s, f.can_id & (kCanErrFlag | kCanEffMask), 8);  // as can-utils: ERR flag kept, 8 digits
  else if (f.is_extended())
    put_hex(s, f.can_id & kCanEffMask, 8);
  else
    put_hex(s, f.can_id & kCanSffMask, 3);
  s.push_back('#');
  if (f.is_remote() && !f.is_error()) {
    s.push_back('R');
    if (f.len > 0) s.push_back(kHex[f.len]);
  } else {
    for (uint8_t i = 0; i < f.len; ++i) put_hex(s, f.data[i], 2);
  }
  return s;
}

CandumpRecord parse_candump_line(std::string_view line) {
  auto fail = [](const std::string& why) { throw std::invalid_argument(why); };
  while (!line.empty() && (line.back() == '\r' || line.back() == ' ' || line.back() == '\t'))
    line.remove_suffix(1);
  std::string_view rest = line;
  const std::string_view ts = next_token(rest);
  if (ts.size() < 4 || ts.front() != '(' || ts.back() != ')')
    fail("expected a timestamp '(seconds.microseconds)', got '" + std::string(ts) + "'");
  const std::string_view num = ts.substr(1, ts.size() - 2);
  const std::size_t dot = num.find('.');
  if (dot == std::string_view::npos || dot == 0 || dot + 1 == num.size())
    fail("timestamp '" + std::string(ts) + "' is not 'seconds.fraction'");
  if (dot > 12) fail("timestamp '" + std::string(ts) + "' has too many digits");
  int64_t sec = 0, frac_ns = 0;
  for (std::size_t i = 0; i < dot; ++i) {
    if (num[i] < '0' || num[i] > '9') fail("timestamp '" + std::string(ts) + "' is not a number");
    sec = sec * 10 + (num[i] - '0');
  }
  // Nanoseconds in int64 reach year 2262: a later time is not a capture (found by fuzzing).
  if (sec > std::numeric_limits<int64_t>::max() / 1000000000 - 1)
    fail("timestamp '" + std::string(ts) + "' is out of range (after the year 2262)");
  const std::size_t nfrac = num.size() - dot - 1;
  if (nfrac > 9) fail("timestamp '" + std::string(ts) + "' has more than 9 fraction digits");
  for (std::size_t i = 0; i < 9; ++i) {
    int digit = 0;
    if (i < nfrac) {
      const char c = num[dot + 1 + i];
      if (c < '0' || c > '9') fail("timestamp '" + std::string(ts) + "' is not a number");
      digit = c - '0';
    }
    frac_ns = frac_ns * 10 + digit;
  }
  CandumpRecord rec;
  rec.frame.rx_time_ns = sec * 1000000000 + frac_ns;
  const std::string_view iface = next_token(rest);
  if (iface.empty()) fail("missing interface name after the timestamp");
  rec.interface = std::string(iface);
  const std::string_view frame = next_token(rest);
  if (frame.empty()) fail("missing frame 'ID#DATA' after the interface name");
  const std::string_view extra = next_token(rest);
  if (!extra.empty() && extra != "R" && extra != "T")
    fail("unexpected text '" + std::string(extra) + "' after the frame (only R or T allowed)");
  if (!next_token(rest).empty()) fail("unexpected text after the frame");

  const std::size_t hash = frame.find('#');
  if (hash == std::string_view::npos) fail("frame '" + std::string(frame) + "' has no '#'");
  const std::string_view id_text = frame.substr(0, hash);
  std::string_view data = frame.substr(hash + 1);
  if (id_text.size() != 3 && id_text.size() != 8)
    fail("identifier '" + std::string(id_text) +
         "' must have 3 (standard) or 8 (extended) hex digits");
  uint32_t id = 0;
  for (char c : id_text) {
    const int v = hex_value(c);
    if (v < 0) fail("identifier '" + std::string(id_text) + "' is not hexadecimal");
    id = (id << 4) | static_cast<uint32_t>(v);
  }
  CanFrame& f = rec.frame.frame;
  if (id_text.size() == 3) {
    if (id > kCanSffMask) fail("standard identifier '" + std::string(id_text) + "' exceeds 0x7FF");
    f.can_id = id;
  } else {
    if (id & (kCanEffFlag | kCanRtrFlag))
      fail("extended identifier '" + std::string(id_text) + "' exceeds 0x1FFFFFFF");
    f.can_id = (id & kCanErrFlag) ? id : (id | kCanEffFlag);  // as can-utils' parse_canframe
  }
  if (!data.empty() && data.front() == '#')
    fail("CAN FD frame '" + std::string(frame) + "' is not supported (classic CAN only)");
  if (!data.empty() && (data.front() == 'R' || data.front() == 'r')) {
    if (f.is_error()) fail("an error frame cannot be a remote frame");
    f.can_id |= kCanRtrFlag;
    if (data.size() == 2 && data[1] >= '0' && data[1] <= '8')
      f.len = static_cast<uint8_t>(data[1] - '0');
    else if (data.size() != 1)
      fail("remote frame '" + std::string(frame) + "' must be 'ID#R' or 'ID#R' + DLC digit 0-8");
    return rec;
  }
  uint8_t n = 0;
  while (!data.empty()) {
    if (data.front() == '.') {  // optional byte separator (can-utils' parse_canframe accepts it)
      data.remove_prefix(1);
      continue;
    }
    if (data.size() < 2)
      fail("data '" + std::string(frame.substr(hash + 1)) + "' has an odd number of hex digits");
    const int hi = hex_value(data[0]), lo = hex_value(data[1]);
    if (hi < 0 || lo < 0)
      fail("data '" + std::string(frame.substr(hash + 1)) + "' is not hexadecimal");
    if (n == kCanMaxDataLength)
      fail("frame '" + std::string(frame) + "' has more than 8 data bytes");
    f.data[n++] = static_cast<uint8_t>((hi << 4) | lo);
    data.remove_prefix(2);
  }
  f.len = n;  // error frames: candump writes 8 bytes, python-can none; both are accepted
  return rec;
}

// ------------------------------------------------------------------------------------------ reader

CandumpReader::CandumpReader(const std::string& path) : path_(path) {
  file_ = std::fopen(path.c_str(), "re");
  if (!file_) throw CandumpParseError(path, 0, std::string("cannot open: ") + std::strerror(errno));
}

CandumpReader::~CandumpReader() {
  if (file_) std::fclose(file_);
}

int CandumpReader::fd() const { return ::fileno(file_); }

bool CandumpReader::next(CandumpRecord& record) {
  for (;;) {
    line_.clear();
    int c;
    bool newline = false;
    while ((c = std::getc(file_)) != EOF) {
      if (c == '\n') {
        newline = true;
        break;
      }
      line_.push_back(static_cast<char>(c));
    }
    if (std::ferror(file_))
      throw CandumpParseError(path_, line_no_ + 1,
                              std::string("read error: ") + std::strerror(errno));
    if (!newline && line_.empty()) return false;
    ++line_no_;
    if (line_.find_first_not_of(" \t\r") == std::string::npos) continue;
    try {
      record = parse_candump_line(line_);
      return true;
    } catch (const std::invalid_argument& e) {
      if (!newline) {  // unterminated last line: the writer died mid-line
        ++truncated_;
        return false;
      }
      throw CandumpParseError(path_, line_no_, e.what());
    }
  }
}

// ------------------------------------------------------------------------------------------ writer

CandumpWriter::CandumpWriter(const std::string& path, bool append) : path_(path) {
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_CLOEXEC | (append ? O_APPEND : O_TRUNC), 0644);
  if (fd_ < 0) throw std::runtime_error(sys_error("cannot create candump log", path));
  buffer_.reserve(1 << 16);
}

CandumpWriter::~CandumpWriter() {
  if (fd_ >= 0) {
    try {
      flush();
    } catch (const std::exception&) {
      // Destructors must not throw; close() reports errors to callers that care.
    }
    ::close(fd_);
  }
}

void CandumpWriter::write(const ReceivedFrame& frame, std::string_view interface) {
  if (fd_ < 0) throw std::runtime_error("candump log " + path_ + ": write after close");
  buffer_ += format_candump_line(frame, interface);
  buffer_.push_back('\n');
  ++frames_;
  if (buffer_.size() >= (1 << 16) - 64) flush();
}

void CandumpWriter::flush() {
  std::size_t off = 0;
  while (off < buffer_.size()) {
    const ssize_t n = ::write(fd_, buffer_.data() + off, buffer_.size() - off);
    if (n < 0) {
      if (errno == EINTR) continue;
      const std::string msg = sys_error("cannot write candump log", path_);
      buffer_.erase(0, off);
      throw std::runtime_error(msg);
    }
    off += static_cast<std::size_t>(n);
  }
  buffer_.clear();
}

void CandumpWriter::sync() {
  flush();
  if (::fdatasync(fd_) != 0) throw std::runtime_error(sys_error("cannot sync candump log", path_));
}

void CandumpWriter::close() {
  if (fd_ < 0) return;
  sync();
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) throw std::runtime_error(sys_error("cannot close candump log", path_));
}

}  // namespace imucal::drivers::imu
