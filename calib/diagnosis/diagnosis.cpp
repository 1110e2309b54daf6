#include "calib/diagnosis/diagnosis.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <optional>
#include <sstream>
#include <stdexcept>

#include "calib/core/chi2.hpp"
#include "calib/diagnosis/effect_magnitude.hpp"
#include "calib/diagnosis/gap_fit.hpp"
#include "calib/diagnosis/gap_linearisation.hpp"
#include "calib/diagnosis/rest_tremor_candidate.hpp"
#include "calib/diagnosis/simulated_twin.hpp"
#include "calib/diagnosis/stochastic_candidates.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::core;
using namespace calib::effects;

namespace {

/// The linearised problem plus the held-out folds.
struct Problem {
  const GapModel& model;
  const GapLinearisation& lin;
  const Eigen::VectorXd& r0;
  const Eigen::VectorXd& r0_raw;
  const Eigen::MatrixXd& Jb;
  const Eigen::MatrixXd& Jb_raw;
  std::vector<std::vector<int>> folds;
};

std::vector<std::vector<int>> make_folds(const GapModel& m, int k) {
  const auto& segs = m.segments();
  size_t rests = 0;
  for (const auto& s : segs) rests += s.kind == GapSegment::Kind::kRest ? 1 : 0;
  const int K = std::max(2, std::min<int>(k, static_cast<int>(rests)));
  std::vector<std::vector<int>> folds(static_cast<size_t>(K));
  // Table-free: a rest's attitude is an unknown that only its own rest and the moves on either side
  // see, so those moves must stay in the training set when the rest is held out: move i goes
  // to fold i + 2 (K >= 4 rests here), never to its neighbours' folds.
  const bool attitudes = m.attitude_unknowns() > 0;
  const size_t shift = attitudes ? 2 : 0;
  for (size_t s = 0; s < segs.size(); ++s) {
    // A rest and the move after it go together (interleaved folds: no extrapolation in time).
    const bool move = segs[s].kind == GapSegment::Kind::kMove;
    const size_t f = (segs[s].rest_a + (move ? shift : 0)) % static_cast<size_t>(K);
    for (int r = m.row_begin(s); r < m.row_end(s); ++r) {
      // The relative heading across a table-free move is that move's alone: it stays in the fit.
      if (move && attitudes && r - m.row_begin(s) == GapModel::kHeadingRow) continue;
      folds[f].push_back(r);
    }
  }
  return folds;
}

Eigen::MatrixXd hcat(const Eigen::MatrixXd& A, const Eigen::MatrixXd& B) {
  Eigen::MatrixXd M(A.rows(), A.cols() + B.cols());
  M << A, B;
  return M;
}

/// A sea segment: the NIS over its fixes, and per component (north, east) the mean post-fit
/// innovation (m) and its sum over the predicted spread of the sum (a common offset, N(0, 1) under
/// the model); the other components NaN.
SegmentGap localise_innovations(const Problem& p, const GlsFit& fit, size_t s,
                                const Eigen::VectorXd& e_w, const Eigen::MatrixXd& JcovW) {
  SegmentGap g;
  g.segment = p.model.segments()[s];
  g.z.fill(std::numeric_limits<double>::quiet_NaN());
  g.residual_si.fill(std::numeric_limits<double>::quiet_NaN());
  double sum[2] = {0, 0}, sum_raw[2] = {0, 0}, spread[2] = {0, 0}, leverage = 0.0;
  int n[2] = {0, 0};
  const int b = p.model.row_begin(s), e = p.model.row_end(s);
  for (int r = b; r < e; ++r) {
    const int c = p.model.row_component(r);
    const double lev = JcovW.row(r).dot(p.Jb.row(r));
    sum[c] += e_w(r);
    sum_raw[c] += p.r0_raw(r) + p.Jb_raw.row(r).dot(fit.x);
    spread[c] += 1.0 - lev;
    ++n[c];
    g.nis += e_w(r) * e_w(r);
    leverage += lev;
  }
  for (int c = 0; c < 2; ++c) {
    if (n[c] == 0) continue;
    g.residual_si[static_cast<size_t>(c)] = sum_raw[c] / n[c];
    g.z[static_cast<size_t>(c)] = sum[c] / std::sqrt(std::max(spread[c], 1e-6 * n[c]));
  }
  const int rows = e - b;
  g.nis_expected = rows - leverage;
  g.p_value = rows > 0 ? chi2_survival(g.nis * rows / std::max(g.nis_expected, 1e-3), rows) : 1.0;
  return g;
}

std::vector<SegmentGap> localise(const Problem& p, const GlsFit& fit) {
  if (p.model.innovations()) {
    const Eigen::VectorXd e_w = p.r0 + p.Jb * fit.x;
    const Eigen::MatrixXd JcovW = p.Jb * fit.cov;
    std::vector<SegmentGap> out;
    for (size_t s = 0; s < p.model.segments().size(); ++s)
      out.push_back(localise_innovations(p, fit, s, e_w, JcovW));
    return out;
  }
  const Eigen::VectorXd e_raw = p.r0_raw + p.Jb_raw * fit.x;
  const Eigen::VectorXd e_w = p.r0 + p.Jb * fit.x;
  const Eigen::MatrixXd Jcov = p.Jb_raw * fit.cov;
  const Eigen::MatrixXd JcovW = p.Jb * fit.cov;
  std::vector<SegmentGap> out;
  for (size_t s = 0; s < p.model.segments().size(); ++s) {
    SegmentGap g;
    g.segment = p.model.segments()[s];
    const int r0 = kGapRowsPerSegment * static_cast<int>(s);
    const Block6& P = p.model.covariance(s);
    double leverage = 0.0;
    for (int c = 0; c < kGapRowsPerSegment; ++c) {
      const int r = r0 + c;
      // Predicted spread of the post-fit residual: P_ii - (J Cov Jᵀ)_ii.
      const double var = P(c, c) - Jcov.row(r).dot(p.Jb_raw.row(r));
      g.residual_si[static_cast<size_t>(c)] = e_raw(r);
      g.z[static_cast<size_t>(c)] = e_raw(r) / std::sqrt(std::max(var, 1e-6 * P(c, c)));
      g.nis += e_w(r) * e_w(r);
      leverage += JcovW.row(r).dot(p.Jb.row(r));
    }
    g.nis_expected = kGapRowsPerSegment - leverage;
    g.p_value = chi2_survival(g.nis * kGapRowsPerSegment / std::max(g.nis_expected, 1e-3),
                              kGapRowsPerSegment);
    out.push_back(g);
  }
  return out;
}

/// The simulated twin through the same residual model, refitted with the same Jacobian (same
/// trajectory, same parameters): its overall χ²/dof and per-segment NIS beside the real ones.
void compare_with_twin(DiagnosisResult& d, const DiagnosisInput& in, const Problem& p,
                       const DiagnosisOptions& opt) {
  if (p.model.table_free()) {  // no reference trajectory to simulate the twin along
    d.twin_gap = std::numeric_limits<double>::quiet_NaN();
    for (auto& s : d.segments) s.nis_twin = std::numeric_limits<double>::quiet_NaN();
    return;
  }
  const DiagnosisInput twin = simulated_twin(in, d.base, opt.twin_seed);
  const GapModel tm(twin, opt.min_rest_samples);
  if (tm.rows() != p.model.rows()) return;  // same rest flags, so never; be safe
  const Eigen::VectorXd r = tm.whiten(tm.residuals(d.base, Effects{}));
  const GlsFit f = gls_fit(r, p.Jb);
  d.twin_gap = f.chi2 / f.dof;
  const Eigen::VectorXd e = r + p.Jb * f.x;
  for (size_t s = 0; s < d.segments.size(); ++s)
    d.segments[s].nis_twin =
        e.segment<kGapRowsPerSegment>(kGapRowsPerSegment * static_cast<int>(s)).squaredNorm();
}

std::string base_names(const GapLinearisation& lin, const std::vector<int>& idx) {
  std::string s;
  for (int i : idx) s += (s.empty() ? "" : ", ") + lin.column_name(i);
  return s;
}

/// The part of an estimate y (covariance Sy) along the directions whose σ is at most `limit`: a
/// direction more uncertain than the largest plausible size says nothing of the size (issue #49: on
/// `short` and factory-std the common part of the three lever arms, an offset of the whole triad,
/// is fitted with σ ≈ 0.8 m beside K2, and its noise made the debiased norm of a real 45 mm size
/// effect 0 ± 832 mm). Returns false when every direction is resolved (y, Sy unchanged).
bool resolved_part(Eigen::VectorXd& y, Eigen::MatrixXd& Sy, double limit, int& unresolved) {
  if (!std::isfinite(limit)) return false;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(Sy);
  std::vector<Eigen::Index> keep;
  for (Eigen::Index i = 0; i < Sy.rows(); ++i)
    if (std::sqrt(std::max(0.0, es.eigenvalues()(i))) <= limit) keep.push_back(i);
  unresolved = static_cast<int>(Sy.rows()) - static_cast<int>(keep.size());
  if (unresolved == 0) return false;
  const auto m = static_cast<Eigen::Index>(keep.size());
  Eigen::MatrixXd V(Sy.rows(), m);
  for (Eigen::Index j = 0; j < m; ++j)
    V.col(j) = es.eigenvectors().col(keep[static_cast<size_t>(j)]);
  y = V.transpose() * y;
  Sy = V.transpose() * Sy * V;
  return true;
}

/// A fitted candidate's magnitude and its σ. The magnitude is a norm of scaled parameters,
/// |s ⊙ v|; with two or more fitted components it is debiased for their noise
/// (calib/diagnosis/effect_magnitude.hpp), with one it is |x| ± σ. With a finite `resolve_limit`
/// (the largest plausible size, in the magnitude's unit) the directions resolved within it are
/// also weighed alone (resolved_part), and their size reported where it tells more than the
/// whole's.
/// Returns how many directions the reported size leaves out.
int set_magnitude(CandidateResult& r, const EffectInfo& e, const std::vector<int>& param_index,
                  const Eigen::VectorXd& x, const Eigen::MatrixXd& cov_x,
                  double resolve_limit = std::numeric_limits<double>::infinity()) {
  const int n = static_cast<int>(param_index.size());
  Eigen::VectorXd scale_h(n);
  for (int k = 0; k < n; ++k) {
    Eigen::VectorXd unit = Eigen::VectorXd::Zero(e.size());
    unit(param_index[static_cast<size_t>(k)]) = 1.0;
    scale_h(k) = e.magnitude(unit);
  }
  Eigen::VectorXd y = scale_h.cwiseProduct(x);
  Eigen::MatrixXd Sy = scale_h.asDiagonal() * cov_x * scale_h.asDiagonal();
  if ((scale_h.array() > 0.0).count() < 2) {
    r.magnitude = y.norm();
    r.magnitude_sigma = std::sqrt(std::max(0.0, Sy.sum()));
    return 0;
  }
  const NormEstimate whole = debiased_norm(y, Sy);
  r.magnitude = whole.value;
  r.magnitude_sigma = whole.sigma;
  int unresolved = 0;
  if (!resolved_part(y, Sy, resolve_limit, unresolved) || y.size() == 0) return 0;
  // The resolved part's size where it tells more (a larger size/σ): on a lever-arm run the whole
  // norm is noise-level; on a sea run's g-sensitivity, its poorly resolved directions carry it.
  NormEstimate part;
  if (y.size() == 1) {
    part.value = std::abs(y(0));
    part.sigma = std::sqrt(std::max(0.0, Sy(0, 0)));
  } else {
    part = debiased_norm(y, Sy);
  }
  auto ratio = [](const NormEstimate& m) { return m.sigma > 0.0 ? m.value / m.sigma : 0.0; };
  if (ratio(part) <= ratio(whole)) return 0;
  r.magnitude = part.value;
  r.magnitude_sigma = part.sigma;
  return unresolved;
}

/// "partly separable: 2 of 3 parameter directions (the others alias ...); 1 more fitted with them,
/// not resolved (correlation 0.972)".
std::string partly_separable_note(const Problem& p, const Separability& sep, int n) {
  std::ostringstream os;
  os << "partly separable: " << sep.basis.cols() << " of " << n << " parameter directions";
  if (!sep.aliases.empty()) os << " (the others alias " << base_names(p.lin, sep.aliases) << ")";
  if (sep.nuisance.cols() > 0)
    os << "; " << sep.nuisance.cols() << " more fitted with them, not resolved (correlation "
       << correlation_text(sep.max_nuisance_correlation) << ")";
  return os.str();
}

/// A candidate's fitted columns and how their coefficients map back to the effect's parameters.
struct Scored {
  CandidateResult result;
  Eigen::MatrixXd J_eff;  ///< its fitted columns (whitened)
  /// SI effect parameters (those in param_index) from the fitted coefficients α: x = B α.
  Eigen::MatrixXd B;
  std::vector<int> param_index;
  double tau_s = 0.0;  ///< shape parameter used (thermal drift), 0 if none
  /// It stands in the stepwise search for a set this sequence cannot tell apart (issue #49 item 2:
  /// the set's first-ranked member); set_others are the other members, never searched themselves.
  bool represents_set = false;
  std::vector<std::string> set_others;
  /// The output filter's p-value given a slow wandering of the bias
  /// (output_filter_p_given_wandering); NaN for every other candidate.
  double p_given_wandering = std::numeric_limits<double>::quiet_NaN();
};

/// An effect's values, parameters and magnitude from its fitted coefficients α (covariance cov_a):
/// the candidate's own fit, or its share of a joint fit with other effects.
struct EffectValues {
  Eigen::VectorXd value_si;
  std::vector<CandidateParam> params;
  double magnitude = 0.0, magnitude_sigma = 0.0;
  int unresolved = 0;  ///< directions left out of the magnitude (set_magnitude's resolve_limit)
};

EffectValues effect_values(const Scored& s, const Eigen::VectorXd& alpha,
                           const Eigen::MatrixXd& cov_a,
                           double resolve_limit = std::numeric_limits<double>::infinity()) {
  const EffectInfo& e = effect_info(s.result.id);
  const Eigen::VectorXd x = s.B * alpha;
  const Eigen::MatrixXd cov_x = s.B * cov_a * s.B.transpose();
  EffectValues v;
  v.value_si = Eigen::VectorXd::Zero(e.size());
  Eigen::VectorXd sigma_si = Eigen::VectorXd::Zero(e.size());
  for (size_t k = 0; k < s.param_index.size(); ++k) {
    const auto i = static_cast<Eigen::Index>(k);
    v.value_si(s.param_index[k]) = x(i);
    sigma_si(s.param_index[k]) = std::sqrt(std::max(0.0, cov_x(i, i)));
  }
  if (s.tau_s > 0.0) v.value_si(e.size() - 1) = s.tau_s;
  for (int j = 0; j < e.size(); ++j) {
    const EffectParamInfo& pi = e.params[static_cast<size_t>(j)];
    v.params.push_back({pi.name, pi.human_unit, v.value_si(j) * pi.si_to_human,
                        pi.shape ? 0.0 : sigma_si(j) * pi.si_to_human});
  }
  CandidateResult m;
  v.unresolved = set_magnitude(m, e, s.param_index, x, cov_x, resolve_limit);
  v.magnitude = m.magnitude;
  v.magnitude_sigma = m.magnitude_sigma;
  return v;
}

/// The largest plausible size of a candidate on this run's unit, in its magnitude's unit: the limit
/// of judge_plausibility, and the σ beyond which a direction of a joint fit says nothing of the
/// size.
double plausible_size(const Scored& s, const Problem& p, const DiagnosisOptions& opt) {
  const EffectInfo& e = effect_info(s.result.id);
  const double t = e.magnitude(Eigen::Map<const Eigen::VectorXd>(
      e.typical.data(), static_cast<Eigen::Index>(e.typical.size())));
  const double limit =
      plausible_limit_typical(s.result.id, p.model.input().grade, opt.max_plausible_typical);
  return e.magnitude_params.empty() ? limit : limit * t;
}

/// Fit one candidate jointly with the base (in its separable subspace) and score it.
Scored score_candidate(const Problem& p, const CandidateColumns& c, double chi2_0,
                       const DiagnosisOptions& opt) {
  const EffectInfo& e = effect_info(c.id);
  Scored s;
  CandidateResult& r = s.result;
  r.id = c.id;
  r.name = e.name;
  r.unit = e.magnitude_unit();
  // A direction whose typical-size effect moves the whitened residuals by less than 0.01 (χ² 1e-4)
  // has no signature at all on this sequence — typical for the unit's grade: a MEMS unit's effects
  // are effect_scale times the catalogue's (navigation-grade) typical sizes, and so is its noise.
  const Separability sep =
      separability(p.Jb, c.J, opt.separability_limit,
                   signature_floor(effect_scale(c.id, p.model.input().grade)), opt.fit_limit);
  r.max_correlation = sep.max_correlation;
  const int n = static_cast<int>(c.J.cols());
  if (sep.basis.cols() == 0) {
    std::ostringstream os;
    os << "not separable on this sequence: ";
    if (sep.no_signature == n)
      os << "it changes no rest or move residual (no signature)";
    else
      os << "its parameters correlate "
         << correlation_text(std::max(sep.max_correlation, opt.separability_limit)) << " > "
         << opt.separability_limit << " with " << base_names(p.lin, sep.aliases);
    r.note = os.str();
    r.value_si = Eigen::VectorXd::Zero(e.size());
    return s;
  }
  if (sep.basis.cols() < n) r.note = partly_separable_note(p, sep, n);
  r.separable = true;
  // The fitted directions: the separable ones and the nuisance ones (DiagnosisOptions::fit_limit).
  Eigen::MatrixXd basis(n, sep.basis.cols() + sep.nuisance.cols());
  basis << sep.basis, sep.nuisance;
  r.k = static_cast<int>(basis.cols());
  s.J_eff = c.J * basis;
  s.B = c.scale.asDiagonal() * basis;  // back to the effect's SI parameters: x = scale ⊙ (basis α)
  s.param_index = c.param_index;
  s.tau_s = c.tau_s;
  const GlsFit fit = gls_fit(p.r0, hcat(p.Jb, s.J_eff));
  r.lr = std::max(0.0, chi2_0 - fit.chi2);
  r.p_value = chi2_survival(r.lr, r.k);
  r.bic_gain = r.lr - r.k * std::log(static_cast<double>(p.r0.size()));
  EffectValues v = effect_values(s, fit.x.tail(r.k), fit.cov.bottomRightCorner(r.k, r.k));
  r.value_si = std::move(v.value_si);
  r.params = std::move(v.params);
  r.magnitude = v.magnitude;
  r.magnitude_sigma = v.magnitude_sigma;
  try {
    r.held_out_gap = held_out_gap(p.r0, hcat(p.Jb, s.J_eff), p.folds).ratio();
  } catch (const std::invalid_argument&) {
    r.held_out_gap = std::numeric_limits<double>::quiet_NaN();
    r.note += std::string(r.note.empty() ? "" : "; ") +
              "no held-out check: with a fold held out its parameters are not separable";
  }
  r.chi2_after = fit.chi2;
  return s;
}

// A candidate is fitted only with at least this many residuals to spare (rows - base columns - its
// parameters).
constexpr int kMinDofForCandidate = 12;
// The held-out folds need rests to fit on: below this the run is too short to diagnose.
constexpr size_t kMinRests = 4;

Scored not_applicable(const EffectInfo& e, const std::string& note) {
  Scored s;
  s.result.id = e.id;
  s.result.name = e.name;
  s.result.note = note;
  s.result.value_si = Eigen::VectorXd::Zero(e.size());
  return s;
}

/// Where the per-sample candidates are judged. The hand's tremor on every rest. The lag-1 ones
/// (quantisation, the output filter) assume a still unit: on every rest too, unless the tremor is
/// significant — then a hand's motion correlates the samples as a low-pass filter would (the
/// corpus' hand-held rests: gyro lag-1 0.5-0.9, the same unit on the bench 0.0), and they are
/// judged on the rests as quiet as the quietest (still_rests), if the tremor's test finds no
/// motion there either; else on none.
struct PerSampleRests {
  std::optional<CandidateResult> tremor;
  std::vector<RestPeriod> lag1;
  std::string lag1_note;  ///< why lag1 holds fewer than the run's rests; "" when it holds all
};

PerSampleRests per_sample_rests(const Problem& p, const std::vector<EffectId>& ids,
                                const DiagnosisOptions& opt) {
  PerSampleRests ps;
  ps.lag1 = p.model.rests();
  if (std::find(ids.begin(), ids.end(), EffectId::kRestTremor) == ids.end() ||
      !p.model.not_applicable(EffectId::kRestTremor).empty())
    return ps;
  ps.tremor = score_rest_tremor(p.model.input(), p.model.rests(), p.lin.base(), opt.folds);
  const double level = opt.alpha / static_cast<double>(ids.size());
  if (!(ps.tremor->p_value < level)) return ps;
  ps.lag1 = still_rests(p.model.input(), p.model.rests());
  if (score_rest_tremor(p.model.input(), ps.lag1, p.lin.base(), opt.folds).p_value < level)
    ps.lag1.clear();  // the quietest rests move too: no rest is still
  ps.lag1_note = "judged on the " + std::to_string(ps.lag1.size()) + " of " +
                 std::to_string(p.model.rests().size()) +
                 " rests whose gyros show no motion (rest_tremor: a hand's motion correlates the "
                 "samples)";
  return ps;
}

/// Quantisation or the output filter on the rests per_sample_rests chose.
Scored score_lag1(EffectId id, const Problem& p, const PerSampleRests& ps,
                  const DiagnosisOptions& opt) {
  if (ps.lag1.size() < 2)
    return not_applicable(effect_info(id),
                          "not assessed: the rests move (rest_tremor), and a moving unit's samples "
                          "are correlated by the hand, not by the sensor");
  Scored s;
  s.result = id == EffectId::kQuantisation
                 ? score_quantisation(p.model.input(), ps.lag1, opt.folds)
                 : score_output_filter(p.model.input(), ps.lag1, opt.folds);
  if (id == EffectId::kOutputFilter)
    s.p_given_wandering = output_filter_p_given_wandering(p.model.input(), ps.lag1);
  if (!ps.lag1_note.empty()) s.result.note += "; " + ps.lag1_note;
  return s;
}

/// All candidates scored (thermal drift: the best τ of the grid), unranked.
std::vector<Scored> score_all(const Problem& p, double chi2_0, const DiagnosisOptions& opt) {
  std::vector<EffectId> ids = opt.candidates;
  if (ids.empty())
    for (const auto& e : effect_catalogue()) ids.push_back(e.id);
  const PerSampleRests per_sample = per_sample_rests(p, ids, opt);
  std::vector<Scored> out;
  for (EffectId id : ids) {
    const EffectInfo& e = effect_info(id);
    if (const std::string why = p.model.not_applicable(id); !why.empty()) {
      out.push_back(not_applicable(e, why));
      continue;
    }
    if (id == EffectId::kQuantisation || id == EffectId::kOutputFilter) {
      out.push_back(score_lag1(id, p, per_sample, opt));
      continue;
    }
    if (id == EffectId::kRestTremor) {
      Scored s;
      s.result = *per_sample.tremor;
      out.push_back(std::move(s));
      continue;
    }
    if (id == EffectId::kBiasInstability) {
      Scored s;
      s.result = score_bias_instability(p.lin, p.folds, opt.instability_tau_grid_s);
      out.push_back(std::move(s));
      continue;
    }
    int k_max = 0;
    for (const auto& pi : e.params) k_max += pi.shape ? 0 : 1;
    const int nb = static_cast<int>(p.Jb.cols());
    if (p.model.rows() - nb - k_max < kMinDofForCandidate) {
      const std::string why = "the run is too short for its " + std::to_string(k_max) +
                              " parameters (" + std::to_string(p.model.rows()) + " residuals for " +
                              std::to_string(nb) + " + " + std::to_string(k_max) + ")";
      if (!opt.candidates.empty())
        throw std::invalid_argument("gap diagnosis: candidate " + e.name + ": " + why);
      Scored s;
      s.result.id = id;
      s.result.name = e.name;
      s.result.note = "not fitted: " + why;
      s.result.value_si = Eigen::VectorXd::Zero(e.size());
      out.push_back(std::move(s));
      continue;
    }
    std::vector<double> taus{0.0};
    if (id == EffectId::kThermalDrift) taus = opt.thermal_tau_grid_s;
    Scored best;
    bool have = false;
    for (double tau : taus) {
      Scored s = score_candidate(p, p.lin.candidate(id, tau), chi2_0, opt);
      if (!have || s.result.lr > best.result.lr) best = std::move(s);
      have = true;
    }
    out.push_back(std::move(best));
  }
  return out;
}

/// Mark significance (Bonferroni) and confounding between significant candidates, then rank by BIC
/// gain (separable first). A significant candidate whose signature another significant one shares
/// (> separability_limit) stays in the ranking but is marked: the diagnosis cannot tell them apart
/// on this sequence, so neither is a finding.
/// Marks a candidate of implausible size (far beyond its catalogue typical): never a finding.
void judge_plausibility(CandidateResult& r, double max_typical) {
  const EffectInfo& e = effect_info(r.id);
  const Eigen::VectorXd typical = Eigen::Map<const Eigen::VectorXd>(
      e.typical.data(), static_cast<Eigen::Index>(e.typical.size()));
  const double t = e.magnitude(typical);
  if (!(t > 0.0) || !r.separable) return;
  r.typical_ratio = r.magnitude / t;
  // Implausible only when the size is beyond the limit by more than its own 2σ: a poorly
  // determined fit (a sea run's g-sensitivity diagonal, σ half its value) may land above the limit
  // by its noise alone.
  const double sigma = std::isfinite(r.magnitude_sigma) ? r.magnitude_sigma : 0.0;
  r.plausible = (r.magnitude - 2.0 * sigma) / t <= max_typical;
  if (!r.plausible) {
    std::ostringstream os;
    os.precision(3);
    os << "implausible size: " << r.typical_ratio << "x its typical " << t << " " << r.unit
       << " (limit " << max_typical << "x, beyond it by more than 2 sigma)";
    r.note += (r.note.empty() ? "" : "; ") + os.str();
  }
}

/// Mark significance (Bonferroni), plausibility and confounding between significant candidates,
/// then rank: findings first (significant, or an ambiguous set's members) by their held-out gap —
/// the proof of a cause is how much of the gap it predicts on segments it was not fitted to —
/// then the rest by BIC gain (separable first). A candidate whose signature another significant
/// one shares (> separability_limit) is not significant on its own: the two explain as a set.
/// Whether a candidate predicts the held-out segments better than the model without it (its own
/// statistic's held-out gap for one judged on its own, as quantisation). A candidate that only fits
/// the segments it was fitted to is no cause, however small its p-value (issue #19 item 6: a
/// thermal drift fitted to a K2 run's residuals made the held-out gap worse, 84 -> 110, and read
/// "significant").
bool predicts_held_out(CandidateResult& r, double gap_before) {
  const double before = std::isnan(r.held_out_gap_before) ? gap_before : r.held_out_gap_before;
  if (std::isnan(r.held_out_gap) || std::isnan(before) || r.held_out_gap < before) return true;
  std::ostringstream os;
  os.precision(3);
  os << "does not predict the held-out segments (held-out gap " << before << " -> "
     << r.held_out_gap << ")";
  r.note += (r.note.empty() ? "" : "; ") + os.str();
  return false;
}

/// Each set of candidates this sequence cannot tell apart enters the stepwise search as one
/// candidate (issue #49 item 2), so that another effect is never chosen for the set's signature:
/// its first-ranked member stands for it. (On an independent simulator's K2 + lever-arm run the
/// K2 | asymmetry set, left out of the search, left its signature to a 10 m size effect.)
void mark_set_representatives(std::vector<Scored>& c) {
  std::vector<std::string> represented;
  for (Scored& s : c) {
    const CandidateResult& r = s.result;
    if (!r.in_ambiguous_set || s.J_eff.cols() == 0) continue;
    if (std::find(represented.begin(), represented.end(), r.name) != represented.end()) continue;
    s.represents_set = true;
    s.set_others = r.confounded_with;
    represented.push_back(r.name);
    represented.insert(represented.end(), r.confounded_with.begin(), r.confounded_with.end());
  }
}

void rank(std::vector<Scored>& c, const Problem& p, double held_out_before,
          const DiagnosisOptions& opt) {
  const double level = opt.alpha / std::max<size_t>(1, c.size());
  std::vector<bool> test(c.size(), false);
  for (size_t i = 0; i < c.size(); ++i) {
    CandidateResult& r = c[i].result;
    // The limit grows with the unit's grade: a MEMS unit's effects dwarf a navigation unit's.
    judge_plausibility(
        r, plausible_limit_typical(r.id, p.model.input().grade, opt.max_plausible_typical));
    test[i] =
        r.separable && r.plausible && r.p_value < level && predicts_held_out(r, held_out_before);
  }
  for (size_t i = 0; i < c.size(); ++i)
    for (size_t j = i + 1; j < c.size(); ++j) {
      auto &a = c[i].result, &b = c[j].result;
      if (!test[i] || !test[j]) continue;
      if (c[i].J_eff.cols() == 0 || c[j].J_eff.cols() == 0) continue;  // stochastic: no signature
      const double rho = canonical_correlation(p.Jb, c[i].J_eff, c[j].J_eff);
      if (rho > opt.separability_limit) {
        a.confounded_with.push_back(b.name);
        b.confounded_with.push_back(a.name);
      }
    }
  for (size_t i = 0; i < c.size(); ++i) {
    CandidateResult& r = c[i].result;
    r.significant = test[i] && r.confounded_with.empty();
    r.in_ambiguous_set = test[i] && !r.confounded_with.empty();
    if (r.confounded_with.empty()) continue;
    std::string others;
    for (const auto& o : r.confounded_with) others += (others.empty() ? "" : ", ") + o;
    std::ostringstream os;
    os << "not separable on this sequence from " << others << " (their signatures correlate > "
       << opt.separability_limit << ")";
    r.note += (r.note.empty() ? "" : "; ") + os.str();
  }
  auto finding = [](const CandidateResult& r) { return r.significant || r.in_ambiguous_set; };
  auto held_out = [](const CandidateResult& r) {
    return std::isnan(r.held_out_gap) ? std::numeric_limits<double>::infinity() : r.held_out_gap;
  };
  std::stable_sort(c.begin(), c.end(), [&](const Scored& a, const Scored& b) {
    if (finding(a.result) != finding(b.result)) return finding(a.result);
    if (finding(a.result) && held_out(a.result) != held_out(b.result))
      return held_out(a.result) < held_out(b.result);
    if (a.result.separable != b.result.separable) return a.result.separable;
    return a.result.bic_gain > b.result.bic_gain;
  });
  mark_set_representatives(c);
}

std::vector<ParamShift> moved_params(const GapLinearisation& lin, const GlsFit& before,
                                     const GlsFit& after) {
  std::vector<ParamShift> out;
  for (size_t c = 0; c < lin.columns().size(); ++c) {
    const int j = lin.columns()[c];
    if (j < 0) continue;  // a rest's attitude: not a calibration parameter
    const int i = static_cast<int>(c);
    const double sigma = std::sqrt(before.cov(i, i));
    const double d = after.x(i) - before.x(i);
    if (sigma > 0.0 && std::abs(d) > sigma) {
      const ParamInfo& pi = param_info(j);
      out.push_back({pi.name, pi.human_unit, d / sigma, d * pi.si_to_human});
    }
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    return std::abs(a.shift_sigma) > std::abs(b.shift_sigma);
  });
  return out;
}

std::vector<std::pair<std::string, double>> remaining_gap(const Problem& p,
                                                          const Eigen::MatrixXd& J,
                                                          const GlsFit& fit) {
  const Eigen::VectorXd e = p.r0 + J * fit.x;
  std::vector<std::pair<std::string, double>> out;
  for (size_t s = 0; s < p.model.segments().size(); ++s)
    for (int r = p.model.row_begin(s); r < p.model.row_end(s); ++r) {
      const double z = e(r);
      if (std::abs(z) > 3.0)
        out.push_back(
            {p.model.segments()[s].label() + " " + p.model.component_name(p.model.row_component(r)),
             z});
    }
  std::sort(out.begin(), out.end(),
            [](const auto& a, const auto& b) { return std::abs(a.second) > std::abs(b.second); });
  if (out.size() > 10) out.resize(10);
  return out;
}

/// GLS under a covariance S of the whitened residuals (whitened again by its Cholesky factor).
GlsFit gls_fit_cov(const Eigen::VectorXd& r0, const Eigen::MatrixXd& J, const Eigen::MatrixXd& S) {
  const Eigen::LLT<Eigen::MatrixXd> llt(S);
  return gls_fit(llt.matrixL().solve(r0), llt.matrixL().solve(J));
}

/// One step of the explanation as selected: which candidate, its test given the steps before it,
/// the overall χ² and dof and the held-out gap once it is added.
struct StepFit {
  size_t member = 0;
  double p_value = 1.0;
  double chi2 = std::numeric_limits<double>::quiet_NaN();
  int dof = 0;
  double held_out = std::numeric_limits<double>::quiet_NaN();
  /// An undeclared Gauss-Markov bias chosen with it would explain it as well (its test given the
  /// bias and the others fails): the run cannot tell this trend from the bias's wandering.
  bool like_wandering = false;
  /// A noise member's size given the set before it (a Gauss-Markov bias after the set); absent:
  /// its own fit's.
  std::optional<CandidateResult> size_given_set = std::nullopt;
};

/// The explanation chosen for the segment residuals (plus quantisation, which acts on the
/// per-sample statistics only): its steps (candidate indices, most important first), their
/// columns, and the residual covariance if a Gauss-Markov bias is among them.
struct Selection {
  std::vector<StepFit> steps;
  double bic = 0.0;
  Eigen::MatrixXd J;  ///< [Jb, deterministic members' columns in step order]
  bool gm = false;
  Eigen::MatrixXd S;  ///< whitened-residual covariance under the Gauss-Markov bias (gm only)
  std::vector<std::string> ambiguous;
  /// Members the search chose whose place the final joint fit does not support (earn_places).
  std::vector<UnsupportedEffect> unsupported;
};

/// A candidate judged on a per-sample statistic of its own (the rest samples' lag-1
/// autocovariance; for the hand's tremor the accelerometers against the gyro-integrated tilt within
/// the rests), not on the segment residuals.
bool judged_per_sample(EffectId id) {
  return id == EffectId::kQuantisation || id == EffectId::kOutputFilter ||
         id == EffectId::kRestTremor;
}

std::optional<size_t> index_of(const std::vector<Scored>& c, EffectId id) {
  for (size_t i = 0; i < c.size(); ++i)
    if (c[i].result.id == id) return i;
  return std::nullopt;
}

// At most this many deterministic effects in one explanation: beyond it the candidates' joint fit
// has more unknowns than a factory sequence's rests constrain well. The paper's units carry six
// sources that bias a calibration (issue #26, README "The paper's figures: a gap budget").
constexpr size_t kMaxSteps = 6;

/// Whether a candidate may join a stepwise explanation: a deterministic effect (it has columns),
/// separable from the base, and not one of a set this sequence cannot tell apart unless it stands
/// for the set (mark_set_representatives). Its size is
/// judged given the effects chosen before it (next_step): fitted alone, a candidate takes on what
/// the others do — on a paper-like unit the size effect alone read 2600x its typical lever arms,
/// beside a 2.5 ms gyro/accelerometer skew that moves the same moves.
bool steppable(const Scored& s) {
  const CandidateResult& r = s.result;
  return s.J_eff.cols() > 0 && r.separable && (!r.in_ambiguous_set || s.represents_set);
}

/// A candidate's size from a joint fit (`v`), judged by judge_plausibility against `max_typical`:
/// plausible, or not with the note saying why.
CandidateResult judged_size(const Scored& s, const EffectValues& v, double max_typical) {
  CandidateResult r;
  r.id = s.result.id;
  r.separable = true;
  r.unit = s.result.unit;
  r.magnitude = v.magnitude;
  r.magnitude_sigma = v.magnitude_sigma;
  judge_plausibility(r, max_typical);
  return r;
}

/// Whether a candidate's size in a joint fit (its coefficients at the tail of `fit`) is plausible
/// (judge_plausibility's rule).
bool plausible_in(const Scored& s, const GlsFit& fit, double max_typical, double resolve_limit) {
  const auto k = s.J_eff.cols();
  // Judged along the directions the fit resolves within the bound, as the final set is
  // (judge_member): the lever arms' unresolved common part (σ ≈ 0.8 m) would make any size effect
  // implausible beside a 300 mm bound (the paper-like unit's lost its place that way).
  const EffectValues v =
      effect_values(s, fit.x.tail(k), fit.cov.bottomRightCorner(k, k), resolve_limit);
  return judged_size(s, v, max_typical).plausible;
}

/// The next step of the forward selection given the columns J (base + the effects chosen, χ²
/// chi2_now, held-out gap held_now): among the candidates not chosen whose likelihood ratio given J
/// passes `level` and that shrink the held-out gap, the one that predicts the held-out segments
/// best (the larger ratio on a tie). Empty when none does.
std::optional<StepFit> next_step(const std::vector<Scored>& c, const Problem& p,
                                 const Eigen::MatrixXd& J, const StepFit& now,
                                 const std::vector<bool>& chosen, double level,
                                 const DiagnosisOptions& opt) {
  std::optional<StepFit> best;
  double best_lr = 0.0;
  for (size_t i = 0; i < c.size(); ++i) {
    if (chosen[i] || !steppable(c[i])) continue;
    const Eigen::MatrixXd Ji = hcat(J, c[i].J_eff);
    StepFit f;
    f.member = i;
    double lr = 0.0;
    try {
      const GlsFit fit = gls_fit(p.r0, Ji);
      lr = now.chi2 - fit.chi2;
      f.p_value = chi2_survival(std::max(0.0, lr), c[i].result.k);
      if (!(f.p_value < level)) continue;
      const double limit =
          plausible_limit_typical(c[i].result.id, p.model.input().grade, opt.max_plausible_typical);
      if (!plausible_in(c[i], fit, limit, plausible_size(c[i], p, opt))) continue;
      f.chi2 = fit.chi2;
      f.dof = fit.dof;
      f.held_out = held_out_gap(p.r0, Ji, p.folds).ratio();
    } catch (const std::invalid_argument&) {
      continue;  // not separable from the effects already chosen (or with a fold held out)
    }
    if (!(f.held_out < now.held_out)) continue;  // fits the training segments only: no cause
    if (!best || f.held_out < best->held_out || (f.held_out == best->held_out && lr > best_lr)) {
      best = f;
      best_lr = lr;
    }
  }
  return best;
}

/// Forward selection from the best finding `first` (issue #22 item 2): each step adds next_step's
/// choice, until none passes (what remains is consistent with the model as far as any candidate
/// can tell, or nothing separable is left) or kMaxSteps effects are chosen.
Selection forward_selection(const std::vector<Scored>& c, const Problem& p, size_t first,
                            double chi2_0, double level, const DiagnosisOptions& opt) {
  Selection sel;
  sel.J = hcat(p.Jb, c[first].J_eff);
  const GlsFit f1 = gls_fit(p.r0, sel.J);
  sel.steps.push_back(
      {first, c[first].result.p_value, f1.chi2, f1.dof, c[first].result.held_out_gap});
  std::vector<bool> chosen(c.size(), false);
  chosen[first] = true;
  int k = c[first].result.k;
  while (sel.steps.size() < kMaxSteps) {
    const auto step = next_step(c, p, sel.J, sel.steps.back(), chosen, level, opt);
    if (!step) break;
    sel.J = hcat(sel.J, c[step->member].J_eff);
    chosen[step->member] = true;
    k += c[step->member].result.k;
    sel.steps.push_back(*step);
  }
  sel.bic = (chi2_0 - sel.steps.back().chi2) - k * std::log(static_cast<double>(p.r0.size()));
  return sel;
}

/// The base and the steps' columns, in step order.
Eigen::MatrixXd step_columns(const std::vector<Scored>& c, const Problem& p,
                             const std::vector<StepFit>& steps) {
  Eigen::MatrixXd J = p.Jb;
  for (const StepFit& f : steps) J = hcat(J, c[f.member].J_eff);
  return J;
}

/// The steps' figures in order, each given the steps before it: χ², dof, held-out gap and the
/// test's p-value (after earn_places removed some, the survivors' "given the steps before" change).
void refit_steps(Selection& sel, const std::vector<Scored>& c, const Problem& p, double chi2_0) {
  Eigen::MatrixXd J = p.Jb;
  double chi2_before = chi2_0;
  int k = 0;
  for (StepFit& f : sel.steps) {
    J = hcat(J, c[f.member].J_eff);
    const GlsFit fit = gls_fit(p.r0, J);
    f.p_value = chi2_survival(std::max(0.0, chi2_before - fit.chi2), c[f.member].result.k);
    f.chi2 = fit.chi2;
    f.dof = fit.dof;
    f.held_out = held_out_gap(p.r0, J, p.folds).ratio();
    chi2_before = fit.chi2;
    k += c[f.member].result.k;
  }
  sel.J = J;
  sel.bic = sel.steps.empty()
                ? 0.0
                : (chi2_0 - sel.steps.back().chi2) - k * std::log(static_cast<double>(p.r0.size()));
}

/// Whether fitted coefficients a (covariance C) differ from zero by more than 2σ in their own
/// dimension: the Wald statistic aᵀC⁻¹a beyond χ²(k)'s two-sided 2σ quantile (p < 0.0455). A
/// multi-parameter effect is present beyond doubt when this holds, however noise-level the norm of
/// its parameters (a sea run's g-sensitivity: norm 0.16 ± 0.15 °/h/g, p 1e-59).
bool beyond_two_sigma(const Eigen::VectorXd& a, const Eigen::MatrixXd& C) {
  if (a.size() == 0) return false;
  const Eigen::LDLT<Eigen::MatrixXd> ldlt(C);
  if (ldlt.info() != Eigen::Success) return false;
  const double w = a.dot(ldlt.solve(a));
  return std::isfinite(w) && chi2_survival(std::max(0.0, w), static_cast<int>(a.size())) < 0.0455;
}

/// How member i of the set `steps` fares in the final joint fit (issue #49 item 1): every test it
/// fails, for people ("" when it earns its place), its size there and its test given the others.
UnsupportedEffect judge_member(const std::vector<Scored>& c, const Problem& p,
                               const std::vector<StepFit>& steps, size_t i, const GlsFit& fit,
                               double held_all, double level, const DiagnosisOptions& opt) {
  const Scored& sc = c[steps[i].member];
  Eigen::Index col = p.Jb.cols();
  for (size_t j = 0; j < i; ++j) col += c[steps[j].member].J_eff.cols();
  const auto k = sc.J_eff.cols();
  const EffectValues v = effect_values(sc, fit.x.segment(col, k), fit.cov.block(col, col, k, k),
                                       plausible_size(sc, p, opt));
  std::vector<StepFit> others = steps;
  others.erase(others.begin() + static_cast<std::ptrdiff_t>(i));
  const Eigen::MatrixXd J_wo = step_columns(c, p, others);
  UnsupportedEffect u{sc.result.name, v.magnitude, v.magnitude_sigma, sc.result.unit, 1.0, ""};
  u.p_value = chi2_survival(std::max(0.0, gls_fit(p.r0, J_wo).chi2 - fit.chi2), sc.result.k);
  std::ostringstream os;
  os.precision(3);
  auto add = [&](const std::string& why) { os << (os.tellp() > 0 ? "; " : "") << why; };
  if (!(u.p_value < level)) {
    std::ostringstream w;
    w.precision(2);
    w << "not significant given the others refitted (p " << u.p_value << ", level " << level << ")";
    add(w.str());
  }
  if (!beyond_two_sigma(fit.x.segment(col, k), fit.cov.block(col, col, k, k)))
    add("its size is within 2 sigma of zero");
  const CandidateResult r = judged_size(
      sc, v,
      plausible_limit_typical(sc.result.id, p.model.input().grade, opt.max_plausible_typical));
  if (!r.plausible) add(r.note + ": an alias of another effect, not this one");
  double held_wo = std::numeric_limits<double>::infinity();
  try {
    held_wo = held_out_gap(p.r0, J_wo, p.folds).ratio();
  } catch (const std::invalid_argument&) {
    // without it the base is not separable on a fold: it is needed
  }
  if (!(held_wo > held_all)) {
    std::ostringstream w;
    w.precision(3);
    w << "leaving it out does not worsen the held-out gap (" << held_all << " with it, " << held_wo
      << " without)";
    add(w.str());
  }
  u.reason = os.str();
  return u;
}

/// A named effect is earned (issue #49 item 1): in the final joint fit of the stepwise set, each
/// member's size must be significant given all the others refitted (not only given the steps
/// before it), at least 2σ from zero and plausible for the grade, and leaving it out must worsen
/// the held-out gap. The member that fails worst (largest p given the others) is dropped and the
/// set refitted, until every member earns its place. Returns the dropped ones with their reasons.
std::vector<UnsupportedEffect> earn_places(Selection& sel, const std::vector<Scored>& c,
                                           const Problem& p, double chi2_0, double level,
                                           const DiagnosisOptions& opt) {
  std::vector<UnsupportedEffect> dropped;
  while (!sel.steps.empty()) {
    const Eigen::MatrixXd J = step_columns(c, p, sel.steps);
    const GlsFit fit = gls_fit(p.r0, J);
    const double held_all = held_out_gap(p.r0, J, p.folds).ratio();
    std::optional<size_t> worst;
    UnsupportedEffect worst_u;
    for (size_t i = 0; i < sel.steps.size(); ++i) {
      UnsupportedEffect u = judge_member(c, p, sel.steps, i, fit, held_all, level, opt);
      if (u.reason.empty()) continue;
      if (!worst || u.p_value > worst_u.p_value) {
        worst = i;
        worst_u = std::move(u);
      }
    }
    if (!worst) break;
    dropped.push_back(std::move(worst_u));
    sel.steps.erase(sel.steps.begin() + static_cast<std::ptrdiff_t>(*worst));
  }
  refit_steps(sel, c, p, chi2_0);
  return dropped;
}

/// Backward elimination under a Gauss-Markov bias: the deterministic members that the wandering
/// bias would make unnecessary (a slow trend is also a wandering bias), least needed first, while
/// one's test given the others and the bias fails `level`. Returns their candidate indices. They
/// stay in the explanation, marked: on a factory run a thermal drift at several times its threshold
/// is absorbed by an undeclared Gauss-Markov bias as often as a bias's wandering is taken for a
/// drift (validate-diagnosis triples, issue #22), so the run cannot tell the two apart.
std::vector<size_t> unneeded_under_gauss_markov(const std::vector<Scored>& c, const Problem& p,
                                                std::vector<StepFit> steps, double level,
                                                const DiagnosisOptions& opt) {
  std::vector<size_t> out;
  while (!steps.empty()) {
    const GaussMarkovFit fc =
        fit_gauss_markov(p.lin, step_columns(c, p, steps), opt.instability_tau_grid_s);
    std::optional<size_t> drop;
    double drop_p = level;
    for (size_t i = 0; i < steps.size(); ++i) {
      std::vector<StepFit> others = steps;
      others.erase(others.begin() + static_cast<std::ptrdiff_t>(i));
      const double lr = gls_fit_cov(p.r0, step_columns(c, p, others), fc.S).chi2 - fc.chi2;
      const double pv = chi2_survival(std::max(0.0, lr), c[steps[i].member].result.k);
      if (pv >= drop_p) {
        drop = i;
        drop_p = pv;
      }
    }
    if (!drop) break;
    out.push_back(steps[*drop].member);
    steps.erase(steps.begin() + static_cast<std::ptrdiff_t>(*drop));
  }
  return out;
}

/// The deterministic set `det` with an undeclared Gauss-Markov bias `g` after it, when both are
/// needed: the wandering given the set, and the set given the wandering. Members the wandering
/// alone could stand for are marked (StepFit::like_wandering). Empty when either is not needed.
std::optional<Selection> with_gauss_markov(const std::vector<Scored>& c, const Problem& p,
                                           const Selection& det, size_t g, double chi2_0,
                                           double level, const DiagnosisOptions& opt) {
  const GaussMarkovFit fc = fit_gauss_markov(p.lin, det.J, opt.instability_tau_grid_s);
  const int k_det = static_cast<int>(det.J.cols() - p.Jb.cols());
  const double lr_det_given_g = gls_fit_cov(p.r0, p.Jb, fc.S).chi2 - fc.chi2;
  if (!(chi2_survival(fc.lr, 2) < level && chi2_survival(lr_det_given_g, k_det) < level))
    return std::nullopt;
  // Its size given the set, judged as any candidate's: alone it takes on the set's effects too.
  CandidateResult given = c[g].result;
  set_gauss_markov_size(given, p.lin, det.J, fc);
  given.plausible = true;
  given.separable = true;
  judge_plausibility(given,
                     plausible_limit_typical(EffectId::kBiasInstability, p.model.input().grade,
                                             opt.max_plausible_typical));
  if (!given.plausible) return std::nullopt;
  Selection s = det;
  s.gm = true;
  s.S = fc.S;
  const std::vector<size_t> like = unneeded_under_gauss_markov(c, p, det.steps, level, opt);
  for (StepFit& f : s.steps)
    f.like_wandering = std::find(like.begin(), like.end(), f.member) != like.end();
  const double lr_det = chi2_0 - det.steps.back().chi2;
  s.bic = lr_det + fc.lr - (k_det + 2) * std::log(static_cast<double>(p.r0.size()));
  StepFit gm{g, chi2_survival(fc.lr, 2), fc.chi2, det.steps.back().dof,
             std::numeric_limits<double>::quiet_NaN()};
  gm.size_given_set = std::move(given);
  try {
    gm.held_out = held_out_gap_correlated(p.r0, det.J, fc.S, p.folds).ratio();
  } catch (const std::invalid_argument&) {
    // no held-out figure for this step
  }
  s.steps.push_back(gm);
  return s;
}

/// The deterministic member of `both` (a set followed by a Gauss-Markov bias) whose size, fitted
/// with the others under the bias's covariance, is within 2σ of zero or implausible — the weakest
/// by size/σ — with why; empty when every member keeps its size (issue #49 item 1: with the
/// wandering beside it a K2 run's thermal drift read "0 ± 2.1 × typical" and was named).
std::optional<std::pair<size_t, UnsupportedEffect>> unsized_under_gauss_markov(
    const std::vector<Scored>& c, const Problem& p, const Selection& both,
    const DiagnosisOptions& opt) {
  const GlsFit fit = gls_fit_cov(p.r0, both.J, both.S);
  std::optional<std::pair<size_t, UnsupportedEffect>> weakest;
  double weakest_ratio = std::numeric_limits<double>::infinity();
  Eigen::Index col = p.Jb.cols();
  for (size_t i = 0; i < both.steps.size(); ++i) {
    const Scored& sc = c[both.steps[i].member];
    const auto k = sc.J_eff.cols();
    if (k == 0 || col + k > fit.x.size()) continue;  // the bias itself
    const EffectValues v = effect_values(sc, fit.x.segment(col, k), fit.cov.block(col, col, k, k),
                                         plausible_size(sc, p, opt));
    col += k;
    const CandidateResult r = judged_size(
        sc, v,
        plausible_limit_typical(sc.result.id, p.model.input().grade, opt.max_plausible_typical));
    const bool sized =
        beyond_two_sigma(fit.x.segment(col - k, k), fit.cov.block(col - k, col - k, k, k));
    const double ratio = v.magnitude_sigma > 0.0 ? v.magnitude / v.magnitude_sigma : 0.0;
    if ((sized && r.plausible) || ratio >= weakest_ratio) continue;
    weakest_ratio = ratio;
    UnsupportedEffect u{sc.result.name, v.magnitude, v.magnitude_sigma, sc.result.unit, 1.0, ""};
    u.reason = r.plausible ? "its size is within 2 sigma of zero given the bias instability named "
                             "with it: the bias's wandering takes its signature"
                           : r.note + ", given the bias instability named with it";
    weakest = std::make_pair(i, std::move(u));
  }
  return weakest;
}

/// Whether an undeclared Gauss-Markov bias and the deterministic set `det` are told apart in the
/// bias's favour: the bias needed given the set, the set not needed given the bias (issue #49 item
/// 3: each slow signature the wandering could absorb is tested against it both ways).
bool wandering_explains_the_set(const Problem& p, const Selection& det, double level,
                                const DiagnosisOptions& opt) {
  const GaussMarkovFit fc = fit_gauss_markov(p.lin, det.J, opt.instability_tau_grid_s);
  const int k_det = static_cast<int>(det.J.cols() - p.Jb.cols());
  const double lr_det_given_g = gls_fit_cov(p.r0, p.Jb, fc.S).chi2 - fc.chi2;
  return chi2_survival(fc.lr, 2) < level && !(chi2_survival(lr_det_given_g, k_det) < level);
}

/// The selection of a set this sequence cannot tell apart, alone: explained by the set (issue #19
/// item 6), its members listed, no step.
Selection set_alone(const std::vector<Scored>& c, const Problem& p, size_t member) {
  Selection s;
  s.ambiguous.push_back(c[member].result.name);
  for (const auto& o : c[member].set_others) s.ambiguous.push_back(o);
  s.J = hcat(p.Jb, c[member].J_eff);
  return s;
}

/// The deterministic explanation: forward selection from the best finding (a set this sequence
/// cannot tell apart enters as one), then each member's place earned in the final joint fit.
/// Empty steps when none is left; the dropped members in `unsupported` either way.
std::optional<Selection> deterministic_set(const std::vector<Scored>& c, const Problem& p,
                                           double chi2_0, double level, const DiagnosisOptions& opt,
                                           std::vector<UnsupportedEffect>& unsupported) {
  std::optional<size_t> d1;
  for (size_t i = 0; i < c.size() && !d1; ++i)
    if ((c[i].result.significant || c[i].represents_set) && c[i].J_eff.cols() > 0) d1 = i;
  if (!d1) return std::nullopt;
  Selection det = forward_selection(c, p, *d1, chi2_0, level, opt);
  unsupported = earn_places(det, c, p, chi2_0, level, opt);
  if (det.steps.empty()) return std::nullopt;
  return det;
}

/// The output filter where the bias wanders (its candidate significant): a drift of minutes raises
/// the rest samples' lag-1 autocorrelation as a filter does, but alike at lag 2, where a filter's
/// falls (output_filter_p_given_wandering). Not supported when the fall is not significant (issue
/// #49: named beside every independent simulator's Gauss-Markov drift, lag-1 a ≈ 0.04).
UnsupportedEffect filter_beside_wandering(const Scored& filter) {
  const CandidateResult& f = filter.result;
  std::ostringstream os;
  os.precision(2);
  os << "its lag-1 autocorrelation is what the bias's wandering makes: lags 1 and 2 correlate "
        "alike (p "
     << filter.p_given_wandering << " for a filter's fall from lag 1 to lag 2)";
  return {f.name, f.magnitude, f.magnitude_sigma, f.unit, filter.p_given_wandering, os.str()};
}

/// The per-sample candidates (quantisation, the output filter, the hand's tremor), independent of
/// the segment residuals, join the selection last when significant — the filter, where the bias
/// wanders, only when its signature is more than the wandering's (filter_beside_wandering).
void join_per_sample(Selection& best, const std::vector<Scored>& c, bool wandering, double level,
                     std::vector<UnsupportedEffect>& unsupported) {
  for (EffectId id : {EffectId::kQuantisation, EffectId::kOutputFilter, EffectId::kRestTremor}) {
    const auto q = index_of(c, id);
    if (!q || !c[*q].result.significant) continue;
    if (id == EffectId::kOutputFilter && wandering && !(c[*q].p_given_wandering < level)) {
      unsupported.push_back(filter_beside_wandering(c[*q]));
      continue;
    }
    best.steps.push_back({*q, c[*q].result.p_value, std::numeric_limits<double>::quiet_NaN(), 0,
                          c[*q].result.held_out_gap});
  }
}

/// Model choice among: the stepwise set of deterministic effects (deterministic_set), an
/// undeclared Gauss-Markov bias GM, and the set followed by GM. Bias instability comes last (issue
/// #49 item 3): its per-segment offsets absorb any slow signature, so it is named alone only when
/// no deterministic effect earned a place, and after a set only when it is needed given the set and
/// the set given it (with_gauss_markov); where it could stand for a member instead, that member's
/// step says so. Its size is judged against the grade's datasheet range
/// (EffectInfo::plausible_max). A set of candidates this sequence cannot tell apart, alone, is the
/// finding as a set. Quantisation, the output filter and the hand's tremor, independent of the
/// segment residuals, join last when significant.
Selection select_model(const std::vector<Scored>& c, const Problem& p, double chi2_0,
                       double held_out_before, const DiagnosisOptions& opt) {
  Selection best;
  best.J = p.Jb;
  if (c.empty()) return best;
  const double level = opt.alpha / static_cast<double>(c.size());
  std::vector<UnsupportedEffect> unsupported;
  const std::optional<Selection> det = deterministic_set(c, p, chi2_0, level, opt, unsupported);
  const auto g = index_of(c, EffectId::kBiasInstability);
  if (det && det->steps.size() == 1 && c[det->steps[0].member].represents_set) {
    best = set_alone(c, p, det->steps[0].member);
    best.unsupported = std::move(unsupported);
    return best;
  }
  std::optional<Selection> set = det;
  const CandidateResult* r = g ? &c[*g].result : nullptr;
  // After the set, the wandering is judged given it, also when alone it was significant but of
  // implausible size: alone it takes on the set's effects too. A member whose size the wandering
  // then takes leaves the set (unsized_under_gauss_markov) and the two are judged again.
  const bool gm_candidate =
      r && (r->significant || (!r->plausible && r->separable && r->p_value < level));
  while (set && gm_candidate) {
    auto both = with_gauss_markov(c, p, *set, *g, chi2_0, level, opt);
    if (!both && r->significant && wandering_explains_the_set(p, *set, level, opt)) {
      // The two told apart: the wandering is needed given the set, the set not given it. Its
      // members the wandering makes unnecessary leave; the rest is judged with it again.
      std::vector<size_t> like = unneeded_under_gauss_markov(c, p, set->steps, level, opt);
      if (like.empty())
        for (const StepFit& f : set->steps) like.push_back(f.member);
      for (size_t m : like) {
        const CandidateResult& cr = c[m].result;
        unsupported.push_back({cr.name, cr.magnitude, cr.magnitude_sigma, cr.unit, 1.0,
                               "not significant given the bias instability, which is needed "
                               "given it: the wandering explains what it fitted"});
        set->steps.erase(std::find_if(set->steps.begin(), set->steps.end(),
                                      [&](const StepFit& f) { return f.member == m; }));
      }
      refit_steps(*set, c, p, chi2_0);
      if (set->steps.empty()) set.reset();
      continue;
    }
    if (!both) {
      if (r->significant) {
        // The bias alone would do: its members it could stand for say so (not chosen by BIC).
        const std::vector<size_t> like = unneeded_under_gauss_markov(c, p, set->steps, level, opt);
        for (StepFit& f : set->steps)
          f.like_wandering = std::find(like.begin(), like.end(), f.member) != like.end();
      }
      break;
    }
    auto weak = unsized_under_gauss_markov(c, p, *both, opt);
    if (!weak) {
      set = std::move(*both);
      break;
    }
    unsupported.push_back(std::move(weak->second));
    set->steps.erase(set->steps.begin() + static_cast<std::ptrdiff_t>(weak->first));
    refit_steps(*set, c, p, chi2_0);
    if (set->steps.empty()) set.reset();
  }
  // A set the wandering could not join (its size given the set implausible, or not needed) that is
  // no explanation by itself (it removes less than min_shrinkage of the held-out excess) while the
  // wandering alone predicts the held-out segments better: the set is what the wandering fitted
  // (a PSINS K2 + Markov-drift run: K2 alone 1650 -> 1099, the wandering -> 0.96).
  const auto shrinkage = [&](double after) {
    return held_out_before > 1.0 ? (held_out_before - after) / (held_out_before - 1.0) : 1.0;
  };
  if (set && !set->gm && r && r->significant && r->held_out_gap < set->steps.back().held_out &&
      shrinkage(set->steps.back().held_out) < opt.min_shrinkage) {
    for (const StepFit& f : set->steps) {
      const CandidateResult& cr = c[f.member].result;
      std::ostringstream os;
      os.precision(3);
      os << "the bias instability alone predicts the held-out segments better (held-out gap "
         << r->held_out_gap << " against " << set->steps.back().held_out << " with the set)";
      unsupported.push_back(
          {cr.name, cr.magnitude, cr.magnitude_sigma, cr.unit, f.p_value, os.str()});
    }
    set.reset();
  }
  if (set) {
    best = std::move(*set);
  } else if (g && c[*g].result.significant) {
    const GaussMarkovFit f = fit_gauss_markov(p.lin, p.Jb, opt.instability_tau_grid_s);
    best.gm = true;
    best.S = f.S;
    best.bic = c[*g].result.bic_gain;
    best.steps.push_back({*g, c[*g].result.p_value, f.chi2,
                          p.model.rows() - static_cast<int>(p.Jb.cols()),
                          c[*g].result.held_out_gap});
  }
  join_per_sample(best, c, best.gm || (r && r->p_value < level), level, unsupported);
  best.unsupported = std::move(unsupported);
  return best;
}

/// The selection's steps for the result: each deterministic effect's size from the joint fit
/// `fit` of the whole set (its columns in step order after the base), a noise candidate's from its
/// own fit; the gaps after each step.
std::vector<DiagnosisStep> result_steps(const Selection& sel, const std::vector<Scored>& c,
                                        const Problem& p, const GlsFit& fit,
                                        const DiagnosisOptions& opt) {
  std::vector<DiagnosisStep> out;
  Eigen::Index col = p.Jb.cols();
  for (const StepFit& f : sel.steps) {
    const Scored& sc = c[f.member];
    DiagnosisStep st;
    st.candidate = f.member;
    st.effect = sc.result.name;
    st.unit = sc.result.unit;
    st.p_value = f.p_value;
    st.gap_after = f.dof > 0 ? f.chi2 / f.dof : std::numeric_limits<double>::quiet_NaN();
    st.held_out_after = f.held_out;
    st.set = sc.set_others;
    if (f.like_wandering)
      st.note = sel.gm ? "the bias instability named with it would explain it as well: this run "
                         "cannot tell a trend of this shape from the bias's wandering"
                       : "an undeclared bias instability alone would explain it as well (not "
                         "named: not needed given this set): this run cannot tell a trend of "
                         "this shape from a wandering bias";
    const auto k = sc.J_eff.cols();
    if (k > 0 && col + k <= fit.x.size()) {
      const EffectValues v = effect_values(sc, fit.x.segment(col, k), fit.cov.block(col, col, k, k),
                                           plausible_size(sc, p, opt));
      st.params = v.params;
      st.magnitude = v.magnitude;
      st.magnitude_sigma = v.magnitude_sigma;
      if (!(v.magnitude >= 2.0 * v.magnitude_sigma)) {
        std::ostringstream os;
        os.precision(2);
        os << "present (its parameters differ from zero by more than 2 sigma, p " << f.p_value
           << ") but its size is not resolved on this run: the norm of its parameters is within 2 "
              "sigma of zero";
        st.note += (st.note.empty() ? "" : "; ") + os.str();
      }
      if (v.unresolved > 0) {
        std::ostringstream os;
        os.precision(3);
        os << "its size along the directions this run resolves: " << v.unresolved
           << " parameter direction(s) not resolved (sigma beyond the largest plausible size, "
           << plausible_size(sc, p, opt) << " " << sc.result.unit << ")";
        st.note += (st.note.empty() ? "" : "; ") + os.str();
      }
      col += k;
    } else {
      const CandidateResult& own = f.size_given_set ? *f.size_given_set : sc.result;
      st.params = own.params;
      st.magnitude = own.magnitude;
      st.magnitude_sigma = own.magnitude_sigma;
    }
    out.push_back(std::move(st));
  }
  return out;
}

/// Fill best/second/steps/ambiguous, the held-out figures, the moved parameters, the remaining gap
/// and the verdict from the selection.
void apply_selection(DiagnosisResult& d, const Selection& sel, const std::vector<Scored>& c,
                     const Problem& p, const GlsFit& fit0, const DiagnosisOptions& opt) {
  d.ambiguous = sel.ambiguous;
  const bool segment_model = sel.gm || sel.J.cols() > p.Jb.cols();
  const GlsFit fit = sel.gm ? gls_fit_cov(p.r0, sel.J, sel.S) : gls_fit(p.r0, sel.J);
  d.gap_after_best = fit.chi2 / fit.dof;
  d.steps = result_steps(sel, c, p, fit, opt);
  d.best.reset();
  d.second.reset();
  if (!sel.steps.empty()) d.best = sel.steps[0].member;
  if (sel.steps.size() > 1) d.second = sel.steps[1].member;
  if (segment_model || !sel.ambiguous.empty()) {
    d.held_out.has_after = true;
    const HeldOutGap h = sel.gm ? held_out_gap_correlated(p.r0, sel.J, sel.S, p.folds)
                                : held_out_gap(p.r0, sel.J, p.folds);
    d.held_out.gap_after = d.best ? c[*d.best].result.held_out_gap : h.ratio();
    size_t segment_members = 0;
    for (const StepFit& f : sel.steps)
      segment_members += judged_per_sample(c[f.member].result.id) ? 0 : 1;
    if (segment_members > 1) {
      d.held_out.has_pair = true;
      d.held_out.gap_after_pair = h.ratio();
    }
    d.moved = moved_params(p.lin, fit0, fit);
  } else if (d.best) {  // quantisation or the output filter alone: judged on its own statistic
    d.held_out.has_after = true;
    d.held_out.gap_before = c[*d.best].result.held_out_gap_before;
    d.held_out.gap_after = c[*d.best].result.held_out_gap;
  }
  if (d.held_out.has_after && d.held_out.gap_before > 1.0) {
    const double after = d.held_out.has_pair ? d.held_out.gap_after_pair : d.held_out.gap_after;
    d.held_out.shrinkage =
        std::clamp((d.held_out.gap_before - after) / (d.held_out.gap_before - 1.0), 0.0, 1.0);
  }
  d.remaining = remaining_gap(p, sel.J, gls_fit(p.r0, sel.J));
  const bool fits_now = chi2_survival(fit.chi2, fit.dof) >= opt.alpha;
  d.explained_by.clear();
  if (!d.best && sel.ambiguous.empty()) {
    d.verdict = d.overall_p >= opt.alpha ? "consistent" : "unexplained";
    return;
  }
  // A set this sequence cannot tell apart explains the gap as well as one named effect: it is
  // explained (by the set), not unexplained (issue #19 item 6).
  d.verdict = fits_now ? "explained" : "unexplained";
  if (!fits_now) return;
  if (!sel.ambiguous.empty()) {
    d.explained_by = sel.ambiguous;
  } else {
    for (const StepFit& f : sel.steps) {
      d.explained_by.push_back(c[f.member].result.name);
      for (const auto& o : c[f.member].set_others) d.explained_by.push_back(o);
    }
  }
}

/// What is left of a selection whose segment explanation removes too little of the held-out gap
/// (explains_enough): its per-sample members (quantisation, the output filter) that each remove
/// enough of their own statistic's held-out gap. They act on no segment residual, so the segments'
/// failure says nothing of them: a filter whose unequal lags make a skew far beyond any plausible
/// size is still the filter. Empty when the selection had no segment member (the per-sample ones
/// were then judged themselves).
Selection per_sample_findings(const Selection& sel, const std::vector<Scored>& c, const Problem& p,
                              const DiagnosisOptions& opt) {
  Selection kept;
  kept.J = p.Jb;
  const bool had_segment_member =
      std::any_of(sel.steps.begin(), sel.steps.end(),
                  [&](const StepFit& f) { return !judged_per_sample(c[f.member].result.id); });
  if (!had_segment_member || !sel.ambiguous.empty()) return kept;
  for (const StepFit& f : sel.steps) {
    const CandidateResult& r = c[f.member].result;
    if (!judged_per_sample(r.id) || !(r.held_out_gap_before > 1.0)) continue;
    const double shrink = (r.held_out_gap_before - r.held_out_gap) / (r.held_out_gap_before - 1.0);
    if (shrink >= opt.min_shrinkage) kept.steps.push_back(f);
  }
  return kept;
}

/// Whether the selected finding (best effect, pair or ambiguous set) removes enough of the held-out
/// gap's excess to count as an explanation (DiagnosisOptions::min_shrinkage). Quantisation alone is
/// judged on its own statistic's held-out gap, the same way. No finding: nothing to judge.
bool explains_enough(const DiagnosisResult& d, const DiagnosisOptions& opt) {
  if (!d.best && d.ambiguous.empty()) return true;
  if (!d.held_out.has_after) return true;
  return d.held_out.gap_before > 1.0 && d.held_out.shrinkage >= opt.min_shrinkage;
}

std::string summarise(const DiagnosisResult& d) {
  std::ostringstream os;
  os.precision(3);
  if (d.verdict == "consistent" && d.ambiguous.empty()) {
    os << "the run is consistent with the model (chi2/dof " << d.overall_gap << ", expected 1 +- "
       << d.overall_sigma << "); no candidate effect is significant";
    return os.str();
  }
  if (!d.ambiguous.empty()) {
    os << (d.verdict == "explained" ? "explained by " : "partly explained by ");
    for (size_t i = 0; i < d.ambiguous.size(); ++i)
      os << (i ? (i + 1 == d.ambiguous.size() ? " or " : ", ") : "") << d.ambiguous[i];
    os << " (equally well: this sequence cannot tell them apart); held-out gap "
       << d.held_out.gap_before << " -> " << d.held_out.gap_after;
  } else if (d.best) {
    os << (d.verdict == "explained" ? "explained by " : "partly explained by ");
    // Each effect's size from the joint fit of the whole set (the steps), in the order chosen.
    for (size_t i = 0; i < d.steps.size(); ++i) {
      const DiagnosisStep& s = d.steps[i];
      os << (i ? (i + 1 == d.steps.size() ? " and " : ", ") : "") << s.effect;
      for (const auto& o : s.set) os << " | " << o;
      os << " = " << s.magnitude << " +- " << s.magnitude_sigma << " " << s.unit;
    }
    os << "; held-out gap " << d.held_out.gap_before << " -> "
       << (d.held_out.has_pair ? d.held_out.gap_after_pair : d.held_out.gap_after);
  } else {
    os << "unexplained: chi2/dof " << d.overall_gap << " (expected 1 +- " << d.overall_sigma
       << ") and no candidate effect explains it";
    // Named in the JSON and the report (weak_candidate), not here: the summary is the station's
    // REVIEW reason, which must not suggest a cause the held-out segments do not confirm.
    if (!d.weak_candidate.empty())
      os << " (the best candidate removes " << std::lround(100.0 * d.weak_shrinkage)
         << " % of the held-out gap)";
  }
  if (d.verdict == "unexplained" && !d.remaining.empty())
    os << "; largest remaining: " << d.remaining.front().first;
  if (!d.unsupported.empty()) {
    os << "; fitted, not supported: ";
    for (size_t i = 0; i < d.unsupported.size(); ++i)
      os << (i ? ", " : "") << d.unsupported[i].effect;
  }
  return os.str();
}

/// "the 27 calibration parameters" on a table run; on a table-free run its 24 and the rests'
/// attitudes.
std::string base_text(const GapLinearisation& lin) {
  const int params = lin.param_columns();
  const int attitudes = static_cast<int>(lin.columns().size()) - params;
  std::string s = "the " + std::to_string(params) + " calibration parameters";
  if (attitudes > 0) s += " and " + std::to_string(attitudes) + " rest-attitude unknowns";
  return s;
}

/// Enough rests and residuals for the base columns, and for every requested candidate (before
/// any work).
void check_run_size(const GapModel& model, const GapLinearisation& lin,
                    const DiagnosisOptions& opt) {
  const int m = model.rows();
  const int nb = static_cast<int>(lin.Jb().cols());
  if (model.rests().size() < kMinRests)
    throw std::invalid_argument(
        "gap diagnosis: the run is too short to diagnose: it has " +
        std::to_string(model.rests().size()) + " rest period(s), a diagnosis needs at least " +
        std::to_string(kMinRests) + " (it fits on some and predicts the others)");
  if (m <= nb + kMinDofForCandidate)
    throw std::invalid_argument("gap diagnosis: the run is too short to diagnose: only " +
                                std::to_string(m) + " residuals for " + base_text(lin) +
                                " (it needs more rests and moves)");
  for (EffectId id : opt.candidates) {
    int k = 0;
    for (const auto& pi : effect_info(id).params) k += pi.shape ? 0 : 1;
    if (m - nb - k < kMinDofForCandidate)
      throw std::invalid_argument("gap diagnosis: candidate " + effect_info(id).name +
                                  ": the run is too short for its " + std::to_string(k) +
                                  " parameters (" + std::to_string(m) + " residuals for " +
                                  std::to_string(nb) + " + " + std::to_string(k) + ")");
  }
}

/// The base refit (no effect) and what it says about the run: the overall gap, the localisation,
/// the whiteness, the twin and the held-out gap.
GlsFit fit_base(DiagnosisResult& d, const DiagnosisInput& in, const Problem& p,
                const DiagnosisOptions& opt) {
  GlsFit fit0;
  try {
    fit0 = gls_fit(p.r0, p.Jb);
  } catch (const std::invalid_argument&) {
    throw std::invalid_argument(
        "gap diagnosis: the run is too short to diagnose: " + base_text(p.lin) +
        " are not all separable on its " + std::to_string(p.model.rests().size()) + " rests");
  }
  d.rows = p.model.rows();
  d.dof = fit0.dof;
  d.chi2 = fit0.chi2;
  d.overall_gap = fit0.chi2 / fit0.dof;
  d.overall_sigma = std::sqrt(2.0 / fit0.dof);
  d.overall_p = chi2_survival(fit0.chi2, fit0.dof);
  d.base = p.lin.params_after(fit0.x);
  d.base_sigma = p.lin.params_sigma(fit0.cov);
  d.segments = localise(p, fit0);
  d.innovation_residuals = p.model.innovations();
  for (int c = 0; c < p.model.components(); ++c) {
    d.components.push_back(p.model.component_name(c));
    d.component_keys.push_back(p.model.component_key(c));
  }
  // A rocking deck turns the unit during its rests: their samples say nothing of the sensor noise.
  if (p.model.innovations()) {
    d.whiteness.lag1_autocorr.fill(std::numeric_limits<double>::quiet_NaN());
    d.whiteness.lag1_z.fill(std::numeric_limits<double>::quiet_NaN());
  } else {
    d.whiteness = whiteness_stats(in.cal, p.model.rests());
  }
  compare_with_twin(d, in, p, opt);
  try {
    d.held_out.gap_before = held_out_gap(p.r0, p.Jb, p.folds).ratio();
  } catch (const std::invalid_argument&) {
    throw std::invalid_argument(
        "gap diagnosis: the run is too short to diagnose: with a fifth of its " +
        std::to_string(p.model.rests().size()) + " rests held out (to predict them), " +
        base_text(p.lin) + " are not all separable");
  }
  return fit0;
}

}  // namespace

DiagnosisResult diagnose(const DiagnosisInput& in, const ParamSet& base,
                         const DiagnosisOptions& opt) {
  const auto t0 = std::chrono::steady_clock::now();
  const GapModel model(in, opt.min_rest_samples, &base);
  const GapLinearisation lin(model, base);
  Problem p{
      model, lin, lin.r0(), lin.r0_raw(), lin.Jb(), lin.Jb_raw(), make_folds(model, opt.folds)};
  check_run_size(model, lin, opt);
  DiagnosisResult d;
  const GlsFit fit0 = fit_base(d, in, p, opt);
  std::vector<Scored> cands = score_all(p, fit0.chi2, opt);
  rank(cands, p, d.held_out.gap_before, opt);
  const Selection sel = select_model(cands, p, fit0.chi2, d.held_out.gap_before, opt);
  apply_selection(d, sel, cands, p, fit0, opt);
  if (!explains_enough(d, opt)) {
    // A significant candidate that predicts too little of the held-out gap is no finding: judge the
    // run as without one (best, pair and ambiguous set cleared, the held-out "before" kept).
    d.weak_candidate =
        d.best ? cands[*d.best].result.name : (d.ambiguous.empty() ? "" : d.ambiguous.front());
    d.weak_shrinkage = d.held_out.shrinkage;
    const double gap_before = d.held_out.gap_before;
    d.best.reset();
    d.second.reset();
    d.steps.clear();
    d.held_out = {};
    d.held_out.gap_before = gap_before;
    d.moved.clear();
    apply_selection(d, per_sample_findings(sel, cands, p, opt), cands, p, fit0, opt);
  }
  d.unsupported = sel.unsupported;
  for (auto& s : cands) d.candidates.push_back(std::move(s.result));
  d.summary = summarise(d);
  d.runtime_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return d;
}

DiagnosisOptions diagnosis_options_for_false_alarm(double per_run) {
  if (!(per_run > 0.0 && per_run < 1.0))
    throw std::invalid_argument(
        "gap diagnosis: the false-alarm rate per run must be in (0, 1), got " +
        std::to_string(per_run));
  DiagnosisOptions o;
  // The overall test at alpha and the candidates at alpha / k each (select_model): the union of the
  // two families is at most 2 alpha (Bonferroni).
  o.alpha = per_run / 2.0;
  return o;
}

}  // namespace imucal::calib::diagnosis
