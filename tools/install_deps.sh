#!/usr/bin/env bash
# Installs the Debian 12 packages streamcvd needs to build and test, only when some are missing.
# Usage: tools/install_deps.sh   (as root, or with sudo available)
set -euo pipefail
packages=(build-essential cmake g++ pkg-config git
  libeigen3-dev libtbb-dev libzstd-dev zstd libopenmesh-dev libcli11-dev
  libfast-float-dev nlohmann-json3-dev libgtest-dev libpng-dev
  pybind11-dev python3-dev python3-numpy python3-pytest  # the Python module (python/) and its tests
  clang-14 libclang-rt-14-dev)  # clang: the libFuzzer targets (fuzz/)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install_deps: all ${#packages[@]} packages present"
  exit 0
fi
echo "install_deps: installing ${missing[*]}"
SUDO=""
if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
export DEBIAN_FRONTEND=noninteractive
$SUDO apt-get update -qq
$SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}"
