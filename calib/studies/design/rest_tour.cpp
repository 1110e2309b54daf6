#include "calib/studies/design/rest_tour.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numeric>
#include <stdexcept>

#include "sequences/profile_generator.hpp"

namespace imucal::calib::studies::design {

using sequences::Axis;

namespace {

std::string pose_text(const std::pair<double, double>& p) {
  char b[48];
  std::snprintf(b, sizeof b, "(%g, %g)", p.first, p.second);
  return b;
}

/// Each pose's rest: its weight's share of `budget_s`, raised to `min_rest_s` where that share is
/// shorter (the others then share what is left), rounded down to 0.1 s with the remainder on the
/// longest rest, so the rests sum to `budget_s` to the 0.1 s the file is written with.
std::vector<double> shared_rests(const RestTour& tour, double budget_s, double min_rest_s) {
  std::vector<double> rest(tour.poses(), 0.0);
  std::vector<bool> at_min(tour.poses(), false);
  for (bool changed = true; changed;) {
    changed = false;
    double weights = 0.0, free_s = budget_s;
    for (size_t i = 0; i < rest.size(); ++i)
      if (at_min[i])
        free_s -= min_rest_s;
      else
        weights += tour.rest_weight[i];
    for (size_t i = 0; i < rest.size(); ++i) {
      if (at_min[i]) continue;
      rest[i] = free_s * tour.rest_weight[i] / weights;
      if (rest[i] < min_rest_s) at_min[i] = changed = true;
    }
  }
  double sum = 0.0;
  for (size_t i = 0; i < rest.size(); ++i) {
    rest[i] = at_min[i] ? min_rest_s : std::max(min_rest_s, std::floor(rest[i] * 10.0) / 10.0);
    sum += rest[i];
  }
  const auto longest = std::max_element(rest.begin(), rest.end());
  *longest = std::round((*longest + budget_s - sum) * 10.0) / 10.0;
  return rest;
}

}  // namespace

std::pair<double, double> RestTour::pose_deg(size_t i) const {
  double outer = outer0_deg, inner = inner0_deg;
  for (size_t k = 0; k < i && k < legs.size(); ++k)
    (legs[k].axis == Axis::kOuter ? outer : inner) += legs[k].by_deg;
  return {outer, inner};
}

double RestTour::rotation_time_s() const {
  double t = 0.0;
  for (const TourLeg& leg : legs)
    t += sequences::rotation_timing(std::abs(leg.by_deg), rate_dps, accel_dps2).total_s();
  return t;
}

RestTour tour_of(const sequences::Sequence& seq) {
  RestTour tour;
  tour.outer0_deg = seq.start.outer_deg;
  tour.inner0_deg = seq.start.inner_deg;
  tour.rest_weight.push_back(seq.start.rest_s);
  double outer = seq.start.outer_deg, inner = seq.start.inner_deg;
  bool rate_set = false;
  for (const sequences::Step& st : seq.steps) {
    if (st.kind == sequences::StepKind::kRest) {
      tour.rest_weight.back() += st.duration_s;
      continue;
    }
    double& angle = st.axis == Axis::kOuter ? outer : inner;
    const double by = sequences::step_angle_change_deg(st, angle);
    if (by == 0.0) continue;
    angle += by;
    tour.legs.push_back({st.axis, by});
    tour.rest_weight.push_back(0.0);
    if (!rate_set) {
      tour.rate_dps = st.rate_dps;
      tour.accel_dps2 = st.accel_dps2;
      rate_set = true;
    }
  }
  return tour;
}

double minimum_time_s(const RestTour& tour, double min_rest_s) {
  return tour.rotation_time_s() + min_rest_s * static_cast<double>(tour.poses());
}

sequences::Sequence sequence_of(const RestTour& tour, double total_s, double min_rest_s,
                                const std::string& name, const std::string& description) {
  const double rest_budget_s = total_s - tour.rotation_time_s();
  if (!(rest_budget_s >= min_rest_s * static_cast<double>(tour.poses()))) {
    char b[128];
    std::snprintf(b, sizeof b, "a tour of %zu rotations needs at least %.1f s", tour.legs.size(),
                  minimum_time_s(tour, min_rest_s));
    throw std::invalid_argument(b);
  }
  const std::vector<double> rest = shared_rests(tour, rest_budget_s, min_rest_s);
  sequences::Sequence seq;
  seq.name = name;
  seq.description = description;
  seq.source_path = name;
  seq.start.outer_deg = tour.outer0_deg;
  seq.start.inner_deg = tour.inner0_deg;
  seq.start.rest_s = rest[0];
  for (size_t i = 0; i < tour.legs.size(); ++i) {
    sequences::Step turn;
    turn.kind = sequences::StepKind::kRotate;
    turn.axis = tour.legs[i].axis;
    turn.by_deg = tour.legs[i].by_deg;
    turn.rate_dps = tour.rate_dps;
    turn.accel_dps2 = tour.accel_dps2;
    seq.steps.push_back(turn);
    sequences::Step rest_step;
    rest_step.duration_s = rest[i + 1];
    seq.steps.push_back(rest_step);
  }
  return seq;
}

std::vector<TourMove> tours_one_pose_shorter(const RestTour& tour) {
  std::vector<TourMove> out;
  const size_t n = tour.legs.size();
  if (n < 2) return out;
  {  // the first pose
    TourMove m{tour, "dropped the first pose " + pose_text(tour.pose_deg(0))};
    const auto p1 = tour.pose_deg(1);
    m.tour.outer0_deg = p1.first;
    m.tour.inner0_deg = p1.second;
    m.tour.legs.erase(m.tour.legs.begin());
    m.tour.rest_weight.erase(m.tour.rest_weight.begin());
    out.push_back(std::move(m));
  }
  for (size_t i = 1; i < n; ++i) {  // pose i between legs i-1 and i
    if (tour.legs[i - 1].axis != tour.legs[i].axis) continue;
    TourMove m{tour, "dropped pose " + pose_text(tour.pose_deg(i))};
    const double by = tour.legs[i - 1].by_deg + tour.legs[i].by_deg;
    if (std::abs(by) > 1e-9) {
      m.tour.legs[i - 1].by_deg = by;
      m.tour.legs.erase(m.tour.legs.begin() + static_cast<long>(i));
      m.tour.rest_weight.erase(m.tour.rest_weight.begin() + static_cast<long>(i));
    } else {
      // There and back: pose i + 1 is pose i - 1; its rest joins that one's.
      if (n < 3) continue;
      m.what += " and the return to " + pose_text(tour.pose_deg(i - 1));
      m.tour.rest_weight[i - 1] += tour.rest_weight[i + 1];
      m.tour.legs.erase(m.tour.legs.begin() + static_cast<long>(i - 1),
                        m.tour.legs.begin() + static_cast<long>(i + 1));
      m.tour.rest_weight.erase(m.tour.rest_weight.begin() + static_cast<long>(i),
                               m.tour.rest_weight.begin() + static_cast<long>(i + 2));
    }
    out.push_back(std::move(m));
  }
  {  // the last pose
    TourMove m{tour, "dropped the last pose " + pose_text(tour.pose_deg(n))};
    m.tour.legs.pop_back();
    m.tour.rest_weight.pop_back();
    out.push_back(std::move(m));
  }
  return out;
}

namespace {

/// An axis without angle limits: a rotation on it may turn a full or half turn more.
bool turns_freely(Axis axis, const sequences::TableLimits& limits) {
  return axis == Axis::kOuter
             ? std::isinf(limits.outer_min_deg) && std::isinf(limits.outer_max_deg)
             : std::isinf(limits.inner_min_deg) && std::isinf(limits.inner_max_deg);
}

}  // namespace

std::vector<TourMove> tours_one_turn_longer(const RestTour& tour,
                                            const sequences::TableLimits& limits) {
  std::vector<TourMove> out;
  for (size_t i = 0; i < tour.legs.size(); ++i) {
    const TourLeg& leg = tour.legs[i];
    if (!turns_freely(leg.axis, limits)) continue;
    TourMove m{tour, "a full turn more on the rotation to " + pose_text(tour.pose_deg(i + 1))};
    m.tour.legs[i].by_deg += leg.by_deg > 0 ? 360.0 : -360.0;
    out.push_back(std::move(m));
  }
  return out;
}

std::vector<TourMove> tours_half_turn_changed(const RestTour& tour,
                                              const sequences::TableLimits& limits) {
  std::vector<TourMove> out;
  for (size_t i = 0; i < tour.legs.size(); ++i) {
    const TourLeg& leg = tour.legs[i];
    if (!turns_freely(leg.axis, limits)) continue;
    for (double half : {180.0, -180.0}) {
      const double by = leg.by_deg + half;
      if (std::abs(by) < 1e-9 || std::abs(by) > 540.0 + 1e-9) continue;
      TourMove m{tour, std::string("rotation ") + std::to_string(i + 1) + " by " +
                           std::to_string(static_cast<int>(std::lround(by))) + " deg instead of " +
                           std::to_string(static_cast<int>(std::lround(leg.by_deg)))};
      m.tour.legs[i].by_deg = by;
      out.push_back(std::move(m));
    }
  }
  return out;
}

RestTour with_rest_weight(const RestTour& tour, size_t pose, double factor) {
  RestTour t = tour;
  t.rest_weight.at(pose) *= factor;
  return t;
}

}  // namespace imucal::calib::studies::design
