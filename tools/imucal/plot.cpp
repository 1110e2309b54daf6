#include "tools/imucal/plot.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>
#include <vector>

#include "tools/report/svg_panel.hpp"

namespace imucal::tools::imucal {

namespace {

using report::esc;
using report::kLeft;
using report::kPanelH;
using report::kRight;
using report::kTop;
using report::kWidth;
using report::num;
using report::Panel;

void legend(std::ostringstream& os, double y, bool ains, bool nlsq,
            const std::string& second_name = "NLSQ") {
  double x = kWidth - 220;
  if (ains) {
    os << "<rect x='" << x << "' y='" << y - 10 << "' width='12' height='12' fill='#1f77b4'/>"
       << "<text x='" << x + 16 << "' y='" << y << "' font-size='12'>AINS</text>\n";
    x += 70;
  }
  if (nlsq)
    os << "<rect x='" << x << "' y='" << y - 10 << "' width='12' height='12' fill='#ff7f0e'/>"
       << "<text x='" << x + 16 << "' y='" << y << "' font-size='12'>" << second_name
       << "</text>\n";
}

/// Compact axis label: "accel_M[0][1]" -> "Ma xy", "gyro_bias_radps[2]" -> "bg z", ς -> "ς x".
std::string short_label(int i) {
  static const char* axes = "xyz";
  const int k = i % 27;
  if (k < 3) return std::string("ba ") + axes[k];
  if (k < 12) return std::string("Ma ") + axes[(k - 3) / 3] + axes[(k - 3) % 3];
  if (k < 15) return std::string("bg ") + axes[k - 12];
  if (k < 24) return std::string("Mg ") + axes[(k - 15) / 3] + axes[(k - 15) % 3];
  return std::string("ς ") + axes[k - 24];
}

}  // namespace

namespace {

const char* const kBlue = "#1f77b4";
const char* const kOrange = "#ff7f0e";

/// Per parameter: AINS against the second method in combined σ (or an estimate against the truth
/// in σ); a parameter not observable in this setting (ς without a table) has no bar.
void parameter_panel(std::ostringstream& os, double y0, const calib::pipeline::PipelineResult& r,
                     const calib::pipeline::MethodOutcome* second, const std::string& second_name,
                     const calib::core::ParamSet* truth, double k_sigma) {
  const bool both = r.ains && second;
  const int n = calib::core::ParamSet::kSize;
  Panel p{os, y0, -std::max(k_sigma * 1.5, 1.0), std::max(k_sigma * 1.5, 1.0),
          static_cast<size_t>(n)};
  p.frame(both ? "AINS − " + second_name + " per parameter, in combined σ (bound ±" +
                     num(k_sigma, "%.0f") + "σ)"
               : "estimate − truth per parameter, in σ",
          both ? "Δ / sqrt(σA² + σB²)" : "error / σ");
  p.hline(k_sigma, "#d62728", "6,3");
  p.hline(-k_sigma, "#d62728", "6,3");
  p.hline(0.0, "#444");
  for (int i = 0; i < n; ++i) {
    const auto& info = calib::core::param_info(i);
    auto z_of = [&](const calib::core::CalibrationResult& a) {
      const double s = a.sigma.to_vector()(i);
      return s > 0 ? (a.params.to_vector()(i) - truth->to_vector()(i)) / s : 0.0;
    };
    const bool observable = (!r.ains || r.ains->result.observable[static_cast<size_t>(i)]) &&
                            (!second || second->result.observable[static_cast<size_t>(i)]);
    if (!observable) {
      // Not observable in this setting (e.g. ς without a table): no bar.
    } else if (both) {
      const double sa = r.ains->result.sigma.to_vector()(i),
                   sb = second->result.sigma.to_vector()(i);
      const double d = r.ains->result.params.to_vector()(i) - second->result.params.to_vector()(i);
      const double z = d / std::sqrt(sa * sa + sb * sb);
      p.bar(static_cast<size_t>(i), z, 0.0, p.slot() * 0.6,
            std::abs(z) > k_sigma ? "#d62728" : "#2ca02c",
            info.name + ": " + num(z, "%.2f") + " σ");
    } else {
      const auto& a = r.ains ? r.ains->result : second->result;
      p.bar(static_cast<size_t>(i), z_of(a), 0.0, p.slot() * 0.6, r.ains ? kBlue : kOrange,
            info.name + ": " + num(z_of(a), "%.2f") + " σ");
    }
    os << "<text transform='translate(" << p.x(static_cast<size_t>(i)) + 4 << ","
       << y0 + kPanelH + 6 << ") rotate(90)' font-size='11'>" << esc(short_label(i)) << "</text>\n";
  }
}

/// One metric per rest period, AINS (blue) beside the second method (orange).
struct RestPanel {
  const char* title;
  const char* axis;
  double min_top;
  double (*value)(const calib::checks::RestPeriodMetric&);
  const char* format;
  const char* unit;
};

void rest_panel(std::ostringstream& os, double y0, const RestPanel& spec,
                const calib::checks::EvaluationMetrics* ma,
                const calib::checks::EvaluationMetrics* mb, size_t periods,
                const std::string& second_name, bool with_legend) {
  double top = 0;
  for (const auto* mm : {ma, mb})
    if (mm)
      for (const auto& pp : mm->periods) top = std::max(top, spec.value(pp));
  top = std::max(spec.min_top, 1.15 * top);
  const double w = 0.35;
  Panel p{os, y0, 0.0, top, periods};
  p.frame(spec.title, spec.axis);
  if (with_legend) legend(os, y0 - 8, ma != nullptr, mb != nullptr, second_name);
  for (size_t i = 0; i < periods; ++i) {
    if (ma && i < ma->periods.size())
      p.bar(i, spec.value(ma->periods[i]), mb ? -p.slot() * w / 2 : 0, p.slot() * w, kBlue,
            "AINS rest " + std::to_string(i + 1) + ": " +
                num(spec.value(ma->periods[i]), spec.format) + spec.unit);
    if (mb && i < mb->periods.size())
      p.bar(i, spec.value(mb->periods[i]), ma ? p.slot() * w / 2 : 0, p.slot() * w, kOrange,
            second_name + " rest " + std::to_string(i + 1) + ": " +
                num(spec.value(mb->periods[i]), spec.format) + spec.unit);
    os << "<text x='" << p.x(i) << "' y='" << y0 + kPanelH + 14
       << "' text-anchor='middle' font-size='10'>" << i + 1 << "</text>\n";
  }
  os << "<text x='" << kWidth / 2 << "' y='" << y0 + kPanelH + 32
     << "' text-anchor='middle' font-size='12'>rest period</text>\n";
}

}  // namespace

std::string calibration_svg(const calib::pipeline::PipelineResult& r,
                            const calib::core::ParamSet* truth, double k_sigma,
                            const std::string& title) {
  std::ostringstream os;
  // The second method: NLSQ in the factory, the legacy method on land and at sea.
  const calib::pipeline::MethodOutcome* second = r.nlsq     ? &*r.nlsq
                                                 : r.legacy ? &*r.legacy
                                                            : nullptr;
  const std::string second_name = r.nlsq ? "NLSQ" : "legacy";
  const bool panel1 = (r.ains && second) || truth;
  const int panels = (panel1 ? 1 : 0) + 2;
  const double height = kTop + panels * (kPanelH + 90);
  os << "<svg xmlns='http://www.w3.org/2000/svg' width='" << kWidth << "' height='" << height
     << "' font-family='sans-serif'>\n<rect width='100%' height='100%' fill='white'/>\n";
  os << "<text x='" << kLeft << "' y='24' font-size='16' font-weight='bold'>" << esc(title);
  if (r.crosscheck) os << " — cross-check " << r.crosscheck->verdict();
  os << "</text>\n";
  double y0 = kTop + 20;
  if (panel1) {
    parameter_panel(os, y0, r, second, second_name, truth, k_sigma);
    y0 += kPanelH + 90;
  }
  const calib::checks::EvaluationMetrics* ma = r.ains ? &r.ains->metrics : nullptr;
  const calib::checks::EvaluationMetrics* mb = second ? &second->metrics : nullptr;
  const size_t periods = std::max(ma ? ma->periods.size() : 0, mb ? mb->periods.size() : 0);
  if (periods > 0) {
    const RestPanel accel{
        "acceleration error of each rest period (eq. 53–54)",
        "|mean δa_n| (µg)",
        1.0,
        [](const calib::checks::RestPeriodMetric& q) { return q.accel_err_n_ug.norm(); },
        "%.2f",
        " µg"};
    rest_panel(os, y0, accel, ma, mb, periods, second_name, true);
    y0 += kPanelH + 90;
    const RestPanel orient{
        "orientation residual of each rest period (eq. 51–52)",
        "RMS (mdeg)",
        0.01,
        [](const calib::checks::RestPeriodMetric& q) { return q.orientation_rms_mdeg; },
        "%.3f",
        " mdeg"};
    rest_panel(os, y0, orient, ma, mb, periods, second_name, false);
  }
  os << "</svg>\n";
  return os.str();
}

}  // namespace imucal::tools::imucal
