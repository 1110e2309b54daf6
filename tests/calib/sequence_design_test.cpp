// The sequence designer's parts (calib/studies/design/): a sequence as a tour of rest poses and
// back, the tours one pose shorter or a turn longer, and the search on a short reference — its
// result a sequence of exactly the time asked, within the table's limits, no worse than where it
// started.
#include "calib/studies/design/sequence_design.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>

#include "calib/checks/crlb.hpp"
#include "calib/core/site_presets.hpp"
#include "sequences/library.hpp"
#include "sequences/parser.hpp"
#include "sequences/profile_generator.hpp"
#include "sequences/validator.hpp"

namespace imucal::calib {
using namespace imucal::calib::checks;
using namespace imucal::calib::core;
using namespace imucal::calib::studies::design;
namespace {

using sequences::Axis;

sequences::Sequence library(const std::string& name) {
  return sequences::parse_sequence_file(sequences::resolve_sequence(name));
}

std::vector<double> rests_of(const sequences::Sequence& seq) {
  std::vector<double> r{seq.start.rest_s};
  for (const auto& st : seq.steps)
    if (st.kind == sequences::StepKind::kRest) r.push_back(st.duration_s);
  return r;
}

TEST(RestTour, FactoryStdIsTwentyOneRotationsBetweenTwentyTwoPosesAndComesBackWhole) {
  const sequences::Sequence std_seq = library("factory-std");
  const RestTour tour = tour_of(std_seq);
  EXPECT_EQ(tour.legs.size(), 21u);
  EXPECT_EQ(tour.poses(), 22u);
  EXPECT_EQ(tour.pose_deg(21), std::make_pair(0.0, 0.0));
  EXPECT_EQ(tour.pose_deg(3), std::make_pair(90.0, 180.0));
  const double duration_s = sequences::generate_profile(std_seq).duration_s();
  EXPECT_NEAR(tour.rotation_time_s() + 2040.0, duration_s, 1e-6);
  // At its own time the tour gives back the sequence's rests, and the same motion.
  const sequences::Sequence again = sequence_of(tour, duration_s, 10.0, "again", "");
  EXPECT_EQ(rests_of(again), rests_of(std_seq));
  EXPECT_NEAR(sequences::generate_profile(again).duration_s(), duration_s, 1e-6);
}

TEST(RestTour, AtAnotherTimeTheRestsScaleUniformlyAndNeverUnderTheMinimum) {
  const RestTour tour = tour_of(library("factory-std"));
  const double rest_s = 2040.0, t_s = tour.rotation_time_s() + 0.5 * rest_s;
  const auto rests = rests_of(sequence_of(tour, t_s, 10.0, "half", ""));
  EXPECT_NEAR(std::accumulate(rests.begin(), rests.end(), 0.0), 0.5 * rest_s, 1e-6);
  EXPECT_NEAR(rests[0], 60.0, 0.15);
  EXPECT_NEAR(rests[1], 45.0, 0.15);
  // So short that a share would fall under the minimum: raised to it, the others share the rest.
  RestTour skewed = tour;
  skewed.rest_weight[1] = 1e-3;
  const auto r = rests_of(sequence_of(skewed, tour.rotation_time_s() + 500.0, 10.0, "s", ""));
  EXPECT_EQ(r[1], 10.0);
  EXPECT_NEAR(std::accumulate(r.begin(), r.end(), 0.0), 500.0, 1e-6);
  EXPECT_THROW(sequence_of(tour, tour.rotation_time_s() + 219.0, 10.0, "x", ""),
               std::invalid_argument);
}

TEST(RestTour, APoseBetweenTwoTurnsAboutOneAxisGoesTheTurnsMerged) {
  RestTour t;
  t.legs = {{Axis::kInner, 90.0},
            {Axis::kInner, 90.0},
            {Axis::kOuter, 90.0},
            {Axis::kInner, 45.0},
            {Axis::kInner, -45.0}};
  t.rest_weight = {1, 2, 3, 4, 5, 6};
  const auto moves = tours_one_pose_shorter(t);
  // First pose, pose 1 (inner 90 + 90), pose 4 (there and back), last pose.
  ASSERT_EQ(moves.size(), 4u);
  EXPECT_EQ(moves[0].tour.pose_deg(0), std::make_pair(0.0, 90.0));
  EXPECT_EQ(moves[1].tour.legs.size(), 4u);
  EXPECT_EQ(moves[1].tour.legs[0].by_deg, 180.0);
  EXPECT_EQ(moves[1].tour.rest_weight, (std::vector<double>{1, 3, 4, 5, 6}));
  // Inner +45 then -45 returns to pose 3: both turns go, and pose 5's rest joins pose 3's.
  EXPECT_EQ(moves[2].tour.legs.size(), 3u);
  EXPECT_EQ(moves[2].tour.rest_weight, (std::vector<double>{1, 2, 3, 10}));
  EXPECT_EQ(moves[2].tour.pose_deg(3), t.pose_deg(5));
  EXPECT_EQ(moves[3].tour.legs.size(), 4u);
  for (const auto& m : moves) EXPECT_EQ(m.tour.rest_weight.size(), m.tour.poses()) << m.what;
}

TEST(RestTour, TurnsAreChangedOnlyOnAnAxisWithoutTravelLimits) {
  RestTour t;
  t.legs = {{Axis::kOuter, 90.0}, {Axis::kInner, 180.0}};
  t.rest_weight = {1, 1, 1};
  sequences::TableLimits limits;
  EXPECT_EQ(tours_one_turn_longer(t, limits).size(), 2u);
  // Inner 180 +- 180: 360 (kept) and 0 (no rotation, left out); outer 90 +- 180: 270 and -90.
  EXPECT_EQ(tours_half_turn_changed(t, limits).size(), 3u);
  limits.outer_min_deg = -180.0;
  limits.outer_max_deg = 180.0;
  EXPECT_EQ(tours_one_turn_longer(t, limits).size(), 1u);
  EXPECT_EQ(tours_half_turn_changed(t, limits).size(), 1u);
}

TEST(SequenceDesign, OnShortAtTwoThirdsOfItsTimeGivesAValidSequenceOfThatTimeNoWorseThanTheCut) {
  const sequences::Sequence reference = library("short");
  DesignSetting s;
  s.site = demo_factory_site();
  s.limits = sequences::effective_limits(sequences::TableLimits{}, reference.limits);
  std::vector<std::string> progress;
  s.progress = [&](const std::string& line) { progress.push_back(line); };
  const double t_ref_s = sequences::generate_profile(reference).duration_s();
  const double t_s = std::round(2.0 / 3.0 * t_ref_s);
  const SequenceDesign d = design_for_time(reference, t_s, s);
  EXPECT_FALSE(progress.empty());
  EXPECT_GT(d.evaluations, 10);
  const auto issues = sequences::validate(d.sequence, s.limits);
  for (const auto& i : issues) ADD_FAILURE() << i.message;
  EXPECT_NEAR(sequences::generate_profile(d.sequence).duration_s(), t_s, 0.11);
  EXPECT_NEAR(d.design.duration_s, t_s, 0.11);
  EXPECT_NEAR(d.reference.duration_s, t_ref_s, 1e-6);
  // The search starts from the cut and takes only better tours: the design's objective is at most
  // the cut's, judged on the same targets.
  const ParamVector cut_ratio = d.cut.sigma.cwiseQuotient(d.target);
  EXPECT_LE(d.objective, cut_ratio.maxCoeff() * (1.0 + 1e-3));
  EXPECT_TRUE(unobservable_parameters(compute_crlb(sequences::generate_profile(d.sequence),
                                                   TableGeometry{}, s.site, s.noise, 100.0))
                  .empty());
}

TEST(SequenceDesign, RefusesATimeOutsideTheLimitsOrTooShortForAnyTour) {
  const sequences::Sequence reference = library("short");
  DesignSetting s;
  s.limits = sequences::effective_limits(sequences::TableLimits{}, reference.limits);
  EXPECT_THROW(design_for_time(reference, 0.0, s), std::invalid_argument);
  EXPECT_THROW(design_for_time(reference, s.limits.max_duration_s + 1.0, s), std::invalid_argument);
  EXPECT_THROW(design_for_time(reference, 15.0, s), std::invalid_argument);
}

TEST(SequenceDesign, WhiteNoiseFloorIsTheBiasGroupsAlone) {
  const NoiseModel noise;
  EXPECT_DOUBLE_EQ(white_noise_floor(0, noise, 100.0), noise.vrw_mps_per_sqrt_s / 10.0);
  EXPECT_DOUBLE_EQ(white_noise_floor(12, noise, 100.0), noise.arw_rad_per_sqrt_s / 10.0);
  EXPECT_EQ(white_noise_floor(3, noise, 100.0), 0.0);
  EXPECT_EQ(white_noise_floor(26, noise, 100.0), 0.0);
}

}  // namespace
}  // namespace imucal::calib
