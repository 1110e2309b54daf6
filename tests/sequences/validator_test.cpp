// Validator: table limits, rest rules, angle tracking, duration, and the line it blames.
#include "sequences/validator.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "sequences/parser.hpp"

namespace imucal::sequences {
namespace {

Sequence parse(const std::string& text) { return parse_sequence_string(text, "v.toml"); }

// Lines 1-6; steps start at line 7. Keep one key per line so line numbers can be counted.
const std::string kHead =
    "name = \"v\"\n"   // 1
    "[start]\n"        // 2
    "outer_deg = 0\n"  // 3
    "inner_deg = 0\n"  // 4
    "rest_s = 30\n"    // 5
    "[defaults]\n";    // 6

std::string rot_validator(const char* axis, const std::string& angle_kv, const std::string& extra = "") {
  return std::string("[[step]]\nrotate = \"") + axis + "\"\n" + angle_kv + "\n" + extra;
}
std::string rest(double s) { return "[[step]]\nrest_s = " + std::to_string(s) + "\n"; }

bool any_contains(const std::vector<ValidationIssue>& v, const std::string& needle) {
  for (const auto& i : v)
    if (i.message.find(needle) != std::string::npos) return true;
  return false;
}

TEST(Validator, AcceptsAWellFormedSequence) {
  const Sequence s = parse(kHead + rot_validator("inner", "by_deg = 90") + rest(30) +
                           rot_validator("outer", "to_deg = -90") + rest(30));
  const auto issues = validate(s, TableLimits{});
  EXPECT_TRUE(issues.empty()) << issues.front().message;
  EXPECT_NO_THROW(validate_or_throw(s, TableLimits{}));
}

TEST(Validator, RateOverLimitBlamesTheRateKey) {
  // line 7 [[step]], 8 rotate, 9 by_deg, 10 rate_dps
  const Sequence s = parse(kHead + rot_validator("inner", "by_deg = 90", "rate_dps = 25\n") + rest(30));
  const auto issues = validate(s, TableLimits{});
  ASSERT_EQ(issues.size(), 1u);
  EXPECT_EQ(issues[0].line, 10);
  EXPECT_EQ(issues[0].step_index, 0);
  EXPECT_NE(issues[0].message.find("rate"), std::string::npos);
  TableLimits faster;
  faster.max_rate_dps = 30.0;
  EXPECT_TRUE(validate(s, faster).empty());
}

TEST(Validator, DefaultRateOverLimitBlamesTheDefaultsKey) {
  const Sequence s = parse(kHead + "rate_dps = 21\n" + rot_validator("inner", "by_deg = 90") + rest(30));
  const auto issues = validate(s, TableLimits{});
  ASSERT_EQ(issues.size(), 1u);
  EXPECT_EQ(issues[0].line, 7);  // "rate_dps = 21" under [defaults]
}

TEST(Validator, AccelerationOverLimit) {
  const Sequence s = parse(kHead + rot_validator("outer", "by_deg = 90", "accel_dps2 = 12\n") + rest(30));
  const auto issues = validate(s, TableLimits{});
  ASSERT_EQ(issues.size(), 1u);
  EXPECT_EQ(issues[0].line, 10);
  EXPECT_NE(issues[0].message.find("acceleration"), std::string::npos);
}

TEST(Validator, ShortRestsAreRejectedIncludingTheInitialOne) {
  std::string text = kHead + rot_validator("outer", "by_deg = 90") + rest(9.5);  // rest_s at line 11
  text.replace(text.find("rest_s = 30"), 11, "rest_s = 5.0");
  const Sequence s = parse(text);
  const auto issues = validate(s, TableLimits{});
  ASSERT_EQ(issues.size(), 2u);
  EXPECT_EQ(issues[0].line, 5);
  EXPECT_EQ(issues[0].step_index, -1);
  EXPECT_EQ(issues[1].line, 11);
  EXPECT_EQ(issues[1].step_index, 1);
  TableLimits lax;
  lax.min_rest_s = 5.0;
  EXPECT_TRUE(validate(s, lax).empty());
}

TEST(Validator, TracksCommandedAnglesAgainstAxisLimits) {
  TableLimits lim;
  lim.inner_min_deg = -100.0;
  lim.inner_max_deg = 100.0;
  lim.outer_min_deg = -200.0;
  lim.outer_max_deg = 200.0;
  // A rotation step takes 3 lines, a rest 2: step 2k+1 starts at line 7 + 5k.
  // inner: 0 -> 90 (ok) -> 180 (out, step 3, by_deg at line 14) -> to 0 (ok, tracking reset)
  // outer: 0 -> to 190 (ok) -> by 20 = 210 (out, step 9, by_deg at line 29)
  const Sequence s = parse(kHead + rot_validator("inner", "by_deg = 90") + rest(30) +  // steps 1,2
                           rot_validator("inner", "by_deg = 90") + rest(30) +          // steps 3,4
                           rot_validator("inner", "to_deg = 0") + rest(30) +           // steps 5,6
                           rot_validator("outer", "to_deg = 190") + rest(30) +         // steps 7,8
                           rot_validator("outer", "by_deg = 20") + rest(30));          // steps 9,10
  const auto issues = validate(s, lim);
  ASSERT_EQ(issues.size(), 2u);
  EXPECT_EQ(issues[0].step_index, 2);
  EXPECT_EQ(issues[0].line, 14);
  EXPECT_NE(issues[0].message.find("180"), std::string::npos) << issues[0].message;
  EXPECT_EQ(issues[1].step_index, 8);
  EXPECT_EQ(issues[1].line, 29);
  EXPECT_NE(issues[1].message.find("210"), std::string::npos) << issues[1].message;
}

TEST(Validator, StartOutsideLimits) {
  std::string text = kHead + rot_validator("inner", "by_deg = -90") + rest(30);
  text.replace(text.find("inner_deg = 0"), 13, "inner_deg = 300");
  TableLimits lim;
  lim.inner_max_deg = 180.0;
  const auto issues = validate(parse(text), lim);
  // The start (300) is outside, and so is the angle after the first step (300 - 90 = 210).
  ASSERT_EQ(issues.size(), 2u);
  EXPECT_EQ(issues[0].line, 2);  // [start]
  EXPECT_EQ(issues[0].step_index, -1);
  EXPECT_EQ(issues[1].line, 9);
  EXPECT_NE(issues[1].message.find("210"), std::string::npos) << issues[1].message;
}

TEST(Validator, FileLimitsTightenButNeverRelax) {
  const std::string limits = "[limits]\ninner_max_deg = 45\nmax_rate_dps = 50\nmin_rest_s = 20\n";
  const Sequence s =
      parse(kHead + limits + rot_validator("inner", "by_deg = 90", "rate_dps = 25\n") + rest(15));
  const TableLimits eff = effective_limits(TableLimits{}, s.limits);
  EXPECT_EQ(eff.inner_max_deg, 45.0);
  EXPECT_EQ(eff.max_rate_dps, 20.0);  // station's 20 wins over the file's 50
  EXPECT_EQ(eff.min_rest_s, 20.0);    // file's 20 wins over the station's 10
  EXPECT_EQ(eff.inner_min_deg, -std::numeric_limits<double>::infinity());
  const auto issues = validate(s, eff);
  EXPECT_EQ(issues.size(), 3u);  // inner angle 90 > 45, rate 25 > 20, rest 15 < 20
  EXPECT_TRUE(any_contains(issues, "outside its limits"));
  EXPECT_TRUE(any_contains(issues, "rate"));
  EXPECT_TRUE(any_contains(issues, "shorter"));
}

TEST(Validator, TotalDurationFromTrapezoidTiming) {
  // 30 s + (90 deg at 10 deg/s, 10 deg/s^2: 1 s ramp up (5 deg), 8 s cruise (80 deg), 1 s ramp
  // down) + 30 s = 70 s.
  const Sequence s = parse(kHead + rot_validator("outer", "by_deg = 90") + rest(30));
  TableLimits lim;
  lim.max_duration_s = 70.01;
  EXPECT_TRUE(validate(s, lim).empty());
  lim.max_duration_s = 69.99;
  const auto issues = validate(s, lim);
  ASSERT_EQ(issues.size(), 1u);
  EXPECT_EQ(issues[0].step_index, 1);  // exceeded during the final rest
  EXPECT_EQ(issues[0].line, 10);
  EXPECT_NE(issues[0].message.find("duration"), std::string::npos);
  // Triangular: 4 deg at 10 deg/s^2 peaks at sqrt(40) deg/s after sqrt(0.4) s; total 2 sqrt(0.4).
  const Sequence tri = parse(kHead + rot_validator("outer", "by_deg = 4") + rest(30));
  lim.max_duration_s = 60.0 + 2.0 * std::sqrt(0.4) + 1e-6;
  EXPECT_TRUE(validate(tri, lim).empty());
  lim.max_duration_s = 60.0 + 2.0 * std::sqrt(0.4) - 1e-6;
  EXPECT_EQ(validate(tri, lim).size(), 1u);
}

TEST(Validator, EveryRotationNeedsARestAfterIt) {
  // Two rotations back to back, and a final rotation with nothing after it.
  const Sequence s = parse(kHead + rot_validator("outer", "by_deg = 90") +  // step 1 at line 7
                           rot_validator("inner", "by_deg = 90") +          // step 2 at line 10
                           rest(30) +                             // step 3 at line 13
                           rot_validator("inner", "by_deg = -90"));         // step 4 at line 15
  const auto issues = validate(s, TableLimits{});
  ASSERT_EQ(issues.size(), 2u);
  EXPECT_EQ(issues[0].line, 7);
  EXPECT_EQ(issues[0].step_index, 0);
  EXPECT_EQ(issues[1].line, 15);
  EXPECT_EQ(issues[1].step_index, 3);
  EXPECT_NE(issues[0].message.find("rest"), std::string::npos);
}

TEST(Validator, ASequenceWithoutRotationIsRejected) {
  const auto issues = validate(parse(kHead + rest(30)), TableLimits{});
  ASSERT_EQ(issues.size(), 1u);
  EXPECT_EQ(issues[0].line, 0);
  EXPECT_NE(issues[0].message.find("no rotation"), std::string::npos);
}

TEST(Validator, ZeroAngleRotations) {
  const Sequence s = parse(kHead + rot_validator("outer", "by_deg = 0") + rest(30) +  // by_deg: line 9
                           rot_validator("inner", "to_deg = 0") + rest(30) +          // to_deg: line 14
                           rot_validator("inner", "by_deg = 45") + rest(30));
  const auto issues = validate(s, TableLimits{});
  ASSERT_EQ(issues.size(), 2u);
  EXPECT_EQ(issues[0].line, 9);
  EXPECT_EQ(issues[1].line, 14);
  EXPECT_NE(issues[1].message.find("zero angle"), std::string::npos);
}

TEST(Validator, ProgrammaticGarbageGivesIssuesNotCrashes) {
  Sequence s = parse(kHead + rot_validator("outer", "by_deg = 90") + rest(30));
  s.steps[0].rate_dps = std::numeric_limits<double>::quiet_NaN();
  s.steps[1].duration_s = -1.0;
  const auto issues = validate(s, TableLimits{});
  EXPECT_TRUE(any_contains(issues, "rate_dps must be finite"));
  EXPECT_TRUE(any_contains(issues, "rest_s must be finite"));
}

TEST(Validator, ThrowsTheFirstIssueWithFileAndLine) {
  const Sequence s = parse(kHead + rot_validator("outer", "by_deg = 90", "rate_dps = 25\n") + rest(3));
  try {
    validate_or_throw(s, TableLimits{});
    FAIL() << "expected SequenceError";
  } catch (const SequenceError& e) {
    EXPECT_EQ(e.file(), "v.toml");
    EXPECT_EQ(e.line(), 10);
    EXPECT_NE(std::string(e.what()).find("v.toml:10: "), std::string::npos);
    EXPECT_NE(e.message().find("and 1 more issue"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace imucal::sequences
