#include "tools/imucal/design_sequence_cmd.hpp"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <stdexcept>

#include "calib/core/site_presets.hpp"
#include "calib/diagnosis/false_alarm.hpp"
#include "calib/sim/sim_input.hpp"
#include "calib/studies/design/sequence_design.hpp"
#include "db/archive/io_util.hpp"
#include "db/archive/unit_file.hpp"
#include "sequences/library.hpp"
#include "sequences/parser.hpp"
#include "sequences/profile_generator.hpp"
#include "sequences/sequence_error.hpp"
#include "tools/imucal/exit_codes.hpp"
#include "tools/imucal/format.hpp"

namespace imucal::tools::imucal {

namespace {

/// A parsed, validated library sequence or file; errors name the option.
sequences::Sequence read_sequence(const std::string& option, const std::string& name_or_path) {
  try {
    const std::string path = sequences::resolve_sequence(name_or_path);
    sequences::Sequence seq = sequences::parse_sequence_file(path);
    sequences::validate_or_throw(seq,
                                 sequences::effective_limits(sequences::TableLimits{}, seq.limits));
    return seq;
  } catch (const sequences::SequenceError& e) {
    throw std::invalid_argument(option + ": " + e.what());
  }
}

// ------------------------------------------------------------------ the file

/// A body axis as text ("+x"), or the vector when the direction is no body axis.
std::string body_direction(double x, double y, double z) {
  const double v[3] = {x, y, z};
  for (int k = 0; k < 3; ++k)
    if (std::abs(std::abs(v[k]) - 1.0) < 1e-6) return std::string(v[k] > 0 ? "+" : "-") + "xyz"[k];
  char b[64];
  std::snprintf(b, sizeof b, "(%.2f, %.2f, %.2f)", x, y, z);
  return b;
}

/// "(90, 0): about body +x, y down" — the pose reached and what the rotation did, with the
/// default geometry (sequences/FORMAT.md, Geometry).
std::string pose_comment(const calib::studies::design::RestTour& tour, size_t leg) {
  const auto [o_deg, i_deg] = tour.pose_deg(leg + 1);
  const double i0_deg = tour.pose_deg(leg).second;  // an outer turn's body axis: the inner angle
  const double d = M_PI / 180.0, sign = tour.legs[leg].by_deg > 0 ? 1.0 : -1.0;
  std::string about;
  if (tour.legs[leg].axis == sequences::Axis::kInner)
    about = body_direction(0, 0, sign);
  else
    about = body_direction(sign * std::cos(i0_deg * d), -sign * std::sin(i0_deg * d), 0.0);
  const double down[3] = {std::sin(o_deg * d) * std::sin(i_deg * d),
                          std::sin(o_deg * d) * std::cos(i_deg * d), std::cos(o_deg * d)};
  std::string pose = "down is body " + body_direction(down[0], down[1], down[2]);
  char b[160];
  std::snprintf(b, sizeof b, "(%g, %g): about body %s, %s", o_deg, i_deg, about.c_str(),
                pose.c_str());
  return b;
}

std::string number(double v) {
  char b[32];
  std::snprintf(b, sizeof b, "%.1f", v);
  return b;
}

void write_limits(std::ostringstream& os, const sequences::DeclaredLimits& l) {
  const std::pair<const char*, const std::optional<double>*> keys[] = {
      {"max_rate_dps", &l.max_rate_dps},   {"max_accel_dps2", &l.max_accel_dps2},
      {"min_rest_s", &l.min_rest_s},       {"max_duration_s", &l.max_duration_s},
      {"inner_min_deg", &l.inner_min_deg}, {"inner_max_deg", &l.inner_max_deg},
      {"outer_min_deg", &l.outer_min_deg}, {"outer_max_deg", &l.outer_max_deg}};
  bool any = false;
  for (const auto& [key, value] : keys) {
    if (!value->has_value()) continue;
    if (!any) os << "\n[limits]\n";
    any = true;
    os << key << " = " << number(**value) << "\n";
  }
}

std::string toml_text(const calib::studies::design::SequenceDesign& d,
                      const DesignSequenceArgs& a) {
  const sequences::Sequence& seq = d.sequence;
  std::ostringstream os;
  os << "# Rotation sequence for the two-axis calibration turntable (format: "
        "sequences/FORMAT.md).\n"
     << "# Made by the sequence designer (calib/studies/design/sequence_design.hpp) with:\n"
     << "#   " << a.command_line << "\n"
     << "# Default geometry (calib/core/table_model.hpp): outer axis horizontal (north), inner "
        "axis "
        "=\n# platform normal = body z. Comments on steps give the (outer, inner) pose reached, in "
        "degrees,\n# the body axis turned about and the body axis pointing down.\n\n";
  os << "name = \"" << seq.name << "\"\n";
  os << "description = \"" << seq.description << "\"\n\n";
  os << "[start]  # (" << seq.start.outer_deg << ", " << seq.start.inner_deg << ")\n"
     << "outer_deg = " << number(seq.start.outer_deg)
     << "\ninner_deg = " << number(seq.start.inner_deg) << "\nrest_s = " << number(seq.start.rest_s)
     << "\n\n";
  os << "[defaults]\nrate_dps = " << number(d.tour.rate_dps)
     << "\naccel_dps2 = " << number(d.tour.accel_dps2) << "\n";
  write_limits(os, seq.limits);
  size_t leg = 0;
  for (const sequences::Step& st : seq.steps) {
    if (st.kind == sequences::StepKind::kRotate) {
      os << "\n[[step]]  # " << pose_comment(d.tour, leg++) << "\nrotate = \""
         << sequences::axis_name(st.axis) << "\"\nby_deg = " << number(*st.by_deg) << "\n";
    } else {
      os << "\n[[step]]\nrest_s = " << number(st.duration_s) << "\n";
    }
  }
  return os.str();
}

// ------------------------------------------------------------------ the report

double group_rms(const calib::core::ParamVector& v, calib::core::ParamGroup g) {
  double s = 0.0;
  int n = 0;
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i)
    if (calib::core::param_info(i).group == g) {
      s += v(i) * v(i);
      ++n;
    }
  return std::sqrt(s / n);
}

/// The group's worst parameter: max over it of num_i / den_i.
double group_worst(const calib::core::ParamVector& num, const calib::core::ParamVector& den,
                   calib::core::ParamGroup g) {
  double worst = 0.0;
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i)
    if (calib::core::param_info(i).group == g && den(i) > 0)
      worst = std::max(worst, num(i) / den(i));
  return worst;
}

void print_groups(const calib::studies::design::SequenceDesign& d,
                  const calib::core::NoiseModel& noise) {
  std::printf(
      "\nper parameter group (CRLB 1-sigma, RMS over the group; ratios: the group's worst "
      "parameter)\n");
  std::printf("  %-16s %-7s %12s %12s %10s %10s %10s\n", "group", "unit", "sigma ref",
              "sigma design", "design/ref", "design/cut", "/floor");
  calib::core::ParamVector floor = calib::core::ParamVector::Zero();
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i)
    floor(i) = calib::studies::design::white_noise_floor(i, noise, d.design.duration_s);
  for (int gi = 0; gi < calib::core::kNumParamGroups; ++gi) {
    const auto g = static_cast<calib::core::ParamGroup>(gi);
    int first = 0;
    while (calib::core::param_info(first).group != g) ++first;
    const auto& info = calib::core::param_info(first);
    const double fr = group_worst(d.design.sigma, floor, g);
    std::printf(
        "  %-16s %-7s %12.4g %12.4g %10.3f %10.3f %10s\n", calib::core::group_name(g).c_str(),
        info.human_unit.c_str(), group_rms(d.reference.sigma, g) * info.si_to_human,
        group_rms(d.design.sigma, g) * info.si_to_human,
        group_worst(d.design.sigma, d.reference.sigma, g),
        group_worst(d.design.sigma, d.cut.sigma, g), fr > 0 ? fmt("%.3f", fr).c_str() : "-");
  }
}

void print_effects(const calib::studies::design::SequenceDesign& d) {
  if (d.reference.effects.empty()) {
    std::printf("\neffects: not analysed (--no-effects)\n");
    return;
  }
  std::printf("\nper catalogue effect (detection threshold; separable on reference -> design)\n");
  std::printf("  %-24s %14s %14s %8s  %s\n", "effect", "threshold ref", "threshold des", "ratio",
              "separable");
  for (size_t k = 0; k < d.reference.effects.size() && k < d.design.effects.size(); ++k) {
    const auto& r = d.reference.effects[k];
    const auto& e = d.design.effects[k];
    char tr[32] = "-", te[32] = "-", ratio[16] = "-";
    if (std::isfinite(r.threshold))
      std::snprintf(tr, sizeof tr, "%.3g %s", r.threshold, r.unit.c_str());
    if (std::isfinite(e.threshold))
      std::snprintf(te, sizeof te, "%.3g %s", e.threshold, e.unit.c_str());
    if (std::isfinite(r.threshold) && std::isfinite(e.threshold))
      std::snprintf(ratio, sizeof ratio, "%.3f", e.threshold / r.threshold);
    std::printf("  %-24s %14s %14s %8s  %s -> %s\n", r.name.c_str(), tr, te, ratio,
                r.separable() ? "yes" : "no", e.separable() ? "yes" : "no");
  }
}

void print_report(const calib::studies::design::SequenceDesign& d, const DesignSequenceArgs& a,
                  const calib::core::NoiseModel& noise, double run_s) {
  std::printf(
      "designed %s: %.1f s of table time (%s: %.1f s, ratio %.3f), %zu rotations at "
      "%g deg/s and %g deg/s^2, %zu rests\n",
      d.sequence.name.c_str(), d.design.duration_s,
      a.target_from.empty() ? a.like.c_str() : a.target_from.c_str(), d.reference.duration_s,
      d.design.duration_s / d.reference.duration_s, d.tour.legs.size(), d.tour.rate_dps,
      d.tour.accel_dps2, d.tour.poses());
  std::printf("search: %d CRLB runs in %.0f s; what it changed:\n", d.evaluations, run_s);
  for (const auto& line : d.log) std::printf("  %s\n", line.c_str());
  print_groups(d, noise);
  print_effects(d);
  const auto lost = calib::studies::design::effects_lost(
      d.reference.effects, d.design.effects,
      calib::studies::design::DesignSetting{}.threshold_factor);
  std::printf("\nmax sigma/target %.4f (targets: %s); %s\n", d.objective,
              a.target_from.empty() ? "the obvious cut, the biases also <= 1.05 x N/sqrt(T)"
                                    : "factor x the target sequence's sigma",
              lost.empty() ? "every effect the reference separates kept"
                           : ("effects lost: " + std::to_string(lost.size())).c_str());
}

std::string default_name(const DesignSequenceArgs& a) {
  if (!a.name.empty()) return a.name;
  if (!a.out.empty()) return std::filesystem::path(a.out).stem().string();
  return a.like + "-design";
}

void check_args(const DesignSequenceArgs& a) {
  if (a.target_from.empty() && !(a.time_s > 0))
    throw std::invalid_argument("give --time-s T or --target-from SEQ --factor K");
  if (!a.out.empty()) {
    const auto dir = std::filesystem::path(a.out).parent_path();
    if (!dir.empty() && !std::filesystem::is_directory(dir))
      throw std::invalid_argument("--out: directory '" + dir.string() + "' does not exist");
  }
}

}  // namespace

CLI::App* add_design_sequence_command(CLI::App& app, DesignSequenceArgs& a) {
  auto* c = app.add_subcommand(
      "design-sequence",
      "design a rotation sequence by the CRLB: like a reference in a given table time, or the "
      "shortest reaching K x a sequence's sigma");
  c->add_option("--like", a.like, "the reference sequence (library name or TOML file)")
      ->capture_default_str();
  auto* time = c->add_option("--time-s", a.time_s, "table time of the design, s")
                   ->check(CLI::Range(1.0, 1e5));
  auto* from = c->add_option("--target-from", a.target_from,
                             "the sequence whose sigma, times --factor, the design must reach in "
                             "the least time");
  c->add_option("--factor", a.factor, "with --target-from: sigma <= K x its sigma in every group")
      ->capture_default_str()
      ->check(CLI::Range(0.1, 100.0))
      ->needs(from);
  time->excludes(from);
  c->add_option("--out", a.out, "write the sequence here (atomically); default: stdout only");
  c->add_option("--name", a.name, "the design's name (default: --out's stem)");
  c->add_option("--unit", a.unit, "unit file (noise model, parameters); default: built-in");
  c->add_option("--rate", a.rate_hz, "IMU rate of the final figures, Hz")
      ->capture_default_str()
      ->check(CLI::Range(10.0, 2000.0));
  c->add_option("--search-rate", a.search_rate_hz, "IMU rate of the search's CRLB runs, Hz")
      ->capture_default_str()
      ->check(CLI::Range(5.0, 2000.0));
  c->add_flag("--no-effects", a.no_effects,
              "skip the effects' detectability (faster; effects neither kept nor reported)");
  return c;
}

int cmd_design_sequence(const DesignSequenceArgs& a) {
  check_args(a);
  const auto t0 = std::chrono::steady_clock::now();
  const sequences::Sequence like = read_sequence("--like", a.like);
  const calib::effects::UnitModel unit =
      a.unit.empty() ? calib::effects::default_unit() : db::archive::read_unit_file(a.unit);

  calib::studies::design::DesignSetting s;
  s.site = calib::core::demo_factory_site();
  s.noise = unit.noise;
  s.base = unit.params;
  s.limits = sequences::effective_limits(sequences::TableLimits{}, like.limits);
  s.rate_hz = a.rate_hz;
  s.search_rate_hz = a.search_rate_hz;
  s.diagnosis =
      calib::diagnosis::diagnosis_options_for_false_alarm(calib::diagnosis::kDefaultGapFalseAlarm);
  if (!a.no_effects)
    s.exact_run = [geometry = s.geometry, site = s.site, unit](
                      const sequences::MotionProfile& profile, double rate_hz) {
      return calib::sim::truth_run_source(profile, geometry, site, unit, rate_hz)(
          calib::effects::Effects{}, 1, false);
    };
  s.progress = [t0](const std::string& line) {
    std::fprintf(stderr, "design-sequence [%5.0f s] %s\n",
                 std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(),
                 line.c_str());
  };

  calib::studies::design::SequenceDesign d;
  try {
    if (a.target_from.empty()) {
      d = calib::studies::design::design_for_time(like, a.time_s, s);
    } else {
      const sequences::Sequence target = read_sequence("--target-from", a.target_from);
      d = calib::studies::design::design_for_target(like, target, a.factor, s);
    }
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument(std::string(a.target_from.empty() ? "--time-s" : "--factor") +
                                ": " + e.what());
  }
  d.sequence.name = default_name(a);
  d.sequence.limits = like.limits;
  char desc[256];
  std::snprintf(desc, sizeof desc,
                "Designed from %s for %.0f s of table time: %zu rotations at %g deg/s, %zu rests "
                "(imucal design-sequence).",
                like.name.c_str(), d.design.duration_s, d.tour.legs.size(), d.tour.rate_dps,
                d.tour.poses());
  d.sequence.description = desc;
  const std::string text = toml_text(d, a);
  // The file the design writes must be one the parser and validator accept as it stands.
  const sequences::Sequence again = sequences::parse_sequence_string(text, default_name(a));
  sequences::validate_or_throw(again,
                               sequences::effective_limits(sequences::TableLimits{}, again.limits));
  const double run_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  print_report(d, a, s.noise, run_s);
  if (!a.out.empty()) {
    db::archive::write_file_atomic(a.out, text);
    std::printf("wrote %s\n", a.out.c_str());
  } else {
    std::printf("\n%s", text.c_str());
  }
  return d.targets_met ? 0 : kExitReview;
}

}  // namespace imucal::tools::imucal
