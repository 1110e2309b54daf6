// Parameter-set JSON (ARCHITECTURE §3): exact schema keys and shapes, row-major matrices, bit-exact
// round trip, field-named errors.
#include "db/archive/param_json.hpp"

#include <gtest/gtest.h>
#include <stdlib.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <random>
#include <set>

#include "db/archive/archive_error.hpp"
#include "db/archive/io_util.hpp"

namespace imucal::db::archive {
namespace {

using nlohmann::json;
namespace fs = std::filesystem;

calib::core::ParamSet random_params(uint64_t seed, double scale) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> n(0.0, scale);
  calib::core::ParamVector x;
  for (int i = 0; i < calib::core::ParamSet::kSize; ++i) x(i) = n(rng);
  return calib::core::ParamSet::from_vector(x);
}

calib::core::ParamSet abs_params(uint64_t seed, double scale) {
  return calib::core::ParamSet::from_vector(random_params(seed, scale).to_vector().cwiseAbs());
}

std::set<std::string> keys(const json& j) {
  std::set<std::string> s;
  for (auto it = j.begin(); it != j.end(); ++it) s.insert(it.key());
  return s;
}

ArchiveError from_json_error(const json& j, calib::core::ParamSet* sigma = nullptr) {
  try {
    param_set_from_json(j, "unit42.json", sigma);
  } catch (const ArchiveError& e) {
    return e;
  }
  ADD_FAILURE() << "no error for " << j.dump();
  return ArchiveError("none", "none");
}

TEST(ParamJson, SchemaKeysAndShapesExactlyAsDesign) {
  const calib::core::ParamSet p = random_params(1, 1e-4);
  const json j = param_set_to_json(p);
  const std::set<std::string> design = {"accel_bias_mps2", "accel_M", "gyro_bias_radps", "gyro_M",
                                        "table_misalignment_rad"};
  EXPECT_EQ(keys(j), design);
  for (const char* v : {"accel_bias_mps2", "gyro_bias_radps", "table_misalignment_rad"}) {
    ASSERT_TRUE(j[v].is_array());
    EXPECT_EQ(j[v].size(), 3u);
  }
  for (const char* m : {"accel_M", "gyro_M"}) {
    ASSERT_EQ(j[m].size(), 3u);
    for (const auto& row : j[m]) EXPECT_EQ(row.size(), 3u);
  }
  const calib::core::ParamSet s = abs_params(2, 1e-6);
  const json js = param_set_to_json(p, &s);
  std::set<std::string> with_sigma = design;
  with_sigma.insert("sigma");
  EXPECT_EQ(keys(js), with_sigma);
  EXPECT_EQ(keys(js["sigma"]), design);
}

TEST(ParamJson, MatricesAreRowsAndValuesLandInTheirFields) {
  calib::core::ParamSet p;
  p.accel_bias_mps2 = {1, 2, 3};
  p.accel_M(0, 1) = 7.0;  // row 0, column 1
  p.accel_M(2, 0) = -4.0;
  p.gyro_bias_radps = {4, 5, 6};
  p.gyro_M(1, 2) = 9.0;
  p.table_misalignment_rad = {7, 8, 9};
  const json j = param_set_to_json(p);
  EXPECT_EQ(j["accel_M"][0][1].get<double>(), 7.0);
  EXPECT_EQ(j["accel_M"][1][0].get<double>(), 0.0);
  EXPECT_EQ(j["accel_M"][2][0].get<double>(), -4.0);
  EXPECT_EQ(j["gyro_M"][1][2].get<double>(), 9.0);
  EXPECT_EQ(j["accel_bias_mps2"][2].get<double>(), 3.0);
  EXPECT_EQ(j["gyro_bias_radps"][0].get<double>(), 4.0);
  EXPECT_EQ(j["table_misalignment_rad"][1].get<double>(), 8.0);
  // Parse hand-written JSON (integers are numbers too).
  const json hand = json::parse(R"({"accel_bias_mps2":[1,2,3],"accel_M":[[0,7,0],[0,0,0],[-4,0,0]],
      "gyro_bias_radps":[4,5,6],"gyro_M":[[0,0,0],[0,0,9],[0,0,0]],"table_misalignment_rad":[7,8,9]})");
  const calib::core::ParamSet q = param_set_from_json(hand, "hand.json");
  EXPECT_EQ(q.to_vector(), p.to_vector());
}

TEST(ParamJson, TextRoundTripIsBitExact) {
  const calib::core::ParamSet p = random_params(3, 1e-3);
  const calib::core::ParamSet s = abs_params(4, 1e-7);
  const std::string text = param_set_to_json(p, &s).dump(2);
  calib::core::ParamSet s2;
  const calib::core::ParamSet p2 = param_set_from_json(json::parse(text), "rt.json", &s2);
  const auto a = p.to_vector(), b = p2.to_vector(), c = s.to_vector(), d = s2.to_vector();
  EXPECT_EQ(std::memcmp(a.data(), b.data(), sizeof(double) * calib::core::ParamSet::kSize), 0);
  EXPECT_EQ(std::memcmp(c.data(), d.data(), sizeof(double) * calib::core::ParamSet::kSize), 0);
}

TEST(ParamJson, FieldNamedErrors) {
  const json good = param_set_to_json(random_params(5, 1e-4));
  {
    json j = good;
    j.erase("gyro_M");
    const ArchiveError e = from_json_error(j);
    EXPECT_EQ(e.field(), "gyro_M");
    EXPECT_NE(std::string(e.what()).find("unit42.json: field 'gyro_M': missing"), std::string::npos)
        << e.what();
  }
  {
    json j = good;
    j["accel_M"].erase(2);
    EXPECT_EQ(from_json_error(j).field(), "accel_M");
  }
  {
    json j = good;
    j["accel_M"][1].push_back(0.0);
    const ArchiveError e = from_json_error(j);
    EXPECT_EQ(e.field(), "accel_M[1]");
    EXPECT_NE(e.message().find("array of 4"), std::string::npos) << e.what();
  }
  {
    json j = good;
    j["accel_M"][1][2] = "0.001";
    const ArchiveError e = from_json_error(j);
    EXPECT_EQ(e.field(), "accel_M[1][2]");
    EXPECT_NE(e.message().find("expected a number, got string"), std::string::npos) << e.what();
  }
  {
    json j = good;
    j["gyro_bias_radps"][0] = nullptr;  // what NaN becomes in many JSON writers
    EXPECT_EQ(from_json_error(j).field(), "gyro_bias_radps[0]");
  }
  {
    json j = good;
    j["table_misalignment_rad"] = 0.0;
    EXPECT_EQ(from_json_error(j).field(), "table_misalignment_rad");
  }
  {
    json j = good;
    j["accel_scale"] = json::array({1, 2, 3});
    const ArchiveError e = from_json_error(j);
    EXPECT_EQ(e.field(), "accel_scale");
    EXPECT_NE(e.message().find("unknown field"), std::string::npos);
  }
  { EXPECT_EQ(from_json_error(json::array()).field(), "<root>"); }
  {
    // sigma required by the caller but absent; negative sigma.
    calib::core::ParamSet s;
    EXPECT_EQ(from_json_error(good, &s).field(), "sigma");
    json j = param_set_to_json(random_params(6, 1e-4), &s);
    j["sigma"]["gyro_M"][2][1] = -1e-6;
    EXPECT_EQ(from_json_error(j, &s).field(), "sigma.gyro_M[2][1]");
    j["sigma"]["gyro_M"][2][1] = 1e-6;
    j["sigma"].erase("accel_bias_mps2");
    EXPECT_EQ(from_json_error(j, &s).field(), "sigma.accel_bias_mps2");
  }
}

TEST(ParamJson, WriterRefusesNanAndNegativeSigma) {
  calib::core::ParamSet p;
  p.gyro_M(1, 1) = std::nan("");
  EXPECT_THROW(param_set_to_json(p), ArchiveError);
  calib::core::ParamSet ok, s;
  s.accel_bias_mps2(0) = -1.0;
  EXPECT_THROW(param_set_to_json(ok, &s), ArchiveError);
}

TEST(ParamJson, FileRoundTripAndSyntaxErrorLine) {
  std::string d = (fs::temp_directory_path() / "imucal_pj_XXXXXX").string();
  ASSERT_NE(::mkdtemp(d.data()), nullptr);
  const std::string path = d + "/est.json";
  const calib::core::ParamSet p = random_params(7, 1e-4);
  const calib::core::ParamSet s = abs_params(8, 1e-6);
  write_param_file(path, p, &s);
  calib::core::ParamSet s2;
  const calib::core::ParamSet p2 = read_param_file(path, &s2);
  EXPECT_EQ(p2.to_vector(), p.to_vector());
  EXPECT_EQ(s2.to_vector(), s.to_vector());
  // A syntax error on line 3 is reported on line 3.
  write_file_atomic(path, "{\n  \"accel_bias_mps2\": [1, 2, 3],\n  \"accel_M\": [[1, 2,, 3]]\n}\n");
  try {
    read_param_file(path);
    FAIL() << "no error";
  } catch (const ArchiveError& e) {
    EXPECT_EQ(e.file(), path);
    EXPECT_EQ(e.line(), 3u) << e.what();
    EXPECT_NE(e.message().find("invalid JSON"), std::string::npos) << e.what();
  }
  fs::remove_all(d);
}

}  // namespace
}  // namespace imucal::db::archive
