// The sea run's residuals (calib/diagnosis/gap_model.hpp, "Sea runs"): the navigation filter's
// GNSS innovations with the sensor parameters held at the hypothesis.
#include <stdexcept>

#include "calib/ains/ains_innovations.hpp"
#include "calib/diagnosis/gap_model.hpp"
#include "calib/effects/effect_compensation.hpp"
#include "calib/effects/site_errors.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::ains;
using namespace calib::core;
using namespace calib::effects;

namespace {

bool horizontal_fix(int kind) {
  return kind == AinsInnovation::kGnssNorth || kind == AinsInnovation::kGnssEast;
}

AinsOptions filter_options(size_t min_rest_samples) {
  AinsOptions opt;
  opt.min_rest_samples = min_rest_samples;
  return opt;
}

}  // namespace

void GapModel::build_innovation_rows(const ParamSet& calibrated, size_t min_rest_samples) {
  innovations_ = true;
  min_rest_samples_ = min_rest_samples;
  const AinsInnovations a = ains_innovations(in_, calibrated, filter_options(min_rest_samples));
  // Every hypothesis starts the INS where the calibration's coarse alignment put it: the
  // initial attitude error is the filter's to estimate, the same way each time.
  C_bn0_ = a.C_bn0;
  size_t j = 0;
  for (const GapSegment& seg : segments_) {
    seg_row_begin_.push_back(static_cast<int>(row_sample_.size()));
    for (; j < a.rows.size() && a.rows[j].sample_index < seg.end; ++j) {
      const AinsInnovation& r = a.rows[j];
      if (r.sample_index < seg.begin || !horizontal_fix(r.kind)) continue;
      row_source_.push_back(j);
      row_sample_.push_back(r.sample_index);
      row_kind_.push_back(r.kind == AinsInnovation::kGnssNorth ? 0 : 1);
      row_sqrt_s_.push_back(std::sqrt(r.s));
    }
  }
  seg_row_begin_.push_back(static_cast<int>(row_sample_.size()));
  if (row_sample_.empty())
    throw std::invalid_argument(
        "gap diagnosis: no GNSS fix falls within the run's rests and moves");
}

Eigen::VectorXd GapModel::innovation_residuals(const ParamSet& base, const Effects& fx) const {
  // The hypothesis: the unit's effects taken out of its increments, the site's put into the
  // Earth model (latitude comes from the fixes at sea, so only gravity matters).
  CalibrationInput in = in_;
  Effects sensor = fx;
  for (const EffectInfo& e : effect_catalogue())
    if (e.kind != EffectKind::kSensor && sensor.active(e.id))
      set_effect_vector(sensor, e.id, Eigen::VectorXd::Zero(e.size()));
  remove_sensor_effects(in.imu, sensor, base);
  if (fx.gravity_error_mps2 != 0.0) in.site = true_site(in.site, fx.gravity_error_mps2, 0.0);
  AinsOptions opt = filter_options(min_rest_samples_);
  opt.initial_C_bn = C_bn0_;
  const AinsInnovations a = ains_innovations(in, base, opt);
  Eigen::VectorXd r(rows());
  for (int i = 0; i < rows(); ++i) {
    const size_t j = row_source_[static_cast<size_t>(i)];
    if (j >= a.rows.size() || a.rows[j].sample_index != row_sample_[static_cast<size_t>(i)])
      throw std::logic_error("gap model: the filter's updates changed with the hypothesis");
    r(i) = a.rows[j].nu;
  }
  return r;
}

}  // namespace imucal::calib::diagnosis
