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
  if (t < earliest_served_ms()) {
    note += field + " " + text + " is before the earliest date served; 1900-01-01 is used. ";
    return earliest_served_ms();
  }
  if (t > latest_served_ms()) {
    note += field + " " + text + " is after the latest date served; 2999-12-31 is used. ";
    return latest_served_ms();
  }
  return t;
}

std::string clamped_date_text(const std::string& field, const std::string& text, bool end,
                              std::string& notes) {
  if (text.empty()) return text;
  std::string note;
  window_time(field, text, end, note);
  if (note.empty()) return text;
  notes += note;
  return end ? "2999-12-31" : "1900-01-01";
}

std::string window_time_text(db::history::TimestampMs t_ms) { return short_time(t_ms); }

}  // namespace imucal::tools::stationweb
