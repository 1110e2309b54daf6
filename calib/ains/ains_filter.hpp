#pragma once
// One forward pass of the AINS error-state Kalman filter and the RTS smoother over its epochs
// (ARCHITECTURE §6). Shared by calibrate_ains (iterated over passes) and compute_crlb (one
// covariance pass along the true trajectory). Internal to calib/: callers use ains.hpp/crlb.hpp.
#include <cstdint>
#include <vector>

#include "calib/ains/ains.hpp"
#include "calib/ains/ains_model.hpp"

namespace imucal::calib::ains {
using namespace calib::core;

/// The input checked once and the epoch schedule fixed once for all passes.
struct PreparedInput {
  const CalibrationInput* in = nullptr;
  size_t k0 = 0;  ///< first sample of the first rest period: INS start
  /// Per sample: 0 = no KF epoch, 1 = epoch without aiding, 2 = epoch with aiding.
  std::vector<uint8_t> schedule;
  /// Sea: per sample the index of the GNSS fix used there, -1 if none (empty otherwise).
  std::vector<int32_t> gnss_at;
  RestPeriod first_rest;  ///< the rest period the INS starts in (field: the alignment window)
  size_t num_epochs = 0;
  size_t num_rest_periods = 0;
  /// Per sample: 1 where CalibrationInput::unusable says a clipped or dropped sample is.
  std::vector<uint8_t> unusable;
};

/// Validate the input and options (std::invalid_argument with the offending field/sample) and
/// build the epoch schedule: aiding at the first sample of every rest period of at least
/// opt.min_rest_samples samples, then every opt.update_interval_s, and at its last sample.
PreparedInput prepare_input(const CalibrationInput& in, const AinsOptions& opt);

/// Field settings: the site for the coarse alignment (at sea the first fix's position).
inline Site alignment_site(const CalibrationInput& in) {
  Site site = in.site;
  if (in.setting == Setting::kSea && !in.gnss.empty()) {
    site.lat_rad = in.gnss.front().lat_rad;
    site.lon_rad = in.gnss.front().lon_rad;
  }
  return site;
}

/// What the RTS needs from one KF epoch (kept compact: ~14 kB per epoch, ~50 MB for 1 h at 1 Hz).
struct EpochRecord {
  size_t k = 0;  ///< sample index
  double t_s = 0.0;
  bool aided = false;
  NavState nominal;                 ///< nominal INS state before the feedback reset
  StateVec x_f = StateVec::Zero();  ///< filtered error state (after update, before reset)
  StateCov P_f = StateCov::Zero();  ///< its covariance (the reset does not change it)
  // Transition to the next epoch: Φ = [[Φ_nn, Φ_ns], [0, I]], Q only on the nav block, and the
  // filter's predicted state there (from the *reset* state, so the RTS stays consistent).
  NavMat Phi_nn = NavMat::Identity();
  NavSensorMat Phi_ns = NavSensorMat::Zero();
  NavMat Q = NavMat::Zero();
  StateVec x_p_next = StateVec::Zero();
};

/// One scalar aiding innovation of a pass (what ains_innovations() returns, see there).
struct InnovationRecord {
  size_t k = 0;  ///< sample index
  int kind = 0;  ///< AinsInnovation::Kind
  double nu = 0.0, s = 0.0;
};

struct PassConfig {
  ParamSet nominal;  ///< parameters the INS compensates with during this pass
  /// Field settings: the nominal attitude at the INS start and the prior mean of its error ψ(0)
  /// (the coarse alignment's attitude relative to it). Unused in the factory setting.
  Eigen::Matrix3d C_bn0 = Eigen::Matrix3d::Identity();
  Eigen::Vector3d psi0_prior_mean = Eigen::Vector3d::Zero();
  /// Land below navigation grade, every pass but the first: the attitude (b to n) whose
  /// tilt the nominal is moved onto at each epoch, one per epoch — the previous pass's smoothed
  /// attitude. The navigation states are then linearised about the last smoothed trajectory as the
  /// parameters are about the last estimate (the iterated Kalman smoother as Gauss-Newton: B. M.
  /// Bell, SIAM J. Optim. 4(3), 1994). Null: the filter's own tilt is fed back once determined.
  const std::vector<Eigen::Matrix3d>* attitude_track = nullptr;
  ParamVector prior_mean = ParamVector::Zero();  ///< prior mean of θ (ParamSet order)
  ParamSet prior_sigma;                          ///< prior 1-σ of θ (> 0; 0 holds θ fixed)
  /// When set, receives every aiding update's scalar innovation and its predicted variance.
  std::vector<InnovationRecord>* innovations = nullptr;
};

struct PassResult {
  StateVec x = StateVec::Zero();  ///< final filtered state (sensor part: θ - nominal)
  StateCov P = StateCov::Zero();
  size_t num_updates = 0;
  double nis_sum = 0.0;
  size_t nis_count = 0;
};

/// One forward pass. If `epochs` is non-null it is cleared and filled for rts_smooth.
PassResult run_pass(const PreparedInput& pin, const AinsOptions& opt, const PassConfig& cfg,
                    std::vector<EpochRecord>* epochs);

/// RTS backward pass over the epochs of run_pass. param_mismatch_sigma (optional) receives
/// max_i |x_s,θ(first) - x_f,θ(last)| / σ_i (zero for random constants in exact arithmetic).
std::vector<SmoothedNav> rts_smooth(const std::vector<EpochRecord>& epochs,
                                    double* param_mismatch_sigma);

}  // namespace imucal::calib::ains
