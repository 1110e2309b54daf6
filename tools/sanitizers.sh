#!/usr/bin/env bash
# The sanitizer runs of issue #10 (item 5), each in its own build tree beside build/:
#   tools/sanitizers.sh tsan   the threaded tests (capture, turntable client, simulator, control
#                              server, daemon, run controller) and three end-to-end tests whose
#                              stationd/stationsim/stationctl are TSan builds too; every process
#                              writes its reports under build-tsan/reports, and any report fails.
#   tools/sanitizers.sh asan   every test under ASan + UBSan (clang-16; -fno-sanitize-recover: UB
#                              stops the test) but the QEMU guest and the install sets (a kernel in
#                              an emulator, the Debian package's own build trees: neither runs
#                              instrumented code), the slow sets at their CI counts and the bounded
#                              libFuzzer runs among them; tree build-asan, the calibration core
#                              linked uninstrumented from the Release tree (build/ first, which
#                              tools/setup.sh --test builds). Every process's reports go to
#                              build-asan/reports, and any report fails. IMUCAL_SKIP_FUZZ=1 leaves
#                              out the fuzz runs; IMUCAL_ASAN_CORE=1 instruments the core too (tree
#                              build-asan-core; about 6x the suite's Release time against 1.3x,
#                              docs/validation/build-and-ci.md).
#   tools/sanitizers.sh fuzz   only the libFuzzer targets (tree build-fuzz, the calibration core
#                              linked from build/): 30 s of fuzzing each, which starts with their
#                              seed corpus and regression inputs.
# tools/test.sh runs asan and tsan (README, "The test command", for the times). ccache makes repeated
# runs cheap.
# IMUCAL_SANITIZER_TREE=DIR uses another build tree; IMUCAL_BUILD_ONLY=1 stops after the build.
set -euo pipefail
cd "$(dirname "$0")/.."
mode=${1:-}
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER="$(bash tools/ccache_launcher.sh)")
generator() {  # generator TREE: Ninja for a new tree (issue #51), nothing for one configured before
  [ -f "$1/CMakeCache.txt" ] || echo "-GNinja"
}

# The calibration core (single-threaded math, which neither the threaded tests nor the parsers
# need instrumented) linked from the Release tree when it exists, for the tsan and fuzz modes:
# compiling it is most of a sanitizer tree's build time.
release_calib=()
[[ -f build/calib/libimucal_calib_core.a ]] && release_calib=(-DIMUCAL_CALIB_PREBUILT_DIR="$PWD/build/calib")

fresh_reports() {  # fresh_reports TREE: an empty TREE/reports; prints its absolute path
  local dir
  dir=$(cd "$1" && pwd)/reports
  rm -rf "$dir" && mkdir -p "$dir"
  echo "$dir"
}
found_reports() {  # found_reports MODE GLOB: prints the reports matching GLOB; true if any
  compgen -G "$2" >/dev/null || return 1
  echo "$1: sanitizer reports:"
  ls $2
  head -60 $2
}

case $mode in
  tsan)
    tree=${IMUCAL_SANITIZER_TREE:-build-tsan}
    # The threaded test files (room/file): capture, turntable client, simulator, control server,
    # export stream, daemon, run controller, and the end-to-end runs (stationctl diagnose on its own
    # thread, issue #22; the outbox sender's thread beside the run, issue #24). The tree builds them
    # alone (IMUCAL_TEST_SELECTION), in their rooms' programs.
    files=(e2e/station_fleet e2e/station_run e2e/station_faults e2e/station_gap e2e/station_abort
           station/run_controller station/daemon station/capture drivers/turntable_client
           drivers/station_sim station/control_server station/export_stream)
    # Line tables only (-g1) are all the reports need; the test programs at -O0 (compile time).
    cmake -S . -B $tree $(generator $tree) -DIMUCAL_TSAN=ON -DCMAKE_BUILD_TYPE=None -DCMAKE_CXX_FLAGS="-O1 -g1" \
      -DIMUCAL_TEST_OPTIMIZE=-O0 -DIMUCAL_TEST_SELECTION="$(IFS=';'; echo "${files[*]}")" -DIMUCAL_CALIB_PREBUILT_FIRST=OFF \
      "${launcher[@]}" "${release_calib[@]}" >/dev/null
    cmake --build $tree -j2 --target station_tests drivers_tests e2e_tests stationd stationsim stationctl
    reports=$(fresh_reports $tree)
    failed=0
    # The busy-CPU run is a timing test (the daemon sharing a core with busy loops): under TSan it
    # only costs 40 s and says nothing about races that the other runs do not.
    skip="-StationEndToEnd.ShortSequencePassesWithTheDaemonOnABusyCpu"
    # Two files at a time, as ctest -j2 runs the suite (the end-to-end files, the longest, first):
    # each writes its verdict beside its output, read back in the list's order below.
    export TSAN_TREE=$tree TSAN_REPORTS=$reports TSAN_SKIP=$skip
    # <tree>/tests/<room>_<file>_test runs that file's tests (tools/run_test_file.sh).
    programs=("${files[@]//\//_}")
    programs=("${programs[@]/%/_test}")
    printf '%s\n' "${programs[@]}" | xargs -P2 -I{} bash -c '
      t={}
      if TSAN_OPTIONS="halt_on_error=0 second_deadlock_stack=1 log_path=$TSAN_REPORTS/$t" \
        "$TSAN_TREE/tests/$t" --gtest_filter="$TSAN_SKIP" >"$TSAN_REPORTS/$t.out" 2>&1; then
        echo pass >"$TSAN_REPORTS/$t.verdict"
      else
        echo fail >"$TSAN_REPORTS/$t.verdict"
      fi'
    for t in "${programs[@]}"; do
      if [ "$(cat "$reports/$t.verdict" 2>/dev/null)" = pass ]; then
        # A file script that selected no test exits 0 too: that is no pass.
        if ! grep -qE '^\[  PASSED  \] [1-9]' "$reports/$t.out"; then
          echo "tsan: $t ran no test (output: $reports/$t.out)"
          failed=1
          continue
        fi
        echo "tsan: $t passed ($(grep -oE '^\[  PASSED  \] [0-9]+' "$reports/$t.out" | grep -oE '[0-9]+$') tests)"
      else
        echo "tsan: $t FAILED (output: $reports/$t.out); its failures:"
        grep -B2 -A12 -E "Failure|FAILED|terminate|Segmentation" "$reports/$t.out" | head -80 || true
        failed=1
      fi
    done
    found_reports tsan "$reports/*.[0-9]*" && failed=1
    exit $failed
    ;;
  asan | fuzz)
    # clang-16 (gcc takes three times as long to compile under ASan), the same flags for both: the
    # programs under test at -O1, the calibration core at -O2 without Eigen's own index assertions
    # (the suite spends its time in its Eigen loops, ~20x Release's time under ASan with them; ASan
    # itself catches an index out of bounds, and Release runs without them too), the test programs
    # at -O0: under ASan + UBSan a file compiles in a quarter of its -O1 time (stationd's main, 7.4
    # against 31.6 CPU-s), and the tree's cold build went from 1 027 to 592 s (2026-11-30).
    # A test file instantiates the same Eigen templates as the libraries it calls, and the linker
    # keeps the first copy it meets, the test's: so -O0 tests are only affordable because the
    # asan tree loads the calibration core first on every link line, and the core runs its own
    # Release copies (calib/prebuilt_core_first.cmake; not in the TSan tree, which must see
    # std::shared_ptr's atomics instrumented). Before that, Nlsq.NoiseFreeDefaultUnitRecoveredExactly
    # took 20.8 CPU-s with -O0 tests, 1.9 with -O1. The tree's own libraries are loaded first too
    # (whole, after the core), so the programs of tools/ go to -O0 as well, but for those on a run's
    # hot path (IMUCAL_PROGRAM_OPTIMIZE, IMUCAL_KEEP_OPTIMIZED in the top-level CMakeLists.txt).
    # IMUCAL_ASAN_CORE=1 keeps -O1 tests and programs (no core to load first). Only the libFuzzer
    # binaries carry coverage.
    # The fuzz mode has a tree of its own, build-fuzz, that links the Release calibration core like
    # the TSan tree (no parser calls into its math); the asan tree builds and runs the same targets
    # among its tests.
    calib=()
    program_opt=""
    if [ "$mode" = fuzz ]; then
      tree=${IMUCAL_SANITIZER_TREE:-build-fuzz}
      calib=("${release_calib[@]}" -DIMUCAL_CALIB_PREBUILT_FIRST=OFF)
      test_opt=-O0
    elif [ "${IMUCAL_ASAN_CORE:-0}" = 1 ]; then
      tree=${IMUCAL_SANITIZER_TREE:-build-asan-core}
      test_opt=-O1
    else
      # Every test under ASan + UBSan, the calibration core (pure single-threaded arithmetic,
      # fuzzed on its own) linked uninstrumented from the Release tree and loaded first, so that it
      # runs its own Release code (calib/prebuilt_core_first.cmake): 1.3x the tests' Release
      # time against 6.5x with the core instrumented (docs/validation/build-and-ci.md, issue #51).
      if [ ${#release_calib[@]} -eq 0 ]; then
        echo "asan: build/calib/libimucal_calib_core.a is missing: build the Release tree first" \
          "(tools/setup.sh --test), or instrument the core too with IMUCAL_ASAN_CORE=1" >&2
        exit 2
      fi
      tree=${IMUCAL_SANITIZER_TREE:-build-asan}
      calib=("${release_calib[@]}" -DIMUCAL_CALIB_PREBUILT_FIRST=ON)
      test_opt=-O0
      program_opt=-O0
    fi
    CC=clang-16 CXX=clang++-16 cmake -S . -B $tree $(generator $tree) -DIMUCAL_FUZZ=ON -DCMAKE_BUILD_TYPE=None \
      -DCMAKE_CXX_FLAGS="-O1 -gline-tables-only" -DIMUCAL_CALIB_OPTIMIZE="-O2 -DEIGEN_NO_DEBUG" -DIMUCAL_TEST_OPTIMIZE=$test_opt \
      -DIMUCAL_PROGRAM_OPTIMIZE="$program_opt" "${launcher[@]}" "${calib[@]}" >/dev/null
    if [ "$mode" = fuzz ]; then
      # Each fuzz run starts by executing its whole corpus and regression inputs under ASan + UBSan,
      # so the replay programs (tests of the asan tree) are not built here.
      cmake --build $tree -j2 --target fuzz_targets
      selection=(-R "^Fuzz\\.run\\.")
    else
      cmake --build $tree -j2
      # Every test but the QEMU guest and the install sets, the slow sets at their CI counts
      # (docs/validation/ci-counts.md: the same counts and bounds as in Release, and the calibration
      # core is the Release one, so they give the same figures).
      selection=(-LE "qemu|install")
      [ "${IMUCAL_SKIP_FUZZ:-0}" = 1 ] && selection+=(-E "^Fuzz\\.run\\.")
      # The costliest tests first (their Release costs, tests/ctest_costs.txt, for a new tree).
      bash tools/refresh_ctest_costs.sh --seed $tree
    fi
    [ "${IMUCAL_BUILD_ONLY:-0}" = 1 ] && exit 0
    # Every process (test programs and the stationd/stationsim/stationctl/imucal they start) logs
    # its sanitizer reports under $tree/reports; a report fails the stage even when the process
    # that wrote it was a child whose exit status no test looked at.
    reports=$(fresh_reports $tree)
    failed=0
    (cd $tree && ASAN_OPTIONS="detect_leaks=1:log_path=$reports/asan" \
      UBSAN_OPTIONS="print_stacktrace=1:log_path=$reports/ubsan" \
      ctest -j2 "${selection[@]}" --output-on-failure --timeout 1500) || failed=1
    found_reports $mode "$reports/*san.[0-9]*" && failed=1
    exit $failed
    ;;
  *)
    echo "usage: tools/sanitizers.sh tsan|asan|fuzz" >&2
    exit 2
    ;;
esac
