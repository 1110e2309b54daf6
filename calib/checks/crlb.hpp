#pragma once
// Cramér-Rao lower bound and observability of the calibration parameters for a rotation sequence
// (ARCHITECTURE §6): a covariance run of the AINS linearised model (same states, aiding, epochs and
// noise as calibrate_ains) along the *true* trajectory given by the motion profile and the table
// model. No data needed. For this linear-Gaussian model the smoother's posterior covariance is the
// Bayesian CRLB (with the AINS prior), so it is both the efficiency yardstick of the estimators and
// the tool to reject rank-deficient sequences.
#include <string>
#include <vector>

#include "calib/ains/ains.hpp"
#include "calib/core/earth.hpp"
#include "calib/core/noise_model.hpp"
#include "calib/core/param_set.hpp"
#include "calib/core/table_model.hpp"
#include "sequences/motion_profile.hpp"

namespace imucal::calib::checks {
using namespace calib::ains;
using namespace calib::core;

struct CrlbResult {
  ParamSet sigma;       ///< achievable 1-σ per parameter
  ParamCovariance cov;  ///< full posterior covariance (ParamSet flat order)
};

/// Throws std::invalid_argument for an empty profile, a non-positive rate or a profile without
/// rest periods long enough for aiding.
CrlbResult compute_crlb(const sequences::MotionProfile& profile, const TableGeometry& geometry,
                        const Site& site, const NoiseModel& noise, double rate_hz,
                        const AinsOptions& opt = {});

/// Observability thresholds on σ_post / σ_prior. A parameter the table motion excites ends at
/// 1e-4..3e-3 of its (AINS default) prior; one seen only through the Earth rate (e.g. a gyro scale
/// factor about an axis the table never turns) at 0.02..0.1; one not seen at all at ~0.7..1.
/// The table heading misalignment ς_z is the exception: only gyrocompassing observes it, limited
/// by the gyro noise (≈ 0.1-0.3 of a 1 mrad prior for a nav-grade unit) and not by the sequence,
/// so for it only the (near) absence of any information is flagged.
constexpr double kUnobservableSigmaRatio = 0.01;
constexpr double kUnobservableSigmaRatioTableHeading = 0.9;

/// Names (ParamInfo::name) of the parameters with σ_post > ratio·σ_prior (prior from
/// effective_prior_sigma(opt), ratios above), in flat order.
std::vector<std::string> unobservable_parameters(const CrlbResult& crlb,
                                                 const AinsOptions& opt = {});

/// σ_post / σ_prior per parameter (flat order), for reports and sequence design.
ParamVector crlb_prior_ratio(const CrlbResult& crlb, const AinsOptions& opt = {});

}  // namespace imucal::calib::checks
