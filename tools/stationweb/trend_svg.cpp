#include "tools/stationweb/trend_svg.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <sstream>

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

constexpr const char* kColours[] = {"#1f77b4", "#ff7f0e", "#2ca02c",
                                    "#d62728", "#9467bd", "#8c564b"};
constexpr double kHeight = kTop + kPanelH + 56;
constexpr double kInset = 12;  ///< px between the frame and the first/last run
constexpr double kHourMs = 3600e3;

std::vector<int> members(calib::core::ParamGroup g) {
  std::vector<int> out;
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i)
    if (calib::core::param_info(i).group == g) out.push_back(i);
  return out;
}

/// "accel_M[0][1]" -> "xy", "gyro_bias_radps[2]" -> "z".
std::string component_label(int i) {
  const std::string& name = calib::core::param_info(i).name;
  std::string out;
  for (std::size_t p = name.find('['); p != std::string::npos; p = name.find('[', p + 1))
    out += "xyz"[name[p + 1] - '0'];
  return out;
}

constexpr double kMinGap = 9;  ///< px between two runs' markers (issue #52 item 9: 1.6 px apart)

/// Calibration time to page x, the runs spread between the frame's edges.
struct TimeAxis {
  double t0_ms, t1_ms;
  std::map<db::history::RunId, double> spread;  ///< each run's x, at least kMinGap apart
  double x(double t_ms) const {
    return kLeft + kInset +
           (kWidth - kLeft - kRight - 2 * kInset) * (t_ms - t0_ms) / (t1_ms - t0_ms);
  }
  /// A run's x: its time's, moved just enough that no two runs' markers overlap.
  double at(const TrendPoint& q) const {
    const auto it = spread.find(q.run_id);
    return it == spread.end() ? x(static_cast<double>(q.t_ms)) : it->second;
  }
};

/// Runs closer in time than a marker's width pushed apart, forwards then (where that ran past the
/// frame) backwards; runs that far apart already keep their time's x.
void spread_runs(TimeAxis& axis, const std::vector<TrendPoint>& points) {
  std::vector<const TrendPoint*> order;
  for (const TrendPoint& p : points) order.push_back(&p);
  std::stable_sort(order.begin(), order.end(), [](const TrendPoint* a, const TrendPoint* b) {
    return a->t_ms < b->t_ms || (a->t_ms == b->t_ms && a->run_id < b->run_id);
  });
  std::vector<double> xs;
  for (const TrendPoint* p : order)
    xs.push_back(
        std::max(axis.x(static_cast<double>(p->t_ms)), xs.empty() ? -1e9 : xs.back() + kMinGap));
  const double right = kWidth - kRight - 2;
  for (std::size_t i = xs.size(); i-- > 0;)
    xs[i] = std::min(xs[i], i + 1 < xs.size() ? xs[i + 1] - kMinGap : right);
  for (std::size_t i = 0; i < order.size(); ++i) axis.spread[order[i]->run_id] = xs[i];
}

TimeAxis time_axis(const std::vector<TrendPoint>& points) {
  double t0 = static_cast<double>(points.front().t_ms), t1 = t0;
  for (const TrendPoint& p : points) {
    t0 = std::min(t0, static_cast<double>(p.t_ms));
    t1 = std::max(t1, static_cast<double>(p.t_ms));
  }
  if (t1 - t0 < kHourMs) {  // one run, or runs within the hour: an hour's width around them
    const double mid = (t0 + t1) / 2;
    t0 = mid - kHourMs / 2;
    t1 = mid + kHourMs / 2;
  }
  TimeAxis axis{t0, t1, {}};
  spread_runs(axis, points);
  return axis;
}

/// The y range in human units covering every drawn value ± 3σ, widened to round ticks.
void y_range(const std::vector<TrendPoint>& points, const std::vector<int>& idx, double& lo,
             double& hi) {
  lo = INFINITY;
  hi = -INFINITY;
  for (const TrendPoint& p : points)
    for (int i : idx) {
      if (!p.observable[static_cast<std::size_t>(i)]) continue;
      const double s = calib::core::param_info(i).si_to_human;
      lo = std::min(lo, (p.value(i) - 3 * p.sigma(i)) * s);
      hi = std::max(hi, (p.value(i) + 3 * p.sigma(i)) * s);
    }
  if (!(lo <= hi)) lo = -1, hi = 1;  // nothing observable
  tools::report::round_range(lo, hi);
}

/// Five time labels; the first starts and the last ends at its tick, inside the picture (a
/// centred last label was cut at the chart's edge: issue #52 item 12).
void time_ticks(std::ostringstream& os, const TimeAxis& axis) {
  const bool short_span = axis.t1_ms - axis.t0_ms < 3 * 24 * kHourMs;
  for (int k = 0; k <= 4; ++k) {
    const double t = axis.t0_ms + (axis.t1_ms - axis.t0_ms) * k / 4.0;
    const auto t_ms = static_cast<db::history::TimestampMs>(std::llround(t));
    const double x = axis.x(t), y = kTop + kPanelH;
    os << "<line x1='" << x << "' x2='" << x << "' y1='" << y << "' y2='" << y + 5
       << "' stroke='#888'/><text x='" << x << "' y='" << y + 18 << "' text-anchor='"
       << (k == 0   ? "start"
           : k == 4 ? "end"
                    : "middle")
       << "' font-size='11'>" << (short_span ? short_time(t_ms).substr(0, 16) : utc_date(t_ms))
       << "</text>\n";
  }
  os << "<text x='" << kWidth / 2 << "' y='" << kTop + kPanelH + 36
     << "' text-anchor='middle' font-size='12'>calibration time (run start, UTC)</text>\n";
}

/// The band value ± k σ of one component through its runs (a bar for a single run).
void band(std::ostringstream& os, const Panel& p, const TimeAxis& axis,
          const std::vector<const TrendPoint*>& pts, int i, double k, const char* colour,
          double opacity) {
  const double s = calib::core::param_info(i).si_to_human;
  auto upper = [&](const TrendPoint* q) { return p.y((q->value(i) + k * q->sigma(i)) * s); };
  auto lower = [&](const TrendPoint* q) { return p.y((q->value(i) - k * q->sigma(i)) * s); };
  if (pts.size() == 1) {
    const double x = axis.at(*pts[0]);
    os << "<rect x='" << x - 5 << "' y='" << upper(pts[0]) << "' width='10' height='"
       << std::max(lower(pts[0]) - upper(pts[0]), 0.5) << "' fill='" << colour << "' fill-opacity='"
       << opacity << "'/>\n";
    return;
  }
  os << "<polygon fill='" << colour << "' fill-opacity='" << opacity << "' stroke='none' points='";
  for (const TrendPoint* q : pts) os << axis.at(*q) << ',' << upper(q) << ' ';
  for (auto it = pts.rbegin(); it != pts.rend(); ++it)
    os << axis.at(**it) << ',' << lower(*it) << ' ';
  os << "'/>\n";
}

bool frame_dependent(int i) {
  const calib::core::ParamGroup g = calib::core::param_info(i).group;
  return g == calib::core::ParamGroup::kAccelMisalign ||
         g == calib::core::ParamGroup::kGyroMisalign;
}

const char* frame_name(calib::core::BodyFrame f) {
  return f == calib::core::BodyFrame::kHousing ? "housing" : "accel_symmetric";
}

/// Whether the panel of `idx` holds drawn points of both body frames (then split by frame).
bool mixed_frames(const std::vector<TrendPoint>& points, const std::vector<int>& idx) {
  if (!frame_dependent(idx.front())) return false;
  bool housing = false, other = false;
  for (const TrendPoint& q : points)
    for (int i : idx)
      if (q.observable[static_cast<std::size_t>(i)])
        (q.body_frame == calib::core::BodyFrame::kHousing ? housing : other) = true;
  return housing && other;
}

/// One series of one component: its points (one body frame where that matters), bands, line and
/// markers.
void series(std::ostringstream& os, const Panel& p, const TimeAxis& axis,
            const std::vector<const TrendPoint*>& pts, int i, const char* colour,
            std::optional<db::history::RunId> active, bool dashed) {
  if (pts.empty()) return;
  band(os, p, axis, pts, i, 3.0, colour, 0.10);
  band(os, p, axis, pts, i, 1.0, colour, 0.28);
  const calib::core::ParamInfo& info = calib::core::param_info(i);
  const double s = info.si_to_human;
  os << "<polyline fill='none' stroke='" << colour << "' stroke-width='1.2'"
     << (dashed ? " stroke-dasharray='5,3'" : "") << " data-param='" << info.name
     << "' data-frame='" << frame_name(pts.front()->body_frame) << "' points='";
  for (const TrendPoint* q : pts) os << axis.at(*q) << ',' << p.y(q->value(i) * s) << ' ';
  os << "'/>\n";
  for (const TrendPoint* q : pts) {
    const bool is_active = active && *active == q->run_id;
    // PASS filled; REVIEW a hollow ring in the component's colour; any other verdict a dark ring.
    const bool pass = q->verdict == "PASS", review = q->verdict == "REVIEW";
    const char* stroke = is_active ? "#000" : pass || review ? colour : "#333";
    os << "<circle class='pt" << (is_active ? " active" : "") << "' cx='" << axis.at(*q) << "' cy='"
       << p.y(q->value(i) * s) << "' r='"
       << (is_active ? 5
           : pass    ? 3
                     : 4.5)
       << "' fill='" << (pass ? colour : "#fff") << "' stroke='" << stroke << "' stroke-width='"
       << (is_active || !pass ? 2 : 1) << "' data-run-id='" << q->run_id << "' data-verdict='"
       << esc(q->verdict) << "' data-t-ms='" << q->t_ms << "' data-param='" << info.name
       << "' data-frame='" << frame_name(q->body_frame) << "' data-value-si='" << exact(q->value(i))
       << "' data-sigma-si='" << exact(q->sigma(i)) << "'><title>run " << q->run_id << " ("
       << esc(q->verdict) << ") " << short_time(q->t_ms) << ": " << info.name << " = "
       << fmt("%.4g", q->value(i) * s) << " ± " << fmt("%.2g", q->sigma(i) * s) << " "
       << esc(info.human_unit) << " (1σ"
       << (frame_dependent(i)
               ? std::string(", ") + (q->body_frame == calib::core::BodyFrame::kHousing
                                          ? "housing frame"
                                          : "accelerometer triad's frame")
               : std::string())
       << ")</title></circle>\n";
  }
}

void component(std::ostringstream& os, const Panel& p, const TimeAxis& axis,
               const std::vector<TrendPoint>& points, int i, const char* colour,
               std::optional<db::history::RunId> active) {
  std::vector<const TrendPoint*> housing, other;
  for (const TrendPoint& q : points)
    if (q.observable[static_cast<std::size_t>(i)])
      (!frame_dependent(i) || q.body_frame == calib::core::BodyFrame::kHousing ? housing : other)
          .push_back(&q);
  series(os, p, axis, housing, i, colour, active, false);
  series(os, p, axis, other, i, colour, active, true);
}

void active_marker(std::ostringstream& os, const TimeAxis& axis,
                   const std::vector<TrendPoint>& points,
                   std::optional<db::history::RunId> active) {
  if (!active) return;
  for (const TrendPoint& q : points) {
    if (q.run_id != *active) continue;
    const double x = axis.at(q);
    os << "<line class='active-marker' x1='" << x << "' x2='" << x << "' y1='" << kTop << "' y2='"
       << kTop + kPanelH << "' stroke='#000' stroke-dasharray='4,3'/>"
       << "<text x='" << x + 4 << "' y='" << kTop + 12 << "' font-size='11'>active set (run "
       << q.run_id << ")</text>\n";
  }
}

/// Under the time axis of a panel whose points are in two body frames: what solid and dashed are.
void frame_legend(std::ostringstream& os) {
  os << "<g class='frame-legend'><line x1='" << kLeft << "' x2='" << kLeft + 24 << "' y1='"
     << kHeight - 8 << "' y2='" << kHeight - 8 << "' stroke='#444'/><text x='" << kLeft + 28
     << "' y='" << kHeight - 4 << "' font-size='11'>housing frame (factory runs)</text><line x1='"
     << kLeft + 210 << "' x2='" << kLeft + 234 << "' y1='" << kHeight - 8 << "' y2='" << kHeight - 8
     << "' stroke='#444' stroke-dasharray='5,3'/><text x='" << kLeft + 238 << "' y='" << kHeight - 4
     << "' font-size='11'>accelerometer triad's frame (land, sea, legacy): a separate series, "
        "the frames differ by the housing angle</text></g>\n";
}

void legend(std::ostringstream& os, const std::vector<int>& idx) {
  double x = kWidth - kRight - 48.0 * static_cast<double>(idx.size()) - 120;
  os << "<text x='" << x << "' y='" << kTop - 8 << "' font-size='11'>band ±1σ, light ±3σ:</text>";
  x += 120;
  for (std::size_t k = 0; k < idx.size(); ++k, x += 48)
    os << "<rect x='" << x << "' y='" << kTop - 18 << "' width='10' height='10' fill='"
       << kColours[k] << "'/><text x='" << x + 13 << "' y='" << kTop - 8 << "' font-size='11'>"
       << component_label(idx[k]) << "</text>";
  os << "\n";
}

}  // namespace

std::string trend_svg(calib::core::ParamGroup group, const std::vector<TrendPoint>& points,
                      std::optional<db::history::RunId> active_run) {
  const std::vector<int> idx = members(group);
  const calib::core::ParamInfo& first = calib::core::param_info(idx.front());
  std::ostringstream os;
  os << "<svg id='trend-" << calib::core::group_name(group)
     << "' xmlns='http://www.w3.org/2000/svg' "
     << "width='" << kWidth << "' height='" << kHeight << "' viewBox='0 0 " << kWidth << ' '
     << kHeight << "' font-family='sans-serif'>\n";
  if (points.empty()) return os.str() + "</svg>\n";
  double lo = 0, hi = 0;
  y_range(points, idx, lo, hi);
  Panel p{os, kTop, lo, hi, 1};
  p.frame(calib::core::group_name(group) + " (AINS)", first.human_unit);
  const TimeAxis axis = time_axis(points);
  time_ticks(os, axis);
  for (std::size_t k = 0; k < idx.size(); ++k)
    component(os, p, axis, points, idx[k], kColours[k], active_run);
  active_marker(os, axis, points, active_run);
  legend(os, idx);
  if (mixed_frames(points, idx)) frame_legend(os);
  os << "</svg>\n";
  return os.str();
}

}  // namespace imucal::tools::stationweb
