#pragma once
// Sub-element decomposition of a tetrahedron cut by planes ([preprint] sec.
// 5.2: sub-elements per side, each integrated, eq. (52)). The cut planes are
// given by level-set values at the four corners, interpolated linearly in the
// element's local coordinates, so the decomposition is done in the reference
// tetrahedron and holds for curved tet10 elements too. The parts are kept as
// convex cells (polygon faces) while the planes are applied one after the
// other, and only then tetrahedralized, each by coning its faces to its
// vertex centroid. k planes make at most sum_{i<=3} C(k, i) = O(k^3) cells
// (the cells of an arrangement of k planes; k + 1 slabs for near-parallel
// cuts) and O(k^3) sub-tetrahedra in all, whereas splitting sub-tetrahedra
// cut by cut grew as about 4^k (issue 24: 6 cuts took 3.4 s and 385 MB).
// A cut whose corner values differ from an earlier cut's (or their negatives)
// by at most 1e-9 of the largest |phi| is that cut inside this element: it
// takes the earlier cut's sides and splits nothing (no slab of roundoff
// thickness).
#include <vector>

namespace incise {

// Face tags of a sub-tetrahedron face: 0..3 = lies in that face of the parent
// element, kSubFaceCut = lies on a cut surface, kSubFaceInside = interior.
inline constexpr signed char kSubFaceCut = 4, kSubFaceInside = 5;

struct SubTets {
  std::vector<double> rst;          // (nsub, 4, 3) vertices in local coordinates (r, s, t)
  std::vector<signed char> face;    // (nsub, 4) tag of the face opposite vertex k
  std::vector<signed char> side;    // (nsub, ncut) side (+1 / -1) of each cut
  std::vector<double> volume;       // (nsub) reference volume (the parent has 1/6)
  int ncut = 0;
  int size() const { return static_cast<int>(volume.size()); }
};

// phi: (ncut, 4) level-set values at the corners, with exact signs already
// applied (a corner exactly on a surface has phi == 0). Every cut must have
// corners strictly on both sides (the element is cut by it).
// only (optional, (ncut, 2)): cut c splits only the sub-tets on side
// only[2c+1] of the earlier cut only[2c] (-1: everywhere); the others get
// side 0 for c. A cut ending on another cut inside the element (a T) splits
// just its own side.
SubTets subdivide_tet(const std::vector<double>& phi, int ncut, const std::vector<int>& only = {});

}  // namespace incise
