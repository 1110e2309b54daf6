#include "calib/ains_filter.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "calib/imu_error_model.hpp"
#include "calib/rotation.hpp"

namespace imucal::calib::ains {

using Eigen::Matrix3d;
using Eigen::Vector3d;

namespace {

constexpr int kNs = kNumSensor;

[[noreturn]] void fail(const std::string& what) {
  throw std::invalid_argument("calibrate_ains: " + what);
}

bool finite3(const Vector3d& v) { return v.allFinite(); }

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

PreparedInput prepare_input(const CalibrationInput& in, const AinsOptions& opt) {
  if (opt.setting != AinsSetting::kFactory)
    fail(
        "only the factory setting (table orientation aiding) is implemented; the land and sea "
        "settings need a gyrocompass initial alignment");
  if (opt.max_iterations < 1) fail("option max_iterations must be >= 1");
  check_positive(opt.convergence_sigma_ratio, "convergence_sigma_ratio");
  check_positive(opt.attitude_sigma_rad, "attitude_sigma_rad");
  check_positive(opt.zupt_sigma_mps, "zupt_sigma_mps");
  check_positive(opt.depth_sigma_m, "depth_sigma_m");
  check_positive(opt.update_interval_s, "update_interval_s");
  check_positive(opt.propagation_interval_s, "propagation_interval_s");
  if (opt.min_rest_samples < 2) fail("option min_rest_samples must be >= 2");
  const ParamVector prior = opt.prior_sigma.to_vector();
  if (!prior.allFinite()) fail("option prior_sigma has a non-finite element");

  check_nonnegative(in.noise.arw_rad_per_sqrt_s, "arw_rad_per_sqrt_s");
  check_nonnegative(in.noise.vrw_mps_per_sqrt_s, "vrw_mps_per_sqrt_s");
  check_nonnegative(in.noise.dtheta_lsb_rad, "dtheta_lsb_rad");
  check_nonnegative(in.noise.dv_lsb_mps, "dv_lsb_mps");
  if (!(std::isfinite(in.site.lat_rad) && std::abs(in.site.lat_rad) < 0.5 * kPi - 1e-6 &&
        std::isfinite(in.site.lon_rad) && std::isfinite(in.site.height_m)))
    fail("site latitude/longitude/height must be finite with |latitude| < 90 deg");
  if (in.site.gravity_mps2 && !(std::isfinite(*in.site.gravity_mps2) && *in.site.gravity_mps2 > 0))
    fail("site gravity_mps2 must be finite and > 0");

  const size_t n = in.imu.size();
  if (n == 0) fail("input has no IMU samples");
  if (in.reference.size() != n)
    fail("imu has " + std::to_string(n) + " samples but reference has " +
         std::to_string(in.reference.size()) + " (must be equal, same time axis)");
  for (size_t k = 0; k < n; ++k) {
    const ImuIncrement& s = in.imu[k];
    if (!std::isfinite(s.t_s)) fail(at("imu", k) + ".t_s is not finite");
    if (!(std::isfinite(s.dt_s) && s.dt_s > 0.0))
      fail(at("imu", k) + ".dt_s must be finite and > 0");
    if (!finite3(s.dtheta_rad)) fail(at("imu", k) + ".dtheta_rad is not finite");
    if (!finite3(s.dv_mps)) fail(at("imu", k) + ".dv_mps is not finite");
    if (k > 0 && !(s.t_s > in.imu[k - 1].t_s)) fail(at("imu", k) + ".t_s is not increasing");
    const ReferenceSample& r = in.reference[k];
    if (!(std::abs(r.t_s - s.t_s) <= 0.5 * s.dt_s))
      fail(at("reference", k) + ".t_s differs from imu[k].t_s by more than half a sample");
    if (!r.C_bn_ref.allFinite()) fail(at("reference", k) + ".C_bn_ref is not finite");
    if ((r.C_bn_ref.transpose() * r.C_bn_ref - Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6 ||
        r.C_bn_ref.determinant() < 0.0)
      fail(at("reference", k) + ".C_bn_ref is not a rotation matrix");
  }

  const std::vector<RestPeriod> rests = find_rest_periods(in, opt.min_rest_samples);
  if (rests.empty())
    fail("no rest periods of at least " + std::to_string(opt.min_rest_samples) +
         " samples (reference at_rest): the AINS is aided only at rest");

  PreparedInput pin;
  pin.in = &in;
  pin.k0 = rests.front().begin;
  pin.num_rest_periods = rests.size();
  pin.schedule.assign(n, 0);
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
  if (pin.schedule[n - 1] == 0) pin.schedule[n - 1] = 1;
  for (size_t k = pin.k0; k < n; ++k) pin.num_epochs += pin.schedule[k] != 0;
  return pin;
}

PassResult run_pass(const PreparedInput& pin, const AinsOptions& opt, const PassConfig& cfg,
                    std::vector<EpochRecord>* epochs) {
  const CalibrationInput& in = *pin.in;
  const size_t n = in.imu.size();
  const EarthModel earth(in.site);
  const Strapdown ins(earth);
  const ImuCompensator err(cfg.nominal);
  const Matrix3d Aa_inv = (Matrix3d::Identity() + cfg.nominal.accel_M).inverse();
  const Matrix3d Ag_inv = (Matrix3d::Identity() + cfg.nominal.gyro_M).inverse();
  const Vector3d sigma_hat = cfg.nominal.table_misalignment_rad;
  // Predicted reference: C_bn_ref = exp(-[ς x]) C_bn_true (conventions.hpp), so Ĉ_ref = exp(-[ς̂ x])
  // Ĉ_bn.
  const Matrix3d C_unmis = rotvec_to_matrix<double>(Vector3d(-sigma_hat));
  const double h0 = in.site.height_m;
  const double dg_dh = 0.5 * (EarthModel::normal_gravity_mps2(in.site.lat_rad, h0 + 1.0) -
                              EarthModel::normal_gravity_mps2(in.site.lat_rad, h0 - 1.0));

  // Continuous process noise: ARW drives ψ through -C_bn n_g (isotropic), VRW drives δv.
  // Quantisation is not added: a unit's output register carries the rounding remainder into the
  // next sample (as the simulator does), so rounding never accumulates into a random walk.
  const double q_psi = in.noise.arw_rad_per_sqrt_s * in.noise.arw_rad_per_sqrt_s;
  const double q_vel = in.noise.vrw_mps_per_sqrt_s * in.noise.vrw_mps_per_sqrt_s;
  NavMat Qc = NavMat::Zero();
  Qc.block<3, 3>(kPsi, kPsi) = q_psi * Matrix3d::Identity();
  Qc.block<3, 3>(kVel, kVel) = q_vel * Matrix3d::Identity();

  // Nominal INS initialised from the reference at the first rest sample, corrected by ς̂.
  NavState nav;
  nav.C_bn = orthonormalize(rotvec_to_matrix<double>(sigma_hat) * in.reference[pin.k0].C_bn_ref);
  nav.v_n_mps.setZero();
  nav.lat_rad = in.site.lat_rad;
  nav.lon_rad = in.site.lon_rad;
  nav.height_m = h0;

  // Prior. The sensor states are θ - θ̂, so their prior mean is the prior mean minus the nominal.
  // Ĉ_bn(0) = exp([ς̂ x]) C_ref(0) = (I - [(ς - ς̂) x]) C_bn_true  =>  ψ(0) = Δς + ε, ε the
  // reference noise: ψ(0) and Δς are fully correlated in the prior.
  StateVec x = StateVec::Zero();
  StateCov P = StateCov::Zero();
  params_to_sensor_states(cfg.prior_mean - cfg.nominal.to_vector(), x);
  const ParamVector ps = cfg.prior_sigma.to_vector();
  for (int i = 0; i < ParamSet::kSize; ++i) {
    const int s = state_index_of_param(i);
    P(s, s) = ps(i) * ps(i);
  }
  x.segment<3>(kPsi) = x.segment<3>(kTableMis);
  const Matrix3d P_mis = P.block<3, 3>(kTableMis, kTableMis);
  P.block<3, 3>(kPsi, kPsi) =
      P_mis + opt.attitude_sigma_rad * opt.attitude_sigma_rad * Matrix3d::Identity();
  P.block<3, 3>(kPsi, kTableMis) = P_mis;
  P.block<3, 3>(kTableMis, kPsi) = P_mis;
  P.block<3, 3>(kVel, kVel) = opt.zupt_sigma_mps * opt.zupt_sigma_mps * Matrix3d::Identity();
  P(kPos + 0, kPos + 0) = 1.0;  // horizontal position: 1 m (not observed, barely coupled)
  P(kPos + 1, kPos + 1) = 1.0;
  P(kPos + 2, kPos + 2) = opt.depth_sigma_m * opt.depth_sigma_m;

  PassResult res;
  if (epochs) {
    epochs->clear();
    epochs->reserve(pin.num_epochs);
  }

  // Transition accumulated since the last epoch.
  NavMat Phi_nn = NavMat::Identity();
  NavSensorMat Phi_ns = NavSensorMat::Zero();
  NavMat Q = NavMat::Zero();
  SensorCouplingAccumulator acc;

  // F_nn depends on the nominal's latitude, height, velocity and mean specific force, which are
  // constant to first order between two epochs (at rest and, with the IMU at the rotation centre,
  // during moves: f_n = -g). It is linearised once per epoch interval; Φ_nn and Q of a
  // sub-interval are reused while its length repeats. (Re-linearising every sub-interval, or
  // using one sub-interval per epoch, changes the estimates by < 1e-3 σ.)
  bool lin_valid = false;
  NavMat F = NavMat::Zero(), F2 = NavMat::Zero(), Phi_sub_nn = NavMat::Identity(),
         Q_sub = NavMat::Zero();
  double T_cached = -1.0;
  auto close_subinterval = [&]() {
    if (acc.empty()) return;
    const double T = acc.duration_s();
    if (!lin_valid) {
      NavLinearisation lin;
      lin.lat_rad = nav.lat_rad;
      lin.height_m = nav.height_m;
      lin.v_n_mps = nav.v_n_mps;
      lin.f_n_mps2 = acc.mean_f_n_mps2();
      lin.dg_dh_per_s2 = dg_dh;
      F = nav_error_dynamics(lin);
      F2 = F.lazyProduct(F);
      lin_valid = true;
      T_cached = -1.0;
    }
    if (std::abs(T - T_cached) > 1e-9 * T) {
      Phi_sub_nn = nav_transition(F, T);
      // Q_sub = ∫ Φ(s) Qc Φ(s)^T ds to third order; Qc is diagonal: F Qc is a column scaling.
      NavMat FQ = F;
      FQ.middleCols<3>(kPsi) *= q_psi;
      FQ.middleCols<3>(kVel) *= q_vel;
      FQ.middleCols<3>(kPos).setZero();
      Q_sub = Qc * T + 0.5 * (FQ + FQ.transpose()) * (T * T) +
              (1.0 / 3.0) * (T * T * T) * FQ.lazyProduct(F.transpose());
      T_cached = T;
    }
    const NavSensorMat Phi_sub_ns = acc.transition(F, F2);
    // Compose: Φ_ep <- Φ_sub Φ_ep (block upper-triangular with identity sensor block; the ς
    // columns of Φ_ns stay zero: ς does not drive the navigation errors).
    constexpr int kDriven = kTableMis - kNumNav;
    // (lazyProduct: coefficient-based, far cheaper than blocked GEMM at these sizes)
    const Eigen::Matrix<double, kNumNav, kDriven> Phi_ns_new =
        Phi_sub_nn.lazyProduct(Phi_ns.leftCols<kDriven>()) + Phi_sub_ns.leftCols<kDriven>();
    Phi_ns.leftCols<kDriven>() = Phi_ns_new;
    const NavMat Phi_nn_new = Phi_sub_nn.lazyProduct(Phi_nn);
    Phi_nn = Phi_nn_new;
    const NavMat PQ = Phi_sub_nn.lazyProduct(Q);
    Q = PQ.lazyProduct(Phi_sub_nn.transpose()) + Q_sub;
    acc.reset();
  };

  auto predict = [&]() {
    // x <- Φ x ; P <- Φ P Φ^T + Q using the block structure (sensor block unchanged).
    const Eigen::Matrix<double, kNs, 1> xs = x.tail<kNs>();
    x.head<kNumNav>() = Phi_nn * x.head<kNumNav>() + Phi_ns * xs;
    propagate_covariance(Phi_nn, Phi_ns, Q, P, P);
    if (epochs && !epochs->empty()) {
      EpochRecord& prev = epochs->back();
      prev.Phi_nn = Phi_nn;
      prev.Phi_ns = Phi_ns;
      prev.Q = Q;
      prev.x_p_next = x;
    }
    Phi_nn.setIdentity();
    Phi_ns.setZero();
    Q.setZero();
    lin_valid = false;
  };

  // Sequential scalar update with h = c1 e_i1 + c2 e_i2 (all our H rows have this form).
  auto scalar_update = [&](double z, int i1, double c1, int i2, double c2, double r) {
    Eigen::Matrix<double, kNumStates, 1> Ph = c1 * P.col(i1);
    if (c2 != 0.0) Ph += c2 * P.col(i2);
    const double s = c1 * Ph(i1) + (c2 != 0.0 ? c2 * Ph(i2) : 0.0) + r;
    const double nu = z - (c1 * x(i1) + (c2 != 0.0 ? c2 * x(i2) : 0.0));
    x += Ph * (nu / s);
    P.noalias() -= (Ph / s) * Ph.transpose();
    res.nis_sum += nu * nu / s;
    ++res.nis_count;
  };

  auto update = [&](size_t k, bool with_attitude) {
    if (with_attitude) {
      // eq. 32-35 with m = n: δC = I - Ĉ_ref C_ref^T ≈ [ψ x] - [Δς x]; z = log(C_ref Ĉ_ref^T).
      const Matrix3d C_ref_hat = C_unmis * nav.C_bn;
      const Vector3d z = matrix_to_rotvec(in.reference[k].C_bn_ref * C_ref_hat.transpose());
      const double r = opt.attitude_sigma_rad * opt.attitude_sigma_rad;
      for (int i = 0; i < 3; ++i) scalar_update(z(i), kPsi + i, 1.0, kTableMis + i, -1.0, r);
    }
    // eq. 36-39: ZUPT, δz = v̂_n - 0 = δv_n.
    const double r_v = opt.zupt_sigma_mps * opt.zupt_sigma_mps;
    for (int i = 0; i < 3; ++i) scalar_update(nav.v_n_mps(i), kVel + i, 1.0, 0, 0.0, r_v);
    // eq. 40-43: mean depth, δz = d̂ - d0 = δp_D (depth = -height).
    scalar_update(h0 - nav.height_m, kPos + 2, 1.0, 0, 0.0, opt.depth_sigma_m * opt.depth_sigma_m);
    P = 0.5 * (P + P.transpose()).eval();
    ++res.num_updates;
  };

  auto record_and_reset = [&](size_t k, bool aided) {
    if (epochs) {
      epochs->emplace_back();
      EpochRecord& e = epochs->back();
      e.k = k;
      e.t_s = in.imu[k].t_s;
      e.aided = aided;
      e.nominal = nav;
      e.x_f = x;
      e.P_f = P;
    }
    // Feedback of the navigation errors into the nominal (parameters stay fixed in a pass).
    // Ĉ = (I - [ψ x]) C  =>  C = exp([ψ x]) Ĉ; v = v̂ - δv; p = p̂ - δp.
    const Vector3d psi = x.segment<3>(kPsi);
    const Vector3d dv = x.segment<3>(kVel);
    const Vector3d dp = x.segment<3>(kPos);
    nav.C_bn = orthonormalize(rotvec_to_matrix<double>(psi) * nav.C_bn);
    nav.v_n_mps -= dv;
    const double RNh = EarthModel::radius_north_m(nav.lat_rad) + nav.height_m;
    const double REh = EarthModel::radius_east_m(nav.lat_rad) + nav.height_m;
    nav.lat_rad -= dp(0) / RNh;
    nav.lon_rad -= dp(1) / (REh * std::cos(nav.lat_rad));
    nav.height_m += dp(2);
    x.head<kNumNav>().setZero();
  };

  // Epoch at the INS start: ZUPT and depth only (the attitude there initialised the nominal).
  update(pin.k0, false);
  record_and_reset(pin.k0, true);

  for (size_t k = pin.k0 + 1; k < n; ++k) {
    const ImuIncrement& s = in.imu[k];
    const Vector3d dth = err.dtheta(s.dtheta_rad, s.dt_s);
    const Vector3d dv = err.dv(s.dv_mps, s.dt_s);
    const Matrix3d C_start = nav.C_bn;
    ins.step(nav, dth, dv, s.dt_s);
    acc.add(C_start, nav.C_bn, dth, dv, s.dt_s, Ag_inv, Aa_inv);
    const uint8_t kind = pin.schedule[k];
    if (kind != 0 || acc.duration_s() >= opt.propagation_interval_s - 0.5 * s.dt_s)
      close_subinterval();
    if (kind != 0) {
      predict();
      if (kind == 2) update(k, true);
      record_and_reset(k, kind == 2);
      if (!x.allFinite() || !P.allFinite())
        throw std::runtime_error("calibrate_ains: filter diverged (non-finite state) at sample " +
                                 std::to_string(k));
    }
  }
  res.x = x;
  res.P = P;
  return res;
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
