#pragma once
// What the blind validations of the gap diagnosis print beside their assertions: the headline
// figures and every run the diagnosis got wrong, so a failing CI log says which.
#include <cstdio>

#include "calib/diagnosis/diagnosis_validation.hpp"

namespace imucal::calib::testing {
using namespace imucal::calib::diagnosis;

inline void print_validation(const ValidationReport& r) {
  std::printf(
      "%zu effects, %d single runs, %d null, %d pairs: top-1 %.2f, false alarms %.2f, "
      "median shrinkage %.2f, pairs %.2f\n",
      r.effects.size(), r.single_runs, r.null_count, r.pair_count, r.top1, r.false_alarm,
      r.median_shrinkage, r.pair_both);
  for (const auto& run : r.runs)
    if ((run.injected.size() == 1 && run.named != run.injected[0]) ||
        (run.injected.empty() && run.named != "none"))
      std::printf("  miss: %s -> %s (%s)\n",
                  run.injected.empty() ? "none" : run.injected[0].c_str(), run.named.c_str(),
                  run.verdict.c_str());
}

}  // namespace imucal::calib::testing
