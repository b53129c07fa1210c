#!/usr/bin/env bash
# Solver-policy study (issue 4): the swinging-beam scene (assets/scenes/swing_beam.json:
# clamped at x = 0, free end prescribed through a large arc over 1 s, gravity,
# soft corotated tet10) at about 3k, 10k, 20k and 30k DOF, and a compact cube
# (clamped base, top face dragged sideways) at about 4k, 10k and 20k DOF, and
# the organ-like gmsh meshes assets/meshes/organ_{3k,10k,20k,30k}.msh with the
# boundary conditions of assets/scenes/organ_drag.json (flat bottom clamped, a
# 2 x 2 cm cap of the top pushed down 1 cm and dragged 1.5 cm over 1 s, E = 3e4).
# Each size runs `incise compare` (exact reference, then lagged refreshed every
# 5 frames in the step, warped, warped_cg) and `incise bench` of lagged with a
# background factor (k = 1), and writes BUILD/policies/*.json; the table
# printed at the end is what docs/benchmarks.md quotes.
# POLICY_TANGENT=consistent runs every case with integrator.tangent "consistent"
# (default: frozen_rotation, the scene default).
# Usage: bench-policies.sh [BUILD_DIR] [FRAMES_SMALL] [FRAMES_LARGE]
set -euo pipefail
cd "$(dirname "$0")/../.."
build="${1:-build}"
frames_small="${2:-300}"
frames_large="${3:-60}"
incise="$build/tools/incise"
tangent="${POLICY_TANGENT:-frozen_rotation}"
out="$build/policies"
mkdir -p "$out"
# name kind nx ny nz frames policies (warped_cg needs ~100 iterations on this
# scene, so it runs on the small cases only); organ cases: nx = mesh suffix
cases=(
  "beam-3k beam 10 3 3 $frames_small lagged,warped,warped_cg"
  "beam-10k beam 20 4 4 $frames_small lagged,warped"
  "beam-20k beam 28 5 5 $frames_large lagged,warped"
  "beam-30k beam 28 6 6 $frames_large lagged,warped"
  "cube-4k cube 5 5 5 $frames_large lagged,warped,warped_cg"
  "cube-10k cube 7 7 7 $frames_large lagged,warped"
  "cube-20k cube 9 9 9 $frames_large lagged,warped"
  "organ-3k organ 3k - - $frames_small lagged,warped,warped_cg"
  "organ-10k organ 10k - - $frames_small lagged,warped"
  "organ-20k organ 20k - - $frames_large lagged,warped"
  "organ-30k organ 30k - - $frames_large lagged,warped"
)
only="${BENCH_ONLY:-}"  # e.g. BENCH_ONLY="beam-20k cube-4k" to run some cases
for c in "${cases[@]}"; do
  read -r name kind nx ny nz frames policies <<<"$c"
  if [ -n "$only" ] && [[ " $only " != *" $name "* ]]; then continue; fi
  young=1e5
  if [ "$kind" = organ ]; then
    mesh="assets/meshes/organ_$nx.msh"  # committed; see assets/meshes/organ.geo
    young=3e4
    bc='"fixed": [{"box": [[-1, -1, -1], [1, 1, 0]]}],
 "prescribed": [{"box": [[-0.025, -0.01, 0.041], [-0.005, 0.01, 0.06]],
                 "displacement": {"x": 0.015, "y": 0, "z": -0.01}, "ramp": 1.0}]'
  elif [ "$kind" = beam ]; then
    mesh="$out/beam_${nx}x${ny}x${nz}.vtu"
    [ -f "$mesh" ] || "$incise" mesh beam --size 0.2 0.05 0.05 --cells "$nx" "$ny" "$nz" --out "$mesh" >/dev/null
    bc='"fixed": [{"box": [[-1, -1, -1], [0, 1, 1]]}],
 "prescribed": [{"plane": {"point": [0.2, 0, 0], "normal": [-1, 0, 0]},
                 "displacement": {"x": -0.12, "y": 0.1, "z": 0.08}, "ramp": 1.0}]'
  else
    mesh="$out/cube_${nx}.vtu"
    [ -f "$mesh" ] || "$incise" mesh beam --size 0.1 0.1 0.1 --cells "$nx" "$ny" "$nz" --out "$mesh" >/dev/null
    bc='"fixed": [{"box": [[-1, -1, -1], [1, 1, 0]]}],
 "prescribed": [{"plane": {"point": [0, 0, 0.1], "normal": [0, 0, -1]},
                 "displacement": {"x": 0.05, "y": 0.03, "z": -0.03}, "ramp": 1.0}]'
  fi
  cat >"$out/$name.json" <<JSON
{"mesh": {"file": "$(realpath --relative-to="$out" "$mesh")", "order": 2},
 "material": {"model": "corotated", "young": $young, "poisson": 0.45, "density": 1000,
              "rayleigh": {"mass": 1.0, "stiffness": 0.002}},
 "mass": "lumped", "gravity": [0, 0, -9.81], "integrator": {"tangent": "$tangent"},
 $bc}
JSON
  echo "compare $name ($frames frames) ..." >&2
  "$incise" compare "$out/$name.json" --policy "$policies" --refresh-every 5 --max-iterations 100 \
    --frames "1,10,$frames" --json "$out/$name.result.json" >"$out/$name.log" 2>&1 || echo "  failed: see $out/$name.log" >&2
  "$incise" bench "$out/$name.json" --policy lagged --background --frames 30 --warmup 2 \
    --json "$out/$name.background.json" >"$out/$name.background.log" 2>&1 || echo "  failed: see $out/$name.background.log" >&2
done
python3 - "$out" "${cases[@]}" <<'PY'
import json, sys
out = sys.argv[1]
print("| case | DOF | nnz(L) | policy | frame median ms | frame p99 ms | CG its median (max) | err @1 | err @10 | err @last (frame) |")
print("|---|---|---|---|---|---|---|---|---|---|")
def fmt(e):
    return "diverged" if e >= 1 else f"{e:.1e}"
for c in sys.argv[2:]:
    name = c.split()[0]
    try:
        j = json.load(open(f"{out}/{name}.result.json"))
    except Exception:
        print(f"| {name} | (failed) |"); continue
    print(f"| {name} | {j['dof']} | {j['exact']['nnz_L']:.3g} | exact | {j['exact']['frame_median_ms']:.1f} | {j['exact']['frame_p99_ms']:.1f} | - | 0 | 0 | 0 |")
    for p in j["policies"]:
        errs = [r for r in p["errors"] if "rel_l2_error" in r]
        e = {r["frame"]: r["rel_l2_error"] for r in errs}
        last = errs[-1]["frame"] if errs else 0
        its = f"{p['iterations']['median']:.0f} ({p['iterations']['max']:.0f})" if p["policy"] in ("lagged", "warped_cg") else "-"
        name_p = p["policy"] + (f" (k={p['refresh_every']}{', background' if p['background'] else ''})" if p["policy"] == "lagged" else "")
        failed = any("failed" in r for r in p["errors"])
        print(f"| | | | {name_p} | {p['frame_median_ms']:.1f} | {p['frame_p99_ms']:.1f} | {its} | {fmt(e.get(1, 1))} | {fmt(e.get(10, 1))} | "
              f"{'failed' if failed else fmt(e.get(last, 1))} ({last}) |")
    try:
        b = json.load(open(f"{out}/{name}.background.json"))
        print(f"| | | | lagged (k=1, background; bench, 30 frames) | {b['frame']['median_ms']:.1f} | {b['frame']['p99_ms']:.1f} | "
              f"{b['solver']['iterations']['median']:.0f} ({b['solver']['iterations']['max']:.0f}) | (see text) | | |")
    except Exception:
        pass
PY
