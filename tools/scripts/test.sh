#!/usr/bin/env bash
# Fresh Debian 12 -> the whole test suite: installs what is missing, builds
# (Release with assertions), runs ctest. --sanitize: the ASan+UBSan build instead.
set -euo pipefail
cd "$(dirname "$0")/../.."
bash tools/scripts/install-deps.sh
if [ "${1:-}" = "--sanitize" ]; then
  bash tools/scripts/build.sh build-asan -DINCISE_SANITIZE=ON
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  ctest --test-dir build-asan -j "$(nproc)" --output-on-failure --timeout 900
else
  bash tools/scripts/build.sh build
  ctest --test-dir build -j "$(nproc)" --output-on-failure --timeout 600
fi
