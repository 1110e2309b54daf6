// altsim — an independent simulator of the factory table run (issue #22), into a run archive:
//   altsim --sequence NAME|FILE --out DIR [--seed N] [--effect NAME=V1,V2,...]... [--no-noise]
//          [--rate HZ]
// The unit is altsim's own navigation-grade default (below), not the project's default unit; the
// effects are the catalogue's, SI values in the catalogue's parameter order (imucal effects).
// Exit codes: 0 written; 1 bad input or failure (one line on stderr); 2 usage error.
#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <stdexcept>
#include <string>
#include <vector>

#include "sequences/library.hpp"
#include "tools/altsim/alt_archive.hpp"
#include "tools/altsim/alt_effects.hpp"
#include "tools/altsim/alt_sim.hpp"

using namespace imucal;

namespace {

constexpr double kDeg = tools::altsim::kPi / 180.0;
constexpr double kMicroG_mps2 = 9.80665e-6;
constexpr double kDegPerHour_radps = kDeg / 3600.0;
constexpr double kArcsec_rad = kDeg / 3600.0;

// The station altsim simulates: DTU, Kongens Lyngby, with the factory's surveyed gravity.
constexpr double kLat_deg = 55.7856, kLon_deg = 12.5213, kHeight_m = 30.0;
constexpr double kGravity_mps2 = 9.81565;

/// altsim's own navigation-grade unit (ARCHITECTURE §7 sizes, values of its own): biases ~50 µg and
/// ~0.01 °/h, scale factors and misalignments a few hundred ppm, ARW 0.0015 °/√h, VRW 10 µg/√Hz,
/// the built-in protocol's resolution (1e-9 rad, 1e-7 m/s).
tools::altsim::AltUnit default_alt_unit() {
  tools::altsim::AltUnit u;
  tools::altsim::AltErrorModel& e = u.errors;
  e.b_a_mps2 = Eigen::Vector3d(-45.0, 35.0, 55.0) * kMicroG_mps2;
  e.M_a << 250e-6, -90e-6, 60e-6,  //
      110e-6, -180e-6, -70e-6,     //
      -50e-6, 130e-6, 380e-6;
  e.b_g_radps = Eigen::Vector3d(0.009, 0.011, -0.007) * kDegPerHour_radps;
  e.M_g << -120e-6, 170e-6, 80e-6,  //
      -60e-6, 330e-6, -140e-6,      //
      100e-6, -75e-6, 210e-6;
  u.noise.arw_rad_per_sqrt_s = 0.0015 * kDeg / 60.0;
  u.noise.vrw_mps_per_sqrt_s = 10.0 * kMicroG_mps2;
  u.noise.dtheta_lsb_rad = 1e-9;
  u.noise.dv_lsb_mps = 1e-7;
  return u;
}

struct Args {
  std::string sequence, out_dir;
  uint64_t seed = 1;
  std::vector<std::string> effects;
  bool no_noise = false;
  double rate_hz = 100.0;
};

int run(const Args& a) {
  tools::altsim::AltUnit unit = default_alt_unit();
  for (const std::string& spec : a.effects) {
    try {
      tools::altsim::apply_alt_effect_spec(unit.effects, spec);
    } catch (const std::invalid_argument& e) {
      throw std::invalid_argument("--effect " + spec + ": " + e.what());
    }
  }
  const std::string seq_path = sequences::resolve_sequence(a.sequence);
  const sequences::MotionProfile profile = sequences::load_profile(seq_path);
  tools::altsim::AltRunInfo info;
  info.serial = "ALTSIM-" + std::to_string(a.seed);
  info.software_version = std::string("altsim ") + IMUCAL_VERSION;
  info.lat_deg = kLat_deg;
  info.lon_deg = kLon_deg;
  info.height_m = kHeight_m;
  info.gravity_mps2 = kGravity_mps2;
  info.rate_hz = a.rate_hz;
  info.sequence_name = profile.name;
  info.sequence_sha256 = sequences::sequence_hash(seq_path);
  info.table.misalignment_rad = Eigen::Vector3d(-12.0, 18.0, 25.0) * kArcsec_rad;
  info.unit = unit;
  tools::altsim::AltSite site;
  site.lat_rad = kLat_deg * kDeg;
  site.gravity_mps2 = kGravity_mps2;
  tools::altsim::AltOptions opt;
  opt.rate_hz = a.rate_hz;
  opt.seed = a.seed;
  opt.noise = !a.no_noise;
  const auto t0 = std::chrono::steady_clock::now();
  const std::vector<tools::altsim::AltSample> samples =
      tools::altsim::simulate_alt(profile, info.table, site, unit, opt);
  const double sim_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  tools::altsim::write_alt_archive(a.out_dir, info, samples);
  std::printf("wrote %s: %zu samples, %.2f s, sequence %s, seed %llu%s (simulated in %.2f s)\n",
              a.out_dir.c_str(), samples.size(), samples.back().t_s, profile.name.c_str(),
              static_cast<unsigned long long>(a.seed), a.no_noise ? ", no noise" : "", sim_s);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"altsim: an independent simulator of the factory table run, into a run archive"};
  Args a;
  app.add_option("--sequence", a.sequence, "sequence name (factory-std, short, ...) or TOML file")
      ->required();
  app.add_option("--out", a.out_dir, "archive directory to create (absent or empty)")->required();
  app.add_option("--seed", a.seed, "noise seed")->capture_default_str();
  app.add_option("--effect", a.effects,
                 "inject a catalogue effect, NAME=V[,V...] in SI, the catalogue's parameter order "
                 "(repeatable; known: " +
                     tools::altsim::alt_effect_names() + ")")
      ->take_all();
  app.add_flag("--no-noise", a.no_noise, "deterministic increments (no noise, no quantisation)");
  app.add_option("--rate", a.rate_hz, "IMU rate, Hz")
      ->capture_default_str()
      ->check(CLI::Range(10.0, 2000.0));
  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e) == 0 ? 0 : 2;
  }
  try {
    return run(a);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "altsim: %s\n", e.what());
    return 1;
  }
}
