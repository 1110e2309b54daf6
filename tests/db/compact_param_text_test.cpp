// The fast reader of stored parameter-set text (db/history/compact_param_text.hpp) against the
// strict path: on what the repository writes it gives exactly the values a JSON parser gives, and
// it refuses (so that the strict reader reports the error) everything that is not that shape.
#include "db/history/compact_param_text.hpp"

#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "db/archive/param_json.hpp"

using imucal::calib::core::ParamSet;
using imucal::db::history::read_compact_param_set;
using json = nlohmann::json;

namespace {

/// Values of all magnitudes and signs, as calibrations and sigmas give them.
ParamSet random_set(std::mt19937_64& rng, bool non_negative) {
  std::uniform_real_distribution<double> mantissa(non_negative ? 0.0 : -1.0, 1.0);
  std::uniform_int_distribution<int> exponent(-12, 3);
  Eigen::Matrix<double, ParamSet::kSize, 1> x;
  for (int i = 0; i < ParamSet::kSize; ++i) x(i) = mantissa(rng) * std::pow(10.0, exponent(rng));
  x(3) = 0.0;  // exact zeros and integers too
  x(4) = non_negative ? 2.0 : -2.0;
  return ParamSet::from_vector(x);
}

/// What the repository stores: the compact dump of the five keys.
std::string stored_text(const ParamSet& p) {
  return imucal::db::archive::param_set_to_json(p).dump();
}

}  // namespace

TEST(CompactParamText, ReadsWhatTheRepositoryWritesBitForBitLikeAJsonParser) {
  std::mt19937_64 rng(7);
  for (int k = 0; k < 2000; ++k) {
    const bool sigma = k % 2 == 1;
    const std::string text = stored_text(random_set(rng, sigma));
    ParamSet fast;
    ASSERT_TRUE(read_compact_param_set(text, sigma, fast)) << text;
    const ParamSet strict = imucal::db::archive::param_set_from_json(json::parse(text), "test");
    for (int i = 0; i < ParamSet::kSize; ++i)
      ASSERT_EQ(fast.to_vector()(i), strict.to_vector()(i)) << i << " in " << text;
  }
}

TEST(CompactParamText, AcceptsTheKeysInAnyOrder) {
  const std::string text =
      R"({"table_misalignment_rad":[1,2,3],"gyro_M":[[1,2,3],[4,5,6],[7,8,9]],)"
      R"("gyro_bias_radps":[4e-1,5E+2,-6.5e-3],"accel_bias_mps2":[0,0.5,-0],)"
      R"("accel_M":[[10,20,30],[40,50,60],[70,80,90]]})";
  ParamSet p;
  ASSERT_TRUE(read_compact_param_set(text, false, p));
  EXPECT_EQ(p.accel_M(1, 2), 60.0);  // row-major text into the matrix's (row, column)
  EXPECT_EQ(p.accel_M(2, 0), 70.0);
  EXPECT_EQ(p.gyro_M(0, 1), 2.0);
  EXPECT_EQ(p.gyro_bias_radps(1), 500.0);
  EXPECT_EQ(p.gyro_bias_radps(2), -6.5e-3);
  EXPECT_EQ(p.table_misalignment_rad(2), 3.0);
}

TEST(CompactParamText, RefusesAnythingElseSoTheStrictReaderNamesTheProblem) {
  const std::string good = stored_text(ParamSet{});
  ParamSet p;
  ASSERT_TRUE(read_compact_param_set(good, true, p));
  auto with = [&](const std::string& from, const std::string& to) {
    std::string t = good;
    const auto at = t.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return t.replace(at, from.size(), to);
  };
  const std::vector<std::string> bad = {
      "",
      "{}",
      good + " ",
      good + "x",
      " " + good,
      with("\"accel_M\":", "\"accel_M\" :"),         // whitespace: not the stored shape
      with("\"accel_M\"", "\"accel_m\""),            // unknown key
      with("\"gyro_M\"", "\"accel_M\""),             // a key twice, one missing
      with("[0.0,0.0,0.0]]", "[0.0,0.0]]"),          // a short row
      with("[0.0,0.0,0.0]]", "[0.0,0.0,0.0,0.0]]"),  // a long row
      with("0.0", "\"0\""),                          // a string
      with("0.0", "NaN"),
      with("0.0", "inf"),
      with("0.0", "1e999"),  // not finite
      with("0.0", "01"),     // not JSON numbers
      with("0.0", "1."),
      with("0.0", ".5"),
      with("0.0", "+1"),
      with("0.0", "1e"),
      with("0.0", "-"),
      with("\"table_misalignment_rad\"", "\"table_misalignment_ra\\d\""),  // an escape
  };
  for (const auto& t : bad) EXPECT_FALSE(read_compact_param_set(t, false, p)) << t;
  // A negative entry is a value, never a 1-sigma.
  const std::string negative = with("0.0", "-1e-3");
  EXPECT_TRUE(read_compact_param_set(negative, false, p));
  EXPECT_FALSE(read_compact_param_set(negative, true, p));
}
