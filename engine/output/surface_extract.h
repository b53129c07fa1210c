#pragma once
// The faces a viewer (render/) draws and an instrument (collision/) touches:
// exactly the DisplayMesh cell faces flagged kFaceBoundary or kFaceCut (never
// unflagged inner faces), boundary faces first, then cut faces, so each group
// is one contiguous draw.
#include <cstdint>
#include <vector>

#include "engine/output/display_mesh.h"

namespace incise {

struct Surface {
  int order = 1;                     // 1: flat 3-node faces, 2: curved 6-node faces
  int nboundary = 0, ncut = 0;       // faces [0, nboundary) on the outer surface, then cut faces
  std::vector<int> face_nodes;       // (nface, npf) DisplayMesh point ids: corners 0,1,2 then (tet10)
                                     // mid-edge nodes of face edges 0-1, 1-2, 2-0; outward orientation
  std::vector<int> face_cell;        // (nface) cell the face belongs to
  std::vector<int> face_local;       // (nface) which face of the cell: k, opposite corner k (kTetFace)
  int npf() const { return order == 2 ? 6 : 3; }
  int nface() const { return nboundary + ncut; }
};

// A face flagged both boundary and cut (a cut along the outer surface) counts as cut.
Surface extract_surface(const DisplayMesh& mesh);

// Identifies the cell structure (order, point count, cells, face flags): equal
// signatures mean the same Surface, so only positions need re-uploading.
std::uint64_t topology_signature(const DisplayMesh& mesh);

}  // namespace incise
