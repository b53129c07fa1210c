#!/usr/bin/env bash
# Issue 4 "real-time" configuration against `exact`: the organ-like meshes
# (assets/meshes/organ_*.msh, organ_drag boundary conditions) at 3k, 10k, 20k
# and 30k DOF, the swinging beam at 10k and 20k, and the progressive incision
# of assets/scenes/organ_incision.json (10k DOF); and issue 20's fast-motion
# cases at 20k DOF: hang-20k (a soft organ, E = 10 kPa, nu = 0.45, rho =
# 1060, Rayleigh 0.5 / 0.01, hung by its top 2 cm and released from rest
# under gravity), drag-20k (the same organ taken at its lower face by a
# grasper, dragged 5 cm at 0.2 m/s and let go:
# assets/trajectories/organ_grasp_drag.csv; drag15mm-20k: 1.5 cm, a
# surgeon's amplitude, organ_grasp_drag_15mm.csv) and haptics-20k
# (assets/scenes/organ_haptics.json: the probe on the scripted haptic device
# while the scalpel incises; its bench runs the 1 kHz haptic thread), and the
# second organ, from a real segmentation (assets/meshes/liver_19k.msh, 18,957
# DOF): hang-liver19k (held at its posterior face, released from rest) and
# demo-liver19k (assets/scenes/liver_demo.json on it: scalpel, grasper,
# haptic probe); and a hard case, probe-incision-10k (organ_instruments.json
# with the probe pressing 1.5 cm beside the incision:
# assets/trajectories/organ_probe_beside_incision.csv; it diverged under
# every policy before the twenty-second session), and the same on organ_20k,
# probe-incision-20k (issue 20's case (c) on the first organ: haptics-20k's
# scalpel only cuts after 20 s). Each case runs
#   incise compare  (exact reference, then the policy; error after 1, 30, FRAMES frames)
#   incise bench    (frame, cut-frame and stage timings of the policy alone)
# The policy: solver.preset "realtime" (docs/scene-format.md, "Presets"),
# passed as --set solver.preset=realtime with the per-case K as
# --set solver.refresh_every=K; an environment variable below adds a --set
# only when it is given. The preset: lagged CG, background factorization taken
# K frames after it starts (K grows with the factor time), warp, CG tolerance
# TOL (1e-2; 1e-3 before the increment predictor), CG's products with A
# from a float copy of it (REALTIME_MATRIX=double for A itself), factored
# in single precision (REALTIME_FACTOR_PRECISION=double for CHOLMOD's double
# factor) and rounded to a binary16 factor copy that the substitutions read
# (REALTIME_COPY=float for the float factor itself, docs/numerics.md), substitutions on two
# threads (REALTIME_SUBSTITUTION_THREADS=1 for one), element tangents kept
# while F moves less than 1e-2 (REALTIME_TANGENT_REUSE=0 turns it off; compare's
# exact reference always assembles every element), two assembly workers, the
# second on the helpers' CPUs and stood down while the idle-priority
# background factorization is late or a cut-ahead runs (REALTIME_THREADS=1
# for one), and the
# consistent corotated tangent (integrator.tangent; REALTIME_TANGENT=frozen_rotation
# for the default), a rescue refactorization after 20 stalled CG iterations
# (REALTIME_RESCUE) and late background factors skipped instead of waited for
# (REALTIME_LATE=wait for deterministic runs), and the stepping thread on a CPU
# of its own with the helpers on the others (REALTIME_AFFINITY=none leaves it
# to the kernel); the contact correction as the preconditioner gives it
# (REALTIME_REFINE=2 refines it by projected CG: contact.refine_rounds). incise bench times FRAMES frames
# too (BENCH_FRAMES to change), started at PACE Hz as the real-time loop does
# (default 30; PACE=0 runs them back to back), and writes its per-frame trace
# to BUILD/realtime/NAME.trace.csv. incise compare runs back to back.
# Usage: bench-realtime.sh [BUILD_DIR] [FRAMES] [TOL]   (BENCH_ONLY="organ-10k ..." to pick cases)
set -euo pipefail
cd "$(dirname "$0")/../.."
build="${1:-build}"
frames="${2:-300}"
tol="${3:-}"                               # solver.tolerance (the preset: 1e-2)
incise="$build/tools/incise"
out="$build/realtime"
mkdir -p "$out"
# Empty: the preset's value. Each one given becomes a --set below.
extra="${REALTIME_OPTIONS:-}"  # e.g. "--set solver.factor_copy=none --set solver.factor_precision=double"
bench_frames="${BENCH_FRAMES:-$frames}"   # frames timed by incise bench (after 5 warm-up frames)
pace="${PACE:-30}"                          # incise bench --pace (0: frames back to back)
tangent="${REALTIME_TANGENT:-}"             # integrator.tangent (the preset: consistent; frozen_rotation: the default)
rescue="${REALTIME_RESCUE:-}"               # solver.rescue_after (the preset: 20; 0: off)
late="${REALTIME_LATE:-}"                   # solver.late_factor (the preset: skip, no stalls; wait: deterministic)
copy="${REALTIME_COPY:-}"                   # solver.factor_copy (the preset: half; float or none)
reuse="${REALTIME_TANGENT_REUSE:-}"         # integrator.tangent_reuse of the policy runs (the preset: 0.01; 0: off; the exact reference never)
subthreads="${REALTIME_SUBSTITUTION_THREADS:-}"  # solver.substitution_threads (the preset: 2)
precision="${REALTIME_FACTOR_PRECISION:-}"  # solver.factor_precision (the preset: single; needs a copy, float or half)
affinity="${REALTIME_AFFINITY:-}"           # solver.affinity (the preset: split; none leaves it to the kernel)
coarse="${REALTIME_COARSE:-}"               # solver.coarse (the preset: none; corners: the two-level preconditioner)
frame_its="${REALTIME_FRAME_ITERATIONS:-}"  # solver.frame_iterations (the preset: 0, no cap; N: CG iterations per frame)
refine="${REALTIME_REFINE:-}"              # contact.refine_rounds (default 0; 2: the contact correction by projected CG, docs/numerics.md)
matrix="${REALTIME_MATRIX:-}"              # solver.matrix_precision (the preset: single; double)
threads="${REALTIME_THREADS:-}"             # solver.threads, the assembly workers (the preset: 2)
set_opts=""
add() { if [ -n "$2" ]; then set_opts="$set_opts --set $1=$2"; fi; }
add solver.tolerance "$tol"
add integrator.tangent "$tangent"
add solver.rescue_after "$rescue"
add solver.late_factor "$late"
add solver.factor_copy "$copy"
add integrator.tangent_reuse "$reuse"
add solver.substitution_threads "$subthreads"
add solver.factor_precision "$precision"
add solver.affinity "$affinity"
add solver.coarse "$coarse"
add solver.frame_iterations "$frame_its"
add contact.refine_rounds "$refine"
add solver.matrix_precision "$matrix"
add solver.threads "$threads"
# name mesh-or-scene K
# K: a background job (53 ms at 10k, 185 ms at 20k, 385 ms at 30k once
# CHOLMOD's OpenMP teams were made serial; single precision, eighth session:
# 32 ms at 10k, 75 ms at 20k, BM_Factorization) is taken about K frames after
# it starts; measured paced at 30 Hz, fifth session (docs/benchmarks.md).
cases=(
  "organ-3k organ_3k 1"
  "organ-10k organ_10k 2"
  "organ-20k organ_20k 3"
  "organ-30k organ_30k 4"
  "beam-10k beam_20x4x4 2"
  "beam-20k beam_28x5x5 3"
  "incision-10k organ_incision 2"
  "hang-20k organ_20k 3"
  "drag-20k organ_20k 3"
  "drag15mm-20k organ_20k 3"
  "haptics-20k organ_haptics 3"
  "hang-liver19k liver_19k 3"
  "demo-liver19k liver_demo 3"
  "probe-incision-10k organ_instruments 2"
  "probe-incision-20k organ_instruments 3"
)
only="${BENCH_ONLY:-}"
for c in "${cases[@]}"; do
  read -r name mesh k <<<"$c"
  if [ -n "$only" ] && [[ " $only " != *" $name "* ]]; then continue; fi
  scene="$out/$name.json"
  bench_extra=""
  case "$name" in
    hang-liver*)
      # The second organ of issue 20, from a real segmentation (CGAL's liver,
      # assets/meshes/SOURCES.md): the demo's material, held at its
      # posterior face, released from rest under gravity.
      cat >"$scene" <<JSON
{"mesh": {"file": "$(realpath --relative-to="$out" "assets/meshes/$mesh.msh")", "order": 2},
 "material": {"model": "corotated", "young": 2e4, "poisson": 0.45, "density": 1060,
              "rayleigh": {"mass": 1.0, "stiffness": 0.005}},
 "mass": "lumped", "gravity": [0, 0, -9.81],
 "fixed": [{"box": [[-0.2, 0.035, -0.2], [0.2, 0.2, 0.2]]}]}
JSON
      ;;
    hang-*|drag*-*)
      grasper=""
      if [ "${name%%-*}" != hang ]; then
        traj=assets/trajectories/organ_grasp_drag.csv
        [ "${name%%-*}" = drag15mm ] && traj=assets/trajectories/organ_grasp_drag_15mm.csv
        grasper=', "instruments": [{"type": "grasper", "name": "grasper", "jaw_size": [0.01, 0.002, 0.01], "opening": 0.012,
                  "trajectory": "'"$(realpath --relative-to="$out" "$traj")"'"}]'
      fi
      cat >"$scene" <<JSON
{"mesh": {"file": "$(realpath --relative-to="$out" "assets/meshes/$mesh.msh")", "order": 2},
 "material": {"model": "corotated", "young": 1e4, "poisson": 0.45, "density": 1060,
              "rayleigh": {"mass": 0.5, "stiffness": 0.01}},
 "mass": "lumped", "gravity": [0, 0, -9.81],
 "fixed": [{"box": [[-1, -1, 0.03], [1, 1, 1]]}]$grasper}
JSON
      ;;
    organ-*)
      cat >"$scene" <<JSON
{"mesh": {"file": "$(realpath --relative-to="$out" "assets/meshes/$mesh.msh")", "order": 2},
 "material": {"model": "corotated", "young": 3e4, "poisson": 0.45, "density": 1000,
              "rayleigh": {"mass": 1.0, "stiffness": 0.002}},
 "mass": "lumped", "gravity": [0, 0, -9.81],
 "fixed": [{"box": [[-1, -1, -1], [1, 1, 0]]}],
 "prescribed": [{"box": [[-0.025, -0.01, 0.041], [-0.005, 0.01, 0.06]],
                 "displacement": {"x": 0.015, "y": 0, "z": -0.01}, "ramp": 1.0}]}
JSON
      ;;
    beam-*)
      read -r nx ny nz <<<"$(echo "${mesh#beam_}" | tr x ' ')"
      [ -f "$out/$mesh.vtu" ] || "$incise" mesh beam --size 0.2 0.05 0.05 --cells "$nx" "$ny" "$nz" --out "$out/$mesh.vtu" >/dev/null
      cat >"$scene" <<JSON
{"mesh": {"file": "$mesh.vtu", "order": 2},
 "material": {"model": "corotated", "young": 1e5, "poisson": 0.45, "density": 1000,
              "rayleigh": {"mass": 1.0, "stiffness": 0.002}},
 "mass": "lumped", "gravity": [0, 0, -9.81],
 "fixed": [{"box": [[-1, -1, -1], [0, 1, 1]]}],
 "prescribed": [{"plane": {"point": [0.2, 0, 0], "normal": [-1, 0, 0]},
                 "displacement": {"x": -0.12, "y": 0.1, "z": 0.08}, "ramp": 1.0}]}
JSON
      ;;
    incision-*|haptics-*|demo-*|probe-*)
      # A bundled scene with its instruments; demo-liver19k is the liver demo
      # (scalpel, grasper, haptic probe) on the 19k mesh instead of its own;
      # probe-incision-10k takes the probe's hard-case trajectory.
      [ "${name%%-*}" = haptics ] || [ "${name%%-*}" = demo ] && bench_extra="--haptics"
      mesh_file=""
      [ "$name" = demo-liver19k ] && mesh_file="../meshes/liver_19k.msh"
      [ "$name" = probe-incision-20k ] && mesh_file="../meshes/organ_20k.msh"
      probe_traj=""
      [ "${name%-*}" = probe-incision ] && probe_traj="../trajectories/organ_probe_beside_incision.csv"
      python3 - "assets/scenes/$mesh.json" "$scene" "$mesh_file" "$probe_traj" <<'PY'
import json, os, sys
src, dst, mesh, probe = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4]
d = json.load(open(src))
d.pop("integrator", None)  # the preset's (a --set when REALTIME_TANGENT is given)
if os.path.basename(src) == "organ_haptics.json":
    d["initial"] = "rest"  # haptics-20k as measured since the twentieth session: the sag from rest too
rel = lambda f: os.path.relpath(os.path.join(os.path.dirname(src), f), os.path.dirname(dst))
d["mesh"]["file"] = rel(mesh or d["mesh"]["file"])
for ins in d.get("instruments", []):
    if probe and ins.get("type") == "probe":
        ins["trajectory"] = probe
    if "trajectory" in ins:
        ins["trajectory"] = rel(ins["trajectory"])
for k in ("output", "render", "run", "solver"):
    d.pop(k, None)
json.dump(d, open(dst, "w"), indent=1)
PY
      ;;
  esac
  opts="--set solver.preset=realtime --set solver.refresh_every=$k$set_opts $extra"
  echo "compare $name ($frames frames; $opts) ..." >&2
  # shellcheck disable=SC2086
  "$incise" compare "$scene" $opts --frames "1,30,$frames" --json "$out/$name.compare.json" >"$out/$name.compare.log" 2>&1 ||
    echo "  failed: see $out/$name.compare.log" >&2
  # shellcheck disable=SC2086
  "$incise" bench "$scene" $opts --frames "$bench_frames" --warmup 5 --pace "$pace" $bench_extra --json "$out/$name.bench.json" \
    --trace "$out/$name.trace.csv" >"$out/$name.bench.log" 2>&1 ||
    echo "  failed: see $out/$name.bench.log" >&2
done
python3 - "$out" "${tol:-1e-2}" "${tangent:-consistent}" "${copy:-half} copy, ${precision:-single}-precision factor" "${subthreads:-2}" "${reuse:-0.01}" "${cases[@]}" <<'PY'
import json, sys
out, tol, tangent, copy, subthreads, reuse = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4], sys.argv[5], sys.argv[6]
print(f"| case | DOF | nnz(L) | exact median ms | policy (CG tol {tol}) | median ms | p99 ms | max ms | cut frames: count, median / p99 / max ms | CG its median (max) | Newton/frame | err @1 | err @30 | err @last |")
print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
for c in sys.argv[7:]:
    name, _, k = c.split()
    try:
        j = json.load(open(f"{out}/{name}.compare.json")); b = json.load(open(f"{out}/{name}.bench.json"))
    except Exception:
        continue
    p = j["policies"][0]
    e = {r["frame"]: r.get("rel_l2_error", float("nan")) for r in p["errors"]}
    last = max(e) if e else 0
    cf = b["cut_frames"]
    cut = f"{cf['count']}, {cf['median_ms']:.1f} / {cf['p99_ms']:.1f} / {cf['max_ms']:.1f}" if cf["count"] else "-"
    it = b["solver"]["iterations"]
    paced = f", paced {b['pace_hz']:g} Hz" if b.get("pace_hz") else ""
    print(f"| {name} | {b['dof']} | {j['exact']['nnz_L']:.3g} | {j['exact']['frame_median_ms']:.1f} | lagged k={k}, background, warp, tangent {tangent}, {copy}, {subthreads}-thread subst., reuse {reuse}{paced} | "
          f"{b['frame']['median_ms']:.1f} | {b['frame']['p99_ms']:.1f} | {b['frame']['max_ms']:.1f} | {cut} | {it['median']:.0f} ({it['max']:.0f}) | "
          f"{b['newton']['mean']:.2f} | {e.get(1, float('nan')):.1e} | {e.get(30, float('nan')):.1e} | {e.get(last, float('nan')):.1e} ({last}) |")
PY
