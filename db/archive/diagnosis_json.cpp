#include "db/archive/diagnosis_json.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace imucal::db::archive {

namespace {

using nlohmann::json;

/// JSON has no NaN/Inf: a non-finite figure (e.g. a χ² ratio of nothing) becomes null.
json num(double x) { return std::isfinite(x) ? json(x) : json(nullptr); }

json params_json(const std::vector<calib::diagnosis::CandidateParam>& ps) {
  json a = json::array();
  for (const auto& p : ps)
    a.push_back(
        {{"name", p.name}, {"value", num(p.value)}, {"sigma", num(p.sigma)}, {"unit", p.unit}});
  return a;
}

json finding(const calib::diagnosis::CandidateResult& c) {
  return {{"effect", c.name},
          {"magnitude", num(c.magnitude)},
          {"sigma", num(c.magnitude_sigma)},
          {"unit", c.unit},
          {"parameters", params_json(c.params)}};
}

/// One step of the stepwise explanation: the effect, its size in the joint fit of the set, its test
/// given the steps before it and the gaps once it is added.
json step_json(const calib::diagnosis::DiagnosisStep& s) {
  return {{"effect", s.effect},
          {"magnitude", num(s.magnitude)},
          {"sigma", num(s.magnitude_sigma)},
          {"unit", s.unit},
          {"p_value", num(s.p_value)},
          {"gap_after", num(s.gap_after)},
          {"held_out_after", num(s.held_out_after)},
          {"note", s.note},
          // The other members of a set this sequence cannot tell apart that the step stands for.
          {"set", s.set},
          {"parameters", params_json(s.params)}};
}

json unsupported_json(const calib::diagnosis::UnsupportedEffect& u) {
  return {{"effect", u.effect},
          {"magnitude", num(u.magnitude)},
          {"sigma", num(u.magnitude_sigma)},
          {"unit", u.unit},
          {"p_value_given_others", num(u.p_value)},
          {"reason", u.reason}};
}

json candidate_json(const calib::diagnosis::CandidateResult& c) {
  return {{"effect", c.name},
          {"score", num(c.bic_gain)},
          {"lr", num(c.lr)},
          {"k", c.k},
          {"p_value", num(c.p_value)},
          {"bic_gain", num(c.bic_gain)},
          {"magnitude", num(c.magnitude)},
          {"sigma", num(c.magnitude_sigma)},
          {"unit", c.unit},
          // "separable": a finding on its own could be told apart on this sequence — from the
          // base parameters and from every other significant candidate (issue #19 item 6: it
          // read true beside a note saying "not separable ... from accel_asymmetry").
          {"separable", c.separable && c.confounded_with.empty()},
          {"separable_from_base", c.separable},
          {"significant", c.significant},
          {"in_ambiguous_set", c.in_ambiguous_set},
          {"plausible", c.plausible},
          {"typical_ratio", num(c.typical_ratio)},
          {"note", c.note},
          {"held_out_gap", c.separable ? num(c.held_out_gap) : json(nullptr)},
          // A candidate judged on a statistic of its own (quantisation, the output filter): that
          // statistic's held-out gap without it (null for the others: the segments' applies).
          {"held_out_gap_before", num(c.held_out_gap_before)},
          {"max_correlation", num(c.max_correlation)},
          {"confounded_with", c.confounded_with},
          {"parameters", params_json(c.params)}};
}

json segment_json(const calib::diagnosis::SegmentGap& g, const std::vector<std::string>& keys) {
  json z = json::object(), r = json::object();
  for (size_t c = 0; c < keys.size(); ++c) {
    z[keys[c]] = num(g.z[c]);
    r[keys[c]] = num(g.residual_si[c]);
  }
  const bool rest = g.segment.kind == calib::diagnosis::GapSegment::Kind::kRest;
  return {{"label", g.segment.label()},
          {"kind", rest ? "rest" : "move"},
          {"number", g.segment.number},
          {"t0_s", num(g.segment.t0_s)},
          {"t1_s", num(g.segment.t1_s)},
          {"outer_deg", num(g.segment.outer_deg)},
          {"inner_deg", num(g.segment.inner_deg)},
          {"nis", num(g.nis)},
          {"nis_expected", num(g.nis_expected)},
          {"nis_sim", num(g.nis_twin)},
          {"p_value", num(g.p_value)},
          {"z", z},
          {"residual_si", r}};
}

}  // namespace

nlohmann::json diagnosis_to_json(const calib::diagnosis::DiagnosisResult& d) {
  json j;
  j["verdict"] = d.verdict;
  j["summary"] = d.summary;
  j["best"] = d.best ? finding(d.candidates[*d.best]) : json(nullptr);
  j["second"] = d.second ? finding(d.candidates[*d.second]) : json(nullptr);
  j["ambiguous"] = d.ambiguous;
  j["explained_by"] = d.explained_by;
  json steps = json::array();
  for (const auto& st : d.steps) steps.push_back(step_json(st));
  j["steps"] = steps;
  // Chosen by the stepwise search, then dropped: their place in the final set is not earned.
  json unsupported = json::array();
  for (const auto& u : d.unsupported) unsupported.push_back(unsupported_json(u));
  j["not_supported"] = unsupported;
  // A significant candidate that removed too little of the held-out gap to be a finding.
  j["weak_candidate"] = d.weak_candidate.empty() ? json(nullptr)
                                                 : json{{"effect", d.weak_candidate},
                                                        {"shrinkage", num(d.weak_shrinkage)}};
  json cands = json::array();
  for (const auto& c : d.candidates) cands.push_back(candidate_json(c));
  j["candidates"] = cands;
  j["held_out"] = {
      {"gap_before", num(d.held_out.gap_before)},
      {"gap_after", d.held_out.has_after ? num(d.held_out.gap_after) : json(nullptr)},
      {"gap_after_pair", d.held_out.has_pair ? num(d.held_out.gap_after_pair) : json(nullptr)},
      {"shrinkage", d.held_out.has_after ? num(d.held_out.shrinkage) : json(nullptr)}};
  j["overall"] = {{"chi2", num(d.chi2)},
                  {"dof", d.dof},
                  {"gap", num(d.overall_gap)},
                  {"expected", num(d.overall_expected)},
                  {"sigma", num(d.overall_sigma)},
                  {"p_value", num(d.overall_p)},
                  {"gap_after_best", num(d.gap_after_best)},
                  {"simulated_gap", num(d.twin_gap)}};
  json axes = json::object();
  for (int c = 0; c < calib::diagnosis::kGapRowsPerSegment; ++c) {
    json adev = json::array(), exp = json::array();
    for (double v : d.whiteness.adev[static_cast<size_t>(c)]) adev.push_back(num(v));
    for (double v : d.whiteness.adev_expected[static_cast<size_t>(c)]) exp.push_back(num(v));
    axes[calib::diagnosis::gap_component_key(c)] = {
        {"lag1_autocorr", num(d.whiteness.lag1_autocorr[static_cast<size_t>(c)])},
        {"lag1_z", num(d.whiteness.lag1_z[static_cast<size_t>(c)])},
        {"adev", adev},
        {"adev_expected", exp}};
  }
  j["whiteness"] = {{"tau_s", d.whiteness.tau_s}, {"axes", axes}};
  json segs = json::array();
  for (const auto& g : d.segments) segs.push_back(segment_json(g, d.component_keys));
  j["residuals"] = d.innovation_residuals ? "gnss_innovations" : "rests_and_moves";
  j["components"] = d.component_keys;
  j["segments"] = segs;
  json moved = json::array();
  for (const auto& m : d.moved)
    moved.push_back({{"name", m.name},
                     {"shift_sigma", num(m.shift_sigma)},
                     {"shift", num(m.shift)},
                     {"unit", m.unit}});
  j["moved_parameters"] = moved;
  json rem = json::array();
  for (const auto& [where, z] : d.remaining) rem.push_back({{"where", where}, {"z", num(z)}});
  j["remaining"] = rem;
  j["runtime_s"] = num(d.runtime_s);
  return j;
}

nlohmann::json diagnosis_run_json(const calib::diagnosis::DiagnosisResult& d,
                                  const std::string& archive, const RunInfo& info,
                                  const calib::core::CalibrationInput& in,
                                  const std::string& base_calibration) {
  json j = diagnosis_to_json(d);
  j["archive"] = archive;
  j["serial"] = info.serial;
  j["sequence"] = info.sequence_name;
  j["setting"] = calib::core::setting_name(in.setting);
  j["grade"] = calib::core::grade_name(in.grade);
  j["table_free"] = !in.has_reference_attitude();
  j["base_calibration"] = base_calibration;
  j["samples"] = in.imu.size();
  return j;
}

nlohmann::json diagnosis_summary_json(const calib::diagnosis::DiagnosisResult& d) {
  const json full = diagnosis_to_json(d);
  json s;
  for (const char* k : {"verdict", "summary", "best", "second", "ambiguous", "explained_by",
                        "not_supported", "weak_candidate", "held_out"})
    s[k] = full[k];
  // The explained set's steps without their parameters: effect, size and the gaps after it.
  s["steps"] = json::array();
  for (json st : full["steps"]) {
    st.erase("parameters");
    s["steps"].push_back(std::move(st));
  }
  s["overall"] = {{"gap", full["overall"]["gap"]},
                  {"expected", full["overall"]["expected"]},
                  {"sigma", full["overall"]["sigma"]},
                  {"p_value", full["overall"]["p_value"]}};
  return s;
}

namespace {

/// One finding ({"effect", "parameters": [{"name", "value", "unit"}]}) into `fx`, in SI.
std::string add_finding(const nlohmann::json& f, const std::string& where,
                        calib::effects::Effects& fx) {
  auto bad = [&](const std::string& what) { return std::invalid_argument(where + ": " + what); };
  if (!f.is_object() || !f.contains("effect") || !f["effect"].is_string())
    throw bad("not a finding (an object with \"effect\" and \"parameters\")");
  const std::string name = f["effect"].get<std::string>();
  const calib::effects::EffectInfo* e = calib::effects::find_effect(name);
  if (!e) throw bad("unknown effect \"" + name + "\"");
  if (!f.contains("parameters") || !f["parameters"].is_array()) throw bad("no \"parameters\"");
  Eigen::VectorXd v = calib::effects::effect_vector(fx, e->id);
  for (int i = 0; i < e->size(); ++i) {
    const calib::effects::EffectParamInfo& pi = e->params[static_cast<size_t>(i)];
    bool found = false;
    for (const auto& p : f["parameters"]) {
      if (!p.is_object() || p.value("name", "") != pi.name) continue;
      if (!p.contains("value") || !p["value"].is_number())
        throw bad(name + "." + pi.name + ": \"value\" must be a number");
      v(i) = p["value"].get<double>() / pi.si_to_human;
      found = true;
    }
    if (!found) throw bad(name + ": parameter " + pi.name + " missing");
  }
  calib::effects::set_effect_vector(fx, e->id, v);
  std::ostringstream os;
  os.precision(3);
  os << name;
  if (f.contains("magnitude") && f["magnitude"].is_number())
    os << " = " << f["magnitude"].get<double>() << " " << f.value("unit", "");
  return os.str();
}

}  // namespace

DiagnosedEffects diagnosed_effects(const nlohmann::json& j, const std::string& origin) {
  if (!j.is_object() || !j.contains("verdict"))
    throw std::invalid_argument(origin + ": not a gap diagnosis (no \"verdict\")");
  DiagnosedEffects out;
  // The whole explained set (each effect's size from their joint fit) when the diagnosis has its
  // steps; a diagnosis written before them (or a summary) by its best effect and the second.
  if (j.contains("steps") && j["steps"].is_array() && !j["steps"].empty() &&
      j["steps"][0].contains("parameters")) {
    // A noise member of the set (bias instability, quantisation, the output filter) is a property
    // of the unit's noise, not a signal to subtract: the deterministic members are removed, the
    // noise ones left to the noise model. A set of noise members only is refused below (as a
    // best finding that is noise is, by remove_sensor_effects).
    std::string noise_only;
    for (size_t i = 0; i < j["steps"].size(); ++i) {
      const nlohmann::json& st = j["steps"][i];
      const calib::effects::EffectInfo* e =
          st.is_object() && st.contains("effect") && st["effect"].is_string()
              ? calib::effects::find_effect(st["effect"].get<std::string>())
              : nullptr;
      if (e && e->kind == calib::effects::EffectKind::kStochastic) {
        noise_only += (noise_only.empty() ? "" : ", ") + e->name;
        continue;
      }
      out.names.push_back(
          add_finding(st, origin + ": steps[" + std::to_string(i) + "]", out.effects));
    }
    if (out.names.empty() && !noise_only.empty())
      throw std::invalid_argument(origin + ": the diagnosis names only noise (" + noise_only +
                                  "): it is noise, it cannot be removed from the data (declare it "
                                  "in the noise model)");
  } else {
    for (const char* k : {"best", "second"}) {
      if (!j.contains(k) || j[k].is_null()) continue;
      out.names.push_back(add_finding(j[k], origin + ": " + k, out.effects));
    }
  }
  if (out.names.empty())
    throw std::invalid_argument(origin + ": the diagnosis names no effect to compensate (verdict " +
                                j["verdict"].dump() + ")");
  return out;
}

}  // namespace imucal::db::archive
