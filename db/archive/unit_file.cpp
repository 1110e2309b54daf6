#include "db/archive/unit_file.hpp"

#include <cmath>
#include <set>

#include "calib/conventions.hpp"
#include "db/archive/archive_error.hpp"
#include "db/archive/io_util.hpp"
#include "db/archive/param_json.hpp"
#include "db/archive/toml_util.hpp"

namespace imucal::archive {

namespace {

// Human unit -> SI, one fixed expression per unit. The writer inverts these with human_for_si so
// that write-then-read reproduces the SI doubles.
double ug_to_mps2(double h) { return h * kMicroG_mps2; }
double ppm_to_1(double h) { return h / 1e6; }  // division by an exact 1e6: correctly rounded
double deg_per_h_to_radps(double h) { return h * kDegPerHourToRadPerSec; }
double arcsec_to_rad(double h) { return h * kArcsecToRad; }
double arw_to_si(double h) { return h * kDegToRad / 60.0; }             // deg/√h -> rad/√s
double vrw_to_si(double h) { return h * kMicroG_mps2; }                 // µg/√Hz -> (m/s)/√s
double k2_to_si(double h) { return h * 1e-6 / kStandardGravity_mps2; }  // µg/g² -> 1/(m/s²)
double gsens_to_si(double h) { return h * kDegPerHourToRadPerSec / kStandardGravity_mps2; }
double identity(double h) { return h; }

using Conv = double (*)(double);

double to_human(double si, Conv to_si) {
  const double unit = to_si(1.0);
  return human_for_si(si, si / unit, to_si);
}
Eigen::Vector3d to_human(const Eigen::Vector3d& si, Conv to_si) {
  return {to_human(si(0), to_si), to_human(si(1), to_si), to_human(si(2), to_si)};
}
Eigen::Matrix3d to_human(const Eigen::Matrix3d& si, Conv to_si) {
  Eigen::Matrix3d h;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) h(r, c) = to_human(si(r, c), to_si);
  return h;
}
Eigen::Vector3d to_si(const Eigen::Vector3d& h, Conv f) { return {f(h(0)), f(h(1)), f(h(2))}; }
Eigen::Matrix3d to_si(const Eigen::Matrix3d& h, Conv f) {
  Eigen::Matrix3d m;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 3; ++c) m(r, c) = f(h(r, c));
  return m;
}

// Noise fields: (unit-file key, SI member, conversion, must be > 0 instead of >= 0).
struct NoiseField {
  const char* unit_key;
  const char* json_key;
  double calib::NoiseModel::*member;
  Conv to_si;
  bool strictly_positive;
};
const NoiseField kNoiseFields[] = {
    {"arw_deg_per_sqrt_h", "arw_rad_per_sqrt_s", &calib::NoiseModel::arw_rad_per_sqrt_s, arw_to_si,
     false},
    {"vrw_ug_per_sqrt_hz", "vrw_mps_per_sqrt_s", &calib::NoiseModel::vrw_mps_per_sqrt_s, vrw_to_si,
     false},
    {"gyro_bias_instability_deg_per_h", "gyro_bias_instability_radps",
     &calib::NoiseModel::gyro_bias_instability_radps, deg_per_h_to_radps, false},
    {"gyro_bias_tau_s", "gyro_bias_tau_s", &calib::NoiseModel::gyro_bias_tau_s, identity, true},
    {"accel_bias_instability_ug", "accel_bias_instability_mps2",
     &calib::NoiseModel::accel_bias_instability_mps2, ug_to_mps2, false},
    {"accel_bias_tau_s", "accel_bias_tau_s", &calib::NoiseModel::accel_bias_tau_s, identity, true},
    {"dtheta_lsb_rad", "dtheta_lsb_rad", &calib::NoiseModel::dtheta_lsb_rad, identity, false},
    {"dv_lsb_mps", "dv_lsb_mps", &calib::NoiseModel::dv_lsb_mps, identity, false},
};

void check_noise_value(const NoiseField& f, double v, const std::string& origin, std::size_t line,
                       const std::string& field) {
  if (f.strictly_positive ? !(v > 0.0) : !(v >= 0.0))
    throw ArchiveError(origin, line,
                       std::string("must be ") + (f.strictly_positive ? "> 0" : ">= 0") + ", got " +
                           format_double(v),
                       field);
}

}  // namespace

calib::UnitModel parse_unit_file(const std::string& text, const std::string& origin) {
  const toml::table tbl = parse_toml_text(text, origin);
  const TomlSection root(tbl, origin, "", {"accel", "gyro", "table", "noise", "effects"});
  calib::UnitModel u;
  u.params = calib::ParamSet{};  // missing keys mean zero
  u.effects = calib::Effects{};
  u.noise = calib::NoiseModel{};  // missing noise keys take these defaults

  if (auto s = root.section("accel", {"bias_ug", "M_ppm"})) {
    if (auto v = s->vec3("bias_ug")) u.params.accel_bias_mps2 = to_si(*v, ug_to_mps2);
    if (auto m = s->mat3("M_ppm")) u.params.accel_M = to_si(*m, ppm_to_1);
  }
  if (auto s = root.section("gyro", {"bias_deg_per_h", "M_ppm"})) {
    if (auto v = s->vec3("bias_deg_per_h"))
      u.params.gyro_bias_radps = to_si(*v, deg_per_h_to_radps);
    if (auto m = s->mat3("M_ppm")) u.params.gyro_M = to_si(*m, ppm_to_1);
  }
  if (auto s = root.section("table", {"misalignment_arcsec"})) {
    if (auto v = s->vec3("misalignment_arcsec"))
      u.params.table_misalignment_rad = to_si(*v, arcsec_to_rad);
  }
  if (auto s = root.section(
          "noise", {"arw_deg_per_sqrt_h", "vrw_ug_per_sqrt_hz", "gyro_bias_instability_deg_per_h",
                    "gyro_bias_tau_s", "accel_bias_instability_ug", "accel_bias_tau_s",
                    "dtheta_lsb_rad", "dv_lsb_mps"})) {
    for (const NoiseField& f : kNoiseFields)
      if (auto h = s->number(f.unit_key)) {
        check_noise_value(f, *h, origin, s->line_of(f.unit_key), s->path(f.unit_key));
        u.noise.*f.member = f.to_si(*h);
      }
  }
  if (auto s = root.section("effects", {"k2_ug_per_g2", "asym_ppm", "g_sens_deg_per_h_per_g",
                                        "lever_arm_m", "table_time_offset_s"})) {
    if (auto v = s->vec3("k2_ug_per_g2")) u.effects.accel_k2_per_mps2 = to_si(*v, k2_to_si);
    if (auto v = s->vec3("asym_ppm")) u.effects.accel_asym = to_si(*v, ppm_to_1);
    if (auto m = s->mat3("g_sens_deg_per_h_per_g")) u.effects.gyro_g_sens = to_si(*m, gsens_to_si);
    if (auto m = s->mat3("lever_arm_m"))
      for (int i = 0; i < 3; ++i)
        u.effects.accel_lever_arm_m[static_cast<size_t>(i)] = m->row(i).transpose();
    if (auto t = s->number("table_time_offset_s")) u.effects.table_time_offset_s = *t;
  }
  return u;
}

calib::UnitModel read_unit_file(const std::string& path) {
  return parse_unit_file(read_text_file(path), path);
}

std::string unit_file_text(const calib::UnitModel& u) {
  TomlWriter w;
  w.comment("IMU unit model (db/archive/FORMAT.md). Human units; M_ppm: diagonal = scale-factor");
  w.comment("error in ppm, off-diagonal = misalignment in µrad (both 1e-6).");
  w.section("accel");
  w.key("bias_ug", to_human(u.params.accel_bias_mps2, ug_to_mps2));
  w.key("M_ppm", to_human(u.params.accel_M, ppm_to_1));
  w.section("gyro");
  w.key("bias_deg_per_h", to_human(u.params.gyro_bias_radps, deg_per_h_to_radps));
  w.key("M_ppm", to_human(u.params.gyro_M, ppm_to_1));
  w.section("table");
  w.key("misalignment_arcsec", to_human(u.params.table_misalignment_rad, arcsec_to_rad));
  w.section("noise");
  for (const NoiseField& f : kNoiseFields) w.key(f.unit_key, to_human(u.noise.*f.member, f.to_si));
  w.section("effects");
  w.key("k2_ug_per_g2", to_human(u.effects.accel_k2_per_mps2, k2_to_si));
  w.key("asym_ppm", to_human(u.effects.accel_asym, ppm_to_1));
  w.key("g_sens_deg_per_h_per_g", to_human(u.effects.gyro_g_sens, gsens_to_si));
  Eigen::Matrix3d lever;
  for (int i = 0; i < 3; ++i)
    lever.row(i) = u.effects.accel_lever_arm_m[static_cast<size_t>(i)].transpose();
  w.key("lever_arm_m", lever);
  w.key("table_time_offset_s", u.effects.table_time_offset_s);
  return w.text();
}

void write_unit_file(const std::string& path, const calib::UnitModel& unit) {
  write_file_atomic(path, unit_file_text(unit));
}

Truth truth_from_unit(const calib::UnitModel& unit) {
  return Truth{unit.params, unit.effects.active_names(), unit.noise};
}

std::string truth_json_text(const Truth& truth) {
  nlohmann::json j = nlohmann::json::object();
  j["params"] = param_set_to_json(truth.params);
  std::set<std::string> seen;
  for (const auto& e : truth.effects) {
    if (e.empty() || !seen.insert(e).second)
      throw ArchiveError::field_error(
          "<truth>", "effects", e.empty() ? "empty effect name" : "duplicate effect '" + e + "'");
  }
  j["effects"] = truth.effects;
  nlohmann::json n = nlohmann::json::object();
  for (const NoiseField& f : kNoiseFields) {
    const double v = truth.noise.*f.member;
    if (!std::isfinite(v))
      throw ArchiveError::field_error("<truth>", std::string("noise.") + f.json_key,
                                      "cannot write NaN or Inf");
    n[f.json_key] = v;
  }
  j["noise"] = n;
  return j.dump(2) + "\n";
}

Truth parse_truth_json(const std::string& text, const std::string& origin) {
  const nlohmann::json j = parse_json_text(text, origin);
  if (!j.is_object())
    throw ArchiveError::field_error(origin, "<root>",
                                    std::string("expected a JSON object, got ") + j.type_name());
  for (auto it = j.begin(); it != j.end(); ++it)
    if (it.key() != "params" && it.key() != "effects" && it.key() != "noise")
      throw ArchiveError::field_error(origin, it.key(),
                                      "unknown field (expected params, effects, noise)");
  for (const char* k : {"params", "effects", "noise"})
    if (!j.contains(k)) throw ArchiveError::field_error(origin, k, "missing");

  Truth t;
  // Field paths inside params are reported relative to "params".
  try {
    t.params = param_set_from_json(j["params"], origin, nullptr);
  } catch (const ArchiveError& e) {
    throw ArchiveError::field_error(origin, "params." + e.field(), e.message());
  }
  const auto& eff = j["effects"];
  if (!eff.is_array())
    throw ArchiveError::field_error(
        origin, "effects", std::string("expected an array of strings, got ") + eff.type_name());
  std::set<std::string> seen;
  for (size_t i = 0; i < eff.size(); ++i) {
    const std::string field = "effects[" + std::to_string(i) + "]";
    if (!eff[i].is_string())
      throw ArchiveError::field_error(origin, field,
                                      std::string("expected a string, got ") + eff[i].type_name());
    const std::string name = eff[i].get<std::string>();
    if (name.empty()) throw ArchiveError::field_error(origin, field, "empty effect name");
    if (!seen.insert(name).second)
      throw ArchiveError::field_error(origin, field, "duplicate effect '" + name + "'");
    t.effects.push_back(name);
  }
  const auto& n = j["noise"];
  if (!n.is_object())
    throw ArchiveError::field_error(origin, "noise",
                                    std::string("expected an object, got ") + n.type_name());
  for (auto it = n.begin(); it != n.end(); ++it) {
    bool known = false;
    for (const NoiseField& f : kNoiseFields) known = known || it.key() == f.json_key;
    if (!known) throw ArchiveError::field_error(origin, "noise." + it.key(), "unknown field");
  }
  for (const NoiseField& f : kNoiseFields) {
    const std::string field = std::string("noise.") + f.json_key;
    if (!n.contains(f.json_key)) throw ArchiveError::field_error(origin, field, "missing");
    const auto& v = n[f.json_key];
    if (!v.is_number())
      throw ArchiveError::field_error(origin, field,
                                      std::string("expected a number, got ") + v.type_name());
    const double x = v.get<double>();
    if (!std::isfinite(x)) throw ArchiveError::field_error(origin, field, "not a finite number");
    check_noise_value(f, x, origin, 0, field);
    t.noise.*f.member = x;
  }
  return t;
}

void write_truth_json(const std::string& path, const Truth& truth) {
  write_file_atomic(path, truth_json_text(truth));
}

Truth read_truth_json(const std::string& path) {
  return parse_truth_json(read_text_file(path), path);
}

}  // namespace imucal::archive
