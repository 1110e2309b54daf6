#pragma once
// printf-style formatting of one value into a std::string, for the commands' human-readable
// tables (one definition: the commands' files are compiled together in a unity build).
#include <cstdio>
#include <string>

namespace imucal::tools::imucal {

/// `format` applied to `v` (at most 63 characters: a table cell).
inline std::string fmt(const char* format, double v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

/// `format` applied to the string `v` (at most 63 characters).
inline std::string fmt(const char* format, const char* v) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, v);
  return buf;
}

}  // namespace imucal::tools::imucal
