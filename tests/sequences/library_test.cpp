// Library: name resolution, hashing, load_profile, and the shipped sequences' content: they
// parse, validate, fit their time budgets, and exercise every body axis (checked with the table
// geometry formula of calib/core/table_model.hpp, evaluated here independently of calib's code).
#include "sequences/library.hpp"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <set>
#include <string>

#include "calib/core/table_model.hpp"
#include "sequences/parser.hpp"
#include "sequences/profile_generator.hpp"

namespace imucal::sequences {
namespace {
namespace fs = std::filesystem;

// ---------------------------------------------------------------- SHA-256
TEST(Sha256, KnownDigests) {
  // FIPS 180-2 / NIST example vectors.
  EXPECT_EQ(sha256_hex(""), "e3b0c44298fc1c149afbf4c8996fb92427ae41e4649b934ca495991b7852b855");
  EXPECT_EQ(sha256_hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
  EXPECT_EQ(sha256_hex("abcdbcdecdefdefgefghfghighijhijkijkljklmklmnlmnomnopnopq"),
            "248d6a61d20638b8e5c026930c3e6039a33ce45964ff2167f6ecedd419db06c1");
  EXPECT_EQ(
      sha256_hex("abcdefghbcdefghicdefghijdefghijkefghijklfghijklmghijklmnhijklmnoijklmnopjklmnopq"
                 "klmnopqrlmnopqrsmnopqrstnopqrstu"),
      "cf5b16a778af8380036ce59e7b0492370b249b11e8f07a51afac45037afee9d1");
  EXPECT_EQ(sha256_hex(std::string(1000000, 'a')),
            "cdc76e5c9914fb9281a1c7e284d73e67f1809a48a497200e046d39ccc7112cd0");
}

// Runs coreutils' sha256sum on a file: an independent implementation for the padding edge cases.
std::string sha256sum_tool(const std::string& path) {
  const std::string cmd = "sha256sum '" + path + "'";
  FILE* p = popen(cmd.c_str(), "r");
  if (!p) return "popen failed";
  char buf[128] = {};
  const size_t n = fread(buf, 1, 64, p);
  pclose(p);
  return std::string(buf, n);
}

fs::path temp_file(const std::string& name) { return fs::temp_directory_path() / name; }

void write_file(const fs::path& p, const std::string& bytes) {
  std::ofstream out(p, std::ios::binary);
  out << bytes;
}

TEST(Sha256, PaddingBoundariesAgreeWithSha256sum) {
  const fs::path p = temp_file("imucal_sha_boundary.bin");
  for (size_t len : {1u, 55u, 56u, 57u, 63u, 64u, 65u, 119u, 120u, 128u, 1000u}) {
    std::string bytes(len, '\0');
    for (size_t i = 0; i < len; ++i) bytes[i] = static_cast<char>((i * 131 + 7) & 0xff);
    write_file(p, bytes);
    EXPECT_EQ(sequence_hash(p.string()), sha256sum_tool(p.string())) << "length " << len;
    EXPECT_EQ(sequence_hash(p.string()), sha256_hex(bytes));
  }
  fs::remove(p);
}

TEST(Sha256, SequenceHashTracksTheFileBytes) {
  const fs::path p = temp_file("imucal_sha_seq.toml");
  write_file(p, "name = \"a\"\n");
  const std::string h1 = sequence_hash(p.string());
  write_file(p, "name = \"b\"\n");
  EXPECT_NE(sequence_hash(p.string()), h1);
  fs::remove(p);
  EXPECT_THROW(sequence_hash(p.string()), SequenceError);
}

// ---------------------------------------------------------------- resolution
TEST(Library, ListsTheShippedSequences) {
  const auto names = available_sequences();
  for (const char* n : {"factory-std", "factory-fast", "pos19", "short"})
    EXPECT_NE(std::find(names.begin(), names.end(), n), names.end()) << n;
  EXPECT_TRUE(std::is_sorted(names.begin(), names.end()));
}

TEST(Library, ResolvesNamesAndPaths) {
  const std::string expected = (fs::path(IMUCAL_SEQUENCE_DIR) / "short.toml").string();
  EXPECT_EQ(resolve_sequence("short"), expected);
  EXPECT_EQ(resolve_sequence("short.toml"), expected);
  EXPECT_EQ(resolve_sequence(expected), expected);  // an existing path is returned unchanged
  const fs::path own = temp_file("imucal_own_sequence.toml");
  write_file(own, "x");
  EXPECT_EQ(resolve_sequence(own.string()), own.string());
  fs::remove(own);
}

TEST(Library, UnknownNameListsTheAvailableOnes) {
  for (const std::string bad : {"nonexistent", "/no/such/dir/short.toml", ""}) {
    try {
      resolve_sequence(bad);
      FAIL() << "expected SequenceError for '" << bad << "'";
    } catch (const SequenceError& e) {
      EXPECT_EQ(e.file(), bad);
      const std::string msg = e.what();
      for (const char* n : {"factory-std", "pos19", "short"})
        EXPECT_NE(msg.find(n), std::string::npos) << msg;
      // Issue #19 item 9: no line number for a missing file ("shrot:0: ..."); a bare name is an
      // unknown sequence, named as the user typed it.
      EXPECT_EQ(msg.find(":0:"), std::string::npos) << msg;
      if (bad.find('/') == std::string::npos)
        EXPECT_EQ(msg.rfind("unknown sequence '" + bad + "' (library ", 0), 0u) << msg;
      else
        EXPECT_EQ(msg.rfind(bad + ": no such sequence file (library ", 0), 0u) << msg;
    }
  }
}

TEST(Library, EnvironmentOverridesTheDirectory) {
  const fs::path dir = fs::temp_directory_path() / "imucal_seq_env_dir";
  fs::create_directories(dir);
  write_file(dir / "mine.toml",
             "name = \"mine\"\n[start]\nrest_s = 20\n[[step]]\nrotate = \"outer\"\nby_deg = 45\n"
             "[[step]]\nrest_s = 20\n");
  setenv("IMUCAL_SEQUENCE_DIR", dir.c_str(), 1);
  const auto names = available_sequences();
  const std::string resolved = resolve_sequence("mine");
  const MotionProfile p = load_profile("mine");
  unsetenv("IMUCAL_SEQUENCE_DIR");
  fs::remove_all(dir);
  EXPECT_EQ(names, std::vector<std::string>{"mine"});
  EXPECT_EQ(resolved, (dir / "mine.toml").string());
  EXPECT_EQ(p.name, "mine");
  EXPECT_EQ(sequence_dir(), IMUCAL_SEQUENCE_DIR);
}

// stationd's configured directory (set_sequence_dir) wins over the environment; "" restores the
// lookup.
TEST(Library, ConfiguredDirectoryWinsOverTheEnvironment) {
  const fs::path dir = fs::temp_directory_path() / "imucal_seq_cfg_dir";
  fs::create_directories(dir);
  write_file(dir / "cfg.toml", "x");
  setenv("IMUCAL_SEQUENCE_DIR", "/nonexistent-env-dir", 1);
  set_sequence_dir(dir.string());
  const std::string configured = sequence_dir();
  const std::string resolved = resolve_sequence("cfg");
  set_sequence_dir("");
  const std::string env = sequence_dir();
  unsetenv("IMUCAL_SEQUENCE_DIR");
  fs::remove_all(dir);
  EXPECT_EQ(configured, dir.string());
  EXPECT_EQ(resolved, (dir / "cfg.toml").string());
  EXPECT_EQ(env, "/nonexistent-env-dir");
  EXPECT_EQ(sequence_dir(), IMUCAL_SEQUENCE_DIR);
}

TEST(Library, LoadProfileRejectsInvalidSequencesWithFileAndLine) {
  const fs::path p = temp_file("imucal_invalid_seq.toml");
  // Parses, but the rotation is not followed by a rest (validator), line 4.
  write_file(p,
             "name = \"bad\"\n[start]\nrest_s = 20\n[[step]]\nrotate = \"outer\"\nby_deg = 45\n");
  try {
    load_profile(p.string());
    FAIL() << "expected SequenceError";
  } catch (const SequenceError& e) {
    EXPECT_EQ(e.file(), p.string());
    EXPECT_EQ(e.line(), 4);
  }
  // The file's [limits] tighten the default station limits: 45 deg > inner_max_deg 30 (line 8).
  write_file(p,
             "name = \"bad\"\n[start]\nrest_s = 20\n[limits]\ninner_max_deg = 30\n"
             "[[step]]\nrotate = \"inner\"\nby_deg = 45\n[[step]]\nrest_s = 20\n");
  try {
    load_profile(p.string());
    FAIL() << "expected SequenceError";
  } catch (const SequenceError& e) {
    EXPECT_EQ(e.line(), 8);
  }
  fs::remove(p);
}

// ---------------------------------------------------------------- shipped sequences
// Table geometry formula of calib/core/table_model.hpp, evaluated here from TableGeometry's fields:
// C_bn = Rz(heading) R(a_outer, outer) R(a_inner, inner) C_bp.
Eigen::Matrix3d rot(const Eigen::Vector3d& axis, double angle) {
  return Eigen::AngleAxisd(angle, axis.normalized()).toRotationMatrix();
}
Eigen::Matrix3d C_bn_of(const calib::core::TableGeometry& g, double outer, double inner) {
  return rot(Eigen::Vector3d::UnitZ(), g.heading_rad) * rot(g.outer_axis_t, outer) *
         rot(g.inner_axis_o, inner) * g.C_bp;
}
// Body rate w.r.t. n, in body axes: outer rate about a_outer (in n), inner rate about the inner
// axis carried by the outer gimbal.
Eigen::Vector3d w_nb_b_of(const calib::core::TableGeometry& g, const TableState& s) {
  const Eigen::Matrix3d C_tn = rot(Eigen::Vector3d::UnitZ(), g.heading_rad);
  const Eigen::Vector3d w_n =
      C_tn * g.outer_axis_t.normalized() * s.outer_rate_radps +
      C_tn * rot(g.outer_axis_t, s.outer_rad) * g.inner_axis_o.normalized() * s.inner_rate_radps;
  return C_bn_of(g, s.outer_rad, s.inner_rad).transpose() * w_n;
}

struct Coverage {
  bool down[3] = {}, up[3] = {};              ///< body axis k along +down / -down at some rest
  bool about_pos[3] = {}, about_neg[3] = {};  ///< some rotation about body +k / -k
  int rests = 0;
  double min_rest_s = 1e300, max_rest_s = 0.0;
};

Coverage coverage(const MotionProfile& p, const calib::core::TableGeometry& g) {
  Coverage c;
  for (const ProfileSegment& s : p.segments) {
    const TableState mid = p.at(0.5 * (s.t0_s + s.t1_s));
    if (s.kind == SegmentKind::kRest) {
      ++c.rests;
      c.min_rest_s = std::min(c.min_rest_s, s.t1_s - s.t0_s);
      c.max_rest_s = std::max(c.max_rest_s, s.t1_s - s.t0_s);
      const Eigen::Matrix3d C = C_bn_of(g, mid.outer_rad, mid.inner_rad);
      for (int k = 0; k < 3; ++k) {
        const double d = C(2, k);  // down component of body axis k
        if (d > 0.999) c.down[k] = true;
        if (d < -0.999) c.up[k] = true;
      }
    } else {
      const Eigen::Vector3d w = w_nb_b_of(g, mid);
      const Eigen::Vector3d u = w.normalized();
      for (int k = 0; k < 3; ++k) {
        if (u(k) > 0.999) c.about_pos[k] = true;
        if (u(k) < -0.999) c.about_neg[k] = true;
      }
    }
  }
  return c;
}

struct Shipped {
  const char* name;
  double max_duration_s;
  double min_rest_s, max_rest_s;
};

class ShippedSequences : public ::testing::TestWithParam<Shipped> {};

TEST_P(ShippedSequences, ParseValidateAndFitTheirBudget) {
  const Shipped& sh = GetParam();
  const std::string path = resolve_sequence(sh.name);
  const Sequence seq = parse_sequence_file(path);
  EXPECT_EQ(seq.name, sh.name);
  EXPECT_FALSE(seq.description.empty());
  const auto issues = validate(seq, effective_limits(TableLimits{}, seq.limits));
  for (const auto& i : issues) ADD_FAILURE() << path << ":" << i.line << ": " << i.message;
  const MotionProfile p = load_profile(sh.name);
  EXPECT_LE(p.duration_s(), sh.max_duration_s);
  const Coverage c = coverage(p, calib::core::TableGeometry{});
  EXPECT_GE(c.min_rest_s, sh.min_rest_s);
  EXPECT_LE(c.max_rest_s, sh.max_rest_s);
  std::printf("[ %s ] duration %.1f s (%.1f min), %d rests, %zu segments\n", sh.name,
              p.duration_s(), p.duration_s() / 60.0, c.rests, p.segments.size());
}

TEST_P(ShippedSequences, ExerciseEveryBodyAxisWithTheDefaultGeometry) {
  const Coverage c = coverage(load_profile(GetParam().name), calib::core::TableGeometry{});
  const char* axis[3] = {"x", "y", "z"};
  for (int k = 0; k < 3; ++k) {
    // Gyro scale factors and misalignments: rotations about each body axis, both senses.
    EXPECT_TRUE(c.about_pos[k]) << "no rotation about body +" << axis[k];
    EXPECT_TRUE(c.about_neg[k]) << "no rotation about body -" << axis[k];
  }
  // Accelerometer scale factors and misalignments: each body axis sees +1 g and -1 g at rest.
  for (int k = 0; k < 3; ++k) {
    EXPECT_TRUE(c.down[k]) << "body " << axis[k] << " never points down at rest";
    EXPECT_TRUE(c.up[k]) << "body " << axis[k] << " never points up at rest";
  }
}

INSTANTIATE_TEST_SUITE_P(All, ShippedSequences,
                         ::testing::Values(Shipped{"factory-std", 3600.0, 60.0, 120.0},
                                           Shipped{"factory-fast", 0.6 * 2277.0, 10.0, 200.0},
                                           Shipped{"short", 600.0, 15.0, 60.0},
                                           Shipped{"pos19", 5400.0, 10.0, 600.0}),
                         [](const auto& info) {
                           std::string n = info.param.name;
                           std::replace(n.begin(), n.end(), '-', '_');
                           return n;
                         });

TEST(ShippedSequencesPos19, HasNineteenDistinctStaticPositions) {
  const MotionProfile p = load_profile("pos19");
  std::vector<Eigen::Matrix3d> poses;
  for (const ProfileSegment& s : p.segments) {
    if (s.kind != SegmentKind::kRest) continue;
    const Eigen::Matrix3d C =
        C_bn_of(calib::core::TableGeometry{}, s.outer.angle0_rad, s.inner.angle0_rad);
    for (const auto& q : poses) EXPECT_GT((C - q).norm(), 0.1) << "repeated position";
    poses.push_back(C);
  }
  EXPECT_EQ(poses.size(), 19u);
  // "Various tilts": the angle between body z and down takes 0, 45, 90, 135 and 180 deg.
  std::set<long> tilts;
  for (const auto& C : poses)
    tilts.insert(std::lround(std::acos(std::clamp(C(2, 2), -1.0, 1.0)) * 180.0 / M_PI));
  EXPECT_EQ(tilts, (std::set<long>{0, 45, 90, 135, 180}));
}

// The geometry formula used above, evaluated independently of calib/, agrees with calib's
// TableModel (which the simulator and estimators use) for the default and a rotated geometry.
TEST(Geometry, IndependentFormulaMatchesTableModel) {
  calib::core::TableGeometry tilted;
  tilted.heading_rad = 0.3;
  tilted.C_bp = rot(Eigen::Vector3d(1.0, 2.0, 3.0), 0.2);
  for (const calib::core::TableGeometry& g : {calib::core::TableGeometry{}, tilted}) {
    const calib::core::TableModel model(g);
    for (double o = -200.0; o <= 200.0; o += 37.0) {
      for (double i = -200.0; i <= 200.0; i += 41.0) {
        TableState s;
        s.outer_rad = o * M_PI / 180.0;
        s.inner_rad = i * M_PI / 180.0;
        s.outer_rate_radps = 0.1;
        s.inner_rate_radps = -0.07;
        EXPECT_LT(
            (model.C_bn(s.outer_rad, s.inner_rad) - C_bn_of(g, s.outer_rad, s.inner_rad)).norm(),
            1e-12);
        EXPECT_LT((model.w_nb_b(s) - w_nb_b_of(g, s)).norm(), 1e-12);
      }
    }
  }
}

}  // namespace
}  // namespace imucal::sequences
