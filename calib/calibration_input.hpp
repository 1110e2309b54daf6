#pragma once
// What every calibration method and the evaluation consume, and what the methods return.
// Built from a run archive (db/archive) or directly from the truth simulator; calib/ never reads
// files itself.
#include <Eigen/Core>
#include <limits>
#include <string>
#include <vector>

#include "calib/earth.hpp"
#include "calib/imu_increment.hpp"
#include "calib/param_set.hpp"
#include "calib/truth_sim.hpp"

namespace imucal::calib {

/// Reference attitude for sample k (same time axis as the IMU): the table's C_bn (without ς) or
/// the attitude log's, and whether the unit is at rest.
struct ReferenceSample {
  double t_s = 0.0;
  Eigen::Matrix3d C_bn_ref = Eigen::Matrix3d::Identity();
  bool at_rest = false;
  /// The table's encoder angles behind C_bn_ref (NaN when the reference is an attitude log): the
  /// gap diagnosis needs them for the table effects (non-orthogonality, wobble).
  double outer_rad = std::numeric_limits<double>::quiet_NaN();
  double inner_rad = std::numeric_limits<double>::quiet_NaN();
};

struct CalibrationInput {
  Site site;
  ImuSeries imu;                           ///< raw (uncompensated) increments
  std::vector<ReferenceSample> reference;  ///< same length and times as imu
  NoiseModel noise;                        ///< sensor noise spec (datasheet or unit file)
};

/// Half-open index range [begin, end) of one rest period in imu/reference.
struct RestPeriod {
  size_t begin = 0;
  size_t end = 0;
  size_t size() const { return end - begin; }
};

/// Maximal runs of at_rest samples with at least min_samples samples.
std::vector<RestPeriod> find_rest_periods(const CalibrationInput& in, size_t min_samples);

struct CalibrationResult {
  std::string method;  ///< "ains" or "nlsq"
  ParamSet params;
  ParamSet sigma;  ///< 1-σ of each parameter (sqrt of cov diagonal)
  ParamCovariance cov = ParamCovariance::Zero();
  bool converged = false;
  int iterations = 0;
  double runtime_s = 0.0;
  std::vector<std::string> warnings;
};

/// sigma from a covariance (sqrt of the diagonal, in ParamSet shape).
ParamSet sigma_from_covariance(const ParamCovariance& cov);

/// Build a CalibrationInput from a simulation (the table reference from encoder angles).
CalibrationInput input_from_simulation(const SimResult& sim, const TableGeometry& geometry,
                                       const Site& site, const NoiseModel& noise);

}  // namespace imucal::calib
