#pragma once
// The segment residual model of the sim-to-real gap diagnosis (DESIGN §8, issue #8).
//
// A run is cut into segments that tile it: every rest period R (the table holds still) and every
// move between two consecutive rests A -> B. Each segment yields six residuals of the real data
// against the model (calibration parameters + a hypothesis of effects), in body axes:
//   rest R:  accel  a_R = K⁻¹ f̄_R + C_bn(R)ᵀ g_n          mean compensated specific force against
//                                                          gravity where the table puts it
//            gyro   w_R = ω̄_R - C_bn(R)ᵀ ω_ie_n          mean compensated rate against Earth rate
//   move i:  gyro   ψ_i = C_bn(B)ᵀ log(C_bn(B) Ĉ_bn(B)ᵀ)  attitude propagated by the gyros from the
//                                                          table's attitude at A against B's
//            accel  v_i = C_bn(B)ᵀ Δv_n                   velocity gained over the move (the table
//                                                          does not translate: zero)
// (f̄, ω̄: the increments compensated by the error model of eq. 18/23 *and* by the hypothesised
// sensor effects; K: the Earth-rotation term of the increments' start-of-interval frame, see
// NlsqRestMean; C_bn = exp([ς×]) C_bn_table with the hypothesised table imperfections; g and ω_ie
// from the site with the hypothesised gravity and latitude errors.)
//
// Under the model the residuals are zero-mean Gaussian with a covariance that follows from the
// declared noise (ARW, VRW, quantisation): per rest VRW²/T and ARW²/T per axis; per move the
// attitude random walk ARW²T, the velocity VRW²T plus the tilt the attitude noise causes in gravity
// (|g|² ARW² T³/3 horizontally) and their correlation (ARW² T²/2 [f_n×]). Segments are independent
// (disjoint samples). So a residual vector whitened segment by segment is N(0, I) under the model:
// every departure — per segment, per sensor axis — is the gap, in units of the model's own spread.
#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "calib/core/calibration_input.hpp"
#include "calib/core/param_set.hpp"
#include "calib/core/table_model.hpp"
#include "calib/effects/catalogue.hpp"

namespace imucal::calib {

/// What the diagnosis reads: the calibration input (table angles in the reference samples for table
/// archives) and, for table archives, the table geometry (needed by the table effects).
struct DiagnosisInput {
  CalibrationInput cal;
  std::optional<TableGeometry> geometry;  ///< empty for attitude-log archives
};

struct GapSegment {
  enum class Kind { kRest, kMove };
  Kind kind = Kind::kRest;
  int number = 0;                 ///< 1-based rest number or move number
  size_t begin = 0, end = 0;      ///< samples [begin, end)
  size_t rest_a = 0, rest_b = 0;  ///< rest indices (a rest: both its own)
  double t0_s = 0.0, t1_s = 0.0;  ///< time span (IMU clock)
  /// The table attitude (or attitude log) at the segment's end, and for table archives its angles.
  double outer_deg = 0.0, inner_deg = 0.0;
  std::string label() const;  ///< "rest 3", "move 2 (rest 2 -> 3)"
};

/// Residual components per segment, in this order (rows 6s .. 6s+5 of segment s).
constexpr int kGapRowsPerSegment = 6;
/// "accel x", ..., "gyro z".
const char* gap_component_name(int c);

using Block6 = Eigen::Matrix<double, 6, 6>;

class GapModel {
 public:
  /// Cuts the run into rests (at_rest runs of at least min_rest_samples) and the moves between
  /// them. Throws std::invalid_argument naming the problem: fewer than 2 rests, non-finite noise.
  GapModel(const DiagnosisInput& in, size_t min_rest_samples = 100);

  const std::vector<GapSegment>& segments() const { return segments_; }
  int rows() const { return kGapRowsPerSegment * static_cast<int>(segments_.size()); }
  /// Whether the archive's reference carries table angles (table effects can be evaluated).
  bool has_table() const { return geometry_.has_value(); }
  double duration_s() const;
  const CalibrationInput& input() const { return in_; }
  const std::vector<RestPeriod>& rests() const { return rests_; }

  /// The residual vector (rows()) of the data against the model (base parameters + effects). Raw,
  /// SI (accel rows m/s² at rest, m/s for moves; gyro rows rad/s at rest, rad for moves).
  Eigen::VectorXd residuals(const ParamSet& base, const Effects& fx) const;
  /// The model's predicted covariance of one segment's residuals (declared noise).
  const Block6& covariance(size_t segment) const { return cov_[segment]; }
  /// Whitening per segment: L⁻¹ r with L Lᵀ the segment covariance.
  Eigen::VectorXd whiten(const Eigen::VectorXd& r) const;
  Eigen::MatrixXd whiten(const Eigen::MatrixXd& J) const;

 private:
  /// Per-rest sums of the raw increments: the rest residuals need nothing per sample.
  struct RestSums {
    Eigen::Vector3d f_mean_raw = Eigen::Vector3d::Zero();  ///< Σ dv~ / T
    Eigen::Vector3d w_mean_raw = Eigen::Vector3d::Zero();  ///< Σ dθ~ / T
    double T_s = 0.0, h1_s = 0.0, h2_s2 = 0.0;             ///< see NlsqRestMean
    double t0_s = 0.0;      ///< start of the rest's first interval, from the run's start
    size_t ref_sample = 0;  ///< the reference sample giving the rest's attitude (its middle)
  };
  void build_segments(size_t min_rest_samples);
  void build_covariances();
  Eigen::Matrix3d true_attitude(size_t sample, const ParamSet& base, const Effects& fx) const;
  void rest_residual(size_t r, const ParamSet& base, const Effects& fx, double* out) const;
  void move_residual(const GapSegment& s, const ParamSet& base, const Effects& fx,
                     double* out) const;

  const CalibrationInput& in_;
  std::optional<TableGeometry> geometry_;
  std::vector<RestPeriod> rests_;
  std::vector<RestSums> sums_;
  std::vector<GapSegment> segments_;
  std::vector<Block6> cov_;
  std::vector<Block6> whitener_;  ///< L⁻¹ per segment
  double t_first_s_ = 0.0;        ///< start of the first interval (thermal drift's t = 0)
};

}  // namespace imucal::calib
