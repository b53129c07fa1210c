#!/usr/bin/env bash
# Cost of repeated cuts through the same elements (issue 24): k near-parallel
# planes through a one-cell box (6 tetrahedra, every one crossed by every
# plane), tet4 and tet10, k = 5, 10, 20 (or the list in $CUTS). Per case: the
# DOFs after the cut, the cut frame's time (layout + model + solver set-up +
# transfer) as the median of REPEAT runs, and the process's peak RSS.
#   bash tools/scripts/bench-repeated-cuts.sh [BUILD_DIR] [REPEAT]
set -euo pipefail
cd "$(dirname "$0")/../.."
build="${1:-build}"
repeat="${2:-3}"
incise="$build/tools/incise"
[ -x "$incise" ] || { echo "bench-repeated-cuts.sh: $incise not built" >&2; exit 2; }
out="$build/bench/repeated-cuts"
mkdir -p "$out"
"$incise" mesh beam --size 1 1 1 --cells 1 1 1 --out "$out/box.vtu" >/dev/null
printf '%-6s %4s %6s %14s %12s\n' order cuts DOF "cut frame ms" "peak MB"
for order in 1 2; do
  for k in ${CUTS:-5 10 20}; do
    cuts=""
    for ((i = 0; i < k; i++)); do
      # x = 0.2 .. 0.8, tilted by -1e-3, 0, 1e-3: near-parallel, apart inside the box
      x=$(awk -v i="$i" -v k="$k" 'BEGIN { printf "%.6f", 0.2 + 0.6 * i / (k > 1 ? k - 1 : 1) }')
      a=$(awk -v i="$i" 'BEGIN { printf "%g", 1e-3 * ((i % 3) - 1) }')
      cuts+="${cuts:+, }{\"type\": \"plane\", \"point\": [$x, 0.5, 0.5], \"normal\": [1, $a, $(awk -v a="$a" 'BEGIN { print -a }')], \"at_time\": 0}"
    done
    scene="$out/cuts-$order-$k.json"
    cat >"$scene" <<JSON
{"mesh": {"file": "box.vtu", "order": $order},
 "material": {"model": "corotated", "young": 1e4, "poisson": 0.3, "density": 1000},
 "mass": "lumped", "gravity": [0, 0, -9.81], "fixed": [{"box": [[-1, -1, -1], [1e-9, 2, 2]]}],
 "cuts": [$cuts]}
JSON
    ms=()
    for ((r = 0; r < repeat; r++)); do
      "$incise" run "$scene" --frames 2 --out "$out/run-$order-$k" >"$out/run-$order-$k.log" 2>&1 ||
        { cat "$out/run-$order-$k.log" >&2; exit 1; }
      read -r dof t mb < <(python3 -c 'import json, sys; d = json.load(open(sys.argv[1]))
print(d["dof"], d["cut_frames"]["max_ms"], d["peak_rss_mb"])' "$out/run-$order-$k/timing.json")
      ms+=("$t")
    done
    med=$(printf '%s\n' "${ms[@]}" | sort -g | awk '{ a[NR] = $1 } END { print a[int((NR + 1) / 2)] }')
    printf '%-6s %4d %6d %14.1f %12.1f\n' "tet$([ "$order" = 1 ] && echo 4 || echo 10)" "$k" "$dof" "$med" "$mb"
  done
done
