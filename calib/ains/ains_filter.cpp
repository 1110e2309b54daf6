#include "calib/ains/ains_filter.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "calib/ains/ains_innovations.hpp"
#include "calib/core/imu_error_model.hpp"
#include "calib/core/rotation.hpp"

namespace imucal::calib::ains {
using namespace calib::core;

using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

constexpr int kNs = kNumSensor;

[[noreturn]] void fail(const std::string& what) {
  throw std::invalid_argument("AINS: " + what);  // the method, not the function (issue #19)
}

std::string at(const char* field, size_t k) {
  std::ostringstream os;
  os << field << "[" << k << "]";
  return os.str();
}

void check_positive(double v, const char* name) {
  if (!(std::isfinite(v) && v > 0.0))
    fail(std::string("option ") + name + " must be finite and > 0, got " + std::to_string(v));
}

void check_nonnegative(double v, const char* name) {
  if (!(std::isfinite(v) && v >= 0.0))
    fail(std::string("noise model ") + name + " must be finite and >= 0, got " + std::to_string(v));
}

}  // namespace

namespace {

void check_options(const AinsOptions& opt) {
  if (opt.max_iterations < 1) fail("option max_iterations must be >= 1");
  check_positive(opt.convergence_sigma_ratio, "convergence_sigma_ratio");
  check_positive(opt.attitude_sigma_rad, "attitude_sigma_rad");
  check_positive(opt.zupt_sigma_mps, "zupt_sigma_mps");
  check_positive(opt.depth_sigma_m, "depth_sigma_m");
  check_positive(opt.sea_depth_sigma_m, "sea_depth_sigma_m");
  check_positive(opt.initial_tilt_sigma_rad, "initial_tilt_sigma_rad");
  check_positive(opt.initial_heading_sigma_rad, "initial_heading_sigma_rad");
  check_positive(opt.sea_initial_velocity_sigma_mps, "sea_initial_velocity_sigma_mps");
  check_positive(opt.update_interval_s, "update_interval_s");
  check_positive(opt.propagation_interval_s, "propagation_interval_s");
  if (!std::isfinite(opt.gnss_sigma_m)) fail("option gnss_sigma_m must be finite");
  if (opt.min_rest_samples < 2) fail("option min_rest_samples must be >= 2");
  if (!opt.prior_sigma.to_vector().allFinite()) fail("option prior_sigma has a non-finite element");
  if (opt.start && !opt.start->to_vector().allFinite())
    fail("option start has a non-finite element");
}

void check_site_and_noise(const CalibrationInput& in) {
  check_nonnegative(in.noise.arw_rad_per_sqrt_s, "arw_rad_per_sqrt_s");
  check_nonnegative(in.noise.vrw_mps_per_sqrt_s, "vrw_mps_per_sqrt_s");
  check_nonnegative(in.noise.dtheta_lsb_rad, "dtheta_lsb_rad");
  check_nonnegative(in.noise.dv_lsb_mps, "dv_lsb_mps");
  if (!(std::isfinite(in.site.lat_rad) && std::abs(in.site.lat_rad) < 0.5 * kPi - 1e-6 &&
        std::isfinite(in.site.lon_rad) && std::isfinite(in.site.height_m)))
    fail("site latitude/longitude/height must be finite with |latitude| < 90 deg");
  if (in.site.gravity_mps2 && !(std::isfinite(*in.site.gravity_mps2) && *in.site.gravity_mps2 > 0))
    fail("site gravity_mps2 must be finite and > 0");
}

/// Sea: every fix checked and mapped to the IMU sample nearest its time.
std::vector<int32_t> map_gnss(const CalibrationInput& in) {
  if (in.setting != Setting::kSea) {
    if (!in.gnss.empty() && in.setting == Setting::kFactory)
      fail("GNSS fixes are given for a factory run (only the sea setting uses them)");
    return {};
  }
  if (in.gnss.empty())
    fail("the sea setting needs GNSS position fixes (gnss.csv): there is no zero velocity at sea");
  const size_t n = in.imu.size();
  const double t_first = in.imu.front().t_s - in.imu.front().dt_s, t_last = in.imu.back().t_s;
  std::vector<int32_t> at_sample(n, -1);
  size_t k = 0;
  for (size_t i = 0; i < in.gnss.size(); ++i) {
    const GnssFix& g = in.gnss[i];
    if (!(std::isfinite(g.t_s) && std::isfinite(g.lat_rad) && std::isfinite(g.lon_rad) &&
          std::abs(g.lat_rad) < 0.5 * kPi && std::isfinite(g.sigma_m) && g.sigma_m > 0.0))
      fail(at("gnss", i) + " has a non-finite value, |latitude| >= 90 deg or sigma_m <= 0");
    if (i > 0 && !(g.t_s > in.gnss[i - 1].t_s)) fail(at("gnss", i) + ".t_s is not increasing");
    if (g.t_s < t_first || g.t_s > t_last)
      fail(at("gnss", i) + ".t_s = " + std::to_string(g.t_s) + " is outside the IMU's time span [" +
           std::to_string(t_first) + ", " + std::to_string(t_last) + "]");
    while (k + 1 < n && std::abs(in.imu[k + 1].t_s - g.t_s) <= std::abs(in.imu[k].t_s - g.t_s)) ++k;
    at_sample[k] = static_cast<int32_t>(i);
  }
  return at_sample;
}

}  // namespace

PreparedInput prepare_input(const CalibrationInput& in, const AinsOptions& opt) {
  check_options(opt);
  check_site_and_noise(in);
  check_input_samples(in, "AINS: ");
  const size_t n = in.imu.size();

  const std::vector<RestPeriod> rests = find_rest_periods(in, opt.min_rest_samples);
  if (rests.empty())
    fail("no rest periods of at least " + std::to_string(opt.min_rest_samples) +
         " samples (at_rest): the AINS is aided only at rest and aligns on the first one");

  PreparedInput pin;
  pin.in = &in;
  pin.k0 = rests.front().begin;
  pin.first_rest = rests.front();
  pin.num_rest_periods = rests.size();
  pin.gnss_at = map_gnss(in);
  pin.schedule.assign(n, 0);
  if (in.setting == Setting::kSea) {
    // Aided wherever a fix is (rest or not): GNSS and mean depth do not need the unit at rest.
    for (size_t k = pin.k0 + 1; k < n; ++k)
      if (pin.gnss_at[k] >= 0) pin.schedule[k] = 2;
  } else {
    double t_last = -1e300;
    for (const RestPeriod& rp : rests) {
      for (size_t k = rp.begin; k < rp.end; ++k) {
        const double t = in.imu[k].t_s;
        const double half_dt = 0.5 * in.imu[k].dt_s;
        const bool first = k == rp.begin;
        const bool due = t - t_last >= opt.update_interval_s - half_dt;
        // The last sample of a period is used too, unless an update was just made.
        const bool last = k + 1 == rp.end && t - t_last >= 0.5 * opt.update_interval_s;
        if (first || due || last) {
          pin.schedule[k] = 2;
          t_last = t;
        }
      }
    }
  }
  if (pin.schedule[n - 1] == 0) pin.schedule[n - 1] = 1;
  pin.unusable.assign(n, 0);
  for (const UnusableSpan& s : in.unusable)
    for (size_t k = s.begin; k < std::min(s.end, n); ++k) pin.unusable[k] = 1;
  // The pass records the start epoch k0 whatever its schedule, then every scheduled sample after
  // it: one short and the epochs' storage (~14 kB each) is reallocated and copied at the end.
  pin.num_epochs = 1;
  for (size_t k = pin.k0 + 1; k < n; ++k) pin.num_epochs += pin.schedule[k] != 0;
  return pin;
}

namespace {

/// One forward pass as named steps: the initial state, the accumulation of the transition over
/// sub-intervals, prediction, the aiding updates of the setting, and the feedback reset.
class PassRunner {
 public:
  PassRunner(const PreparedInput& pin, const AinsOptions& opt, const PassConfig& cfg,
             std::vector<EpochRecord>* epochs)
      : pin_(pin),
        in_(*pin.in),
        opt_(opt),
        cfg_(cfg),
        epochs_(epochs),
        earth_(in_.site),
        ins_(earth_),
        err_(cfg.nominal),
        Aa_inv_((Matrix3d::Identity() + cfg.nominal.accel_M).inverse()),
        Ag_inv_((Matrix3d::Identity() + cfg.nominal.gyro_M).inverse()),
        // Predicted reference: C_bn_ref = exp(-[ς x]) C_bn_true (conventions.hpp).
        C_unmis_(rotvec_to_matrix<double>(Vector3d(-cfg.nominal.table_misalignment_rad))),
        h0_(in_.site.height_m),
        dg_dh_(0.5 * (EarthModel::normal_gravity_mps2(in_.site.lat_rad, h0_ + 1.0) -
                      EarthModel::normal_gravity_mps2(in_.site.lat_rad, h0_ - 1.0))),
        // Continuous process noise: ARW drives ψ through -C_bn n_g (isotropic), VRW drives δv.
        // A carried rounding is not added: the output register carries the remainder into the
        // next sample (as the simulator does), so it never accumulates. A per-sample rounding (a
        // logger of counts) does, as white noise of density LSB²/(12 dt) (noise_model.hpp).
        q_psi_(in_.noise.arw_rad_per_sqrt_s * in_.noise.arw_rad_per_sqrt_s +
               rounding_white_density(in_.noise.dtheta_lsb_rad, in_.noise.lsb_rounding,
                                      in_.imu.front().dt_s)),
        q_vel_(in_.noise.vrw_mps_per_sqrt_s * in_.noise.vrw_mps_per_sqrt_s +
               rounding_white_density(in_.noise.dv_lsb_mps, in_.noise.lsb_rounding,
                                      in_.imu.front().dt_s)) {
    Qc_.block<3, 3>(kPsi, kPsi) = q_psi_ * Matrix3d::Identity();
    Qc_.block<3, 3>(kVel, kVel) = q_vel_ * Matrix3d::Identity();
  }

  PassResult run() {
    init_nav();
    init_covariance();
    if (epochs_) {
      epochs_->clear();
      epochs_->reserve(pin_.num_epochs);
    }
    // Epoch at the INS start: no attitude aiding (the attitude there initialised the nominal).
    update(pin_.k0, /*with_attitude=*/false);
    record_and_reset(pin_.k0, true);
    const size_t n = in_.imu.size();
    for (size_t k = pin_.k0 + 1; k < n; ++k) {
      const ImuIncrement& s = in_.imu[k];
      const Vector3d dth = err_.dtheta(s.dtheta_rad, s.dt_s);
      const Vector3d dv = err_.dv(s.dv_mps, s.dt_s);
      const Matrix3d C_start = nav_.C_bn;
      ins_.step(nav_, dth, dv, s.dt_s);
      acc_.add(C_start, nav_.C_bn, dth, dv, s.dt_s);
      const uint8_t kind = pin_.schedule[k];
      // Released once, at the stretch's last sample.
      const bool stretch_ends = pin_.unusable[k] != 0 && (k + 1 == n || pin_.unusable[k + 1] == 0);
      release_pending_ = release_pending_ || stretch_ends;
      if (kind != 0 || stretch_ends ||
          acc_.duration_s() >= opt_.propagation_interval_s - 0.5 * s.dt_s)
        close_subinterval();
      if (kind == 0) continue;
      predict();
      if (kind == 2) update(k, in_.has_reference_attitude());
      record_and_reset(k, kind == 2);
      if (!x_.allFinite() || !P_.allFinite())
        throw std::runtime_error("AINS: filter diverged (non-finite state) at sample " +
                                 std::to_string(k));
    }
    res_.x = x_;
    res_.P = P_;
    return res_;
  }

 private:
  bool field() const { return in_.setting != Setting::kFactory; }

  void init_nav() {
    if (field()) {
      nav_.C_bn = cfg_.C_bn0;
    } else {
      // From the reference at the first rest sample, corrected by ς̂.
      nav_.C_bn = orthonormalize(rotvec_to_matrix<double>(cfg_.nominal.table_misalignment_rad) *
                                 in_.reference[pin_.k0].C_bn_ref);
    }
    nav_.v_n_mps.setZero();
    nav_.lat_rad = in_.site.lat_rad;
    nav_.lon_rad = in_.site.lon_rad;
    nav_.height_m = h0_;
    if (in_.setting == Setting::kSea) {
      // Horizontal position from the fix nearest the start (the site is only approximate).
      const GnssFix& g = in_.gnss[first_fix_index()];
      nav_.lat_rad = g.lat_rad;
      nav_.lon_rad = g.lon_rad;
    }
  }

  size_t first_fix_index() const {
    for (size_t k = pin_.k0; k < pin_.gnss_at.size(); ++k)
      if (pin_.gnss_at[k] >= 0) return static_cast<size_t>(pin_.gnss_at[k]);
    return 0;
  }

  void init_covariance() {
    // The sensor states are θ - θ̂, so their prior mean is the prior mean minus the nominal.
    params_to_sensor_states(cfg_.prior_mean - cfg_.nominal.to_vector(), x_);
    const ParamVector ps = cfg_.prior_sigma.to_vector();
    for (int i = 0; i < ParamSet::kSize; ++i) {
      const int s = state_index_of_param(i);
      P_(s, s) = ps(i) * ps(i);
    }
    if (field()) {
      init_field_attitude_and_frame();
    } else {
      // Ĉ_bn(0) = exp([ς̂ x]) C_ref(0) = (I - [(ς - ς̂) x]) C_bn_true  =>  ψ(0) = Δς + ε, ε the
      // reference noise: ψ(0) and Δς are fully correlated in the prior.
      x_.segment<3>(kPsi) = x_.segment<3>(kTableMis);
      const Matrix3d P_mis = P_.block<3, 3>(kTableMis, kTableMis);
      P_.block<3, 3>(kPsi, kPsi) =
          P_mis + opt_.attitude_sigma_rad * opt_.attitude_sigma_rad * Matrix3d::Identity();
      P_.block<3, 3>(kPsi, kTableMis) = P_mis;
      P_.block<3, 3>(kTableMis, kPsi) = P_mis;
    }
    const bool sea = in_.setting == Setting::kSea;
    const double sv = sea ? opt_.sea_initial_velocity_sigma_mps : opt_.zupt_sigma_mps;
    P_.block<3, 3>(kVel, kVel) = sv * sv * Matrix3d::Identity();
    const double sp = sea ? 3.0 * gnss_sigma(in_.gnss[first_fix_index()]) : 1.0;
    P_(kPos + 0, kPos + 0) = sp * sp;  // horizontal: 1 m on land (not observed, barely coupled)
    P_(kPos + 1, kPos + 1) = sp * sp;
    P_(kPos + 2, kPos + 2) = depth_sigma() * depth_sigma();
  }

  /// Field settings: ψ(0) about the coarse alignment with a broad prior; ς frozen at zero (no
  /// table: 33 live states); and the body frame fixed by "M_a symmetric"
  /// (calib/core/body_frame.hpp): three exact pseudo-measurements M_a(i,j) - M_a(j,i) = 0 on the
  /// nominal plus the state.
  void init_field_attitude_and_frame() {
    x_.segment<3>(kPsi) = cfg_.psi0_prior_mean;
    const Vector3d sig(opt_.initial_tilt_sigma_rad, opt_.initial_tilt_sigma_rad,
                       opt_.initial_heading_sigma_rad);
    // The tilt/heading split is about n axes: ψ is an n-frame angle (Ĉ = (I - [ψ x]) C).
    P_.block<3, 3>(kPsi, kPsi) = sig.cwiseProduct(sig).asDiagonal();
    x_.segment<3>(kTableMis).setZero();
    P_.block<3, kNumStates>(kTableMis, 0).setZero();
    P_.block<kNumStates, 3>(0, kTableMis).setZero();
    constexpr double kExact = 1e-9;  // pseudo-measurement σ (dimensionless): a hard constraint
    const Matrix3d& M = cfg_.nominal.accel_M;
    for (int i = 0; i < 3; ++i)
      for (int j = i + 1; j < 3; ++j) {
        // State of accel_M(r, c) is kAccM + 3c + r (column-major, ains_model.hpp).
        const double z = -(M(i, j) - M(j, i));
        scalar_update(z, kAccM + 3 * j + i, 1.0, kAccM + 3 * i + j, -1.0, kExact * kExact,
                      /*count_nis=*/false);
      }
  }

  double depth_sigma() const {
    return in_.setting == Setting::kSea ? opt_.sea_depth_sigma_m : opt_.depth_sigma_m;
  }
  double gnss_sigma(const GnssFix& g) const {
    return opt_.gnss_sigma_m > 0.0 ? opt_.gnss_sigma_m : g.sigma_m;
  }

  /// One sub-interval's transition, composed into the epoch's. F_nn is linearised at the nominal
  /// of each sub-interval (latitude, height, velocity, the sub-interval's mean specific force):
  /// linearising once per epoch interval instead moved ς_z by up to 0.04 σ with the sub-interval
  /// length, re-linearising each one makes 0.1 s and 1 s sub-intervals agree to 1e-4 σ.
  void close_subinterval() {
    if (acc_.empty()) return;
    const double T = acc_.duration_s();
    linearise();
    const NavMat Phi_sub_nn = nav_transition(F_, T);
    NavMat Q_sub = process_noise(T);
    if (release_pending_) release_carried_state(Q_sub);
    const NavSensorMat Phi_sub_ns = acc_.transition(F_, F2_, Ag_inv_, Aa_inv_);
    acc_.reset();
    if (epoch_start_) {  // Φ_ep = I, Q_ep = 0 so far: nothing to compose
      Phi_nn_ = Phi_sub_nn;
      Phi_ns_ = Phi_sub_ns;
      Q_ = Q_sub;
      epoch_start_ = false;
      return;
    }
    // Compose: Φ_ep <- Φ_sub Φ_ep (block upper-triangular with identity sensor block; the ς
    // columns of Φ_ns stay zero: ς does not drive the navigation errors).
    constexpr int kDriven = kTableMis - kNumNav;
    // (lazyProduct: coefficient-based, far cheaper than blocked GEMM at these sizes)
    const Eigen::Matrix<double, kNumNav, kDriven> Phi_ns_new =
        Phi_sub_nn.lazyProduct(Phi_ns_.leftCols<kDriven>()) + Phi_sub_ns.leftCols<kDriven>();
    Phi_ns_.leftCols<kDriven>() = Phi_ns_new;
    const NavMat Phi_nn_new = Phi_sub_nn.lazyProduct(Phi_nn_);
    Phi_nn_ = Phi_nn_new;
    const NavMat PQ = Phi_sub_nn.lazyProduct(Q_);
    Q_ = PQ.lazyProduct(Phi_sub_nn.transpose()) + Q_sub;
  }

  /// A clipped or dropped stretch ends in this sub-interval: what it carried (attitude, velocity)
  /// is released by AinsOptions' unusable σ, so the next rest, not the stretch, decides them.
  void release_carried_state(NavMat& Q_sub) {
    const double sa = opt_.unusable_attitude_sigma_rad, sv = opt_.unusable_velocity_sigma_mps;
    Q_sub.block<3, 3>(kPsi, kPsi) += sa * sa * Matrix3d::Identity();
    Q_sub.block<3, 3>(kVel, kVel) += sv * sv * Matrix3d::Identity();
    release_pending_ = false;
  }

  /// Q_sub = ∫ Φ(s) Qc Φ(s)^T ds with Φ(s) = I + F s + F² s²/2, term by term: exact for the
  /// ψ -> δv -> δp chain (F³ is Earth-rate sized), so a sub-interval may be a second long.
  NavMat process_noise(double T) const {
    // Q = Σ_i (F^i Qc) H_iᵀ with H_i = Σ_j c_ij F^j, c_ij = T^(i+j+1) / (i! j! (i+j+1)); Qc is
    // diagonal, so F^i Qc is a column scaling of F^i (the δp columns are zero).
    const NavMat powers[3] = {NavMat::Identity(), F_, F2_};
    const double inv_fact[3] = {1.0, 1.0, 0.5};
    NavMat Q = NavMat::Zero();
    for (int i = 0; i < 3; ++i) {
      Eigen::Matrix<double, kNumNav, 6> FiQ = powers[i].leftCols<6>();
      FiQ.middleCols<3>(kPsi) *= q_psi_;
      FiQ.middleCols<3>(kVel) *= q_vel_;
      NavMat H = NavMat::Zero();
      for (int j = 0; j < 3; ++j) {
        const int order = i + j + 1;
        H += (inv_fact[i] * inv_fact[j] * std::pow(T, order) / order) * powers[j];
      }
      Q += FiQ.lazyProduct(H.leftCols<6>().transpose());
    }
    return Q;
  }

  void linearise() {
    NavLinearisation lin;
    lin.lat_rad = nav_.lat_rad;
    lin.height_m = nav_.height_m;
    lin.v_n_mps = nav_.v_n_mps;
    lin.f_n_mps2 = acc_.mean_f_n_mps2();
    lin.dg_dh_per_s2 = dg_dh_;
    F_ = nav_error_dynamics(lin);
    F2_ = F_.lazyProduct(F_);
  }

  /// x <- Φ x ; P <- Φ P Φ^T + Q using the block structure (sensor block unchanged).
  void predict() {
    const Eigen::Matrix<double, kNs, 1> xs = x_.tail<kNs>();
    x_.head<kNumNav>() = Phi_nn_ * x_.head<kNumNav>() + Phi_ns_ * xs;
    propagate_covariance(Phi_nn_, Phi_ns_, Q_, P_, P_);
    if (epochs_ && !epochs_->empty()) {
      EpochRecord& prev = epochs_->back();
      prev.Phi_nn = Phi_nn_;
      prev.Phi_ns = Phi_ns_;
      prev.Q = Q_;
      prev.x_p_next = x_;
    }
    Phi_nn_.setIdentity();
    Phi_ns_.setZero();
    Q_.setZero();
    epoch_start_ = true;
  }

  /// Sequential scalar update with h = c1 e_i1 + c2 e_i2 (all our H rows have this form).
  void scalar_update(double z, int i1, double c1, int i2, double c2, double r,
                     bool count_nis = true, int kind = 0) {
    Eigen::Matrix<double, kNumStates, 1> Ph = c1 * P_.col(i1);
    if (c2 != 0.0) Ph += c2 * P_.col(i2);
    const double s = c1 * Ph(i1) + (c2 != 0.0 ? c2 * Ph(i2) : 0.0) + r;
    const double nu = z - (c1 * x_(i1) + (c2 != 0.0 ? c2 * x_(i2) : 0.0));
    x_ += Ph * (nu / s);
    P_.noalias() -= (Ph / s) * Ph.transpose();
    if (!count_nis) return;
    res_.nis_sum += nu * nu / s;
    ++res_.nis_count;
    if (cfg_.innovations) cfg_.innovations->push_back({k_, kind, nu, s});
  }

  void update(size_t k, bool with_attitude) {
    k_ = k;
    if (with_attitude) {
      // eq. 32-35 with m = n: δC = I - Ĉ_ref C_ref^T ≈ [ψ x] - [Δς x]; z = log(C_ref Ĉ_ref^T).
      const Matrix3d C_ref_hat = C_unmis_ * nav_.C_bn;
      const Vector3d z = matrix_to_rotvec(in_.reference[k].C_bn_ref * C_ref_hat.transpose());
      const double r = opt_.attitude_sigma_rad * opt_.attitude_sigma_rad;
      for (int i = 0; i < 3; ++i)
        scalar_update(z(i), kPsi + i, 1.0, kTableMis + i, -1.0, r, true,
                      AinsInnovation::kAttitudeX + i);
    }
    if (in_.setting == Setting::kSea) {
      if (k != pin_.k0) update_gnss(in_.gnss[static_cast<size_t>(pin_.gnss_at[k])]);
    } else {
      // eq. 36-39: ZUPT, δz = v̂_n - 0 = δv_n.
      const double r_v = opt_.zupt_sigma_mps * opt_.zupt_sigma_mps;
      for (int i = 0; i < 3; ++i)
        scalar_update(nav_.v_n_mps(i), kVel + i, 1.0, 0, 0.0, r_v, true,
                      AinsInnovation::kZuptNorth + i);
    }
    // eq. 40-43: mean depth, δz = d̂ - d0 = δp_D (depth = -height).
    scalar_update(h0_ - nav_.height_m, kPos + 2, 1.0, 0, 0.0, depth_sigma() * depth_sigma(), true,
                  AinsInnovation::kDepth);
    P_ = 0.5 * (P_ + P_.transpose()).eval();
    ++res_.num_updates;
  }

  /// eq. 44-47: δz = p̂ - p_gnss as north/east metres, H = I2 on δp_N, δp_E.
  void update_gnss(const GnssFix& g) {
    const double RNh = EarthModel::radius_north_m(nav_.lat_rad) + nav_.height_m;
    const double REh = EarthModel::radius_east_m(nav_.lat_rad) + nav_.height_m;
    const double zN = (nav_.lat_rad - g.lat_rad) * RNh;
    const double zE = (nav_.lon_rad - g.lon_rad) * REh * std::cos(nav_.lat_rad);
    const double r = gnss_sigma(g) * gnss_sigma(g);
    scalar_update(zN, kPos + 0, 1.0, 0, 0.0, r, true, AinsInnovation::kGnssNorth);
    scalar_update(zE, kPos + 1, 1.0, 0, 0.0, r, true, AinsInnovation::kGnssEast);
  }

  void record_and_reset(size_t k, bool aided) {
    if (epochs_) {
      epochs_->emplace_back();
      EpochRecord& e = epochs_->back();
      e.k = k;
      e.t_s = in_.imu[k].t_s;
      e.aided = aided;
      e.nominal = nav_;
      e.x_f = x_;
      e.P_f = P_;
    }
    // Feedback of the navigation errors into the nominal (parameters stay fixed in a pass).
    // Ĉ = (I - [ψ x]) C  =>  C = exp([ψ x]) Ĉ; v = v̂ - δv; p = p̂ - δp.
    const Vector3d psi = attitude_feedback();
    const Vector3d dv = x_.segment<3>(kVel);
    const Vector3d dp = x_.segment<3>(kPos);
    nav_.C_bn = orthonormalize(rotvec_to_matrix<double>(psi) * nav_.C_bn);
    nav_.v_n_mps -= dv;
    const double RNh = EarthModel::radius_north_m(nav_.lat_rad) + nav_.height_m;
    const double REh = EarthModel::radius_east_m(nav_.lat_rad) + nav_.height_m;
    nav_.lat_rad -= dp(0) / RNh;
    nav_.lon_rad -= dp(1) / (REh * std::cos(nav_.lat_rad));
    nav_.height_m += dp(2);
    x_.segment<3>(kPsi) -= psi;
    x_.segment<6>(kVel).setZero();
    ++epoch_index_;
  }

  /// The rotation ψ that moves the nominal attitude at this epoch (the error state keeps the rest).
  /// Factory: the filtered ψ. Field settings: the heading (ψ_D) is never fed back from the filter,
  /// and the tilt only once it is determined (σ < kTiltFeedbackMaxSigma_rad). Without attitude
  /// aiding the filtered heading stays uncertain by ~1 mrad for the whole run and early on by the
  /// prior's spread; feeding such estimates into the nominal moves the linearisation point by as
  /// much and biases the result (measured: gyro biases off by 5-40σ on land). The heading error
  /// stays in the state instead — the model is linear in it — and the iterated smoother re-centres
  /// the initial attitude on its smoothed value between passes.
  /// With an attitude track (on land below navigation grade, after the first pass) the nominal's
  /// tilt is moved onto the track's instead: a MEMS unit's tilt σ hovers about the gate for
  /// minutes, and left alone the nominal's tilt wandered with the gyro noise (1 °/√h) to 14-29 mrad
  /// on the 38-minute factory-std run; the linear model misses the vertical specific force it
  /// costs, g(1 - cos θ) ≈ gθ²/2 ≈ 400 µg, which the filter took for accelerometer scale errors of
  /// 300 ppm at σ 12 ppm (docs/validation/ains_mems_land.md).
  Vector3d attitude_feedback() const {
    Vector3d psi = x_.segment<3>(kPsi);
    if (!field()) return psi;
    // (The epoch schedule is fixed for all passes, so the track has an attitude for every epoch.)
    if (cfg_.attitude_track && epoch_index_ < cfg_.attitude_track->size()) {
      psi = matrix_to_rotvec((*cfg_.attitude_track)[epoch_index_] * nav_.C_bn.transpose());
      psi(2) = 0.0;  // the tilt only: the heading stays in the state, as without a track
      return psi;
    }
    psi(2) = 0.0;
    for (int i = 0; i < 2; ++i)
      if (P_(kPsi + i, kPsi + i) > kTiltFeedbackMaxSigma_rad * kTiltFeedbackMaxSigma_rad)
        psi(i) = 0.0;
    return psi;
  }

  static constexpr double kTiltFeedbackMaxSigma_rad = 1e-4;

  const PreparedInput& pin_;
  const CalibrationInput& in_;
  const AinsOptions& opt_;
  const PassConfig& cfg_;
  std::vector<EpochRecord>* epochs_;
  const EarthModel earth_;
  const Strapdown ins_;
  const ImuCompensator err_;
  const Matrix3d Aa_inv_, Ag_inv_, C_unmis_;
  const double h0_, dg_dh_, q_psi_, q_vel_;
  NavMat Qc_ = NavMat::Zero();

  NavState nav_;
  StateVec x_ = StateVec::Zero();
  StateCov P_ = StateCov::Zero();
  PassResult res_;
  // Transition accumulated since the last epoch, and the current linearisation.
  NavMat Phi_nn_ = NavMat::Identity();
  NavSensorMat Phi_ns_ = NavSensorMat::Zero();
  NavMat Q_ = NavMat::Zero();
  SensorCouplingAccumulator acc_;
  size_t k_ = 0;                  ///< sample of the update in progress (for the innovation records)
  size_t epoch_index_ = 0;        ///< epochs recorded so far (index into cfg_.attitude_track)
  bool epoch_start_ = true;       ///< no sub-interval composed into Φ_nn_, Φ_ns_, Q_ yet
  bool release_pending_ = false;  ///< an unusable sample since the last sub-interval closed
  NavMat F_ = NavMat::Zero(), F2_ = NavMat::Zero();
};

}  // namespace

PassResult run_pass(const PreparedInput& pin, const AinsOptions& opt, const PassConfig& cfg,
                    std::vector<EpochRecord>* epochs) {
  return PassRunner(pin, opt, cfg, epochs).run();
}

std::vector<SmoothedNav> rts_smooth(const std::vector<EpochRecord>& E,
                                    double* param_mismatch_sigma) {
  std::vector<SmoothedNav> out(E.size());
  if (E.empty()) return out;
  auto emit = [&](size_t i, const StateVec& xs, const StateCov& Ps) {
    const EpochRecord& e = E[i];
    SmoothedNav& o = out[i];
    o.sample_index = e.k;
    o.t_s = e.t_s;
    o.aided = e.aided;
    o.psi_rad = xs.segment<3>(kPsi);
    o.dv_mps = xs.segment<3>(kVel);
    o.dp_m = xs.segment<3>(kPos);
    o.sigma_psi_rad = Ps.diagonal().segment<3>(kPsi).cwiseMax(0.0).cwiseSqrt();
    o.sigma_v_mps = Ps.diagonal().segment<3>(kVel).cwiseMax(0.0).cwiseSqrt();
    o.sigma_p_m = Ps.diagonal().segment<3>(kPos).cwiseMax(0.0).cwiseSqrt();
    o.nav = e.nominal;
    o.nav.C_bn = orthonormalize(rotvec_to_matrix<double>(o.psi_rad) * e.nominal.C_bn);
    o.nav.v_n_mps = e.nominal.v_n_mps - o.dv_mps;
    const double RNh = EarthModel::radius_north_m(e.nominal.lat_rad) + e.nominal.height_m;
    const double REh = EarthModel::radius_east_m(e.nominal.lat_rad) + e.nominal.height_m;
    o.nav.lat_rad = e.nominal.lat_rad - o.dp_m(0) / RNh;
    o.nav.lon_rad = e.nominal.lon_rad - o.dp_m(1) / (REh * std::cos(e.nominal.lat_rad));
    o.nav.height_m = e.nominal.height_m + o.dp_m(2);
  };

  // With random-constant sensor states Φ = [[Φ_nn, Φ_ns], [0, I]] and Q has no sensor part, so
  // P_p e_s = Φ P_f e_s and the RTS gain G = P_f Φ^T P_p^-1 is [[G_n], [0, I]]: the sensor states'
  // smoothed values equal the final filtered ones and only the 9 navigation rows of G are needed.
  const size_t K = E.size();
  StateVec xs = E[K - 1].x_f;
  StateCov Ps = E[K - 1].P_f;
  emit(K - 1, xs, Ps);
  StateCov Pp, dP;
  Eigen::Matrix<double, kNumStates, kNumNav> C9, GnT;
  for (size_t i = K - 1; i-- > 0;) {
    const EpochRecord& e = E[i];
    propagate_covariance(e.Phi_nn, e.Phi_ns, e.Q, e.P_f, Pp);
    // (Φ P_f) e_n: nav rows Φ_nn P_nn + Φ_ns P_sn, sensor rows P_sn.
    C9.topRows<kNumNav>() = e.Phi_nn * e.P_f.topLeftCorner<kNumNav, kNumNav>() +
                            e.Phi_ns * e.P_f.bottomLeftCorner<kNs, kNumNav>();
    C9.bottomRows<kNs>() = e.P_f.bottomLeftCorner<kNs, kNumNav>();
    // Variances span ~20 orders of magnitude: equilibrate before factorising.
    const StateVec d = Pp.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
    const StateCov Pn = d.asDiagonal() * Pp * d.asDiagonal();
    const Eigen::LDLT<StateCov> ldlt(Pn);
    GnT = d.asDiagonal() * ldlt.solve(d.asDiagonal() * C9);
    const StateVec dx = xs - e.x_p_next;
    xs = e.x_f;
    xs.head<kNumNav>() += GnT.transpose() * dx;
    xs.tail<kNs>() += dx.tail<kNs>();
    // P_s = P_f + G (P_s' - P_p) G^T with G = [[G_n], [0, I]].
    dP = Ps - Pp;
    const Eigen::Matrix<double, kNumNav, kNumStates> GdP = GnT.transpose() * dP;
    Ps = e.P_f;
    Ps.topLeftCorner<kNumNav, kNumNav>() += GdP * GnT;
    Ps.topRightCorner<kNumNav, kNs>() += GdP.rightCols<kNs>();
    Ps.bottomLeftCorner<kNs, kNumNav>() = Ps.topRightCorner<kNumNav, kNs>().transpose();
    Ps.bottomRightCorner<kNs, kNs>() += dP.bottomRightCorner<kNs, kNs>();
    Ps.topLeftCorner<kNumNav, kNumNav>() = 0.5 * (Ps.topLeftCorner<kNumNav, kNumNav>() +
                                                  Ps.topLeftCorner<kNumNav, kNumNav>().transpose())
                                                     .eval();
    emit(i, xs, Ps);
  }
  if (param_mismatch_sigma) {
    const StateVec& x_last = E[K - 1].x_f;
    double m = 0.0;
    for (int s = kNumNav; s < kNumStates; ++s) {
      const double sig = std::sqrt(std::max(E[K - 1].P_f(s, s), 1e-300));
      m = std::max(m, std::abs(xs(s) - x_last(s)) / sig);
    }
    *param_mismatch_sigma = m;
  }
  return out;
}

}  // namespace imucal::calib::ains
