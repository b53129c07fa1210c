#!/usr/bin/env bash
# The embedding example against the installed package, as an application
# would build it: installs build/ into a temporary prefix (cmake --install),
# configures examples/embed with find_package(incise) from there (not the
# build tree), builds it and runs it on the bundled organ for 100 frames.
set -euo pipefail
cd "$(dirname "$0")/../.."
[ -x build/tools/incise ] || bash tools/scripts/build.sh build
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
cmake --install build --prefix "$tmp/prefix" >/dev/null
cmake -S examples/embed -B "$tmp/build" -G Ninja -DCMAKE_PREFIX_PATH="$tmp/prefix" >/dev/null
cmake --build "$tmp/build"
"$tmp/build/embed" assets/scenes/organ_drag.json
