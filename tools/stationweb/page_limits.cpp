#include "tools/stationweb/page_limits.hpp"

#include "tools/stationweb/html.hpp"
#include "tools/stationweb/page_util.hpp"

namespace imucal::tools::stationweb {

db::history::TimestampMs earliest_served_ms() {
  static const db::history::TimestampMs t = db::history::parse_time_utc("1900-01-01");
  return t;
}

db::history::TimestampMs latest_served_ms() {
  // 2999-12-31 plus a day: format_time_utc writes four-digit years only.
  static const db::history::TimestampMs t = db::history::parse_time_utc("2999-12-31") + kDayMs;
  return t;
}

db::history::TimestampMs window_time(const std::string& field, const std::string& text, bool end,
                                     std::string& note) {
  db::history::TimestampMs t = 0;
  try {
    t = db::history::parse_time_utc(text);
  } catch (const db::history::InvalidInput& e) {
    bad_input(field, e.what());
  }
  // "until=2024-05-07" means up to the end of that day.
  if (end && text.size() == 10) t += kDayMs;
  // Clamped to the day the note names, read as this side reads a date: a start at its beginning,
  // an end at its end (issue #52 F12: "2999-12-31 is used" then "from 3000-01-01" no more).
  if (t < earliest_served_ms()) {
    note += field + " " + text + " is before the earliest date served; 1900-01-01 is used. ";
    return earliest_served_ms() + (end ? kDayMs : 0);
  }
  if (end ? t > latest_served_ms() : t >= latest_served_ms()) {
    note += field + " " + text + " is after the latest date served; 2999-12-31 is used. ";
    return latest_served_ms() - (end ? 0 : kDayMs);
  }
  return t;
}

std::string clamped_date_text(const std::string& field, const std::string& text, bool end,
                              std::string& notes) {
  if (text.empty()) return text;
  std::string note;
  const db::history::TimestampMs t = window_time(field, text, end, note);
  if (note.empty()) return text;
  notes += note;
  // The side it was clamped to (an until before 1900 is 1900-01-01, not 2999-12-31).
  return t <= earliest_served_ms() + kDayMs ? "1900-01-01" : "2999-12-31";
}

std::string window_time_text(db::history::TimestampMs t_ms) { return short_time(t_ms); }

}  // namespace imucal::tools::stationweb
