#!/usr/bin/env bash
# Builds the libFuzzer targets of fuzz/ (clang-15, ASan + UBSan) into
# build-fuzz/ and runs each for SECONDS (default 30, or $FUZZ_SECONDS) from a
# corpus seeded with the repository's own scenes, meshes and replays.
#   bash tools/scripts/fuzz.sh [SECONDS]
# Per target: one summary line (executions, exec/s, cov, ft, corpus). Saved
# findings (fuzz/findings/TARGET-*) are rerun first. Exits with the first
# failure's libFuzzer exit code when a target crashed, hung, leaked or ran out
# of memory; the input is in build-fuzz/artifacts/ (fuzz/README.md: how to
# reproduce one).
set -euo pipefail
cd "$(dirname "$0")/../.."
root=$PWD
seconds=${1:-${FUZZ_SECONDS:-30}}
if ! [[ $seconds =~ ^[0-9]+$ ]] || [ "$seconds" -lt 1 ]; then
  echo "fuzz.sh: SECONDS must be a positive integer, got '$seconds'" >&2
  exit 2
fi
out=$root/build-fuzz

for tool in clang-15 clang++-15 cmake ninja; do
  command -v "$tool" >/dev/null || { echo "fuzz.sh: $tool not found (bash tools/scripts/install-deps.sh)" >&2; exit 2; }
done

# --- build -------------------------------------------------------------------
start=$SECONDS
mkdir -p "$out"
# Configured every time (a second): fuzz_replay appears once replay_file.cpp exists.
CC=clang-15 CXX=clang++-15 cmake -S fuzz -B "$out" -G Ninja -DCMAKE_BUILD_TYPE=RelWithDebInfo >"$out/configure.log" 2>&1 ||
  { cat "$out/configure.log" >&2; echo "fuzz.sh: configure failed" >&2; exit 2; }
ninja -C "$out" -j "$(nproc)" >"$out/build.log" 2>&1 || { cat "$out/build.log" >&2; echo "fuzz.sh: build failed" >&2; exit 2; }
echo "fuzz.sh: built in $((SECONDS - start)) s ($out)"

targets=(fuzz_scene fuzz_mesh fuzz_cut_surface fuzz_csv)
if [ -x "$out/fuzz_replay" ]; then
  targets+=(fuzz_replay)
else
  echo "fuzz.sh: fuzz_replay not built (engine/runtime/replay_file.cpp missing), skipped"
fi

# --- seeds (copied fresh each run; new inputs the fuzzer finds stay) --------
mkdir -p "$out/artifacts" "$out/logs"
# seed NAME TARGET [PREFIX-BYTE-AS-PRINTF-ESCAPE] < file: a corpus entry
seed() {
  local dir=$out/corpus/$2
  mkdir -p "$dir"
  { [ -n "${3:-}" ] && printf "$3"; cat; } >"$dir/seed-$1"
}
for f in assets/scenes/*.json; do seed "$(basename "$f")" fuzz_scene <"$f"; done
# Meshes: small files only (< 200 KB), the format byte first (fuzz/fuzz_mesh.cpp).
for f in assets/meshes/*.msh assets/meshes/*.vtk assets/meshes/*.vtu assets/meshes/*.inp; do
  [ "$(stat -c %s "$f")" -lt 204800 ] || continue
  case $f in
    *.msh) b=g ;; *.vtk) b=k ;; *.vtu) b=u ;; *.inp) b=a ;;
  esac
  seed "$(basename "$f")" fuzz_mesh "$b" <"$f"
done
for f in assets/meshes/*.node; do
  ele=${f%.node}.ele
  [ -f "$ele" ] || continue
  { cat "$f"; echo "#--ele--"; cat "$ele"; } | seed "$(basename "${f%.node}").tetgen" fuzz_mesh t
done
# Cut surfaces (selector byte o/s, fuzz/fuzz_cut_surface.cpp): the repository's
# .obj/.stl under 200 KB, and two small written here (the repository may hold none).
for f in $(find assets tests -name '*.obj' -o -name '*.stl' 2>/dev/null); do
  [ "$(stat -c %s "$f")" -lt 204800 ] || continue
  case $f in *.obj) b=o ;; *) b=s ;; esac
  seed "$(basename "$f")" fuzz_cut_surface "$b" <"$f"
done
printf 'v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nv 0.5 0.5 1\nf 1 2 3 4\nf -1 1/1 2//2\nf 2 3 5\n' | seed square.obj fuzz_cut_surface o
printf 'solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid s\n' |
  seed tri.stl fuzz_cut_surface s
# CSVs (selector byte p/t, fuzz/fuzz_csv.cpp): trajectories and probe tables.
for f in $(find assets tests -name '*.csv' 2>/dev/null); do
  [ "$(stat -c %s "$f")" -lt 204800 ] || continue
  if head -c 200 "$f" | grep -q 'qw'; then b=t; else b=p; fi
  seed "$(basename "$f")" fuzz_csv "$b" <"$f"
done
printf 'x,y,z\n0,0,0\n1.5, -2e-3, 7\n# comment\n' | seed probe.csv fuzz_csv p
if [[ " ${targets[*]} " == *" fuzz_replay "* ]]; then
  replays=$out/seeds/replay
  rm -rf "$replays"
  mkdir -p "$replays"
  "$out/replay_seeds" "$replays"
  if [ -d fuzz/seeds ]; then
    find fuzz/seeds -name '*.replay' -exec cp {} "$replays/" \;
  fi
  if [ -x build/tools/incise ]; then  # a real recording, when the engine is built
    timeout 120 build/tools/incise run assets/scenes/swing_beam.json --frames 3 --record-states 2 \
      --out "$out/seeds/incise-run" --record "$replays/swing_beam.replay" >"$out/logs/record-seed.log" 2>&1 ||
      echo "fuzz.sh: build/tools/incise could not record a replay seed ($out/logs/record-seed.log); going on without it"
  fi
  for f in "$replays"/*.replay; do
    [ -f "$f" ] || continue
    seed "$(basename "$f").fixsum" fuzz_replay '\001' <"$f"  # odd byte: the harness fixes checksums
    seed "$(basename "$f")" fuzz_replay '\000' <"$f"
  done
fi

# --- run -------------------------------------------------------------------------
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1${UBSAN_OPTIONS:+:$UBSAN_OPTIONS}
# report LOG: the error line of a failed run, the frame it happened in and
# the top frames in this repository (shortened; the log has the whole stack).
report() {
  grep -m1 -E '==ERROR|runtime error:|ERROR: libFuzzer|Assertion .* failed|terminate called|^fuzz_[a-z]+: ' "$1" | cut -c1-300 | sed 's/^/    /' || true
  grep -E '^ *#[0-9]+ 0x' "$1" |
    grep -vE 'fuzzer::|__sanitizer|__asan|__ubsan|libc\.so|libstdc\+\+|__pthread_kill|raise |abort |in main |in _start ' |
    awk -v root="$root/" 'NR == 1 || index($0, root) { print; if (++n == 6) exit }' |
    sed -E 's/^ *(#[0-9]+) 0x[0-9a-f]+ in (.*) ([^ ]+:[0-9]+(:[0-9]+)?)$/\1 \3  \2/; s/ \(BuildId[^)]*\)//; s/std::__cxx11::basic_string<char, std::char_traits<char>, std::allocator<char>>/std::string/g' |
    cut -c1-220 | sed 's/^/      /' || true
}
failed=()
first_rc=0
fail() {  # fail TARGET RC
  failed+=("$1")
  [ "$first_rc" -ne 0 ] || first_rc=$2
}

# Saved findings (fuzz/findings/TARGET-*) first: inputs that once failed, each
# fixed and kept so that it stays fixed.
for t in "${targets[@]}"; do
  for f in fuzz/findings/"$t"-*; do
    [ -f "$f" ] || continue
    log=$out/logs/finding-$(basename "$f").log
    rc=0
    "$out/$t" -runs=1 "$f" >"$log" 2>&1 || rc=$?
    if [ "$rc" -eq 0 ]; then
      echo "$t: $f (a fixed finding, kept as a regression input): passes"
    else
      echo "$t: saved finding $f: STILL FAILS (exit $rc, $log)"
      report "$log"
      fail "$t" "$rc"
    fi
  done
done

for t in "${targets[@]}"; do
  case $t in
    fuzz_mesh) max_len=262144 ;;
    *) max_len=65536 ;;
  esac
  log=$out/logs/$t.log
  args=(-max_total_time="$seconds" -max_len="$max_len" -rss_limit_mb=2048 -timeout=10 -print_final_stats=1
        -artifact_prefix="$out/artifacts/$t-")
  [ -f "fuzz/dict/$t.dict" ] && args+=(-dict="fuzz/dict/$t.dict")
  rc=0
  "$out/$t" "${args[@]}" "$out/corpus/$t" >"$log" 2>&1 || rc=$?
  stat_of() { sed -n "s/^stat::$1: *\([0-9]*\).*/\1/p" "$log" | tail -1; }
  last=$(grep -E '^#[0-9]+.*cov: ' "$log" | tail -1 || true)
  cov=$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<<"$last")
  ft=$(sed -n 's/.* ft: \([0-9]*\).*/\1/p' <<<"$last")
  printf '%-16s %s: %s executions, %s exec/s, cov: %s, ft: %s, corpus: %s files (%s)\n' "$t" \
    "$([ "$rc" -eq 0 ] && echo ok || echo "FAILED (exit $rc)")" "$(stat_of number_of_executed_units)" \
    "$(stat_of average_exec_per_sec)" "${cov:-?}" "${ft:-?}" "$(find "$out/corpus/$t" -type f | wc -l)" "$log"
  if [ "$rc" -ne 0 ]; then
    fail "$t" "$rc"
    report "$log"
    art=$(sed -n 's/.*Test unit written to \(.*\)$/\1/p' "$log" | tail -1)
    echo "    input saved to: ${art:-(none written; see $log)}"
    if [ -n "$art" ]; then echo "    reproduce: $out/$t $art"; fi
  fi
done

if [ ${#failed[@]} -gt 0 ]; then
  echo "fuzz.sh: FAILED: $(printf '%s\n' "${failed[@]}" | sort -u | tr '\n' ' ')- inputs in $out/artifacts/ and fuzz/findings/, logs in $out/logs/" >&2
  exit "$first_rc"  # the first failure's libFuzzer exit code
fi
echo "fuzz.sh: all ${#targets[@]} targets ran ${seconds} s without a failure"
