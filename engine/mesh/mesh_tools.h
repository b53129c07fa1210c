#pragma once
// Mesh operations: structured beams, tet4 -> tet10, quality report and checks.
#include <array>
#include <string>
#include <vector>

#include "engine/mesh/mesh.h"

namespace incise {

// Box [0,lx]x[0,ly]x[0,lz] split into nx*ny*nz cubes of 6 tetrahedra each
// (Kuhn split, conforming across cubes). order 2 adds shared mid-edge nodes.
Mesh make_beam(double lx, double ly, double lz, int nx, int ny, int nz, int order);

// Raises a tet4 mesh to tet10: one shared node at the midpoint of each edge.
// A tet10 mesh is returned unchanged.
Mesh raise_to_tet10(const Mesh& mesh);
// A tet10 mesh's corner nodes as a tet4 mesh (mid-edge nodes dropped,
// corners renumbered in ascending order; curved faces become flat). A tet4
// mesh is returned as it is.
Mesh lower_to_tet4(const Mesh& mesh);

struct MeshQuality {
  int nnode = 0, ntet = 0;
  double min_volume = 0, max_volume = 0, total_volume = 0;
  double min_dihedral_deg = 0, max_dihedral_deg = 0;  // over corner tets
  int worst_tet = -1;  // element with the smallest min dihedral angle
};
// Volumes of tet10 elements are integrated with their quadratic geometry.
MeshQuality mesh_quality(const Mesh& mesh);
std::string format_quality(const MeshQuality& q);  // one human-readable block

// Throws incise::Error naming the first inverted or zero-volume element
// ("mesh.msh: element 17 (nodes 3 8 9 12) has volume -1.2e-06 <= 0: inverted
// or degenerate; reorder its nodes or fix the mesh"), an out-of-range node id,
// or a non-finite coordinate. For tet10 also checks the Jacobian at the corners
// and mid-edge nodes is positive.
// For tet10 also det J > 0 at the stiffness and volume quadrature points
// (a curved element can fold between its nodes). Errors start with
// "FILE:LINE: " and name the file's element id when the reader recorded them.
void check_mesh(const Mesh& mesh);

// Nodes used by elements that lie exactly where another used node lies: an
// export that did not merge duplicate vertices leaves the elements on
// either side unconnected there (the helper's beam came apart at x = 0.05,
// silently). `count` such nodes (every node of a group but its first), the
// first pair found (a < b), or count 0. A slit meshed on purpose
// (cutting/conforming_slit.h) has them too.
struct CoincidentNodes {
  int count = 0;
  int a = -1, b = -1;
};
CoincidentNodes coincident_nodes(const Mesh& mesh);

// The barycentric points (L0..L3) where check_mesh() evaluates a tet10's
// det J: its 4 corners, 6 mid-edge nodes, the 4-point stiffness rule
// (cubature_tet4()), then the 27 volume points.
std::vector<std::array<double, 4>> tet10_check_points_barycentric();

}  // namespace incise
