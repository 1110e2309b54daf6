#include "calib/pipeline/holding_method.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>

#include "calib/checks/held_out_check.hpp"
#include "calib/core/conventions.hpp"

namespace imucal::calib::pipeline {
using namespace calib::checks;

namespace {

/// A rest residual as a person reads it: two significant digits ("0.20 mg", "0.025 mg", "1.8 mg",
/// "12 mg").
std::string milli_g_text(double mps2) {
  const double mg = mps2 / kStandardGravity_mps2 * 1e3;
  const int decimals = mg > 0.0 && std::isfinite(mg)
                           ? std::max(0, 1 - static_cast<int>(std::floor(std::log10(mg))))
                           : 0;
  char buf[48];
  std::snprintf(buf, sizeof buf, "%.*f mg", decimals, mg);
  return buf;
}

/// A ratio to one decimal ("1.8×"), to two where one would print it equal to the limit while it
/// is not ("1.52×" against 1.5×).
std::string ratio_text(double ratio, double limit) {
  char r1[32], lim[32];
  std::snprintf(r1, sizeof r1, "%.1f", ratio);
  std::snprintf(lim, sizeof lim, "%.1f", limit);
  if (std::string(r1) == lim && ratio != limit) std::snprintf(r1, sizeof r1, "%.2f", ratio);
  return std::string(r1) + "×";
}

std::string limit_text(double limit) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g×", limit);
  return buf;
}

/// "MEMS" and "tactical" as a sentence reads them.
std::string grade_text(Grade g) { return g == Grade::kMems ? "MEMS" : grade_name(g); }

std::string reason_text(const HoldingMethod& h, const CalibrationInput& in) {
  const double ratio = h.ains_rest_rms_mps2 / h.legacy_rest_rms_mps2;
  const std::string figures =
      "AINS leaves " + milli_g_text(h.ains_rest_rms_mps2) + " over the " + std::to_string(h.rests) +
      " rests against legacy's " + milli_g_text(h.legacy_rest_rms_mps2) + " (" +
      ratio_text(ratio, h.max_ratio) + ", limit " + limit_text(h.max_ratio) + ")";
  if (h.method == Method::kAins)
    return figures +
           ": AINS holds the rests; the verdict rests on both methods and the cross-check";
  return figures + ": at " + grade_text(in.grade) +
         " grade on this recording the filter cannot hold the rests; the verdict and the active "
         "set rest on legacy";
}

}  // namespace

const char* method_name(Method m) {
  static const char* const kNames[] = {"ains", "nlsq", "legacy"};  // in Method's order
  return kNames[static_cast<int>(m)];
}

std::optional<HoldingMethod> judge_holding_method(const CalibrationInput& in,
                                                  const CalibrationResult& ains,
                                                  const CalibrationResult& legacy,
                                                  const LegacyOptions& rests_as,
                                                  const HoldingOptions& options) {
  const double limit = options.max_ains_to_legacy_rest_ratio;
  if (!(std::isfinite(limit) && limit > 0.0))
    throw std::invalid_argument("max_ains_to_legacy_rest_ratio must be positive and finite (got " +
                                std::to_string(limit) + ")");
  if (in.setting != Setting::kLand || in.grade == Grade::kNavigation) return std::nullopt;
  // The legacy fit's own rests, so both sets are judged on exactly what the fit averaged.
  HeldOutCheckOptions rests;
  rests.min_rest_samples = rests_as.min_rest_samples;
  rests.trim_s = rests_as.trim_s;
  const HeldOutCheck a = check_held_out(in, ains.params, rests);
  const HeldOutCheck l = check_held_out(in, legacy.params, rests);
  HoldingMethod h;
  h.rests = a.rests.size();
  h.ains_rest_rms_mps2 = a.rest_rms_corrected_mps2;
  h.legacy_rest_rms_mps2 = l.rest_rms_corrected_mps2;
  h.max_ratio = limit;
  // Written as a product: a legacy residual of zero (never on real data) leaves AINS holding
  // only where it is zero too.
  h.method =
      h.ains_rest_rms_mps2 > limit * h.legacy_rest_rms_mps2 ? Method::kLegacy : Method::kAins;
  h.reason = reason_text(h, in);
  return h;
}

}  // namespace imucal::calib::pipeline
