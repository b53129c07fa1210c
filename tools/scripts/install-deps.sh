#!/usr/bin/env bash
# Installs the Debian 12 packages incise needs, only those missing.
set -euo pipefail
packages=(
  build-essential cmake ninja-build pkg-config
  libeigen3-dev libsuitesparse-dev libopenblas0-pthread
  nlohmann-json3-dev libcli11-dev libgtest-dev libbenchmark-dev
  libegl-dev libgl-dev libgl1-mesa-dri libegl-mesa0 libpng-dev
  libfcl-dev libccd-dev zlib1g-dev
  libboost-dev libopenigtlink-dev
  clang-15 python3-matplotlib python3-meshio tetgen
)
missing=()
for p in "${packages[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -eq 0 ]; then
  echo "install-deps: all ${#packages[@]} packages present"
  exit 0
fi
echo "install-deps: installing ${missing[*]}"
sudo_cmd=""
[ "$(id -u)" -eq 0 ] || sudo_cmd="sudo"
export DEBIAN_FRONTEND=noninteractive
$sudo_cmd apt-get update -qq
$sudo_cmd apt-get install -y -qq --no-install-recommends "${missing[@]}"
