#!/usr/bin/env bash
# Installs every Debian package the project needs, then configures and builds it.
# Idempotent: safe to run on a fresh machine and again on a prepared one.
# The packages only tests need (qemu and a kernel image, chromium, clang-16, the CAN and Modbus peer
# tools) are installed in the background while the build runs: their download and unpacking
# overlap the compilation, and the script waits for them before it returns.
set -euo pipefail
cd "$(dirname "$0")/.."
BUILD_PKGS=(build-essential cmake ccache pkg-config
            libeigen3-dev libceres-dev libmodbus-dev libsqlite3-dev libspdlog-dev
            libgtest-dev libgmock-dev libcli11-dev libtomlplusplus-dev nlohmann-json3-dev
            libbenchmark-dev libsystemd-dev)
TEST_PKGS=(can-utils python3-can python3-canmatrix mbpoll
           qemu-system-x86 linux-image-amd64 busybox-static cpio iproute2 xz-utils binutils
           chromium clang-16 libclang-rt-16-dev)
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

mapfile -t missing_build < <(missing "${BUILD_PKGS[@]}")
mapfile -t missing_test < <(missing "${TEST_PKGS[@]}")
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
# code only orchestrates and asserts; the code under test keeps the build type's flags).
build_status=0
{ cmake -S . -B build -DCMAKE_BUILD_TYPE="$BUILD_TYPE" -DCMAKE_CXX_COMPILER_LAUNCHER=ccache \
    -DIMUCAL_TEST_OPTIMIZE="${IMUCAL_TEST_OPTIMIZE--O1}" >/dev/null &&
  cmake --build build -j2; } || build_status=$?

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
