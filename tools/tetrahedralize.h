#pragma once
// A closed triangle surface (.stl, .ply, .off; .obj converted to .off) filled
// with tetrahedra by TetGen (Debian `tetgen`, run as a program: `tetgen -pq`
// with a volume bound from the target edge length), for `incise mesh
// tetrahedralize`.
#include <string>

#include "engine/mesh/mesh.h"

namespace incise {

// Tetrahedra of edge length about `size` (a volume bound of a regular
// tetrahedron of that edge) with radius-edge ratio at most `quality`, tet4.
// The regions that only inner closed shells bound (cavities) are left empty
// unless `fill_cavities`; `note` (if given) then says what was left out.
// Throws incise::Error naming the surface when TetGen is missing, fails, or
// makes no tetrahedra (an open or self-intersecting surface), with the end
// of its log, and before TetGen refines when `size` would make more than
// kMaxBeamTets tetrahedra (estimated from the volume the surface encloses).
Mesh tetrahedralize(const std::string& surface, double size, double quality = 1.4, bool fill_cavities = false,
                    std::string* note = nullptr);

}  // namespace incise
