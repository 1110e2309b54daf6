#pragma once
// The segment residual model of the sim-to-real gap diagnosis (ARCHITECTURE §8, issue #8).
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
// (|g|² ARW² T³/3 horizontally) and their correlation (ARW² T²/2 [f_n×]); a carried rounding adds
// one LSB residue at each end (2·LSB²/12), a per-sample one its white density LSB²/(12 dt) to ARW²
// and VRW² (calib/core/noise_model.hpp). Segments are independent
// (disjoint samples). So a residual vector whitened segment by segment is N(0, I) under the model:
// every departure — per segment, per sensor axis — is the gap, in units of the model's own spread.
//
// Table-free runs (land, multi-position by hand; issue #21 item 4) have no attitude reference. The
// same residuals are formed against an attitude per rest that the model carries as unknowns: an
// estimate from the data and the calibrated parameters (levelled on each rest's specific force,
// carried across each move by the gyros, the common heading chosen by the Earth rate the rests
// see) plus a small rotation δ_R (navigation axes, rad) per rest that the diagnosis fits with the
// base parameters. What such a run observes is then what is left: the gravity magnitude and the
// Earth rate at each rest, the gravity and attitude carried by the gyros across each move, the
// zero velocity gained over it. The table misalignment ς has no meaning there (it is the rests'
// common attitude). Rests are trimmed by half a second at each end (the hand's detector edge).
//
// Sea runs (issue #21 item 4) have no still rest: the deck rocks, heaves and drifts the unit. What
// such a run observes is what the navigation filter makes of its GNSS fixes, so its residuals are
// the AINS innovations of each horizontal fix with the sensor parameters held at the hypothesis
// (calib/ains/ains_innovations.hpp): the data, less the hypothesised sensor effects, run through
// a navigation-only filter compensated by the base parameters; raw in metres, whitened by each
// innovation's predicted σ (independent N(0, 1) under the model). Segments are still the rests
// and moves the detector finds (for localising and for the held-out folds); each holds the fixes
// that fall in it, two rows per fix (north, east). The depth updates are not residuals: heave is
// a narrow-band swell that the filter takes as white noise of its RMS, so their whitened values
// are correlated over the swell's period.
#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "calib/core/calibration_input.hpp"
#include "calib/core/param_set.hpp"
#include "calib/core/rotation.hpp"
#include "calib/core/table_model.hpp"
#include "calib/effects/catalogue.hpp"

namespace imucal::calib::diagnosis {
using namespace calib::core;
using namespace calib::effects;

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

/// Residual components per segment, in this order (rows 6s .. 6s+5 of segment s); a sea run's
/// segments have components 0 and 1 only (GNSS north, east) and any number of rows.
constexpr int kGapRowsPerSegment = 6;
/// "accel x", ..., "gyro z".
const char* gap_component_name(int c);
/// "accel_x", ..., "gyro_z" (the JSON's keys).
const char* gap_component_key(int c);

using Block6 = Eigen::Matrix<double, 6, 6>;

class GapModel {
 public:
  /// Cuts the run into rests (at_rest runs of at least min_rest_samples) and the moves between
  /// them. A run without an attitude reference (land, sea) is table-free: `calibrated` (required
  /// then) gives the rests' attitude estimates, at sea the navigation filter's compensation.
  /// Throws std::invalid_argument naming the problem: fewer than 2 rests, non-finite noise, a sea
  /// run without GNSS fixes, a table-free run without `calibrated`.
  GapModel(const DiagnosisInput& in, size_t min_rest_samples = 100,
           const ParamSet* calibrated = nullptr);
  /// Throws std::invalid_argument, saying why, for a run the model cannot take whatever its data:
  /// a sea run without GNSS fixes (callers may ask before any other work).
  static void check_setting(const CalibrationInput& in);

  const std::vector<GapSegment>& segments() const { return segments_; }
  int rows() const {
    return innovations_ ? static_cast<int>(row_sample_.size())
                        : kGapRowsPerSegment * static_cast<int>(segments_.size());
  }
  /// A sea run: the residuals are the navigation filter's GNSS innovations (see the header).
  bool innovations() const { return innovations_; }
  /// Segment s's rows are [row_begin(s), row_end(s)).
  int row_begin(size_t s) const {
    return innovations_ ? seg_row_begin_[s] : kGapRowsPerSegment * static_cast<int>(s);
  }
  int row_end(size_t s) const {
    return innovations_ ? seg_row_begin_[s + 1] : kGapRowsPerSegment * static_cast<int>(s + 1);
  }
  /// The component of row i (0 .. components() - 1) and the components' names.
  int row_component(int i) const {
    return innovations_ ? row_kind_[static_cast<size_t>(i)] : i % kGapRowsPerSegment;
  }
  int components() const { return innovations_ ? 2 : kGapRowsPerSegment; }
  /// "accel x" ... "gyro z"; at sea "gnss north", "gnss east".
  const char* component_name(int c) const;
  /// "accel_x" ... "gyro_z"; at sea "gnss_north", "gnss_east" (the JSON's keys).
  const char* component_key(int c) const;
  /// Whether the archive's reference carries table angles (table effects can be evaluated).
  bool has_table() const { return geometry_.has_value(); }
  /// Why candidate `id` has no meaning on this run, or "" when it has: a table effect without
  /// table angles; at sea also the latitude (the fixes give it) and the noise candidates (judged on
  /// still rests and the segment residuals' covariance, which a rocking deck does not leave).
  std::string not_applicable(EffectId id) const;
  double duration_s() const;
  const CalibrationInput& input() const { return in_; }
  const std::vector<RestPeriod>& rests() const { return rests_; }
  /// No attitude reference: each rest's attitude is an unknown of the fit (see the header).
  bool table_free() const { return table_free_; }
  /// The rest attitudes' unknowns: 3 per rest (δ_R, navigation axes, rad), table-free runs only.
  int attitude_unknowns() const {
    return table_free_ && !innovations_ ? 3 * static_cast<int>(rests_.size()) : 0;
  }
  /// The estimate of rest r's attitude the residuals start from (the table's on table runs).
  const Eigen::Matrix3d& rest_attitude_estimate(size_t r) const { return rest_C_bn_[r]; }
  /// On a table-free move, the whitened row that alone carries the relative heading of its rests
  /// (see heading_last): no other segment predicts it, so the held-out check leaves it out.
  static constexpr int kHeadingRow = kGapRowsPerSegment - 1;
  /// The segments rest r's attitude enters: the rest itself and the moves on either side.
  std::vector<size_t> segments_of_rest(size_t r) const;

  /// The residual vector (rows()) of the data against the model (base parameters + effects). Raw,
  /// SI (accel rows m/s² at rest, m/s for moves; gyro rows rad/s at rest, rad for moves).
  Eigen::VectorXd residuals(const ParamSet& base, const Effects& fx) const;
  /// The same with the rest attitudes rotated by `dpsi_n` (attitude_unknowns() entries).
  Eigen::VectorXd residuals(const ParamSet& base, const Effects& fx,
                            const Eigen::VectorXd& dpsi_n) const;
  /// d residuals / d δ (raw, rows() × attitude_unknowns()) at δ = 0, by differences of the
  /// segments each rest's attitude enters.
  Eigen::MatrixXd attitude_jacobian(const ParamSet& base) const;
  /// One segment's six residuals (rows 6s .. 6s+5 of residuals()); dpsi_n may be null.
  void segment_residuals(size_t s, const ParamSet& base, const Effects& fx,
                         const Eigen::VectorXd* dpsi_n, double* out) const;
  /// The model's predicted covariance of one segment's residuals (declared noise; not at sea,
  /// where each row is whitened by its innovation's predicted σ).
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
  void trim_rests(size_t min_rest_samples);
  void build_covariances();  ///< (re)builds cov_ and whitener_ from the rest attitudes
  Block6 heading_last(const Block6& W, const GapSegment& s) const;
  Eigen::Matrix3d true_attitude(size_t sample, const ParamSet& base, const Effects& fx) const;
  /// Rest r's attitude under the hypothesis: the table's (with ς and the table effects), or the
  /// table-free estimate rotated by its unknowns.
  Eigen::Matrix3d rest_attitude(size_t r, const ParamSet& base, const Effects& fx,
                                const Eigen::VectorXd* dpsi_n) const;
  void rest_residual(size_t r, const ParamSet& base, const Effects& fx,
                     const Eigen::VectorXd* dpsi_n, double* out) const;
  void move_residual(const GapSegment& s, const ParamSet& base, const Effects& fx,
                     const Eigen::VectorXd* dpsi_n, double* out) const;
  /// One strapdown attitude step (conventions.hpp): C(k) = exp(-[e×]) C(k-1) exp([dθ×]), e the
  /// Earth's rotation over the interval in navigation axes.
  static Eigen::Matrix3d advance_attitude(const Eigen::Matrix3d& C, const Eigen::Vector3d& dth,
                                          const Eigen::Vector3d& e) {
    return rotvec_to_matrix<double>(Eigen::Vector3d(-e)) * C * rotvec_to_matrix<double>(dth);
  }
  /// The gyro-propagated attitude at the end of a move from `C_start` (the move residual's
  /// strapdown without effects), for the table-free estimates.
  Eigen::Matrix3d carry_attitude(const GapSegment& s, const ParamSet& calibrated,
                                 const Eigen::Matrix3d& C_start) const;
  // Sea runs (gap_model_innovations.cpp).
  void build_innovation_rows(const ParamSet& calibrated, size_t min_rest_samples);
  Eigen::VectorXd innovation_residuals(const ParamSet& base, const Effects& fx) const;
  // Table-free estimates (gap_model_attitudes.cpp).
  void estimate_rest_attitudes(const ParamSet& calibrated);
  void chain_rest_attitudes(const ParamSet& calibrated);
  void choose_common_heading(const ParamSet& calibrated);
  void refine_rest_attitudes(const ParamSet& calibrated);

  const CalibrationInput& in_;
  std::optional<TableGeometry> geometry_;
  std::vector<RestPeriod> rests_;
  std::vector<RestSums> sums_;
  std::vector<GapSegment> segments_;
  std::vector<Block6> cov_;
  std::vector<Block6> whitener_;  ///< L⁻¹ per segment
  bool table_free_ = false;
  std::vector<Eigen::Matrix3d> rest_C_bn_;  ///< per rest: the table's, or the estimate
  double t_first_s_ = 0.0;                  ///< start of the first interval (thermal drift's t = 0)
  // Sea: the kept rows (GNSS fixes inside a segment), their index among the filter's innovations,
  // sample, component (0 north, 1 east) and predicted σ; the INS start attitude held for every
  // hypothesis; segment s's rows [seg_row_begin_[s], seg_row_begin_[s + 1]).
  bool innovations_ = false;
  Eigen::Matrix3d C_bn0_ = Eigen::Matrix3d::Identity();
  size_t min_rest_samples_ = 100;
  std::vector<size_t> row_source_, row_sample_;
  std::vector<int> row_kind_, seg_row_begin_;
  std::vector<double> row_sqrt_s_;
};

}  // namespace imucal::calib::diagnosis
