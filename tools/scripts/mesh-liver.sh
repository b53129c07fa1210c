#!/usr/bin/env bash
# Makes assets/meshes/liver.msh (the liver demo's mesh) from the segmented
# liver image in CGAL's data (Debian libcgal-demo:
# /usr/share/doc/libcgal-dev/data.tar.gz, data/images/liver.inr.gz; CGAL
# 5.5.1, CC0 1.0 like CGAL's other data without a copyright notice, per
# /usr/share/doc/libcgal-dev/copyright) with CGAL's Mesh_3
# (tools/mesh/liver_mesh.cpp: every voxel label > 0 is tissue, cells of
# CELL_MM, surface within DISTANCE_MM), then raised to tet10 by
# `incise mesh convert --order 2`. Defaults 20 and 2.5 mm: 2,070 tetrahedra,
# 3,887 tet10 nodes, 11,661 DOF (assets/meshes/liver.msh, the demo's);
# 14 mm gave assets/meshes/liver_19k.msh (3,676 tetrahedra, 18,957 DOF).
# A rerun may differ by an element or two (Mesh_3 is not bit-reproducible
# here). Installs libcgal-dev, libcgal-demo and
# libmpfr-dev when missing (not needed to run incise).
#
# usage: bash tools/scripts/mesh-liver.sh [CELL_MM] [DISTANCE_MM] [OUT.msh]
set -euo pipefail
cd "$(dirname "$0")/../.."
cell="${1:-20}"
distance="${2:-2.5}"
out="${3:-assets/meshes/liver.msh}"
missing=()
for p in libcgal-dev libcgal-demo libmpfr-dev libgmp-dev; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if [ ${#missing[@]} -gt 0 ]; then
  sudo_cmd=""
  [ "$(id -u)" -eq 0 ] || sudo_cmd="sudo"
  $sudo_cmd apt-get install -y -qq --no-install-recommends "${missing[@]}"
fi
[ -x build/tools/incise ] || bash tools/scripts/build.sh build
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
tar -xzf /usr/share/doc/libcgal-dev/data.tar.gz -C "$tmp" data/images/liver.inr.gz
gunzip "$tmp/data/images/liver.inr.gz"  # CGAL's ImageIO reads .gz only when built with zlib support
g++ -O2 -std=c++17 tools/mesh/liver_mesh.cpp -o "$tmp/liver_mesh" -lgmp -lmpfr
"$tmp/liver_mesh" "$tmp/data/images/liver.inr" "$tmp/liver.vtk" "$cell" "$distance"
./build/tools/incise mesh convert "$tmp/liver.vtk" "$out" --order 2
