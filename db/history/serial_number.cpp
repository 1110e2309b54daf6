#include "db/history/serial_number.hpp"

#include <cstdio>

#include "db/history/repository.hpp"

namespace imucal::db::history {

const char* const kSerialRule =
    "a serial number has 1 to 32 characters, only ASCII letters, digits, '-', '_' and '.', "
    "starts with a letter or digit, and has a letter or digit after each '-', '_' or '.'";

namespace {

bool is_alnum_ascii(unsigned char c) {
  return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9');
}

/// Printable description of one byte for the message: 'x', "space", or a hex code.
std::string describe_byte(unsigned char c) {
  char buf[40];
  if (c == ' ') return "a space";
  if (c == '/') return "'/' (path separator)";
  if (c < 0x20 || c == 0x7f) {
    std::snprintf(buf, sizeof buf, "control character 0x%02x", c);
    return buf;
  }
  if (c >= 0x80) {
    std::snprintf(buf, sizeof buf, "non-ASCII byte 0x%02x", c);
    return buf;
  }
  std::snprintf(buf, sizeof buf, "'%c'", c);
  return buf;
}

/// The serial quoted for a message, with unprintable bytes escaped (never echo a raw control
/// character to a terminal or log).
std::string quoted(const std::string& s) {
  std::string out = "\"";
  const std::size_t shown = s.size() > 64 ? 64 : s.size();
  for (std::size_t i = 0; i < shown; ++i) {
    const unsigned char c = static_cast<unsigned char>(s[i]);
    if (c < 0x20 || c >= 0x7f || c == '"' || c == '\\') {
      char buf[8];
      std::snprintf(buf, sizeof buf, "\\x%02x", c);
      out += buf;
    } else {
      out += static_cast<char>(c);
    }
  }
  if (shown < s.size()) out += "...";
  return out + "\"";
}

}  // namespace

std::optional<std::string> serial_problem(const std::string& serial) {
  const std::string head = "serial number " + quoted(serial) + ": ";
  const std::string tail = std::string(" (") + kSerialRule + ")";
  if (serial.empty()) return "serial number is empty" + tail;
  if (serial.size() > kSerialMaxLength)
    return head + "too long: " + std::to_string(serial.size()) + " characters, at most " +
           std::to_string(kSerialMaxLength) + " allowed" + tail;
  for (std::size_t i = 0; i < serial.size(); ++i) {
    const unsigned char c = static_cast<unsigned char>(serial[i]);
    const bool ok = is_alnum_ascii(c) || c == '-' || c == '_' || c == '.';
    if (!ok)
      return head + describe_byte(c) + " at position " + std::to_string(i + 1) + " is not allowed" +
             tail;
  }
  if (!is_alnum_ascii(static_cast<unsigned char>(serial[0])))
    return head + "must start with a letter or digit, not '" + serial.substr(0, 1) + "'" + tail;
  // Only separators are left to check (the alphabet held above): each needs a letter or digit
  // after it.
  for (std::size_t i = 1; i < serial.size(); ++i)
    if (!is_alnum_ascii(static_cast<unsigned char>(serial[i - 1])) &&
        !is_alnum_ascii(static_cast<unsigned char>(serial[i])))
      return head + "'" + serial.substr(i - 1, 2) + "' at position " + std::to_string(i) +
             ": a letter or digit must follow each '-', '_' or '.'" + tail;
  if (!is_alnum_ascii(static_cast<unsigned char>(serial.back())))
    return head + "ends with '" + serial.substr(serial.size() - 1) +
           "': a letter or digit must follow each '-', '_' or '.'" + tail;
  return std::nullopt;
}

void validate_serial(const std::string& serial) {
  if (auto problem = serial_problem(serial)) throw InvalidInput(*problem);
}

std::string did_you_mean(const std::vector<std::string>& serials) {
  if (serials.empty()) return "";
  std::string names;
  for (std::size_t i = 0; i < serials.size(); ++i) names += (i == 0 ? "" : " or ") + serials[i];
  return "; did you mean " + names + "? (serial numbers are compared exactly, case included)";
}

}  // namespace imucal::db::history
