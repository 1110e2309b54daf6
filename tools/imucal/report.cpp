#include "tools/imucal/report.hpp"

#include <cmath>
#include <cstdio>
#include <string>

#include "calib/core/body_frame.hpp"
#include "db/archive/param_json.hpp"
#include "tools/imucal/format.hpp"

namespace imucal::tools::imucal {

namespace {

const char* frame_name(calib::core::BodyFrame f) {
  return f == calib::core::BodyFrame::kHousing ? "housing" : "accel_symmetric";
}

std::vector<std::string> unobservable_names(const calib::core::CalibrationResult& r) {
  std::vector<std::string> out;
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i)
    if (!r.observable[static_cast<size_t>(i)]) out.push_back(calib::core::param_info(i).name);
  return out;
}

/// The truth in the frame a result is expressed in (what its error is measured against).
calib::core::ParamVector truth_in_frame(const calib::core::ParamSet& truth,
                                        calib::core::BodyFrame f) {
  return f == calib::core::BodyFrame::kHousing
             ? truth.to_vector()
             : calib::core::to_accel_symmetric_frame(truth).params.to_vector();
}

nlohmann::json outcome_json(const calib::pipeline::MethodOutcome& m) {
  return {{"method", m.result.method},
          {"setting", calib::core::setting_name(m.result.setting)},
          {"body_frame", frame_name(m.result.body_frame)},
          {"unobservable", unobservable_names(m.result)},
          {"unobservable_notes", m.result.unobservable_notes},
          {"params", db::archive::param_set_to_json(m.result.params)},
          {"sigma", db::archive::param_set_to_json(m.result.sigma)},
          {"metrics", metrics_to_json(m.metrics)},
          {"runtime_s", m.result.runtime_s},
          {"iterations", m.result.iterations},
          {"converged", m.result.converged},
          {"warnings", m.result.warnings}};
}

}  // namespace

nlohmann::json metrics_to_json(const calib::checks::EvaluationMetrics& m) {
  if (!m.evaluated) return {{"evaluated", false}, {"reason", m.not_evaluated_reason}};
  return {{"evaluated", true},
          {"orientation_rmse_mdeg", m.orientation_rmse_mdeg},
          {"accel_rmse_ug", m.accel_rmse_ug},
          {"heading_offset_gamma_np_rad", m.heading_offset_gamma_np_rad},
          {"body_misalignment_theta_bp_rad",
           {m.body_misalignment_theta_bp_rad(0), m.body_misalignment_theta_bp_rad(1),
            m.body_misalignment_theta_bp_rad(2)}},
          {"rest_periods", m.periods.size()}};
}

nlohmann::json pipeline_to_json(const calib::pipeline::PipelineResult& r) {
  nlohmann::json j = nlohmann::json::object();
  if (r.ains) j["ains"] = outcome_json(*r.ains);
  if (r.nlsq) j["nlsq"] = outcome_json(*r.nlsq);
  if (r.legacy) j["legacy"] = outcome_json(*r.legacy);
  if (r.crosscheck) {
    nlohmann::json failures = nlohmann::json::array();
    for (const auto& f : r.crosscheck->failures)
      failures.push_back({{"term", f.term}, {"detail", f.detail}});
    j["crosscheck"] = {{"verdict", r.crosscheck->verdict()},
                       {"failures", failures},
                       {"not_compared", r.crosscheck->skipped}};
  }
  nlohmann::json limit_failures = nlohmann::json::array();
  for (const auto& f : r.limits.failures)
    limit_failures.push_back({{"method", f.method}, {"term", f.term}, {"detail", f.detail}});
  j["limits"] = {{"pass", r.limits.pass}, {"failures", limit_failures}};
  if (r.holding)
    j["holding"] = {{"method", calib::pipeline::method_name(r.holding->method)},
                    {"reason", r.holding->reason},
                    {"rests", r.holding->rests},
                    {"ains_rest_rms_mps2", r.holding->ains_rest_rms_mps2},
                    {"legacy_rest_rms_mps2", r.holding->legacy_rest_rms_mps2},
                    {"max_ratio", r.holding->max_ratio}};
  j["verdict"] = r.pass() ? "PASS" : "REVIEW";
  j["unchecked_reason"] =
      r.unchecked_reason.empty() ? nlohmann::json(nullptr) : nlohmann::json(r.unchecked_reason);
  return j;
}

void print_parameter_table(std::ostream& os, const calib::pipeline::PipelineResult& r,
                           const calib::core::ParamSet* truth) {
  std::vector<std::pair<std::string, const calib::core::CalibrationResult*>> cols;
  if (r.ains) cols.emplace_back("AINS", &r.ains->result);
  if (r.nlsq) cols.emplace_back("NLSQ", &r.nlsq->result);
  if (r.legacy) cols.emplace_back("legacy", &r.legacy->result);
  std::vector<calib::core::ParamVector> col_truth;
  for (const auto& c : cols)
    col_truth.push_back(truth ? truth_in_frame(*truth, c.second->body_frame)
                              : calib::core::ParamVector::Zero());
  char line[512];
  std::snprintf(line, sizeof line, "%-26s %-7s", "parameter", "unit");
  os << line;
  if (truth) os << fmt("%12s", "truth");
  for (const auto& c : cols) {
    os << fmt("%14s", (c.first + " est").c_str()) << fmt("%11s", "±1σ");
    if (truth) os << fmt("%8s", "err/σ");
  }
  os << '\n';
  // The truth printed is the one err/σ is measured against: in the first method's frame (all
  // methods of one setting share it; a different one is named below).
  const calib::core::ParamVector tv =
      col_truth.empty() ? calib::core::ParamVector::Zero() : col_truth[0];
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
    const auto& info = calib::core::param_info(i);
    std::snprintf(line, sizeof line, "%-26s %-7s", info.name.c_str(), info.human_unit.c_str());
    os << line;
    if (truth) os << fmt("%12.3f", tv(i) * info.si_to_human);
    for (size_t c = 0; c < cols.size(); ++c) {
      const calib::core::CalibrationResult& res = *cols[c].second;
      if (!res.observable[static_cast<size_t>(i)]) {
        os << fmt("%14s", "n/a") << fmt("%11s", "") << (truth ? fmt("%8s", "") : "");
        continue;
      }
      const double est = res.params.to_vector()(i), sd = res.sigma.to_vector()(i);
      os << fmt("%14.3f", est * info.si_to_human) << fmt("%11.3f", sd * info.si_to_human);
      if (truth) os << fmt("%8.2f", sd > 0 ? (est - col_truth[c](i)) / sd : NAN);
    }
    os << '\n';
  }
  for (const auto& c : cols)
    if (c.second->body_frame == calib::core::BodyFrame::kAccelSymmetric)
      os << c.first
         << ": misalignments in the accelerometer triad's own orthogonal frame (accel_M "
            "symmetric)"
         << (truth ? "; truth and err/σ in that frame" : "") << '\n';
  if (truth)
    for (size_t c = 1; c < cols.size(); ++c)
      if (cols[c].second->body_frame != cols[0].second->body_frame)
        os << cols[c].first << ": err/σ against the truth in its own frame ("
           << frame_name(cols[c].second->body_frame) << "), not the truth column's\n";
}

void print_evaluation(std::ostream& os, const calib::checks::EvaluationMetrics& m) {
  if (!m.evaluated) {
    os << "not evaluated: " << m.not_evaluated_reason << '\n';
    return;
  }
  os << fmt("orientation RMSE %.3f mdeg", m.orientation_rmse_mdeg)
     << fmt(", acceleration RMSE %.2f µg", m.accel_rmse_ug)
     << fmt(" over %.0f rest periods", static_cast<double>(m.periods.size()))
     << fmt("; fitted heading offset %.2f arcsec\n", m.heading_offset_gamma_np_rad * 206264.806);
}

void print_metrics_and_verdict(std::ostream& os, const calib::pipeline::PipelineResult& r) {
  for (const auto* m : {r.ains ? &*r.ains : nullptr, r.nlsq ? &*r.nlsq : nullptr,
                        r.legacy ? &*r.legacy : nullptr}) {
    if (!m) continue;
    os << m->result.method << ": " << (m->result.converged ? "converged" : "NOT converged")
       << fmt(" in %.0f iterations", m->result.iterations)
       << fmt(", %.2f s; ", m->result.runtime_s);
    print_evaluation(os, m->metrics);
    for (const auto& w : m->result.warnings) os << "  warning: " << w << '\n';
    for (const auto& n : m->result.unobservable_notes) os << "  not observable: " << n << '\n';
  }
  if (!r.crosscheck && r.ains && !r.nlsq && !r.legacy &&
      r.ains->result.setting == calib::core::Setting::kSea)
    os << "cross-check: none at sea (the legacy method needs a still platform; AINS stands "
          "alone)\n";
  if (r.crosscheck) {
    os << "cross-check: " << r.crosscheck->verdict();
    if (!r.crosscheck->skipped.empty())
      os << " (" << r.crosscheck->skipped.size() << " parameters not compared: not observable)";
    os << '\n';
    for (const auto& f : r.crosscheck->failures) os << "  " << f.detail << '\n';
  }
  os << "limits: " << (r.limits.pass ? "all hold" : "FAILED") << '\n';
  for (const auto& f : r.limits.failures) os << "  " << f.detail << '\n';
  if (r.holding)
    os << "holds: " << calib::pipeline::method_name(r.holding->method) << " — " << r.holding->reason
       << '\n';
  os << "verdict: " << (r.pass() ? "PASS" : "REVIEW");
  if (r.rests_on_legacy())
    os << " — on legacy alone: its limits "
       << (r.limits_hold_for(calib::pipeline::Method::kLegacy) ? "hold" : "fail")
       << "; AINS's results and the cross-check are shown, not counted";
  if (!r.unchecked_reason.empty()) os << " — " << r.unchecked_reason << " (as in the station)";
  os << '\n';
}

void print_crlb(std::ostream& os, const calib::checks::CrlbResult& crlb,
                const std::vector<std::string>& unobservable) {
  const calib::core::ParamVector s = crlb.sigma.to_vector();
  char line[256];
  std::snprintf(line, sizeof line, "%-26s %-7s %14s\n", "parameter", "unit", "CRLB 1σ");
  os << line;
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
    const auto& info = calib::core::param_info(i);
    std::snprintf(line, sizeof line, "%-26s %-7s %14.4f\n", info.name.c_str(),
                  info.human_unit.c_str(), s(i) * info.si_to_human);
    os << line;
  }
  if (unobservable.empty()) {
    os << "all 27 parameters observable on this sequence\n";
  } else {
    os << "UNOBSERVABLE on this sequence:";
    for (const auto& n : unobservable) os << ' ' << n;
    os << '\n';
  }
}

}  // namespace imucal::tools::imucal
