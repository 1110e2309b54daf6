#include "calib/effects/catalogue.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace imucal::calib::effects {

namespace {

constexpr double kG0 = kStandardGravity_mps2;
constexpr double kUg = 1.0 / kMicroG_mps2;             // m/s² -> µg
constexpr double kDph = 1.0 / kDegPerHourToRadPerSec;  // rad/s -> °/h
constexpr double kArcsec = 1.0 / kArcsecToRad;         // rad -> arcsec
constexpr double kArcmin = 1.0 / (kDegToRad / 60.0);   // rad -> arcmin
constexpr double kK2 = kG0 * 1e6;                      // 1/(m/s²) -> µg/g²
constexpr double kGsens = kG0 * kDph;                  // (rad/s)/(m/s²) -> (°/h)/g

EffectParamInfo p(std::string name, std::string si, std::string human, double k,
                  bool shape = false) {
  return {std::move(name), std::move(si), std::move(human), k, shape};
}

/// The first four entries: the accelerometer and gyro effects with per-axis parameters.
std::vector<EffectInfo> sensor_effects() {
  std::vector<EffectInfo> c;
  const char* xyz[3] = {"x", "y", "z"};
  {
    EffectInfo e{EffectId::kAccelQuadraticK2,
                 "accel_quadratic_k2",
                 EffectKind::kSensor,
                 "df_i = K2_i f_i^2",
                 "even in f: aliases into bias at +-1 g, shows at tilts",
                 {},
                 {},
                 {0, 1, 2}};
    for (auto a : xyz) e.params.push_back(p(std::string("k2_") + a, "1/(m/s^2)", "ug/g^2", kK2));
    e.typical = {20.0 / kK2, -15.0 / kK2, 25.0 / kK2};
    c.push_back(e);
  }
  {
    EffectInfo e{EffectId::kAccelAsymmetry,
                 "accel_asymmetry",
                 EffectKind::kSensor,
                 "df_i = Kap_i |f_i|",
                 "like K2 but |cos| instead of cos^2 at tilts",
                 {},
                 {},
                 {0, 1, 2}};
    for (auto a : xyz) e.params.push_back(p(std::string("kap_") + a, "1", "ppm", 1e6));
    e.typical = {10e-6, -8e-6, 12e-6};
    c.push_back(e);
  }
  {
    EffectInfo e{EffectId::kSizeEffect,
                 "size_effect",
                 EffectKind::kSensor,
                 "df_i = (([wdot x] + [w x]^2) r_i)_i, r_i = lever arm of accelerometer i",
                 "only while rotating: ~w^2 in cruise, spikes ~wdot",
                 {},
                 {},
                 {}};
    for (auto a : xyz)
      for (auto b : xyz) e.params.push_back(p(std::string("r_") + a + "_" + b, "m", "mm", 1e3));
    e.typical = {0.02, 0.01, 0.0, -0.01, 0.02, 0.0, 0.0, 0.01, 0.03};
    for (int i = 0; i < 9; ++i) e.magnitude_params.push_back(i);
    c.push_back(e);
  }
  {
    EffectInfo e{EffectId::kGyroGSensitivity,
                 "gyro_g_sensitivity",
                 EffectKind::kSensor,
                 "dw = G f (G 3x3, row i = output axis i)",
                 "static gyro bias changes with orientation",
                 {},
                 {},
                 {}};
    for (auto a : xyz)
      for (auto b : xyz)
        e.params.push_back(p(std::string("G_") + a + b, "(rad/s)/(m/s^2)", "deg/h/g", kGsens));
    e.typical = {0.005 / kGsens, 0.002 / kGsens, 0.0, 0.0,           -0.004 / kGsens,
                 0.002 / kGsens, 0.001 / kGsens, 0.0, 0.006 / kGsens};
    for (int i = 0; i < 9; ++i) e.magnitude_params.push_back(i);
    c.push_back(e);
  }
  return c;
}

/// Skew, time offset, warm-up, instability, table, site and quantisation entries (catalogue order).
void add_remaining_effects(std::vector<EffectInfo>& c) {
  const char* xyz[3] = {"x", "y", "z"};
  c.push_back({EffectId::kGyroAccelSkew,
               "gyro_accel_skew",
               EffectKind::kSensor,
               "df = t_GA (w x f): the accelerometers sample t_GA after the gyros",
               "only while rotating, sign flips with the direction",
               {p("t_GA", "s", "ms", 1e3)},
               {0.5e-3},
               {0}});
  c.push_back({EffectId::kTableTimeOffset,
               "table_time_offset",
               EffectKind::kTable,
               "encoder angles(t) = true angles(t - dt)",
               "only where encoder angles during motion are used",
               {p("dt", "s", "ms", 1e3)},
               {5e-3},
               {0}});
  {
    EffectInfo e{EffectId::kThermalDrift,
                 "thermal_drift",
                 EffectKind::kSensor,
                 "b(t) = b + A exp(-t/tau), t from the run's first sample",
                 "time trend, not orientation-locked",
                 {},
                 {},
                 {}};
    for (auto a : xyz) e.params.push_back(p(std::string("accel_") + a, "m/s^2", "ug", kUg));
    for (auto a : xyz) e.params.push_back(p(std::string("gyro_") + a, "rad/s", "deg/h", kDph));
    e.params.push_back(p("tau", "s", "s", 1.0, true));
    e.typical = {20.0 / kUg,   -20.0 / kUg,   20.0 / kUg, 0.005 / kDph,
                 0.005 / kDph, -0.005 / kDph, 900.0};
    c.push_back(e);
  }
  c.push_back({EffectId::kBiasInstability,
               "bias_instability",
               EffectKind::kStochastic,
               "first-order Gauss-Markov bias per axis (sigma, tau), not in the noise model",
               "run-to-run, long-lag autocorrelation of the rest residuals",
               {p("gyro_sigma", "rad/s", "deg/h", kDph), p("accel_sigma", "m/s^2", "ug", kUg),
                p("tau", "s", "s", 1.0, true)},
               {0.001 / kDph, 10.0 / kUg, 1000.0},
               {}});
  c.push_back(
      {EffectId::kTableNonorthogonality,
       "table_nonorthogonality",
       EffectKind::kTable,
       "inner axis = Ry(delta) e_z in the outer-gimbal frame (90 deg - delta to the outer axis)",
       "biases misalignment terms",
       {p("delta", "rad", "arcsec", kArcsec)},
       {5.0 / kArcsec},
       {0}});
  c.push_back({EffectId::kTableWobble,
               "table_wobble",
               EffectKind::kTable,
               "platform tilt delta_o(inner) = Rz(-inner) (w_x, w_y, 0)",
               "residual periodic in the inner angle",
               {p("w_x", "rad", "arcsec", kArcsec), p("w_y", "rad", "arcsec", kArcsec)},
               {3.0 / kArcsec, -2.0 / kArcsec},
               {0, 1}});
  c.push_back({EffectId::kGravityError,
               "gravity_error",
               EffectKind::kSite,
               "true g = configured g + dg",
               "scale-factor-like, all axes",
               {p("dg", "m/s^2", "ug", kUg)},
               {20.0 / kUg},
               {0}});
  c.push_back({EffectId::kLatitudeError,
               "latitude_error",
               EffectKind::kSite,
               "true latitude = configured latitude + dlat",
               "orientation-dependent gyro residual",
               {p("dlat", "rad", "arcmin", kArcmin)},
               {1.0 / kArcmin},
               {0}});
  c.push_back({EffectId::kQuantisation,
               "quantisation",
               EffectKind::kStochastic,
               "increments rounded to the LSB (remainder carried)",
               "white, Allan slope -1",
               {p("dtheta_lsb", "rad", "nrad", 1e9), p("dv_lsb", "m/s", "um/s", 1e6)},
               {5e-8, 1e-5},
               {}});
  // A navigation-grade unit's increments are hardly filtered: typical a = 0.2 (a corner near
  // 0.26/dt, 26 Hz at 100 Hz). Measured on IMU-TK's Xsens recording: 0.085 gyro, 0.16
  // accelerometer (issue #48); a stronger anti-alias stage gives up to 0.9.
  c.push_back({EffectId::kOutputFilter,
               "output_filter",
               EffectKind::kStochastic,
               "first-order output filter y_k = a y_(k-1) + (1-a) x_k per sensor",
               "positive lag-1 autocorrelation a of rest samples; quieter samples, same means",
               {p("gyro_a", "1", "1", 1.0), p("accel_a", "1", "1", 1.0)},
               {0.2, 0.2},
               {0, 1}});
  // A hand's tremor does not follow the unit's grade (calib/diagnosis/gap_fit.hpp effect_scale).
  // Typical: the corpus' hand-held recordings as the diagnosis measures them (0.19-0.24 °/s,
  // 0.016-0.026°; docs/validation/diagnosis.md, "Tremor in a rest"); physiological tremor reaches
  // 1.5 °/s, a hand's sway a few tenths of a degree.
  c.push_back({EffectId::kRestTremor,
               "rest_tremor",
               EffectKind::kStochastic,
               "a hand holds the unit in its rests: tremor (6-11 Hz, RMS rate per axis) and sway "
               "(0.3-1.2 Hz, RMS angle per axis) about a pivot",
               "the accelerometers' excursions within a rest follow the gyro-integrated tilt "
               "(slope 1, none under sensor noise); rest means carry the hand's turn",
               {p("rate_rms", "rad/s", "deg/s", kRadToDeg), p("tilt_rms", "rad", "deg", kRadToDeg),
                p("pivot", "m", "mm", 1e3, true)},
               {0.3 * kDegToRad, 0.03 * kDegToRad, 0.1},
               {0}});
}

/// The physical bounds of EffectInfo::plausible_max (navigation, tactical, MEMS; magnitude units),
/// where the general rule (50× the navigation-grade typical size times the grade's effect scale, 1
/// : 100 : 10⁴) would allow sizes no unit has (issue #49: a 10 m lever arm named on a tactical
/// unit). Each is generous — the diagnosis must not call a real unit implausible — and reasoned:
void set_plausible_bounds(std::vector<EffectInfo>& c) {
  auto set = [&](EffectId id, double navigation, double tactical, double mems) {
    c[static_cast<size_t>(id)].plausible_max = {navigation, tactical, mems};
  };
  const double none = EffectInfo::kNoPlausibleBound;
  // K2 (µg/g², norm of three): quartz pendulous ≲ 50, tactical ≲ 10³, MEMS nonlinearity ≲ 1 %/g.
  set(EffectId::kAccelQuadraticK2, none, 20000.0, 100000.0);
  // Asymmetry (ppm, norm of three): as K2 at 1 g.
  set(EffectId::kAccelAsymmetry, none, 20000.0, 100000.0);
  // Lever arms (mm, norm of nine): the accelerometers sit inside the unit, whatever its grade; the
  // largest navigation units measure ~30 cm, three arms of 15 cm make 260 mm.
  set(EffectId::kSizeEffect, 300.0, 300.0, 300.0);
  // g-sensitivity ((°/h)/g, norm of nine): MEMS datasheets 0.01–0.1 (°/s)/g, i.e. ≤ 360 per axis.
  set(EffectId::kGyroGSensitivity, none, none, 2000.0);
  // Skew (ms): a few sample periods at the slowest rates such units log (100 Hz MEMS, 1 kHz
  // navigation).
  set(EffectId::kGyroAccelSkew, 10.0, 30.0, 50.0);
  // Thermal warm-up (× typical 20 µg, 0.005 °/h): the grade's bias range (tactical ~20 mg and
  // 5 °/h, MEMS ~200 mg and 50 °/h taken together).
  set(EffectId::kThermalDrift, none, 1000.0, 10000.0);
  // Bias instability (× typical 10 µg, 0.001 °/h): datasheets' ranges — navigation ≤ 0.01 °/h and
  // 100 µg, tactical ≤ 1 °/h and 10 mg, MEMS ≤ 100 °/h and 100 mg.
  set(EffectId::kBiasInstability, 10.0, 1000.0, 100000.0);
}

std::vector<EffectInfo> build_catalogue() {
  std::vector<EffectInfo> c = sensor_effects();
  add_remaining_effects(c);
  set_plausible_bounds(c);
  return c;
}

}  // namespace

const std::string& EffectInfo::magnitude_unit() const {
  static const std::string relative = "x typical";
  return magnitude_params.empty() ? relative
                                  : params[static_cast<size_t>(magnitude_params[0])].human_unit;
}

double EffectInfo::magnitude(const Eigen::VectorXd& si) const {
  double s2 = 0.0;
  if (!magnitude_params.empty()) {
    for (int i : magnitude_params) {
      const double h = si(i) * params[static_cast<size_t>(i)].si_to_human;
      s2 += h * h;
    }
    return std::sqrt(s2);
  }
  // Mixed units: the amplitude parameters relative to their typical values, normalised so that the
  // typical pattern has magnitude 1.
  double t2 = 0.0;
  for (int i = 0; i < size(); ++i) {
    if (params[static_cast<size_t>(i)].shape || typical[static_cast<size_t>(i)] == 0.0) continue;
    const double r = si(i) / typical[static_cast<size_t>(i)];
    s2 += r * r;
    t2 += 1.0;
  }
  return t2 > 0.0 ? std::sqrt(s2 / t2) : 0.0;
}

const std::vector<EffectInfo>& effect_catalogue() {
  static const std::vector<EffectInfo> c = build_catalogue();
  return c;
}

const EffectInfo& effect_info(EffectId id) { return effect_catalogue()[static_cast<size_t>(id)]; }

const EffectInfo* find_effect(const std::string& name) {
  for (const auto& e : effect_catalogue())
    if (e.name == name) return &e;
  return nullptr;
}

std::string effect_names_list() {
  std::string s;
  for (const auto& e : effect_catalogue()) s += (s.empty() ? "" : ", ") + e.name;
  return s;
}

std::vector<EffectId> parse_effect_list(const std::string& list) {
  std::vector<EffectId> ids;
  std::stringstream ss(list);
  std::string name;
  while (std::getline(ss, name, ',')) {
    if (name.empty()) continue;
    const EffectInfo* e = find_effect(name);
    if (!e)
      throw std::invalid_argument("unknown effect '" + name + "' (known: " + effect_names_list() +
                                  ")");
    ids.push_back(e->id);
  }
  if (!list.empty() && ids.empty()) throw std::invalid_argument("no effect named");
  return ids;
}

Eigen::VectorXd effect_vector(const Effects& fx, EffectId id) {
  Eigen::VectorXd v(effect_info(id).size());
  switch (id) {
    case EffectId::kAccelQuadraticK2:
      v = fx.accel_k2_per_mps2;
      break;
    case EffectId::kAccelAsymmetry:
      v = fx.accel_asym;
      break;
    case EffectId::kSizeEffect:
      for (int i = 0; i < 3; ++i)
        v.segment<3>(3 * i) = fx.accel_lever_arm_m[static_cast<size_t>(i)];
      break;
    case EffectId::kGyroGSensitivity:
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) v(3 * i + j) = fx.gyro_g_sens(i, j);
      break;
    case EffectId::kGyroAccelSkew:
      v(0) = fx.gyro_accel_skew_s;
      break;
    case EffectId::kTableTimeOffset:
      v(0) = fx.table_time_offset_s;
      break;
    case EffectId::kThermalDrift:
      v << fx.thermal_accel_mps2, fx.thermal_gyro_radps, fx.thermal_tau_s;
      break;
    case EffectId::kBiasInstability:
      v << fx.instability_gyro_radps, fx.instability_accel_mps2, fx.instability_tau_s;
      break;
    case EffectId::kTableNonorthogonality:
      v(0) = fx.table_nonorthogonality_rad;
      break;
    case EffectId::kTableWobble:
      v = fx.table_wobble_rad;
      break;
    case EffectId::kGravityError:
      v(0) = fx.gravity_error_mps2;
      break;
    case EffectId::kLatitudeError:
      v(0) = fx.latitude_error_rad;
      break;
    case EffectId::kQuantisation:
      v << fx.quant_dtheta_rad, fx.quant_dv_mps;
      break;
    case EffectId::kOutputFilter:
      v << fx.output_filter_gyro, fx.output_filter_accel;
      break;
    case EffectId::kRestTremor:
      v << fx.tremor_rate_rms_radps, fx.tremor_tilt_rms_rad, fx.tremor_pivot_m;
      break;
  }
  return v;
}

namespace {

std::string param_list(const EffectInfo& e) {
  std::ostringstream os;
  for (size_t i = 0; i < e.params.size(); ++i)
    os << (i ? ", " : "") << e.params[i].name << " [" << e.params[i].si_unit << "]"
       << (e.params[i].shape ? " (optional, > 0)" : "");
  return os.str();
}

}  // namespace

void set_effect_vector(Effects& fx, EffectId id, const Eigen::VectorXd& v) {
  const EffectInfo& e = effect_info(id);
  if (v.size() != e.size())
    throw std::invalid_argument("effect " + e.name + ": expected " + std::to_string(e.size()) +
                                " value(s) (" + param_list(e) + "), got " +
                                std::to_string(v.size()));
  for (int i = 0; i < e.size(); ++i) {
    if (!std::isfinite(v(i)))
      throw std::invalid_argument("effect " + e.name + ": " +
                                  e.params[static_cast<size_t>(i)].name +
                                  " is not a finite number");
    if (e.params[static_cast<size_t>(i)].shape && !(v(i) > 0.0))
      throw std::invalid_argument("effect " + e.name + ": " +
                                  e.params[static_cast<size_t>(i)].name + " must be > 0");
  }
  if (id == EffectId::kQuantisation && (v(0) < 0.0 || v(1) < 0.0))
    throw std::invalid_argument("effect quantisation: LSBs must be >= 0");
  if (id == EffectId::kOutputFilter && !(v(0) >= 0.0 && v(0) < 1.0 && v(1) >= 0.0 && v(1) < 1.0))
    throw std::invalid_argument("effect output_filter: coefficients must be in [0, 1)");
  if (id == EffectId::kRestTremor && (v(0) < 0.0 || v(1) < 0.0))
    throw std::invalid_argument("effect rest_tremor: the RMS rate and angle must be >= 0");
  if (id == EffectId::kBiasInstability && (v(0) < 0.0 || v(1) < 0.0))
    throw std::invalid_argument("effect bias_instability: sigmas must be >= 0");
  switch (id) {
    case EffectId::kAccelQuadraticK2:
      fx.accel_k2_per_mps2 = v;
      break;
    case EffectId::kAccelAsymmetry:
      fx.accel_asym = v;
      break;
    case EffectId::kSizeEffect:
      for (int i = 0; i < 3; ++i)
        fx.accel_lever_arm_m[static_cast<size_t>(i)] = v.segment<3>(3 * i);
      break;
    case EffectId::kGyroGSensitivity:
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) fx.gyro_g_sens(i, j) = v(3 * i + j);
      break;
    case EffectId::kGyroAccelSkew:
      fx.gyro_accel_skew_s = v(0);
      break;
    case EffectId::kTableTimeOffset:
      fx.table_time_offset_s = v(0);
      break;
    case EffectId::kThermalDrift:
      fx.thermal_accel_mps2 = v.segment<3>(0);
      fx.thermal_gyro_radps = v.segment<3>(3);
      fx.thermal_tau_s = v(6);
      break;
    case EffectId::kBiasInstability:
      fx.instability_gyro_radps = v(0);
      fx.instability_accel_mps2 = v(1);
      fx.instability_tau_s = v(2);
      break;
    case EffectId::kTableNonorthogonality:
      fx.table_nonorthogonality_rad = v(0);
      break;
    case EffectId::kTableWobble:
      fx.table_wobble_rad = v;
      break;
    case EffectId::kGravityError:
      fx.gravity_error_mps2 = v(0);
      break;
    case EffectId::kLatitudeError:
      fx.latitude_error_rad = v(0);
      break;
    case EffectId::kQuantisation:
      fx.quant_dtheta_rad = v(0);
      fx.quant_dv_mps = v(1);
      break;
    case EffectId::kOutputFilter:
      fx.output_filter_gyro = v(0);
      fx.output_filter_accel = v(1);
      break;
    case EffectId::kRestTremor:
      fx.tremor_rate_rms_radps = v(0);
      fx.tremor_tilt_rms_rad = v(1);
      fx.tremor_pivot_m = v(2);
      break;
  }
}

bool Effects::active(EffectId id) const {
  const EffectInfo& e = effect_info(id);
  const Eigen::VectorXd v = effect_vector(*this, id);
  for (int i = 0; i < e.size(); ++i)
    if (!e.params[static_cast<size_t>(i)].shape && v(i) != 0.0) return true;
  return false;
}

bool Effects::any() const {
  for (const auto& e : effect_catalogue())
    if (active(e.id)) return true;
  return false;
}

std::vector<std::string> Effects::active_names() const {
  std::vector<std::string> n;
  for (const auto& e : effect_catalogue())
    if (active(e.id)) n.push_back(e.name);
  return n;
}

bool operator==(const Effects& a, const Effects& b) {
  for (const auto& e : effect_catalogue())
    if (effect_vector(a, e.id) != effect_vector(b, e.id)) return false;
  return true;
}

void apply_effect_spec(Effects& fx, const std::string& spec) {
  const size_t eq = spec.find('=');
  const std::string name = spec.substr(0, eq);
  const EffectInfo* e = find_effect(name);
  if (!e)
    throw std::invalid_argument("unknown effect '" + name + "' (known: " + effect_names_list() +
                                ")");
  if (eq == std::string::npos || eq + 1 >= spec.size())
    throw std::invalid_argument("effect " + name + ": expected " + name + "=V[,V...] with " +
                                param_list(*e));
  std::vector<double> vals;
  std::stringstream ss(spec.substr(eq + 1));
  std::string tok;
  while (std::getline(ss, tok, ',')) {
    size_t used = 0;
    double x = 0.0;
    try {
      x = std::stod(tok, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != tok.size())
      throw std::invalid_argument("effect " + name + ": '" + tok +
                                  "' is not a number (values: " + param_list(*e) + ")");
    vals.push_back(x);
  }
  Eigen::VectorXd v = effect_vector(fx, e->id);
  const int n = static_cast<int>(vals.size());
  int required = e->size();
  while (required > 0 && e->params[static_cast<size_t>(required - 1)].shape) --required;
  if (n < required || n > e->size())
    throw std::invalid_argument("effect " + name + ": expected " + std::to_string(required) +
                                (required == e->size() ? "" : "-" + std::to_string(e->size())) +
                                " value(s) (" + param_list(*e) + "), got " + std::to_string(n));
  for (int i = 0; i < n; ++i) v(i) = vals[static_cast<size_t>(i)];
  set_effect_vector(fx, e->id, v);
}

}  // namespace imucal::calib::effects
