#pragma once
// The SVG building blocks of imucal's pictures (calibration_svg, the gap budget's per-IMU plot):
// a panel with a linear y axis and n slots along x, its frame and grid, bars, dots and lines.
// Plain SVG, no plotting library.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <string>

#include "tools/report/html_escape.hpp"

namespace imucal::tools::report {

inline constexpr double kWidth = 960, kPanelH = 230, kLeft = 70, kRight = 20, kTop = 50;

inline std::string num(double v, const char* f = "%.1f") {
  char b[48];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

inline std::string esc(const std::string& s) { return html_escape(s); }

/// Widens [lo, hi] to four intervals of a round step (1, 2 or 5 × 10^k) from a multiple of it, so
/// that the five tick labels of Panel::frame are round numbers. An empty range grows around it.
inline void round_range(double& lo, double& hi) {
  if (!std::isfinite(lo) || !std::isfinite(hi)) return;
  if (!(hi > lo)) {
    const double pad = lo != 0 ? std::abs(lo) * 0.1 : 1.0;
    lo -= pad;
    hi += pad;
  }
  const double magnitude = std::pow(10.0, std::floor(std::log10((hi - lo) / 4.0)));
  for (double m : {1.0, 2.0, 5.0, 10.0, 20.0}) {
    const double step = m * magnitude, start = std::floor(lo / step) * step;
    if (start + 4 * step >= hi) {
      lo = start;
      hi = start + 4 * step;
      return;
    }
  }
}

/// One panel: y axis from -ymax..ymax (symmetric) or 0..ymax, n slots along x.
struct Panel {
  std::ostringstream& os;
  double y0;  ///< top of the panel in page coordinates
  double ymin, ymax;
  size_t n;
  double x(size_t i) const {
    return kLeft +
           (kWidth - kLeft - kRight) * (static_cast<double>(i) + 0.5) / static_cast<double>(n);
  }
  double slot() const { return (kWidth - kLeft - kRight) / static_cast<double>(n); }
  double y(double v) const {
    const double c = std::clamp(v, ymin, ymax);
    return y0 + kPanelH * (ymax - c) / (ymax - ymin);
  }
  /// Decimals of the y tick labels: none from a span of 10 up, else at least 2 and enough that
  /// the five labels of a narrow span (0.004 deg/h) differ.
  int tick_decimals() const {
    const double span = std::abs(ymax - ymin);
    if (span >= 10) return 0;
    const double step = span / 4.0;
    if (!(step > 0) || !std::isfinite(step)) return 2;
    return std::clamp(static_cast<int>(-std::floor(std::log10(step))), 2, 12);
  }
  void frame(const std::string& title, const std::string& ylabel) {
    os << "<text x='" << kLeft << "' y='" << y0 - 8 << "' font-weight='bold'>" << esc(title)
       << "</text>\n";
    os << "<rect x='" << kLeft << "' y='" << y0 << "' width='" << kWidth - kLeft - kRight
       << "' height='" << kPanelH << "' fill='none' stroke='#888'/>\n";
    for (int t = 0; t <= 4; ++t) {
      double v = ymin + (ymax - ymin) * t / 4.0;
      if (std::abs(v) < 1e-9 * std::abs(ymax - ymin)) v = 0.0;  // no "-0.00" from rounding
      os << "<text x='" << kLeft - 6 << "' y='" << y(v) + 4 << "' text-anchor='end' font-size='11'>"
         << num(v, ("%." + std::to_string(tick_decimals()) + "f").c_str()) << "</text>\n";
      os << "<line x1='" << kLeft << "' x2='" << kWidth - kRight << "' y1='" << y(v) << "' y2='"
         << y(v) << "' stroke='#eee'/>\n";
    }
    os << "<text transform='translate(16," << y0 + kPanelH / 2 << ") rotate(-90)' "
       << "text-anchor='middle' font-size='12'>" << esc(ylabel) << "</text>\n";
  }
  void hline(double v, const char* color, const char* dash = "") {
    os << "<line x1='" << kLeft << "' x2='" << kWidth - kRight << "' y1='" << y(v) << "' y2='"
       << y(v) << "' stroke='" << color << "' stroke-dasharray='" << dash << "'/>\n";
  }
  void bar(size_t i, double v, double offset, double w, const char* color, const std::string& tip) {
    const double top = std::min(y(v), y(std::max(0.0, ymin))),
                 bottom = std::max(y(v), y(std::max(0.0, ymin)));
    os << "<rect x='" << x(i) + offset - w / 2 << "' y='" << top << "' width='" << w << "' height='"
       << std::max(bottom - top, 0.5) << "' fill='" << color << "'><title>" << esc(tip)
       << "</title></rect>\n";
  }
  /// A box from value `lo` to `hi` in slot i (a stacked bar's share, a quartile box), with a
  /// tooltip and extra attributes (e.g. data-* for scripts) written into the element.
  void span(size_t i, double lo, double hi, double offset, double w, const char* color,
            const std::string& tip, const std::string& attributes = "") {
    const double top = std::min(y(lo), y(hi)), bottom = std::max(y(lo), y(hi));
    os << "<rect x='" << x(i) + offset - w / 2 << "' y='" << top << "' width='" << w << "' height='"
       << std::max(bottom - top, 0.5) << "' fill='" << color << "' " << attributes << "><title>"
       << esc(tip) << "</title></rect>\n";
  }
  /// A dot in slot i, `offset` px from its centre, with a tooltip; `css_class` names its series.
  void dot(size_t i, double v, double offset, double r, const char* fill, const char* stroke,
           const char* css_class, const std::string& tip) {
    os << "<circle class='" << css_class << "' cx='" << x(i) + offset << "' cy='" << y(v) << "' r='"
       << r << "' fill='" << fill << "' stroke='" << stroke << "'><title>" << esc(tip)
       << "</title></circle>\n";
  }
  /// A short horizontal mark in slot i (a mean), `offset` px from its centre, `w` wide.
  void tick(size_t i, double v, double offset, double w, const char* color) {
    os << "<line x1='" << x(i) + offset - w / 2 << "' x2='" << x(i) + offset + w / 2 << "' y1='"
       << y(v) << "' y2='" << y(v) << "' stroke='" << color << "' stroke-width='3'/>\n";
  }
};

}  // namespace imucal::tools::report
