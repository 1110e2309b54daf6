#pragma once
// A diagnosis that names a withheld effect: the verdict "explained", the effect named first, and
// every fitted parameter within 4σ of the injected value (printed beside it). Shared by the tests
// of the table-free and sea diagnoses; and the look-ups the per-sample candidates' tests share.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "calib/diagnosis/diagnosis.hpp"

namespace imucal::test_support {

/// The finding (nullptr, with a failure recorded, when the diagnosis named none).
inline const calib::diagnosis::CandidateResult* expect_finding(
    const calib::diagnosis::DiagnosisResult& d, calib::effects::EffectId id,
    const calib::effects::Effects& injected) {
  const calib::effects::EffectInfo& e = calib::effects::effect_info(id);
  std::printf("%s: %s\n", e.name.c_str(), d.summary.c_str());
  EXPECT_TRUE(d.best) << d.summary;
  if (!d.best) return nullptr;
  const calib::diagnosis::CandidateResult& best = d.candidates[*d.best];
  EXPECT_EQ(best.name, e.name);
  EXPECT_EQ(d.verdict, "explained");
  const Eigen::VectorXd truth = calib::effects::effect_vector(injected, id);
  for (size_t j = 0; j < best.params.size(); ++j) {
    const calib::diagnosis::CandidateParam& p = best.params[j];
    const double t = truth(static_cast<int>(j)) * e.params[j].si_to_human;
    std::printf("  %s = %.4g +- %.3g (truth %.4g) %s\n", p.name.c_str(), p.value, p.sigma, t,
                p.unit.c_str());
    if (!(p.sigma > 0.0)) continue;  // a shape parameter (thermal τ) is searched on a grid
    EXPECT_LT(std::abs(p.value - t), 4.0 * p.sigma) << p.name;
  }
  return &best;
}

/// The candidate of that name (every diagnosis scores each catalogue effect).
inline const calib::diagnosis::CandidateResult& candidate(
    const calib::diagnosis::DiagnosisResult& d, const std::string& name) {
  for (const auto& c : d.candidates)
    if (c.name == name) return c;
  throw std::runtime_error("no candidate " + name);
}

/// Whether the explanation (its steps) names the effect.
inline bool named(const calib::diagnosis::DiagnosisResult& d, const std::string& name) {
  for (const auto& s : d.steps)
    if (s.effect == name) return true;
  return false;
}

/// A per-sample candidate (judged on a statistic of its own) named with its first two parameters
/// within k_sigma of the truth (human units; error/σ printed) and its own statistic's held-out gap
/// shrunk by more than half its excess.
inline void expect_per_sample_finding(const calib::diagnosis::DiagnosisResult& d,
                                      const std::string& name, double truth0, double truth1,
                                      double k_sigma, const std::string& run) {
  const calib::diagnosis::CandidateResult& c = candidate(d, name);
  EXPECT_TRUE(c.significant) << run << ": " << c.note;
  EXPECT_TRUE(named(d, name)) << run << ": " << d.summary;
  ASSERT_GE(c.params.size(), 2u);
  const double truth[2] = {truth0, truth1};
  for (size_t j = 0; j < 2; ++j) {
    const calib::diagnosis::CandidateParam& p = c.params[j];
    std::printf("  %s error/sigma %+.2f\n", p.name.c_str(), (p.value - truth[j]) / p.sigma);
    EXPECT_NEAR(p.value, truth[j], k_sigma * p.sigma) << run << " " << p.name;
  }
  EXPECT_GT((c.held_out_gap_before - c.held_out_gap) / (c.held_out_gap_before - 1.0), 0.5) << run;
}

}  // namespace imucal::test_support
