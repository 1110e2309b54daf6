#include "calib/studies/design/sequence_design.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <stdexcept>

#include "calib/checks/crlb.hpp"
#include "calib/core/run_concurrently.hpp"
#include "sequences/profile_generator.hpp"

namespace imucal::calib::studies::design {
using namespace calib::checks;
using namespace calib::core;
using namespace calib::diagnosis;

namespace {

/// A tour the search looked at, with its σ (search rate) and how far it is from the targets.
struct Candidate {
  RestTour tour;
  std::string what;
  ParamVector sigma = ParamVector::Zero();
  /// The largest ratio to its target: σ_i / target_i over the parameters and, once the effects
  /// are analysed, threshold / (factor × the reference's) over the effects the reference separates
  /// (kLostEffectRatio for one no longer separable). ≤ 1: every target met.
  double objective = std::numeric_limits<double>::infinity();
  std::string worst;  ///< the parameter or effect at the objective
  /// What the search minimises: a soft maximum of the same ratios (the sum of their 32nd powers,
  /// to the 1/32), so that a move easing several near the maximum counts even when the maximum
  /// stays. sigma_score: of the parameters alone, a lower bound of score.
  double sigma_score = std::numeric_limits<double>::infinity();
  double score = std::numeric_limits<double>::infinity();
};

constexpr double kSoftMaxPower = 32.0;

Candidate candidate(RestTour tour, std::string what) {
  Candidate c;
  c.tour = std::move(tour);
  c.what = std::move(what);
  return c;
}
constexpr double kLostEffectRatio = 10.0;
/// The tours best by σ whose effects are analysed each round (an analysis costs ~5 CRLB runs).
constexpr size_t kShortlist = 10;

std::string fmt(const char* format, double a, double b = 0.0) {
  char buf[160];
  std::snprintf(buf, sizeof buf, format, a, b);
  return buf;
}

bool is_bias(int i) {
  const ParamGroup g = param_info(i).group;
  return g == ParamGroup::kAccelBias || g == ParamGroup::kGyroBias;
}

double soft_max_term(double ratio) { return std::pow(ratio, kSoftMaxPower); }

/// Two workers over the indices 0..n-1 (the station machines have two cores).
template <typename Fn>
void for_each_on_two_threads(size_t n, Fn&& fn) {
  auto run = [&](size_t first) {
    for (size_t k = first; k < n; k += 2) fn(k);
  };
  run_concurrently([&] { run(0); }, [&] { run(1); });
}

/// The search at one table time: its targets, the effects it must keep, and its CRLB runs.
class Search {
 public:
  Search(const DesignSetting& setting, double total_s, ParamVector target,
         std::vector<EffectDetectability> effects_reference)
      : s_(setting),
        total_s_(total_s),
        target_(std::move(target)),
        effects_reference_(std::move(effects_reference)) {}

  int evaluations() const { return evaluations_; }
  std::vector<std::string>& log() { return log_; }

  sequences::MotionProfile profile(const RestTour& tour) const {
    return sequences::generate_profile(
        sequence_of(tour, total_s_, s_.limits.min_rest_s, "design", ""));
  }

  bool fits(const RestTour& tour) const {
    return minimum_time_s(tour, s_.limits.min_rest_s) <= total_s_;
  }

  /// σ and the parameters' ratios of every candidate.
  void evaluate(std::vector<Candidate>& cands) {
    for_each_on_two_threads(cands.size(), [&](size_t k) {
      Candidate& c = cands[k];
      c.sigma =
          compute_crlb(profile(c.tour), s_.geometry, s_.site, s_.noise, s_.search_rate_hz, s_.ains)
              .sigma.to_vector();
      const ParamVector ratio = c.sigma.cwiseQuotient(target_);
      Eigen::Index worst = 0;
      c.objective = ratio.maxCoeff(&worst);
      c.worst = param_info(static_cast<int>(worst)).name;
      c.sigma_score = std::pow(ratio.array().pow(kSoftMaxPower).sum(), 1.0 / kSoftMaxPower);
      c.score = c.sigma_score;
    });
    evaluations_ += static_cast<int>(cands.size());
  }

  /// Adds the effects' ratios to the candidates' objective and score.
  void analyse_effects(std::vector<Candidate>& cands) {
    if (!s_.exact_run || effects_reference_.empty()) return;
    for_each_on_two_threads(cands.size(), [&](size_t k) {
      Candidate& c = cands[k];
      const auto d = effect_detectability(s_.exact_run(profile(c.tour), s_.search_rate_hz),
                                          s_.geometry, s_.base, s_.diagnosis);
      double sum = std::pow(c.sigma_score, kSoftMaxPower);
      for (const EffectDetectability& r : effects_reference_) {
        if (!r.separable()) continue;
        const auto e =
            std::find_if(d.begin(), d.end(), [&](const auto& x) { return x.id == r.id; });
        const double ratio = e != d.end() && e->separable()
                                 ? e->threshold / (s_.threshold_factor * r.threshold)
                                 : kLostEffectRatio;
        sum += soft_max_term(std::min(ratio, kLostEffectRatio));
        if (ratio > c.objective) {
          c.objective = ratio;
          c.worst = r.name;
        }
      }
      c.score = std::pow(sum, 1.0 / kSoftMaxPower);
    });
    evaluations_ += static_cast<int>(5 * cands.size());
  }

  void say(const std::string& line) {
    if (s_.progress)
      s_.progress(fmt("T %.0f s", total_s_) + ": " + line + fmt(" (%.0f CRLB runs)", evaluations_));
  }

  /// Takes the candidate with the best score when it beats `best`: the few best by σ alone are
  /// analysed for the effects (σ alone bounds the score from below).
  bool take_better(std::vector<Candidate> cands, Candidate& best) {
    std::sort(cands.begin(), cands.end(),
              [](const Candidate& a, const Candidate& b) { return a.sigma_score < b.sigma_score; });
    size_t n = 0;
    while (n < cands.size() && n < kShortlist && cands[n].sigma_score < best.score - 1e-7) ++n;
    cands.resize(n);
    analyse_effects(cands);
    const auto it = std::min_element(
        cands.begin(), cands.end(), [](const auto& a, const auto& b) { return a.score < b.score; });
    if (it == cands.end() || !(it->score < best.score - 1e-7)) return false;
    if (it != cands.begin()) ++held_back_;
    best = *it;
    if (best.what.rfind("rest at", 0) != 0)
      log_.push_back(best.what + fmt(": max ratio to target %.4f", best.objective) + " (" +
                     best.worst + ")");
    else
      ++rest_moves_;
    return true;
  }

  int rest_moves() const { return rest_moves_; }
  int held_back() const { return held_back_; }

 private:
  const DesignSetting& s_;
  double total_s_;
  ParamVector target_;
  std::vector<EffectDetectability> effects_reference_;
  int evaluations_ = 0;
  int rest_moves_ = 0;
  int held_back_ = 0;  ///< rounds where the tour best by σ lost an effect and another was taken
  std::vector<std::string> log_;
};

/// Step 1: the reference's rate and acceleration or the table's limits.
Candidate choose_rates(Search& search, const RestTour& reference, const DesignSetting& s) {
  std::vector<Candidate> cands;
  for (double rate : {reference.rate_dps, s.limits.max_rate_dps})
    for (double accel : {reference.accel_dps2, s.limits.max_accel_dps2}) {
      Candidate c = candidate(reference, fmt("rotations at %g deg/s, %g deg/s^2", rate, accel));
      c.tour.rate_dps = std::min(rate, s.limits.max_rate_dps);
      c.tour.accel_dps2 = std::min(accel, s.limits.max_accel_dps2);
      if (search.fits(c.tour)) cands.push_back(c);
    }
  if (cands.empty())
    throw std::invalid_argument("the reference's rotations and minimum rests alone take longer");
  search.evaluate(cands);
  Candidate best;
  if (!search.take_better(cands, best)) throw std::invalid_argument("no rate gives finite sigma");
  search.say(best.what + fmt(", max ratio to target %.4f", best.objective) + " (" + best.worst +
             ")");
  return best;
}

/// Step 2: from the tour with the chosen rates, the move that helps most of: drop a rest pose,
/// add a full turn to a rotation, change a rotation by a half turn, or raise or lower one pose's
/// share of the rest by a factor; while one helps. The factor goes 1.5, 1.2, 1.07 as the moves at
/// the larger one run out.
Candidate improve_tour(Search& search, Candidate best, const sequences::TableLimits& limits) {
  constexpr int kMaxRounds = 400;
  int round = 0;
  // Sweeps of ever finer rest-share factors, again while a sweep still finds a better tour.
  for (int sweep = 0, improved = 1; improved && sweep < 3; ++sweep) {
    improved = 0;
    for (double factor : {1.5, 1.2, 1.07, 1.03}) {
      while (round++ < kMaxRounds) {
        std::vector<Candidate> cands;
        for (TourMove& m : tours_one_pose_shorter(best.tour))
          cands.push_back(candidate(std::move(m.tour), std::move(m.what)));
        for (TourMove& m : tours_one_turn_longer(best.tour, limits))
          if (search.fits(m.tour)) cands.push_back(candidate(std::move(m.tour), std::move(m.what)));
        for (TourMove& m : tours_half_turn_changed(best.tour, limits))
          if (search.fits(m.tour)) cands.push_back(candidate(std::move(m.tour), std::move(m.what)));
        for (size_t i = 0; i < best.tour.poses(); ++i)
          for (double f : {factor, 1.0 / factor}) {
            const auto p = best.tour.pose_deg(i);
            cands.push_back(
                candidate(with_rest_weight(best.tour, i, f),
                          fmt("rest at (%g, %g)", p.first, p.second) + fmt(" x%.2f", f)));
          }
        search.evaluate(cands);
        if (!search.take_better(std::move(cands), best)) break;
        ++improved;
        search.say(fmt("round %.0f: %.0f poses, ", round, static_cast<double>(best.tour.poses())) +
                   best.what + fmt(", max ratio to target %.4f", best.objective) + " (" +
                   best.worst + ")");
      }
    }
  }
  search.log().push_back(
      fmt("%.0f rounds took a tour other than the best by sigma: that one lost an effect",
          search.held_back()));
  search.log().push_back(fmt("%.0f changes of a pose's share of the rest", search.rest_moves()) +
                         fmt(": max ratio to target %.4f", best.objective) + " (" + best.worst +
                         ")");
  return best;
}

/// Step 3: the largest ratio itself down, by small changes of the rest shares, every one analysed
/// for the effects (the soft maximum of step 2 may stop just above a target that a trade between
/// the two largest ratios still reaches).
Candidate polish(Search& search, Candidate best) {
  constexpr int kMaxPolishRounds = 25;
  int taken = 0;
  for (int round = 0; round < kMaxPolishRounds && best.objective > 1.0; ++round) {
    std::vector<Candidate> cands;
    for (size_t i = 0; i < best.tour.poses(); ++i)
      for (double f : {1.1, 1.0 / 1.1, 1.03, 1.0 / 1.03})
        cands.push_back(candidate(with_rest_weight(best.tour, i, f), "polish"));
    search.evaluate(cands);
    search.analyse_effects(cands);
    const auto it = std::min_element(cands.begin(), cands.end(), [](const auto& a, const auto& b) {
      return a.objective < b.objective;
    });
    if (!(it->objective < best.objective - 1e-6)) break;
    best = *it;
    ++taken;
    search.say(fmt("polish %.0f: max ratio to target %.4f", taken, best.objective) + " (" +
               best.worst + ")");
  }
  if (taken > 0)
    search.log().push_back(
        fmt("%.0f small changes of the rest shares on the largest ratio", taken) +
        fmt(": max ratio to target %.4f", best.objective) + " (" + best.worst + ")");
  return best;
}

SequenceFigures figures(const sequences::MotionProfile& profile, const DesignSetting& s,
                        bool with_effects) {
  SequenceFigures f;
  f.duration_s = profile.duration_s();
  f.sigma = compute_crlb(profile, s.geometry, s.site, s.noise, s.rate_hz, s.ains).sigma.to_vector();
  if (with_effects && s.exact_run)
    f.effects =
        effect_detectability(s.exact_run(profile, s.rate_hz), s.geometry, s.base, s.diagnosis);
  return f;
}

ParamVector search_sigma(const sequences::Sequence& seq, const DesignSetting& s) {
  return compute_crlb(sequences::generate_profile(seq), s.geometry, s.site, s.noise,
                      s.search_rate_hz, s.ains)
      .sigma.to_vector();
}

std::vector<EffectDetectability> search_effects(const sequences::Sequence& seq,
                                                const DesignSetting& s) {
  if (!s.exact_run) return {};
  return effect_detectability(s.exact_run(sequences::generate_profile(seq), s.search_rate_hz),
                              s.geometry, s.base, s.diagnosis);
}

/// The greedy search at one time, from the reference's tour.
struct Outcome {
  Candidate best;
  int evaluations = 0;
  std::vector<std::string> log;
};

Outcome search_at(const RestTour& reference, double total_s, const ParamVector& target,
                  const std::vector<EffectDetectability>& effects_reference,
                  const DesignSetting& s) {
  Search search(s, total_s, target, effects_reference);
  Candidate best = choose_rates(search, reference, s);
  best = improve_tour(search, best, s.limits);
  best = polish(search, best);
  return {best, search.evaluations(), search.log()};
}

void check_time(double total_s, const DesignSetting& s) {
  if (!(std::isfinite(total_s) && total_s > 0.0 && total_s <= s.limits.max_duration_s))
    throw std::invalid_argument(fmt("table time %g s outside (0, %g] s (max_duration_s)", total_s,
                                    s.limits.max_duration_s));
}

SequenceDesign finish(const sequences::Sequence& reference, const RestTour& reference_tour,
                      Outcome outcome, double total_s, const ParamVector& target,
                      const DesignSetting& s) {
  SequenceDesign d;
  d.tour = outcome.best.tour;
  d.sequence = sequence_of(d.tour, total_s, s.limits.min_rest_s, reference.name + "-design", "");
  d.target = target;
  d.objective = outcome.best.objective;
  d.log = std::move(outcome.log);
  d.evaluations = outcome.evaluations;
  if (s.progress) s.progress("final figures at the IMU rate (reference, obvious cut, design)");
  d.reference = figures(sequences::generate_profile(reference), s, true);
  d.cut = figures(sequences::generate_profile(
                      sequence_of(reference_tour, total_s, s.limits.min_rest_s, "cut", "")),
                  s, false);
  d.design = figures(sequences::generate_profile(d.sequence), s, true);
  d.effects_kept = effects_lost(d.reference.effects, d.design.effects, s.threshold_factor).empty();
  d.targets_met = d.objective <= 1.0 && d.effects_kept;
  return d;
}

}  // namespace

double white_noise_floor(int i, const NoiseModel& noise, double duration_s) {
  const ParamGroup g = param_info(i).group;
  if (g == ParamGroup::kAccelBias) return noise.vrw_mps_per_sqrt_s / std::sqrt(duration_s);
  if (g == ParamGroup::kGyroBias) return noise.arw_rad_per_sqrt_s / std::sqrt(duration_s);
  return 0.0;
}

std::vector<std::string> effects_lost(const std::vector<EffectDetectability>& reference,
                                      const std::vector<EffectDetectability>& design,
                                      double threshold_factor) {
  std::vector<std::string> lost;
  for (const EffectDetectability& r : reference) {
    if (!r.separable()) continue;
    const auto d = std::find_if(design.begin(), design.end(),
                                [&](const EffectDetectability& e) { return e.id == r.id; });
    if (d == design.end() || !d->separable() || !(d->threshold <= threshold_factor * r.threshold))
      lost.push_back(r.name);
  }
  return lost;
}

SequenceDesign design_for_time(const sequences::Sequence& reference, double total_s,
                               const DesignSetting& s) {
  check_time(total_s, s);
  const RestTour reference_tour = tour_of(reference);
  if (reference_tour.legs.empty()) throw std::invalid_argument("the reference has no rotation");
  // Targets: the obvious cut's σ; the biases also at most bias_floor_factor × N/√T.
  ParamVector target =
      search_sigma(sequence_of(reference_tour, total_s, s.limits.min_rest_s, "cut", ""), s);
  for (int i = 0; i < ParamSet::kSize; ++i)
    if (is_bias(i))
      target(i) = std::min(target(i), s.bias_floor_factor * white_noise_floor(i, s.noise, total_s));
  if (s.progress) s.progress("effects of the reference (detectability)");
  Outcome o = search_at(reference_tour, total_s, target, search_effects(reference, s), s);
  return finish(reference, reference_tour, std::move(o), total_s, target, s);
}

SequenceDesign design_for_target(const sequences::Sequence& reference,
                                 const sequences::Sequence& target_seq, double factor,
                                 const DesignSetting& s) {
  if (!(std::isfinite(factor) && factor > 0.0))
    throw std::invalid_argument("the factor must be finite and > 0");
  const RestTour reference_tour = tour_of(reference);
  if (reference_tour.legs.empty()) throw std::invalid_argument("the reference has no rotation");
  const ParamVector target = factor * search_sigma(target_seq, s);
  if (s.progress) s.progress("effects of the target sequence (detectability)");
  const auto effects_reference = search_effects(target_seq, s);
  // No sequence beats N/√T: below (N / (K σ))² the biases cannot reach their targets.
  double lo_s = 2.0 * s.limits.min_rest_s;
  for (int i = 0; i < ParamSet::kSize; ++i)
    if (is_bias(i))
      lo_s = std::max(lo_s, std::pow(white_noise_floor(i, s.noise, 1.0) / target(i), 2));
  double hi_s = std::min(s.limits.max_duration_s,
                         std::ceil(sequences::generate_profile(target_seq).duration_s() /
                                   std::min(1.0, factor * factor)));
  auto feasible = [&](double t_s, Outcome& out) {
    try {
      out = search_at(reference_tour, t_s, target, effects_reference, s);
    } catch (const std::invalid_argument&) {
      return false;
    }
    return out.best.objective <= 1.0;
  };
  Outcome best;
  if (!feasible(hi_s, best)) {
    hi_s = s.limits.max_duration_s;
    if (!feasible(hi_s, best))
      throw std::invalid_argument(
          fmt("no design up to %g s (max_duration_s) reaches %g x the "
              "target's sigma",
              hi_s, factor));
  }
  lo_s = std::min(lo_s, hi_s);
  while (hi_s - lo_s > std::max(1.0, 0.01 * hi_s)) {
    const double mid_s = std::round(0.5 * (lo_s + hi_s));
    if (s.progress) s.progress(fmt("bisection: [%.0f, %.0f] s", lo_s, hi_s));
    Outcome o;
    if (feasible(mid_s, o)) {
      hi_s = mid_s;
      best = std::move(o);
    } else {
      lo_s = mid_s;
    }
  }
  return finish(target_seq, tour_of(target_seq), std::move(best), hi_s, target, s);
}

}  // namespace imucal::calib::studies::design
