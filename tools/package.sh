#!/usr/bin/env bash
# Builds the Debian package build/imucal_<version>_amd64.deb (README, "Install"): what the main job
# installs and builds (tools/setup.sh --main), help2man for the man pages and cpp-httplib for
# stationweb (QA's web view, packaged beside the four programs), then cpack.
# Install it with:  sudo apt-get install ./build/imucal_<version>_amd64.deb
set -euo pipefail
cd "$(dirname "$0")/.."
bash tools/setup.sh --main
if ! command -v help2man >/dev/null || ! pkg-config --exists cpp-httplib; then
  SUDO=""
  [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq help2man libcpp-httplib-dev
fi
cmake -S . -B build >/dev/null  # finds help2man and cpp-httplib if they were just installed
cmake --build build -j2 --target install_data stationweb
(cd build && cpack -G DEB)
deb=$(ls -t build/imucal_*_amd64.deb | head -1)
echo "package: $deb"
echo "install: sudo apt-get install ./$deb"
