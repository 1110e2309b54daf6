#include "calib/diagnosis/diagnosis_validation.hpp"

#include <algorithm>
#include <atomic>
#include <mutex>
#include <random>
#include <stdexcept>
#include <thread>

#include "calib/ains/ains.hpp"
#include "calib/core/calibration_input.hpp"
#include "calib/diagnosis/gap_fit.hpp"
#include "calib/legacy/legacy.hpp"
#include "calib/nlsq/nlsq.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::ains;
using namespace calib::core;
using namespace calib::effects;
using namespace calib::legacy;
using namespace calib::nlsq;

namespace {

constexpr double kPlausibleShare = 0.7;

struct Task {
  std::vector<EffectId> ids;
  std::vector<double> factor;
  std::vector<double> sign;
  uint64_t seed = 0;
};

std::vector<Task> make_tasks(const std::vector<EffectId>& ids,
                             const std::map<EffectId, double>& max_factor,
                             const ValidationOptions& opt) {
  std::mt19937_64 rng(opt.seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::bernoulli_distribution coin(0.5);
  std::vector<Task> tasks;
  auto draw = [&](std::vector<EffectId> which) {
    Task t;
    t.ids = std::move(which);
    for (size_t i = 0; i < t.ids.size(); ++i) {
      const double hi = max_factor.at(t.ids[i]);
      t.factor.push_back(opt.min_factor + (hi - opt.min_factor) * unit(rng));
      const bool stochastic = effect_info(t.ids[i]).kind == EffectKind::kStochastic;
      t.sign.push_back(coin(rng) || stochastic ? 1.0 : -1.0);  // a σ or an LSB has no sign
    }
    t.seed = opt.seed * 1000003ULL + tasks.size() + 1;
    tasks.push_back(std::move(t));
  };
  for (EffectId id : ids)
    for (int i = 0; i < opt.runs_per_effect; ++i) draw({id});
  for (int i = 0; i < opt.null_runs; ++i) draw({});
  // n distinct effects drawn at random (n <= ids.size()).
  auto distinct = [&](size_t n) {
    std::vector<EffectId> pool = ids, out;
    for (size_t k = 0; k < n; ++k) {
      std::uniform_int_distribution<size_t> pick(0, pool.size() - 1);
      const size_t i = pick(rng);
      out.push_back(pool[i]);
      pool.erase(pool.begin() + static_cast<std::ptrdiff_t>(i));
    }
    return out;
  };
  if (ids.size() >= 2)
    for (int i = 0; i < opt.pair_runs; ++i) draw(distinct(2));
  if (ids.size() >= 3)
    for (int i = 0; i < opt.triple_runs; ++i) draw(distinct(3));
  return tasks;
}

ValidationRun run_one(const Task& t, const std::map<EffectId, double>& threshold,
                      const RunSource& world, const TableGeometry& geometry,
                      const DiagnosisOptions& diagnosis) {
  Effects effects;
  ValidationRun r;
  r.seed = t.seed;
  for (size_t i = 0; i < t.ids.size(); ++i) {
    const EffectInfo& e = effect_info(t.ids[i]);
    set_effect_vector(effects, e.id,
                      scaled_typical(e, t.factor[i] * threshold.at(e.id), t.sign[i]));
    r.injected.push_back(e.name);
    r.factor.push_back(t.factor[i]);
  }
  DiagnosisInput in;
  in.cal = world(effects, t.seed, /*noise=*/true);
  in.geometry = geometry;
  try {
    // A table run is calibrated by NLSQ; a land run by the multi-position method, which needs no
    // prior beyond the grade's; a sea run by AINS (the multi-position method needs still rests).
    // The diagnosis refits the base parameters either way.
    const CalibrationResult cal = in.cal.setting == Setting::kSea   ? calibrate_ains(in.cal)
                                  : in.cal.has_reference_attitude() ? calibrate_nlsq(in.cal)
                                                                    : calibrate_legacy(in.cal);
    const DiagnosisResult d = diagnose(in, cal.params, diagnosis);
    r.verdict = d.verdict;
    if (d.best) {
      r.named = d.candidates[*d.best].name;
    } else if (!d.ambiguous.empty()) {
      r.named = "ambiguous:";
      for (const auto& a : d.ambiguous) r.named += " " + a;
    } else {
      r.named = "none";
    }
    if (d.second) r.second = d.candidates[*d.second].name;
    for (const auto& st : d.steps) {
      r.explained.push_back(st.effect);
      r.explained.insert(r.explained.end(), st.set.begin(), st.set.end());
    }
    r.has_shrinkage = d.held_out.has_after;
    r.shrinkage = d.held_out.shrinkage;
  } catch (const std::exception& ex) {
    r.verdict = "error";
    r.named = std::string("error: ") + ex.what();
  }
  return r;
}

bool is_noise_candidate(const std::string& name) {
  return name == "bias_instability" || name == "quantisation" || name == "output_filter" ||
         name == "rest_tremor";
}

/// A run with several effects: whether its first named effect is injected, all are named, and
/// whether a noise candidate not injected comes before an injected effect.
struct MultiScore {
  bool first_injected = false, all_named = false, noise_ahead = false;
};

MultiScore score_multi(const ValidationRun& r) {
  auto injected = [&](const std::string& n) {
    return std::find(r.injected.begin(), r.injected.end(), n) != r.injected.end();
  };
  MultiScore s;
  s.first_injected = !r.explained.empty() && injected(r.explained.front());
  s.all_named = std::all_of(r.injected.begin(), r.injected.end(), [&](const std::string& n) {
    return std::find(r.explained.begin(), r.explained.end(), n) != r.explained.end();
  });
  bool noise_seen = false;
  for (const auto& n : r.explained) {
    if (injected(n) && noise_seen) s.noise_ahead = true;
    if (!injected(n) && is_noise_candidate(n)) noise_seen = true;
  }
  return s;
}

double share(int k, int n) { return n ? static_cast<double>(k) / n : 0.0; }

void summarise(ValidationReport& rep) {
  std::vector<double> shrink;
  int single_ok = 0, null_alarm = 0, pair_ok = 0, triple_ok = 0, first_ok = 0;
  for (const auto& r : rep.runs) {
    const std::string injected = r.injected.empty()       ? "none"
                                 : r.injected.size() == 1 ? r.injected[0]
                                                          : "";
    if (r.injected.size() <= 1) rep.confusion[injected][r.named] += 1;
    if (r.injected.empty()) {
      ++rep.null_count;
      null_alarm += (r.named != "none" || r.verdict != "consistent") ? 1 : 0;
    } else if (r.injected.size() == 1) {
      ++rep.single_runs;
      if (r.named == r.injected[0]) {
        ++single_ok;
        if (r.has_shrinkage) shrink.push_back(r.shrinkage);
      }
    } else {
      const MultiScore m = score_multi(r);
      (r.injected.size() == 2 ? rep.pair_count : rep.triple_count) += 1;
      (r.injected.size() == 2 ? pair_ok : triple_ok) += m.all_named ? 1 : 0;
      first_ok += m.first_injected ? 1 : 0;
      rep.multi_noise_ahead += m.noise_ahead ? 1 : 0;
    }
  }
  rep.top1 = share(single_ok, rep.single_runs);
  rep.null_alarms = null_alarm;
  rep.false_alarm = share(null_alarm, rep.null_count);
  rep.pair_both = share(pair_ok, rep.pair_count);
  rep.triple_all = share(triple_ok, rep.triple_count);
  rep.multi_first_injected = share(first_ok, rep.pair_count + rep.triple_count);
  if (!shrink.empty()) {
    std::sort(shrink.begin(), shrink.end());
    const size_t n = shrink.size();
    rep.median_shrinkage = n % 2 ? shrink[n / 2] : 0.5 * (shrink[n / 2 - 1] + shrink[n / 2]);
  }
}

}  // namespace

Eigen::VectorXd scaled_typical(const EffectInfo& e, double magnitude, double sign) {
  Eigen::VectorXd v = Eigen::Map<const Eigen::VectorXd>(e.typical.data(), e.size());
  const double m0 = e.magnitude(v);
  if (!(m0 > 0.0)) throw std::invalid_argument("effect " + e.name + ": typical magnitude is zero");
  for (int i = 0; i < e.size(); ++i)
    if (!e.params[static_cast<size_t>(i)].shape) v(i) *= sign * magnitude / m0;
  return v;
}

ValidationReport validate_diagnosis(const RunSource& world, const TableGeometry& geometry,
                                    const ParamSet& base, const std::string& sequence,
                                    const ValidationOptions& opt) {
  ValidationReport rep;
  rep.sequence = sequence;
  const CalibrationInput exact = world(Effects{}, 1, /*noise=*/false);
  rep.detectability = effect_detectability(exact, geometry, base, opt.diagnosis);
  std::map<EffectId, double> threshold, max_factor;
  std::vector<EffectId> ids;
  const Grade grade = exact.grade;
  for (const auto& d : rep.detectability) {
    const bool wanted = opt.effects.empty() || std::find(opt.effects.begin(), opt.effects.end(),
                                                         d.id) != opt.effects.end();
    if (!wanted || !d.separable() || !std::isfinite(d.threshold)) continue;
    // A hand holds the unit only where no table does: on a table run the rests are the table's,
    // and a hand there is no test of the diagnosis (drawn beside the output filter and the
    // quantisation, it made triples no factory run has).
    if (d.id == EffectId::kRestTremor && exact.has_reference_attitude()) continue;
    // A size the diagnosis is told to call implausible is no test of it: where the sequence
    // detects an effect only near that limit (a sea run's g-sensitivity: 10× its typical size),
    // draw no higher than kPlausibleShare of it, so a fit a few σ high stays plausible too.
    const double ceiling =
        kPlausibleShare *
        plausible_limit_typical(d.id, grade, opt.diagnosis.max_plausible_typical) * d.typical /
        d.threshold;
    if (d.typical > 0.0 && ceiling < opt.min_factor) {
      rep.beyond_plausible.push_back(d.name);
      continue;
    }
    ids.push_back(d.id);
    threshold[d.id] = d.threshold;
    max_factor[d.id] = d.typical > 0.0 ? std::min(opt.max_factor, ceiling) : opt.max_factor;
    if (max_factor[d.id] < opt.max_factor) rep.factor_cap[d.name] = max_factor[d.id];
    rep.effects.push_back(d.name);
  }
  const std::vector<Task> tasks = make_tasks(ids, max_factor, opt);
  rep.runs.resize(tasks.size());
  std::atomic<size_t> next{0};
  std::mutex mu;
  int done = 0;
  auto worker = [&] {
    for (size_t i = next++; i < tasks.size(); i = next++) {
      try {
        rep.runs[i] = run_one(tasks[i], threshold, world, geometry, opt.diagnosis);
      } catch (const std::exception& ex) {  // a worker must never take the process down
        rep.runs[i].verdict = "error";
        rep.runs[i].named = std::string("error: ") + ex.what();
        rep.runs[i].seed = tasks[i].seed;
        for (EffectId id : tasks[i].ids) rep.runs[i].injected.push_back(effect_info(id).name);
        rep.runs[i].factor = tasks[i].factor;
      }
      const std::lock_guard<std::mutex> lock(mu);
      ++done;
      if (opt.on_progress) opt.on_progress(done, static_cast<int>(tasks.size()));
    }
  };
  const int n = opt.threads > 0 ? opt.threads : std::max(1u, std::thread::hardware_concurrency());
  std::vector<std::thread> pool;
  for (int i = 0; i < n; ++i) pool.emplace_back(worker);
  for (auto& t : pool) t.join();
  summarise(rep);
  return rep;
}

}  // namespace imucal::calib::diagnosis
