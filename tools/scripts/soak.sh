#!/usr/bin/env bash
# Issue 24: the soak. The organ incision (assets/meshes/organ_10k.msh, the
# material of assets/scenes/organ_haptics.json, solver.preset realtime) with
# a scalpel, a probe on the haptic thread and a grasper (SOAK_GRASPER=0
# leaves it out), for SOAK_FRAMES frames (default
# 10,000 = 333 s of scene time at dt = 1/30 s), while a sampler reads the
# process's resident memory, threads and open file descriptors.
#
#   - scalpel: one incision along -x at y = 0.015 (scene time 1-4 s), then
#     parked beside the organ for the rest of the run;
#   - grasper (unless SOAK_GRASPER=0): every 8 s of scene time from 2 s
#     until 60% of the run it takes the upper face at (-0.02, -0.015), lifts
#     it 5 mm and pulls it 4 mm sideways, holds, lets go and withdraws; then
#     it stays parked 5 cm above. (Before solver.condense_below a tiny piece
#     at the incision's exit end ran away with it; docs/benchmarks.md,
#     Issue 24: soak);
#   - probe: held by the haptic thread (haptics.device "scripted", 1 kHz)
#     whose clock is the wall clock, not the scene's: 3 mm presses and 1 cm
#     slides every 10 s of WALL time for SOAK_PROBE_WALL_S seconds (default
#     300), then lifted clear. Frames are paced at 30 Hz, never ahead of the
#     wall clock, so the probe stops no later than frame 30 * SOAK_PROBE_WALL_S;
#     how much earlier depends on how slowly the frames run (the plot script
#     finds the last frame with probe force from the logs).
# After the probe has lifted (and the grasper's last cycle) nothing acts on
# the organ but gravity: its energy must decay.
#
# The trajectories and the scene are generated into the output folder (no
# large files in the repository). The run writes a .vtu every SOAK_EVERY
# frames (default 50), from which tools/scripts/plot-soak.py computes
# kinetic, elastic and gravity energy (the run has no per-frame energy output).
#
# Usage: tools/scripts/soak.sh [INCISE]   (default build/tools/incise)
#   env: SOAK_FRAMES (10000), SOAK_OUT (out/soak), SOAK_EVERY (50), SOAK_GRASPER (1),
#        SOAK_PROBE_WALL_S (300), SOAK_SAMPLE_S (0.5), SOAK_PLOT (1: run
#        plot-soak.py after the run, its summary and PNGs into SOAK_OUT; needs
#        python3 with numpy, matplotlib, meshio: SOAK_PYTHON, default
#        /usr/bin/python3; the committed docs/img/soak_*.png are copies)
# Writes into SOAK_OUT: soak_scene.json, traj_*.csv, run.log, timing.json,
#   haptics_*.csv/json, soak_scene_*.vtu + .pvd, resources.csv
#   (t_s,epoch_s,rss_mb,hwm_mb,threads,fds), frame_times.csv (frame,epoch_s,file:
#   the .vtu files' modification times), exit_code.
set -euo pipefail
incise=${1:-build/tools/incise}
frames=${SOAK_FRAMES:-10000}
out=${SOAK_OUT:-out/soak}
every=${SOAK_EVERY:-50}
probe_wall=${SOAK_PROBE_WALL_S:-300}
sample_s=${SOAK_SAMPLE_S:-0.5}
py=${SOAK_PYTHON:-/usr/bin/python3}
repo=$(cd "$(dirname "$0")/../.." && pwd)

[ -x "$incise" ] || { echo "soak.sh: $incise is not an executable (give the incise binary as the first argument)" >&2; exit 2; }
mkdir -p "$out"
out=$(cd "$out" && pwd)
rm -f "$out"/*.vtu "$out"/*.pvd "$out"/resources.csv "$out"/frame_times.csv "$out"/exit_code

# Scene and trajectories.
python3 - "$repo" "$out" "$frames" "$probe_wall" "$every" "${SOAK_GRASPER:-1}" <<'PY'
import json, os, sys
repo, out, frames, probe_wall, every = sys.argv[1], sys.argv[2], int(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5])
grasper = sys.argv[6] == "1"
dt = 1.0 / 30.0
T = frames * dt
q_vert = "0.7071067811865476, 0, 0.7071067811865476, 0"   # tool x -> world -z
def write(name, header, rows, comment):
    with open(os.path.join(out, name), "w") as f:
        f.write("# " + comment + "\n" + header + "\n")
        for r in rows:
            f.write(", ".join(f"{v:.6g}" if isinstance(v, float) else str(v) for v in r) + "\n")
# Scalpel: as assets/trajectories/organ_scalpel.csv, 1-4 s, then parked at x = -0.075.
sc = [(0.0, 0.075), (1.0, 0.055), (1.5, 0.045), (3.5, -0.045), (4.0, -0.055), (4.5, -0.075), (max(T, 5.0), -0.075)]
write("traj_scalpel.csv", "t,x,y,z,qw,qx,qy,qz", [(t, x, 0.015, 0.025, q_vert) for t, x in sc],
      "soak scalpel: one incision along -x at y = 0.015, then parked")
# Grasper: cycles of 8 s from 2 s until 0.6 T; jaws across y, 1 cm along z around the origin.
g, t0, gx, gy, gz, up = [], 2.0, -0.02, -0.015, 0.045, 0.10
g.append((0.0, gx, gy, up, 0))
while t0 + 4.0 <= 0.6 * T:
    g += [(t0, gx, gy, up, 0), (t0 + 1.0, gx, gy, gz, 0), (t0 + 1.2, gx, gy, gz, 1),
          (t0 + 2.2, gx, gy - 0.004, gz + 0.005, 1), (t0 + 3.2, gx, gy - 0.004, gz + 0.005, 1),
          (t0 + 3.4, gx, gy - 0.004, gz + 0.005, 0), (t0 + 4.0, gx, gy, up, 0)]
    t0 += 8.0
g.append((max(T, g[-1][0] + 1.0), gx, gy, up, 0))
write("traj_grasper.csv", "t,x,y,z,qw,qx,qy,qz,jaw", [(t, x, y, z, "1, 0, 0, 0", j) for t, x, y, z, j in g],
      f"soak grasper: take the upper face, lift 5 mm, pull 4 mm, hold, let go; cycles of 8 s from 2 s to {t0:.1f} s")
# Probe (haptic device, wall clock): organ_haptic_probe.csv's cycle every 10 s until probe_wall, then lifted.
p, c = [(0.0, 0.02, -0.01, 0.05)], 0.0
cyc = [(1.0, 0.02, 0.0439), (2.5, 0.015, 0.0467), (4.0, 0.01, 0.0495), (5.0, 0.01, 0.0495), (6.0, 0.01, 0.058), (7.0, 0.02, 0.05)]
while c + 10.0 <= probe_wall:
    p += [(c + dt_, x, -0.01, z) for dt_, x, z in cyc]
    c += 10.0
p += [(c + 1.0, 0.02, -0.01, 0.07), (c + 2.0 + 10 * T, 0.02, -0.01, 0.07)]
write("traj_probe.csv", "t,x,y,z,qw,qx,qy,qz", [(t, x, y, z, "1, 0, 0, 0") for t, x, y, z in p],
      f"soak probe (haptic, wall clock): 3 mm press and 1 cm slide every 10 s until {c:.0f} s, then lifted clear")
scene = json.load(open(os.path.join(repo, "assets/scenes/organ_haptics.json")))
scene["mesh"]["file"] = os.path.join(repo, "assets/meshes/organ_10k.msh")
scene["instruments"] = [
    {"type": "probe", "name": "probe", "radius": 0.01, "trajectory": "traj_probe.csv"},
    {"type": "scalpel", "name": "scalpel", "blade": [0.03, 0.0005, 0.008], "trajectory": "traj_scalpel.csv"},
    {"type": "grasper", "name": "grasper", "jaw_size": [0.01, 0.002, 0.01], "opening": 0.012, "contact": False,
     "trajectory": "traj_grasper.csv"},
]
if not grasper:
    scene["instruments"].pop()
scene["solver"] = {"preset": "realtime"}
scene["run"] = {"frames": frames}
scene["output"] = {"dir": ".", "vtu": True, "every": every}
json.dump(scene, open(os.path.join(out, "soak_scene.json"), "w"), indent=1)
print(f"soak: {frames} frames ({T:.1f} s of scene time); " + (f"grasper cycles until {t0:.1f} s (frame {round(t0 / dt)}); " if grasper else "no grasper; ") +
      f"incision at 1-4 s (frames 30-120); probe strokes until {c:.0f} s of wall time; .vtu every {every} frames into {out}")
PY

# The run, and the sampler beside it.
"$incise" run "$out/soak_scene.json" --frames "$frames" --haptics --out "$out" > "$out/run.log" 2>&1 &
pid=$!
echo "soak: incise pid $pid, sampling every $sample_s s into $out/resources.csv"
echo "t_s,epoch_s,rss_mb,hwm_mb,threads,fds" > "$out/resources.csv"
start=$(date +%s.%N)
while kill -0 "$pid" 2>/dev/null; do
  now=$(date +%s.%N)
  if st=$(cat "/proc/$pid/status" 2>/dev/null) && fds=$(ls "/proc/$pid/fd" 2>/dev/null | wc -l); then
    awk -v t="$now" -v t0="$start" -v fds="$fds" '
      /^VmRSS:/ {rss = $2} /^VmHWM:/ {hwm = $2} /^Threads:/ {thr = $2}
      END {if (rss != "") printf "%.2f,%.3f,%.1f,%.1f,%d,%d\n", t - t0, t, rss / 1024, hwm / 1024, thr, fds}' \
      <<< "$st" >> "$out/resources.csv"
  fi
  sleep "$sample_s"
done
rc=0
wait "$pid" || rc=$?
echo "$rc" > "$out/exit_code"
echo "soak: incise exited with $rc after $(awk -v a="$start" -v b="$(date +%s.%N)" 'BEGIN {printf "%.0f", b - a}') s"
tail -n 30 "$out/run.log"

# Frame -> wall clock, from the .vtu files' modification times (frame from the .pvd's timestep).
python3 - "$out" <<'PY' > "$out/frame_times.csv"
import glob, os, re, sys
out = sys.argv[1]
print("frame,epoch_s,file")
for pvd in glob.glob(os.path.join(out, "*.pvd")):
    for t, f in re.findall(r'timestep="([^"]+)"[^>]*file="([^"]+)"', open(pvd).read()):
        print(f"{round(float(t) * 30)},{os.stat(os.path.join(out, f)).st_mtime:.3f},{f}")
PY

if [ "${SOAK_PLOT:-1}" = 1 ]; then
  "$py" "$repo/tools/scripts/plot-soak.py" "$out" --img "$out" | tee "$out/summary.txt"
fi
exit "$rc"
