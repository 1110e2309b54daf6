#pragma once
// Whose a run's end was (issue #50), as SQL: the rule that classifies the runs stored before the
// verdict was, and the verdicts each state allows. One text for the station's history (migration
// 10) and the fleet store (migration 4), so that a store counts the runs its stations have not
// resent yet as the stations do.
#include <string>

namespace imucal::db::history {

/// A CASE expression over the columns `state` and `failure_reason`: done → PASS, review → REVIEW,
/// interrupted → INTERRUPTED, aborted by the table ("table: …") → STATION-FAULT, other aborted →
/// ABORTED, failed by the archive, the import's storage or the CAN channel (the reason texts the
/// station writes) → STATION-FAULT, every other failed → FAILED.
inline constexpr const char* kVerdictOfEndedRunSql = R"SQL(CASE
    WHEN state = 'done' THEN 'PASS'
    WHEN state = 'review' THEN 'REVIEW'
    WHEN state = 'interrupted' THEN 'INTERRUPTED'
    WHEN state = 'aborted' AND failure_reason LIKE 'table: %' THEN 'STATION-FAULT'
    WHEN state = 'aborted' THEN 'ABORTED'
    WHEN failure_reason LIKE 'archive: %'
      OR failure_reason LIKE 'import: cannot store the archive%'
      OR failure_reason LIKE 'capture: CAN channel error%'
      OR failure_reason LIKE 'capture: CAN controller % went bus-off%'
      OR failure_reason LIKE 'capture: run archive write failed%'
      OR failure_reason LIKE 'capture: %the CAN channel is closed%'
      OR failure_reason LIKE 'capture: unixcan:%'
      OR failure_reason LIKE 'capture: socketcan:%'
      OR failure_reason LIKE 'capture: candump:%' THEN 'STATION-FAULT'
    ELSE 'FAILED' END)SQL";

/// A boolean SQL expression: the verdict fits the state (none while live; PASS done, REVIEW
/// review; a station fault may end a run failed, aborted or interrupted). `row` prefixes the
/// columns ("NEW." in a trigger, "" in a CHECK).
inline std::string verdict_fits_state_sql(const std::string& row) {
  const std::string s = row + "state", v = row + "verdict";
  return "(" + s + " IN ('preparing', 'running', 'calibrating') AND " + v + " IS NULL)\n  OR (" +
         s + " = 'done' AND " + v + " = 'PASS') OR (" + s + " = 'review' AND " + v +
         " = 'REVIEW')\n  OR (" + s + " = 'failed' AND " + v +
         " IN ('FAILED', 'STATION-FAULT'))\n  OR (" + s + " = 'aborted' AND " + v +
         " IN ('ABORTED', 'STATION-FAULT'))\n  OR (" + s + " = 'interrupted' AND " + v +
         " IN ('INTERRUPTED', 'STATION-FAULT'))";
}

}  // namespace imucal::db::history
