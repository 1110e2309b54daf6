#include "tools/altsim/alt_effects.hpp"

#include <cmath>
#include <cstdlib>
#include <sstream>
#include <stdexcept>

namespace imucal::tools::altsim {

namespace {

std::vector<std::string> per_axis(const std::string& prefix) {
  return {prefix + "x", prefix + "y", prefix + "z"};
}

std::vector<std::string> per_pair(const std::string& prefix, const std::string& sep) {
  std::vector<std::string> v;
  for (const char* a : {"x", "y", "z"})
    for (const char* b : {"x", "y", "z"}) v.push_back(prefix + a + sep + b);
  return v;
}

std::vector<AltEffectParams> build_table() {
  return {
      {"accel_quadratic_k2", per_axis("k2_"), false},
      {"accel_asymmetry", per_axis("kap_"), false},
      {"size_effect", per_pair("r_", "_"), false},        // r_<accelerometer>_<component>
      {"gyro_g_sensitivity", per_pair("G_", ""), false},  // G_<gyro><force axis>, row-major
      {"gyro_accel_skew", {"t_GA"}, false},
      {"table_time_offset", {"dt"}, false},
      {"thermal_drift",
       {"accel_x", "accel_y", "accel_z", "gyro_x", "gyro_y", "gyro_z", "tau"},
       true},
      {"bias_instability", {"gyro_sigma", "accel_sigma", "tau"}, true},
      {"table_nonorthogonality", {"delta"}, false},
      {"table_wobble", {"w_x", "w_y"}, false},
      {"gravity_error", {"dg"}, false},
      {"latitude_error", {"dlat"}, false},
      {"quantisation", {"dtheta_lsb", "dv_lsb"}, false},
      {"output_filter", {"gyro_a", "accel_a"}, false},
      {"rest_tremor", {"rate_rms", "tilt_rms", "pivot"}, true},
  };
}

const AltEffectParams& find(const std::string& name) {
  for (const auto& e : alt_effect_table())
    if (e.name == name) return e;
  throw std::invalid_argument("unknown effect '" + name + "' (known: " + alt_effect_names() + ")");
}

/// Pointers to the fields behind each effect's parameters, in table order.
std::vector<double*> fields(AltEffects& fx, const std::string& name) {
  auto v3 = [](Eigen::Vector3d& v) { return std::vector<double*>{&v.x(), &v.y(), &v.z()}; };
  if (name == "accel_quadratic_k2") return v3(fx.accel_k2_per_mps2);
  if (name == "accel_asymmetry") return v3(fx.accel_asym);
  if (name == "size_effect") {
    std::vector<double*> p;
    for (auto& r : fx.accel_lever_arm_m)
      for (int j = 0; j < 3; ++j) p.push_back(&r(j));
    return p;
  }
  if (name == "gyro_g_sensitivity") {
    std::vector<double*> p;
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) p.push_back(&fx.gyro_g_sens(i, j));
    return p;
  }
  if (name == "gyro_accel_skew") return {&fx.gyro_accel_skew_s};
  if (name == "table_time_offset") return {&fx.table_time_offset_s};
  if (name == "thermal_drift") {
    std::vector<double*> p = v3(fx.thermal_accel_mps2);
    for (double* g : v3(fx.thermal_gyro_radps)) p.push_back(g);
    p.push_back(&fx.thermal_tau_s);
    return p;
  }
  if (name == "bias_instability")
    return {&fx.instability_gyro_radps, &fx.instability_accel_mps2, &fx.instability_tau_s};
  if (name == "table_nonorthogonality") return {&fx.table_nonorthogonality_rad};
  if (name == "table_wobble") return {&fx.table_wobble_rad.x(), &fx.table_wobble_rad.y()};
  if (name == "gravity_error") return {&fx.gravity_error_mps2};
  if (name == "latitude_error") return {&fx.latitude_error_rad};
  if (name == "quantisation") return {&fx.quant_dtheta_rad, &fx.quant_dv_mps};
  if (name == "output_filter") return {&fx.output_filter_gyro, &fx.output_filter_accel};
  if (name == "rest_tremor")
    return {&fx.tremor_rate_rms_radps, &fx.tremor_tilt_rms_rad, &fx.tremor_pivot_m};
  throw std::invalid_argument("unknown effect '" + name + "' (known: " + alt_effect_names() + ")");
}

std::string param_list(const AltEffectParams& e) {
  std::string s;
  for (size_t i = 0; i < e.params.size(); ++i)
    s += (i ? ", " : "") + e.params[i] +
         (e.trailing_shape && i + 1 == e.params.size() ? " (optional, > 0)" : "");
  return s;
}

std::vector<double> parse_values(const AltEffectParams& e, const std::string& text) {
  std::vector<double> vals;
  std::stringstream ss(text);
  std::string tok;
  while (std::getline(ss, tok, ',')) {
    char* end = nullptr;
    const double x = tok.empty() ? NAN : std::strtod(tok.c_str(), &end);
    if (tok.empty() || end != tok.c_str() + tok.size() || !std::isfinite(x))
      throw std::invalid_argument("effect " + e.name + ": '" + tok +
                                  "' is not a finite number (values: " + param_list(e) + ")");
    vals.push_back(x);
  }
  return vals;
}

}  // namespace

const std::vector<AltEffectParams>& alt_effect_table() {
  static const std::vector<AltEffectParams> t = build_table();
  return t;
}

std::string alt_effect_names() {
  std::string s;
  for (const auto& e : alt_effect_table()) s += (s.empty() ? "" : ", ") + e.name;
  return s;
}

std::vector<double> alt_effect_values(const AltEffects& fx, const std::string& name) {
  AltEffects copy = fx;
  std::vector<double> v;
  for (double* p : fields(copy, name)) v.push_back(*p);
  return v;
}

bool alt_effect_active(const AltEffects& fx, const std::string& name) {
  const AltEffectParams& e = find(name);
  const std::vector<double> v = alt_effect_values(fx, name);
  const size_t amplitudes = v.size() - (e.trailing_shape ? 1 : 0);
  for (size_t i = 0; i < amplitudes; ++i)
    if (v[i] != 0.0) return true;
  return false;
}

void apply_alt_effect_spec(AltEffects& fx, const std::string& spec) {
  const size_t eq = spec.find('=');
  const AltEffectParams& e = find(spec.substr(0, eq));
  if (eq == std::string::npos || eq + 1 >= spec.size())
    throw std::invalid_argument("effect " + e.name + ": expected " + e.name + "=V[,V...] with " +
                                param_list(e));
  const std::vector<double> vals = parse_values(e, spec.substr(eq + 1));
  const size_t all = e.params.size(), required = all - (e.trailing_shape ? 1 : 0);
  if (vals.size() < required || vals.size() > all)
    throw std::invalid_argument("effect " + e.name + ": expected " + std::to_string(required) +
                                (required == all ? "" : "-" + std::to_string(all)) + " value(s) (" +
                                param_list(e) + "), got " + std::to_string(vals.size()));
  if (e.trailing_shape && vals.size() == all && !(vals.back() > 0.0))
    throw std::invalid_argument("effect " + e.name + ": " + e.params.back() + " must be > 0");
  if ((e.name == "bias_instability" || e.name == "quantisation" || e.name == "rest_tremor") &&
      (vals[0] < 0.0 || vals[1] < 0.0))
    throw std::invalid_argument("effect " + e.name + ": sigmas, LSBs and RMS values must be >= 0");
  if (e.name == "output_filter" &&
      !(vals[0] >= 0.0 && vals[0] < 1.0 && vals[1] >= 0.0 && vals[1] < 1.0))
    throw std::invalid_argument("effect output_filter: coefficients must be in [0, 1)");
  const std::vector<double*> f = fields(fx, e.name);
  for (size_t i = 0; i < vals.size(); ++i) *f[i] = vals[i];
}

}  // namespace imucal::tools::altsim
