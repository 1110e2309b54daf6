#pragma once
// Station signatures (issue #25): for one period (a week, say) of a fleet's runs, how far each
// station's units depart, in common, from the fleet's — and which station error explains it.
//
// The model (a one-way random-effects model per parameter, solved jointly for the 27 AINS
// parameters): run r of unit u at station s estimates
//     x̂_r = x_u + δ_s + e_r,   e_r ~ N(0, diag σ_r²)   (the estimator's own σ, Monte-Carlo honest)
// where x_u is the unit's true value (units differ: the spread of a production population) and δ_s
// what the station adds to every unit (δ_s ~ N(0, Ω) between sound stations, plus a station error's
// response R·e when it has one). Two kinds of evidence about δ_s - δ_fleet:
//   * units seen at one station only ("population"): the station's mean against the other
//     stations' means; each mean carries the unit spread, so its covariance is the pooled
//     within-station covariance S_W (unit spread + noise, estimated from the fleet) over the
//     number of units. A 50 µg gravity error against a population whose common accelerometer
//     scale spreads ~110 ppm is 50 ppm against 16 ppm with 50 units.
//   * units seen at two or more stations (re-calibrated elsewhere, or a golden unit on its
//     schedule): the unit's own estimates at this station against its estimates elsewhere; its
//     x_u cancels, only the runs' σ remain (~1 ppm): the sharpest signature.
// Both are combined by their information (inverse covariance). Ω (the station-to-station spread
// beyond sampling, "what part of the spread belongs to the station") is estimated by moments from
// the sound stations' departures and added to every station's covariance before a test.
//
// The test: each station error's size is fitted to the station's departure by generalised least
// squares against its response (size, σ, z); a station is flagged when the largest |z| reaches the
// threshold that keeps the false-alarm rate per station and period at `false_alarm` (Bonferroni
// over the candidates, two-sided). Once no more stations are flagged, the strongest unflagged one
// is tested again against an Ω estimated without it (two stations with the same error would
// otherwise pass for the stations' spread and hide each other). A flagged station may have more
// than one error (a table out of
// square at a site with a wrong gravity): forward selection — every other candidate is fitted
// jointly with those already named, and the strongest is named too while its |z| given them
// reaches the threshold. The responses are known to `response_tolerance` (measured: linear to
// 2 %), so what a named error of size a leaves unexplained is counted as noise of sd tolerance·a·r
// in that test; otherwise a large error's second-order remainder would name a second cause. The
// fleet's reference for a station leaves that station out, and flagged stations are left out of
// every reference and of Ω (passes until the flags settle).
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "calib/core/param_set.hpp"
#include "calib/studies/fleet/station_error.hpp"

namespace imucal::calib::studies::fleet {
using namespace calib::core;

/// One AINS result of the period, as stored (factory table runs whose every term is determined).
struct SignatureRun {
  std::string station;
  std::string serial;
  std::int64_t run_id = 0;
  ParamVector value = ParamVector::Zero();  ///< the AINS estimate, SI
  ParamVector sigma = ParamVector::Zero();  ///< its 1-σ
};

struct SignatureOptions {
  /// Family-wise false-alarm rate per station and period (all candidates together).
  double false_alarm = 1e-3;
  /// Fewest population units for a station's population evidence (fewer: only its repeat units).
  int min_units = 3;
  /// Passes of "flag, leave the flagged out of the references, refit" at most.
  int max_passes = 8;
  /// Relative accuracy of the responses (model error of a named station error, see above).
  double response_tolerance = 0.02;
  /// Station errors named on one station at most.
  int max_errors = 3;
};

/// One station error fitted to one station's departure.
struct StationFit {
  std::string effect;
  double size_si = 0.0, sigma_si = 0.0;
  double z() const { return sigma_si > 0 ? size_si / sigma_si : 0.0; }
};

struct StationSignature {
  std::string station;
  int runs = 0;                                 ///< the station's runs in the period
  int population_units = 0;                     ///< units seen only here
  int repeat_units = 0;                         ///< units also seen at another (reference) station
  ParamVector departure = ParamVector::Zero();  ///< δ_s - δ_fleet estimate, SI
  ParamVector departure_sigma = ParamVector::Zero();  ///< its σ (Ω included)
  std::vector<StationFit> fits;                       ///< every candidate alone, catalogue order
  std::optional<StationFit> alarm;                    ///< alarms.front() when flagged
  /// The errors named, in the order selected, sized jointly (empty: not flagged).
  std::vector<StationFit> alarms;
  /// Every candidate not named, each fitted jointly with the named ones (z given them, the model
  /// error of the named ones counted); empty when not flagged.
  std::vector<StationFit> fits_given_alarms;
  std::vector<std::int64_t> run_ids;  ///< the runs it touches
  bool assessed = false;              ///< false: too little evidence (no reference, no units)
  std::string why_not;                ///< when not assessed
};

struct FleetSignatures {
  std::vector<StationSignature> stations;               ///< by station name
  double z_threshold = 0.0;                             ///< |z| that flags
  ParamVector unit_spread_sd = ParamVector::Zero();     ///< sqrt(diag S_W - mean σ²): the units
  ParamVector station_spread_sd = ParamVector::Zero();  ///< sqrt(diag Ω): sound stations
  int passes = 0;
};

/// The signatures of one period's runs against `errors` (responses measured). std::invalid_argument
/// if an error has no response, or options are out of range.
FleetSignatures station_signatures(const std::vector<SignatureRun>& runs,
                                   const std::vector<StationError>& errors,
                                   const SignatureOptions& options = {});

/// The |z| a family of `candidates` two-sided tests must reach for a family-wise rate `alpha`.
double bonferroni_z(double alpha, int candidates);

}  // namespace imucal::calib::studies::fleet
