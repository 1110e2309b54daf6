// The diagnosis report's first line (tools/report/diagnosis_text.hpp), issue #50 item 5: an
// imported recording has no sequence, and the line printed "sequence , 12000 samples".
#include <gtest/gtest.h>

#include <nlohmann/json.hpp>
#include <string>

#include "tools/report/diagnosis_text.hpp"

namespace imucal::tools::report {
namespace {

std::string first_line_of(const std::string& text) { return text.substr(0, text.find('\n')); }

nlohmann::json minimal_diagnosis(const std::string& sequence) {
  return {{"archive", "/data/imported"}, {"serial", "IMP-7"},       {"sequence", sequence},
          {"samples", 12000u},           {"verdict", "consistent"}, {"summary", "no gap"}};
}

TEST(DiagnosisTextRunLine, AnImportedRunWithoutSequenceNamesNone) {
  const std::string line = first_line_of(diagnosis_report_text(minimal_diagnosis("")));
  EXPECT_EQ(line.find("sequence"), std::string::npos) << line;
  EXPECT_NE(line.find("(serial IMP-7, 12000 samples, "), std::string::npos) << line;
}

TEST(DiagnosisTextRunLine, AStationRunNamesItsSequence) {
  const std::string line = first_line_of(diagnosis_report_text(minimal_diagnosis("short")));
  EXPECT_NE(line.find("(serial IMP-7, sequence short, 12000 samples, "), std::string::npos) << line;
}

}  // namespace
}  // namespace imucal::tools::report
