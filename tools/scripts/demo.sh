#!/usr/bin/env bash
# Fresh Debian 12 -> the liver demo (assets/scenes/liver_demo.json): installs
# what is missing, builds, then
#   1. runs the scene with the haptic thread, rendering every frame (PNG, and
#      MP4 when ffmpeg is there) and recording the run;
#   2. replays the recording and verifies it bit for bit;
#   3. times the same frames (incise bench --haptics) and draws the budget.
# Outputs in out/liver_demo/ (README, "The demo"). DEMO_FRAMES=N runs N frames
# instead of the scene's 135 (CI uses a few).
set -euo pipefail
cd "$(dirname "$0")/../.."
bash tools/scripts/install-deps.sh
bash tools/scripts/build.sh build
scene=assets/scenes/liver_demo.json
out=out/liver_demo
frames=(--frames "${DEMO_FRAMES:-135}")
mkdir -p "$out"
./build/tools/incise run "$scene" --haptics --render "$out/frames" --record "$out/liver_demo.replay" "${frames[@]}" "$@"
./build/tools/incise replay "$out/liver_demo.replay" --verify
./build/tools/incise bench "$scene" --haptics --warmup 0 --plot "$out/budget.png" --json "$out/budget.json" "${frames[@]}" "$@"
echo "demo: frames in $out/frames, haptic logs and timing.json in $out, budget in $out/budget.png"
