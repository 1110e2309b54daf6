#pragma once
// The pieces every stationweb page is made of: the page frame (HTML5, inline CSS, no script, no
// external resource — not even a favicon request), escaping, number and time formatting, and the
// error a page throws for bad input or an unknown record (the server turns it into 400/404).
//
// Numbers a test or a script may read off a page are also written in full precision into data
// attributes (`data-si="%.17g"`, SI units as stored): the text shows human units.
#include <stdexcept>
#include <string>

#include "db/history/repository.hpp"

namespace imucal::tools::stationweb {

/// A page's refusal: HTTP status (400 bad input, 404 no such record), the query or path field it
/// is about ("" when none), and a message for people.
struct PageError : std::runtime_error {
  PageError(int status_code, std::string field_name, const std::string& message)
      : std::runtime_error(message), status(status_code), field(std::move(field_name)) {}
  int status;
  std::string field;
};

/// 400 naming the field: "<field>: <message>".
[[noreturn]] void bad_input(const std::string& field, const std::string& message);

/// HTML/attribute escaping (the five markup characters).
std::string esc(const std::string& text);
/// printf-style formatting of one number.
std::string fmt(const char* format, double value);
/// Full precision for data attributes: the shortest "%.17g" text.
std::string exact(double value);
/// "2024-05-01 12:34:56" (UTC, no milliseconds) of a time.
std::string short_time(db::history::TimestampMs t_ms);
/// "2024-05-01" of a time (its UTC day).
std::string utc_date(db::history::TimestampMs t_ms);
/// The ISO text of a UTC day number (db::history::utc_day): "2024-05-01".
std::string day_text(std::int64_t day);
/// Percent-encoding of a query value (RFC 3986 unreserved characters kept).
std::string url_encode(const std::string& value);

/// `value` to the decimal place of its 1-σ's second significant digit (issue #52 item 12: no
/// fixed three decimals whatever the size); "%.4g" when σ is 0 or not finite.
std::string fmt_to_sigma(double value, double sigma);
/// fmt_to_sigma for a difference or any signed figure: "+1.23" / "-1.23" with `plus` (no sign
/// otherwise), and a value that rounds to zero at that precision is "0.0…" with no sign (never
/// "-0.0" nor "+0": issue #52 item 12).
std::string fmt_signed_to_sigma(double value, double sigma, bool plus = false);
/// A 1-σ (or any spread) to two significant digits, without an exponent within 1e-6..1e7.
std::string fmt_sigma(double sigma);
/// "1 run", "3 runs": the count and the noun, plural unless one.
std::string count_of(std::int64_t n, const std::string& noun);
/// A notice for the top of a rendered page (after the navigation bar): `page_html` with
/// <p id='notice' class='alarm'>text</p> inserted; unchanged when `text` is empty or the body is
/// no page (no navigation bar: a download).
std::string with_notice(std::string page_html, const std::string& text);

/// <a href='/run/ID'>ID</a> and <a href='/unit/SN'>SN</a>.
std::string run_link(db::history::RunId id);
std::string unit_link(const std::string& serial);

/// The whole document: <title>, the navigation bar (index, fleet, serial search) and `body`.
std::string page(const std::string& title, const std::string& body);
/// An error page: the status line as heading, the message in <p id='error'> with data-status and
/// data-field.
std::string error_page(int status, const std::string& reason, const std::string& field,
                       const std::string& message);

}  // namespace imucal::tools::stationweb
