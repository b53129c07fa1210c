#pragma once
// Curved faces as flat triangles: each 6-node (tet10) face is sampled on a
// regular grid of n segments per edge (n^2 triangles; engine/output/face_grid.h,
// shared with collision/), each 3-node face is one triangle. Normals are the
// analytic normals of the quadratic face, averaged over the grid vertices
// that coincide on one surface (same DisplayMesh points, same kind, within a
// crease angle), so a curved surface shades smoothly while a cut face never
// shares a normal with the boundary.
#include <vector>

#include "engine/output/display_mesh.h"
#include "engine/output/face_grid.h"
#include "engine/output/surface_extract.h"

namespace incise {

struct Tessellation {
  int segments = 1;              // per face edge
  int verts_per_face = 3;        // (n + 1)(n + 2) / 2
  int tris_per_face = 1;         // n^2
  std::vector<double> grid;      // (verts_per_face, 3) barycentric weights (L0, L1, L2) of each grid vertex
  std::vector<unsigned> tris;    // (nface * tris_per_face, 3) vertex ids, outward (counter-clockwise)
  std::vector<int> group;        // (nvert) smoothing group of each vertex; normals are averaged per group
  int ngroup = 0;
  int nvert() const { return static_cast<int>(group.size()); }
};

// Crease: grid vertices on one point whose reference normals differ by more
// than this angle keep separate normals (the edges of a block stay sharp).
inline constexpr double kCreaseDeg = 45.0;

// segments is used for curved faces (>= 2); flat faces always use 1.
// Smoothing groups are decided on the reference positions, once per topology.
Tessellation build_tessellation(const Surface& surface, const DisplayMesh& mesh, int segments);

// Current positions and normals of every grid vertex: pos and nrm are
// (nvert, 3). work is scratch kept between frames (no allocation per frame).
void tessellate(const Surface& surface, const Tessellation& t, const DisplayMesh& mesh, std::vector<float>& pos,
                std::vector<float>& nrm, std::vector<double>& work);

}  // namespace incise
