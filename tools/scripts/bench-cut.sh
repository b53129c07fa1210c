#!/usr/bin/env bash
# Frame times with and without a cut on a ~20k-DOF tet10 beam (28x5x5 cells),
# and the cost of the cut frame: a through-cut plane at 0.5 s and, separately,
# a progressive incision swept over 1 s. Usage: bench-cut.sh [BUILD_DIR] [FRAMES]
set -euo pipefail
cd "$(dirname "$0")/../.."
build="${1:-build}"
frames="${2:-45}"
incise="$build/tools/incise"
out="$build/bench"
mkdir -p "$out"
mesh="$out/beam_28x5x5.vtu"
[ -f "$mesh" ] || "$incise" mesh beam --size 0.2 0.05 0.05 --cells 28 5 5 --out "$mesh" >/dev/null
common='"mesh": {"file": "beam_28x5x5.vtu", "order": 2},
 "material": {"model": "corotated", "young": 1e5, "poisson": 0.45, "density": 1000,
              "rayleigh": {"mass": 1.0, "stiffness": 0.002}},
 "mass": "lumped", "gravity": [0, 0, -9.81], "fixed": [{"box": [[-1, -1, -1], [0, 1, 1]]}]'
echo "{$common}" > "$out/cut-none.json"
echo "{$common, \"cuts\": [{\"type\": \"plane\", \"point\": [0.1213, 0, 0], \"normal\": [1, 0.05, 0.1], \"at_time\": 0.5}]}" > "$out/cut-plane.json"
echo "{$common, \"cuts\": [{\"type\": \"swept\", \"edge_start\": [[0.1213, -0.01, 0.06], [0.1213, 0.06, 0.06]],
  \"edge_end\": [[0.1213, -0.01, 0.01], [0.1213, 0.06, 0.01]], \"at_time\": 0.2, \"duration\": 1.0}]}" > "$out/cut-swept.json"
for c in none plane swept; do
  echo "== $c" >&2
  "$incise" bench "$out/cut-$c.json" --frames "$frames" --json "$out/cut-$c.result.json" | tail -12
done
