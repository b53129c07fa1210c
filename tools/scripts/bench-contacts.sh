#!/usr/bin/env bash
# Issue 17: what the instruments cost per frame on the 20k-DOF organ
# (assets/scenes/organ_instruments.json on assets/meshes/organ_20k.msh: a
# probe pressing, a scalpel incising, realtime preset). Prints the collision stage (tree refit + queries + rows)
# and the contact stage (compliance W = H A^-1 H^T from the policy's factor,
# projected Gauss-Seidel, correction) median and p99, and how they grow with
# the number of contact rows: the probe alone, radius R (default 0.012 m),
# to the trajectory's depth, with contact.max_rows = 1, 10, 20, 50.
# Usage: tools/scripts/bench-contacts.sh [BUILD_DIR] ; FRAMES (default 60).
set -euo pipefail
build=${1:-build}
frames=${FRAMES:-60}
radius=${R:-0.012}
incise="$build/tools/incise"
scene=assets/scenes/organ_instruments.json
out="$build/bench-contacts"
mkdir -p "$out"
row() {  # name json
  python3 - "$1" "$2" <<'PY'
import json, sys
j = json.load(open(sys.argv[2]))
s, i = j["stages"], j["instruments"]
print(f"{sys.argv[1]:<28} collision {s['collision']['median_ms']:7.2f} / {s['collision']['p99_ms']:7.2f} ms"
      f"   contact {s['contact']['median_ms']:7.2f} / {s['contact']['p99_ms']:7.2f} ms"
      f"   rows mean {i['contacts_mean']:5.1f} max {i['contacts_max']:3d}"
      f"   frame {j['frame']['median_ms']:7.1f} / {j['frame']['p99_ms']:7.1f} ms")
PY
}
echo "median / p99 over $frames frames (2 shared cores: noisy)"
mesh=(--set mesh.file=../meshes/organ_20k.msh)
"$incise" bench "$scene" --frames "$frames" "${mesh[@]}" --json "$out/both.json" > "$out/both.txt"
row "probe + scalpel (default)" "$out/both.json"
# The probe alone, larger, so that it touches 50 faces; the scalpel's pose is
# moved far away (it then sweeps nothing).
for rows in 1 10 20 50; do
  "$incise" bench "$scene" --frames "$frames" "${mesh[@]}" --set instruments.0.radius="$radius" \
    --set contact.max_rows="$rows" --set instruments.1.trajectory=../trajectories/far_away.csv \
    --json "$out/rows$rows.json" > "$out/rows$rows.txt"
  row "probe r=$radius, max_rows $rows" "$out/rows$rows.json"
done
