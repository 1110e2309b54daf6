#include "calib/ains/ains_innovations.hpp"

#include "calib/ains/ains_filter.hpp"
#include "calib/core/coarse_alignment.hpp"
#include "calib/core/unit_grade.hpp"

namespace imucal::calib::ains {
using namespace calib::core;

AinsInnovations ains_innovations(const CalibrationInput& in, const ParamSet& params,
                                 const AinsOptions& opt) {
  const ains::PreparedInput pin = ains::prepare_input(in, opt);
  ains::PassConfig cfg;
  cfg.nominal = params;
  cfg.prior_mean = params.to_vector();  // sensor states θ - nominal: zero, and held there
  cfg.prior_sigma = ParamSet::from_vector(ParamVector::Zero());
  AinsInnovations out;
  if (in.setting != Setting::kFactory) {
    cfg.C_bn0 = opt.initial_C_bn
                    ? *opt.initial_C_bn
                    : coarse_align(in.imu, pin.first_rest.begin, pin.first_rest.end,
                                   ains::alignment_site(in), params, in.noise.vrw_mps_per_sqrt_s,
                                   grade_prior(in.grade).alignment_min_window_s)
                          .C_bn;
    out.C_bn0 = cfg.C_bn0;
  }
  std::vector<ains::InnovationRecord> rec;
  rec.reserve(3 * pin.num_epochs);
  cfg.innovations = &rec;
  ains::run_pass(pin, opt, cfg, nullptr);
  out.rows.reserve(rec.size());
  for (const ains::InnovationRecord& r : rec)
    out.rows.push_back({r.k, in.imu[r.k].t_s, r.kind, r.nu, r.s});
  return out;
}

}  // namespace imucal::calib::ains
