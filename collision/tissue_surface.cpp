#include "collision/tissue_surface.h"

#include <string>

#include "engine/fem/element.h"
#include "engine/mesh/mesh.h"
#include "engine/model/front_enrichment.h"
#include "engine/output/display_mesh.h"
#include "engine/output/face_grid.h"
#include "engine/output/surface_extract.h"
#include "engine/util/error.h"

namespace incise {

TissueSurface::TissueSurface(const Model& m, const State& s, int segs) {
  if (static_cast<int>(s.u.size()) != m.ndof())
    throw Error("TissueSurface: the state has " + std::to_string(s.u.size()) + " DOFs, the model " +
                std::to_string(m.ndof()));
  const DisplayMesh d = display_mesh(m, s, DisplayCells::Surface);  // the flagged faces' cells
  const Surface surf = extract_surface(d);
  const FaceGrid g = face_grid(face_segments(d.order, segs));
  const int vpf = g.verts_per_face;
  segments = g.segments;
  nface = surf.nface();
  nboundary = surf.nboundary;
  ndof = m.ndof();
  npe = m.mesh.npe();
  elem_node = m.mesh.tet;
  piece_enr = m.cuts.piece_enr;
  node_X.assign(m.X.begin(), m.X.begin() + 3 * static_cast<size_t>(m.nnode));
  node_branch = m.cuts.node_branch;
  front_phi = m.cuts.front_phi;
  front_psi = m.cuts.front_psi;
  const BranchView branch = branch_view();
  const size_t nv = static_cast<size_t>(nface) * vpf, nt = static_cast<size_t>(nface) * g.tris_per_face;
  vert_elem.reserve(nv);
  vert_piece.reserve(nv);
  vert_side.reserve(nv);
  vert_rst.reserve(3 * nv);
  vert_X.reserve(3 * nv);
  vert_ptr.reserve(nv + 1);
  vert_ptr.push_back(0);
  tri.reserve(3 * nt);
  tri_face.reserve(nt);
  tri_cut.reserve(nt);
  for (int f = 0; f < nface; ++f) {
    const int c = surf.face_cell[f];
    const int e = d.cell_elem[c], piece = d.cell_piece[c];
    const int* corner = kTetFace[surf.face_local[f]];  // the face's corners in the cell, outward order
    const double* crst = &d.cell_rst[static_cast<size_t>(d.npe()) * 3 * c];
    // A sub-tetrahedron's side of the front's cut plane (its cut faces lie
    // on the plane, where phi's sign is roundoff), as the display takes it.
    // A whole element's points take phi's own sign (0): one may straddle the
    // plane ahead of the front, where F is continuous.
    const bool sub = branch.node_branch && m.cuts.elem_split[e];
    const int side = sub ? subtet_front_side(npe, &elem_node[static_cast<size_t>(e) * npe], branch.node_branch,
                                             branch.front_phi, crst)
                         : 0;
    const int base = nvert();
    for (int v = 0; v < vpf; ++v) {
      // rst is linear over the cell's (sub-)tetrahedron, so over the face.
      const double* L = &g.weights[3 * static_cast<size_t>(v)];
      double rst[3] = {0, 0, 0}, X[3];
      for (int j = 0; j < 3; ++j)
        for (int k = 0; k < 3; ++k) rst[k] += L[j] * crst[3 * corner[j] + k];
      reference_position(e, rst, X);
      const PointWeights w = point_weights(e, piece, rst, side);
      vert_elem.push_back(e);
      vert_piece.push_back(piece);
      vert_side.push_back(static_cast<signed char>(side));
      vert_rst.insert(vert_rst.end(), rst, rst + 3);
      vert_X.insert(vert_X.end(), X, X + 3);
      vert_dofnode.insert(vert_dofnode.end(), w.dofnode, w.dofnode + w.n);
      vert_weight.insert(vert_weight.end(), w.weight, w.weight + w.n);
      vert_ptr.push_back(static_cast<int>(vert_dofnode.size()));
    }
    for (int t = 0; t < g.tris_per_face; ++t) {
      for (int j = 0; j < 3; ++j) tri.push_back(base + g.tris[3 * t + j]);
      tri_face.push_back(f);
      tri_cut.push_back(f >= nboundary ? 1 : 0);
    }
  }
  x.resize(3 * nv);
  update_positions(s);
}

BranchView TissueSurface::branch_view() const {
  if (node_branch.empty()) return {};
  return {node_branch.data(), front_phi.data(), front_psi.data()};
}

PointWeights TissueSurface::point_weights(int elem, int piece, const double rst[3], int side) const {
  return point_dof_weights(npe, &elem_node[static_cast<size_t>(elem) * npe],
                           piece >= 0 ? &piece_enr[static_cast<size_t>(piece) * npe] : nullptr, rst, branch_view(),
                           side);
}

void TissueSurface::reference_position(int elem, const double rst[3], double X[3]) const {
  double N[10];
  shape_values(npe, rst, N);
  const int* nodes = &elem_node[static_cast<size_t>(elem) * npe];
  X[0] = X[1] = X[2] = 0.0;
  for (int a = 0; a < npe; ++a)
    for (int c = 0; c < 3; ++c) X[c] += N[a] * node_X[3 * nodes[a] + c];
}

void TissueSurface::update_positions(const State& s) {
  if (static_cast<int>(s.u.size()) != ndof)
    throw Error("TissueSurface::update_positions: the state has " + std::to_string(s.u.size()) +
                " DOFs, the surface was built on a model with " + std::to_string(ndof) +
                " (rebuild it after a cut)");
  const double* u = s.u.data();
  const int nv = nvert();
  for (int v = 0; v < nv; ++v) {
    double p[3] = {vert_X[3 * v], vert_X[3 * v + 1], vert_X[3 * v + 2]};
    for (int k = vert_ptr[v]; k < vert_ptr[v + 1]; ++k) {
      const double w = vert_weight[k];
      const double* uk = u + 3 * static_cast<size_t>(vert_dofnode[k]);
      p[0] += w * uk[0], p[1] += w * uk[1], p[2] += w * uk[2];
    }
    x[3 * v] = p[0], x[3 * v + 1] = p[1], x[3 * v + 2] = p[2];
  }
}

}  // namespace incise
