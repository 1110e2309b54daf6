#include "db/history/fleet_stats.hpp"

#include <algorithm>
#include <cmath>
#include <map>
#include <optional>
#include <set>

#include "calib/core/param_set.hpp"
#include "db/history/serial_number.hpp"

namespace imucal::db::history {

namespace {

constexpr std::int64_t kDayMs = 86400000;
constexpr std::size_t kMaxStationBytes = 200;

/// Quantile p of sorted values by linear interpolation (type 7).
double quantile_sorted(const std::vector<double>& x, double p) {
  const double h = static_cast<double>(x.size() - 1) * p;
  const auto lo = static_cast<std::size_t>(std::floor(h));
  if (lo + 1 >= x.size()) return x.back();
  return x[lo] + (h - static_cast<double>(lo)) * (x[lo + 1] - x[lo]);
}

}  // namespace

int param_index(const std::string& name) {
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i)
    if (calib::core::param_info(i).name == name) return i;
  throw InvalidInput("parameter \"" + name.substr(0, 80) +
                     "\" is unknown (expected a name of the parameter-set JSON such as "
                     "accel_bias_mps2[0], accel_M[0][1], gyro_bias_radps[2], gyro_M[2][2], "
                     "table_misalignment_rad[1])");
}

bool frame_dependent(int param_index) {
  // accel_M at 3..11 and gyro_M at 15..23, row-major (calib::core::param_info order).
  for (const int first : {3, 15}) {
    const int k = param_index - first;
    if (k >= 0 && k < 9) return k / 3 != k % 3;
  }
  return false;
}

std::vector<std::string> verdict_list(const std::string& text) {
  std::vector<std::string> out;
  std::size_t p = 0;
  while (p <= text.size()) {
    const std::size_t q = std::min(text.find(',', p), text.size());
    std::size_t a = p, b = q;
    while (a < b && (text[a] == ' ' || text[a] == '\t')) ++a;
    while (b > a && (text[b - 1] == ' ' || text[b - 1] == '\t')) --b;
    if (b > a) out.push_back(text.substr(a, b - a));
    p = q + 1;
  }
  return out;
}

std::int64_t utc_day(TimestampMs t_ms) {
  return t_ms >= 0 ? t_ms / kDayMs : -((-t_ms + kDayMs - 1) / kDayMs);
}

ParamSummary summarize(std::vector<double>& values) {
  ParamSummary s;
  s.count = static_cast<std::int64_t>(values.size());
  if (values.empty()) return s;
  std::sort(values.begin(), values.end());
  double sum = 0;
  for (double v : values) sum += v;
  s.mean = sum / static_cast<double>(values.size());
  double ss = 0;  // two-pass: no cancellation for values far from zero
  for (double v : values) ss += (v - s.mean) * (v - s.mean);
  s.std_dev = values.size() > 1 ? std::sqrt(ss / static_cast<double>(values.size() - 1)) : 0.0;
  s.min = values.front();
  s.max = values.back();
  s.q1 = quantile_sorted(values, 0.25);
  s.median = quantile_sorted(values, 0.5);
  s.q3 = quantile_sorted(values, 0.75);
  return s;
}

void validate_filter(const FleetFilter& f) {
  if (f.since_ms && f.until_ms && *f.since_ms > *f.until_ms)
    throw InvalidInput("since " + format_time_utc(*f.since_ms) + " is after until " +
                       format_time_utc(*f.until_ms));
  if (f.serial) validate_serial(*f.serial);
  if (f.setting && *f.setting != "factory" && *f.setting != "land" && *f.setting != "sea")
    throw InvalidInput("setting \"" + f.setting->substr(0, 40) + "\" is not factory, land or sea");
  if (f.verdict) {
    const std::vector<std::string> words = verdict_list(*f.verdict);
    if (words.empty()) throw InvalidInput("verdict: none given");
    for (const std::string& word : words) {
      if (word == "live") continue;
      try {
        run_verdict_from_string(word);
      } catch (const InvalidInput&) {
        throw InvalidInput("verdict \"" + word.substr(0, 40) +
                           "\" is not PASS, REVIEW, FAILED, STATION-FAULT, ABORTED, INTERRUPTED "
                           "or live");
      }
    }
  }
  if (f.station) {
    if (f.station->size() > kMaxStationBytes)
      throw InvalidInput("station name longer than " + std::to_string(kMaxStationBytes) + " bytes");
    for (unsigned char c : *f.station)
      if (c < 0x20 || c == 0x7F) throw InvalidInput("station name has a control character");
  }
}

namespace {

/// The captures of `links`: each root (the run reached by following origins until a run that
/// names none) with its runs, and every run's creation order.
struct Captures {
  std::map<RunId, std::vector<RunId>> runs;  // root -> its runs, the root among them
  std::map<RunId, std::int64_t> seq;
  bool before(RunId a, RunId b) const {
    return std::make_pair(seq.at(a), a) < std::make_pair(seq.at(b), b);
  }
};

Captures captures_of(const std::vector<ReprocessLink>& links) {
  std::map<RunId, RunId> origin_of;
  Captures c;
  for (const ReprocessLink& l : links) {
    origin_of[l.run] = l.origin;
    c.seq[l.run] = l.run_seq;
    c.seq.emplace(l.origin, l.origin_seq);
  }
  for (const auto& [run, seq] : c.seq) {
    RunId root = run;  // a chain is short: guarded against a cycle anyway
    for (std::size_t hops = 0; hops <= origin_of.size(); ++hops) {
      const auto it = origin_of.find(root);
      if (it == origin_of.end()) break;
      root = it->second;
    }
    c.runs[root].push_back(run);
  }
  return c;
}

}  // namespace

std::vector<RunId> superseded_runs(const std::vector<ReprocessLink>& links) {
  const Captures c = captures_of(links);
  std::vector<RunId> out;
  for (const auto& [root, runs] : c.runs) {
    const RunId newest = *std::max_element(runs.begin(), runs.end(),
                                           [&](RunId a, RunId b) { return c.before(a, b); });
    for (const RunId r : runs)
      if (r != newest) out.push_back(r);
  }
  std::sort(out.begin(), out.end());
  return out;
}

std::vector<RunId> signature_stand_ins(const std::vector<ReprocessLink>& links,
                                       const std::vector<RunId>& usable) {
  const Captures c = captures_of(links);
  const std::set<RunId> ok(usable.begin(), usable.end());
  std::vector<RunId> out;
  for (const auto& [root, runs] : c.runs) {
    if (ok.count(root)) continue;  // the original stands
    std::optional<RunId> first;
    for (const RunId r : runs)
      if (r != root && ok.count(r) && (!first || c.before(r, *first))) first = r;
    if (first) out.push_back(*first);
  }
  std::sort(out.begin(), out.end());
  return out;
}

}  // namespace imucal::db::history
