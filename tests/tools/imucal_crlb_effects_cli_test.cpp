// `imucal crlb --effects` as a reader sees it (issue #19 item 8): the table's "ratio" column is
// explained, an effect that the sequence separates but cannot detect at its typical size is said so
// in words with how far off it is, and correlations are printed to three digits. The figures to
// expect come from the same command's --json (threshold, typical, separable, max_correlation: the
// analysis' numbers, not its wording).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <regex>
#include <sstream>
#include <string>
#include <vector>

#include "tests/support/imucal_cli.hpp"

namespace {

using imucal::test_support::run_imucal;

std::vector<std::string> lines_of(const std::string& text) {
  std::vector<std::string> v;
  std::istringstream is(text);
  for (std::string l; std::getline(is, l);) v.push_back(l);
  return v;
}

std::string fmt(const char* f, double v) {
  char b[32];
  std::snprintf(b, sizeof b, f, v);
  return b;
}

bool has_word(const std::string& line, const std::string& word) {
  return std::regex_search(line, std::regex("(^|[^a-z0-9_])" + word + "($|[^a-z0-9_])"));
}

struct Crlb {
  std::vector<std::string> text;
  nlohmann::json effects;
};

Crlb crlb_effects(const std::string& sequence) {
  const auto t = run_imucal("crlb --effects --sequence " + sequence, false);
  const auto j = run_imucal("crlb --effects --json --sequence " + sequence, false);
  EXPECT_EQ(t.code, 0) << t.out;
  EXPECT_EQ(j.code, 0) << j.out;
  return {lines_of(t.out), nlohmann::json::parse(j.out)["effects"]};
}

}  // namespace

TEST(CrlbEffects, TheRatioColumnIsExplained) {
  const Crlb c = crlb_effects("short");
  // A legend line (not the column header) that says what the ratio is made of.
  int legends = 0;
  for (const auto& l : c.text)
    if (std::regex_search(l, std::regex("ratio\\b.*threshold.*typical"))) ++legends;
  EXPECT_EQ(legends, 1) << "no line says what 'ratio' is (threshold / typical)";
}

TEST(CrlbEffects, SeparableButNotDetectableAtTypicalSizeIsSaidInWords) {
  for (const char* seq : {"short", "factory-std"}) {
    const Crlb c = crlb_effects(seq);
    int undetectable = 0;
    for (const auto& e : c.effects) {
      const std::string name = e["effect"];
      if (!e["threshold"].is_number() || e["typical"].get<double>() <= 0) continue;
      const double ratio = e["threshold"].get<double>() / e["typical"].get<double>();
      // The sentence: the effect's name, "typical size", and how many times its typical size it
      // must be (as the ratio column prints it, two significant digits).
      std::string said;
      for (const auto& l : c.text)
        if (has_word(l, name) && l.find("typical size") != std::string::npos) said += l + "\n";
      if (e["separable"].get<bool>() && ratio > 1.0) {
        ++undetectable;
        EXPECT_NE(said.find(fmt("%.2g", ratio) + "x"), std::string::npos)
            << seq << ": " << name << " (ratio " << ratio << ") not said in words:\n"
            << said;
      } else {
        EXPECT_EQ(said, "") << seq << ": " << name << " (ratio " << ratio << ", separable "
                            << e["separable"] << ")";
      }
    }
    // Both sequences have such effects (g-sensitivity and latitude): the test checks something.
    EXPECT_GE(undetectable, 2) << seq;
  }
}

TEST(CrlbEffects, CorrelationsHaveThreeDigits) {
  const Crlb c = crlb_effects("short");
  const std::regex number("correlates? ([0-9][0-9.eE+-]*)");
  int seen = 0;
  for (const auto& l : c.text)
    for (std::sregex_iterator m(l.begin(), l.end(), number), end; m != end; ++m, ++seen)
      EXPECT_TRUE(std::regex_match((*m)[1].str(), std::regex("[01]\\.[0-9]{3}")))
          << "'" << (*m)[1] << "' in: " << l;
  EXPECT_GE(seen, 3) << "the short sequence has correlated effects (K2/asymmetry, gravity error)";
  // A correlation with the base parameters is the analysis' own, rounded (not truncated).
  for (const auto& e : c.effects) {
    const double rho = e["max_correlation"].get<double>();
    if (e["separable_directions"].get<int>() > 0 || rho < 0.95) continue;
    for (const auto& l : c.text) {
      if (!has_word(l, e["effect"].get<std::string>()) || l.find("base parameters") == l.npos)
        continue;
      EXPECT_NE(l.find("correlates " + fmt("%.3f", rho)), std::string::npos) << rho << ": " << l;
    }
  }
}

// Issue #22 item 1: the thresholds are those of the station's false-alarm rate per run
// ([calibration] gap_false_alarm, 1e-4 unless configured), said in the table's first line and the
// JSON; a laxer rate gives lower thresholds. By the header's rule (threshold ∝ √(χ²_k critical
// value − k)), going from 2e-3 to 1e-4 per run raises a one-direction effect's threshold by
// √((χ²₁(1 − 5e-5/N) − 1)/(χ²₁(1 − 1e-3/N) − 1)) ≈ 1.2-1.3 for N of 10-14 candidates, more
// directions by less.
TEST(CrlbEffects, ThresholdsAreThoseOfTheStationsFalseAlarmRate) {
  const auto dflt = run_imucal("crlb --effects --json --sequence short", false);
  const auto lax = run_imucal("crlb --effects --json --false-alarm 2e-3 --sequence short", false);
  const auto text = run_imucal("crlb --effects --sequence short", false);
  ASSERT_EQ(dflt.code, 0) << dflt.out;
  ASSERT_EQ(lax.code, 0) << lax.out;
  EXPECT_NE(text.out.find("false-alarm rate of 0.0001 per run (the station's default"),
            std::string::npos)
      << text.out.substr(0, 400);
  const auto d = nlohmann::json::parse(dflt.out), l = nlohmann::json::parse(lax.out);
  EXPECT_DOUBLE_EQ(d["false_alarm_per_run"].get<double>(), 1e-4);
  EXPECT_DOUBLE_EQ(l["false_alarm_per_run"].get<double>(), 2e-3);
  int compared = 0;
  for (size_t i = 0; i < d["effects"].size(); ++i) {
    const auto &a = d["effects"][i], &b = l["effects"][i];
    ASSERT_EQ(a["effect"], b["effect"]);
    if (!a["threshold"].is_number() || !b["threshold"].is_number()) continue;
    const double ratio = a["threshold"].get<double>() / b["threshold"].get<double>();
    EXPECT_GT(ratio, 1.05) << a["effect"];
    EXPECT_LT(ratio, 1.4) << a["effect"];
    ++compared;
  }
  EXPECT_GE(compared, 5);
  const auto bad = run_imucal("crlb --effects --false-alarm 0 --sequence short", false);
  EXPECT_NE(bad.code, 0);
}
