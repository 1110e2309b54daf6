#include "calib/diagnosis/gap_fit.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/QR>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <stdexcept>

namespace imucal::calib::diagnosis {

namespace {

Eigen::MatrixXd take_rows(const Eigen::MatrixXd& M, const std::vector<int>& rows) {
  Eigen::MatrixXd out(static_cast<Eigen::Index>(rows.size()), M.cols());
  for (size_t i = 0; i < rows.size(); ++i) out.row(static_cast<Eigen::Index>(i)) = M.row(rows[i]);
  return out;
}

Eigen::VectorXd take_rows(const Eigen::VectorXd& v, const std::vector<int>& rows) {
  Eigen::VectorXd out(static_cast<Eigen::Index>(rows.size()));
  for (size_t i = 0; i < rows.size(); ++i) out(static_cast<Eigen::Index>(i)) = v(rows[i]);
  return out;
}

/// The rows 0..m-1 not in `held` (the training rows of a fold).
std::vector<int> complement(const std::vector<int>& held, int m) {
  std::vector<char> out(static_cast<size_t>(m), 0);
  for (int i : held) out[static_cast<size_t>(i)] = 1;
  std::vector<int> train;
  for (int i = 0; i < m; ++i)
    if (!out[static_cast<size_t>(i)]) train.push_back(i);
  return train;
}

/// Orthonormal basis of the part of A that the columns of B do not explain.
Eigen::MatrixXd residual_basis(const Eigen::MatrixXd& B, const Eigen::MatrixXd& A) {
  Eigen::MatrixXd R = A;
  if (B.cols() > 0) {
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(B);
    const Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(B.rows(), B.cols());
    R -= Q * (Q.transpose() * A);
  }
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(R, Eigen::ComputeThinU);
  const double smax = svd.singularValues().size() ? svd.singularValues()(0) : 0.0;
  int k = 0;
  while (k < svd.singularValues().size() && svd.singularValues()(k) > 1e-9 * std::max(smax, 1e-300))
    ++k;
  return svd.matrixU().leftCols(k);
}

}  // namespace

GlsFit gls_fit(const Eigen::VectorXd& r0_all, const Eigen::MatrixXd& J_all,
               const std::vector<int>& rows) {
  const Eigen::VectorXd r0 = rows.empty() ? r0_all : take_rows(r0_all, rows);
  const Eigen::MatrixXd J = rows.empty() ? J_all : take_rows(J_all, rows);
  GlsFit f;
  const int n = static_cast<int>(J.cols());
  f.dof = static_cast<int>(J.rows()) - n;
  if (n == 0) {
    f.x.resize(0);
    f.cov.resize(0, 0);
    f.chi2 = r0.squaredNorm();
    return f;
  }
  const Eigen::VectorXd d = J.colwise().norm().transpose().cwiseMax(1e-300).cwiseInverse();
  const Eigen::MatrixXd Js = J * d.asDiagonal();
  const Eigen::MatrixXd H = Js.transpose() * Js;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(H);
  if (es.info() != Eigen::Success || !(es.eigenvalues()(0) > 1e-13 * es.eigenvalues()(n - 1)))
    throw std::invalid_argument("gap fit: parameters not separable on these rows (rank deficient)");
  const Eigen::MatrixXd Hinv = es.eigenvectors() * es.eigenvalues().cwiseInverse().asDiagonal() *
                               es.eigenvectors().transpose();
  const Eigen::VectorXd xs = -Hinv * (Js.transpose() * r0);
  f.x = d.asDiagonal() * xs;
  f.cov = d.asDiagonal() * Hinv * d.asDiagonal();
  f.chi2 = (r0 + J * f.x).squaredNorm();
  return f;
}

HeldOutGap held_out_gap(const Eigen::VectorXd& r0, const Eigen::MatrixXd& J,
                        const std::vector<std::vector<int>>& folds) {
  HeldOutGap g;
  const int m = static_cast<int>(r0.size());
  for (const auto& held : folds) {
    const std::vector<int> train = complement(held, m);
    const GlsFit fit = gls_fit(r0, J, train);
    const Eigen::MatrixXd Jh = take_rows(J, held);
    const Eigen::VectorXd rh = take_rows(r0, held) + Jh * fit.x;
    g.chi2 += rh.squaredNorm();
    g.expected += static_cast<double>(held.size()) + (Jh * fit.cov * Jh.transpose()).trace();
  }
  return g;
}

HeldOutGap held_out_gap_correlated(const Eigen::VectorXd& r0, const Eigen::MatrixXd& J,
                                   const Eigen::MatrixXd& S,
                                   const std::vector<std::vector<int>>& folds) {
  HeldOutGap g;
  const int m = static_cast<int>(r0.size());
  for (const auto& held : folds) {
    const std::vector<int> train = complement(held, m);
    const auto nt = static_cast<Eigen::Index>(train.size()),
               nh = static_cast<Eigen::Index>(held.size());
    Eigen::MatrixXd S_TT(nt, nt), S_HT(nh, nt), S_HH(nh, nh);
    for (Eigen::Index i = 0; i < nt; ++i)
      for (Eigen::Index j = 0; j < nt; ++j)
        S_TT(i, j) = S(train[static_cast<size_t>(i)], train[static_cast<size_t>(j)]);
    for (Eigen::Index i = 0; i < nh; ++i) {
      for (Eigen::Index j = 0; j < nt; ++j)
        S_HT(i, j) = S(held[static_cast<size_t>(i)], train[static_cast<size_t>(j)]);
      for (Eigen::Index j = 0; j < nh; ++j)
        S_HH(i, j) = S(held[static_cast<size_t>(i)], held[static_cast<size_t>(j)]);
    }
    const Eigen::LLT<Eigen::MatrixXd> llt(S_TT);
    const Eigen::VectorXd rT = take_rows(r0, train);
    const Eigen::MatrixXd JT = take_rows(J, train);
    const GlsFit fit = gls_fit(llt.matrixL().solve(rT), llt.matrixL().solve(JT));
    const Eigen::MatrixXd A = llt.solve(S_HT.transpose()).transpose();  // S_HT S_TT⁻¹
    const Eigen::VectorXd nT = rT + JT * fit.x;
    const Eigen::MatrixXd JH = take_rows(J, held);
    const Eigen::VectorXd e = take_rows(r0, held) + JH * fit.x - A * nT;
    const Eigen::MatrixXd Jeff = JH - A * JT;
    const Eigen::MatrixXd C = S_HH - A * S_HT.transpose();
    const Eigen::LLT<Eigen::MatrixXd> lc(C);
    g.chi2 += e.dot(lc.solve(e));
    g.expected += static_cast<double>(nh) + (lc.solve(Jeff * fit.cov * Jeff.transpose())).trace();
  }
  return g;
}

Separability separability(const Eigen::MatrixXd& Jb, const Eigen::MatrixXd& Jc, double limit,
                          double signature_floor, double fit_limit) {
  Separability s;
  const int nc = static_cast<int>(Jc.cols());
  // Directions of the candidate's own information matrix; those below the floor have no signature.
  const Eigen::MatrixXd Hcc = Jc.transpose() * Jc;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> ec(Hcc);
  std::vector<int> keep;
  for (int i = 0; i < nc; ++i)
    if (ec.eigenvalues()(i) > signature_floor) keep.push_back(i);
  s.no_signature = nc - static_cast<int>(keep.size());
  s.basis.resize(nc, 0);
  if (keep.empty()) return s;
  Eigen::MatrixXd U(nc, static_cast<Eigen::Index>(keep.size()));
  for (size_t i = 0; i < keep.size(); ++i) {
    const int j = keep[i];
    U.col(static_cast<Eigen::Index>(i)) = ec.eigenvectors().col(j) / std::sqrt(ec.eigenvalues()(j));
  }
  // In these coordinates Jc U has orthonormal columns; the base's share of each direction is the
  // projection onto span(Jb). λ = 1 - ρ² are the eigenvalues of Uᵀ S U, S the Schur complement.
  const Eigen::MatrixXd A = Jc * U;
  Eigen::MatrixXd P = A;
  Eigen::MatrixXd Q;
  if (Jb.cols() > 0) {
    const Eigen::HouseholderQR<Eigen::MatrixXd> qr(Jb);
    Q = qr.householderQ() * Eigen::MatrixXd::Identity(Jb.rows(), Jb.cols());
    P = A - Q * (Q.transpose() * A);
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> el(P.transpose() * P);
  const double lambda_min = 1.0 - limit * limit;
  const double lambda_fit = fit_limit > limit ? 1.0 - fit_limit * fit_limit : lambda_min;
  std::vector<int> sep, nuisance;
  for (int i = 0; i < el.eigenvalues().size(); ++i) {
    const double lam = std::clamp(el.eigenvalues()(i), 0.0, 1.0);
    const double rho = std::sqrt(1.0 - lam);
    s.max_correlation = std::max(s.max_correlation, rho);
    s.min_correlation = std::min(s.min_correlation, rho);
    if (lam > lambda_min) {
      sep.push_back(i);
    } else if (lam > lambda_fit) {
      nuisance.push_back(i);
      s.max_nuisance_correlation = std::max(s.max_nuisance_correlation, rho);
    }
  }
  s.basis.resize(nc, static_cast<Eigen::Index>(sep.size()));
  for (size_t i = 0; i < sep.size(); ++i)
    s.basis.col(static_cast<Eigen::Index>(i)) = U * el.eigenvectors().col(sep[i]);
  s.nuisance.resize(nc, static_cast<Eigen::Index>(nuisance.size()));
  for (size_t i = 0; i < nuisance.size(); ++i)
    s.nuisance.col(static_cast<Eigen::Index>(i)) = U * el.eigenvectors().col(nuisance[i]);
  // Which base columns mimic the worst direction: the regression of its signature on the base.
  if (Jb.cols() > 0) {
    const Eigen::VectorXd worst = A * el.eigenvectors().col(0);
    const Eigen::VectorXd beta = Jb.colPivHouseholderQr().solve(worst);
    std::vector<std::pair<double, int>> w;
    for (int j = 0; j < Jb.cols(); ++j) w.push_back({std::abs(beta(j)) * Jb.col(j).norm(), j});
    std::sort(w.begin(), w.end(), [](const auto& a, const auto& b) { return a.first > b.first; });
    for (size_t i = 0; i < w.size() && i < 3; ++i)
      if (w[i].first > 0.1 * w[0].first) s.aliases.push_back(w[i].second);
  }
  return s;
}

double canonical_correlation(const Eigen::MatrixXd& Jb, const Eigen::MatrixXd& A,
                             const Eigen::MatrixXd& B) {
  if (A.cols() == 0 || B.cols() == 0 || A.rows() != Jb.rows() || B.rows() != Jb.rows()) return 0.0;
  const Eigen::MatrixXd Qa = residual_basis(Jb, A), Qb = residual_basis(Jb, B);
  if (Qa.cols() == 0 || Qb.cols() == 0) return 0.0;
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(Qa.transpose() * Qb);
  return std::min(1.0, svd.singularValues()(0));
}

std::string correlation_text(double r) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.3f", r);
  return buf;
}

}  // namespace imucal::calib::diagnosis
