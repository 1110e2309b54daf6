#include "calib/sim/field_sim.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>

#include "calib/core/conventions.hpp"
#include "calib/core/rotation.hpp"
#include "calib/core/table_model.hpp"
#include "calib/effects/rest_tremor.hpp"
#include "calib/effects/site_errors.hpp"
#include "calib/sim/truth_physics.hpp"

namespace imucal::calib::sim {
using namespace calib::core;
using namespace calib::effects;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

[[noreturn]] void fail(const std::string& what) {
  throw std::invalid_argument("field simulation: " + what);
}

void check_positive(double v, const char* name) {
  if (!(std::isfinite(v) && v > 0.0))
    fail(std::string("option ") + name + " must be positive and finite, got " + std::to_string(v));
}

void check_options(const FieldSimOptions& o, const UnitModel& unit) {
  if (o.setting == Setting::kFactory)
    fail("the factory setting is simulated with the table simulator (imucal simulate)");
  check_positive(o.rate_hz, "rate_hz");
  check_positive(o.rock_period_s, "rock_period_s");
  check_positive(o.drift_period_s, "drift_period_s");
  check_positive(o.heave_period_s, "heave_period_s");
  check_positive(o.gnss_rate_hz, "gnss_rate_hz");
  check_positive(o.gnss_sigma_m, "gnss_sigma_m");
  for (double v :
       {o.placement_sigma_deg, o.rock_amplitude_deg, o.drift_amplitude_m, o.heave_amplitude_m})
    if (!(std::isfinite(v) && v >= 0.0)) fail("amplitudes and placement_sigma_deg must be >= 0");
  if (!(o.duration_jitter >= 0.0 && o.duration_jitter < 0.9))
    fail("option duration_jitter must be in [0, 0.9)");
  const Effects& fx = unit.effects;
  if (fx.table_time_offset_s != 0.0 || fx.table_nonorthogonality_rad != 0.0 ||
      !fx.table_wobble_rad.isZero())
    fail("table effects have no meaning without a table (land/sea)");
  if (o.setting == Setting::kSea && fx.active(EffectId::kRestTremor))
    fail(
        "rest_tremor (a hand holding the unit in its rests) is simulated on land only: at sea the "
        "deck moves the unit in its rests, and the diagnosis assesses no noise there");
}

/// The size effect's velocity increment over [t0, t1] (calib/effects/size_effect.hpp), body axes:
/// component i of ∫ ([ω̇×] + [ω×]²) r_i dt, the ω̇ part exactly (ω(t1) - ω(t0)), the ω² part by
/// 3-point Gauss-Legendre; ω the body rate relative to the ground from the attitude by central
/// differences (the Earth's rate adds ~1e-4 of it, and the frame turns by ω dt within a sample:
/// both far below the effect's own noise). One sample's ω(t1) is the next one's ω(t0), kept.
template <typename AttitudeAt>
class LeverArmIncrement {
 public:
  LeverArmIncrement(const std::array<Eigen::Vector3d, 3>& r_m, const AttitudeAt& C_bn_at)
      : r_m_(r_m), C_bn_at_(C_bn_at) {}

  Eigen::Vector3d dv_b(double t0, double t1) {
    const Eigen::Vector3d w0 = t0 == t_prev_ ? w_prev_ : w_b(t0);
    const Eigen::Vector3d w1 = w_b(t1);
    t_prev_ = t1;
    w_prev_ = w1;
    const Eigen::Vector3d dw = w1 - w0;
    Eigen::Vector3d dv = Eigen::Vector3d::Zero();
    for (int i = 0; i < 3; ++i) {
      const Eigen::Vector3d& r = r_m_[static_cast<size_t>(i)];
      if (r.isZero()) continue;
      double centripetal = 0.0;
      for (int q = 0; q < 3; ++q) {
        const Eigen::Vector3d w = w_b(t0 + GaussLegendre3::kNode[q] * (t1 - t0));
        centripetal += GaussLegendre3::kWeight[q] * (t1 - t0) * w.cross(w.cross(r))(i);
      }
      dv(i) = dw.cross(r)(i) + centripetal;
    }
    return dv;
  }

  /// A sample in which the unit does not turn against the ground (a rest on land): nothing to
  /// integrate, and ω(t1) is zero for the next sample.
  void still(double t1) {
    t_prev_ = t1;
    w_prev_.setZero();
  }

 private:
  static constexpr double kH_s = 1e-4;
  Eigen::Vector3d w_b(double t) const {
    const double a = std::max(0.0, t - kH_s);
    return Eigen::Vector3d(matrix_to_rotvec(C_bn_at_(a).transpose() * C_bn_at_(t + kH_s)) /
                           (t + kH_s - a));
  }
  const std::array<Eigen::Vector3d, 3>& r_m_;
  const AttitudeAt& C_bn_at_;
  double t_prev_ = -1.0;
  Eigen::Vector3d w_prev_ = Eigen::Vector3d::Zero();
};

/// Smooth 0 -> 1 step (zero slope at both ends).
double smoothstep(double x) {
  x = std::clamp(x, 0.0, 1.0);
  return 0.5 - 0.5 * std::cos(kPi * x);
}

/// The hand's timeline: every profile segment stretched by its own factor, each rest with its
/// own placement error, blended over the moves between rests.
class HandTimeline {
 public:
  HandTimeline(const sequences::MotionProfile& p, const FieldSimOptions& o, std::mt19937_64& rng)
      : profile_(p) {
    std::uniform_real_distribution<double> jitter(1.0 - o.duration_jitter, 1.0 + o.duration_jitter);
    std::normal_distribution<double> n01;
    double t = 0.0;
    Eigen::Vector3d e = Eigen::Vector3d::Zero();
    for (const auto& seg : p.segments) {
      Warped w;
      w.t0 = t;
      w.t1 = t + (seg.t1_s - seg.t0_s) * jitter(rng);
      w.rest = seg.kind == sequences::SegmentKind::kRest;
      if (w.rest) {
        e = Eigen::Vector3d(n01(rng), n01(rng), n01(rng)) * (o.placement_sigma_deg * kDegToRad);
      }
      w.placement = e;
      warped_.push_back(w);
      t = w.t1;
    }
    // Each move run (consecutive moves) blends from the rest before to the rest after.
    for (size_t i = 0; i < warped_.size(); ++i) {
      if (warped_[i].rest) continue;
      size_t j = i;
      while (j < warped_.size() && !warped_[j].rest) ++j;
      const Eigen::Vector3d from = i > 0 ? warped_[i - 1].placement : Eigen::Vector3d::Zero();
      const Eigen::Vector3d to = j < warped_.size() ? warped_[j].placement : from;
      for (size_t k = i; k < j; ++k) {
        warped_[k].blend_from = from;
        warped_[k].blend_to = to;
        warped_[k].run_t0 = warped_[i].t0;
        warped_[k].run_t1 = warped_[j - 1].t1;
      }
      i = j;
    }
  }

  double duration_s() const { return warped_.empty() ? 0.0 : warped_.back().t1; }

  /// Profile time and placement rotation vector at hand time t.
  void at(double t, double& t_profile, Eigen::Vector3d& placement, bool& rest) const {
    const size_t i = index(t);
    const Warped& w = warped_[i];
    const auto& seg = profile_.segments[i];
    const double x = (t - w.t0) / (w.t1 - w.t0);
    t_profile = seg.t0_s + std::clamp(x, 0.0, 1.0) * (seg.t1_s - seg.t0_s);
    rest = w.rest;
    if (w.rest) {
      placement = w.placement;
    } else {
      const double s = smoothstep((t - w.run_t0) / (w.run_t1 - w.run_t0));
      placement = (1.0 - s) * w.blend_from + s * w.blend_to;
    }
  }

  /// True if [t0, t1] lies inside one rest segment.
  bool rest_interval(double t0, double t1) const {
    const Warped& w = warped_[index(0.5 * (t0 + t1))];
    return w.rest && t0 >= w.t0 && t1 <= w.t1;
  }

  /// The rest holding t: its segment index and the time since it began; false outside rests.
  bool rest_at(double t, size_t& segment, double& tau_s) const {
    segment = index(t);
    const Warped& w = warped_[segment];
    tau_s = t - w.t0;
    return w.rest && t >= w.t0 && t <= w.t1;
  }

  /// Per segment: the rest's duration, 0 for a move (draw_rest_tremor's input).
  std::vector<double> rest_durations_s() const {
    std::vector<double> out;
    for (const auto& w : warped_) out.push_back(w.rest ? w.t1 - w.t0 : 0.0);
    return out;
  }

  std::vector<std::pair<double, double>> rest_spans() const {
    std::vector<std::pair<double, double>> out;
    for (const auto& w : warped_)
      if (w.rest) out.emplace_back(w.t0, w.t1);
    return out;
  }

 private:
  struct Warped {
    double t0 = 0, t1 = 0;
    bool rest = false;
    Eigen::Vector3d placement = Eigen::Vector3d::Zero();
    Eigen::Vector3d blend_from = Eigen::Vector3d::Zero(), blend_to = Eigen::Vector3d::Zero();
    double run_t0 = 0, run_t1 = 1;
  };
  size_t index(double t) const {
    size_t lo = 0, hi = warped_.size();
    while (hi - lo > 1) {
      const size_t mid = (lo + hi) / 2;
      (warped_[mid].t0 <= t ? lo : hi) = mid;
    }
    return lo;
  }
  const sequences::MotionProfile& profile_;
  std::vector<Warped> warped_;
};

/// The platform: still on land; at sea a DP vessel's slow drift, heave and rocking (sinusoids).
struct Platform {
  bool sea = false;
  double drift_amp = 0, drift_w = 0, heave_amp = 0, heave_w = 0, rock_amp = 0, rock_w = 0;
  double phase[6] = {0, 0, 0, 0, 0, 0};

  /// NED displacement from the site, m, and its rate.
  Eigen::Vector3d p(double t) const {
    if (!sea) return Eigen::Vector3d::Zero();
    return {drift_amp * std::sin(drift_w * t + phase[0]),
            drift_amp * std::sin(0.77 * drift_w * t + phase[1]),
            heave_amp * std::sin(heave_w * t + phase[2])};
  }
  Eigen::Vector3d p_dot(double t) const {
    if (!sea) return Eigen::Vector3d::Zero();
    return {drift_amp * drift_w * std::cos(drift_w * t + phase[0]),
            drift_amp * 0.77 * drift_w * std::cos(0.77 * drift_w * t + phase[1]),
            heave_amp * heave_w * std::cos(heave_w * t + phase[2])};
  }
  /// Rocking rotation (n side): roll and pitch at the amplitude, yaw at half of it, incommensurate
  /// periods around the nominal one.
  Eigen::Matrix3d C_rock(double t) const {
    if (!sea) return Eigen::Matrix3d::Identity();
    const Eigen::Vector3d rho(rock_amp * std::sin(rock_w * t + phase[3]),
                              rock_amp * std::sin(1.13 * rock_w * t + phase[4]),
                              0.5 * rock_amp * std::sin(0.71 * rock_w * t + phase[5]));
    return rotvec_to_matrix<double>(rho);
  }
};

/// Earth-fixed kinematics of the unit: position (from the site's tangent frame, exact to far
/// below a millimetre over a DP excursion), n-frame at the current position, inertial frame.
class EarthKinematics {
 public:
  EarthKinematics(const Site& site) : site_(site) {
    r0_ = ecef(site.lat_rad, site.lon_rad, site.height_m);
    C_en0_ = C_en(site.lat_rad, site.lon_rad);
    RN_ = EarthModel::radius_north_m(site.lat_rad) + site.height_m;
    RE_ = EarthModel::radius_east_m(site.lat_rad) + site.height_m;
    w_ie_ = Eigen::Vector3d(0, 0, wgs84::kEarthRate_radps);
  }
  static Eigen::Vector3d ecef(double lat, double lon, double h) {
    const double s = std::sin(lat), c = std::cos(lat);
    const double N = wgs84::kSemiMajor_m / std::sqrt(1.0 - wgs84::kEcc2 * s * s);
    return {(N + h) * c * std::cos(lon), (N + h) * c * std::sin(lon),
            (N * (1.0 - wgs84::kEcc2) + h) * s};
  }
  /// n (NED) to e.
  static Eigen::Matrix3d C_en(double lat, double lon) {
    const double sL = std::sin(lat), cL = std::cos(lat), sl = std::sin(lon), cl = std::cos(lon);
    Eigen::Matrix3d C;
    C << -sL * cl, -sl, -cL * cl,  //
        -sL * sl, cl, -cL * sl,    //
        cL, 0.0, -sL;
    return C;
  }
  /// e to i: the Earth turned by ω_ie t about its axis.
  Eigen::Matrix3d C_ie(double t) const {
    const double a = wgs84::kEarthRate_radps * t, c = std::cos(a), s = std::sin(a);
    Eigen::Matrix3d C;
    C << c, -s, 0.0,  //
        s, c, 0.0,    //
        0.0, 0.0, 1.0;
    return C;
  }
  /// Geodetic position of a NED displacement p (tangent frame at the site).
  void lla(const Eigen::Vector3d& p, double& lat, double& lon, double& h) const {
    lat = site_.lat_rad + p(0) / RN_;
    lon = site_.lon_rad + p(1) / (RE_ * std::cos(site_.lat_rad));
    h = site_.height_m - p(2);
  }
  Eigen::Vector3d r_e(const Eigen::Vector3d& p) const { return r0_ + C_en0_ * p; }
  Eigen::Vector3d v_e(const Eigen::Vector3d& p_dot) const { return C_en0_ * p_dot; }
  /// C_bi = C_ie C_en(position) C_bn: body to inertial (C_ie = C_ie(t), computed once a sample).
  Eigen::Matrix3d C_bi(const Eigen::Matrix3d& C_ie, const Eigen::Vector3d& p,
                       const Eigen::Matrix3d& C_bn) const {
    double lat, lon, h;
    lla(p, lat, lon, h);
    return C_ie * C_en(lat, lon) * C_bn;
  }
  Eigen::Vector3d v_i(const Eigen::Matrix3d& C_ie, const Eigen::Vector3d& p,
                      const Eigen::Vector3d& p_dot) const {
    const Eigen::Vector3d r = r_e(p);
    return C_ie * (v_e(p_dot) + w_ie_.cross(r));
  }
  /// Gravitation (mass attraction only) in i: G = g + ω × (ω × r), g along the local down with the
  /// true magnitude (normal gravity at the position, or the surveyed value with its height
  /// gradient, plus any gravity error).
  Eigen::Vector3d G_i(double t, const Eigen::Vector3d& p, double g_offset) const {
    return C_ie(t) * G_e(p, g_offset);
  }

 private:
  /// The same in e, kept for the last position: on land the unit never moves, and three
  /// quadrature nodes a sample ask for it.
  const Eigen::Vector3d& G_e(const Eigen::Vector3d& p, double g_offset) const {
    if (p == G_e_p_ && g_offset == G_e_offset_) return G_e_;
    double lat, lon, h;
    lla(p, lat, lon, h);
    const double g = EarthModel::normal_gravity_mps2(lat, h) + g_offset;
    const Eigen::Vector3d r = r_e(p);
    const Eigen::Vector3d g_e = C_en(lat, lon) * Eigen::Vector3d(0, 0, g);
    G_e_p_ = p;
    G_e_offset_ = g_offset;
    G_e_ = g_e + w_ie_.cross(w_ie_.cross(r));
    return G_e_;
  }

  mutable Eigen::Vector3d G_e_p_{kNaN, kNaN, kNaN}, G_e_;
  mutable double G_e_offset_ = kNaN;
  Site site_;
  Eigen::Vector3d r0_, w_ie_;
  Eigen::Matrix3d C_en0_;
  double RN_, RE_;
};

Platform make_platform(const FieldSimOptions& opt, std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  Platform plat;
  plat.sea = opt.setting == Setting::kSea;
  plat.drift_amp = opt.drift_amplitude_m;
  plat.drift_w = 2.0 * kPi / opt.drift_period_s;
  plat.heave_amp = opt.heave_amplitude_m;
  plat.heave_w = 2.0 * kPi / opt.heave_period_s;
  plat.rock_amp = opt.rock_amplitude_deg * kDegToRad;
  plat.rock_w = 2.0 * kPi / opt.rock_period_s;
  for (double& ph : plat.phase) ph = 2.0 * kPi * u01(rng);
  return plat;
}

/// GNSS fixes at the platform's true position plus white noise, at multiples of 1/rate.
std::vector<GnssFix> gnss_fixes(const Platform& plat, const Site& site, const FieldSimOptions& opt,
                                double t_end, std::mt19937_64& rng) {
  std::normal_distribution<double> n01;
  const double RN = EarthModel::radius_north_m(site.lat_rad) + site.height_m;
  const double RE = EarthModel::radius_east_m(site.lat_rad) + site.height_m;
  std::vector<GnssFix> out;
  for (int m = 1; m / opt.gnss_rate_hz <= t_end + 1e-9; ++m) {
    const double t = m / opt.gnss_rate_hz;
    const Eigen::Vector3d p = plat.p(t);
    GnssFix g;
    g.t_s = t;
    g.lat_rad = site.lat_rad + (p(0) + opt.gnss_sigma_m * n01(rng)) / RN;
    g.lon_rad = site.lon_rad + (p(1) + opt.gnss_sigma_m * n01(rng)) / (RE * std::cos(site.lat_rad));
    g.sigma_m = opt.gnss_sigma_m;
    out.push_back(g);
  }
  return out;
}

}  // namespace

FieldSimResult simulate_field(const sequences::MotionProfile& profile, const Site& site,
                              const UnitModel& unit, const FieldSimOptions& opt) {
  check_options(opt, unit);
  std::mt19937_64 rng(opt.seed * 0x9E3779B97F4A7C15ULL + 17);
  std::uniform_real_distribution<double> u01(0.0, 1.0);
  std::normal_distribution<double> n01;

  TableGeometry geom;
  geom.heading_rad = 2.0 * kPi * u01(rng);
  const TableModel table(geom);
  const HandTimeline hand(profile, opt, rng);
  const Platform plat = make_platform(opt, rng);

  // The true site: the configured one with the latitude_error effect (the physics happens where
  // the unit is, the station computes with what it was told), its gravity the site's (surveyed, or
  // normal gravity there) plus the gravity_error effect.
  const Site truth =
      true_site(site, unit.effects.gravity_error_mps2, unit.effects.latitude_error_rad);
  const double g_offset =
      truth.gravity_mps2
          ? *truth.gravity_mps2 - EarthModel::normal_gravity_mps2(truth.lat_rad, truth.height_m)
          : 0.0;
  const EarthKinematics earth(truth);

  // The placement's rotation and the table's attitude stay the same over a rest (most of a run)
  // and the lever term asks for them ten times a sample: each is recomputed only when its input
  // changes (the same numbers either way).
  Eigen::Vector3d e_last(kNaN, kNaN, kNaN);
  Eigen::Matrix3d C_placement;
  double outer_last = kNaN, inner_last = kNaN;
  Eigen::Matrix3d C_table;
  auto C_nominal_at = [&](double t) {
    double tp;
    Eigen::Vector3d e;
    bool rest;
    hand.at(t, tp, e, rest);
    const sequences::TableState s = profile.at(tp);
    if (e != e_last) {
      e_last = e;
      C_placement = rotvec_to_matrix<double>(e);
    }
    if (s.outer_rad != outer_last || s.inner_rad != inner_last) {
      outer_last = s.outer_rad;
      inner_last = s.inner_rad;
      C_table = table.C_bn(s.outer_rad, s.inner_rad);
    }
    return Eigen::Matrix3d(plat.C_rock(t) * C_placement * C_table);
  };
  // rest_tremor (calib/effects/rest_tremor.hpp; land only): in each rest the hand turns the unit,
  // C_bn = C_nominal exp([θ×]), about its pivot, so the unit's origin moves by
  // d = C_nominal (exp([θ×]) − I) ρ at the velocity C_bn (ω × ρ) (C_nominal holds still in a rest
  // on land); the physics below integrates both like any motion.
  const Effects& fx = unit.effects;
  const bool tremor = fx.active(EffectId::kRestTremor);
  const std::vector<RestTremorMotion> held =
      tremor ? draw_rest_tremor(fx.tremor_rate_rms_radps, fx.tremor_tilt_rms_rad, fx.tremor_pivot_m,
                                hand.rest_durations_s(), opt.seed)
             : std::vector<RestTremorMotion>{};
  auto held_at = [&](double t, double& tau) -> const RestTremorMotion* {
    size_t i;
    return tremor && hand.rest_at(t, i, tau) ? &held[i] : nullptr;
  };
  auto C_bn_at = [&](double t) {
    double tau;
    const RestTremorMotion* m = held_at(t, tau);
    const Eigen::Matrix3d C = C_nominal_at(t);
    return m ? Eigen::Matrix3d(C * rotvec_to_matrix<double>(m->angle_rad(tau))) : C;
  };
  // The platform's position and velocity (NED from the site), with the hand's displacement.
  auto position = [&](double t) {
    double tau;
    const RestTremorMotion* m = held_at(t, tau);
    if (!m) return plat.p(t);
    const Eigen::Matrix3d C = C_nominal_at(t);
    const Eigen::Vector3d& rho = m->pivot_to_unit_b_m();
    return Eigen::Vector3d(plat.p(t) +
                           C * (rotvec_to_matrix<double>(m->angle_rad(tau)) * rho - rho));
  };
  auto velocity = [&](double t) {
    double tau;
    const RestTremorMotion* m = held_at(t, tau);
    if (!m) return plat.p_dot(t);
    return Eigen::Vector3d(plat.p_dot(t) +
                           C_bn_at(t) * m->rate_b_radps(tau).cross(m->pivot_to_unit_b_m()));
  };

  const double dt = 1.0 / opt.rate_hz;
  const size_t n = static_cast<size_t>(std::floor(hand.duration_s() * opt.rate_hz + 1e-9));
  FieldSimResult out;
  out.truth = unit.params;
  out.imu.resize(n);
  out.true_rest.resize(n);
  out.C_bn.resize(n);
  out.rest_spans = hand.rest_spans();
  TruthSensor sensor(unit, dt, opt.seed, opt.noise);
  bool lever = false;
  for (const auto& r : unit.effects.accel_lever_arm_m) lever = lever || !r.isZero();
  LeverArmIncrement lever_arm(unit.effects.accel_lever_arm_m, C_bn_at);
  const Eigen::Matrix3d C_ie0 = earth.C_ie(0.0);
  Eigen::Matrix3d C_bi_prev = earth.C_bi(C_ie0, position(0.0), C_bn_at(0.0));
  Eigen::Vector3d v_i_prev = earth.v_i(C_ie0, position(0.0), velocity(0.0));
  for (size_t k = 0; k < n; ++k) {
    const double t0 = static_cast<double>(k) * dt, t1 = static_cast<double>(k + 1) * dt;
    const Eigen::Matrix3d C_bn = C_bn_at(t1);
    const Eigen::Vector3d p1 = position(t1);
    const Eigen::Matrix3d C_ie = earth.C_ie(t1);
    const Eigen::Matrix3d C_bi = earth.C_bi(C_ie, p1, C_bn);
    const Eigen::Vector3d v_i = earth.v_i(C_ie, p1, velocity(t1));
    Eigen::Vector3d int_G = Eigen::Vector3d::Zero();
    for (int q = 0; q < 3; ++q) {
      const double t = t0 + GaussLegendre3::kNode[q] * dt;
      int_G += GaussLegendre3::kWeight[q] * dt * earth.G_i(t, position(t), g_offset);
    }
    const Eigen::Vector3d dtheta = matrix_to_rotvec(C_bi_prev.transpose() * C_bi);
    Eigen::Vector3d dv = C_bi_prev.transpose() * (v_i - v_i_prev - int_G);
    if (lever) {
      // On land at a rest the attitude is constant over the differences' reach: no lever term
      // (unless a hand turns the unit there).
      if (!plat.sea && !tremor && hand.rest_interval(t0 - 1e-4, t1 + 1e-4))
        lever_arm.still(t1);
      else
        dv += lever_arm.dv_b(t0, t1);
    }
    ImuIncrement& s = out.imu[k];
    s.t_s = t1;
    s.dt_s = dt;
    sensor.measure(dtheta, dv, t0, s);
    s.temp_c = 25.0;
    out.true_rest[k] = hand.rest_interval(t0, t1);
    out.C_bn[k] = C_bn;
    C_bi_prev = C_bi;
    v_i_prev = v_i;
  }

  if (plat.sea) out.gnss = gnss_fixes(plat, truth, opt, n ? out.imu.back().t_s : 0.0, rng);
  return out;
}

}  // namespace imucal::calib::sim
