#include "tools/fleetsim/fleet_sim.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <random>
#include <thread>

#include "calib/core/rotation.hpp"
#include "calib/core/site_presets.hpp"
#include "calib/pipeline/calibration_pipeline.hpp"
#include "calib/sim/sim_input.hpp"
#include "calib/sim/unit_draw.hpp"
#include "sequences/library.hpp"

namespace imucal::tools::fleetsim {

namespace {

/// One seed per (fleet, station, unit, visit), well mixed (splitmix64).
std::uint64_t mix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

std::uint64_t run_seed(const FleetSpec& spec, std::size_t station, int unit, int visit) {
  return mix(mix(mix(spec.seed) ^ station) ^ static_cast<std::uint64_t>(unit + 7)) ^
         static_cast<std::uint64_t>(visit);
}

/// The unit: one of the station's own, or the golden unit (the same at every station).
calib::effects::UnitModel unit_model(const FleetSpec& spec, std::size_t station, int unit) {
  const std::uint64_t seed =
      unit < 0 ? mix(spec.seed ^ 0x601D) : mix(mix(spec.seed) ^ (station * 100003 + 17) ^ unit);
  calib::effects::UnitModel u =
      calib::sim::draw_production_unit(calib::core::Grade::kNavigation, seed);
  u.params.table_misalignment_rad = spec.stations[station].levelling_rad;
  return u;
}

std::string serial(const FleetSpec& spec, std::size_t station, int unit) {
  if (unit < 0) return "GOLDEN-1";
  char buf[32];
  std::snprintf(buf, sizeof buf, "F%llu-S%02zu-U%03d",
                static_cast<unsigned long long>(spec.seed % 1000), station, unit);
  return buf;
}

struct Job {
  std::size_t station;
  int unit, visit;
};

std::vector<Job> jobs_of(const FleetSpec& spec) {
  std::vector<Job> jobs;
  for (std::size_t s = 0; s < spec.stations.size(); ++s) {
    for (int u = 0; u < spec.units_per_station; ++u) jobs.push_back({s, u, 0});
    for (int v = 0; v < spec.golden_visits; ++v) jobs.push_back({s, -1, v});
  }
  return jobs;
}

}  // namespace

FleetSpec sound_fleet(int stations, double levelling_rad, std::uint64_t seed) {
  FleetSpec spec;
  spec.seed = seed;
  std::mt19937_64 rng(mix(seed ^ 0x1E7E1));
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int s = 0; s < stations; ++s) {
    StationSpec st;
    char buf[16];
    std::snprintf(buf, sizeof buf, "st-%02d", s);
    st.name = buf;
    st.levelling_rad = levelling_rad * Eigen::Vector3d(u(rng), u(rng), u(rng));
    spec.stations.push_back(st);
  }
  return spec;
}

calib::ains::AinsOptions fleet_ains_options() { return calib::ains::AinsOptions{}; }

namespace {

/// One run's input on the fleet's sequence, already loaded (once per fleet, not per run).
calib::core::CalibrationInput input_of(const FleetSpec& spec,
                                       const sequences::MotionProfile& profile, std::size_t station,
                                       int unit, int visit) {
  const StationSpec& st = spec.stations.at(station);
  calib::effects::Effects fx;
  fx.gravity_error_mps2 = st.gravity_error_mps2;
  fx.table_nonorthogonality_rad = st.nonorthogonality_rad;
  fx.table_wobble_rad = st.wobble_rad;
  calib::effects::UnitModel u = unit_model(spec, station, unit);
  u.effects = fx;
  // The table as built (its fixture turned, if it is) simulates; the station's reference assumes
  // the nominal one.
  calib::core::TableGeometry as_built;
  as_built.C_bp = calib::core::rotvec_to_matrix<double>(st.fixture_rad);
  calib::sim::SimOptions so;
  so.rate_hz = 100.0;
  so.seed = run_seed(spec, station, unit, visit);
  so.noise = true;
  const calib::core::Site site = calib::core::demo_factory_site();
  return calib::sim::input_from_simulation(calib::sim::simulate(profile, as_built, site, u, so),
                                           calib::core::TableGeometry{}, site, u.noise);
}

}  // namespace

calib::core::CalibrationInput run_input(const FleetSpec& spec, std::size_t station, int unit,
                                        int visit) {
  return input_of(spec, sequences::load_profile(spec.sequence), station, unit, visit);
}

std::vector<FleetRun> simulate_fleet(const FleetSpec& spec,
                                     const std::function<void(int, int)>& progress) {
  const std::vector<Job> jobs = jobs_of(spec);
  const sequences::MotionProfile profile = sequences::load_profile(spec.sequence);
  std::vector<FleetRun> out(jobs.size());
  std::atomic<std::size_t> next{0};
  std::atomic<int> done{0};
  std::mutex progress_mutex;
  auto worker = [&] {
    for (std::size_t i = next++; i < jobs.size(); i = next++) {
      const Job& j = jobs[i];
      const calib::core::CalibrationResult r = calib::ains::calibrate_ains(
          input_of(spec, profile, j.station, j.unit, j.visit), fleet_ains_options());
      FleetRun& f = out[i];
      f.station = j.station;
      f.unit = j.unit;
      f.visit = j.visit;
      f.truth = unit_model(spec, j.station, j.unit).params.to_vector();
      f.converged = r.converged;
      f.run.station = spec.stations[j.station].name;
      f.run.serial = serial(spec, j.station, j.unit);
      f.run.run_id = static_cast<std::int64_t>(i) + 1;
      f.run.value = r.params.to_vector();
      f.run.sigma = r.sigma.to_vector();
      const int n = ++done;
      if (progress) {
        std::lock_guard<std::mutex> lock(progress_mutex);
        progress(n, static_cast<int>(jobs.size()));
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < std::max(1, spec.threads); ++t) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
  return out;
}

std::vector<calib::studies::fleet::StationError> fleet_station_errors(const FleetSpec& spec) {
  std::vector<calib::studies::fleet::StationError> errors =
      calib::studies::fleet::station_error_catalogue();
  calib::studies::fleet::measure_responses(
      errors,
      calib::sim::truth_run_source(sequences::load_profile(spec.sequence),
                                   calib::core::TableGeometry{}, calib::core::demo_factory_site(),
                                   calib::effects::default_unit(), 100.0),
      fleet_ains_options());
  return errors;
}

std::vector<std::string> true_causes(const StationSpec& st) {
  std::vector<std::string> causes;
  if (st.gravity_error_mps2 != 0) causes.push_back("gravity_error");
  if (st.nonorthogonality_rad != 0) causes.push_back("table_nonorthogonality");
  if (st.wobble_rad.squaredNorm() != 0)
    causes.push_back(std::string("table_wobble_") +
                     (std::abs(st.wobble_rad(0)) >= std::abs(st.wobble_rad(1)) ? "x" : "y"));
  if (st.fixture_rad.squaredNorm() != 0) {
    int axis = 0;
    st.fixture_rad.cwiseAbs().maxCoeff(&axis);
    causes.push_back(std::string("fixture_rotation_") + "xyz"[axis]);
  }
  return causes;
}

FleetOutcome assess_fleet(const FleetSpec& spec, const std::vector<FleetRun>& runs,
                          const std::vector<calib::studies::fleet::StationError>& errors,
                          const calib::studies::fleet::SignatureOptions& options,
                          bool population_only) {
  std::vector<calib::studies::fleet::SignatureRun> input;
  for (const FleetRun& r : runs)
    if (!population_only || r.unit >= 0) input.push_back(r.run);
  FleetOutcome o;
  o.signatures = calib::studies::fleet::station_signatures(input, errors, options);
  for (const calib::studies::fleet::StationSignature& sig : o.signatures.stations) {
    std::size_t s = 0;
    while (spec.stations[s].name != sig.station) ++s;
    const StationSpec& st = spec.stations[s];
    const std::vector<std::string> truth = true_causes(st);
    if (truth.empty()) {
      ++o.sound;
      o.false_alarms += sig.alarm ? 1 : 0;
      continue;
    }
    ++o.faulty;
    // Detected: every error named and nothing else; a wrong cause: something named that is not.
    std::vector<std::string> named;
    for (const calib::studies::fleet::StationFit& a : sig.alarms) named.push_back(a.effect);
    const auto is_true = [&](const std::string& e) {
      return std::find(truth.begin(), truth.end(), e) != truth.end();
    };
    const bool all_named = std::all_of(truth.begin(), truth.end(), [&](const std::string& e) {
      return std::find(named.begin(), named.end(), e) != named.end();
    });
    const bool only_true = std::all_of(named.begin(), named.end(), is_true);
    if (all_named && only_true) ++o.detected;
    if (!only_true) ++o.wrong_cause;
  }
  return o;
}

std::vector<ReprocessedScale> reprocess_with_gravity(const FleetSpec& spec, std::size_t station,
                                                     double gravity_correction_mps2) {
  std::vector<ReprocessedScale> out(3 * static_cast<std::size_t>(spec.units_per_station));
  const sequences::MotionProfile profile = sequences::load_profile(spec.sequence);
  std::atomic<int> next{0};
  auto worker = [&] {
    for (int u = next++; u < spec.units_per_station; u = next++) {
      calib::core::CalibrationInput in = input_of(spec, profile, station, u, 0);
      const double surveyed = in.site.gravity_mps2.value_or(
          calib::core::EarthModel::normal_gravity_mps2(in.site.lat_rad, in.site.height_m));
      in.site.gravity_mps2 = surveyed + gravity_correction_mps2;
      const calib::core::CalibrationResult r =
          calib::ains::calibrate_ains(in, fleet_ains_options());
      const calib::core::ParamSet truth = unit_model(spec, station, u).params;
      for (int i = 0; i < 3; ++i)
        out[3 * static_cast<std::size_t>(u) + static_cast<std::size_t>(i)] = {
            r.params.accel_M(i, i) - truth.accel_M(i, i), r.sigma.accel_M(i, i)};
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < std::max(1, spec.threads); ++t) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
  return out;
}

std::vector<db::history::RunId> write_history(const FleetSpec& spec,
                                              db::history::SqliteRepository& repo,
                                              db::history::TimestampMs t0_ms) {
  const std::vector<Job> jobs = jobs_of(spec);
  const sequences::MotionProfile profile = sequences::load_profile(spec.sequence);
  std::vector<calib::pipeline::PipelineResult> results(jobs.size());
  std::atomic<std::size_t> next{0};
  auto worker = [&] {
    for (std::size_t i = next++; i < jobs.size(); i = next++) {
      calib::pipeline::PipelineOptions opt;
      opt.ains = fleet_ains_options();
      results[i] = calib::pipeline::run_calibration(
          input_of(spec, profile, jobs[i].station, jobs[i].unit, jobs[i].visit), opt);
    }
  };
  std::vector<std::thread> pool;
  for (int t = 1; t < std::max(1, spec.threads); ++t) pool.emplace_back(worker);
  worker();
  for (auto& t : pool) t.join();
  constexpr db::history::TimestampMs kRunMs = 600000;  // one run every 10 minutes per station
  std::vector<db::history::RunId> ids;
  std::vector<int> at_station(spec.stations.size(), 0);
  for (std::size_t i = 0; i < jobs.size(); ++i) {
    const Job& j = jobs[i];
    db::history::NewRun run;
    run.serial = serial(spec, j.station, j.unit);
    run.operator_name = "fleetsim";
    run.station = spec.stations[j.station].name;
    run.sequence_name = spec.sequence;
    run.software_version = "fleetsim";
    run.started_at_ms = t0_ms + kRunMs * at_station[j.station]++;
    const db::history::RunId id = repo.create_run(run);
    const calib::pipeline::PipelineResult& r = results[i];
    db::history::RunCompletion done;
    done.ended_at_ms = run.started_at_ms + kRunMs - 60000;
    done.calibrations = {db::history::calibration_record(r.ains->result, &r.ains->metrics),
                         db::history::calibration_record(r.nlsq->result, &r.nlsq->metrics)};
    done.crosscheck = db::history::crosscheck_record(*r.crosscheck, 4.0);
    done.state = r.pass() ? db::history::RunState::kDone : db::history::RunState::kReview;
    if (!r.pass()) done.reasons = {{"cross-check", "cross-check or limits: not PASS"}};
    repo.finish_run(id, done);
    ids.push_back(id);
  }
  return ids;
}

}  // namespace imucal::tools::fleetsim
