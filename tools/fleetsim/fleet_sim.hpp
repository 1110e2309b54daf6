#pragma once
// A simulated fleet (issue #25): stations that calibrate units of one production population with
// the real simulator and the real AINS, some stations with an error of their own (a wrong surveyed
// gravity, a table out of square or wobbling, a fixture turned on its platform), every table
// levelled a little differently, and a golden unit that visits every station on its schedule. What
// the station signatures are shown on, in the benchmark (20 fleets and more) and in CI (one,
// smaller).
//
// Every run is reproducible from (fleet seed, station, unit, visit): run_input() re-creates one run
// exactly, which is how the flagged station's runs are reprocessed with a corrected setting
// without keeping 500 runs' samples in memory.
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "calib/ains/ains.hpp"
#include "calib/core/calibration_input.hpp"
#include "calib/sim/truth_sim.hpp"
#include "calib/studies/fleet/station_signature.hpp"
#include "db/history/sqlite_repository.hpp"

namespace imucal::tools::fleetsim {

struct StationSpec {
  std::string name;
  double gravity_error_mps2 = 0.0;  ///< true local gravity minus the station's surveyed value
  double nonorthogonality_rad = 0.0;
  Eigen::Vector2d wobble_rad = Eigen::Vector2d::Zero();  ///< the table's once-per-rev tilt
  /// The fixture as it sits on the platform, turned by this rotation vector (the station assumes
  /// it square): true C_bp = exp([fixture_rad ×]).
  Eigen::Vector3d fixture_rad = Eigen::Vector3d::Zero();
  Eigen::Vector3d levelling_rad = Eigen::Vector3d::Zero();  ///< the table's ς
};

struct FleetSpec {
  std::vector<StationSpec> stations;
  int units_per_station = 50;
  int golden_visits = 1;  ///< visits of the golden unit to each station (0: none)
  std::string sequence = "short";
  std::uint64_t seed = 1;
  int threads = 2;
};

/// `stations` sound stations named st-00, st-01, ..., tables levelled within ±`levelling_rad`
/// per axis (drawn from `seed`).
FleetSpec sound_fleet(int stations, double levelling_rad, std::uint64_t seed);

struct FleetRun {
  calib::studies::fleet::SignatureRun run;  ///< station, serial, run id, AINS value and σ
  std::size_t station = 0;  ///< index into FleetSpec::stations
  int unit = 0;             ///< unit index at the station; -1: the golden unit
  int visit = 0;
  calib::core::ParamVector truth =
      calib::core::ParamVector::Zero();  ///< the unit's true parameters + ς
  bool converged = false;
};

/// Every run of the fleet, calibrated (in parallel); `progress(done, total)` after each, if given.
std::vector<FleetRun> simulate_fleet(const FleetSpec& spec,
                                     const std::function<void(int, int)>& progress = {});

/// The input of one run exactly as simulate_fleet calibrated it (its station's surveyed site).
calib::core::CalibrationInput run_input(const FleetSpec& spec, std::size_t station, int unit,
                                        int visit);

/// The AINS options the fleet calibrates with.
calib::ains::AinsOptions fleet_ains_options();

/// The station errors with responses measured on the fleet's sequence.
std::vector<calib::studies::fleet::StationError> fleet_station_errors(const FleetSpec& spec);

/// The station errors the spec gave the station (gravity, non-orthogonality, the wobble's larger
/// axis, the fixture's largest axis, in that order); empty for a sound station.
std::vector<std::string> true_causes(const StationSpec& st);

/// What the signatures made of one fleet, station by station.
struct FleetOutcome {
  calib::studies::fleet::FleetSignatures signatures;
  int faulty = 0, detected = 0;  ///< stations with errors; those with every error named, no other
  int wrong_cause = 0;           ///< faulty stations with an error named that they do not have
  int sound = 0, false_alarms = 0;
};

/// The fleet's signatures (population_only: the golden unit's runs left out) and how they
/// compare with the spec's truth.
FleetOutcome assess_fleet(const FleetSpec& spec, const std::vector<FleetRun>& runs,
                          const std::vector<calib::studies::fleet::StationError>& errors,
                          const calib::studies::fleet::SignatureOptions& options,
                          bool population_only);

/// One reprocessed accelerometer scale: its error against the truth and the AINS σ of the run.
struct ReprocessedScale {
  double error = 0.0, sigma = 0.0;
  double z() const { return error / sigma; }
};

/// Reprocessing with a corrected setting: the station's own units' runs calibrated again with its
/// surveyed gravity corrected by `gravity_correction_mps2`; every run's three accelerometer scales.
std::vector<ReprocessedScale> reprocess_with_gravity(const FleetSpec& spec, std::size_t station,
                                                     double gravity_correction_mps2);

/// The fleet's runs as the stations would have stored them, into one history (`repo`, each run
/// with its station's name, sequence and a start time within the week from `t0_ms`): every run
/// calibrated by the station's pipeline (AINS, NLSQ, cross-check, limits; no gap check), done or
/// review by its verdict. Returns the run ids in job order (the station's units, then the golden
/// unit's visits, station by station).
std::vector<db::history::RunId> write_history(const FleetSpec& spec,
                                              db::history::SqliteRepository& repo,
                                              db::history::TimestampMs t0_ms);

}  // namespace imucal::tools::fleetsim
