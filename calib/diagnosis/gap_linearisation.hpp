#pragma once
// The gap model linearised at the calibrated point (ARCHITECTURE §8): whitened residuals r0 of the
// data against the base parameters with no effect, the whitened Jacobian of the 27 base parameters,
// and, on request, a candidate effect's columns — all by differences of the one residual model
// (calib/diagnosis/gap_model.hpp), so the diagnosis fits exactly the model the simulator injects.
// Shared by the diagnosis (a recorded run) and the detectability analysis (a sequence, noise-free).
#include <Eigen/Core>
#include <string>
#include <vector>

#include "calib/core/param_set.hpp"
#include "calib/diagnosis/gap_model.hpp"
#include "calib/effects/catalogue.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::core;
using namespace calib::effects;

/// A candidate's columns: one per non-shape parameter, in units of the parameter's scale.
struct CandidateColumns {
  EffectId id{};
  double tau_s = 0.0;            ///< shape parameter used (thermal drift), 0 if none
  std::vector<int> param_index;  ///< which effect parameter each column moves
  Eigen::VectorXd scale;         ///< SI value of one column unit (the typical size)
  Eigen::MatrixXd J;             ///< whitened
};

/// The base columns: on a table run the 27 calibration parameters; on a table-free run the 24
/// sensor parameters (ς has no meaning without a table) and the rests' attitude unknowns
/// (calib/diagnosis/gap_model.hpp) — what the diagnosis refits before any candidate.
class GapLinearisation {
 public:
  GapLinearisation(const GapModel& model, const ParamSet& base);
  const GapModel& model() const { return model_; }
  const ParamSet& base() const { return base_; }
  const Eigen::VectorXd& r0() const { return r0_; }  ///< whitened
  const Eigen::VectorXd& r0_raw() const { return r0_raw_; }
  const Eigen::MatrixXd& Jb() const { return Jb_; }  ///< whitened, rows x base columns
  const Eigen::MatrixXd& Jb_raw() const { return Jb_raw_; }
  /// What base column c moves: a ParamSet index (flat order) >= 0, or -1 - u for the rests'
  /// attitude unknown u.
  const std::vector<int>& columns() const { return columns_; }
  /// "gyro_bias[0]", "rest 4 attitude (east)".
  std::string column_name(int c) const;
  /// The calibration parameters after a step x over the base columns (attitude unknowns dropped).
  ParamSet params_after(const Eigen::VectorXd& x) const;
  /// σ of the calibration parameters from a covariance over the base columns (0 where no column).
  ParamSet params_sigma(const Eigen::MatrixXd& cov) const;
  /// The calibration parameters among the base columns.
  int param_columns() const;
  /// The candidate's columns (tau_s: the shape parameter to use, thermal drift only; 0 = none).
  CandidateColumns candidate(EffectId id, double tau_s = 0.0) const;

 private:
  Eigen::VectorXd column(const ParamSet& base, const Effects& fx, double step) const;

  const GapModel& model_;
  ParamSet base_;
  Eigen::VectorXd r0_, r0_raw_;
  Eigen::MatrixXd Jb_, Jb_raw_;
  std::vector<int> columns_;
};

/// The scale of parameter j of an effect: its typical value, or (a zero entry in the typical
/// pattern) the largest typical value among its parameters with the same unit.
double effect_param_scale(const EffectInfo& e, int j);

}  // namespace imucal::calib::diagnosis
