#include "calib/diagnosis/gap_linearisation.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace imucal::calib::diagnosis {
using namespace calib::core;
using namespace calib::effects;

namespace {

// Difference steps of the base parameters (flat ParamSet order): small against the parameters'
// effect on the residuals yet far above round-off; the residuals are linear in them to ~1e-6.
double base_step(int i) {
  if (i >= 12 && i < 15) return 1e-8;  // gyro bias, rad/s (0.002 °/h)
  return 1e-5;  // accel bias m/s² (1 µg), dM_a, dM_g (10 ppm), ς rad (2″)
}

}  // namespace

double effect_param_scale(const EffectInfo& e, int j) {
  const double t = std::abs(e.typical[static_cast<size_t>(j)]);
  if (t > 0.0) return t;
  double m = 0.0;
  for (int i = 0; i < e.size(); ++i)
    if (e.params[static_cast<size_t>(i)].human_unit == e.params[static_cast<size_t>(j)].human_unit)
      m = std::max(m, std::abs(e.typical[static_cast<size_t>(i)]));
  return m > 0.0 ? m : 1.0;
}

GapLinearisation::GapLinearisation(const GapModel& model, const ParamSet& base)
    : model_(model), base_(base) {
  r0_raw_ = model_.residuals(base_, Effects{});
  r0_ = model_.whiten(r0_raw_);
  // ς (the last three) is the rests' common attitude on a table-free run: not a column there.
  const int params = model_.table_free() ? ParamSet::kSize - 3 : ParamSet::kSize;
  const int attitudes = model_.attitude_unknowns();
  Jb_raw_.resize(model_.rows(), params + attitudes);
  const ParamVector x0 = base_.to_vector();
  for (int i = 0; i < params; ++i) {
    ParamVector x = x0;
    x(i) += base_step(i);
    Jb_raw_.col(i) = column(ParamSet::from_vector(x), Effects{}, base_step(i));
    columns_.push_back(i);
  }
  if (attitudes > 0) Jb_raw_.rightCols(attitudes) = model_.attitude_jacobian(base_);
  for (int u = 0; u < attitudes; ++u) columns_.push_back(-1 - u);
  Jb_ = model_.whiten(Jb_raw_);
}

std::string GapLinearisation::column_name(int c) const {
  const int j = columns_[static_cast<size_t>(c)];
  if (j >= 0) return param_info(j).name;
  static const char* axis[3] = {"north", "east", "down"};
  const int u = -1 - j;
  return "rest " + std::to_string(u / 3 + 1) + " attitude (" + axis[u % 3] + ")";
}

int GapLinearisation::param_columns() const {
  int n = 0;
  for (int j : columns_) n += j >= 0 ? 1 : 0;
  return n;
}

ParamSet GapLinearisation::params_after(const Eigen::VectorXd& x) const {
  ParamVector v = base_.to_vector();
  for (size_t c = 0; c < columns_.size(); ++c)
    if (columns_[c] >= 0) v(columns_[c]) += x(static_cast<int>(c));
  return ParamSet::from_vector(v);
}

ParamSet GapLinearisation::params_sigma(const Eigen::MatrixXd& cov) const {
  ParamVector v = ParamVector::Zero();
  for (size_t c = 0; c < columns_.size(); ++c)
    if (columns_[c] >= 0)
      v(columns_[c]) = std::sqrt(std::max(0.0, cov(static_cast<int>(c), static_cast<int>(c))));
  return ParamSet::from_vector(v);
}

Eigen::VectorXd GapLinearisation::column(const ParamSet& base, const Effects& fx,
                                         double step) const {
  return (model_.residuals(base, fx) - r0_raw_) / step;
}

CandidateColumns GapLinearisation::candidate(EffectId id, double tau_s) const {
  const EffectInfo& e = effect_info(id);
  CandidateColumns c;
  c.id = id;
  c.tau_s = tau_s;
  for (int j = 0; j < e.size(); ++j)
    if (!e.params[static_cast<size_t>(j)].shape) c.param_index.push_back(j);
  const int n = static_cast<int>(c.param_index.size());
  c.scale.resize(n);
  Eigen::MatrixXd Jraw(model_.rows(), n);
  for (int k = 0; k < n; ++k) {
    const int j = c.param_index[static_cast<size_t>(k)];
    c.scale(k) = effect_param_scale(e, j);
    Effects fx;
    Eigen::VectorXd v = effect_vector(fx, id);
    if (tau_s > 0.0) v(e.size() - 1) = tau_s;  // the shape parameter is the effect's last
    const double step = 0.1 * c.scale(k);
    v(j) = step;
    set_effect_vector(fx, id, v);
    Jraw.col(k) = column(base_, fx, step) * c.scale(k);
  }
  c.J = model_.whiten(Jraw);
  return c;
}

}  // namespace imucal::calib::diagnosis
