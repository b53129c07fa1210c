#!/usr/bin/env bash
# Render-stage timings: the tet10 ~20k-DOF beam of bench-beams.sh stepped
# with `incise bench --render` at 640x480 and 1280x720 (the EGL platform
# chosen automatically; INCISE_EGL_PLATFORM forces one). Prints the median
# and p95 render ms per frame; then, where it was built (libbenchmark-dev),
# incise_render_bench: the render stage alone, uncut and with a hand-made cut.
# Usage: bench-render.sh [BUILD_DIR] [FRAMES]
set -euo pipefail
cd "$(dirname "$0")/../.."
build="${1:-build}"
frames="${2:-20}"
incise="$build/tools/incise"
out="$build/bench-render"
mkdir -p "$out"
mesh="$out/beam_28x5x5.vtu"
[ -f "$mesh" ] || "$incise" mesh beam --size 0.2 0.05 0.05 --cells 28 5 5 --out "$mesh" >/dev/null
for res in "640 480" "1280 720"; do
  read -r w h <<<"$res"
  cat >"$out/beam_${w}x${h}.json" <<JSON
{"mesh": {"file": "$(basename "$mesh")", "order": 2},
 "material": {"model": "corotated", "young": 1e5, "poisson": 0.45, "density": 1000,
              "rayleigh": {"mass": 1.0, "stiffness": 0.002}},
 "fixed": [{"box": [[-1, -1, -1], [0, 1, 1]]}],
 "render": {"width": $w, "height": $h}}
JSON
  "$incise" bench "$out/beam_${w}x${h}.json" --frames "$frames" --warmup 2 --render \
    --json "$out/beam_${w}x${h}.result.json" | grep -E "^(render|frame) |EGL|dof|DOF" || true
done
if [ -x "$build/tools/incise_render_bench" ]; then
  "$build/tools/incise_render_bench"
fi
