// Unit files (TOML, human units) and truth.json: unit conversions checked against hand-derived
// values, default.toml == calib::effects::default_unit() field by field, far.toml within its stated
// sizes, strict errors with line and field.
#include "db/archive/unit_file.hpp"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <random>

#include "db/archive/archive_error.hpp"

namespace imucal::db::archive {
namespace {

namespace fs = std::filesystem;

const std::string kUnitsDir = std::string(IMUCAL_SOURCE_DIR) + "/db/archive/units/";
constexpr double kPiHere = 3.14159265358979323846;

ArchiveError unit_error(const std::string& text) {
  try {
    parse_unit_file(text, "units/bad.toml");
  } catch (const ArchiveError& e) {
    return e;
  }
  ADD_FAILURE() << "no error for:\n" << text;
  return ArchiveError("none", "none");
}

void expect_noise_eq(const calib::core::NoiseModel& a, const calib::core::NoiseModel& b) {
  EXPECT_EQ(a.arw_rad_per_sqrt_s, b.arw_rad_per_sqrt_s);
  EXPECT_EQ(a.vrw_mps_per_sqrt_s, b.vrw_mps_per_sqrt_s);
  EXPECT_EQ(a.gyro_bias_instability_radps, b.gyro_bias_instability_radps);
  EXPECT_EQ(a.gyro_bias_tau_s, b.gyro_bias_tau_s);
  EXPECT_EQ(a.accel_bias_instability_mps2, b.accel_bias_instability_mps2);
  EXPECT_EQ(a.accel_bias_tau_s, b.accel_bias_tau_s);
  EXPECT_EQ(a.dtheta_lsb_rad, b.dtheta_lsb_rad);
  EXPECT_EQ(a.dv_lsb_mps, b.dv_lsb_mps);
}

void expect_effects_eq(const calib::effects::Effects& a, const calib::effects::Effects& b) {
  EXPECT_EQ(a.accel_k2_per_mps2, b.accel_k2_per_mps2);
  EXPECT_EQ(a.accel_asym, b.accel_asym);
  EXPECT_EQ(a.gyro_g_sens, b.gyro_g_sens);
  for (size_t i = 0; i < 3; ++i) EXPECT_EQ(a.accel_lever_arm_m[i], b.accel_lever_arm_m[i]) << i;
  EXPECT_EQ(a.table_time_offset_s, b.table_time_offset_s);
}

TEST(UnitFile, DefaultTomlEqualsDefaultUnitFieldByField) {
  const calib::effects::UnitModel f = read_unit_file(kUnitsDir + "default.toml");
  const calib::effects::UnitModel d = calib::effects::default_unit();
  EXPECT_EQ(f.params.accel_bias_mps2, d.params.accel_bias_mps2);
  EXPECT_EQ(f.params.accel_M, d.params.accel_M);
  EXPECT_EQ(f.params.gyro_bias_radps, d.params.gyro_bias_radps);
  EXPECT_EQ(f.params.gyro_M, d.params.gyro_M);
  EXPECT_EQ(f.params.table_misalignment_rad, d.params.table_misalignment_rad);
  expect_noise_eq(f.noise, d.noise);
  expect_effects_eq(f.effects, d.effects);
}

TEST(UnitFile, FarTomlReachesButStaysWithinItsStatedSizes) {
  const calib::effects::UnitModel u = read_unit_file(kUnitsDir + "far.toml");
  const double g0 = 9.80665;
  auto check = [](const char* what, double max_abs, double limit) {
    EXPECT_LE(max_abs, limit * (1 + 1e-12)) << what;
    EXPECT_GE(max_abs, limit * (1 - 1e-12)) << what << " should reach the stated size";
  };
  check("accel bias 2 mg", u.params.accel_bias_mps2.cwiseAbs().maxCoeff(), 2e-3 * g0);
  check("gyro bias 0.1 deg/h", u.params.gyro_bias_radps.cwiseAbs().maxCoeff(),
        0.1 * kPiHere / 180.0 / 3600.0);
  for (const Eigen::Matrix3d* M : {&u.params.accel_M, &u.params.gyro_M}) {
    check("scale factor 2000 ppm", M->diagonal().cwiseAbs().maxCoeff(), 2000e-6);
    Eigen::Matrix3d off = *M;
    off.diagonal().setZero();
    check("misalignment 2 mrad", off.cwiseAbs().maxCoeff(), 2e-3);
  }
}

TEST(UnitFile, HumanUnitsConvertAsDerivedByHand) {
  const calib::effects::UnitModel u = parse_unit_file(R"(
[accel]
bias_ug = [1000.0, -2000, 0]
M_ppm = [[100, 1, 0], [0, 0, 0], [0, 0, -250]]
[gyro]
bias_deg_per_h = [3600.0, 0, 0]
M_ppm = [[0, 0, 0], [0, 0, 0], [0, 5, 0]]
[table]
misalignment_arcsec = [3600.0, 0, 0]
[noise]
arw_deg_per_sqrt_h = 60.0
vrw_ug_per_sqrt_hz = 1e6
[effects]
k2_ug_per_g2 = [1e6, 0, 0]
asym_ppm = [0, 10, 0]
g_sens_deg_per_h_per_g = [[3600, 0, 0], [0, 0, 0], [0, 0, 0]]
lever_arm_m = [[0.01, 0, 0], [0, 0.02, 0], [0, 0, -0.03]]
table_time_offset_s = 0.005
)",
                                                      "hand.toml");
  const double g0 = 9.80665, deg = kPiHere / 180.0;
  // Relative agreement to a few ulps: the conversion is one or two roundings away from the
  // exact product.
#define EXPECT_REL(a, b) EXPECT_NEAR((a), (b), 1e-15 * std::fabs(b))
  EXPECT_REL(u.params.accel_bias_mps2(0), 1e-3 * g0);  // 1000 µg = 1 mg
  EXPECT_REL(u.params.accel_bias_mps2(1), -2e-3 * g0);
  EXPECT_REL(u.params.accel_M(0, 0), 1e-4);
  EXPECT_REL(u.params.accel_M(0, 1), 1e-6);  // row 0, column 1: 1 µrad
  EXPECT_REL(u.params.accel_M(2, 2), -2.5e-4);
  EXPECT_REL(u.params.gyro_bias_radps(0), deg);  // 3600 deg/h = 1 deg/s
  EXPECT_REL(u.params.gyro_M(2, 1), 5e-6);
  EXPECT_REL(u.params.table_misalignment_rad(0), deg);   // 3600 arcsec = 1 deg
  EXPECT_REL(u.noise.arw_rad_per_sqrt_s, deg);           // 60 deg/√h = 1 deg/√s
  EXPECT_REL(u.noise.vrw_mps_per_sqrt_s, g0);            // 1e6 µg/√Hz = 1 g·√s
  EXPECT_REL(u.effects.accel_k2_per_mps2(0), 1.0 / g0);  // 1 g/g² = 1/g0 per m/s²
  EXPECT_REL(u.effects.accel_asym(1), 1e-5);
  EXPECT_REL(u.effects.gyro_g_sens(0, 0), deg / g0);  // 1 deg/s per g
#undef EXPECT_REL
  EXPECT_EQ(u.effects.accel_lever_arm_m[1], Eigen::Vector3d(0, 0.02, 0));
  EXPECT_EQ(u.effects.accel_lever_arm_m[2], Eigen::Vector3d(0, 0, -0.03));
  EXPECT_EQ(u.effects.table_time_offset_s, 0.005);
  // Unset noise keys keep their NoiseModel{} defaults.
  EXPECT_EQ(u.noise.gyro_bias_tau_s, calib::core::NoiseModel{}.gyro_bias_tau_s);
  EXPECT_EQ(u.noise.dtheta_lsb_rad, calib::core::NoiseModel{}.dtheta_lsb_rad);
}

TEST(UnitFile, MissingKeysMeanZeroExceptNoiseDefaults) {
  const calib::effects::UnitModel u =
      parse_unit_file("[gyro]\nbias_deg_per_h = [0.01, 0, 0]\n", "sparse.toml");
  EXPECT_TRUE(u.params.accel_bias_mps2.isZero());
  EXPECT_TRUE(u.params.accel_M.isZero());
  EXPECT_TRUE(u.params.gyro_M.isZero());
  EXPECT_TRUE(u.params.table_misalignment_rad.isZero());
  EXPECT_GT(u.params.gyro_bias_radps(0), 0.0);
  EXPECT_FALSE(u.effects.any());
  expect_noise_eq(u.noise, calib::core::NoiseModel{});
  const calib::effects::UnitModel empty = parse_unit_file("", "empty.toml");
  EXPECT_TRUE(empty.params.to_vector().isZero());
}

TEST(UnitFile, TextRoundTripReproducesSiValues) {
  // default_unit round-trips bit-exactly; a random unit within an ulp (most values exactly).
  const calib::effects::UnitModel d = calib::effects::default_unit();
  const calib::effects::UnitModel d2 = parse_unit_file(unit_file_text(d), "rt.toml");
  EXPECT_EQ(d2.params.to_vector(), d.params.to_vector());
  expect_noise_eq(d2.noise, d.noise);

  std::mt19937_64 rng(11);
  std::normal_distribution<double> n(0.0, 1.0);
  calib::effects::UnitModel u;
  calib::core::ParamVector x;
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i) x(i) = 1e-4 * n(rng);
  u.params = calib::core::ParamSet::from_vector(x);
  u.noise.gyro_bias_instability_radps = 1e-9 * std::fabs(n(rng));
  u.effects.accel_k2_per_mps2 = Eigen::Vector3d(n(rng), n(rng), n(rng)) * 1e-6;
  u.effects.gyro_g_sens = Eigen::Matrix3d::Random() * 1e-8;
  u.effects.accel_lever_arm_m[1] = Eigen::Vector3d(0.01, -0.02, 0.03);
  u.effects.table_time_offset_s = 0.003;
  const calib::effects::UnitModel u2 = parse_unit_file(unit_file_text(u), "rt.toml");
  const auto a = u.params.to_vector(), b = u2.params.to_vector();
  int exact = 0;
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i) {
    EXPECT_LE(std::fabs(a(i) - b(i)),
              2 * std::nextafter(std::fabs(a(i)), 1.0) - 2 * std::fabs(a(i)))
        << i;
    exact += a(i) == b(i);
  }
  EXPECT_GE(exact, 20);
  EXPECT_NEAR(u2.effects.accel_k2_per_mps2(2), u.effects.accel_k2_per_mps2(2), 1e-21);
  EXPECT_TRUE(u2.effects.gyro_g_sens.isApprox(u.effects.gyro_g_sens, 1e-15));
  EXPECT_EQ(u2.effects.accel_lever_arm_m[1], u.effects.accel_lever_arm_m[1]);
  EXPECT_EQ(u2.effects.table_time_offset_s, 0.003);
  EXPECT_EQ(u2.effects.active_names(), u.effects.active_names());
}

TEST(UnitFile, UnknownKeysAndSectionsRejectedWithLine) {
  const ArchiveError e = unit_error("[accel]\nbias_ug = [1, 2, 3]\nbias_ppm = [1, 2, 3]\n");
  EXPECT_EQ(e.line(), 3u);
  EXPECT_EQ(e.field(), "accel.bias_ppm");
  EXPECT_NE(std::string(e.what()).find("units/bad.toml:3: field 'accel.bias_ppm': unknown key"),
            std::string::npos)
      << e.what();
  const ArchiveError s = unit_error("# comment\n\n[magnetometer]\nbias_nT = 3\n");
  EXPECT_EQ(s.line(), 3u);
  EXPECT_EQ(s.field(), "magnetometer");
  const ArchiveError top = unit_error("serial = \"x\"\n");
  EXPECT_EQ(top.line(), 1u);
}

TEST(UnitFile, WrongShapesTypesAndValuesRejected) {
  const ArchiveError rows = unit_error("[accel]\nM_ppm = [[1, 2, 3], [4, 5, 6]]\n");
  EXPECT_EQ(rows.line(), 2u);
  EXPECT_EQ(rows.field(), "accel.M_ppm");
  const ArchiveError row = unit_error("[gyro]\nM_ppm = [[1, 2, 3], [4, 5], [7, 8, 9]]\n");
  EXPECT_EQ(row.field(), "gyro.M_ppm[1]");
  const ArchiveError str = unit_error("[gyro]\nbias_deg_per_h = [0.01, \"0.02\", 0]\n");
  EXPECT_EQ(str.line(), 2u);
  EXPECT_EQ(str.field(), "gyro.bias_deg_per_h[1]");
  const ArchiveError nan = unit_error("[table]\nmisalignment_arcsec = [nan, 0, 0]\n");
  EXPECT_EQ(nan.field(), "table.misalignment_arcsec[0]");
  const ArchiveError neg = unit_error("[noise]\narw_deg_per_sqrt_h = -0.001\n");
  EXPECT_EQ(neg.line(), 2u);
  EXPECT_EQ(neg.field(), "noise.arw_deg_per_sqrt_h");
  const ArchiveError tau = unit_error("[noise]\n\ngyro_bias_tau_s = 0\n");
  EXPECT_EQ(tau.line(), 3u);
  const ArchiveError syntax = unit_error("[accel]\nbias_ug = [1, 2, 3\n[gyro]\n");
  EXPECT_GE(syntax.line(), 2u);
  EXPECT_NE(syntax.message().find("TOML syntax error"), std::string::npos) << syntax.what();
  const ArchiveError not_table = unit_error("accel = 3\n");
  EXPECT_EQ(not_table.field(), "accel");
}

// Issue #21: a unit file may name its product's grade; written back only when not navigation.
TEST(UnitFile, GradeIsReadCheckedAndRoundTrips) {
  EXPECT_EQ(parse_unit_file("", "units/x.toml").grade, calib::core::Grade::kNavigation);
  const calib::effects::UnitModel mems = parse_unit_file("grade = \"mems\"\n", "units/x.toml");
  EXPECT_EQ(mems.grade, calib::core::Grade::kMems);
  EXPECT_EQ(parse_unit_file(unit_file_text(mems), "units/y.toml").grade, calib::core::Grade::kMems);
  EXPECT_EQ(unit_file_text(calib::effects::default_unit()).find("grade"), std::string::npos);
  const ArchiveError bad = unit_error("\ngrade = \"consumer\"\n");
  EXPECT_EQ(bad.line(), 2u);
  EXPECT_EQ(bad.field(), "grade");
  EXPECT_NE(std::string(bad.what()).find("is not a grade"), std::string::npos) << bad.what();
}

TEST(TruthJson, RoundTripIsBitExact) {
  calib::effects::UnitModel u = calib::effects::default_unit();
  u.effects.accel_k2_per_mps2 = {1e-6, 0, 0};
  u.effects.table_time_offset_s = 0.004;
  u.noise.gyro_bias_instability_radps = 1.234567890123e-9;
  const Truth t = truth_from_unit(u);
  ASSERT_EQ(t.effect_names(),
            (std::vector<std::string>{"accel_quadratic_k2", "table_time_offset"}));
  const Truth r = parse_truth_json(truth_json_text(t), "truth.json");
  const auto a = t.params.to_vector(), b = r.params.to_vector();
  EXPECT_EQ(std::memcmp(a.data(), b.data(), sizeof(double) * calib::core::ParamSet::kSize), 0);
  EXPECT_TRUE(r.effects == t.effects);
  EXPECT_EQ(r.effect_names(), t.effect_names());
  expect_noise_eq(r.noise, t.noise);
}

// truth.json carries every injected effect with its values (issue #8), for every effect of the
// catalogue, bit-exactly; the values are written in SI under the catalogue's parameter names.
TEST(TruthJson, EveryCatalogueEffectRoundTripsWithItsValues) {
  calib::effects::UnitModel u = calib::effects::default_unit();
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> f(0.5, 2.0);
  for (const auto& e : calib::effects::effect_catalogue()) {
    Eigen::VectorXd v(e.size());
    for (int i = 0; i < e.size(); ++i)
      v(i) = e.typical[static_cast<size_t>(i)] * f(rng) +
             (e.typical[static_cast<size_t>(i)] == 0.0 ? 1e-3 * f(rng) : 0.0);
    calib::effects::set_effect_vector(u.effects, e.id, v);
  }
  const Truth t = truth_from_unit(u);
  ASSERT_EQ(t.effect_names().size(), calib::effects::effect_catalogue().size());
  const std::string text = truth_json_text(t);
  const nlohmann::json j = nlohmann::json::parse(text);
  EXPECT_DOUBLE_EQ(j["effects"]["accel_quadratic_k2"]["k2_x"].get<double>(),
                   u.effects.accel_k2_per_mps2(0));
  EXPECT_DOUBLE_EQ(j["effects"]["thermal_drift"]["tau"].get<double>(), u.effects.thermal_tau_s);
  const Truth r = parse_truth_json(text, "truth.json");
  for (const auto& e : calib::effects::effect_catalogue()) {
    const Eigen::VectorXd a = calib::effects::effect_vector(t.effects, e.id),
                          b = calib::effects::effect_vector(r.effects, e.id);
    EXPECT_EQ(std::memcmp(a.data(), b.data(), sizeof(double) * static_cast<size_t>(e.size())), 0)
        << e.name;
  }
}

TEST(TruthJson, OlderListOfNamesIsStillReadWithValuesUnknown) {
  nlohmann::json j =
      nlohmann::json::parse(truth_json_text(truth_from_unit(calib::effects::default_unit())));
  j["effects"] = {"accel_quadratic_k2", "table_time_offset"};
  const Truth r = parse_truth_json(j.dump(), "old/truth.json");
  EXPECT_FALSE(r.effect_values_known);
  EXPECT_EQ(r.effect_names(),
            (std::vector<std::string>{"accel_quadratic_k2", "table_time_offset"}));
  EXPECT_FALSE(r.effects.any());
}

TEST(TruthJson, StrictFieldErrors) {
  const nlohmann::json good =
      nlohmann::json::parse(truth_json_text(truth_from_unit(calib::effects::default_unit())));
  auto err = [](const nlohmann::json& j) {
    try {
      parse_truth_json(j.dump(), "run/truth.json");
    } catch (const ArchiveError& e) {
      return e;
    }
    ADD_FAILURE() << "no error for " << j.dump();
    return ArchiveError("none", "none");
  };
  nlohmann::json j = good;
  j["seed"] = 3;
  EXPECT_EQ(err(j).field(), "seed");
  j = good;
  j["noise"].erase("dv_lsb_mps");
  EXPECT_EQ(err(j).field(), "noise.dv_lsb_mps");
  j = good;
  j["noise"]["accel_bias_tau_s"] = -1.0;
  EXPECT_EQ(err(j).field(), "noise.accel_bias_tau_s");
  j = good;
  j["effects"] = {"size_effect", "size_effect"};
  EXPECT_EQ(err(j).field(), "effects[1]");
  j = good;
  j["effects"] = nlohmann::json::object({{"warp_drive", nlohmann::json::object()}});
  EXPECT_EQ(err(j).field(), "effects.warp_drive");
  EXPECT_NE(err(j).message().find("accel_quadratic_k2"), std::string::npos) << "known names listed";
  j = good;
  j["effects"] = {{"gravity_error", {{"dg", 1e-4}, {"extra", 1.0}}}};
  EXPECT_EQ(err(j).field(), "effects.gravity_error.extra");
  j = good;
  j["effects"] = {{"thermal_drift", {{"accel_x", 1e-4}}}};
  EXPECT_EQ(err(j).field(), "effects.thermal_drift.accel_y");  // missing
  j = good;
  j["effects"] = {{"gravity_error", {{"dg", "big"}}}};
  EXPECT_EQ(err(j).field(), "effects.gravity_error.dg");
  j = good;
  j["effects"] = {{"thermal_drift",
                   {{"accel_x", 0},
                    {"accel_y", 0},
                    {"accel_z", 0},
                    {"gyro_x", 0},
                    {"gyro_y", 0},
                    {"gyro_z", 1e-8},
                    {"tau", -5.0}}}};
  EXPECT_EQ(err(j).field(), "effects.thermal_drift");  // τ must be > 0
  j = good;
  j["params"]["accel_M"][0][1] = "x";
  const ArchiveError p = err(j);
  EXPECT_EQ(p.field(), "params.accel_M[0][1]");
  EXPECT_EQ(p.file(), "run/truth.json");
  j = good;
  j.erase("params");
  EXPECT_EQ(err(j).field(), "params");
}

TEST(UnitFile, WriteReadFile) {
  std::string d = (fs::temp_directory_path() / "imucal_uf_XXXXXX").string();
  ASSERT_NE(::mkdtemp(d.data()), nullptr);
  const calib::effects::UnitModel far = read_unit_file(kUnitsDir + "far.toml");
  write_unit_file(d + "/far2.toml", far);
  const calib::effects::UnitModel back = read_unit_file(d + "/far2.toml");
  EXPECT_EQ(back.params.to_vector(), far.params.to_vector());
  write_truth_json(d + "/truth.json", truth_from_unit(far));
  EXPECT_EQ(read_truth_json(d + "/truth.json").params.to_vector(), far.params.to_vector());
  fs::remove_all(d);
}

}  // namespace
}  // namespace imucal::db::archive

namespace imucal::db::archive {
namespace {

// Every catalogue effect is switchable in a unit file by its name with its SI vector (the order of
// `--effect NAME=V,...`); hand-computed values are checked, the file round-trips, and mistakes are
// named with their line.
TEST(UnitFile, EveryCatalogueEffectBySiVector) {
  const std::string text =
      "[effects]\n"
      "thermal_drift = [1e-4, 0, -2e-4, 0, 0, 2.5e-8, 600]\n"
      "gravity_error = [2e-4]\n"
      "table_wobble = [1.5e-5, -1e-5]\n"
      "quantisation = [1e-8, 1e-6]\n"
      "bias_instability = [5e-9, 1e-4]\n";  // τ left out: keeps its default
  const calib::effects::UnitModel u = parse_unit_file(text, "u.toml");
  EXPECT_EQ(u.effects.thermal_accel_mps2, Eigen::Vector3d(1e-4, 0, -2e-4));
  EXPECT_EQ(u.effects.thermal_gyro_radps(2), 2.5e-8);
  EXPECT_EQ(u.effects.thermal_tau_s, 600.0);
  EXPECT_EQ(u.effects.gravity_error_mps2, 2e-4);
  EXPECT_EQ(u.effects.table_wobble_rad, Eigen::Vector2d(1.5e-5, -1e-5));
  EXPECT_EQ(u.effects.quant_dv_mps, 1e-6);
  EXPECT_EQ(u.effects.instability_accel_mps2, 1e-4);
  EXPECT_EQ(u.effects.instability_tau_s, calib::effects::Effects{}.instability_tau_s);
  const calib::effects::UnitModel r = parse_unit_file(unit_file_text(u), "round.toml");
  EXPECT_TRUE(r.effects == u.effects);
  EXPECT_EQ(r.effects.active_names(), u.effects.active_names());
}

TEST(UnitFile, EffectMistakesAreNamedWithTheirLine) {
  auto err = [](const std::string& t) {
    try {
      parse_unit_file(t, "u.toml");
    } catch (const ArchiveError& e) {
      return e;
    }
    ADD_FAILURE() << "no error for " << t;
    return ArchiveError("none", "none");
  };
  ArchiveError e = err("[effects]\n\ngravity_error = [1e-4, 2e-4]\n");
  EXPECT_EQ(e.line(), 3u);
  EXPECT_NE(e.message().find("dg"), std::string::npos) << e.what();  // lists the parameters
  e = err("[effects]\nwarp_drive = [1]\n");
  EXPECT_EQ(e.field(), "effects.warp_drive");
  e = err("[effects]\nk2_ug_per_g2 = [1, 2, 3]\naccel_quadratic_k2 = [1e-6, 0, 0]\n");
  EXPECT_NE(e.message().find("give it once"), std::string::npos) << e.what();
  e = err("[effects]\nthermal_drift = [0, 0, 0, 0, 0, 1e-8, -5]\n");
  EXPECT_NE(e.message().find("tau"), std::string::npos) << e.what();
}

}  // namespace
// Found by fuzzing: a number beyond double's range in truth.json escaped as nlohmann's
// out_of_range; it is an ArchiveError naming the file like every other bad JSON.
TEST(UnitFile, TruthJsonNumberOutOfRangeIsABadInputError) {
  try {
    parse_truth_json("{\"params\": {\"accel_bias_mps2\": [4e807, 0, 0]}}", "run/truth.json");
    FAIL() << "accepted";
  } catch (const ArchiveError& e) {
    EXPECT_NE(std::string(e.what()).find("run/truth.json"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("invalid JSON"), std::string::npos) << e.what();
  }
}

}  // namespace imucal::db::archive
