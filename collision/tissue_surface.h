#pragma once
// The deformed tissue surface as instruments meet it: the boundary and cut
// faces of the DisplayMesh (engine/output/surface_extract.h), each tet10
// face tessellated into n^2 flat triangles on the renderer's grid
// (engine/output/face_grid.h), so a tool touches what the viewer sees. A
// triangle soup: every face has its own grid vertices (a vertex on a face
// edge appears once per face), each a material point of one piece of one
// element, moved by its DOF weights (collision/point_weights.h).
//
// On whole elements the vertices are exactly the renderer's; on a cut
// element's sub-tetrahedra they are X(rst) + u(rst) of the parent element at
// rst linear over the sub-face, where the renderer interpolates the
// sub-tetrahedron's own 6 face points (the two agree on straight elements).
#include <vector>

#include "collision/point_weights.h"
#include "engine/dynamics/state.h"
#include "engine/model/model.h"

namespace incise {

struct TissueSurface {
  int segments = 1;                 // per face edge: scene render.subdivision for tet10, 1 for tet4
  int nface = 0, nboundary = 0;     // extracted faces: [0, nboundary) outer surface, then cut faces
  int ndof = 0;                     // of the model it was built on (update_positions checks it)

  // What a material point of that model needs (copied, so contacts map
  // without the Model and never onto a newer model's DOF numbering).
  int npe = 4;
  std::vector<int> elem_node;       // (nelem, npe) model.mesh.tet
  std::vector<int> piece_enr;       // (npiece, npe) model.cuts.piece_enr; empty without cuts
  std::vector<double> node_X;       // (nnode, 3) reference positions of the mesh nodes
  // The front enrichment's per-node data (model.cuts.node_branch,
  // front_phi, front_psi); empty without it.
  std::vector<int> node_branch;
  std::vector<double> front_phi, front_psi;

  // Vertices: per face, the face grid's vertices in its order.
  std::vector<int> vert_elem;       // (nvert) element holding the material point
  std::vector<int> vert_piece;      // (nvert) its piece (CutLayout), -1 without cuts
  std::vector<signed char> vert_side;  // (nvert) side of the front's cut plane (its sub-tetrahedron's), 0: phi's sign
  std::vector<double> vert_rst;     // (nvert, 3) local coordinates in the element
  std::vector<double> vert_X;       // (nvert, 3) reference position X(rst)
  std::vector<int> vert_ptr;        // (nvert + 1) into vert_dofnode / vert_weight
  std::vector<int> vert_dofnode;    // DOF nodes moving the vertex ...
  std::vector<double> vert_weight;  // ... with these weights: x = X + sum_k w_k u(dofnode_k)
  std::vector<double> x;            // (nvert, 3) current positions

  // Triangles: counter-clockwise seen from outside the piece they bound, so
  // (x1 - x0) x (x2 - x0) is the outward normal.
  std::vector<int> tri;             // (ntri, 3) vertex ids
  std::vector<int> tri_face;        // (ntri) source face (index in the extracted Surface)
  std::vector<unsigned char> tri_cut;  // (ntri) 1: the face lies on a cut surface

  TissueSurface() = default;
  // segments: curved faces get max(2, segments), flat faces 1 (face_segments).
  TissueSurface(const Model& model, const State& state, int segments);

  // x from the state's displacement; allocates nothing. Throws incise::Error
  // when the state does not fit the model the surface was built on.
  void update_positions(const State& state);

  // DOF weights and reference position X(rst) of any point (elem, piece,
  // rst; side: of the front's cut plane, as vert_side, 0 = phi's sign).
  PointWeights point_weights(int elem, int piece, const double rst[3], int side = 0) const;
  void reference_position(int elem, const double rst[3], double X[3]) const;
  BranchView branch_view() const;  // of the copies above (null without front enrichment)

  int nvert() const { return static_cast<int>(vert_elem.size()); }
  int ntri() const { return static_cast<int>(tri_face.size()); }
  int verts_per_face() const { return nface > 0 ? nvert() / nface : 0; }
};

}  // namespace incise
