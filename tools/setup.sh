#!/usr/bin/env bash
# Installs the Debian packages the project needs, then configures and builds it.
#   tools/setup.sh          everything: all packages, every program, test and benchmark
#   tools/setup.sh --test   the test command (tools/test.sh): all packages; in build/ every program,
#                           the calibration core the sanitizer trees link and the install and QEMU
#                           tests (the rest of the suite runs under ASan + UBSan, issue #51)
#   tools/setup.sh --main   the main job (tools/demo.sh) and the install: only the packages the four
#                           programs need, and only imucal, stationd, stationsim and stationctl
#                           (no test program, no test-only package)
# Idempotent: safe to run on a fresh machine and again on a prepared one. Both modes build in
# build/ (IMUCAL_BUILD_DIR=DIR: elsewhere).
# The packages only tests need (qemu and a kernel image, chromium, clang-16, the CAN and Modbus peer
# tools, lintian for the Debian package, the PostgreSQL server the fleet tests start a throw-away
# cluster of; the main job needs no server, only libpq to link stationd) are installed in the background while the build runs:
# their download and unpacking overlap the compilation, and the script waits for them before it
# returns.
set -euo pipefail
cd "$(dirname "$0")/.."
MODE=all
case "${1:-}" in
  "") ;;
  --main) MODE=main ;;
  --test) MODE=test ;;
  *)
    echo "usage: tools/setup.sh [--main | --test]" >&2
    exit 2
    ;;
esac
MAIN_PKGS=(build-essential cmake ninja-build ccache pkg-config
           libeigen3-dev libceres-dev libmodbus-dev libsqlite3-dev libspdlog-dev
           libcli11-dev libtomlplusplus-dev nlohmann-json3-dev libsystemd-dev libpq-dev)
# Needed before the build, so not in the background: the test programs' and benchmarks' libraries,
# help2man (CMake looks for it when it configures; the man pages of the Debian package), and
# cpp-httplib for stationweb, QA's web view (not a main-job program) and its test.
TEST_BUILD_PKGS=(libgtest-dev libgmock-dev libbenchmark-dev help2man libcpp-httplib-dev)
TEST_PKGS=(can-utils python3-can python3-canmatrix mbpoll
           qemu-system-x86 linux-image-amd64 busybox-static cpio iproute2 xz-utils binutils
           chromium clang-16 libclang-rt-16-dev lintian postgresql)
PROGRAMS=(imucal stationd stationsim stationctl)
SUDO=""
[ "$(id -u)" -ne 0 ] && SUDO="sudo"

missing() {  # the packages of "$@" not installed yet
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || echo "$p"
  done
}
install() {
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "$@"
}

if [ $MODE = main ]; then
  mapfile -t missing_build < <(missing "${MAIN_PKGS[@]}")
  missing_test=()
else
  mapfile -t missing_build < <(missing "${MAIN_PKGS[@]}" "${TEST_BUILD_PKGS[@]}")
  mapfile -t missing_test < <(missing "${TEST_PKGS[@]}")
fi
if [ $((${#missing_build[@]} + ${#missing_test[@]})) -gt 0 ]; then
  $SUDO apt-get update -qq
fi
[ ${#missing_build[@]} -gt 0 ] && install "${missing_build[@]}"

apt_pid=""
apt_log=$(mktemp "${TMPDIR:-/tmp}/imucal-apt-XXXXXX")
if [ ${#missing_test[@]} -gt 0 ]; then
  install "${missing_test[@]}" </dev/null >"$apt_log" 2>&1 &
  apt_pid=$!
fi

BUILD_TYPE=${BUILD_TYPE:-Release}
# The test programs at -O1: a quarter to a third less compile time than Release's -O3 (their own
# code only orchestrates and asserts; the code under test keeps the build type's flags). Linked by
# gold (binutils): 0.3 s instead of 1.0 s for each of ~90 programs.
targets=()
tests=ON
if [ $MODE = main ]; then
  targets=(--target "${PROGRAMS[@]}")
  tests=OFF
elif [ $MODE = test ]; then
  targets=(--target test_command_release)
fi
build_status=0
BUILD_DIR=${IMUCAL_BUILD_DIR:-build}
# Ninja for a new tree (issue #51): it schedules the whole graph at -j2 where make waits directory by
# directory, and its .ninja_log is what tools/build_profile.py reads. A tree configured before
# keeps its generator (CMake refuses to change it).
generator=()
[ -f "$BUILD_DIR/CMakeCache.txt" ] || generator=(-G Ninja)
{ cmake -S . -B "$BUILD_DIR" "${generator[@]}" -DCMAKE_BUILD_TYPE="$BUILD_TYPE" \
    -DCMAKE_CXX_COMPILER_LAUNCHER="$(bash tools/ccache_launcher.sh)" \
    -DCMAKE_INSTALL_PREFIX=/usr -DIMUCAL_BUILD_TESTS=$tests -DCMAKE_EXE_LINKER_FLAGS=-fuse-ld=gold \
    -DIMUCAL_TEST_OPTIMIZE="${IMUCAL_TEST_OPTIMIZE--O1}" >/dev/null &&
  cmake --build "$BUILD_DIR" -j2 "${targets[@]}"; } || build_status=$?

if [ -n "$apt_pid" ]; then
  if ! wait "$apt_pid"; then
    cat "$apt_log" >&2
    echo "setup: installing the test packages failed: ${missing_test[*]}" >&2
    rm -f "$apt_log"
    exit 1
  fi
fi
rm -f "$apt_log"
exit $build_status
