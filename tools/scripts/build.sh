#!/usr/bin/env bash
# Configures and builds incise. Usage: build.sh BUILD_DIR [extra cmake args]
set -euo pipefail
cd "$(dirname "$0")/../.."
dir="$1"; shift
gen=()
command -v ninja >/dev/null && gen=(-G Ninja)
cmake -S . -B "$dir" "${gen[@]}" -DCMAKE_BUILD_TYPE=Release "$@" >/dev/null
cmake --build "$dir" -j "$(nproc)"
