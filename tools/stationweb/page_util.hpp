#pragma once
// Small helpers several of stationweb's pages share (one definition each: the pages' files are
// compiled together in a unity build).
#include <algorithm>
#include <cstdint>
#include <string>
#include <vector>

namespace imucal::tools::stationweb {

/// Milliseconds in a UTC day (the history's timestamps are milliseconds since the epoch).
inline constexpr std::int64_t kDayMs = 86400000;

/// Whether `name` is one of `names` (a parameter in a cross-check's lists).
inline bool listed(const std::vector<std::string>& names, const std::string& name) {
  return std::find(names.begin(), names.end(), name) != names.end();
}

}  // namespace imucal::tools::stationweb
