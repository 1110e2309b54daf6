#include "calib/nlsq/nlsq.hpp"

#include <ceres/ceres.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "calib/core/earth.hpp"
#include "calib/core/rotation.hpp"
#include "calib/nlsq/nlsq_preprocess.hpp"
#include "calib/nlsq/nlsq_residuals.hpp"

namespace imucal::calib::nlsq {
using namespace calib::core;

namespace {

// Messages reach operators: the method's name, not the function's (issue #19 item 9).
constexpr const char* kWho = "NLSQ: ";
// A rotation between rests smaller than this does not count as "the table moved".
constexpr double kMinRotation_rad = 1.0 * kDegToRad;
// Normalised information-matrix eigenvalue below which a direction counts as unobservable.
constexpr double kMinRelativeEigenvalue = 1e-14;

[[noreturn]] void fail(const std::string& what) { throw std::invalid_argument(kWho + what); }

void validate(const CalibrationInput& in, const NlsqOptions& opt) {
  if (!in.has_reference_attitude())
    fail(std::string("needs the table's attitude reference (paper §V); a ") +
         setting_name(in.setting) + " run has none (use AINS or the legacy method)");
  if (opt.max_outer_iterations < 1) fail("options.max_outer_iterations must be >= 1");
  if (!(opt.convergence_sigma_ratio > 0.0)) fail("options.convergence_sigma_ratio must be > 0");
  if (opt.ceres_max_iterations < 1) fail("options.ceres_max_iterations must be >= 1");
  if (opt.min_rest_samples < 2) fail("options.min_rest_samples must be >= 2");
  const NoiseModel& nm = in.noise;
  if (!(std::isfinite(nm.arw_rad_per_sqrt_s) && nm.arw_rad_per_sqrt_s > 0.0))
    fail("noise.arw_rad_per_sqrt_s must be finite and > 0 (it weights the gyro residuals)");
  if (!(std::isfinite(nm.vrw_mps_per_sqrt_s) && nm.vrw_mps_per_sqrt_s > 0.0))
    fail("noise.vrw_mps_per_sqrt_s must be finite and > 0 (it weights the accel residuals)");
  if (!(std::isfinite(nm.dtheta_lsb_rad) && nm.dtheta_lsb_rad >= 0.0))
    fail("noise.dtheta_lsb_rad must be finite and >= 0");
  if (!(std::isfinite(nm.dv_lsb_mps) && nm.dv_lsb_mps >= 0.0))
    fail("noise.dv_lsb_mps must be finite and >= 0");
  if (!std::isfinite(in.site.lat_rad) || std::abs(in.site.lat_rad) > 0.5 * kPi)
    fail("site.lat_rad must be finite and within [-pi/2, pi/2]");
  if (!std::isfinite(in.site.height_m)) fail("site.height_m must be finite");
  if (in.site.gravity_mps2 &&
      !(std::isfinite(*in.site.gravity_mps2) && *in.site.gravity_mps2 > 0.0))
    fail("site.gravity_mps2 must be finite and > 0 when given");
  check_input_samples(in, kWho);
}

/// The five parameter blocks, in ParamSet's flat order.
struct Blocks {
  std::array<double, 3> b_a{};
  std::array<double, 9> M_a{};
  std::array<double, 3> b_g{};
  std::array<double, 9> M_g{};
  std::array<double, 3> sig{};

  void set(const ParamVector& x) {
    std::copy(x.data() + 0, x.data() + 3, b_a.begin());
    std::copy(x.data() + 3, x.data() + 12, M_a.begin());
    std::copy(x.data() + 12, x.data() + 15, b_g.begin());
    std::copy(x.data() + 15, x.data() + 24, M_g.begin());
    std::copy(x.data() + 24, x.data() + 27, sig.begin());
  }
  ParamVector get() const {
    ParamVector x;
    std::copy(b_a.begin(), b_a.end(), x.data() + 0);
    std::copy(M_a.begin(), M_a.end(), x.data() + 3);
    std::copy(b_g.begin(), b_g.end(), x.data() + 12);
    std::copy(M_g.begin(), M_g.end(), x.data() + 15);
    std::copy(sig.begin(), sig.end(), x.data() + 24);
    return x;
  }
};

/// A residual block as added to the problem, with where its parameter blocks sit in θ.
struct BlockRef {
  ceres::CostFunction* cost = nullptr;  // owned by the problem
  std::vector<double*> params;
  std::vector<int> offsets;  // flat index of each parameter block's first element
};

/// Whitened Jacobian (m x 27) and residuals at the current parameter values.
void evaluate_all(const std::vector<BlockRef>& blocks, Eigen::MatrixXd& J, Eigen::VectorXd& r) {
  int m = 0;
  for (const auto& b : blocks) m += b.cost->num_residuals();
  J.setZero(m, ParamSet::kSize);
  r.setZero(m);
  int row = 0;
  for (const auto& b : blocks) {
    const int nr = b.cost->num_residuals();
    const auto& sizes = b.cost->parameter_block_sizes();
    std::vector<std::vector<double>> jac(sizes.size());
    std::vector<double*> jac_ptr(sizes.size());
    for (size_t i = 0; i < sizes.size(); ++i) {
      jac[i].assign(static_cast<size_t>(nr * sizes[i]), 0.0);
      jac_ptr[i] = jac[i].data();
    }
    b.cost->Evaluate(b.params.data(), r.data() + row, jac_ptr.data());
    for (size_t i = 0; i < sizes.size(); ++i)
      for (int rr = 0; rr < nr; ++rr)
        for (int c = 0; c < sizes[i]; ++c)
          J(row + rr, b.offsets[i] + c) = jac[i][static_cast<size_t>(rr * sizes[i] + c)];
    row += nr;
  }
}

/// Parameters that live (mostly) in the unobservable subspace: for each, the share of its
/// normalised unit vector inside the span of the null eigenvectors, listed if above 10 %.
std::string describe_null_space(const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd>& es,
                                int n_null, const std::vector<int>& active) {
  const Eigen::MatrixXd V = es.eigenvectors().leftCols(n_null);
  std::vector<std::pair<double, int>> share;
  for (int i = 0; i < V.rows(); ++i) share.push_back({V.row(i).squaredNorm(), i});
  std::sort(share.begin(), share.end(),
            [](const auto& a, const auto& b) { return a.first > b.first; });
  std::ostringstream os;
  int listed = 0;
  for (const auto& [w, i] : share) {
    if (w < 0.1) break;
    os << (listed++ ? ", " : "") << param_info(active[static_cast<size_t>(i)]).name;
  }
  return os.str();
}

}  // namespace

namespace {

/// The rest periods' means, checked: at least two, rotation matrices, and a rotation between
/// them (else nothing is observable).
std::vector<NlsqRestMean> checked_rest_means(const CalibrationInput& in, const NlsqOptions& opt) {
  const std::vector<RestPeriod> periods = find_rest_periods(in, opt.min_rest_samples);
  if (periods.size() < 2) {
    fail("found " + std::to_string(periods.size()) + " rest period(s) of at least " +
         std::to_string(opt.min_rest_samples) +
         " at_rest samples; NLSQ needs at least 2 (a rotation between two rests)");
  }
  const std::vector<NlsqRestMean> rests = nlsq_rest_means(in, periods);
  for (size_t i = 0; i < rests.size(); ++i) {
    const Eigen::Matrix3d& C = rests[i].C_bn_ref;
    if ((C.transpose() * C - Eigen::Matrix3d::Identity()).norm() > 1e-6)
      fail("reference[" + std::to_string(rests[i].mid) + "].C_bn_ref is not a rotation matrix");
  }
  double max_rotation = 0.0;
  for (size_t i = 0; i + 1 < rests.size(); ++i)
    max_rotation =
        std::max(max_rotation,
                 matrix_to_rotvec(rests[i].C_bn_ref.transpose() * rests[i + 1].C_bn_ref).norm());
  if (max_rotation < kMinRotation_rad)
    fail("no rotation between rest periods (the reference attitude changes by at most " +
         std::to_string(max_rotation * kRadToDeg) + " deg); nothing is observable");
  return rests;
}

/// Flat indices of the estimated parameters (the table misalignment only if asked for), checked
/// against the number of residuals the rests give.
std::vector<int> active_parameters(const std::vector<NlsqRestMean>& rests, const NlsqOptions& opt) {
  std::vector<int> active;
  for (int i = 0; i < ParamSet::kSize; ++i)
    if (i < 24 || opt.estimate_table_misalignment) active.push_back(i);
  const int n_active = static_cast<int>(active.size());
  // 3 residuals per rest (a_R); with the table heading 3 per rest (ψ_R) and 3 per rotation (ψ_i),
  // else 2 per rotation (d_i).
  const size_t n_rot = rests.size() - 1;
  const int n_residuals = static_cast<int>(opt.use_table_heading ? 6 * rests.size() + 3 * n_rot
                                                                 : 3 * rests.size() + 2 * n_rot);
  if (n_residuals <= n_active) {
    fail("only " + std::to_string(n_residuals) + " residuals for " + std::to_string(n_active) +
         " parameters (" + std::to_string(rests.size()) +
         " rest periods); the sequence needs more rests and rotations");
  }
  return active;
}

/// One linearisation's least-squares problem (paper eq. 41-45): the rests' specific-force
/// residuals, and the rotations' attitude residuals linearised at theta0.
struct NlsqProblem {
  const CalibrationInput& in;
  const std::vector<NlsqRestMean>& rests;
  const NlsqOptions& opt;
  Eigen::Vector3d w_ie_n, g_n;

  void build(const ParamVector& theta, Blocks& blk, ceres::Problem& problem,
             std::vector<BlockRef>& refs) const {
    const ParamSet theta0 = ParamSet::from_vector(theta);
    blk.set(theta);
    for (const NlsqRestMean& rest : rests) {
      auto* cost = new ceres::AutoDiffCostFunction<NlsqAccelRestResidual, 3, 3, 9, 3>(
          new NlsqAccelRestResidual{rest, w_ie_n, g_n});
      BlockRef ref{cost, {blk.b_a.data(), blk.M_a.data(), blk.sig.data()}, {0, 3, 24}};
      problem.AddResidualBlock(cost, nullptr, ref.params);
      refs.push_back(std::move(ref));
    }
    auto add_attitude = [&](size_t a, size_t b, NlsqSpan span) {
      const NlsqRotation rot = nlsq_linearise_rotation(in, rests, a, b, theta0, span);
      auto* cost = new ceres::AutoDiffCostFunction<NlsqAttitudeResidual, 3, 3, 9, 3>(
          new NlsqAttitudeResidual{rests[a], rests[b], rot});
      BlockRef ref{cost, {blk.b_g.data(), blk.M_g.data(), blk.sig.data()}, {12, 15, 24}};
      problem.AddResidualBlock(cost, nullptr, ref.params);
      refs.push_back(std::move(ref));
    };
    if (opt.use_table_heading) {
      // The spans tile the run from the first rest's start to the last rest's end: every gyro
      // increment is used once, and the rest noise no longer dilutes the rotations' residuals.
      for (size_t i = 0; i < rests.size(); ++i) {
        add_attitude(i, i, NlsqSpan::kWholeRest);
        if (i + 1 < rests.size()) add_attitude(i, i + 1, NlsqSpan::kRestEndToRestBegin);
      }
    } else {
      for (size_t i = 0; i + 1 < rests.size(); ++i) {
        const NlsqRotation rot = nlsq_linearise_rotation(in, rests, i, i + 1, theta0);
        auto* cost = new ceres::AutoDiffCostFunction<NlsqRotationResidual, 2, 3, 9, 3, 9, 3>(
            new NlsqRotationResidual{rests[i], rests[i + 1], rot, w_ie_n});
        BlockRef ref{
            cost,
            {blk.b_a.data(), blk.M_a.data(), blk.b_g.data(), blk.M_g.data(), blk.sig.data()},
            {0, 3, 12, 15, 24}};
        problem.AddResidualBlock(cost, nullptr, ref.params);
        refs.push_back(std::move(ref));
      }
    }
    if (!opt.estimate_table_misalignment) problem.SetParameterBlockConstant(blk.sig.data());
  }
};

void solve(ceres::Problem& problem, const NlsqOptions& opt) {
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::DENSE_QR;
  so.max_num_iterations = opt.ceres_max_iterations;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  so.minimizer_progress_to_stdout = false;
  so.function_tolerance = 1e-14;
  so.gradient_tolerance = 1e-30;
  so.parameter_tolerance = 1e-14;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  if (summary.termination_type == ceres::FAILURE) fail("Ceres failed: " + summary.message);
}

/// The whitened Jacobian at the solution: the covariance of the active parameters (refused when a
/// direction is not observable with this sequence), χ² and its degrees of freedom.
void covariance_at_solution(const std::vector<BlockRef>& refs, const std::vector<int>& active,
                            ParamCovariance& cov, double& chi2, int& dof) {
  const int n_active = static_cast<int>(active.size());
  Eigen::MatrixXd J_full;
  Eigen::VectorXd r;
  evaluate_all(refs, J_full, r);
  Eigen::MatrixXd J(J_full.rows(), n_active);
  for (int c = 0; c < n_active; ++c) J.col(c) = J_full.col(active[static_cast<size_t>(c)]);
  dof = static_cast<int>(J.rows()) - n_active;
  const Eigen::MatrixXd H = J.transpose() * J;
  const Eigen::VectorXd d = H.diagonal().cwiseMax(1e-300).cwiseSqrt().cwiseInverse();
  const Eigen::MatrixXd Hn = d.asDiagonal() * H * d.asDiagonal();
  Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Hn);
  if (es.info() != Eigen::Success) fail("eigen-decomposition of the information matrix failed");
  const double lmax = es.eigenvalues()(n_active - 1);
  int n_null = 0;
  while (n_null < n_active && !(es.eigenvalues()(n_null) > kMinRelativeEigenvalue * lmax)) ++n_null;
  if (n_null > 0) {
    std::ostringstream os;
    os << "parameters not observable with this sequence: " << n_null
       << " direction(s) with normalised information eigenvalue below " << kMinRelativeEigenvalue
       << " (smallest " << es.eigenvalues()(0) / lmax
       << "); parameters involved: " << describe_null_space(es, n_null, active);
    fail(os.str());
  }
  const Eigen::MatrixXd Hn_inv = es.eigenvectors() * es.eigenvalues().cwiseInverse().asDiagonal() *
                                 es.eigenvectors().transpose();
  const Eigen::MatrixXd cov_active = d.asDiagonal() * Hn_inv * d.asDiagonal();
  cov.setZero();
  for (int i = 0; i < n_active; ++i)
    for (int j = 0; j < n_active; ++j)
      cov(active[static_cast<size_t>(i)], active[static_cast<size_t>(j)]) = cov_active(i, j);
  chi2 = r.squaredNorm();
}

/// A-posteriori variance factor: the weights come from the noise model; if the residuals are
/// clearly larger than it predicts, σ would lie, so scale the covariance (and say so).
void apply_variance_factor(double chi2, int dof, ParamCovariance& cov, CalibrationResult& res) {
  const double variance_factor = chi2 / static_cast<double>(dof);
  if (variance_factor <= 2.0) return;
  std::ostringstream os;
  os << "a-posteriori variance factor chi2/dof = " << variance_factor << " (chi2 " << chi2
     << ", dof " << dof << ") exceeds 2: residuals larger than the noise model predicts; "
     << "sigma scaled by sqrt(" << variance_factor << ")";
  res.warnings.push_back(os.str());
  cov *= variance_factor;
}

}  // namespace

CalibrationResult calibrate_nlsq(const CalibrationInput& in, const NlsqOptions& opt) {
  const auto wall0 = std::chrono::steady_clock::now();
  validate(in, opt);
  const std::vector<NlsqRestMean> rests = checked_rest_means(in, opt);
  const std::vector<int> active = active_parameters(rests, opt);
  const EarthModel earth(in.site);
  const NlsqProblem lsq{in, rests, opt, earth.w_ie_n(), earth.g_n()};

  CalibrationResult res;
  res.method = "nlsq";
  if (in.noise.gyro_bias_instability_radps > 0.0 || in.noise.accel_bias_instability_mps2 > 0.0)
    res.warnings.push_back(
        "bias instability (Gauss-Markov) is not part of the NLSQ residual weights; sigma covers "
        "white noise and quantisation only");

  ParamVector theta = opt.start ? opt.start->to_vector() : ParamVector::Zero();
  ParamCovariance cov = ParamCovariance::Zero();
  double chi2 = 0.0;
  int dof = 0;
  bool converged = false;
  int outer = 0;
  // Outer loop: linearise every rotation's gyro propagation at θ0, solve the (otherwise exactly
  // nonlinear) problem with Ceres, re-linearise at the solution until the step is ≪ σ.
  for (outer = 1; outer <= opt.max_outer_iterations; ++outer) {
    Blocks blk;
    ceres::Problem problem;
    std::vector<BlockRef> refs;
    lsq.build(theta, blk, problem, refs);
    solve(problem, opt);
    covariance_at_solution(refs, active, cov, chi2, dof);
    const ParamVector theta_new = blk.get();
    const ParamVector step = theta_new - theta;
    theta = theta_new;
    converged = true;
    for (int i : active)
      if (!(std::abs(step(i)) < opt.convergence_sigma_ratio * std::sqrt(cov(i, i))))
        converged = false;
    if (converged) break;
  }
  res.iterations = std::min(outer, opt.max_outer_iterations);
  if (!converged)
    res.warnings.push_back("not converged after " + std::to_string(opt.max_outer_iterations) +
                           " re-linearisations (parameter steps not below " +
                           std::to_string(opt.convergence_sigma_ratio) + " sigma)");
  apply_variance_factor(chi2, dof, cov, res);
  res.params = ParamSet::from_vector(theta);
  res.cov = cov;
  res.sigma = sigma_from_covariance(cov);
  res.converged = converged;
  res.runtime_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  return res;
}

}  // namespace imucal::calib::nlsq
