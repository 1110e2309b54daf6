#pragma once
// Monte Carlo check of honest uncertainties (the standards: error/σ ~ N(0, 1)): RMS(error/σ) per
// parameter group over many runs, printed and held to a band.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <string>

#include "calib/core/param_set.hpp"

namespace imucal::calib::testing {
using namespace imucal::calib::core;

class GroupSigmaCheck {
 public:
  /// One run's errors and σ of the first `terms` parameters.
  void add(const ParamVector& error, const ParamVector& sigma, int terms = 24) {
    for (int i = 0; i < terms; ++i) {
      const auto g = static_cast<size_t>(param_info(i).group);
      sum_z2_[g] += (error(i) / sigma(i)) * (error(i) / sigma(i));
      ++count_[g];
    }
  }
  /// Prints "<label>, RMS(error/sigma): group value ..." and expects each group in [lo, hi].
  void expect_within(const std::string& label, double lo = 0.7, double hi = 1.4) const {
    std::printf("%s, RMS(error/sigma):", label.c_str());
    for (size_t g = 0; g < kNumParamGroups; ++g) {
      if (count_[g] == 0) continue;
      const double rms = std::sqrt(sum_z2_[g] / count_[g]);
      const std::string name = group_name(static_cast<ParamGroup>(g));
      std::printf(" %s %.2f", name.c_str(), rms);
      EXPECT_GE(rms, lo) << name;
      EXPECT_LE(rms, hi) << name;
    }
    std::printf("\n");
  }

 private:
  std::array<double, kNumParamGroups> sum_z2_{};
  std::array<int, kNumParamGroups> count_{};
};

}  // namespace imucal::calib::testing
