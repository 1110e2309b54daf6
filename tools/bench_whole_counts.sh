#!/usr/bin/env bash
# The suite's Monte Carlo, validation and heavy tests at the issues' whole counts (issue #51 item 3;
# figures in docs/validation/ci-counts.md). ctest runs each at a reduced CI count; this runs them
# one at a time with IMUCAL_WHOLE_COUNTS=1 (tests/support/ci_count.hpp) from BUILD_DIR/tests with
# --gtest_filter, and prints each one's outcome, wall time and CPU time (/usr/bin/time). A
# benchmark, not CI: an hour or more on two cores without the soak (the soak's 1000 runs add
# ~50 min: --with-soak).
# Usage: tools/bench_whole_counts.sh [BUILD_DIR] [--ci] [--with-soak] [--only REGEX] [--log DIR]
#   BUILD_DIR default build (its tests/ and bin/ built);
#   --ci          the same tests at their CI counts (IMUCAL_WHOLE_COUNTS unset), for the comparison;
#   --with-soak   also the soak (1000 runs over 50 units at the whole count);
#   --only REGEX  only the tests whose "program filter" matches REGEX (grep -E);
#   --log DIR     each test's output kept in DIR (default a temporary directory, removed).
# A per-test variable in the environment (IMUCAL_GAP_NULL_SEEDS, IMUCAL_VALIDATION_RUNS, ...) still
# overrides its count. Exit status: 0 when every test passed, 1 otherwise.
set -uo pipefail
cd "$(dirname "$0")/.."
BUILD=build MODE=whole SOAK=0 ONLY="" LOGDIR=""
while [ $# -gt 0 ]; do
  case "$1" in
    --ci) MODE=ci; shift ;;
    --with-soak) SOAK=1; shift ;;
    --only) ONLY=$2; shift 2 ;;
    --log) LOGDIR=$2; shift 2 ;;
    -*) echo "bench_whole_counts.sh: unknown option $1" >&2; exit 2 ;;
    *) BUILD=$1; shift ;;
  esac
done

# program (in BUILD/tests) and gtest filter, one test a line: the tests whose count or scale
# follows IMUCAL_WHOLE_COUNTS.
TESTS=(
  "calib_sequence_design_slow_test SequenceDesignAtItsOwnTime.NoGroupWorseThanFactoryStd"
  "calib_sequence_design_slow_test SequenceDesignForATarget.FindsAShorterSequenceWithinTheFactorOfShort"
  "station_gap_review_slow_test GapReview.NullRunsStillPass"
  "calib_diagnosis_validation_slow_test DiagnosisValidation.FactoryStdMeetsTheBarWithMargins"
  "calib_diagnosis_land_validation_slow_test LandDiagnosisValidation.FactoryStdByHandMeetsTheBarWithMargins"
  "calib_diagnosis_sea_validation_slow_test SeaDiagnosisValidation.FactoryStdAtSeaMeetsTheBarWithMargins"
  "tools_diagnosis_several_effects_slow_test DiagnosisSeveralEffects.TheProjectsSimulatorMeetsTheBarWithMargins"
  "tools_diagnosis_several_effects_slow_test DiagnosisSeveralEffects.TheIndependentSimulatorMeetsTheBarWithMargins"
  "e2e_station_multi_unit_test StationMultiUnit.FourUnitsOnOneFactoryStdRunEachPassWithinFourSigmaOfItsOwnTruth"
  "e2e_station_crash_slow_test StationCrash.*"
  "fleet_fleet_replication_test FleetReplication.TwentyStationsLoseNothingThroughKillsAndACut"
  "e2e_station_speed_test StationSpeed.TheSameRunsGiveTheSameVerdictsAt100x200xAnd400xOnABusyCpu"
  "tools_imucal_gap_budget_cli_test GapBudgetCli.PrintsTheBudgetWithEverySourcesSizeShareAndWhereToFixIt"
  "tools_imucal_gap_budget_cli_test GapBudgetCli.ShowsItsProgressOnStderr"
  "calib_factory_fast_mc_slow_test FactoryFastMonteCarlo.*"
  "calib_field_calibration_slow_test *FieldCalibration.*"
)
[ "$SOAK" = 1 ] && TESTS+=("e2e_station_soak_slow_test StationSoak.*")

if [ -z "$LOGDIR" ]; then
  LOGDIR=$(mktemp -d)
  trap 'rm -rf "$LOGDIR"' EXIT
fi
mkdir -p "$LOGDIR"
if [ "$MODE" = whole ]; then export IMUCAL_WHOLE_COUNTS=1; else unset IMUCAL_WHOLE_COUNTS; fi

failed=0
printf '%-9s %-6s %8s %8s  %s\n' counts result wall_s cpu_s test
for t in "${TESTS[@]}"; do
  [ -n "$ONLY" ] && ! grep -qE -- "$ONLY" <<<"$t" && continue
  read -r prog filter <<<"$t"
  exe=$BUILD/tests/$prog
  if [ ! -x "$exe" ]; then
    printf '%-9s %-6s %8s %8s  %s\n' "$MODE" MISSING - - "$filter ($exe not built)"
    failed=1
    continue
  fi
  log=$LOGDIR/$(tr -c 'A-Za-z0-9_.-' _ <<<"$filter").log
  # Wall and CPU seconds (user + system, children included): on a shared machine the wall time
  # grows with the other load, the CPU time hardly.
  (cd "$BUILD/tests" && /usr/bin/time -f "@@time %e %U %S" "./$prog" --gtest_filter="$filter") \
    >"$log" 2>&1
  rc=$?
  read -r wall cpu < <(awk '/^@@time / { print $2, $3 + $4 }' "$log" | tail -n 1)
  result=PASS
  if [ $rc -ne 0 ]; then result=FAIL; failed=1; fi
  printf '%-9s %-6s %8.1f %8.1f  %s\n' "$MODE" $result "${wall:-0}" "${cpu:-0}" "$filter"
done
exit $failed
