#!/usr/bin/env bash
# Fresh Debian 12 -> the whole test suite: installs what is missing, builds
# (Release with assertions), runs ctest. --sanitize: the ASan+UBSan build instead.
set -euo pipefail
cd "$(dirname "$0")/../.."
bash tools/scripts/install-deps.sh
if [ "${1:-}" = "--sanitize" ]; then
  bash tools/scripts/build.sh build-asan -DINCISE_SANITIZE=ON
  # intercept_tls_get_addr=0: GCC 12's runtime can misread a dynamic TLS block
  # (Mesa's, after a render test) as a pre-2.25 glibc header, and LeakSanitizer's
  # tracer then segfaults at exit ("Tracer caught signal 11") after a passing
  # test. Seen once in CI on Golden.UncutBlock; not a leak, and not ours.
  export ASAN_OPTIONS=detect_leaks=1:abort_on_error=1:intercept_tls_get_addr=0 UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1
  export LSAN_OPTIONS=suppressions=$PWD/tools/scripts/lsan.supp:print_suppressions=0
  ctest --test-dir build-asan -j "$(nproc)" --output-on-failure --timeout 900
else
  bash tools/scripts/build.sh build
  ctest --test-dir build -j "$(nproc)" --output-on-failure --timeout 600
fi
