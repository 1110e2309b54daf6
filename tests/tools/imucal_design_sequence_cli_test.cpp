// `imucal design-sequence` as a user meets it (issue #23 item 2): bad input names the option or
// file, exits non-zero and writes nothing (an existing --out file is left as it was); a design is
// a sequence file the parser and validator accept, of the time asked, whose header states the
// command that made it and whose steps name the pose reached; the report says what was traded per
// parameter group, and progress lines go to stderr.
#include <gtest/gtest.h>

#include <filesystem>
#include <string>

#include "sequences/parser.hpp"
#include "sequences/profile_generator.hpp"
#include "sequences/validator.hpp"
#include "tests/support/imucal_cli.hpp"

namespace {

namespace fs = std::filesystem;
using imucal::test_support::run_imucal;
using imucal::test_support::slurp;

fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::temp_directory_path() / ("imucal_design_" + name);
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

TEST(DesignSequenceCli, BadInputNamesTheOptionExitsNonZeroAndWritesNothing) {
  const fs::path dir = fresh_dir("bad");
  const fs::path out = dir / "kept.toml";
  {
    std::ofstream f(out);
    f << "the user's own file\n";
  }
  struct Case {
    std::string args, says;
  };
  const Case cases[] = {
      {"--like factory-std", "--time-s"},
      {"--like nosuch --time-s 1000", "--like: unknown sequence 'nosuch'"},
      {"--like factory-std --time-s 300", "--time-s: a tour of 21 rotations needs at least"},
      {"--like factory-std --time-s 9000", "--time-s: table time 9000 s outside"},
      {"--like factory-std --time-s 1000 --factor 2", "--factor requires --target-from"},
      {"--like factory-std --time-s 1000 --target-from short", "excludes"},
      {"--like factory-std --target-from nosuch --factor 1.2", "--target-from: unknown sequence"},
  };
  for (const Case& c : cases) {
    const auto r = run_imucal("design-sequence " + c.args + " --out " + out.string());
    EXPECT_NE(r.code, 0) << c.args << "\n" << r.out;
    EXPECT_NE(r.out.find(c.says), std::string::npos) << c.args << "\n" << r.out;
    EXPECT_EQ(slurp(out), "the user's own file\n") << c.args;
  }
  const auto r = run_imucal("design-sequence --time-s 1000 --out /no/such/dir/x.toml");
  EXPECT_NE(r.code, 0);
  EXPECT_NE(r.out.find("--out: directory '/no/such/dir' does not exist"), std::string::npos)
      << r.out;
  EXPECT_EQ(fs::directory_iterator(dir) != fs::directory_iterator(), true);
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);
}

TEST(DesignSequenceCli, WritesAValidSequenceOfTheTimeAskedAndSaysWhatItTraded) {
  const fs::path dir = fresh_dir("ok");
  const fs::path out = dir / "short-fast.toml";
  // Without the effects' analysis (its cost; tests/calib/factory_fast_test.cpp holds a design's
  // effects): a few seconds.
  const std::string args =
      "design-sequence --like short --time-s 360 --no-effects --out " + out.string();
  const auto r = imucal::test_support::run_command(std::string(IMUCAL_BIN_DIR) + "/imucal " + args +
                                                   " 2>" + (dir / "stderr.txt").string());
  // 0: every target met; 3: designed and written, a target missed (said so).
  EXPECT_TRUE(r.code == 0 || r.code == 3) << r.out;
  const std::string err = slurp(dir / "stderr.txt");
  EXPECT_NE(err.find("design-sequence ["), std::string::npos) << "no progress line:\n" << err;
  for (const char* s : {"designed short-fast: 360.0 s of table time", "per parameter group",
                        "accel_bias", "gyro_misalignment", "table_misalignment", "/floor",
                        "design/cut", "effects: not analysed (--no-effects)", "wrote "})
    EXPECT_NE(r.out.find(s), std::string::npos) << s << "\n" << r.out;

  const std::string text = slurp(out);
  EXPECT_NE(text.find("#   imucal " + args), std::string::npos) << text;
  EXPECT_NE(text.find("[[step]]  # ("), std::string::npos) << "no pose comments:\n" << text;
  const auto seq = imucal::sequences::parse_sequence_file(out.string());
  EXPECT_EQ(seq.name, "short-fast");
  const auto issues = imucal::sequences::validate(
      seq, imucal::sequences::effective_limits(imucal::sequences::TableLimits{}, seq.limits));
  for (const auto& i : issues) ADD_FAILURE() << i.message;
  EXPECT_NEAR(imucal::sequences::generate_profile(seq).duration_s(), 360.0, 0.11);
  // Only the file asked for: the atomic write leaves no temporary behind.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 2);
}

}  // namespace
