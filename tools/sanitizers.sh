#!/usr/bin/env bash
# The sanitizer runs of issue #10 (item 5), each in its own build tree beside build/:
#   tools/sanitizers.sh tsan   the threaded tests (capture, turntable client, simulator, control
#                              server, daemon, run controller) and three end-to-end tests whose
#                              stationd/stationsim/stationctl are TSan builds too; every process
#                              writes its reports under build-tsan/reports, and any report fails.
#   tools/sanitizers.sh asan   the whole suite except the Monte Carlo, QEMU and fuzz sets under
#                              ASan + UBSan (gcc; -fno-sanitize-recover: UB stops the test).
# tools/test.sh runs the tsan mode (~5 min); the asan mode does not fit beside the Release suite
# in CI's 30 minutes on 2 cores (README, "Reliability"). ccache makes repeated runs cheap.
# IMUCAL_SANITIZER_TREE=DIR uses another build tree.
set -euo pipefail
cd "$(dirname "$0")/.."
mode=${1:-}
launcher=()
command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)

case $mode in
  tsan)
    tree=${IMUCAL_SANITIZER_TREE:-build-tsan}
    # The calibration core (single-threaded math) is linked from the Release tree when it exists.
    calib=()
    [[ -f build/calib/libimucal_calib.a ]] && calib=(-DIMUCAL_CALIB_LIBRARY="$PWD/build/calib/libimucal_calib.a")
    cmake -S . -B $tree -DIMUCAL_TSAN=ON -DCMAKE_BUILD_TYPE=None -DCMAKE_CXX_FLAGS="-O1 -g" \
      "${launcher[@]}" "${calib[@]}" >/dev/null
    tests=(station_capture_test drivers_turntable_client_test drivers_station_sim_test
           station_control_server_test station_daemon_test station_run_controller_test
           e2e_station_run_test e2e_station_abort_test e2e_station_faults_test)
    cmake --build $tree -j2 --target "${tests[@]}" stationd stationsim stationctl
    reports=$(cd "$tree" && pwd)/reports
    rm -rf "$reports" && mkdir -p "$reports"
    failed=0
    for t in "${tests[@]}"; do
      if TSAN_OPTIONS="halt_on_error=0 second_deadlock_stack=1 log_path=$reports/$t" \
        "$tree/tests/$t" >"$reports/$t.out" 2>&1; then
        echo "tsan: $t passed"
      else
        echo "tsan: $t FAILED (output: $reports/$t.out)"
        failed=1
      fi
    done
    if compgen -G "$reports/*.[0-9]*" >/dev/null; then
      echo "tsan: ThreadSanitizer reports:"
      ls "$reports"/*.[0-9]*
      head -40 "$reports"/*.[0-9]*
      failed=1
    fi
    exit $failed
    ;;
  asan)
    tree=${IMUCAL_SANITIZER_TREE:-build-asan}
    cmake -S . -B $tree -DIMUCAL_SANITIZE=ON -DCMAKE_BUILD_TYPE=None -DCMAKE_CXX_FLAGS="-O1 -g" \
      "${launcher[@]}" >/dev/null
    cmake --build $tree -j2
    (cd $tree && ASAN_OPTIONS=detect_leaks=1 ctest -j2 -LE "slow|qemu|fuzz" --output-on-failure --timeout 1500)
    ;;
  *)
    echo "usage: tools/sanitizers.sh tsan|asan" >&2
    exit 2
    ;;
esac
