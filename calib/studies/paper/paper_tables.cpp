#include "calib/studies/paper/paper_tables.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <exception>
#include <mutex>
#include <random>
#include <stdexcept>
#include <thread>

#include "calib/ains/ains.hpp"
#include "calib/core/calibration_input.hpp"
#include "calib/core/conventions.hpp"
#include "calib/core/rotation.hpp"
#include "calib/legacy/legacy.hpp"
#include "calib/nlsq/nlsq.hpp"
#include "calib/sim/field_sim.hpp"
#include "calib/sim/sim_input.hpp"

namespace imucal::calib::studies::paper {
using namespace calib::ains;
using namespace calib::checks;
using namespace calib::core;
using namespace calib::effects;
using namespace calib::legacy;
using namespace calib::nlsq;
using namespace calib::sim;

const char* paper_column_name(PaperColumn c) {
  switch (c) {
    case PaperColumn::kFactoryAins:
      return "factory AINS";
    case PaperColumn::kFactoryNlsq:
      return "factory NLSQ";
    case PaperColumn::kFactoryLegacy:
      return "factory legacy";
    case PaperColumn::kLandAins:
      return "land AINS";
    case PaperColumn::kSeaAins:
      return "sea AINS";
  }
  return "?";
}

std::string PaperEffects::names() const {
  if (thermal && instability && k2) return "typical";
  std::string out;
  const auto add = [&out](bool on, const char* name) {
    if (!on) return;
    if (!out.empty()) out += ',';
    out += name;
  };
  add(thermal, "thermal");
  add(instability, "instability");
  add(k2, "k2");
  return out.empty() ? "none" : out;
}

PaperEffects parse_paper_effects(const std::string& text) {
  PaperEffects e;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t comma = std::min(text.find(',', start), text.size());
    const std::string word = text.substr(start, comma - start);
    if (word == "typical") {
      e = PaperEffects::typical();
    } else if (word == "thermal") {
      e.thermal = true;
    } else if (word == "instability") {
      e.instability = true;
    } else if (word == "k2") {
      e.k2 = true;
    } else if (word != "none" || text != "none") {
      throw std::invalid_argument("unknown effect '" + word +
                                  "' (none, typical, or a list of thermal, instability, k2)");
    }
    start = comma + 1;
  }
  return e;
}

namespace {

/// paper_unit's built-in effects (PaperEffects) onto fx at ARCHITECTURE §7's typical sizes, each
/// amplitude times draw(): N(0, 1) for a drawn unit, 1 for the typical one. Drawn whether or not
/// selected (then zeroed), so that a unit's parameters and noise are the same with and without
/// them.
template <typename Draw>
void builtin_effects(Effects& fx, PaperEffects effects, Draw&& draw) {
  for (int i = 0; i < 3; ++i) {
    fx.thermal_accel_mps2(i) = 20.0 * kMicroG_mps2 * draw();
    fx.thermal_gyro_radps(i) = 0.005 * kDegPerHourToRadPerSec * draw();
    fx.accel_k2_per_mps2(i) =
        20.0 * kMicroG_mps2 / (kStandardGravity_mps2 * kStandardGravity_mps2) * draw();
  }
  fx.thermal_tau_s = 900.0;
  fx.instability_gyro_radps = 0.001 * kDegPerHourToRadPerSec;
  fx.instability_accel_mps2 = 10.0 * kMicroG_mps2;
  fx.instability_tau_s = 1000.0;
  if (!effects.thermal) {
    fx.thermal_accel_mps2.setZero();
    fx.thermal_gyro_radps.setZero();
  }
  if (!effects.instability) {
    fx.instability_gyro_radps = 0.0;
    fx.instability_accel_mps2 = 0.0;
  }
  if (!effects.k2) fx.accel_k2_per_mps2.setZero();
}

}  // namespace

UnitModel paper_unit(int unit, uint64_t seed, PaperEffects effects) {
  std::mt19937_64 rng(seed * 1000003ULL + static_cast<uint64_t>(unit) * 7919ULL);
  std::normal_distribution<double> n01;
  std::uniform_real_distribution<double> u(0.8, 1.2);
  UnitModel m = default_unit();
  ParamSet& p = m.params;
  for (int i = 0; i < 3; ++i) {
    p.accel_bias_mps2(i) = 50.0 * kMicroG_mps2 * n01(rng);
    p.gyro_bias_radps(i) = 0.01 * kDegPerHourToRadPerSec * n01(rng);
    for (int j = 0; j < 3; ++j) {
      p.accel_M(i, j) = 300e-6 * n01(rng);
      p.gyro_M(i, j) = 300e-6 * n01(rng);
    }
  }
  // ς belongs to the station's table: the same for every unit (default_unit's).
  m.noise.arw_rad_per_sqrt_s *= u(rng);
  m.noise.vrw_mps_per_sqrt_s *= u(rng);
  // The paper's IMUs were real: each simulated unit also carries the unmodelled physics of the
  // effects catalogue at ARCHITECTURE §7's typical sizes (1σ draws), which no method estimates —
  // warm-up drift, bias instability, quadratic accelerometer error.
  builtin_effects(m.effects, effects, [&] { return n01(rng); });
  return m;
}

namespace {

/// One catalogue effect at `scale` × its typical size onto fx (PaperEffectSize); a sensor
/// effect's amplitudes drawn N(0, 1) from rng, or at +1 (the typical unit) without one.
void add_catalogue_effect(Effects& fx, const PaperEffectSize& e, std::mt19937_64* rng) {
  if (!std::isfinite(e.scale) || e.scale < 0.0)
    throw std::invalid_argument("paper tables: the scale of " + effect_info(e.id).name +
                                " must be finite and >= 0");
  const EffectInfo& info = effect_info(e.id);
  std::normal_distribution<double> n01;
  Eigen::VectorXd v = effect_vector(fx, e.id);
  for (int i = 0; i < info.size(); ++i) {
    const auto k = static_cast<size_t>(i);
    if (info.params[k].shape) {
      v(i) = info.typical[k];
    } else {
      // Drawn whatever the part, so that a part's draws are those of the whole effect.
      const double draw = info.kind == EffectKind::kSensor && rng ? n01(*rng) : 1.0;
      if (paper_effect_param_in_part(info.params[k].name, e.part))
        v(i) += info.typical[k] * e.scale * draw;
    }
  }
  set_effect_vector(fx, e.id, v);
}

}  // namespace

bool paper_effect_param_in_part(const std::string& param_name, PaperEffectSize::Part part) {
  switch (part) {
    case PaperEffectSize::Part::kAccel:
      return param_name.rfind("accel_", 0) == 0;
    case PaperEffectSize::Part::kGyro:
      return param_name.rfind("gyro_", 0) == 0;
    case PaperEffectSize::Part::kAll:
      break;
  }
  return true;
}

const char* paper_effect_part_suffix(PaperEffectSize::Part part) {
  switch (part) {
    case PaperEffectSize::Part::kAccel:
      return ".accel";
    case PaperEffectSize::Part::kGyro:
      return ".gyro";
    case PaperEffectSize::Part::kAll:
      break;
  }
  return "";
}

UnitModel paper_unit(int unit, const PaperTablesOptions& options) {
  UnitModel m = paper_unit(unit, options.seed, options.effects);
  // Streams of their own, so that the unit's parameters and noise stay those of paper_unit, and
  // one per source, so that a unit's draws of one source are the same whichever other sources are
  // on: the gap budget compares models that differ by one source on common random numbers, and a
  // shared stream would redraw every source after the one removed (a new unit, not the same unit
  // without it).
  const uint64_t unit_seed = options.seed * 2000003ULL + static_cast<uint64_t>(unit) * 104729ULL;
  std::normal_distribution<double> n01;
  if (options.setup.uncalibrated_gyro_bias_radps > 0.0) {
    std::mt19937_64 rng(unit_seed);
    for (int i = 0; i < 3; ++i)
      m.params.gyro_bias_radps(i) = options.setup.uncalibrated_gyro_bias_radps * n01(rng);
  }
  for (const PaperEffectSize& e : options.catalogue) {
    std::mt19937_64 rng(unit_seed + 7727ULL * (static_cast<uint64_t>(e.id) + 1ULL));
    add_catalogue_effect(m.effects, e, &rng);
  }
  return m;
}

UnitModel paper_typical_unit(const PaperTablesOptions& options) {
  UnitModel m = default_unit();
  Effects& fx = m.effects;
  builtin_effects(fx, options.effects, [] { return 1.0; });
  for (const PaperEffectSize& e : options.catalogue) add_catalogue_effect(fx, e, nullptr);
  return m;
}

namespace {

/// The table's log as the set-up's errors make it (PaperSetupErrors): each rest position's
/// attitude off by a fresh small rotation and by the fixture's flex under gravity there, and all
/// of it by the fixture's constant heading — on the body side: the log says where the platform
/// is, the unit sits on it. Samples in motion keep the fixture's heading only.
void perturb_reference(CalibrationInput& in, const PaperSetupErrors& setup, std::mt19937_64& rng) {
  if (setup.table_position_error_rad == 0.0 && setup.fixture_heading_rad == 0.0 &&
      setup.fixture_flex_rad_per_g == 0.0)
    return;
  std::normal_distribution<double> n01;
  const Eigen::Matrix3d C_fixture =
      Eigen::AngleAxisd(setup.fixture_heading_rad * n01(rng), Eigen::Vector3d::UnitZ())
          .toRotationMatrix();
  Eigen::Matrix3d F_flex;
  for (int i = 0; i < 9; ++i) F_flex(i / 3, i % 3) = setup.fixture_flex_rad_per_g * n01(rng);
  Eigen::Matrix3d C_position = Eigen::Matrix3d::Identity();
  bool was_at_rest = false;
  for (ReferenceSample& r : in.reference) {
    if (r.at_rest && !was_at_rest) {
      const Eigen::Vector3d error_rad(n01(rng), n01(rng), n01(rng));
      // Gravity's direction in the body frame: the NED down axis seen from the body.
      const Eigen::Vector3d down_b = r.C_bn_ref.transpose() * Eigen::Vector3d::UnitZ();
      C_position =
          rotvec_to_matrix<double>(setup.table_position_error_rad * error_rad + F_flex * down_b);
    }
    was_at_rest = r.at_rest;
    r.C_bn_ref = r.C_bn_ref * C_fixture * (r.at_rest ? C_position : Eigen::Matrix3d::Identity());
  }
}

/// One unit through the three settings and five calibrations, each judged on the table run.
PaperUnitResult run_unit(int unit, const sequences::MotionProfile& profile, const Site& site,
                         const PaperTablesOptions& opt) {
  PaperUnitResult out;
  out.unit = unit;
  out.model = paper_unit(unit, opt);
  const uint64_t seed = opt.seed * 1000 + static_cast<uint64_t>(unit);

  SimOptions so;
  so.rate_hz = opt.rate_hz;
  so.seed = seed;
  const SimResult table_run = simulate(profile, TableGeometry{}, site, out.model, so);
  CalibrationInput factory =
      input_from_simulation(table_run, TableGeometry{}, site, out.model.noise);
  std::mt19937_64 setup_rng(seed * 7919ULL + 17ULL);
  perturb_reference(factory, opt.setup, setup_rng);

  FieldSimOptions fo;
  fo.rate_hz = opt.rate_hz;
  fo.setting = Setting::kLand;
  fo.seed = seed + 101;
  // Land and sea sites have no surveyed gravity: normal gravity, as in the field.
  Site field_site = site;
  field_site.gravity_mps2.reset();
  UnitModel field_unit = out.model;
  field_unit.params.table_misalignment_rad.setZero();  // no table, and none of its effects
  field_unit.effects.table_time_offset_s = 0.0;
  field_unit.effects.table_nonorthogonality_rad = 0.0;
  field_unit.effects.table_wobble_rad.setZero();
  const FieldSimResult land_run = simulate_field(profile, field_site, field_unit, fo);
  fo.setting = Setting::kSea;
  fo.seed = seed + 202;
  const FieldSimResult sea_run = simulate_field(profile, field_site, field_unit, fo);

  std::array<CalibrationResult, kNumPaperColumns> cal;
  cal[0] = calibrate_ains(factory);
  cal[1] = calibrate_nlsq(factory);
  cal[2] = calibrate_legacy(factory);
  cal[3] = calibrate_ains(
      input_from_field_data(Setting::kLand, land_run.imu, {}, field_site, out.model.noise));
  cal[4] = calibrate_ains(
      input_from_field_data(Setting::kSea, sea_run.imu, sea_run.gnss, field_site, out.model.noise));
  // ς is the table's: where a method cannot know it, evaluate with the factory AINS's estimate.
  const Eigen::Vector3d station_sigma = cal[0].params.table_misalignment_rad;
  EvaluationOptions evaluation;
  evaluation.reopen_heading_sigma_rad = opt.setup.evaluation_heading_reopen_rad;
  for (int c = 0; c < kNumPaperColumns; ++c) {
    ParamSet p = cal[static_cast<size_t>(c)].params;
    if (!cal[static_cast<size_t>(c)].observable[24]) p.table_misalignment_rad = station_sigma;
    // §VI: the gyro biases left in the data (estimated here, but no evaluated set carries them).
    if (opt.setup.uncalibrated_gyro_bias_radps > 0.0) p.gyro_bias_radps.setZero();
    out.params[static_cast<size_t>(c)] = p;
    out.sigma[static_cast<size_t>(c)] = cal[static_cast<size_t>(c)].sigma;
    out.converged[static_cast<size_t>(c)] = cal[static_cast<size_t>(c)].converged;
    out.metrics[static_cast<size_t>(c)] = evaluate(factory, p, evaluation);
  }
  return out;
}

}  // namespace

PaperTables run_paper_tables(const sequences::MotionProfile& profile, const Site& site,
                             const PaperTablesOptions& opt) {
  if (opt.units < 1) throw std::invalid_argument("paper tables: --units must be at least 1");
  if (opt.threads < 1) throw std::invalid_argument("paper tables: threads must be at least 1");
  const auto t0 = std::chrono::steady_clock::now();
  PaperTables out;
  out.sequence = profile.name;
  out.effects = opt.effects;
  out.duration_s = profile.duration_s();
  out.units.resize(static_cast<size_t>(opt.units));

  std::atomic<int> next{0};
  std::mutex mu;
  int done = 0;
  std::exception_ptr error;
  auto worker = [&]() {
    for (int i = next++; i < opt.units; i = next++) {
      try {
        PaperUnitResult r = run_unit(i + 1, profile, site, opt);
        std::lock_guard<std::mutex> lock(mu);
        out.units[static_cast<size_t>(i)] = std::move(r);
        ++done;
        if (opt.on_progress) opt.on_progress(done, opt.units);
      } catch (...) {
        std::lock_guard<std::mutex> lock(mu);
        if (!error) error = std::current_exception();
        next = opt.units;  // stop handing out work
      }
    }
  };
  std::vector<std::thread> pool;
  const int n_threads = std::min(opt.threads, opt.units);
  for (int t = 0; t < n_threads; ++t) pool.emplace_back(worker);
  for (auto& t : pool) t.join();
  if (error) std::rethrow_exception(error);

  for (int c = 0; c < kNumPaperColumns; ++c) {
    double so = 0.0, sa = 0.0;
    for (const auto& u : out.units) {
      so += u.metrics[static_cast<size_t>(c)].orientation_rmse_mdeg;
      sa += u.metrics[static_cast<size_t>(c)].accel_rmse_ug;
    }
    out.mean_orientation_mdeg[static_cast<size_t>(c)] = so / opt.units;
    out.mean_accel_ug[static_cast<size_t>(c)] = sa / opt.units;
  }
  out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

const PaperPublished& paper_published() {
  // Tables I–IV of the paper (its §VIII: Jørgensen et al., "IMU Calibration and Validation in
  // a Factory, Remote on Land and at Sea"), columns as PaperColumn: factory AINS, NLSQ,
  // proprietary; land AINS; sea AINS. Rows IMU 1–6, then mean.
  static const PaperPublished p = {{{{10.7668, 11.0004, 12.8470, 30.1818, 17.6468},
                                     {20.3281, 20.9816, 21.9415, 20.4200, 20.0357},
                                     {26.6626, 26.1676, 27.4034, 26.4714, 25.8094},
                                     {22.3295, 23.0129, 22.6769, 22.9644, 25.2287},
                                     {28.8444, 27.5539, 25.1533, 28.0645, 27.4300},
                                     {26.3689, 26.5847, 26.5428, 25.4839, 27.9529},
                                     {22.5500, 22.5502, 22.7608, 25.5977, 24.0173}}},
                                   {{{16.7683, 16.4582, 21.9174, 67.6954, 28.5954},
                                     {29.9454, 26.5149, 29.7009, 29.8001, 32.6557},
                                     {28.5088, 22.1025, 89.6507, 26.8985, 34.5786},
                                     {33.2744, 29.1359, 28.2366, 27.8462, 31.4044},
                                     {25.6030, 23.4516, 31.6360, 28.9807, 24.9405},
                                     {31.9135, 30.0562, 34.0508, 29.7186, 33.9529},
                                     {27.6689, 24.6199, 39.1987, 35.1566, 31.0213}}}};
  return p;
}

}  // namespace imucal::calib::studies::paper
