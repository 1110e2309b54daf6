#pragma once
// A diagnosis that names a withheld effect: the verdict "explained", the effect named first, and
// every fitted parameter within 4σ of the injected value (printed beside it). Shared by the tests
// of the table-free and sea diagnoses.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

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

}  // namespace imucal::test_support
