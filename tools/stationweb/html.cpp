#include "tools/stationweb/html.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include "tools/report/html_escape.hpp"
#include "tools/stationweb/page_util.hpp"

namespace imucal::tools::stationweb {

namespace {

// Plain, printable, and legible in a screenshot: system fonts, a table style, verdict colours.
constexpr const char* kStyle = R"(
body { font-family: sans-serif; margin: 0 24px 24px; color: #222; max-width: 1400px; }
nav { background: #f1f3f5; padding: 8px 12px; margin: 0 -24px 16px; border-bottom: 1px solid #ccc; }
nav a { margin-right: 16px; font-weight: bold; color: #1a4f8b; text-decoration: none; }
nav form { display: inline; float: right; }
h1 { font-size: 1.5em; } h2 { font-size: 1.2em; margin-top: 1.6em; }
table { border-collapse: collapse; margin: 8px 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 3px 8px; text-align: left; vertical-align: top; }
th { background: #f1f3f5; } td.num, th.num { text-align: right; font-variant-numeric: tabular-nums; }
.PASS { color: #176b2c; font-weight: bold; } .REVIEW { color: #a35d00; font-weight: bold; }
.FAILED { color: #b3261e; font-weight: bold; } .muted { color: #666; }
.STATION-FAULT { color: #7b4fa0; font-weight: bold; } .ABORTED, .INTERRUPTED { color: #555; }
.alarm { border-left: 4px solid #b3261e; background: #fdf1f0; padding: 2px 12px; margin: 8px 0; }
#error { font-size: 1.1em; padding: 12px; background: #fff4f4; border: 1px solid #e0a0a0; }
svg { display: block; margin: 8px 0; } pre { background: #f8f9fa; padding: 8px; overflow-x: auto; }
form.filters label { margin-right: 12px; }
)";

}  // namespace

void bad_input(const std::string& field, const std::string& message) {
  throw PageError(400, field, field + ": " + message);
}

std::string esc(const std::string& text) { return tools::report::html_escape(text); }

std::string fmt(const char* format, double value) {
  char buf[64];
  std::snprintf(buf, sizeof buf, format, value);
  return buf;
}

std::string exact(double value) { return fmt("%.17g", value); }

std::string short_time(db::history::TimestampMs t_ms) {
  std::string s = db::history::format_time_utc(t_ms).substr(0, 19);
  s[10] = ' ';
  return s;
}

std::string utc_date(db::history::TimestampMs t_ms) {
  return db::history::format_time_utc(t_ms).substr(0, 10);
}

std::string day_text(std::int64_t day) { return utc_date(day * kDayMs); }

std::string url_encode(const std::string& value) {
  std::string out;
  for (unsigned char c : value) {
    const bool plain = (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') ||
                       c == '-' || c == '_' || c == '.' || c == '~';
    if (plain) {
      out += static_cast<char>(c);
    } else {
      char buf[4];
      std::snprintf(buf, sizeof buf, "%%%02X", c);
      out += buf;
    }
  }
  return out;
}

namespace {

/// Decimal places that show `sigma`'s second significant digit (0..12).
int decimals_for(double sigma) {
  const int d = 1 - static_cast<int>(std::floor(std::log10(std::abs(sigma))));
  return std::max(0, std::min(12, d));
}

}  // namespace

std::string fmt_to_sigma(double value, double sigma) {
  if (!(sigma > 0) || !std::isfinite(sigma) || !std::isfinite(value)) return fmt("%.4g", value);
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.*f", decimals_for(sigma), value);
  return buf;
}

std::string fmt_signed_to_sigma(double value, double sigma, bool plus) {
  std::string s = fmt_to_sigma(value, sigma);
  if (!s.empty() && (s[0] == '-' || s[0] == '+')) s.erase(0, 1);
  if (std::strtod(s.c_str(), nullptr) == 0 || std::isnan(value)) return s;  // "0.0", not "-0.0"
  return (value < 0 ? "-" : plus ? "+" : "") + s;
}

std::string fmt_sigma(double sigma) {
  if (!(sigma > 0) || !std::isfinite(sigma)) return fmt("%.2g", sigma);
  const double a = std::abs(sigma);
  if (a < 1e-6 || a >= 1e7) return fmt("%.2g", sigma);
  return fmt_to_sigma(sigma, sigma);
}

std::string count_of(std::int64_t n, const std::string& noun) {
  return std::to_string(n) + " " + noun + (n == 1 ? "" : "s");
}

std::string with_notice(std::string page_html, const std::string& text) {
  if (text.empty()) return page_html;
  const std::string html = "<p id='notice' class='alarm'>" + esc(text) + "</p>\n";
  const std::size_t at = page_html.find("</nav>\n");
  if (at != std::string::npos) page_html.insert(at + 7, html);  // not a page: left as it is
  return page_html;
}

std::string run_link(db::history::RunId id) {
  return "<a href='/run/" + std::to_string(id) + "'>" + std::to_string(id) + "</a>";
}

std::string unit_link(const std::string& serial) {
  return "<a href='/unit/" + url_encode(serial) + "'>" + esc(serial) + "</a>";
}

std::string page(const std::string& title, const std::string& body) {
  std::string s;
  s.reserve(body.size() + 2048);
  s += "<!DOCTYPE html>\n<html lang='en'>\n<head>\n<meta charset='utf-8'>\n";
  s += "<meta name='viewport' content='width=device-width, initial-scale=1'>\n";
  s += "<link rel='icon' href='data:,'>\n";  // no favicon request (no 404 in the console)
  s += "<title>" + esc(title) + " · stationweb</title>\n<style>" + kStyle + "</style>\n</head>\n";
  s += "<body>\n<nav><a href='/'>Recent runs</a><a href='/fleet'>Fleet</a><a "
       "href='/signatures'>Station signatures</a>";
  s += "<form action='/unit' method='get'><label>Serial <input name='serial' size='18' "
       "required></label> <button type='submit'>Show unit</button></form></nav>\n";
  s += body;
  s += "\n</body>\n</html>\n";
  return s;
}

std::string error_page(int status, const std::string& reason, const std::string& field,
                       const std::string& message) {
  const std::string code = std::to_string(status);
  return page(code + " " + reason, "<h1>" + code + " " + esc(reason) +
                                       "</h1>\n<p id='error' data-status='" + code +
                                       "' data-field='" + esc(field) + "'>" + esc(message) +
                                       "</p>\n<p><a href='/'>Back to the recent runs</a></p>\n");
}

}  // namespace imucal::tools::stationweb
