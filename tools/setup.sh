#!/usr/bin/env bash
# Installs every Debian package the project needs, then configures and builds it.
# Idempotent: safe to run on a fresh machine and again on a prepared one.
set -euo pipefail
cd "$(dirname "$0")/.."
PKGS=(build-essential cmake ccache pkg-config
      libeigen3-dev libceres-dev libmodbus-dev libsqlite3-dev libspdlog-dev
      libgtest-dev libgmock-dev libcli11-dev libtomlplusplus-dev nlohmann-json3-dev
      libbenchmark-dev
      can-utils python3-can python3-canmatrix mbpoll
      libsystemd-dev qemu-system-x86 linux-image-amd64 busybox-static cpio iproute2 xz-utils binutils
      chromium clang-16 libclang-rt-16-dev)
missing=()
for p in "${PKGS[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq "${missing[@]}"
fi
BUILD_TYPE=${BUILD_TYPE:-Release}
cmake -S . -B build -DCMAKE_BUILD_TYPE="$BUILD_TYPE" -DCMAKE_CXX_COMPILER_LAUNCHER=ccache >/dev/null
cmake --build build -j2
