#include "db/archive/unit_file.hpp"

#include <cmath>
#include <set>

#include "calib/core/conventions.hpp"
#include "calib/effects/catalogue.hpp"
#include "db/archive/archive_error.hpp"
#include "db/archive/human_units.hpp"
#include "db/archive/io_util.hpp"
#include "db/archive/param_json.hpp"
#include "db/archive/toml_util.hpp"

namespace imucal::db::archive {

namespace {

// Human unit -> SI, one fixed expression per unit. The writer inverts these with human_for_si so
// that write-then-read reproduces the SI doubles.
double ug_to_mps2(double h) { return h * kMicroG_mps2; }
double ppm_to_1(double h) { return h / 1e6; }  // division by an exact 1e6: correctly rounded
double deg_per_h_to_radps(double h) { return h * kDegPerHourToRadPerSec; }
double arcsec_to_rad(double h) { return h * kArcsecToRad; }
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
  double calib::core::NoiseModel::*member;
  Conv to_si;
  bool strictly_positive;
};
const NoiseField kNoiseFields[] = {
    {"arw_deg_per_sqrt_h", "arw_rad_per_sqrt_s", &calib::core::NoiseModel::arw_rad_per_sqrt_s,
     arw_to_si, false},
    {"vrw_ug_per_sqrt_hz", "vrw_mps_per_sqrt_s", &calib::core::NoiseModel::vrw_mps_per_sqrt_s,
     vrw_to_si, false},
    {"gyro_bias_instability_deg_per_h", "gyro_bias_instability_radps",
     &calib::core::NoiseModel::gyro_bias_instability_radps, deg_per_h_to_radps, false},
    {"gyro_bias_tau_s", "gyro_bias_tau_s", &calib::core::NoiseModel::gyro_bias_tau_s, identity,
     true},
    {"accel_bias_instability_ug", "accel_bias_instability_mps2",
     &calib::core::NoiseModel::accel_bias_instability_mps2, ug_to_mps2, false},
    {"accel_bias_tau_s", "accel_bias_tau_s", &calib::core::NoiseModel::accel_bias_tau_s, identity,
     true},
    {"dtheta_lsb_rad", "dtheta_lsb_rad", &calib::core::NoiseModel::dtheta_lsb_rad, identity, false},
    {"dv_lsb_mps", "dv_lsb_mps", &calib::core::NoiseModel::dv_lsb_mps, identity, false},
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

namespace {

/// The human-unit keys of the first five effects (kept for existing unit files).
const std::vector<std::string_view> kHumanEffectKeys = {
    "k2_ug_per_g2", "asym_ppm", "g_sens_deg_per_h_per_g", "lever_arm_m", "table_time_offset_s"};

/// [effects]: every catalogue effect by its name with its SI parameter vector (the order of
/// `--effect NAME=V,...`, trailing shape parameters optional), plus the older human-unit keys. One
/// effect given both ways is refused.
void parse_effects_section(const TomlSection& root, calib::effects::UnitModel& u) {
  std::vector<std::string_view> allowed = kHumanEffectKeys;
  for (const auto& e : calib::effects::effect_catalogue()) allowed.push_back(e.name);
  const auto s = root.section("effects", allowed);
  if (!s) return;
  if (auto v = s->vec3("k2_ug_per_g2")) u.effects.accel_k2_per_mps2 = to_si(*v, k2_to_si);
  if (auto v = s->vec3("asym_ppm")) u.effects.accel_asym = to_si(*v, ppm_to_1);
  if (auto m = s->mat3("g_sens_deg_per_h_per_g")) u.effects.gyro_g_sens = to_si(*m, gsens_to_si);
  if (auto m = s->mat3("lever_arm_m"))
    for (int i = 0; i < 3; ++i)
      u.effects.accel_lever_arm_m[static_cast<size_t>(i)] = m->row(i).transpose();
  if (auto t = s->number("table_time_offset_s")) u.effects.table_time_offset_s = *t;
  const std::pair<const char*, calib::effects::EffectId> same[] = {
      {"k2_ug_per_g2", calib::effects::EffectId::kAccelQuadraticK2},
      {"asym_ppm", calib::effects::EffectId::kAccelAsymmetry},
      {"g_sens_deg_per_h_per_g", calib::effects::EffectId::kGyroGSensitivity},
      {"lever_arm_m", calib::effects::EffectId::kSizeEffect},
      {"table_time_offset_s", calib::effects::EffectId::kTableTimeOffset}};
  for (const auto& e : calib::effects::effect_catalogue()) {
    const auto v = s->numbers(e.name);
    if (!v) continue;
    for (const auto& [key, id] : same)
      if (id == e.id && s->has(key))
        s->fail(e.name, "effect " + e.name + " is also given as " + key + "; give it once");
    std::string spec = e.name + "=";
    for (size_t i = 0; i < v->size(); ++i) spec += (i ? "," : "") + format_double((*v)[i]);
    try {
      calib::effects::apply_effect_spec(u.effects, spec);
    } catch (const std::invalid_argument& ex) {
      s->fail(e.name, ex.what());
    }
  }
}

}  // namespace

calib::effects::UnitModel parse_unit_file(const std::string& text, const std::string& origin) {
  const toml::table tbl = parse_toml_text(text, origin);
  const TomlSection root(tbl, origin, "", {"grade", "accel", "gyro", "table", "noise", "effects"});
  calib::effects::UnitModel u;
  if (const auto g = root.string("grade")) {
    const std::optional<calib::core::Grade> grade = calib::core::parse_grade(*g);
    if (!grade) root.fail("grade", "\"" + *g + "\" is not a grade (navigation, tactical or mems)");
    u.grade = *grade;
  }
  u.params = calib::core::ParamSet{};  // missing keys mean zero
  u.effects = calib::effects::Effects{};
  u.noise = calib::core::NoiseModel{};  // missing noise keys take these defaults

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
  parse_effects_section(root, u);
  return u;
}

calib::effects::UnitModel read_unit_file(const std::string& path) {
  return parse_unit_file(read_text_file(path), path);
}

std::string unit_file_text(const calib::effects::UnitModel& u) {
  TomlWriter w;
  w.comment("IMU unit model (db/archive/FORMAT.md). Human units; M_ppm: diagonal = scale-factor");
  w.comment("error in ppm, off-diagonal = misalignment in µrad (both 1e-6).");
  if (u.grade != calib::core::Grade::kNavigation) w.key("grade", calib::core::grade_name(u.grade));
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
  for (const auto& e : calib::effects::effect_catalogue()) {
    bool human = false;
    for (auto id :
         {calib::effects::EffectId::kAccelQuadraticK2, calib::effects::EffectId::kAccelAsymmetry,
          calib::effects::EffectId::kGyroGSensitivity, calib::effects::EffectId::kSizeEffect,
          calib::effects::EffectId::kTableTimeOffset})
      human = human || id == e.id;
    if (human || !u.effects.active(e.id)) continue;
    const Eigen::VectorXd v = calib::effects::effect_vector(u.effects, e.id);
    w.key(e.name, std::vector<double>(v.data(), v.data() + v.size()));
  }
  return w.text();
}

void write_unit_file(const std::string& path, const calib::effects::UnitModel& unit) {
  write_file_atomic(path, unit_file_text(unit));
}

Truth truth_from_unit(const calib::effects::UnitModel& unit) {
  Truth t;
  t.params = unit.params;
  t.effects = unit.effects;
  t.noise = unit.noise;
  return t;
}

namespace {

nlohmann::json effects_json(const Truth& truth) {
  if (!truth.effect_values_known) return truth.legacy_effect_names;
  nlohmann::json e = nlohmann::json::object();
  for (const auto& info : calib::effects::effect_catalogue()) {
    if (!truth.effects.active(info.id)) continue;
    const Eigen::VectorXd v = calib::effects::effect_vector(truth.effects, info.id);
    nlohmann::json o = nlohmann::json::object();
    for (int i = 0; i < info.size(); ++i) {
      if (!std::isfinite(v(i)))
        throw ArchiveError::field_error("<truth>", "effects." + info.name, "cannot write NaN or Inf");
      o[info.params[static_cast<size_t>(i)].name] = v(i);
    }
    e[info.name] = o;
  }
  return e;
}

/// "effects": {"<name>": {"<param>": value}} — every parameter of the catalogue entry, no other.
void parse_effect_values(const nlohmann::json& eff, const std::string& origin, Truth& t) {
  for (auto it = eff.begin(); it != eff.end(); ++it) {
    const std::string base = "effects." + it.key();
    const calib::effects::EffectInfo* info = calib::effects::find_effect(it.key());
    if (!info)
      throw ArchiveError::field_error(
          origin, base, "unknown effect (known: " + calib::effects::effect_names_list() + ")");
    if (!it->is_object())
      throw ArchiveError::field_error(origin, base,
                                      std::string("expected an object, got ") + it->type_name());
    for (auto p = it->begin(); p != it->end(); ++p) {
      bool known = false;
      for (const auto& pi : info->params) known = known || pi.name == p.key();
      if (!known) throw ArchiveError::field_error(origin, base + "." + p.key(), "unknown parameter");
    }
    Eigen::VectorXd v(info->size());
    for (int i = 0; i < info->size(); ++i) {
      const std::string& name = info->params[static_cast<size_t>(i)].name;
      const std::string field = base + "." + name;
      if (!it->contains(name)) throw ArchiveError::field_error(origin, field, "missing");
      const auto& x = (*it)[name];
      if (!x.is_number())
        throw ArchiveError::field_error(origin, field,
                                        std::string("expected a number, got ") + x.type_name());
      v(i) = x.get<double>();
    }
    try {
      calib::effects::set_effect_vector(t.effects, info->id, v);
    } catch (const std::invalid_argument& e) {
      throw ArchiveError::field_error(origin, base, e.what());
    }
  }
}

/// The older form: a list of names (values unknown).
void parse_effect_names(const nlohmann::json& eff, const std::string& origin, Truth& t) {
  t.effect_values_known = false;
  std::set<std::string> seen;
  for (size_t i = 0; i < eff.size(); ++i) {
    const std::string field = "effects[" + std::to_string(i) + "]";
    if (!eff[i].is_string())
      throw ArchiveError::field_error(origin, field,
                                      std::string("expected a string, got ") + eff[i].type_name());
    const std::string name = eff[i].get<std::string>();
    if (name.empty()) throw ArchiveError::field_error(origin, field, "empty effect name");
    if (!calib::effects::find_effect(name))
      throw ArchiveError::field_error(
          origin, field,
          "unknown effect '" + name + "' (known: " + calib::effects::effect_names_list() + ")");
    if (!seen.insert(name).second)
      throw ArchiveError::field_error(origin, field, "duplicate effect '" + name + "'");
    t.legacy_effect_names.push_back(name);
  }
}

}  // namespace

std::string truth_json_text(const Truth& truth) {
  nlohmann::json j = nlohmann::json::object();
  j["params"] = param_set_to_json(truth.params);
  j["effects"] = effects_json(truth);
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
  if (eff.is_object())
    parse_effect_values(eff, origin, t);
  else if (eff.is_array())
    parse_effect_names(eff, origin, t);
  else
    throw ArchiveError::field_error(
        origin, "effects",
        std::string("expected an object of effect values, got ") + eff.type_name());
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

}  // namespace imucal::db::archive
