#include "tools/imucal/paper_plot.hpp"

#include <algorithm>
#include <sstream>

#include "tools/report/svg_panel.hpp"

namespace imucal::tools::imucal {

namespace {

using report::esc;
using report::kPanelH;
using report::kTop;
using report::kWidth;
using report::num;
using report::Panel;

const char* const kPaperColor = "#222";
const char* const kModelColor = "#1f77b4";

double mean_of(const std::vector<calib::studies::paper::PaperRow>& rows, size_t c, size_t m) {
  double s = 0.0;
  for (const calib::studies::paper::PaperRow& r : rows) s += r[c][m];
  return s / static_cast<double>(rows.size());
}

/// One metric's panel: per column the paper's IMUs left of centre, the model's units right of it.
void metric_panel(std::ostringstream& os, double y0, size_t m,
                  const std::vector<calib::studies::paper::PaperRow>& paper,
                  const std::vector<calib::studies::paper::PaperRow>& model) {
  double top = 0.0;
  for (const auto* rows : {&paper, &model})
    for (const calib::studies::paper::PaperRow& r : *rows)
      for (const auto& col : r) top = std::max(top, col[m]);
  Panel p{os, y0, 0.0, 1.1 * top, calib::studies::paper::kNumPaperColumns};
  const std::string unit = m == 0 ? "mdeg" : "µg";
  p.frame(m == 0 ? "orientation RMSE per IMU" : "acceleration RMSE per IMU",
          (m == 0 ? "orientation [" : "acceleration [") + unit + "]");
  for (size_t c = 0; c < static_cast<size_t>(calib::studies::paper::kNumPaperColumns); ++c) {
    const std::string column = calib::studies::paper::paper_column_name(
        static_cast<calib::studies::paper::PaperColumn>(c));
    for (size_t u = 0; u < paper.size(); ++u)
      p.dot(c, paper[u][c][m], -0.18 * p.slot(), 4.5, "none", kPaperColor, "paper",
            column + ", paper IMU " + std::to_string(u + 1) + ": " + num(paper[u][c][m], "%.2f") +
                " " + unit);
    for (size_t u = 0; u < model.size(); ++u)
      p.dot(c, model[u][c][m], 0.18 * p.slot(), 3.0, kModelColor, "none", "model",
            column + ", simulated unit " + std::to_string(u + 1) + ": " +
                num(model[u][c][m], "%.2f") + " " + unit);
    p.tick(c, mean_of(paper, c, m), -0.18 * p.slot(), 0.22 * p.slot(), kPaperColor);
    p.tick(c, mean_of(model, c, m), 0.18 * p.slot(), 0.22 * p.slot(), kModelColor);
    os << "<text x='" << p.x(c) << "' y='" << y0 + kPanelH + 16
       << "' text-anchor='middle' font-size='12'>" << esc(column) << "</text>\n";
  }
}

}  // namespace

std::string paper_units_svg(const std::vector<calib::studies::paper::PaperRow>& model,
                            const std::string& title, const std::string& description) {
  const std::vector<calib::studies::paper::PaperRow> paper =
      calib::studies::paper::paper_published_rows();
  const double height = kTop + 2 * (kPanelH + 60);
  std::ostringstream os;
  os << "<svg xmlns='http://www.w3.org/2000/svg' width='" << kWidth << "' height='" << height
     << "' font-family='sans-serif'>\n<desc>" << esc(description)
     << "</desc>\n<rect width='100%' height='100%' fill='white'/>\n";
  os << "<text x='" << kWidth / 2 << "' y='22' text-anchor='middle' font-size='15'>" << esc(title)
     << "</text>\n";
  // Legend: open circles the paper's IMUs, dots the model's units, bars the means.
  os << "<circle cx='" << kWidth - 330 << "' cy='36' r='4.5' fill='none' stroke='" << kPaperColor
     << "'/><text x='" << kWidth - 320 << "' y='40' font-size='12'>paper's six IMUs</text>\n"
     << "<circle cx='" << kWidth - 190 << "' cy='36' r='3' fill='" << kModelColor << "'/><text x='"
     << kWidth - 180 << "' y='40' font-size='12'>simulated units"
     << " (bars: means)</text>\n";
  metric_panel(os, kTop + 10, 0, paper, model);
  metric_panel(os, kTop + 10 + kPanelH + 60, 1, paper, model);
  os << "</svg>\n";
  return os.str();
}

}  // namespace imucal::tools::imucal
