#!/usr/bin/env bash
# Frame-time study on cantilever beams of about 1k, 5k, 20k and 50k DOF for
# tet4, tet10 and tet10SR (corotated, gravity, lumped mass, exact policy).
# Usage: bench-beams.sh [BUILD_DIR] [FRAMES]. Writes BUILD_DIR/bench/*.json and
# prints a markdown table (median ms per stage, factor size and flops).
set -euo pipefail
cd "$(dirname "$0")/../.."
build="${1:-build}"
frames="${2:-30}"
incise="$build/tools/incise"
out="$build/bench"
mkdir -p "$out"
# name order rotation nx ny nz
cases=(
  "tet4-1k 1 per_point 16 4 4"   "tet4-5k 1 per_point 28 7 7"
  "tet4-20k 1 per_point 44 11 11" "tet4-50k 1 per_point 60 15 15"
  "tet10-1k 2 per_point 8 2 2"    "tet10-5k 2 per_point 16 3 3"
  "tet10-20k 2 per_point 28 5 5"  "tet10-50k 2 per_point 36 7 7"
  "tet10SR-1k 2 single 8 2 2"     "tet10SR-5k 2 single 16 3 3"
  "tet10SR-20k 2 single 28 5 5"   "tet10SR-50k 2 single 36 7 7"
)
for c in "${cases[@]}"; do
  read -r name order rot nx ny nz <<<"$c"
  mesh="$out/beam_${nx}x${ny}x${nz}.vtu"
  [ -f "$mesh" ] || "$incise" mesh beam --size 0.2 0.05 0.05 --cells "$nx" "$ny" "$nz" --out "$mesh" >/dev/null
  cat >"$out/$name.json" <<JSON
{"mesh": {"file": "$(basename "$mesh")", "order": $order},
 "material": {"model": "corotated", "rotation": "$rot", "young": 1e5, "poisson": 0.45, "density": 1000,
              "rayleigh": {"mass": 1.0, "stiffness": 0.002}},
 "mass": "lumped", "gravity": [0, 0, -9.81],
 "fixed": [{"box": [[-1, -1, -1], [0, 1, 1]]}]}
JSON
  echo "bench $name ..." >&2
  "$incise" bench "$out/$name.json" --frames "$frames" --warmup 2 --json "$out/$name.result.json" >/dev/null
done
python3 - "$out" "${cases[@]}" <<'PY'
import json, sys
out = sys.argv[1]
print("| case | DOF | assembly | factorization | solve | integration | frame median | frame p99 | over 33 ms | nnz(L) | Mflop/factor | GFLOP/s |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|")
for c in sys.argv[2:]:
    name = c.split()[0]
    j = json.load(open(f"{out}/{name}.result.json"))
    s = j["stages"]
    fm = s["factorization"]["median_ms"]
    gf = j["factor"]["flops"] / (fm * 1e-3) * 1e-9 if fm > 0 else 0
    print(f"| {name} | {j['dof']} | {s['assembly']['median_ms']:.2f} | {fm:.2f} | {s['solve']['median_ms']:.2f} | "
          f"{s['integration']['median_ms']:.2f} | {j['frame']['median_ms']:.2f} | {j['frame']['p99_ms']:.2f} | "
          f"{100*j['frame']['over_budget']:.0f}% | {j['factor']['nnz_L']:.3g} | {j['factor']['flops']*1e-6:.1f} | {gf:.2f} |")
PY
