#pragma once
// The checks of /fleet and /signatures against tests/db/fleet_truth_history.hpp's rows, shared
// by the SQLite test (tests/tools/stationweb_truth_test.cpp) and the fleet store's
// (tests/fleet/stationweb_fleet_truth_test.cpp): the numbers on the page must equal the ones
// computed here from the rows by issue #52's rules.
#include <gtest/gtest.h>

#include <array>
#include <map>
#include <set>
#include <string>

#include "tests/db/fleet_history.hpp"
#include "tests/db/fleet_truth_history.hpp"
#include "tests/support/html_tags.hpp"

namespace imucal::test_support {

/// /fleet's verdict table and `param`'s distribution against the rows counted for `setting` and
/// `verdict` ("" every).
inline void expect_fleet_truth(const std::string& html, const std::vector<db::test::TruthRow>& rows,
                               const std::string& setting, const std::string& verdict, int param) {
  using Counts = std::array<std::int64_t, 8>;  // the six verdicts, live, the units' own outcomes
  std::map<std::string, Counts> expected;
  std::map<std::string, std::int64_t> per_day;
  std::map<std::string, std::vector<double>> values;
  const char* const order[] = {"PASS",          "REVIEW",  "FAILED",
                               "STATION-FAULT", "ABORTED", "INTERRUPTED"};
  for (const db::test::TruthRow& r : db::test::truth_counted(rows, setting, verdict)) {
    Counts& c = expected[r.station];
    const auto k = static_cast<std::size_t>(std::find(order, order + 6, r.verdict) - order);
    ++c[k];
    if (k < 3) ++c[7];
    ++per_day[r.station + " " + db::history::format_time_utc(r.started_at_ms).substr(0, 10)];
    if (r.ains) values[r.station].push_back((*r.ains)(param));
  }
  std::map<std::string, Counts> shown;
  for (Attrs& v : tags(section(html, "verdicts", "</table>"), "<tr data-station"))
    shown[v["data-station"]] = {std::stoll(v["data-pass"]),    std::stoll(v["data-review"]),
                                std::stoll(v["data-failed"]),  std::stoll(v["data-station-fault"]),
                                std::stoll(v["data-aborted"]), std::stoll(v["data-interrupted"]),
                                std::stoll(v["data-live"]),    std::stoll(v["data-unit-outcomes"])};
  EXPECT_EQ(shown, expected) << "setting '" << setting << "' verdict '" << verdict << "'";
  std::map<std::string, std::int64_t> shown_days;
  for (Attrs& c : tags(section(html, "runs-per-day", "</table>"), "<td class='num' data-station"))
    if (c["data-runs"] != "0")
      shown_days[c["data-station"] + " " + c["data-day"]] = std::stoll(c["data-runs"]);
  EXPECT_EQ(shown_days, per_day);
  const auto dist = tags(section(html, "distribution", "</table>"), "<tr data-station");
  ASSERT_EQ(dist.size(), values.size()) << "setting '" << setting << "'";
  for (Attrs d : dist) {
    const auto e = db::test::expected_summary(values[d["data-station"]]);
    const double tol = 1e-12 * std::max(std::abs(e.min), std::abs(e.max));
    EXPECT_EQ(std::stoll(d["data-count"]), e.n) << d["data-station"];
    EXPECT_NEAR(number(d["data-mean"]), e.mean, tol) << d["data-station"];
    EXPECT_NEAR(number(d["data-std"]), e.sd, tol);
    EXPECT_EQ(number(d["data-min"]), e.min);
    EXPECT_NEAR(number(d["data-median"]), e.median, tol);
    EXPECT_EQ(number(d["data-max"]), e.max);
  }
}

/// The units each station ran among the runs the signatures read (factory, originals, the
/// unit's own outcome, an AINS result): what /signatures' "units" must say.
/// With `runs`, the runs instead of the units.
inline std::map<std::string, std::size_t> truth_signature_units(
    const std::vector<db::test::TruthRow>& rows, bool runs = false) {
  std::map<std::string, std::multiset<std::string>> serials;
  for (const db::test::TruthRow& r : rows)
    if (r.setting == "factory" && !r.reprocessed_from && r.ains &&
        (r.verdict == "PASS" || r.verdict == "REVIEW" || r.verdict == "FAILED"))
      serials[r.station].insert(r.serial);
  std::map<std::string, std::size_t> out;
  for (const auto& [station, s] : serials)
    out[station] = runs ? s.size() : std::set<std::string>(s.begin(), s.end()).size();
  return out;
}

/// /signatures' table and /fleet's banner say the same of every station: its units (counted
/// from the rows), whether it was assessed, whether it was flagged.
inline void expect_signatures_agree(const std::string& signatures, const std::string& fleet,
                                    const std::vector<db::test::TruthRow>& rows) {
  std::map<std::string, std::size_t> units, runs;
  std::map<std::string, std::string> said;  // station -> "flagged" / "not assessed" / "ok"
  for (const std::string& row : [&] {
         std::vector<std::string> out;
         const std::string table = section(signatures, "signatures", "</table>");
         for (std::size_t at = table.find("<tr data-station"); at != std::string::npos;
              at = table.find("<tr data-station", at + 1))
           out.push_back(table.substr(at, table.find("</tr>", at) - at));
         return out;
       }()) {
    Attrs tr = tags(row, "<tr data-station")[0];
    const auto cell = tags(row, "<td class='num' data-units");
    if (!cell.empty()) units[tr["data-station"]] = std::stoul(cell[0].at("data-units"));
    runs[tr["data-station"]] = std::stoul(tr["data-runs"]);
    said[tr["data-station"]] = row.find("not assessed") != std::string::npos ? "not assessed"
                               : tr["data-flagged"] == "1"                   ? "flagged"
                                                                             : "ok";
  }
  EXPECT_EQ(units, truth_signature_units(rows)) << "units per station on /signatures";
  EXPECT_EQ(runs, truth_signature_units(rows, true)) << "runs per station on /signatures";
  const std::string banner = section(fleet, "signature-banner", "</div>");
  ASSERT_FALSE(banner.empty());
  for (const auto& [station, what] : said) {
    SCOPED_TRACE(station + ": " + what + "\n" + banner.substr(0, 1500));
    const bool listed = banner.find("data-station='" + station + "'") != std::string::npos;
    if (what == "ok") {
      EXPECT_FALSE(listed);
    } else {
      EXPECT_TRUE(listed);
      EXPECT_EQ(
          banner.find("data-station='" + station + "' data-assessed='0'") != std::string::npos,
          what == "not assessed");
    }
  }
  const bool all_ok =
      std::all_of(said.begin(), said.end(), [](const auto& st) { return st.second == "ok"; });
  if (!all_ok) {
    EXPECT_EQ(banner.find("no station flagged."), std::string::npos)
        << "a station not assessed is not \"no station flagged\"";
  }
}

/// expect_fleet_truth on /fleet under each filter QA uses (the default factory runs, every setting,
/// land alone, PASS alone, station faults of every setting), the pages fetched by `get(target)`,
/// gyro_bias_radps[2] as the parameter: the same checks of the SQLite and the PostgreSQL backends.
template <typename Get>
void expect_fleet_truth_under_every_filter(Get get, const std::vector<db::test::TruthRow>& rows) {
  const int gz = 14;  // gyro_bias_radps[2]
  const std::string p = "&param=gyro_bias_radps%5B2%5D";
  expect_fleet_truth(get("/fleet?" + p), rows, "factory", "", gz);
  expect_fleet_truth(get("/fleet?setting=all" + p), rows, "", "", gz);
  expect_fleet_truth(get("/fleet?setting=land" + p), rows, "land", "", gz);
  expect_fleet_truth(get("/fleet?verdict=PASS" + p), rows, "factory", "PASS", gz);
  expect_fleet_truth(get("/fleet?setting=all&verdict=STATION-FAULT" + p), rows, "", "STATION-FAULT",
                     gz);
}

}  // namespace imucal::test_support
