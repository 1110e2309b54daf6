// Parser: schema, defaults, and that every error names the origin and the offending line.
#include "sequences/parser.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace imucal::sequences {
namespace {

// Line numbers below are counted in these strings; keep them one key per line.
const char* kHeader =
    "name = \"t\"\n"    // 1
    "[start]\n"         // 2
    "rest_s = 30.0\n";  // 3

// Runs the parser on text and returns the error; fails the test if it parses.
SequenceError parse_error(const std::string& text) {
  try {
    parse_sequence_string(text, "mem.toml");
  } catch (const SequenceError& e) {
    return e;
  }
  ADD_FAILURE() << "expected a SequenceError for:\n" << text;
  return SequenceError("", -1, "");
}

TEST(Parser, ParsesAllFieldsAndAppliesDefaults) {
  const std::string text =
      "name = \"demo\"\n"              // 1
      "description = \"two steps\"\n"  // 2
      "[start]\n"                      // 3
      "outer_deg = 10\n"               // 4  integer accepted as number
      "inner_deg = -5.5\n"             // 5
      "rest_s = 30.0\n"                // 6
      "[defaults]\n"                   // 7
      "rate_dps = 7.0\n"               // 8
      "[limits]\n"                     // 9
      "inner_min_deg = -180.0\n"       // 10
      "max_rate_dps = 15.0\n"          // 11
      "[[step]]\n"                     // 12
      "rotate = \"inner\"\n"           // 13
      "by_deg = 90.0\n"                // 14
      "[[step]]\n"                     // 15
      "rest_s = 20\n"                  // 16
      "[[step]]\n"                     // 17
      "rotate = \"outer\"\n"           // 18
      "to_deg = -90.0\n"               // 19
      "rate_dps = 5.0\n"               // 20
      "accel_dps2 = 2.5\n"             // 21
      "[[step]]\n"                     // 22
      "rest_s = 20.0\n";               // 23
  const Sequence s = parse_sequence_string(text, "demo.toml");
  EXPECT_EQ(s.name, "demo");
  EXPECT_EQ(s.description, "two steps");
  EXPECT_EQ(s.source_path, "demo.toml");
  EXPECT_DOUBLE_EQ(s.start.outer_deg, 10.0);
  EXPECT_DOUBLE_EQ(s.start.inner_deg, -5.5);
  EXPECT_DOUBLE_EQ(s.start.rest_s, 30.0);
  EXPECT_EQ(s.start.line, 3);
  EXPECT_EQ(s.start.rest_line, 6);
  ASSERT_TRUE(s.limits.inner_min_deg.has_value());
  EXPECT_DOUBLE_EQ(*s.limits.inner_min_deg, -180.0);
  EXPECT_FALSE(s.limits.inner_max_deg.has_value());
  EXPECT_DOUBLE_EQ(s.limits.max_rate_dps.value_or(0.0), 15.0);
  EXPECT_EQ(s.limits.line, 9);
  ASSERT_EQ(s.steps.size(), 4u);

  const Step& r1 = s.steps[0];
  EXPECT_EQ(r1.kind, StepKind::kRotate);
  EXPECT_EQ(r1.axis, Axis::kInner);
  EXPECT_DOUBLE_EQ(r1.by_deg.value_or(0.0), 90.0);
  EXPECT_FALSE(r1.to_deg.has_value());
  EXPECT_DOUBLE_EQ(r1.rate_dps, 7.0);     // from [defaults]
  EXPECT_DOUBLE_EQ(r1.accel_dps2, 10.0);  // built-in default (FORMAT.md)
  EXPECT_EQ(r1.line, 12);
  EXPECT_EQ(r1.value_line, 14);
  EXPECT_EQ(r1.rate_line, 8);    // blame [defaults] for a default rate
  EXPECT_EQ(r1.accel_line, 12);  // no key anywhere: the step header

  EXPECT_EQ(s.steps[1].kind, StepKind::kRest);
  EXPECT_DOUBLE_EQ(s.steps[1].duration_s, 20.0);
  EXPECT_EQ(s.steps[1].line, 15);

  const Step& r2 = s.steps[2];
  EXPECT_EQ(r2.axis, Axis::kOuter);
  EXPECT_DOUBLE_EQ(r2.to_deg.value_or(0.0), -90.0);
  EXPECT_FALSE(r2.by_deg.has_value());
  EXPECT_DOUBLE_EQ(r2.rate_dps, 5.0);
  EXPECT_DOUBLE_EQ(r2.accel_dps2, 2.5);
  EXPECT_EQ(r2.rate_line, 20);
  EXPECT_EQ(r2.accel_line, 21);
}

TEST(Parser, StartAnglesDefaultToZero) {
  const Sequence s = parse_sequence_string(
      std::string(kHeader) + "[[step]]\nrotate = \"outer\"\nby_deg = 90\n", "x.toml");
  EXPECT_EQ(s.start.outer_deg, 0.0);
  EXPECT_EQ(s.start.inner_deg, 0.0);
  EXPECT_TRUE(s.description.empty());
  EXPECT_EQ(s.steps.at(0).rate_dps, 10.0);
  EXPECT_EQ(s.steps.at(0).accel_dps2, 10.0);
}

TEST(Parser, InlineArrayOfTablesIsAccepted) {
  // A top-level key must come before the first [table] header, hence the order.
  const Sequence s = parse_sequence_string(
      "name = \"t\"\nstep = [ { rotate = \"inner\", by_deg = -45 }, { rest_s = 12 } ]\n"
      "[start]\nrest_s = 30\n",
      "x.toml");
  ASSERT_EQ(s.steps.size(), 2u);
  EXPECT_DOUBLE_EQ(*s.steps[0].by_deg, -45.0);
  EXPECT_DOUBLE_EQ(s.steps[1].duration_s, 12.0);
}

struct BadCase {
  const char* label;
  std::string text;
  int line;
  const char* must_contain;
};

class ParserErrors : public ::testing::TestWithParam<BadCase> {};

TEST_P(ParserErrors, NamesFileLineAndCause) {
  const BadCase& c = GetParam();
  const SequenceError e = parse_error(c.text);
  EXPECT_EQ(e.file(), "mem.toml") << c.label;
  EXPECT_EQ(e.line(), c.line) << c.label << ": " << e.what();
  EXPECT_NE(std::string(e.what()).find(c.must_contain), std::string::npos)
      << c.label << ": " << e.what();
  // A whole-file problem (line 0) reads "mem.toml: ..." — no ":0:" (issue #19 item 9).
  const std::string prefix =
      c.line > 0 ? "mem.toml:" + std::to_string(c.line) + ": " : std::string("mem.toml: ");
  EXPECT_EQ(std::string(e.what()).rfind(prefix, 0), 0u) << e.what();
}

const std::string H = kHeader;  // lines 1-3

INSTANTIATE_TEST_SUITE_P(
    Cases, ParserErrors,
    ::testing::Values(
        BadCase{"unknown key in step",
                H + "[[step]]\nrotate = \"inner\"\nby_deg = 90\nrate_dsp = 5\n", 7, "'rate_dsp'"},
        BadCase{"unknown top-level key", H + "author = \"me\"\n", 4, "'author'"},
        BadCase{"unknown key in start (earliest line wins)",
                "name = \"t\"\n[start]\nzzz = 1\nrest_s = 3\naaa = 2\n", 3, "'zzz'"},
        BadCase{"unknown table", H + "[timing]\nx = 1\n", 4, "'timing'"},
        BadCase{"missing name", "[start]\nrest_s = 3\n[[step]]\nrest_s = 3\n", 0, "'name'"},
        BadCase{"missing start", "name = \"t\"\n[[step]]\nrest_s = 3\n", 0, "[start]"},
        BadCase{"missing start.rest_s",
                "name = \"t\"\n[start]\nouter_deg = 0\n[[step]]\nrest_s = 1\n", 2, "'rest_s'"},
        BadCase{"missing steps", H, 0, "[[step]]"},
        BadCase{"empty step array", "name = \"t\"\nstep = []\n[start]\nrest_s = 3\n", 2, "empty"},
        BadCase{"step is not an array", "name = \"t\"\nstep = 5\n[start]\nrest_s = 3\n", 2,
                "array"},
        BadCase{"name of wrong type", "name = 5\n[start]\nrest_s = 3\n[[step]]\nrest_s = 3\n", 1,
                "string"},
        BadCase{"empty name", "name = \"\"\n[start]\nrest_s = 3\n[[step]]\nrest_s = 3\n", 1,
                "empty"},
        BadCase{"start not a table", "name = \"t\"\nstart = 3\n[[step]]\nrest_s = 3\n", 2, "table"},
        BadCase{"rate of wrong type",
                H + "[[step]]\nrotate = \"inner\"\nby_deg = 90\nrate_dps = \"fast\"\n", 7,
                "number"},
        BadCase{"axis of wrong type", H + "[[step]]\nrotate = 1\nby_deg = 90\n", 5, "string"},
        BadCase{"negative rate", H + "[[step]]\nrotate = \"inner\"\nby_deg = 90\nrate_dps = -1\n",
                7, "> 0"},
        BadCase{"zero accel", H + "[[step]]\nrotate = \"outer\"\nby_deg = 90\naccel_dps2 = 0\n", 7,
                "> 0"},
        BadCase{"zero rest", H + "[[step]]\nrest_s = 0.0\n", 5, "> 0"},
        BadCase{"negative initial rest",
                "name = \"t\"\n[start]\nrest_s = -3\n[[step]]\nrest_s = 3\n", 3, "> 0"},
        BadCase{"negative default rate", H + "[defaults]\nrate_dps = -10\n", 5, "> 0"},
        BadCase{"both by_deg and to_deg",
                H + "[[step]]\nrotate = \"inner\"\nby_deg = 90\nto_deg = 90\n", 7, "both"},
        BadCase{"neither by_deg nor to_deg", H + "[[step]]\nrotate = \"inner\"\n", 4, "by_deg"},
        BadCase{"nan angle", H + "[[step]]\nrotate = \"inner\"\nby_deg = nan\n", 6, "finite"},
        BadCase{"inf rest", H + "[[step]]\nrest_s = inf\n", 5, "finite"},
        BadCase{"nan start angle", "name = \"t\"\n[start]\nouter_deg = -nan\nrest_s = 3\n", 3,
                "finite"},
        BadCase{"unknown axis", H + "[[step]]\nrotate = \"middle\"\nby_deg = 90\n", 5, "'middle'"},
        BadCase{"step without action", H + "[[step]]\nrate_dps = 5\n", 4, "no action"},
        BadCase{"rotate and rest in one step",
                H + "[[step]]\nrotate = \"inner\"\nby_deg = 9\nrest_s = 9\n", 4, "both"},
        BadCase{"rate in a rest step", H + "[[step]]\nrest_s = 10\nrate_dps = 5\n", 6, "rest step"},
        BadCase{"limits min >= max",
                H + "[limits]\ninner_min_deg = 10\ninner_max_deg = -10\n[[step]]\nrest_s = 3\n", 6,
                "inner_max_deg"},
        BadCase{"truncated file", H + "[[step]]\nrotate = \"inn", 5, "syntax"},
        BadCase{"unterminated array", H + "x = [1,\n2,\n", 5, "end-of-file"},
        BadCase{"duplicate key", H + "[[step]]\nrest_s = 3\nrest_s = 4\n", 6, "syntax"},
        BadCase{"malformed header", H + "[[step]\nrest_s = 3\n", 4, "syntax"}));

TEST(Parser, FileErrorsNameThePath) {
  const std::string missing =
      (std::filesystem::temp_directory_path() / "imucal-does-not-exist.toml").string();
  try {
    parse_sequence_file(missing);
    FAIL() << "expected SequenceError";
  } catch (const SequenceError& e) {
    EXPECT_EQ(e.file(), missing);
    EXPECT_EQ(e.line(), 0);
  }
}

TEST(Parser, FileParsesLikeString) {
  const std::string path =
      (std::filesystem::temp_directory_path() / "imucal_parser_test_tmp.toml").string();
  {
    std::ofstream out(path, std::ios::binary);
    out << kHeader
        << "[[step]]\nrotate = \"outer\"\nby_deg = 90\n[[step]]\nrest_s = 3\nbogus = 1\n";
  }
  try {
    parse_sequence_file(path);
    FAIL() << "expected SequenceError";
  } catch (const SequenceError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.line(), 9);
    EXPECT_NE(e.message().find("'bogus'"), std::string::npos);
  }
  std::remove(path.c_str());
}

// Every truncation of every shipped file either parses or fails with a SequenceError whose line
// lies inside the truncated text: no crash, no other exception type, no line out of range.
TEST(Parser, EveryTruncationOfTheShippedFilesFailsCleanly) {
  for (const char* name : {"factory-std", "factory-fast", "short", "pos19"}) {
    const std::string path = std::string(IMUCAL_SEQUENCE_DIR) + "/" + name + ".toml";
    std::ifstream in(path, std::ios::binary);
    ASSERT_TRUE(in) << path;
    const std::string full((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ASSERT_GT(full.size(), 100u);
    int failures = 0;
    for (size_t n = 0; n < full.size(); ++n) {
      const std::string prefix = full.substr(0, n);
      const int lines = 1 + static_cast<int>(std::count(prefix.begin(), prefix.end(), '\n'));
      try {
        parse_sequence_string(prefix, "cut.toml");
      } catch (const SequenceError& e) {
        ++failures;
        ASSERT_GE(e.line(), 0) << n;
        ASSERT_LE(e.line(), lines) << "prefix of " << n << " bytes: " << e.what();
      }
    }
    EXPECT_GT(failures, 0);
    EXPECT_NO_THROW(parse_sequence_string(full, path));
  }
}

}  // namespace
}  // namespace imucal::sequences
