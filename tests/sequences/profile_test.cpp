// Profile generator: exact endpoints, rate/accel bounds, continuity, kinematic consistency.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "sequences/parser.hpp"
#include "sequences/profile_generator.hpp"

namespace imucal::sequences {
namespace {

constexpr double kD2R = M_PI / 180.0;

// Angle / rate of one axis at the END of a segment (the evaluator's quadratic at tau = length).
double end_angle(const ProfileSegment& s, const AxisMotion& m) {
  const double tau = s.t1_s - s.t0_s;
  return m.angle0_rad + m.rate0_radps * tau + 0.5 * m.accel_radps2 * tau * tau;
}
double end_rate(const ProfileSegment& s, const AxisMotion& m) {
  return m.rate0_radps + m.accel_radps2 * (s.t1_s - s.t0_s);
}

// start (10, -20); inner +90; outer to -45 at 5 deg/s, 4 deg/s^2; inner +3 (triangular).
const char* kText =
    "name = \"p\"\n"
    "[start]\nouter_deg = 10\ninner_deg = -20\nrest_s = 30\n"
    "[[step]]\nrotate = \"inner\"\nby_deg = 90\n"
    "[[step]]\nrest_s = 20\n"
    "[[step]]\nrotate = \"outer\"\nto_deg = -45\nrate_dps = 5\naccel_dps2 = 4\n"
    "[[step]]\nrest_s = 20\n"
    "[[step]]\nrotate = \"inner\"\nby_deg = 3\n"
    "[[step]]\nrest_s = 15\n";

class ProfileFixture : public ::testing::Test {
 protected:
  Sequence seq = parse_sequence_string(kText, "p.toml");
  MotionProfile prof = generate_profile(seq);
};

TEST_F(ProfileFixture, SegmentsAreContiguousOrderedAndLabelled) {
  ASSERT_FALSE(prof.segments.empty());
  EXPECT_EQ(prof.name, "p");
  EXPECT_EQ(prof.segments.front().t0_s, 0.0);
  for (size_t k = 0; k < prof.segments.size(); ++k) {
    const ProfileSegment& s = prof.segments[k];
    EXPECT_GT(s.t1_s, s.t0_s) << k;
    if (k + 1 < prof.segments.size()) {
      EXPECT_EQ(s.t1_s, prof.segments[k + 1].t0_s) << k;
    }
  }
  // initial rest, 3 (trapezoid), rest, 3 (trapezoid), rest, 2 (triangle), rest
  const int expected_steps[] = {-1, 0, 0, 0, 1, 2, 2, 2, 3, 4, 4, 5};
  ASSERT_EQ(prof.segments.size(), std::size(expected_steps));
  for (size_t k = 0; k < prof.segments.size(); ++k) {
    const ProfileSegment& s = prof.segments[k];
    EXPECT_EQ(s.step_index, expected_steps[k]) << k;
    const bool rest = expected_steps[k] < 0 || seq.steps[expected_steps[k]].kind == StepKind::kRest;
    EXPECT_EQ(s.kind, rest ? SegmentKind::kRest : SegmentKind::kMove) << k;
    if (rest) {
      EXPECT_EQ(s.outer.rate0_radps, 0.0);
      EXPECT_EQ(s.outer.accel_radps2, 0.0);
      EXPECT_EQ(s.inner.rate0_radps, 0.0);
      EXPECT_EQ(s.inner.accel_radps2, 0.0);
    } else {
      // One axis at a time: the other holds still.
      const Axis ax = seq.steps[expected_steps[k]].axis;
      const AxisMotion& other = ax == Axis::kOuter ? s.inner : s.outer;
      EXPECT_EQ(other.rate0_radps, 0.0);
      EXPECT_EQ(other.accel_radps2, 0.0);
    }
  }
  EXPECT_EQ(prof.segments[0].t1_s, 30.0);
  EXPECT_EQ(prof.segments[4].t1_s - prof.segments[4].t0_s, 20.0);
}

TEST_F(ProfileFixture, RotationsEndExactlyOnTheCommandedAngles) {
  // Commanded (deg): inner -20 -> 70 -> 73; outer 10 -> -45.
  const auto& S = prof.segments;
  EXPECT_NEAR(end_angle(S[3], S[3].inner), 70.0 * kD2R, 1e-12);
  EXPECT_NEAR(end_angle(S[7], S[7].outer), -45.0 * kD2R, 1e-12);
  EXPECT_NEAR(end_angle(S[10], S[10].inner), 73.0 * kD2R, 1e-12);
  // And the rests that follow hold exactly those angles.
  EXPECT_EQ(S[4].inner.angle0_rad, 70.0 * kD2R);
  EXPECT_EQ(S[8].outer.angle0_rad, -45.0 * kD2R);
  EXPECT_EQ(S[11].inner.angle0_rad, 73.0 * kD2R);
  const TableState end = prof.at(prof.duration_s());
  EXPECT_NEAR(end.outer_rad, -45.0 * kD2R, 1e-12);
  EXPECT_NEAR(end.inner_rad, 73.0 * kD2R, 1e-12);
  EXPECT_TRUE(end.at_rest);
}

TEST_F(ProfileFixture, DurationsMatchHandComputedTrapezoids) {
  const auto& S = prof.segments;
  auto span = [&](size_t a, size_t b) { return S[b].t1_s - S[a].t0_s; };
  // 90 deg at 10 deg/s, 10 deg/s^2: 1 s up (5 deg), 8 s cruise (80 deg), 1 s down.
  EXPECT_NEAR(span(1, 3), 10.0, 1e-12);
  EXPECT_NEAR(S[2].t1_s - S[2].t0_s, 8.0, 1e-12);
  // 55 deg at 5 deg/s, 4 deg/s^2: 1.25 s up (3.125 deg) and down, cruise 48.75 / 5 = 9.75 s.
  EXPECT_NEAR(span(5, 7), 12.25, 1e-12);
  // 3 deg at 10 deg/s^2 cannot reach 10 deg/s (needs 10 deg): peak sqrt(30) deg/s.
  EXPECT_NEAR(span(9, 10), 2.0 * std::sqrt(0.3), 1e-12);
  EXPECT_NEAR(prof.duration_s(), 30 + 10 + 20 + 12.25 + 20 + 2 * std::sqrt(0.3) + 15, 1e-9);
}

TEST_F(ProfileFixture, AngleAndRateAreContinuousAcrossSegments) {
  const auto& S = prof.segments;
  for (size_t k = 0; k + 1 < S.size(); ++k) {
    for (int axis = 0; axis < 2; ++axis) {
      const AxisMotion& a = axis ? S[k].inner : S[k].outer;
      const AxisMotion& b = axis ? S[k + 1].inner : S[k + 1].outer;
      EXPECT_NEAR(end_angle(S[k], a), b.angle0_rad, 1e-12) << "segment " << k << " axis " << axis;
      EXPECT_NEAR(end_rate(S[k], a), b.rate0_radps, 1e-12) << "segment " << k << " axis " << axis;
    }
  }
}

TEST_F(ProfileFixture, RateAndAccelerationStayWithinTheStepLimits) {
  double peak_inner = 0.0, peak_outer = 0.0;
  for (double t = 0.0; t <= prof.duration_s(); t += 1e-3) {
    const TableState s = prof.at(t);
    peak_inner = std::max(peak_inner, std::abs(s.inner_rate_radps));
    peak_outer = std::max(peak_outer, std::abs(s.outer_rate_radps));
    EXPECT_LE(std::abs(s.outer_accel_radps2), 4.0 * kD2R + 1e-15);
    EXPECT_LE(std::abs(s.inner_accel_radps2), 10.0 * kD2R + 1e-15);
    if (s.at_rest) {
      ASSERT_EQ(s.inner_rate_radps, 0.0) << t;
      ASSERT_EQ(s.outer_rate_radps, 0.0) << t;
    }
  }
  EXPECT_LE(peak_inner, 10.0 * kD2R * (1 + 1e-12));
  EXPECT_LE(peak_outer, 5.0 * kD2R * (1 + 1e-12));
  EXPECT_NEAR(peak_inner, 10.0 * kD2R, 1e-12);  // the cruise phase reaches the rate
  EXPECT_NEAR(peak_outer, 5.0 * kD2R, 1e-12);
  // The triangular move peaks at sqrt(angle * accel), below its 10 deg/s.
  const ProfileSegment& up = prof.segments[9];
  EXPECT_NEAR(end_rate(up, up.inner), std::sqrt(3.0 * 10.0) * kD2R, 1e-12);
  EXPECT_LT(end_rate(up, up.inner), 10.0 * kD2R);
}

TEST_F(ProfileFixture, IntegralOfRateEqualsAngleChange) {
  // Trapezoidal quadrature of the sampled rate on a grid that ignores the breakpoints; the
  // quadrature error is O(h^2 * jump in acceleration), well below 1e-6 rad at h = 1 ms.
  const double h = 1e-3;
  const double T = prof.duration_s();
  const int n = static_cast<int>(std::ceil(T / h));
  double outer = 0.0, inner = 0.0;
  TableState prev = prof.at(0.0);
  for (int i = 1; i <= n; ++i) {
    const double t0 = (i - 1) * T / n, t1 = i * T / n;
    const TableState cur = prof.at(t1);
    outer += 0.5 * (prev.outer_rate_radps + cur.outer_rate_radps) * (t1 - t0);
    inner += 0.5 * (prev.inner_rate_radps + cur.inner_rate_radps) * (t1 - t0);
    prev = cur;
  }
  EXPECT_NEAR(outer, (-45.0 - 10.0) * kD2R, 1e-6);
  EXPECT_NEAR(inner, (73.0 - -20.0) * kD2R, 1e-6);
}

TEST(Profile, ManyRelativeStepsDoNotAccumulateError) {
  std::string text = "name = \"m\"\n[start]\nouter_deg = 0.1\nrest_s = 10\n";
  double commanded_deg = 0.1;
  for (int k = 0; k < 200; ++k) {
    const double by = (k % 3 == 2) ? -123.4567 : 37.31;
    commanded_deg += by;
    text += "[[step]]\nrotate = \"outer\"\nby_deg = " + std::to_string(by) +
            "\n[[step]]\nrest_s = 10\n";
  }
  const MotionProfile p = generate_profile(parse_sequence_string(text, "m.toml"));
  EXPECT_NEAR(p.at(p.duration_s()).outer_rad, commanded_deg * kD2R, 1e-12);
  // Every move segment's evaluated end is continuous with the next segment.
  for (size_t k = 0; k + 1 < p.segments.size(); ++k)
    ASSERT_NEAR(end_angle(p.segments[k], p.segments[k].outer), p.segments[k + 1].outer.angle0_rad,
                1e-12);
}

TEST(Profile, ExactRampLengthGivesNoCruiseSegment) {
  // 10 deg at 10 deg/s and 10 deg/s^2 is exactly the ramp-up + ramp-down angle.
  const MotionProfile p = generate_profile(parse_sequence_string(
      "name = \"e\"\n[start]\nrest_s = 10\n[[step]]\nrotate = \"inner\"\nby_deg = 10\n"
      "[[step]]\nrest_s = 10\n",
      "e.toml"));
  ASSERT_EQ(p.segments.size(), 4u);
  EXPECT_NEAR(p.segments[2].t1_s - p.segments[1].t0_s, 2.0, 1e-12);
  EXPECT_NEAR(p.at(p.duration_s()).inner_rad, 10.0 * kD2R, 1e-12);
}

TEST(Profile, RotationTimingFormula) {
  // Independent of units: angle 100, rate 4, accel 2 -> ramps of 2 s (4 each), cruise 23 s.
  const RotationTiming t = rotation_timing(100.0, 4.0, 2.0);
  EXPECT_DOUBLE_EQ(t.accel_time_s, 2.0);
  EXPECT_DOUBLE_EQ(t.cruise_time_s, 23.0);
  EXPECT_DOUBLE_EQ(t.total_s(), 27.0);
  const RotationTiming tri = rotation_timing(2.0, 4.0, 2.0);  // needs 8 to reach rate 4
  EXPECT_DOUBLE_EQ(tri.peak_rate, 2.0);
  EXPECT_DOUBLE_EQ(tri.total_s(), 2.0);
}

TEST(Profile, RejectsStepsItCannotExecute) {
  Sequence s = parse_sequence_string(
      "name = \"x\"\n[start]\nrest_s = 10\n[[step]]\nrotate = \"inner\"\nby_deg = 10\n"
      "rate_dps = 3\n[[step]]\nrest_s = 10\n",
      "x.toml");
  s.steps[0].rate_dps = 0.0;
  try {
    generate_profile(s);
    FAIL() << "expected SequenceError";
  } catch (const SequenceError& e) {
    EXPECT_EQ(e.file(), "x.toml");
    EXPECT_EQ(e.line(), 7);  // the rate_dps key
  }
  s.steps[0].rate_dps = 3.0;
  s.steps[1].duration_s = std::nan("");
  EXPECT_THROW(generate_profile(s), SequenceError);
}

}  // namespace
}  // namespace imucal::sequences
