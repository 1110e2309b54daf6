#include "tools/stationweb/fleet_svg.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>

#include "tools/report/station_signatures.hpp"
#include "tools/report/svg_panel.hpp"
#include "tools/stationweb/html.hpp"

namespace imucal::tools::stationweb {

namespace {

using tools::report::kLeft;
using tools::report::kPanelH;
using tools::report::kRight;
using tools::report::kTop;
using tools::report::kWidth;
using tools::report::Panel;

constexpr const char* kStationColours[] = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                                           "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"};

constexpr const char* kVerdictNames[] = {"PASS",    "REVIEW",      "FAILED", "station fault",
                                         "aborted", "interrupted", "live"};
constexpr const char* kVerdictColours[] = {"#2ca02c", "#ff9f1c", "#d62728", "#7b4fa0",
                                           "#5b8fd9", "#8c6d31", "#aaaaaa"};
constexpr std::size_t kVerdictParts = sizeof kVerdictNames / sizeof kVerdictNames[0];

std::string svg_open(const char* id, double height) {
  std::ostringstream os;
  os << "<svg id='" << id << "' xmlns='http://www.w3.org/2000/svg' width='" << kWidth
     << "' height='" << height << "' viewBox='0 0 " << kWidth << ' ' << height
     << "' font-family='sans-serif'>\n";
  return os.str();
}

/// Labels under their slots: every `every`-th (a year of daily periods would smear 366 labels into
/// one band: issue #52 item 5), rotated when more than eight are shown.
void slot_labels(std::ostringstream& os, const Panel& p, const std::vector<std::string>& labels,
                 std::size_t every = 1) {
  const bool rotate = (labels.size() + every - 1) / every > 8;
  for (std::size_t i = 0; i < labels.size(); i += every) {
    const double x = p.x(i), y = kTop + kPanelH + 14;
    if (rotate)
      os << "<text transform='translate(" << x + 3 << ',' << y - 6
         << ") rotate(60)' font-size='11'>" << esc(labels[i]) << "</text>\n";
    else
      os << "<text x='" << x << "' y='" << y << "' text-anchor='middle' font-size='11'>"
         << esc(labels[i]) << "</text>\n";
  }
}

void station_legend(std::ostringstream& os, const std::vector<std::string>& stations) {
  double x = kLeft;
  const double y = kTop + kPanelH + 78;
  for (std::size_t k = 0; k < stations.size(); ++k) {
    os << "<rect x='" << x << "' y='" << y - 10 << "' width='10' height='10' fill='"
       << station_colour(k) << "'/><text x='" << x + 13 << "' y='" << y << "' font-size='11'>"
       << esc(stations[k]) << "</text>\n";
    x += 24 + 7.0 * static_cast<double>(stations[k].size());
  }
}

}  // namespace

const char* station_colour(std::size_t index) {
  return kStationColours[index % (sizeof kStationColours / sizeof *kStationColours)];
}

std::string runs_chart(const std::vector<db::history::StationDayCount>& counts,
                       const std::vector<std::string>& stations, std::int64_t first_day,
                       std::int64_t last_day) {
  const auto n_days = static_cast<std::size_t>(std::max<std::int64_t>(last_day - first_day + 1, 1));
  std::vector<double> total(n_days, 0.0);
  for (const auto& c : counts)
    if (c.day >= first_day && c.day <= last_day)
      total[static_cast<std::size_t>(c.day - first_day)] += static_cast<double>(c.runs);
  double bottom = 0, top = std::max(10.0, *std::max_element(total.begin(), total.end()));
  tools::report::round_range(bottom, top);
  std::ostringstream os;
  os << svg_open("runs-chart", kTop + kPanelH + 96);
  Panel p{os, kTop, bottom, top, n_days};
  p.frame("Runs per UTC day, stacked by station", "runs");
  std::map<std::string, std::size_t> colour_of;
  for (std::size_t k = 0; k < stations.size(); ++k) colour_of[stations[k]] = k;
  std::vector<double> stacked(n_days, 0.0);
  for (const auto& c : counts) {  // sorted by station, then day: stations stack in legend order
    if (c.day < first_day || c.day > last_day) continue;
    const auto i = static_cast<std::size_t>(c.day - first_day);
    const double lo = stacked[i], hi = lo + static_cast<double>(c.runs);
    p.span(i, lo, hi, 0.0, std::max(p.slot() * 0.8, 1.0), station_colour(colour_of[c.station]),
           c.station + " " + day_text(c.day) + ": " + count_of(c.runs, "run"));
    stacked[i] = hi;
  }
  // Every `every`-th day and always the last (the newest day was left without a label: issue #52
  // F12), the label before it dropped when it would crowd it.
  const std::size_t every = std::max<std::size_t>(1, n_days / 12);
  std::vector<std::size_t> labelled;
  for (std::size_t i = 0; i < n_days; i += every) labelled.push_back(i);
  if (labelled.back() != n_days - 1) {
    if (labelled.size() > 1 && n_days - 1 - labelled.back() < (every + 1) / 2) labelled.pop_back();
    labelled.push_back(n_days - 1);
  }
  for (const std::size_t i : labelled)
    os << "<text class='day-label' transform='translate(" << p.x(i) - 3 << ',' << kTop + kPanelH + 8
       << ") rotate(60)' font-size='10'>" << day_text(first_day + static_cast<std::int64_t>(i))
       << "</text>\n";
  station_legend(os, stations);
  return os.str() + "</svg>\n";
}

std::string verdict_chart(const std::vector<db::history::StationVerdictCounts>& verdicts) {
  std::ostringstream os;
  os << svg_open("verdict-chart", kTop + kPanelH + 90);
  if (verdicts.empty()) return os.str() + "</svg>\n";
  // Counts, not shares (issue #52 F12): a share of all runs next to the table's share of the
  // runs the units decided read as two PASS rates. The tooltips give the table's basis.
  double bottom = 0, top = 1;
  for (const auto& v : verdicts) top = std::max(top, static_cast<double>(v.total()));
  tools::report::round_range(bottom, top);
  Panel p{os, kTop, bottom, top, verdicts.size()};
  p.frame("Verdicts per station (runs)", "runs");
  std::vector<std::string> labels;
  for (std::size_t i = 0; i < verdicts.size(); ++i) {
    const auto& v = verdicts[i];
    const std::int64_t own = v.unit_outcomes();
    double lo = 0;
    const std::int64_t parts[kVerdictParts] = {v.pass,    v.review,      v.failed, v.station_fault,
                                               v.aborted, v.interrupted, v.live};
    for (std::size_t k = 0; k < kVerdictParts; ++k) {
      if (parts[k] == 0) continue;
      const double n = static_cast<double>(parts[k]);
      std::string tip = v.station + " " + kVerdictNames[k] + ": " + count_of(parts[k], "run");
      if (k < 3)
        tip += " (" + fmt("%.1f", 100.0 * n / static_cast<double>(own)) + " % of the " +
               std::to_string(own) + " the units decided)";
      p.span(i, lo, lo + n, 0.0, p.slot() * 0.6, kVerdictColours[k], tip);
      lo += n;
    }
    labels.push_back(v.station);
  }
  slot_labels(os, p, labels);
  // The legend under the station labels, as the runs chart's: above the panel it ran into the
  // title on a narrow chart (issue #52 item 12: no label drawn over another).
  double x = kLeft;
  const double y = kTop + kPanelH + 78;
  for (std::size_t k = 0; k < kVerdictParts; ++k, x += 86)
    os << "<rect x='" << x << "' y='" << y - 10 << "' width='10' height='10' fill='"
       << kVerdictColours[k] << "'/><text x='" << x + 13 << "' y='" << y << "' font-size='11'>"
       << kVerdictNames[k] << "</text>\n";
  return os.str() + "</svg>\n";
}

std::string box_plot(const std::vector<db::history::ParamSummary>& summaries,
                     const calib::core::ParamInfo& info) {
  std::ostringstream os;
  os << svg_open("distribution-chart", kTop + kPanelH + 70);
  if (summaries.empty()) return os.str() + "</svg>\n";
  const double s = info.si_to_human;
  double lo = INFINITY, hi = -INFINITY;
  for (const auto& d : summaries) lo = std::min(lo, d.min * s), hi = std::max(hi, d.max * s);
  tools::report::round_range(lo, hi);
  Panel p{os, kTop, lo, hi, summaries.size()};
  p.frame(info.name + " (AINS) per station: min–max, quartiles, median, mean ◆", info.human_unit);
  std::vector<std::string> labels;
  for (std::size_t i = 0; i < summaries.size(); ++i) {
    const auto& d = summaries[i];
    const std::string tip = d.station + ": n " + std::to_string(d.count) + ", median " +
                            fmt("%.4g", d.median * s) + ", mean " + fmt("%.4g", d.mean * s) +
                            " ± " + fmt("%.3g", d.std_dev * s) + " " + info.human_unit;
    const char* colour = station_colour(i);
    p.span(i, d.min * s, d.max * s, 0.0, 1.5, "#555", tip);
    p.span(i, d.q1 * s, d.q3 * s, 0.0, std::min(p.slot() * 0.45, 60.0), colour, tip,
           "fill-opacity='0.55' stroke='#333'");
    p.tick(i, d.median * s, 0.0, std::min(p.slot() * 0.45, 60.0), "#000");
    os << "<rect x='" << p.x(i) - 4 << "' y='" << p.y(d.mean * s) - 4
       << "' width='8' height='8' transform='rotate(45 " << p.x(i) << ' ' << p.y(d.mean * s)
       << ")' fill='#fff' stroke='#000'><title>" << esc(tip) << "</title></rect>\n";
    labels.push_back(d.station + " (" + std::to_string(d.count) + ")");
  }
  slot_labels(os, p, labels);
  return os.str() + "</svg>\n";
}

namespace {

std::string period_label(const nlohmann::json& period) {
  return db::history::format_time_utc(period["since_ms"].get<db::history::TimestampMs>())
      .substr(0, 10);
}

}  // namespace

std::string signature_trend_svg(const nlohmann::json& trend) {
  const auto& periods = trend["periods"];
  const std::vector<std::string> stations = trend["stations"].get<std::vector<std::string>>();
  const double threshold = trend.value("z_threshold", 0.0);
  double top = 1.5 * threshold;
  for (const auto& period : periods)
    for (const auto& c : period["stations"])
      if (c.contains("strongest"))
        top = std::max(top, 1.1 * std::abs(c["strongest"]["z"].get<double>()));
  double bottom = 0;
  tools::report::round_range(bottom, top);
  std::ostringstream os;
  os << svg_open("signature-trend", kTop + kPanelH + 96);
  Panel p{os, kTop, bottom, top, std::max<std::size_t>(periods.size(), 1)};
  p.frame("Each station's strongest station-error fit per period", "|z|");
  if (threshold > 0) {
    p.hline(threshold, "#b3261e", "6 4");
    os << "<text x='" << kWidth - kRight - 4 << "' y='" << p.y(threshold) - 4
       << "' text-anchor='end' font-size='11' fill='#b3261e'>flagged at |z| ≥ "
       << fmt("%.2f", threshold) << "</text>\n";
  }
  for (std::size_t k = 0; k < stations.size(); ++k) {
    std::string points;
    for (std::size_t i = 0; i < periods.size(); ++i)
      if (const auto* c = tools::report::signature_trend_cell(periods[i], stations[k]);
          c && c->contains("strongest"))
        points += fmt("%.1f", p.x(i)) + "," +
                  fmt("%.1f", p.y(std::abs((*c)["strongest"]["z"].get<double>()))) + " ";
    os << "<polyline fill='none' stroke='" << station_colour(k) << "' stroke-width='1.5' points='"
       << points << "'/>\n";
    for (std::size_t i = 0; i < periods.size(); ++i) {
      const auto* c = tools::report::signature_trend_cell(periods[i], stations[k]);
      if (!c || !c->contains("strongest")) continue;
      const auto& f = (*c)["strongest"];
      const bool flagged = (*c)["flagged"].get<bool>();
      const double z = f["z"].get<double>();
      os << "<circle class='pt" << (flagged ? " flagged" : "") << "' data-station='"
         << esc(stations[k]) << "' data-period='" << period_label(periods[i]) << "' cx='" << p.x(i)
         << "' cy='" << p.y(std::abs(z)) << "' r='" << (flagged ? 6 : 3) << "' fill='"
         << station_colour(k) << "' stroke='" << (flagged ? "#b3261e" : "none")
         << "' stroke-width='2'><title>"
         << esc(stations[k] + ", period from " + period_label(periods[i]) + ": " +
                f["effect"].get<std::string>() + " " + fmt("%+.3g", f["size"].get<double>()) +
                " ± " + fmt("%.2g", f["sigma"].get<double>()) + " " + f["unit"].get<std::string>() +
                " (z " + fmt("%+.1f", z) + ")" + (flagged ? ", FLAGGED" : ""))
         << "</title></circle>\n";
    }
  }
  std::vector<std::string> labels;
  // With the year (a trend may span a new year); at most about 24 labels.
  for (const auto& period : periods) labels.push_back(period_label(period));
  slot_labels(os, p, labels, std::max<std::size_t>(1, (labels.size() + 23) / 24));
  station_legend(os, stations);
  return os.str() + "</svg>\n";
}

}  // namespace imucal::tools::stationweb
