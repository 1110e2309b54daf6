#include "calib/diagnosis/gap_model.hpp"

#include <Eigen/Cholesky>
#include <cmath>
#include <stdexcept>
#include <string>

#include "calib/core/earth.hpp"
#include "calib/core/imu_error_model.hpp"
#include "calib/core/rotation.hpp"
#include "calib/effects/effect_compensation.hpp"
#include "calib/effects/sensor_effects.hpp"
#include "calib/effects/site_errors.hpp"
#include "calib/effects/table_imperfections.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::core;
using namespace calib::effects;

namespace {

constexpr const char* kWho = "gap diagnosis: ";
// Re-orthonormalise the propagated attitude this often (round-off ~1e-16 per step).
constexpr size_t kOrthonormaliseEvery = 256;

[[noreturn]] void fail(const std::string& what) { throw std::invalid_argument(kWho + what); }

}  // namespace

const char* gap_component_name(int c) {
  static const char* names[kGapRowsPerSegment] = {"accel x", "accel y", "accel z",
                                                  "gyro x",  "gyro y",  "gyro z"};
  return names[c];
}

std::string GapSegment::label() const {
  if (kind == Kind::kRest) return "rest " + std::to_string(number);
  return "move " + std::to_string(number) + " (rest " + std::to_string(rest_a + 1) + " -> " +
         std::to_string(rest_b + 1) + ")";
}

GapModel::GapModel(const DiagnosisInput& in, size_t min_rest_samples, const ParamSet* calibrated)
    : in_(in.cal), geometry_(in.geometry), table_free_(!in.cal.has_reference_attitude()) {
  if (in_.imu.size() != in_.reference.size() || in_.imu.empty())
    fail("imu and reference must be non-empty and of equal length");
  check_setting(in_);
  if (table_free_ && !calibrated)
    fail(
        "a run without an attitude reference needs its calibration to estimate the rests' "
        "attitudes");
  if (table_free_) geometry_.reset();
  const NoiseModel& nm = in_.noise;
  if (!(nm.arw_rad_per_sqrt_s > 0.0 && nm.vrw_mps_per_sqrt_s > 0.0 &&
        std::isfinite(nm.arw_rad_per_sqrt_s) && std::isfinite(nm.vrw_mps_per_sqrt_s)))
    fail("the noise model needs a finite ARW and VRW > 0 (they are the model's predicted spread)");
  if (geometry_)
    for (const ReferenceSample& r : in_.reference)
      if (!(std::isfinite(r.outer_rad) && std::isfinite(r.inner_rad))) {
        geometry_.reset();  // no angles after all (e.g. built by hand): no table effects
        break;
      }
  t_first_s_ = in_.imu.front().t_s - in_.imu.front().dt_s;
  build_segments(min_rest_samples);
  if (in_.setting == Setting::kSea) {
    build_innovation_rows(*calibrated, min_rest_samples);
  } else if (table_free_) {
    estimate_rest_attitudes(*calibrated);  // builds the covariances on the way
  } else {
    for (const RestSums& r : sums_) rest_C_bn_.push_back(in_.reference[r.ref_sample].C_bn_ref);
    build_covariances();
  }
}

void GapModel::check_setting(const CalibrationInput& in) {
  if (in.setting == Setting::kSea && in.gnss.empty())
    fail(
        "a sea run without GNSS fixes (gnss.csv) cannot be diagnosed: its residuals are the "
        "navigation filter's GNSS innovations, and the vessel moves the unit during its rests");
}

std::string GapModel::not_applicable(EffectId id) const {
  const EffectInfo& e = effect_info(id);
  const bool sea = in_.setting == Setting::kSea;
  if (e.kind == EffectKind::kTable) {
    if (sea) return "not applicable: the run has no table (sea)";
    if (table_free_) return "not applicable: the run has no table (table-free)";
    if (!has_table() && id != EffectId::kTableTimeOffset)
      return "not applicable: the archive has no table angles (attitude log)";
    return "";
  }
  if (!sea) return "";
  if (id == EffectId::kLatitudeError)
    return "not applicable: at sea the latitude comes from the GNSS fixes";
  if (e.kind == EffectKind::kStochastic)
    return "not assessed at sea: the deck's motion leaves no still rest for a noise statistic";
  return "";
}

const char* GapModel::component_name(int c) const {
  if (!innovations_) return gap_component_name(c);
  return c == 0 ? "gnss north" : "gnss east";
}

const char* gap_component_key(int c) {
  static const char* keys[kGapRowsPerSegment] = {"accel_x", "accel_y", "accel_z",
                                                 "gyro_x",  "gyro_y",  "gyro_z"};
  return keys[c];
}

const char* GapModel::component_key(int c) const {
  if (!innovations_) return gap_component_key(c);
  return c == 0 ? "gnss_north" : "gnss_east";
}

std::vector<size_t> GapModel::segments_of_rest(size_t r) const {
  std::vector<size_t> out;
  for (size_t s = 0; s < segments_.size(); ++s)
    if (segments_[s].rest_a == r || segments_[s].rest_b == r) out.push_back(s);
  return out;
}

double GapModel::duration_s() const { return in_.imu.back().t_s - t_first_s_; }

// A rest found by a detector on the data (table-free) may include the first or last instants of
// the hand's motion: half a second off each end (as far as the rest keeps min_rest_samples) leaves
// them to the moves, whose strapdown carries any motion.
void GapModel::trim_rests(size_t min_rest_samples) {
  constexpr double kTrim_s = 0.5;
  for (RestPeriod& p : rests_) {
    size_t b = p.begin, e = p.end;
    while (e - b > min_rest_samples && in_.imu[b].t_s - in_.imu[p.begin].t_s < kTrim_s) ++b;
    while (e - b > min_rest_samples && in_.imu[p.end - 1].t_s - in_.imu[e - 1].t_s < kTrim_s) --e;
    p.begin = b;
    p.end = e;
  }
}

void GapModel::build_segments(size_t min_rest_samples) {
  rests_ = find_rest_periods(in_, min_rest_samples);
  if (table_free_) trim_rests(min_rest_samples);
  if (rests_.size() < 2)
    fail("found " + std::to_string(rests_.size()) + " rest period(s) of at least " +
         std::to_string(min_rest_samples) +
         " at_rest samples; the diagnosis needs at least 2 (rests and the moves between them)");
  auto angles = [&](GapSegment& s, size_t k) {
    s.outer_deg = in_.reference[k].outer_rad * kRadToDeg;
    s.inner_deg = in_.reference[k].inner_rad * kRadToDeg;
  };
  for (size_t r = 0; r < rests_.size(); ++r) {
    const RestPeriod& p = rests_[r];
    RestSums s;
    long double dv[3] = {0, 0, 0}, dth[3] = {0, 0, 0}, s1 = 0, s2 = 0, s3 = 0;
    for (size_t k = p.begin; k < p.end; ++k) {
      const ImuIncrement& x = in_.imu[k];
      for (int i = 0; i < 3; ++i) {
        dv[i] += x.dv_mps(i);
        dth[i] += x.dtheta_rad(i);
      }
      const long double dt = x.dt_s;
      s1 += dt;
      s2 += dt * dt;
      s3 += dt * dt * dt;
    }
    s.T_s = static_cast<double>(s1);
    for (int i = 0; i < 3; ++i) {
      s.f_mean_raw(i) = static_cast<double>(dv[i] / s1);
      s.w_mean_raw(i) = static_cast<double>(dth[i] / s1);
    }
    s.h1_s = static_cast<double>(s2 / (2.0L * s1));
    s.h2_s2 = static_cast<double>(s3 / (6.0L * s1));
    s.t0_s = in_.imu[p.begin].t_s - in_.imu[p.begin].dt_s - t_first_s_;
    s.ref_sample = p.begin + p.size() / 2;
    sums_.push_back(s);

    GapSegment seg;
    seg.kind = GapSegment::Kind::kRest;
    seg.number = static_cast<int>(r) + 1;
    seg.begin = p.begin;
    seg.end = p.end;
    seg.rest_a = seg.rest_b = r;
    seg.t0_s = in_.imu[p.begin].t_s - in_.imu[p.begin].dt_s;
    seg.t1_s = in_.imu[p.end - 1].t_s;
    angles(seg, s.ref_sample);
    segments_.push_back(seg);
    if (r + 1 < rests_.size()) {
      GapSegment mv;
      mv.kind = GapSegment::Kind::kMove;
      mv.number = static_cast<int>(r) + 1;
      mv.begin = p.end;
      mv.end = rests_[r + 1].begin;
      mv.rest_a = r;
      mv.rest_b = r + 1;
      mv.t0_s = seg.t1_s;
      mv.t1_s = in_.imu[mv.end - 1].t_s;
      angles(mv, rests_[r + 1].begin + rests_[r + 1].size() / 2);
      segments_.push_back(mv);
    }
  }
}

void GapModel::build_covariances() {
  cov_.clear();
  whitener_.clear();
  const NoiseModel& nm = in_.noise;
  // The declared rounding (noise_model.hpp): per sample, white noise beside ARW and VRW (it
  // walks the attitude of a move as ARW does); carried, one LSB residue at each end of a segment.
  const double dt = in_.imu.front().dt_s;
  const double arw2 = nm.arw_rad_per_sqrt_s * nm.arw_rad_per_sqrt_s +
                      rounding_white_density(nm.dtheta_lsb_rad, nm.lsb_rounding, dt);
  const double vrw2 = nm.vrw_mps_per_sqrt_s * nm.vrw_mps_per_sqrt_s +
                      rounding_white_density(nm.dv_lsb_mps, nm.lsb_rounding, dt);
  const double q_dv = rounding_end_residues(nm.dv_lsb_mps, nm.lsb_rounding);
  const double q_th = rounding_end_residues(nm.dtheta_lsb_rad, nm.lsb_rounding);
  const EarthModel earth(in_.site);
  const Eigen::Matrix3d F = skew<double>(Eigen::Vector3d(-earth.g_n()));  // [f_n×] at rest
  for (const GapSegment& s : segments_) {
    Block6 P = Block6::Zero();
    if (s.kind == GapSegment::Kind::kRest) {
      const double T = sums_[s.rest_a].T_s;
      P.topLeftCorner<3, 3>().diagonal().setConstant(vrw2 / T + q_dv / (T * T));
      P.bottomRightCorner<3, 3>().diagonal().setConstant(arw2 / T + q_th / (T * T));
    } else {
      double T = 0.0;
      for (size_t k = s.begin; k < s.end; ++k) T += in_.imu[k].dt_s;
      // n-frame: ψ = Σ n_j (random walk), δv = Σ_k [f_n×] ψ_k dt + VRW noise (see header).
      Block6 Pn = Block6::Zero();
      const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
      Pn.topLeftCorner<3, 3>() =
          F * F.transpose() * (arw2 * T * T * T / 3.0) + (vrw2 * T + q_dv) * I;
      Pn.topRightCorner<3, 3>() = F * (arw2 * T * T / 2.0);
      Pn.bottomLeftCorner<3, 3>() = Pn.topRightCorner<3, 3>().transpose();
      Pn.bottomRightCorner<3, 3>() = (arw2 * T + q_th) * I;
      // Residuals are reported in body axes at B: rotate both blocks.
      const Eigen::Matrix3d& C = rest_C_bn_[s.rest_b];
      Block6 R = Block6::Zero();
      R.topLeftCorner<3, 3>() = C.transpose();
      R.bottomRightCorner<3, 3>() = C.transpose();
      P = R * Pn * R.transpose();
    }
    cov_.push_back(P);
    const Eigen::LLT<Block6> llt(P);
    if (llt.info() != Eigen::Success)
      fail("segment " + s.label() + ": covariance not positive definite");
    Block6 L = llt.matrixL();
    Block6 W = L.inverse();
    if (table_free_ && s.kind == GapSegment::Kind::kMove) W = heading_last(W, s) * W;
    whitener_.push_back(W);
  }
}

// A table-free move's attitude residual sees the relative heading of its two rests, which nothing
// else measures (the rests' Earth rate only weakly): the whitening is rotated (Householder) so that
// the heading direction h = (0, C_Bᵀ e_down) lands in whitened row kHeadingRow alone. The other
// five rows are then free of it: the held-out check predicts those (calib/diagnosis/diagnosis.cpp).
Block6 GapModel::heading_last(const Block6& W, const GapSegment& s) const {
  Eigen::Matrix<double, 6, 1> h = Eigen::Matrix<double, 6, 1>::Zero();
  h.tail<3>() = rest_C_bn_[s.rest_b].transpose() * Eigen::Vector3d::UnitZ();
  const Eigen::Matrix<double, 6, 1> u = (W * h).normalized();
  Eigen::Matrix<double, 6, 1> v = u;
  v(kHeadingRow) -= 1.0;
  if (!(v.norm() > 1e-12)) return Block6::Identity();
  return Block6::Identity() - 2.0 * v * v.transpose() / v.squaredNorm();
}

Eigen::VectorXd GapModel::whiten(const Eigen::VectorXd& r) const {
  if (innovations_)
    return r.cwiseQuotient(Eigen::Map<const Eigen::VectorXd>(row_sqrt_s_.data(), rows()));
  Eigen::VectorXd w(r.size());
  for (size_t s = 0; s < segments_.size(); ++s)
    w.segment<6>(6 * static_cast<int>(s)) = whitener_[s] * r.segment<6>(6 * static_cast<int>(s));
  return w;
}

Eigen::MatrixXd GapModel::whiten(const Eigen::MatrixXd& J) const {
  if (innovations_)
    return Eigen::Map<const Eigen::VectorXd>(row_sqrt_s_.data(), rows())
               .cwiseInverse()
               .asDiagonal() *
           J;
  Eigen::MatrixXd w(J.rows(), J.cols());
  for (size_t s = 0; s < segments_.size(); ++s)
    w.middleRows<6>(6 * static_cast<int>(s)) =
        whitener_[s] * J.middleRows<6>(6 * static_cast<int>(s));
  return w;
}

Eigen::Matrix3d GapModel::true_attitude(size_t k, const ParamSet& base, const Effects& fx) const {
  const ReferenceSample& ref = in_.reference[k];
  Eigen::Matrix3d C = ref.C_bn_ref;
  if (geometry_ && (fx.table_nonorthogonality_rad != 0.0 || !fx.table_wobble_rad.isZero()))
    C = table_C_bn<double>(*geometry_, ref.outer_rad, ref.inner_rad, fx.table_nonorthogonality_rad,
                           fx.table_wobble_rad);
  return rotvec_to_matrix<double>(base.table_misalignment_rad) * C;
}

Eigen::Matrix3d GapModel::rest_attitude(size_t r, const ParamSet& base, const Effects& fx,
                                        const Eigen::VectorXd* dpsi_n) const {
  if (!table_free_) return true_attitude(sums_[r].ref_sample, base, fx);
  if (!dpsi_n) return rest_C_bn_[r];
  const Eigen::Vector3d d = dpsi_n->segment<3>(3 * static_cast<int>(r));
  return rotvec_to_matrix<double>(d) * rest_C_bn_[r];
}

void GapModel::segment_residuals(size_t s, const ParamSet& base, const Effects& fx,
                                 const Eigen::VectorXd* dpsi_n, double* out) const {
  if (segments_[s].kind == GapSegment::Kind::kRest)
    rest_residual(segments_[s].rest_a, base, fx, dpsi_n, out);
  else
    move_residual(segments_[s], base, fx, dpsi_n, out);
}

Eigen::VectorXd GapModel::residuals(const ParamSet& base, const Effects& fx) const {
  if (innovations_) return innovation_residuals(base, fx);
  Eigen::VectorXd r(rows());
  for (size_t s = 0; s < segments_.size(); ++s)
    segment_residuals(s, base, fx, nullptr, r.data() + 6 * s);
  return r;
}

Eigen::VectorXd GapModel::residuals(const ParamSet& base, const Effects& fx,
                                    const Eigen::VectorXd& dpsi_n) const {
  if (dpsi_n.size() != attitude_unknowns())
    throw std::logic_error("gap model: rest attitude unknowns of the wrong size");
  Eigen::VectorXd r(rows());
  for (size_t s = 0; s < segments_.size(); ++s)
    segment_residuals(s, base, fx, &dpsi_n, r.data() + 6 * s);
  return r;
}

// At rest f and ω are constant in body axes, so the sensor effects are evaluated once at the rest's
// mean kinematics, the thermal warm-up integrated exactly over the rest's span.
void GapModel::rest_residual(size_t r, const ParamSet& base, const Effects& fx,
                             const Eigen::VectorXd* dpsi_n, double* out) const {
  const RestSums& s = sums_[r];
  const ImuCompensator comp(base);
  const Site site = true_site(in_.site, fx.gravity_error_mps2, fx.latitude_error_rad);
  const EarthModel earth(site);
  const Eigen::Matrix3d C = rest_attitude(r, base, fx, dpsi_n);
  SensorKinematics kin;
  kin.f_b = comp.dv(s.f_mean_raw, 1.0);
  kin.w_b = comp.dtheta(s.w_mean_raw, 1.0);
  kin.t0_s = s.t0_s;
  kin.dt_s = s.T_s;
  const IncrementDelta d = sensor_effects_delta(fx, kin, /*include_size_effect=*/true);
  // Eq. 18/23 inverted with the effects removed first (they act after the error model).
  const Eigen::Vector3d f = comp.A_a_inv * (s.f_mean_raw - base.accel_bias_mps2 - d.dv / s.T_s);
  const Eigen::Vector3d w = comp.A_g_inv * (s.w_mean_raw - base.gyro_bias_radps - d.dtheta / s.T_s);
  const Eigen::Vector3d w_ie_b = C.transpose() * earth.w_ie_n();
  const Eigen::Matrix3d W = skew<double>(w_ie_b);
  const Eigen::Matrix3d K = Eigen::Matrix3d::Identity() + s.h1_s * W + s.h2_s2 * W * W;
  const Eigen::Vector3d a = K.inverse() * f + C.transpose() * earth.g_n();
  const Eigen::Vector3d g = w - w_ie_b;
  for (int i = 0; i < 3; ++i) {
    out[i] = a(i);
    out[3 + i] = g(i);
  }
}

// Strapdown over the move from the table's attitude at A (conventions.hpp):
//   C(k) = exp(-[ω_ie_n dt×]) C(k-1) exp([dθ_k×]),  Δv_n += (I - ½[ω_ie_n dt×]) C(k-1) dv_k + g_n
//   dt.
// Each increment is compensated by the error model and by the hypothesised sensor effects,
// evaluated at the sample's own kinematics (ω̇ by central differences of the raw rates).
void GapModel::move_residual(const GapSegment& seg, const ParamSet& base, const Effects& fx,
                             const Eigen::VectorXd* dpsi_n, double* out) const {
  const ImuCompensator comp(base);
  const Site site = true_site(in_.site, fx.gravity_error_mps2, fx.latitude_error_rad);
  const EarthModel earth(site);
  const Eigen::Vector3d w_ie_n = earth.w_ie_n(), g_n = earth.g_n();
  const bool effects = fx.any();
  Eigen::Matrix3d C = rest_attitude(seg.rest_a, base, fx, dpsi_n);
  Eigen::Vector3d v = Eigen::Vector3d::Zero();
  for (size_t k = seg.begin; k < seg.end; ++k) {
    const ImuIncrement& x = in_.imu[k];
    const double dt = x.dt_s;
    Eigen::Vector3d dv_raw = x.dv_mps, dth_raw = x.dtheta_rad;
    if (effects) {
      const IncrementDelta d = sensor_effects_at(in_.imu, k, comp, fx, t_first_s_);
      dv_raw -= d.dv;
      dth_raw -= d.dtheta;
    }
    const Eigen::Vector3d dv = comp.dv(dv_raw, dt);
    const Eigen::Vector3d dth = comp.dtheta(dth_raw, dt);
    const Eigen::Vector3d e = w_ie_n * dt;
    v += (C * dv - 0.5 * e.cross(C * dv)) + g_n * dt;
    C = advance_attitude(C, dth, e);
    if ((k - seg.begin) % kOrthonormaliseEvery == kOrthonormaliseEvery - 1) C = orthonormalize(C);
  }
  const Eigen::Matrix3d C_b = rest_attitude(seg.rest_b, base, fx, dpsi_n);
  const Eigen::Vector3d psi =
      C_b.transpose() * matrix_to_rotvec(C_b * orthonormalize(C).transpose());
  const Eigen::Vector3d vb = C_b.transpose() * v;
  for (int i = 0; i < 3; ++i) {
    out[i] = vb(i);
    out[3 + i] = psi(i);
  }
}

}  // namespace imucal::calib::diagnosis
