#!/usr/bin/env bash
# Issue 18: the 1 kHz haptic loop beside the 20k-DOF organ being probed and
# cut (assets/scenes/organ_haptics.json: a scripted hand probing in six 10 s
# cycles, a scalpel incising at 20-24 s), frames paced at 30 Hz.
# Alternating pairs: with the haptic thread (`run --haptics`) and without it
# (the probe follows the same trajectory from the tool-poses stage), so the
# frame p99 of the two can be compared; then, with NORT=1, one run without
# real-time rights (CAP_SYS_NICE dropped by setpriv).
# Prints the tick period median / p99 / max, the share of ticks > 0.5 ms
# late, the tick compute p99, allocations per tick, and the frame p99.
# Usage: tools/scripts/bench-haptics.sh [BUILD_DIR] ; FRAMES (default 1800 =
# 60 s), PAIRS (default 2), NORT (default 0), SCENE.
set -euo pipefail
build=${1:-build}
frames=${FRAMES:-1800}
pairs=${PAIRS:-2}
scene=${SCENE:-assets/scenes/organ_haptics.json}
incise="$build/tools/incise"
out="$build/bench-haptics"
mkdir -p "$out"
row() {  # name dir
  python3 - "$1" "$2" <<'PY'
import json, os, sys
name, d = sys.argv[1], sys.argv[2]
t = json.load(open(os.path.join(d, "timing.json")))
f = t["frame"]
line = f"{name:<22} frame median {f['median_ms']:6.1f} p99 {f['p99_ms']:6.1f} max {f['max_ms']:6.1f} ms"
h = os.path.join(d, "haptics.json")
if os.path.exists(h):
    j = json.load(open(h))
    p, c = j["period_ms"], j["compute_us"]
    late = 100.0 * j["late_over_0_5_ms"] / max(j["ticks"], 1)
    line += (f" | ticks {j['ticks']} period {p['median']:.3f} / {p['p99']:.3f} / {p['max']:.2f} ms,"
             f" late>0.5ms {late:.3f}%, compute p99 {c['p99']:.1f} us, alloc/tick {j['allocations'] / max(j['ticks'], 1):.2g},"
             f" force max {j['force_max_n']:.2f} N | {j['scheduling'].split(',')[0]}")
print(line)
PY
}
echo "$scene, $frames frames paced at 30 Hz (2 shared cores: noisy)"
for p in $(seq 1 "$pairs"); do
  "$incise" run "$scene" --frames "$frames" --haptics --out "$out/with$p" > "$out/with$p.txt" 2>&1
  row "pair $p, haptic thread" "$out/with$p"
  "$incise" run "$scene" --frames "$frames" --pace 30 --out "$out/without$p" > "$out/without$p.txt" 2>&1
  row "pair $p, none" "$out/without$p"
done
if [ "${NORT:-0}" = 1 ]; then
  setpriv --bounding-set -sys_nice --inh-caps -sys_nice \
    "$incise" run "$scene" --frames "$frames" --haptics --out "$out/nort" > "$out/nort.txt" 2>&1
  row "no real-time rights" "$out/nort"
fi
