#pragma once
// How cuts split the mesh, as the engine needs it to integrate: produced by
// cutting/ (X-FEM), consumed by build_model. Engine code never looks at cut
// surfaces; it sees pieces of elements, their sub-tetrahedra, and which
// enriched DOF node each piece adds to each element node.
//
// Enrichment ([preprint] eqs. (42), (44): shifted Heaviside, generalised to
// several cuts): in piece P of element e the displacement is
//   u(x) = sum_a N_a(x) (u_a + q_{enr(P,a)}),
// i.e. node a's standard DOF u_a plus, when P lies in another region of a's
// support than a's home region, that region's enriched DOF q. This is
// N_a * Psi with Psi = chi_region(x) - chi_region(x_a): standard DOFs keep
// their meaning as nodal displacements of the home region.
#include <vector>

namespace incise {

struct CutLayout {
  int n_enriched = 0;                 // enriched DOF nodes, appended after the mesh nodes
  std::vector<int> enr_node;          // (n_enriched) mesh node each enriched DOF node enriches
  std::vector<int> elem_piece_ptr;    // (nelem + 1) pieces of each element (an uncut element has 1)
  std::vector<int> piece_enr;         // (npiece, npe) enriched DOF node id (>= nnode) or -1
  std::vector<int> piece_subtet_ptr;  // (npiece + 1) sub-tetrahedra of each piece
  std::vector<double> subtet_rst;     // (nsubtet, 4, 3) vertices in the element's local coordinates
  std::vector<signed char> subtet_face;  // (nsubtet, 4) 0..3 parent face, 4 cut, 5 inside
  std::vector<double> piece_fraction;    // (npiece) volume fraction of the piece in its element
  std::vector<unsigned char> elem_face_cut;  // (nelem, 4) a whole element face lies on a cut
  std::vector<unsigned char> elem_split;     // (nelem) 1 when the element is cut into pieces
  int bodies = 1;                            // connected pieces of tissue (a cut frame that changes it severed one)
  std::vector<int> piece_body;               // (npiece) body of each piece, 0..bodies-1 (empty: all body 0)

  // Front enrichment (compute_cut_layout with branch_front; empty without):
  // every node a of an element a cut's front passes through, or of an
  // element sharing a corner with one (a ring one element wide), gets
  // kBranchFunctions consecutive branch DOF nodes b_k (among the enriched
  // DOF nodes above, enr_node = a) carrying N_a(x) (F_k(x) - F_k(x_a)), F_k
  // the crack-tip functions of engine/model/front_enrichment.h: the first
  // jumps by 2 sqrt(r) across the cut, is zero at the front and continuous
  // ahead of it, so the opening ends at the front line inside the element.
  // phi, psi are interpolated linearly from their values at the corner nodes.
  std::vector<int> node_branch;       // (nnode) first branch DOF node of a mesh node, -1 none; empty: no front enrichment
  std::vector<double> front_phi;      // (nnode) distance to the cut's plane at the corners of the branch nodes' elements
  std::vector<double> front_psi;      // (nnode) in-plane distance to the front there, > 0 ahead of it
  bool has_branch() const { return !node_branch.empty(); }
  int npiece() const { return static_cast<int>(piece_fraction.size()); }
};

}  // namespace incise
