#include "calib/legacy/legacy.hpp"

#include <Eigen/Cholesky>
#include <Eigen/LU>
#include <Eigen/SVD>
#include <chrono>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

#include "calib/core/body_frame.hpp"
#include "calib/core/conventions.hpp"
#include "calib/core/earth.hpp"
#include "calib/core/readable_number.hpp"
#include "calib/core/rotation.hpp"

namespace imucal::calib::legacy {
using namespace calib::core;

namespace {

using Eigen::Matrix3d;
using Eigen::MatrixXd;
using Eigen::Vector3d;
using Eigen::VectorXd;

[[noreturn]] void fail(const std::string& what) {
  throw std::invalid_argument("legacy calibration: " + what);
}

/// One usable rest: its sample range and raw means.
struct Rest {
  size_t begin = 0, end = 0, mid = 0;
  Vector3d f_mean = Vector3d::Zero();  ///< raw specific force, m/s²
  Vector3d w_mean = Vector3d::Zero();  ///< raw angular rate, rad/s
  double T_s = 0.0;                    ///< time averaged, s
};

std::vector<Rest> usable_rests(const CalibrationInput& in, const LegacyOptions& opt) {
  if (in.reference.size() != in.imu.size())
    fail("imu and reference have different lengths (" + std::to_string(in.imu.size()) + " vs " +
         std::to_string(in.reference.size()) + ")");
  for (size_t k = 0; k < in.imu.size(); ++k) {
    const ImuIncrement& s = in.imu[k];
    if (!(std::isfinite(s.dt_s) && s.dt_s > 0.0) || !s.dtheta_rad.allFinite() ||
        !s.dv_mps.allFinite())
      fail("imu[" + std::to_string(k) + "] has a non-finite increment or a non-positive dt_s");
  }
  std::vector<Rest> out;
  for (const TrimmedRest& tr : trimmed_rests(in, opt.min_rest_samples, opt.trim_s)) {
    Rest r;
    r.begin = tr.begin;
    r.end = tr.end;
    double T = 0.0;
    for (size_t k = r.begin; k < r.end; ++k) {
      r.f_mean += in.imu[k].dv_mps;
      r.w_mean += in.imu[k].dtheta_rad;
      T += in.imu[k].dt_s;
    }
    r.f_mean /= T;
    r.w_mean /= T;
    r.T_s = T;
    r.mid = tr.mid;
    out.push_back(r);
  }
  return out;
}

/// Gauss–Newton with Levenberg damping on a small dense problem; returns JᵀJ at the solution
/// and the residual sum of squares.
struct LsqOutcome {
  MatrixXd JtJ;
  double rss = 0.0;
  int m = 0;  ///< residual count
  bool converged = false;
};

/// A noise-weighted model's fit is stationary when the Gauss–Newton step still predicted would
/// move its parameters by less than a thousandth of their own σ: with residuals in units of their
/// noise the predicted decrease gᵀ(JᵀJ)⁻¹g is the step's squared Mahalanobis length. The joint
/// model's Jacobian w.r.t. M_g is a small-angle approximation, so its fit can stop a few 10⁻⁴ σ
/// from the point where that Jacobian's gradient vanishes with no step reducing the true residual
/// (a clang-simulated land run: predicted decrease 1.4·10⁻⁷, every damped step uphill, "did not
/// converge" after 12 rounds;
/// FieldCli.LegacyConvergesOnALandRunThatStoppedWithinItsNoiseOfTheMinimum).
constexpr double kStationaryChi2 = 1e-6;

/// A model whose residuals are in units of their noise says so (`kNoiseWeighted`): the stationary
/// test above applies to it; to the others only the relative tests do.
template <typename Model>
LsqOutcome gauss_newton(Model& model, VectorXd& x, int max_iter = 50) {
  LsqOutcome o;
  double lambda = 1e-9;
  VectorXd r;
  MatrixXd J;
  model.evaluate(x, r, J);
  double rss = r.squaredNorm();
  for (int it = 0; it < max_iter; ++it) {
    const MatrixXd JtJ = J.transpose() * J;
    const VectorXd g = J.transpose() * r;
    MatrixXd A = JtJ;
    A.diagonal() += lambda * JtJ.diagonal().cwiseMax(1e-300);
    const VectorXd dx = -A.ldlt().solve(g);
    // At a stationary point the undamped step predicts no decrease worth having: converged,
    // even when rounding makes the (tiny) step look uphill and it would be rejected below.
    const VectorXd dx_gn = -JtJ.ldlt().solve(g);
    const double stationary = std::max(1e-10 * rss, Model::kNoiseWeighted ? kStationaryChi2 : 0.0);
    if (dx_gn.allFinite() && -g.dot(dx_gn) <= stationary) {
      o.converged = true;
      break;
    }
    VectorXd x_new = x + dx;
    VectorXd r_new;
    MatrixXd J_new;
    model.evaluate(x_new, r_new, J_new);
    const double rss_new = r_new.squaredNorm();
    if (std::isfinite(rss_new) && rss_new <= rss) {
      const bool small = rss - rss_new <= 1e-12 * rss || dx.norm() <= 1e-14 * (1.0 + x.norm());
      x = x_new;
      r = r_new;
      J = J_new;
      rss = rss_new;
      lambda = std::max(lambda * 0.1, 1e-12);
      if (small) {
        o.converged = true;
        break;
      }
    } else {
      lambda *= 10.0;
      if (lambda > 1e8) {
        o.converged = rss < 1e-20;  // nothing left to reduce
        break;
      }
    }
  }
  o.JtJ = J.transpose() * J;
  o.rss = rss;
  o.m = static_cast<int>(r.size());
  return o;
}

/// The accelerometer unknowns x = (b, t): bias and the six entries of the lower-triangular T
/// (f = T (f~ - b)), entry k at (kRow[k], kCol[k]).
namespace tri {
constexpr int kRow[6] = {0, 1, 1, 2, 2, 2}, kCol[6] = {0, 0, 1, 0, 1, 2};

Matrix3d T_of(const VectorXd& x) {
  Matrix3d T = Matrix3d::Zero();
  for (int k = 0; k < 6; ++k) T(kRow[k], kCol[k]) = x(3 + k);
  return T;
}

/// |T (f - b)| - g of one rest and its gradient w.r.t. (b, t), both divided by `scale`.
void magnitude_row(const Vector3d& f_mean, const VectorXd& x, const Matrix3d& T, double g,
                   double scale, double& r,
                   Eigen::Ref<Eigen::RowVectorXd, 0, Eigen::InnerStride<>> J) {
  const Vector3d u = f_mean - x.head<3>();
  const Vector3d y = T * u;
  const double rho = y.norm();
  r = (rho - g) / scale;
  J.head<3>() = -(y / rho).transpose() * T / scale;
  for (int k = 0; k < 6; ++k) J(3 + k) = y(kRow[k]) / rho * u(kCol[k]) / scale;
}

/// ∂(b_a, vec(M_a)) / ∂(b, t) with M_a = T⁻¹ - I (12 x 9; ∂M/∂t = -T⁻¹ E T⁻¹).
Eigen::Matrix<double, 12, 9> to_params_jacobian(const Matrix3d& T) {
  const Matrix3d Ti = T.inverse();
  Eigen::Matrix<double, 12, 9> G = Eigen::Matrix<double, 12, 9>::Zero();
  G.block<3, 3>(0, 0).setIdentity();
  for (int k = 0; k < 6; ++k) {
    Matrix3d E = Matrix3d::Zero();
    E(kRow[k], kCol[k]) = 1.0;
    const Matrix3d dM = -Ti * E * Ti;
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) G(3 + 3 * a + b, 3 + k) = dM(a, b);
  }
  return G;
}
}  // namespace tri

/// Step 2 alone (starting values): bias and triangular T with |T (f_p - b)| = g in every rest.
struct AccelModel {
  static constexpr bool kNoiseWeighted = false;  ///< start values only, in m/s²
  const std::vector<Rest>& rests;
  double g;
  void evaluate(const VectorXd& x, VectorXd& r, MatrixXd& J) const {
    const Matrix3d T = tri::T_of(x);
    r.resize(static_cast<Eigen::Index>(rests.size()));
    J.setZero(static_cast<Eigen::Index>(rests.size()), 9);
    for (size_t p = 0; p < rests.size(); ++p) {
      const auto i = static_cast<Eigen::Index>(p);
      tri::magnitude_row(rests[p].f_mean, x, T, g, 1.0, r(i), J.row(i));
    }
  }
};

/// The residuals' noise, from the unit's white noise and each rest's own length (a hand-placed
/// MEMS run's rests last 3–11 s, a table's a minute or more: weighting them alike made the σ of
/// the one 2× too small and of the other several times too large, issue #21).
struct NoiseWeights {
  std::vector<double> sigma_f;  ///< mean specific force of rest p, per axis, m/s²
  std::vector<double> sigma_w;  ///< mean rate of rest p, per axis, rad/s
  std::vector<double> sigma_d;  ///< down direction carried over move p → p+1, per axis, rad

  NoiseWeights(const CalibrationInput& in, const std::vector<Rest>& rests, double g) {
    const double vrw = in.noise.vrw_mps_per_sqrt_s, arw = in.noise.arw_rad_per_sqrt_s;
    for (const Rest& r : rests) {
      sigma_f.push_back(std::max(vrw / std::sqrt(r.T_s), 1e-7 * g));
      sigma_w.push_back(std::max(arw / std::sqrt(r.T_s), 1e-12));
    }
    // Each rest's down direction is known to σ_f/g across it; the gyros integrate from the
    // middle of one rest to the middle of the next, collecting ARW·√Δt.
    for (size_t p = 0; p + 1 < rests.size(); ++p) {
      const double dt_s = in.imu[rests[p + 1].mid].t_s - in.imu[rests[p].mid].t_s;
      const double dir2 = (sigma_f[p] * sigma_f[p] + sigma_f[p + 1] * sigma_f[p + 1]) / (g * g);
      sigma_d.push_back(std::max(std::sqrt(dir2 + arw * arw * dt_s), 1e-8));
    }
  }

  /// Helmert's variance components, never below the noise model: a real unit's moves scatter
  /// more than its white noise says (hand tremor at the ends of a rest, g-sensitivity), and
  /// weighted by the noise alone they would pull the magnitudes off (issue #21's real recording:
  /// gravity residual 0.19 mg, with the moves scaled to their scatter 0.12). Each class of
  /// residual (magnitudes, moves) is scaled up by its own RMS when that exceeds 1.05 — never down:
  /// scaled down to a sample's luck, the σ of the simulated runs came out 20–75 % too small.
  /// Returns whether either scale moved.
  bool rescale_to(const VectorXd& r_weighted) {
    const auto n = static_cast<Eigen::Index>(sigma_f.size());
    const double k_f = std::sqrt(r_weighted.head(n).squaredNorm() / static_cast<double>(n));
    const double k_d = std::sqrt(r_weighted.tail(r_weighted.size() - n).squaredNorm() /
                                 static_cast<double>(r_weighted.size() - n));
    bool moved = false;
    if (k_f > 1.05) {
      for (double& s : sigma_f) s *= k_f;
      moved = true;
    }
    if (k_d > 1.05) {
      for (double& s : sigma_d) s *= k_d;
      moved = true;
    }
    return moved;
  }
};

/// Step 3: gyro bias and the heading of every rest (Earth rate's horizontal direction).
struct GyroBiasModel {
  static constexpr bool kNoiseWeighted = true;
  const std::vector<Rest>& rests;
  const std::vector<Vector3d>& down;   ///< compensated down direction per rest (body)
  const std::vector<double>& sigma_w;  ///< noise of each rest's mean rate, rad/s
  Matrix3d Ag_inv;
  double Om_s, Om_c;                                 ///< Ω sin φ, Ω cos φ
  std::vector<std::pair<Vector3d, Vector3d>> basis;  ///< (e1, e2) ⊥ down per rest

  GyroBiasModel(const std::vector<Rest>& r, const std::vector<Vector3d>& d,
                const std::vector<double>& sw, const Matrix3d& Ag, double lat)
      : rests(r),
        down(d),
        sigma_w(sw),
        Ag_inv(Ag.inverse()),
        Om_s(wgs84::kEarthRate_radps * std::sin(lat)),
        Om_c(wgs84::kEarthRate_radps * std::cos(lat)) {
    for (const Vector3d& dn : d) {
      const Vector3d a = std::abs(dn(0)) < 0.9 ? Vector3d::UnitX() : Vector3d::UnitY();
      const Vector3d e1 = (a - a.dot(dn) * dn).normalized();
      basis.emplace_back(e1, dn.cross(e1));
    }
  }
  /// Earth rate in body at rest p for heading angle α (ω_ie,n = (Ωc, 0, -Ωs) NED).
  Vector3d earth_rate(size_t p, double a) const {
    return -Om_s * down[p] + Om_c * (std::cos(a) * basis[p].first + std::sin(a) * basis[p].second);
  }
  void evaluate(const VectorXd& x, VectorXd& r, MatrixXd& J) const {
    const size_t n = rests.size();
    const Vector3d b = x.head<3>();
    r.resize(static_cast<Eigen::Index>(3 * n));
    J.setZero(static_cast<Eigen::Index>(3 * n), static_cast<Eigen::Index>(3 + n));
    for (size_t p = 0; p < n; ++p) {
      const double a = x(static_cast<Eigen::Index>(3 + p));
      const auto i = static_cast<Eigen::Index>(3 * p);
      r.segment<3>(i) = (Ag_inv * (rests[p].w_mean - b) - earth_rate(p, a)) / sigma_w[p];
      J.block<3, 3>(i, 0) = -Ag_inv / sigma_w[p];
      J.block<3, 1>(i, static_cast<Eigen::Index>(3 + p)) =
          -Om_c * (-std::sin(a) * basis[p].first + std::cos(a) * basis[p].second) / sigma_w[p];
    }
  }
};

/// Steps 2 and 4 jointly: accelerometer bias and triangular T (9) and gyro M_g (9) such that the
/// compensated specific force has the magnitude g at every rest and the gyros, integrated over
/// every move, turn the gravity direction of the rest before it into that of the rest after it
/// (Earth rotation during the move included). With the table's 90°/180° positions the magnitudes
/// alone leave the accelerometer non-orthogonality unobserved (it enters squared); the moves tie
/// the triad's axes to the gyros' angles. Residuals are weighted by their noise (σ_f, σ_d).
struct JointModel {
  static constexpr bool kNoiseWeighted = true;
  const CalibrationInput& in;
  const std::vector<Rest>& rests;
  const std::vector<size_t>& moves;           ///< p of every usable move p → p+1 (usable_moves)
  const std::vector<Vector3d>& earth_rate_b;  ///< per rest, body frame
  Vector3d b_g;
  double g;
  const NoiseWeights& w;

  /// Down direction of rest p and its Jacobian w.r.t. (b, t) (3 x 9).
  void down(const VectorXd& x, size_t p, Vector3d& d, Eigen::Matrix<double, 3, 9>& Jd) const {
    const Matrix3d T = tri::T_of(x);
    const Vector3d u = rests[p].f_mean - x.head<3>();
    const Vector3d y = T * u;
    const double rho = y.norm();
    d = -y / rho;
    const Matrix3d dd_dy = -(Matrix3d::Identity() - (y / rho) * (y / rho).transpose()) / rho;
    Jd.leftCols<3>() = -dd_dy * T;
    for (int k = 0; k < 6; ++k) Jd.col(3 + k) = dd_dy.col(tri::kRow[k]) * u(tri::kCol[k]);
  }

  void evaluate(const VectorXd& x, VectorXd& r, MatrixXd& J) const {
    const size_t n = rests.size();
    const auto rows = static_cast<Eigen::Index>(n + 3 * moves.size());
    r.resize(rows);
    J.setZero(rows, 18);
    const Matrix3d T = tri::T_of(x);
    for (size_t p = 0; p < n; ++p) {  // magnitudes
      const auto i = static_cast<Eigen::Index>(p);
      tri::magnitude_row(rests[p].f_mean, x, T, g, w.sigma_f[p], r(i), J.row(i).head(9));
    }
    Matrix3d M;
    M << x(9), x(10), x(11), x(12), x(13), x(14), x(15), x(16), x(17);
    const Matrix3d A_inv = (Matrix3d::Identity() + M).inverse();
    std::vector<Vector3d> d(n);
    std::vector<Eigen::Matrix<double, 3, 9>> Jd(n);
    for (size_t p = 0; p < n; ++p) down(x, p, d[p], Jd[p]);
    for (size_t m = 0; m < moves.size(); ++m) {
      const size_t p = moves[m];
      // C = C_{I0←b1} = Π exp([θ_k x]) from the middle of rest p to the middle of rest p+1;
      // W_j = Σ_k θ_k(j) P_k with P_k the product up to and including sample k.
      Matrix3d C = Matrix3d::Identity();
      Matrix3d W[3] = {Matrix3d::Zero(), Matrix3d::Zero(), Matrix3d::Zero()};
      const size_t k0 = rests[p].mid, k1 = rests[p + 1].mid;
      for (size_t k = k0 + 1; k <= k1; ++k) {
        const ImuIncrement& s = in.imu[k];
        const Vector3d th = A_inv * (s.dtheta_rad - b_g * s.dt_s);
        C = C * rotvec_to_matrix<double>(th);
        for (int j = 0; j < 3; ++j) W[j] += th(j) * C;
      }
      const double dt = in.imu[k1].t_s - in.imu[k0].t_s;
      const Matrix3d R = C.transpose() * rotvec_to_matrix<double>(Vector3d(earth_rate_b[p] * dt));
      const Vector3d d_pred = R * d[p];
      const auto i = static_cast<Eigen::Index>(n + 3 * m);
      const double sigma_d = w.sigma_d[p];
      r.segment<3>(i) = (d[p + 1] - d_pred) / sigma_d;
      J.block<3, 9>(i, 0) = (Jd[p + 1] - R * Jd[p]) / sigma_d;
      // δφ = -Cᵀ W_j A⁻¹ e_a per δM_aj (right perturbation of C); ∂r/∂m = -[d_pred x] δφ.
      const Matrix3d Sd = skew<double>(d_pred);
      for (int a = 0; a < 3; ++a)
        for (int j = 0; j < 3; ++j)
          J.block<3, 1>(i, 9 + 3 * a + j) = Sd * (C.transpose() * W[j] * A_inv.col(a)) / sigma_d;
    }
  }
};

ParamCovariance assemble_covariance(const Matrix3d& T, const MatrixXd& cov_accel,
                                    const Matrix3d& cov_bg, const MatrixXd& cov_Mg) {
  ParamCovariance C = ParamCovariance::Zero();
  const Eigen::Matrix<double, 12, 9> G = tri::to_params_jacobian(T);
  C.block<12, 12>(0, 0) = G * cov_accel * G.transpose();
  C.block<3, 3>(12, 12) = cov_bg;
  C.block<9, 9>(15, 15) = cov_Mg;
  return C;
}

/// σ²(JᵀJ)⁻¹ with σ² the residual variance (at least `floor`), by pseudo-inverse if singular.
MatrixXd scaled_covariance(const LsqOutcome& o, double floor_var) {
  const int n = static_cast<int>(o.JtJ.rows());
  const double dof = std::max(1, o.m - n);
  const double s2 = std::max(o.rss / dof, floor_var);
  return s2 * o.JtJ.completeOrthogonalDecomposition().pseudoInverse();
}

}  // namespace

namespace {

/// The moves p → p+1 whose gyro data can be trusted: none with a clipped or dropped sample between
/// the two rests' middles (CalibrationInput::unusable). Each one left out is said in `notes`,
/// numbered as a person counts the rests ("move 6, between rests 6 and 7").
std::vector<size_t> usable_moves(const CalibrationInput& in, const std::vector<Rest>& rests,
                                 std::vector<std::string>& notes) {
  std::vector<size_t> moves;
  for (size_t p = 0; p + 1 < rests.size(); ++p) {
    const auto spans = spans_within(in.unusable, rests[p].mid, rests[p + 1].mid + 1);
    if (spans.empty()) {
      moves.push_back(p);
      continue;
    }
    notes.push_back("move " + std::to_string(p + 1) + " (between rests " + std::to_string(p + 1) +
                    " and " + std::to_string(p + 2) + ", " +
                    instant_text(in.imu[rests[p].end].t_s) + " to " +
                    instant_text(in.imu[rests[p + 1].begin].t_s) +
                    ") left out of the gyro fit: " + reasons_text(spans));
  }
  return moves;
}

/// What was left out, for a refusal: " (2 moves left out: ...)" or "".
std::string left_out_clause(const std::vector<std::string>& notes) {
  if (notes.empty()) return "";
  std::string s = "; " + std::to_string(notes.size()) + (notes.size() == 1 ? " move" : " moves") +
                  " left out for clipped or dropped samples:";
  for (const std::string& n : notes) s += " " + n + ";";
  s.pop_back();
  return s;
}

void check_input(const std::vector<Rest>& rests, const std::vector<size_t>& moves,
                 const std::vector<std::string>& notes) {
  if (rests.size() < 9)
    fail("only " + std::to_string(rests.size()) +
         " usable rest positions; the multi-position test needs at least 9 (9 accelerometer "
         "unknowns)" +
         left_out_clause(notes));
  // Each move fixes two angles of the gyros' 9 scale and misalignment terms.
  if (moves.size() < 5)
    fail("only " + std::to_string(moves.size()) + " usable moves of " +
         std::to_string(rests.size() - 1) +
         "; the gyros' scale and misalignment (9 unknowns, 2 per move) need at least 5" +
         left_out_clause(notes));
  // Raw gravity directions must span three dimensions: every axis must see gravity.
  MatrixXd D(static_cast<Eigen::Index>(rests.size()), 3);
  for (size_t p = 0; p < rests.size(); ++p)
    D.row(static_cast<Eigen::Index>(p)) = rests[p].f_mean.normalized().transpose();
  const double spread = Eigen::JacobiSVD<MatrixXd>(D).singularValues()(2) /
                        std::sqrt(static_cast<double>(rests.size()));
  if (spread < 0.2)
    fail(
        "the rest positions do not span three dimensions (smallest singular value of the "
        "gravity directions " +
        std::to_string(spread) + " < 0.2): some axis never sees gravity");
}

/// Step 2 alone, from scratch (T = I, b = 0): starting values for the joint fit (its
/// non-orthogonality is unobserved with axis-aligned positions; the joint fit resolves it).
VectorXd accelerometer_start(const std::vector<Rest>& rests, double g) {
  VectorXd xa = VectorXd::Zero(9);
  xa(3) = xa(5) = xa(8) = 1.0;
  AccelModel am{rests, g};
  gauss_newton(am, xa);
  if (!xa.allFinite() || !(tri::T_of(xa).determinant() > 0.1))
    fail("the accelerometer fit failed (is the unit at rest in the flagged periods?)");
  return xa;
}

struct LegacyFit {
  VectorXd x;  ///< (b_a, t, vec M_g): 18
  Vector3d bg = Vector3d::Zero();
  LsqOutcome bias, joint;
  int rounds = 0;
};

/// Steps 3 and 2+4, alternated: the bias needs M_g, M_g the bias and the Earth rate. Three rounds
/// settle a unit near nominal; one far from it (a MEMS gyro 24 % off scale, issue #21) goes on
/// until both fits converge, up to kMaxRounds.
constexpr int kMinRounds = 3, kMaxRounds = 12;
LegacyFit fit_alternating(const CalibrationInput& in, const std::vector<Rest>& rests,
                          const std::vector<size_t>& moves, double g, const VectorXd& xa) {
  NoiseWeights w(in, rests, g);
  LegacyFit f;
  f.x = VectorXd::Zero(18);
  f.x.head<9>() = xa;
  Matrix3d Mg = Matrix3d::Zero();
  std::vector<Vector3d> down(rests.size()), earth_b(rests.size());
  for (int round = 0; round < kMaxRounds; ++round) {
    const Matrix3d T = tri::T_of(f.x);
    for (size_t p = 0; p < rests.size(); ++p)
      down[p] = -(T * (rests[p].f_mean - f.x.head<3>())).normalized();
    GyroBiasModel bm(rests, down, w.sigma_w, Matrix3d::Identity() + Mg, in.site.lat_rad);
    VectorXd xb = VectorXd::Zero(static_cast<Eigen::Index>(3 + rests.size()));
    xb.head<3>() = f.bg;
    for (size_t p = 0; p < rests.size(); ++p) {
      const Vector3d w = bm.Ag_inv * (rests[p].w_mean - f.bg);
      xb(static_cast<Eigen::Index>(3 + p)) =
          std::atan2(w.dot(bm.basis[p].second), w.dot(bm.basis[p].first));
    }
    f.bias = gauss_newton(bm, xb);
    f.bg = xb.head<3>();
    for (size_t p = 0; p < rests.size(); ++p)
      earth_b[p] = bm.earth_rate(p, xb(static_cast<Eigen::Index>(3 + p)));
    JointModel jm{in, rests, moves, earth_b, f.bg, g, w};
    f.joint = gauss_newton(jm, f.x, 30);
    Mg = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(f.x.data() + 9);
    f.rounds = round + 1;
    VectorXd r;
    MatrixXd J;
    jm.evaluate(f.x, r, J);
    const bool reweighted = w.rescale_to(r);
    if (f.rounds >= kMinRounds && f.bias.converged && f.joint.converged && !reweighted) break;
  }
  if (!f.x.allFinite() || !f.bg.allFinite() || !(tri::T_of(f.x).determinant() > 0.1) ||
      !(std::abs((Matrix3d::Identity() + Mg).determinant()) > 0.1))
    fail("the fit did not converge");
  return f;
}

/// Parameters, covariance (weighted residuals: (JᵀJ)⁻¹, inflated by the reduced χ² when the fit
/// is worse than the noise), and what the method cannot know — in the triangular frame.
CalibrationResult legacy_result(const CalibrationInput& in, const LegacyFit& f) {
  const Matrix3d T = tri::T_of(f.x);
  CalibrationResult res;
  res.method = "legacy";
  res.setting = in.setting;
  res.params.accel_bias_mps2 = f.x.head<3>();
  res.params.accel_M = T.inverse() - Matrix3d::Identity();
  res.params.gyro_bias_radps = f.bg;
  res.params.gyro_M =
      Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(f.x.data() + 9);
  const MatrixXd cov_j = scaled_covariance(f.joint, 1.0);
  const MatrixXd cov_b = scaled_covariance(f.bias, 1.0);
  res.cov = assemble_covariance(T, cov_j.topLeftCorner(9, 9), cov_b.topLeftCorner<3, 3>(),
                                cov_j.bottomRightCorner(9, 9));
  // The accel-gyro cross-covariance of the joint fit.
  const Eigen::Matrix<double, 12, 9> X = tri::to_params_jacobian(T) * cov_j.topRightCorner(9, 9);
  res.cov.block<12, 9>(0, 15) = X;
  res.cov.block<9, 12>(15, 0) = X.transpose();
  res.sigma = sigma_from_covariance(res.cov);
  res.converged = f.bias.converged && f.joint.converged;
  res.iterations = f.rounds;
  for (int i = 24; i < ParamSet::kSize; ++i) res.observable[static_cast<size_t>(i)] = false;
  res.unobservable_notes.push_back(
      "housing orientation: not determined (legacy method: orthogonal body frame only; "
      "misalignments relative to the accelerometer triad's own frame)");
  res.unobservable_notes.push_back("table misalignment: not estimated by the legacy method");
  res.warnings.push_back(
      "legacy σ from the noise-weighted fits (gyro bias separate: its cross-covariance with the "
      "other terms is neglected)");
  res.body_frame = BodyFrame::kHousing;  // "not accel-symmetric": transformed by the caller
  return res;
}

}  // namespace

CalibrationResult calibrate_legacy(const CalibrationInput& in, const LegacyOptions& opt) {
  const auto t_start = std::chrono::steady_clock::now();
  if (in.setting == Setting::kSea)
    fail(
        "the multi-position method needs a still platform; a sea run's deck rocks and drifts "
        "(calibrate it with AINS, which uses the GNSS fixes)");
  if (opt.min_rest_samples < 4) fail("option min_rest_samples must be >= 4");
  if (!(std::isfinite(opt.trim_s) && opt.trim_s >= 0.0)) fail("option trim_s must be >= 0");
  const std::vector<Rest> rests = usable_rests(in, opt);
  std::vector<std::string> left_out;
  const std::vector<size_t> moves = usable_moves(in, rests, left_out);
  check_input(rests, moves, left_out);
  const double g = EarthModel(in.site).gravity_mps2();
  const LegacyFit fit = fit_alternating(in, rests, moves, g, accelerometer_start(rests, g));
  // From the accelerometer triad's triangular frame into the accel-symmetric one.
  CalibrationResult out = in_accel_symmetric_frame(legacy_result(in, fit));
  out.warnings.insert(out.warnings.end(), left_out.begin(), left_out.end());
  out.runtime_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_start).count();
  return out;
}

}  // namespace imucal::calib::legacy
