#pragma once
// A conforming reference for cut studies: the mesh with its nodes duplicated
// along mesh faces lying on a planar slit x = xc, z >= z_tip (all y). Elements
// on the x > xc side take the duplicates; nodes on the slit front (z == z_tip)
// are shared, so the slit closes there. No X-FEM involved: an independent
// check of the cut model (tests/cutting, tools/study_slit).
#include "engine/mesh/mesh.h"

namespace incise {

// mesh: tet4 or tet10 whose faces conform to the slit (x = xc and z = z_tip
// are node planes). Returns the mesh with duplicated nodes.
Mesh duplicate_nodes_along_slit(const Mesh& mesh, double xc, double z_tip);

}  // namespace incise
