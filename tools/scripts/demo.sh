#!/usr/bin/env bash
# Fresh Debian 12 -> a sagging beam: installs what is missing, builds, runs the
# default scene (ParaView series + timing summary in out/beam_gravity/).
set -euo pipefail
cd "$(dirname "$0")/../.."
bash tools/scripts/install-deps.sh
bash tools/scripts/build.sh build
./build/tools/incise run assets/scenes/beam_gravity.json "$@"
