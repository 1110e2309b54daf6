// imucal — offline calibration tool on run archives (ARCHITECTURE §5):
//   imucal simulate  --sequence FILE --out DIR [--unit FILE] [--seed N] [--setting land|sea]
//   imucal import    --file F | --gyro F --accel F --out DIR [--config TOML] ...  a raw recording
//   imucal calibrate DIR --method ains|nlsq|legacy|all [--setting factory|land|sea] [--json]
//   imucal evaluate  DIR --params FILE [--json]
//   imucal check     CALIBRATION DIR [--json]   a calibration on another recording of the unit
//   imucal apply     CALIBRATION DIR --out OUTDIR   the recording corrected by a calibration
//   imucal crlb      --sequence FILE [--unit FILE] [--json]
//   imucal design-sequence --like SEQ --time-s T | --target-from SEQ --factor K [--out F]
//   imucal bench     DIR [--repeat N] [--json]   wall time and peak memory of calibrate --method
//   all
// Exit codes: 0 success; 1 bad input or failed processing (one-line error on stderr naming the file
// and line/field); 2 usage error; 3 the result needs review (cross-check REVIEW, or a sequence that
// leaves parameters unobservable).
#include <malloc.h>
#include <sys/resource.h>
#include <unistd.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <ctime>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <optional>

#include "calib/checks/crlb.hpp"
#include "calib/core/site_presets.hpp"
#include "calib/diagnosis/false_alarm.hpp"
#include "calib/effects/effect_compensation.hpp"
#include "calib/legacy/legacy.hpp"
#include "calib/pipeline/calibration_pipeline.hpp"
#include "calib/sim/field_sim.hpp"
#include "calib/sim/hand_placement.hpp"
#include "calib/sim/truth_sim.hpp"
#include "calib/sim/unit_draw.hpp"
#include "db/archive/archive_error.hpp"
#include "db/archive/archive_input.hpp"
#include "db/archive/diagnosis_json.hpp"
#include "db/archive/param_json.hpp"
#include "db/archive/run_archive.hpp"
#include "db/archive/unit_file.hpp"
#include "sequences/library.hpp"
#include "sequences/sequence_error.hpp"
#include "tools/imucal/check_cmd.hpp"
#include "tools/imucal/design_sequence_cmd.hpp"
#include "tools/imucal/detectability_cmd.hpp"
#include "tools/imucal/diagnose_cmd.hpp"
#include "tools/imucal/effects_cmd.hpp"
#include "tools/imucal/exit_codes.hpp"
#include "tools/imucal/gap_budget_cmd.hpp"
#include "tools/imucal/import_cmd.hpp"
#include "tools/imucal/paper_tables_cmd.hpp"
#include "tools/imucal/plot.hpp"
#include "tools/imucal/report.hpp"
#include "tools/imucal/validate_cmd.hpp"

using namespace imucal;

namespace {

using tools::imucal::kExitBadInput;
using tools::imucal::kExitReview;
using tools::imucal::kExitUsage;

/// Keep freed memory in the process. Every simulated unit allocates and frees tens of megabytes
/// of samples and filter epochs; by default glibc hands blocks that large back to the kernel and
/// page-faults them in again for the next unit (18 % of a paper-tables run's time in perf, mostly
/// zero-filling fresh pages). Blocks up to 32 MB (glibc's ceiling for this) now come from the
/// heap, and the heap is not trimmed; the process keeps its peak, which it would reach anyway.
void keep_freed_memory() {
  mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024);
  mallopt(M_TRIM_THRESHOLD, 1 << 30);
}

/// --json anywhere on the command line: errors are then one JSON object on stdout too, so that a
/// script parsing the output gets an error it can read instead of a parse failure.
bool wants_json(int argc, char** argv) {
  for (int i = 1; i < argc; ++i)
    if (std::string(argv[i]) == "--json") return true;
  return false;
}

int json_error(const std::string& message, int exit_code) {
  std::cout << nlohmann::json{{"error", message}, {"exit_code", exit_code}}.dump() << '\n';
  std::fprintf(stderr, "imucal: error: %s\n", message.c_str());
  return exit_code;
}

calib::core::Site default_site() { return calib::core::demo_factory_site(); }

std::string iso_utc(std::chrono::system_clock::time_point at) {
  const auto t = std::chrono::system_clock::to_time_t(at);
  char buf[32];
  std::strftime(buf, sizeof buf, "%Y-%m-%dT%H:%M:%SZ", std::gmtime(&t));
  return buf;
}

/// Progress lines on stderr (stdout stays clean for --json), only when stderr is a terminal or
/// IMUCAL_PROGRESS=1.
void progress(const std::string& msg) {
  static const bool on = isatty(2) || std::getenv("IMUCAL_PROGRESS") != nullptr;
  static const auto t0 = std::chrono::steady_clock::now();
  if (on)
    std::fprintf(stderr, "imucal [%6.2f s] %s...\n",
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
                 msg.c_str());
}

calib::effects::UnitModel load_unit(const std::string& path) {
  return path.empty() ? calib::effects::default_unit() : db::archive::read_unit_file(path);
}

/// Reject a sequence that leaves a parameter unobservable, naming the parameters.
void require_full_rank(const calib::checks::CrlbResult& crlb, const std::string& seq_path,
                       const calib::ains::AinsOptions& opt = {},
                       bool heading_by_gyrocompass = true) {
  auto unobs = calib::checks::unobservable_parameters(crlb, opt);
  // Below navigation grade no sequence observes the fixture's heading misalignment ς_z: only
  // gyrocompassing does, and the gyros cannot resolve the Earth rate. The calibration says so.
  if (!heading_by_gyrocompass)
    unobs.erase(std::remove(unobs.begin(), unobs.end(), "table_misalignment_rad[2]"), unobs.end());
  if (unobs.empty()) return;
  std::string names;
  for (const auto& n : unobs) names += (names.empty() ? "" : ", ") + n;
  throw sequences::SequenceError(seq_path, 0, "sequence leaves parameters unobservable: " + names);
}

struct SimulateArgs {
  std::string seq = "factory-std", out_dir, unit;
  uint64_t seed = 1;
  double rate_hz = 100.0;
  bool overwrite = false;
  std::vector<std::string> effect_specs;
  std::string setting = "factory";
  double gnss_sigma_m = 0.3;
  double placement_sigma_deg = 2.0;
  /// The unit drawn from its envelope (without --unit), or the grade instead of the unit file's;
  /// empty: the unit file's, navigation without one.
  std::string grade;
};

/// `--sequence hand`: a hand-placed multi-position run (calib/sim/hand_placement.hpp), field only.
constexpr const char* kHandSequence = "hand";

/// The archive's metadata common to every setting.
db::archive::RunArchive simulated_archive(const SimulateArgs& a,
                                          const calib::effects::UnitModel& unit,
                                          const sequences::MotionProfile& profile,
                                          const std::string& seq_path,
                                          const calib::core::Site& site) {
  db::archive::RunArchive ar;
  ar.info.serial = "SIM-" + std::to_string(a.seed);
  ar.info.station_name = "imucal-sim";
  ar.info.site = site;
  ar.info.imu_rate_hz = a.rate_hz;
  ar.info.sequence_name = profile.name;
  ar.info.sequence_sha256 = seq_path.empty() ? "" : sequences::sequence_hash(seq_path);
  ar.info.grade = unit.grade;
  ar.info.software_version = IMUCAL_VERSION;
  ar.info.arw_rad_per_sqrt_s = unit.noise.arw_rad_per_sqrt_s;
  ar.info.vrw_mps_per_sqrt_s = unit.noise.vrw_mps_per_sqrt_s;
  ar.truth = db::archive::truth_from_unit(unit);
  return ar;
}

/// Land or sea: hand-placed rotations through the sequence's rest positions, no table log, at sea
/// a drifting, rocking deck and GNSS fixes (calib/sim/field_sim.hpp). No surveyed gravity.
db::archive::RunArchive simulate_field_archive(const SimulateArgs& a,
                                               const calib::effects::UnitModel& unit,
                                               const sequences::MotionProfile& profile,
                                               const std::string& seq_path) {
  calib::core::Site site = default_site();
  site.gravity_mps2.reset();
  calib::sim::FieldSimOptions fo;
  fo.setting = *calib::core::parse_setting(a.setting);
  fo.rate_hz = a.rate_hz;
  fo.seed = a.seed;
  fo.gnss_sigma_m = a.gnss_sigma_m;
  fo.placement_sigma_deg = a.placement_sigma_deg;
  calib::effects::UnitModel field_unit = unit;
  field_unit.params.table_misalignment_rad.setZero();  // no table
  progress("simulating " + a.setting + " run on " + profile.name);
  calib::sim::FieldSimResult sim = calib::sim::simulate_field(profile, site, field_unit, fo);
  db::archive::RunArchive ar = simulated_archive(a, field_unit, profile, seq_path, site);
  ar.info.setting = fo.setting;
  ar.info.reference = db::archive::ReferenceKind::kNone;
  ar.imu = std::move(sim.imu);
  ar.gnss = std::move(sim.gnss);
  return ar;
}

int cmd_simulate(const SimulateArgs& a) {
  // Refused before any simulation work.
  db::archive::check_archive_target(a.out_dir, a.overwrite,
                                    "remove it, or give --overwrite to replace it");
  const calib::core::Grade grade =
      *calib::core::parse_grade(a.grade.empty() ? "navigation" : a.grade);
  if (a.seq == kHandSequence && a.setting == "factory")
    throw std::invalid_argument(
        "--sequence hand is a hand-placed run: give --setting land or sea (a table runs a "
        "sequence file)");
  calib::effects::UnitModel unit =
      a.unit.empty() ? calib::sim::draw_unit(grade, a.seed) : load_unit(a.unit);
  if (!a.grade.empty()) unit.grade = grade;  // the command line over the unit file
  // Catalogue effects on top of the unit (checked before any work: nothing is written on error).
  for (const std::string& spec : a.effect_specs) {
    try {
      calib::effects::apply_effect_spec(unit.effects, spec);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("--effect " + spec + ": " + e.what());
    }
  }
  const bool hand = a.seq == kHandSequence;
  const std::string seq_path = hand ? "" : sequences::resolve_sequence(a.seq);
  if (!hand) progress("loading sequence " + seq_path);
  const sequences::MotionProfile profile =
      hand ? calib::sim::hand_placed_profile(a.seed) : sequences::load_profile(seq_path);
  db::archive::RunArchive ar;
  if (a.setting != "factory") {
    ar = simulate_field_archive(a, unit, profile, seq_path);
  } else {
    const calib::core::Site site = default_site();
    const calib::core::TableGeometry geometry{};
    progress("checking observability");
    // Against the prior of the unit's grade (as `crlb --grade` does): a MEMS unit's gyro terms
    // are seen to a small fraction of its wide envelope, not of a navigation unit's.
    calib::ains::AinsOptions prior;
    if (unit.grade != calib::core::Grade::kNavigation)
      prior.prior_sigma = calib::ains::prior_sigma_for_grade(unit.grade);
    require_full_rank(
        calib::checks::compute_crlb(profile, geometry, site, unit.noise, a.rate_hz, prior),
        seq_path, prior, unit.grade == calib::core::Grade::kNavigation);
    progress("simulating " + std::to_string(static_cast<int>(profile.duration_s())) + " s at " +
             std::to_string(static_cast<int>(a.rate_hz)) + " Hz");
    calib::sim::SimOptions opt;
    opt.rate_hz = a.rate_hz;
    opt.seed = a.seed;
    calib::sim::SimResult sim = calib::sim::simulate(profile, geometry, site, unit, opt);
    ar = simulated_archive(a, unit, profile, seq_path, site);
    ar.info.table = db::archive::TableSetup::from_geometry(geometry);
    ar.info.reference = db::archive::ReferenceKind::kTable;
    ar.imu = std::move(sim.imu);
    ar.table = std::move(sim.table);
  }
  // A simulated recording ends now and lasts as long as its data (an import keeps these times).
  const auto end = std::chrono::system_clock::now();
  const double span_s = db::archive::data_span_s(ar);
  ar.info.end_time = iso_utc(end);
  ar.info.start_time = iso_utc(end - std::chrono::seconds(std::llround(span_s)));
  progress("writing " + a.out_dir);
  db::archive::write_archive(a.out_dir, ar, a.overwrite);
  std::cout << "wrote " << a.out_dir << ": " << ar.imu.size() << " samples, " << ar.imu.back().t_s
            << " s, sequence " << profile.name << ", setting " << a.setting
            << (ar.gnss.empty() ? "" : ", " + std::to_string(ar.gnss.size()) + " GNSS fixes")
            << ", seed " << a.seed << '\n';
  return 0;
}

/// What `calibrate` may say about the unit instead of run.toml's [prior].
struct PriorOverride {
  std::string grade;          ///< empty: run.toml's
  double min_rest_s = 0.0;    ///< 0: run.toml's
  double first_rest_s = 0.0;  ///< 0: run.toml's
  std::string compensate;     ///< --compensate: a diagnosis JSON whose effects are removed first
};

/// --compensate FILE: the effects a diagnosis found (its best and second), read before any work.
std::optional<db::archive::DiagnosedEffects> read_compensation(const std::string& path) {
  if (path.empty()) return std::nullopt;
  std::ifstream f(path);
  if (!f) throw std::invalid_argument("--compensate " + path + ": cannot read it");
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(f);
  } catch (const nlohmann::json::parse_error& e) {
    throw std::invalid_argument("--compensate " + path + ": not JSON: " + e.what());
  }
  db::archive::DiagnosedEffects fx = db::archive::diagnosed_effects(j, "--compensate " + path);
  try {
    calib::effects::check_removable(fx.effects);
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("--compensate " + path + ": " + e.what());
  }
  return fx;
}

/// Removes the diagnosed effects from the run before the methods see it, evaluated with the
/// multi-position calibration of the run as it is (the effects act on the true rates and forces,
/// which need a calibration to be known, and that one needs no prior beyond the grade's).
void compensate(calib::core::CalibrationInput& in, const db::archive::DiagnosedEffects& fx) {
  progress("removing the diagnosed effects");
  const calib::core::CalibrationResult base = calib::legacy::calibrate_legacy(in);
  calib::effects::remove_sensor_effects(in.imu, fx.effects, base.params);
}

calib::pipeline::MethodSelection parse_method(const std::string& m) {
  if (m == "ains") return calib::pipeline::MethodSelection::kAins;
  if (m == "nlsq") return calib::pipeline::MethodSelection::kNlsq;
  if (m == "legacy") return calib::pipeline::MethodSelection::kLegacy;
  return calib::pipeline::MethodSelection::kAll;
}

/// The archive's calibration input, optionally processed as another setting: a table run "as
/// land" withholds its reference attitude (rest flags come from the IMU data, as in the field); a
/// table run "as sea" needs GNSS fixes, which a table run does not have. The samples move into the
/// input (no copy of the series next to it); `ar` keeps its info and truth.
calib::core::CalibrationInput calibration_input(db::archive::RunArchive& ar,
                                                const std::string& setting) {
  const calib::core::Setting recorded = ar.info.setting;
  if (!setting.empty()) ar.info.setting = *calib::core::parse_setting(setting);
  calib::core::CalibrationInput in = db::archive::to_calibration_input(std::move(ar));
  ar.info.setting = recorded;
  return in;
}

int cmd_calibrate(const std::string& dir, const std::string& method, bool json, double k_sigma,
                  const std::string& plot_path, const std::string& setting,
                  const PriorOverride& prior) {
  progress("reading " + dir);
  db::archive::RunArchive ar = db::archive::read_archive(dir);
  if (!prior.grade.empty()) ar.info.grade = *calib::core::parse_grade(prior.grade);
  if (prior.min_rest_s > 0.0) ar.info.min_rest_s = prior.min_rest_s;
  if (prior.first_rest_s > 0.0) ar.info.first_rest_s = prior.first_rest_s;
  const std::optional<db::archive::DiagnosedEffects> fx = read_compensation(prior.compensate);
  progress("checking the archive");
  calib::core::CalibrationInput in = calibration_input(ar, setting);
  if (fx) compensate(in, *fx);
  calib::pipeline::PipelineOptions opt;
  opt.methods = parse_method(method);
  opt.crosscheck.k_sigma = k_sigma;
  opt.on_phase = progress;
  const calib::pipeline::PipelineResult r = calib::pipeline::run_calibration(in, opt);
  if (!plot_path.empty()) {
    std::ofstream f(plot_path);
    f << tools::imucal::calibration_svg(
        r, ar.truth ? &ar.truth->params : nullptr, k_sigma,
        "run " + ar.info.serial + " (" + ar.info.sequence_name + ")");
    if (!f) throw std::runtime_error(plot_path + ": cannot write the picture");
  }
  // An archive whose capture did not complete (an aborted or interrupted run) holds a prefix of
  // the sequence: REVIEW at best, whatever the methods make of it.
  const bool partial = ar.info.capture && !ar.info.capture->complete;
  const char* partial_note =
      "archive: capture incomplete (run.toml [capture] complete = false): REVIEW at best";
  if (json) {
    nlohmann::json j = tools::imucal::pipeline_to_json(r);
    j["partial_archive"] = partial;
    if (fx) j["compensated"] = {{"file", prior.compensate}, {"effects", fx->names}};
    if (partial) j["verdict"] = "REVIEW";
    std::cout << j.dump(2) << '\n';
  } else {
    // An imported recording has no sequence: no empty clause for it (issue #50 item 5).
    std::cout << "run " << dir << " (serial " << ar.info.serial
              << (ar.info.sequence_name.empty() ? "" : ", sequence " + ar.info.sequence_name)
              << ", setting " << calib::core::setting_name(in.setting) << ", " << in.imu.size()
              << " samples)\n";
    if (fx) {
      std::cout << "compensated before calibrating (from " << prior.compensate << "):";
      for (const std::string& n : fx->names) std::cout << ' ' << n << ';';
      std::cout << '\n';
    }
    tools::imucal::print_parameter_table(std::cout, r, ar.truth ? &ar.truth->params : nullptr);
    tools::imucal::print_metrics_and_verdict(std::cout, r);
    if (partial) std::cout << partial_note << '\n';
  }
  return r.pass() && !partial ? 0 : kExitReview;
}

int cmd_evaluate(const std::string& dir, const std::string& params_path, bool json) {
  const calib::core::CalibrationInput in =
      db::archive::to_calibration_input(db::archive::read_archive(dir));
  const calib::core::ParamSet params = db::archive::read_param_file(params_path);
  const calib::checks::EvaluationMetrics m = calib::checks::evaluate(in, params);
  if (json)
    std::cout << tools::imucal::metrics_to_json(m).dump(2) << '\n';
  else
    tools::imucal::print_evaluation(std::cout, m);
  return 0;
}

int cmd_crlb(const std::string& seq, const std::string& unit_path, double rate_hz,
             const std::string& grade_name, bool json) {
  const std::string seq_path = sequences::resolve_sequence(seq);
  const sequences::MotionProfile profile = sequences::load_profile(seq_path);
  calib::effects::UnitModel unit = load_unit(unit_path);
  // --grade: the prior of such a unit (the filter's initial covariance) and, without --unit, the
  // noise of the class's worst (issue #21).
  calib::ains::AinsOptions opt;
  if (!grade_name.empty()) {
    const calib::core::Grade grade = *calib::core::parse_grade(grade_name);
    opt.prior_sigma = calib::ains::prior_sigma_for_grade(grade);
    if (unit_path.empty()) {
      unit.noise.arw_rad_per_sqrt_s = calib::core::grade_prior(grade).arw_rad_per_sqrt_s;
      unit.noise.vrw_mps_per_sqrt_s = calib::core::grade_prior(grade).vrw_mps_per_sqrt_s;
    }
  }
  progress("covariance analysis of " + profile.name);
  const calib::checks::CrlbResult crlb = calib::checks::compute_crlb(
      profile, calib::core::TableGeometry{}, default_site(), unit.noise, rate_hz, opt);
  const auto unobs = calib::checks::unobservable_parameters(crlb, opt);
  if (json) {
    std::cout << nlohmann::json{{"sequence", profile.name},
                                {"duration_s", profile.duration_s()},
                                {"sigma", db::archive::param_set_to_json(crlb.sigma)},
                                {"unobservable", unobs}}
                     .dump(2)
              << '\n';
  } else {
    std::cout << "sequence " << profile.name << " (" << profile.duration_s() << " s)\n";
    tools::imucal::print_crlb(std::cout, crlb, unobs);
  }
  return unobs.empty() ? 0 : kExitReview;
}

/// Benchmark of `calibrate --method all` (archive read included): wall time per repetition and the
/// process's peak resident memory. Timing belongs here, not in unit tests (shared, noisy machines).
int cmd_bench(const std::string& dir, int repeat, bool sequential, bool json) {
  std::vector<double> wall_s;
  size_t samples = 0;
  std::string verdict;
  for (int i = 0; i < repeat; ++i) {
    const auto t0 = std::chrono::steady_clock::now();
    const calib::core::CalibrationInput in =
        db::archive::to_calibration_input(db::archive::read_archive(dir));
    calib::pipeline::PipelineOptions options;
    options.concurrent = !sequential;
    const calib::pipeline::PipelineResult r = calib::pipeline::run_calibration(in, options);
    wall_s.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    samples = in.imu.size();
    verdict = r.pass() ? "PASS" : "REVIEW";
  }
  std::sort(wall_s.begin(), wall_s.end());
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  const double peak_mb = static_cast<double>(ru.ru_maxrss) / 1024.0;
  const double median = wall_s[wall_s.size() / 2];
  if (json) {
    std::cout << nlohmann::json{{"samples", samples},           {"repeat", repeat},
                                {"wall_s_min", wall_s.front()}, {"wall_s_median", median},
                                {"peak_rss_mb", peak_mb},       {"verdict", verdict},
                                {"concurrent", !sequential}}
                     .dump(2)
              << '\n';
  } else {
    std::printf(
        "calibrate --method all (%s) on %zu samples: wall min %.3f s, median %.3f s over %d "
        "runs; peak RSS %.1f MB; verdict %s\n",
        sequential ? "methods one after the other" : "methods concurrently", samples,
        wall_s.front(), median, repeat, peak_mb, verdict.c_str());
  }
  return 0;
}

}  // namespace

namespace {

/// Every subcommand's arguments and whether it was given.
struct Commands {
  SimulateArgs sa;
  std::string seq, unit, dir, method = "all", params, setting_override, plot_path;
  PriorOverride prior;     ///< calibrate --grade, --min-rest-s
  std::string crlb_grade;  ///< crlb --grade
  double rate_hz = 100.0, k_sigma = 4.0;
  double false_alarm = calib::diagnosis::kDefaultGapFalseAlarm;  ///< crlb --effects
  bool json = false, effects = false, sequential = false, effects_json = false;
  int repeat = 3;
  tools::imucal::DiagnoseArgs diag;
  tools::imucal::ValidateArgs val;
  tools::imucal::PaperTablesArgs paper;
  tools::imucal::GapBudgetArgs budget;
  tools::imucal::ImportArgs import;
  tools::imucal::DesignSequenceArgs design;
  tools::imucal::CheckArgs check;
  CLI::App *im = nullptr, *gb = nullptr, *ds = nullptr, *ck = nullptr, *ap = nullptr;
  CLI::App *sim = nullptr, *cal = nullptr, *ev = nullptr, *cr = nullptr, *be = nullptr,
           *dg = nullptr, *ef = nullptr, *vd = nullptr, *pt = nullptr;
};

void add_simulate(CLI::App& app, Commands& c) {
  SimulateArgs& sa = c.sa;
  auto* sim = c.sim = app.add_subcommand(
      "simulate", "simulate a unit on a sequence into a run archive (factory table, land or sea)");
  sim->add_option("--sequence", sa.seq,
                  "sequence name (factory-std, factory-fast, factory-60, short, pos19) or TOML "
                  "file; land/sea also 'hand': "
                  "a 50 s rest and 38 hand-placed positions of 3-11 s")
      ->required();
  sim->add_option("--grade", sa.grade,
                  "navigation|tactical|mems: without --unit, a unit drawn (by --seed) from the "
                  "grade's envelope; with it, instead of the unit file's grade; written to "
                  "run.toml [prior] (default: the unit file's, else navigation)")
      ->check(CLI::IsMember({"navigation", "tactical", "mems"}));
  sim->add_option("--out", sa.out_dir, "archive directory to create")->required();
  sim->add_option("--unit", sa.unit, "unit file (TOML); default: the built-in default unit");
  sim->add_option("--seed", sa.seed, "noise seed")->capture_default_str();
  sim->add_option("--rate", sa.rate_hz, "IMU rate, Hz")
      ->capture_default_str()
      ->check(CLI::Range(10.0, 2000.0));
  sim->add_flag("--overwrite", sa.overwrite, "replace an existing archive");
  sim->add_option("--effect", sa.effect_specs,
                  "inject a catalogue effect, NAME=V[,V...] in SI (repeatable; see imucal effects)")
      ->take_all();
  sim->add_option("--setting", sa.setting,
                  "factory (table run), land (hand-placed rotations, no table log) or sea (as land "
                  "on a drifting, rocking deck, with GNSS fixes)")
      ->capture_default_str()
      ->check(CLI::IsMember({"factory", "land", "sea"}));
  sim->add_option("--gnss-sigma", sa.gnss_sigma_m, "sea: GNSS white noise per axis, m")
      ->capture_default_str()
      ->check(CLI::Range(0.01, 100.0));
  sim->add_option("--placement-sigma", sa.placement_sigma_deg,
                  "land/sea: hand placement error per axis and rest, deg")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 20.0));
}

void add_calibrate(CLI::App& app, Commands& c) {
  auto* cal = c.cal = app.add_subcommand(
      "calibrate",
      "calibrate a run archive: factory AINS + NLSQ, land/sea AINS + legacy, and the cross-check");
  cal->add_option("dir", c.dir, "run archive directory")->required();
  cal->add_option("--method", c.method,
                  "ains|nlsq|legacy|all (all: the setting's two methods and their cross-check)")
      ->capture_default_str()
      ->check(CLI::IsMember({"ains", "nlsq", "legacy", "all"}));
  cal->add_option("--setting", c.setting_override,
                  "factory|land|sea: process as this setting instead of run.toml's (e.g. a table "
                  "run as the paper did: its reference withheld)")
      ->check(CLI::IsMember({"factory", "land", "sea"}));
  cal->add_option("--grade", c.prior.grade,
                  "navigation|tactical|mems: the unit's grade instead of run.toml's [prior] grade "
                  "(field runs: navigation finds rests by the rate's magnitude, the others by the "
                  "signals' variation, which needs no calibration)")
      ->check(CLI::IsMember({"navigation", "tactical", "mems"}));
  cal->add_option("--min-rest-s", c.prior.min_rest_s,
                  "field runs: the shortest rest kept, s (default: the detector's, 10 s for "
                  "navigation grade, 2 s otherwise)")
      ->check(CLI::Range(0.5, 600.0));
  cal->add_option("--first-rest-s", c.prior.first_rest_s,
                  "field runs: the first rest must last this long, s (default: navigation grade "
                  "20 s beginning within the first 10 s, for levelling and gyrocompassing; "
                  "tactical and MEMS the first still position of any length, wherever it begins)")
      ->check(CLI::Range(0.5, 600.0));
  cal->add_option("--compensate", c.prior.compensate,
                  "a gap diagnosis (imucal diagnose --json, or --report's diagnosis.json): remove "
                  "the effects it found (its best and second) from the run before calibrating it "
                  "— the unit's sensor effects only, evaluated with the run's multi-position "
                  "calibration");
  cal->add_option("--k-sigma", c.k_sigma, "cross-check bound in combined σ")->capture_default_str();
  cal->add_flag("--json", c.json, "print one JSON object");
  cal->add_option("--plot", c.plot_path,
                  "also write an SVG picture (cross-check, per-rest metrics)")
      ->check([](const std::string& p) {
        const std::string ext = std::filesystem::path(p).extension().string();
        return ext == ".svg" || ext == ".SVG"
                   ? std::string()
                   : "the picture is SVG: name it .svg (got '" + p + "')";
      });
}

/// evaluate, crlb, bench and effects: the smaller commands.
void add_small_commands(CLI::App& app, Commands& c) {
  c.ev = app.add_subcommand("evaluate", "evaluate a parameter set on a run archive (paper §VII)");
  c.ev->add_option("dir", c.dir, "run archive directory")->required();
  c.ev->add_option("--params", c.params, "parameter-set JSON file")->required();
  c.ev->add_flag("--json", c.json, "print one JSON object");

  c.cr = app.add_subcommand("crlb", "achievable σ of every parameter for a sequence");
  c.cr->add_option("--sequence", c.seq, "sequence name or TOML file")->required();
  c.cr->add_option("--unit", c.unit, "unit file (noise model); default: built-in");
  c.cr->add_option("--rate", c.rate_hz, "IMU rate, Hz")->capture_default_str();
  c.cr->add_option("--grade", c.crlb_grade,
                   "navigation|tactical|mems: the filter's prior of such a unit and, without "
                   "--unit, the noise of the class's worst")
      ->check(CLI::IsMember({"navigation", "tactical", "mems"}));
  c.cr->add_flag("--json", c.json, "print one JSON object");
  c.cr->add_flag("--effects", c.effects,
                 "per catalogue effect: detection threshold and separability on the sequence");
  c.cr->add_option("--false-alarm", c.false_alarm,
                   "with --effects: the diagnosis' false-alarm rate per run the thresholds are "
                   "computed at (the station's [calibration] gap_false_alarm)")
      ->capture_default_str()
      ->check(CLI::Range(1e-9, 0.5));

  c.be = app.add_subcommand("bench", "time and peak memory of calibrate --method all");
  c.be->add_option("dir", c.dir, "run archive directory")->required();
  c.be->add_option("--repeat", c.repeat, "repetitions")
      ->capture_default_str()
      ->check(CLI::Range(1, 100));
  c.be->add_flag("--sequential", c.sequential,
                 "the two methods one after the other (as before issue #11), for comparison");
  c.be->add_flag("--json", c.json, "print one JSON object");
}

int dispatch(const Commands& c) {
  if (*c.sim) return cmd_simulate(c.sa);
  if (*c.im) return tools::imucal::cmd_import(c.import);
  if (*c.cal)
    return cmd_calibrate(c.dir, c.method, c.json, c.k_sigma, c.plot_path, c.setting_override,
                         c.prior);
  if (*c.ev) return cmd_evaluate(c.dir, c.params, c.json);
  if (*c.ck) return tools::imucal::cmd_check(c.check);
  if (*c.ap) return tools::imucal::cmd_apply(c.check);
  if (*c.cr && c.effects)
    return tools::imucal::cmd_crlb_effects(c.seq, c.unit, c.rate_hz, c.false_alarm, c.json);
  if (*c.cr) return cmd_crlb(c.seq, c.unit, c.rate_hz, c.crlb_grade, c.json);
  if (*c.be) return cmd_bench(c.dir, c.repeat, c.sequential, c.json);
  if (*c.dg) return tools::imucal::cmd_diagnose(c.diag);
  if (*c.vd) return tools::imucal::cmd_validate(c.val);
  if (*c.pt) return tools::imucal::cmd_paper_tables(c.paper);
  if (*c.gb) return tools::imucal::cmd_gap_budget(c.budget);
  if (*c.ef) return tools::imucal::cmd_effects(c.effects_json);
  if (*c.ds) return tools::imucal::cmd_design_sequence(c.design);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  keep_freed_memory();
  CLI::App app{"imucal — IMU calibration on run archives"};
  app.require_subcommand(1);
  app.set_version_flag("--version", std::string(IMUCAL_VERSION));
  Commands c;
  add_simulate(app, c);
  add_calibrate(app, c);
  add_small_commands(app, c);
  c.dg = tools::imucal::add_diagnose_command(app, c.diag);
  c.ef = app.add_subcommand("effects",
                            "the effects catalogue: names, models, parameters, typical sizes");
  c.ef->add_flag("--json", c.effects_json, "print one JSON array");
  c.vd = tools::imucal::add_validate_command(app, c.val);
  c.pt = tools::imucal::add_paper_tables_command(app, c.paper);
  c.gb = tools::imucal::add_gap_budget_command(app, c.budget);
  c.im = tools::imucal::add_import_command(app, c.import);
  c.ds = tools::imucal::add_design_sequence_command(app, c.design);
  c.ck = tools::imucal::add_check_command(app, c.check);
  c.ap = tools::imucal::add_apply_command(app, c.check);
  for (int i = 0; i < argc; ++i)
    c.design.command_line += (i ? " " : "") + std::string(i ? argv[i] : "imucal");

  const bool json_errors = wants_json(argc, argv);
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    // Help and version exit 0; every usage error exits 2, like every other tool's (CLI11's own
    // codes, 105–109, mean nothing to a shell script).
    if (e.get_exit_code() == 0) return app.exit(e);
    if (json_errors) return json_error(e.what(), kExitUsage);
    app.exit(e);
    return kExitUsage;
  }
  try {
    return dispatch(c);
  } catch (const std::exception& e) {
    if (json_errors) return json_error(e.what(), kExitBadInput);
    std::fprintf(stderr, "imucal: error: %s\n", e.what());
    return kExitBadInput;
  }
}
