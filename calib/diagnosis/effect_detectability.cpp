#include "calib/diagnosis/effect_detectability.hpp"

#include <Eigen/QR>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <sstream>

#include "calib/core/chi2.hpp"
#include "calib/diagnosis/gap_fit.hpp"
#include "calib/diagnosis/gap_linearisation.hpp"
#include "calib/diagnosis/rest_tremor_candidate.hpp"
#include "calib/diagnosis/stochastic_candidates.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::core;
using namespace calib::effects;

namespace {

struct Analysed {
  EffectDetectability d;
  Eigen::MatrixXd J_sep;  ///< whitened columns of its separable directions
};

/// The part of the columns that the base does not explain.
Eigen::MatrixXd residualise(const Eigen::MatrixXd& Jb, const Eigen::MatrixXd& A) {
  const Eigen::HouseholderQR<Eigen::MatrixXd> qr(Jb);
  const Eigen::MatrixXd Q = qr.householderQ() * Eigen::MatrixXd::Identity(Jb.rows(), Jb.cols());
  return A - Q * (Q.transpose() * A);
}

std::vector<double> typical_pattern(const EffectInfo& e, const CandidateColumns& c) {
  std::vector<double> u;
  for (size_t k = 0; k < c.param_index.size(); ++k)
    u.push_back(e.typical[static_cast<size_t>(c.param_index[k])] / c.scale(static_cast<int>(k)));
  return u;
}

Analysed analyse(const GapLinearisation& lin, EffectId id, size_t candidates,
                 const DiagnosisOptions& opt) {
  const EffectInfo& e = effect_info(id);
  Analysed a;
  EffectDetectability& d = a.d;
  d.id = id;
  d.name = e.name;
  d.unit = e.magnitude_unit();
  d.typical = e.magnitude(Eigen::Map<const Eigen::VectorXd>(e.typical.data(), e.size()));
  const double tau = id == EffectId::kThermalDrift ? e.typical.back() : 0.0;
  const CandidateColumns c = lin.candidate(id, tau);
  d.directions = static_cast<int>(c.J.cols());
  const Separability sep =
      separability(lin.Jb(), c.J, opt.separability_limit,
                   signature_floor(effect_scale(id, lin.model().input().grade)));
  d.separable_directions = static_cast<int>(sep.basis.cols());
  d.no_signature = sep.no_signature;
  d.max_correlation = sep.max_correlation;
  for (int i : sep.aliases) d.aliases.push_back(lin.column_name(i));
  if (d.separable_directions == 0) {
    std::ostringstream os;
    if (d.no_signature == d.directions)
      os << "no signature: it changes no rest or move residual on this sequence";
    else
      os << "correlates " << correlation_text(std::max(sep.max_correlation, opt.separability_limit))
         << " > " << opt.separability_limit << " with the base parameters (" <<
          [&] {
            std::string s;
            for (const auto& n : d.aliases) s += (s.empty() ? "" : ", ") + n;
            return s;
          }()
         << ")";
    d.reason = os.str();
    return a;
  }
  a.J_sep = c.J * sep.basis;
  // λ for the typical pattern: its signature beyond the base, as far as the fitted (separable)
  // directions capture it.
  const std::vector<double> u = typical_pattern(e, c);
  const Eigen::VectorXd sig = c.J * Eigen::Map<const Eigen::VectorXd>(u.data(), d.directions);
  const Eigen::MatrixXd Rs = residualise(lin.Jb(), a.J_sep);
  const Eigen::VectorXd rs = residualise(lin.Jb(), sig);
  const Eigen::VectorXd coef = Rs.colPivHouseholderQr().solve(rs);
  const double lambda = (Rs * coef).squaredNorm();
  const int k = d.separable_directions;
  const double crit = chi2_quantile_upper(opt.alpha / static_cast<double>(candidates), k);
  if (lambda > 0.0) d.threshold = d.typical * std::sqrt((crit - k) / lambda);
  return a;
}

/// A stochastic effect: the magnitude m (× typical) at which the expected LR, k + λ(m), reaches the
/// critical value (λ monotonic in m: bisection on a log scale).
Analysed analyse_stochastic(const GapLinearisation& lin, EffectId id, size_t candidates,
                            const DiagnosisOptions& opt) {
  const EffectInfo& e = effect_info(id);
  Analysed a;
  a.d.id = id;
  a.d.name = e.name;
  a.d.unit = e.magnitude_unit();
  a.d.typical = 1.0;
  // The hand's tremor is judged on one slope (k = 1), the others on two statistics.
  const int k = id == EffectId::kRestTremor ? 1 : 2;
  a.d.directions = a.d.separable_directions = k;
  auto lambda = [&](double m) {
    if (id == EffectId::kQuantisation) return quantisation_noncentrality(lin.model(), m);
    if (id == EffectId::kOutputFilter) return output_filter_noncentrality(lin.model(), m);
    if (id == EffectId::kRestTremor) return rest_tremor_noncentrality(lin.model(), m);
    return bias_instability_noncentrality(lin, m);
  };
  const double need = chi2_quantile_upper(opt.alpha / static_cast<double>(candidates), k) - k;
  // A hand's sway on a navigation unit's long table rests shows at a millionth of its typical size.
  double lo = 1e-6, hi = 1e3;
  if (lambda(hi) < need) {
    a.d.separable_directions = 0;
    a.d.reason = "not detectable: even 1000x its typical size stays below the detection level";
    return a;
  }
  for (int i = 0; i < 60; ++i) {
    const double mid = std::sqrt(lo * hi);
    (lambda(mid) < need ? lo : hi) = mid;
  }
  a.d.threshold = std::sqrt(lo * hi);
  if (!e.magnitude_params.empty()) {
    // A magnitude in a unit of its own (output_filter: the coefficients' norm): the threshold in
    // that unit, as the validation scales the typical pattern to it.
    const Eigen::VectorXd typ = Eigen::Map<const Eigen::VectorXd>(
        e.typical.data(), static_cast<Eigen::Index>(e.typical.size()));
    a.d.typical = e.magnitude(typ);
    a.d.threshold *= a.d.typical;
  }
  return a;
}

}  // namespace

std::vector<EffectDetectability> effect_detectability(const CalibrationInput& exact_run,
                                                      const TableGeometry& geometry,
                                                      const ParamSet& base,
                                                      const DiagnosisOptions& opt) {
  DiagnosisInput in;
  in.cal = exact_run;
  in.geometry = geometry;
  const GapModel model(in, opt.min_rest_samples, &base);
  const GapLinearisation lin(model, base);
  std::vector<Analysed> all;
  const size_t n = effect_catalogue().size();
  for (const auto& e : effect_catalogue()) {
    if (const std::string why = model.not_applicable(e.id); !why.empty()) {
      Analysed a;
      a.d.id = e.id;
      a.d.name = e.name;
      a.d.unit = e.magnitude_unit();
      a.d.reason = why;
      all.push_back(a);
      continue;
    }
    if (e.kind == EffectKind::kStochastic) {
      all.push_back(analyse_stochastic(lin, e.id, n, opt));
      continue;
    }
    all.push_back(analyse(lin, e.id, n, opt));
  }
  for (size_t i = 0; i < all.size(); ++i)
    for (size_t j = i + 1; j < all.size(); ++j) {
      if (all[i].J_sep.cols() == 0 || all[j].J_sep.cols() == 0) continue;
      const double rho = canonical_correlation(lin.Jb(), all[i].J_sep, all[j].J_sep);
      all[i].d.max_cross_correlation = std::max(all[i].d.max_cross_correlation, rho);
      all[j].d.max_cross_correlation = std::max(all[j].d.max_cross_correlation, rho);
      if (rho > opt.separability_limit) {
        all[i].d.confounded_with.push_back(all[j].d.name);
        all[j].d.confounded_with.push_back(all[i].d.name);
      }
    }
  std::vector<EffectDetectability> out;
  for (auto& a : all) {
    if (!a.d.confounded_with.empty() && a.d.reason.empty()) {
      std::string s;
      for (const auto& o : a.d.confounded_with) s += (s.empty() ? "" : ", ") + o;
      std::ostringstream os;
      os << "confounded with " << s << " (signatures correlate "
         << correlation_text(a.d.max_cross_correlation) << " > " << opt.separability_limit << ")";
      a.d.reason = os.str();
    }
    out.push_back(a.d);
  }
  return out;
}

}  // namespace imucal::calib::diagnosis
