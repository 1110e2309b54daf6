#pragma once
// The bounds every stationweb page keeps (issue #52 items 4 and 5): the dates a window may name,
// the periods, rows and bytes one response may hold. A request beyond them is answered at once —
// clamped with a sentence that names the limit, or refused naming the field — never by a page of
// half a gigabyte after forty seconds.
#include <cstddef>
#include <cstdint>
#include <string>

#include "db/history/repository.hpp"

namespace imucal::tools::stationweb {

/// The dates a window may name: 1900-01-01 (a history may hold clock-reset runs before 1970) to
/// the end of 2999-12-31; 0001-01-01 or 9999-12-31 is clamped to them, with a note.
db::history::TimestampMs earliest_served_ms();
db::history::TimestampMs latest_served_ms();  ///< 3000-01-01T00:00Z, exclusive

/// A signature trend shows at most this many periods (a year of days), the newest up to `until`.
inline constexpr std::int64_t kMaxTrendPeriods = 366;
/// A signature page or trend reads at most this many factory runs (their AINS results in memory).
inline constexpr std::int64_t kMaxSignatureRuns = 200000;
/// No response body is larger: a page that would be is replaced by a message naming the limit.
inline constexpr std::size_t kMaxPageBytes = 8u << 20;

/// A since/until text as a time: a date-only `until` means the end of that day; outside the
/// served dates it is clamped and `note` says so ("until 9999-12-31 is after the latest date
/// served; 2999-12-31 is used"). 400 naming `field` for unreadable text.
db::history::TimestampMs window_time(const std::string& field, const std::string& text, bool end,
                                     std::string& note);

/// The text to hand to a window parser that reads dates itself (tools/report's signature_window):
/// `text` unchanged within the served dates, else the clamped date ("1900-01-01", "2999-12-31"),
/// the note appended to `notes`. 400 naming `field` for unreadable text.
std::string clamped_date_text(const std::string& field, const std::string& text, bool end,
                              std::string& notes);

/// "2999-12-31 24:00" style texts never appear: the window's ends as "YYYY-MM-DD HH:MM:SS".
std::string window_time_text(db::history::TimestampMs t_ms);

}  // namespace imucal::tools::stationweb
