#pragma once
// The regular grid that turns one curved (6-node) face into flat triangles:
// n segments per face edge, (n + 1)(n + 2) / 2 grid vertices and n^2
// triangles. Shared by the renderer's tessellation (render/tessellate.h) and
// the collision surface (collision/tissue_surface.h), so both see the same
// triangles.
#include <vector>

namespace incise {

struct FaceGrid {
  int segments = 1;           // n, per face edge
  int verts_per_face = 3;     // (n + 1)(n + 2) / 2
  int tris_per_face = 1;      // n^2
  std::vector<int> steps;     // (verts_per_face, 3) integer weights (n - i - j, i, j): exact, for sharing
  std::vector<double> weights;  // (verts_per_face, 3) barycentric (L0, L1, L2) = steps / n
  std::vector<int> tris;      // (tris_per_face, 3) grid vertex ids, counter-clockwise as the face's corners 0, 1, 2
};

// Grid vertex (i, j), i + j <= n, sits at xi = L1 = i / n, eta = L2 = j / n,
// numbered row by row (j outer); segments >= 1.
FaceGrid face_grid(int segments);

// Segments a face of this order gets for a requested subdivision: curved
// (tet10) faces at least 2, flat (tet4) faces always 1.
inline int face_segments(int order, int segments) { return order == 2 ? (segments < 2 ? 2 : segments) : 1; }

}  // namespace incise
