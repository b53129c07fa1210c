#include "engine/output/display_mesh.h"

#include "engine/fem/element.h"
#include "engine/model/front_enrichment.h"

namespace incise {
namespace {

// Local coordinates of the reference element's nodes: corners (0,0,0),
// (1,0,0), (0,1,0), (0,0,1), then the kTet10Edge midpoints.
void append_reference_rst(int npe, std::vector<double>& out) {
  static const double corner[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  for (int a = 0; a < npe; ++a)
    for (int c = 0; c < 3; ++c)
      out.push_back(a < 4 ? corner[a][c] : 0.5 * (corner[kTet10Edge[a - 4][0]][c] + corner[kTet10Edge[a - 4][1]][c]));
}

}  // namespace

DisplayMesh display_mesh(const Model& m, const State& s, DisplayCells which) {
  DisplayMesh d;
  d.order = m.mesh.order;
  const int nn = m.nnode, npe = m.mesh.npe(), nt = m.mesh.ntet();
  const bool surface = which == DisplayCells::Surface;
  d.X.assign(m.X.begin(), m.X.begin() + 3 * nn);
  d.u.assign(s.u.begin(), s.u.begin() + 3 * nn);
  d.v.assign(s.v.begin(), s.v.begin() + 3 * nn);
  if (!m.has_cuts() && !surface) {
    d.cells = m.mesh.tet;
    d.cell_elem.resize(nt);
    for (int e = 0; e < nt; ++e) d.cell_elem[e] = e;
    d.cell_piece.assign(nt, -1);
    d.cell_rst.reserve(static_cast<size_t>(nt) * npe * 3);
    for (int e = 0; e < nt; ++e) append_reference_rst(npe, d.cell_rst);
    d.face_flags.assign(m.tet_face_boundary.begin(), m.tet_face_boundary.end());  // kFaceBoundary == 1
    return d;
  }
  if (!m.has_cuts()) {  // the surface's cells
    for (int e = 0; e < nt; ++e) {
      const unsigned char* fb = &m.tet_face_boundary[4 * static_cast<size_t>(e)];
      if (!(fb[0] || fb[1] || fb[2] || fb[3])) continue;
      d.cells.insert(d.cells.end(), m.mesh.tet.begin() + static_cast<size_t>(e) * npe,
                     m.mesh.tet.begin() + static_cast<size_t>(e + 1) * npe);
      d.cell_elem.push_back(e);
      d.cell_piece.push_back(-1);
      append_reference_rst(npe, d.cell_rst);
      d.face_flags.insert(d.face_flags.end(), fb, fb + 4);  // kFaceBoundary == 1
    }
    return d;
  }
  const CutLayout& L = m.cuts;
  double N[10];
  for (int e = 0; e < nt; ++e) {
    const int* nodes = &m.mesh.tet[static_cast<size_t>(e) * npe];
    if (!L.elem_split[e] && L.elem_piece_ptr[e + 1] - L.elem_piece_ptr[e] == 1) {
      // Whole element: its own nodes, moved with its piece's field (an
      // enriched node shows the value of this element's region).
      unsigned char flags[4];
      for (int k = 0; k < 4; ++k)
        flags[k] = (m.tet_face_boundary[4 * e + k] ? kFaceBoundary : 0) | (L.elem_face_cut[4 * e + k] ? kFaceCut : 0);
      if (surface && !(flags[0] || flags[1] || flags[2] || flags[3])) continue;
      const int P = L.elem_piece_ptr[e];
      const int* enr = &L.piece_enr[static_cast<size_t>(P) * npe];
      bool plain = true;
      for (int a = 0; a < npe; ++a) plain = plain && enr[a] < 0;
      for (int a = 0; a < npe; ++a) {
        if (plain) {
          d.cells.push_back(nodes[a]);
          continue;
        }
        d.cells.push_back(d.npoint());
        for (int c = 0; c < 3; ++c) {
          d.X.push_back(m.X[3 * nodes[a] + c]);
          d.u.push_back(s.u[3 * nodes[a] + c] + (enr[a] >= 0 ? s.u[3 * enr[a] + c] : 0.0));
          d.v.push_back(s.v[3 * nodes[a] + c] + (enr[a] >= 0 ? s.v[3 * enr[a] + c] : 0.0));
        }
      }
      d.cell_elem.push_back(e);
      d.cell_piece.push_back(P);
      append_reference_rst(npe, d.cell_rst);
      d.face_flags.insert(d.face_flags.end(), flags, flags + 4);
      continue;
    }
    // Split element: each piece's sub-tetrahedra, their points mapped by the
    // element's shape functions and moved with the piece's own field.
    for (int P = L.elem_piece_ptr[e]; P < L.elem_piece_ptr[e + 1]; ++P) {
      const int* enr = &L.piece_enr[static_cast<size_t>(P) * npe];
      for (int t = L.piece_subtet_ptr[P]; t < L.piece_subtet_ptr[P + 1]; ++t) {
        unsigned char flags[4];
        for (int k = 0; k < 4; ++k) {
          const signed char tag = L.subtet_face[4 * static_cast<size_t>(t) + k];
          flags[k] = 0;
          if (tag >= 0 && tag < 4) {
            if (m.tet_face_boundary[4 * e + tag]) flags[k] |= kFaceBoundary;
            if (L.elem_face_cut[4 * e + tag]) flags[k] |= kFaceCut;
          } else if (tag == 4) {
            flags[k] |= kFaceCut;
          }
        }
        if (surface && !(flags[0] || flags[1] || flags[2] || flags[3])) continue;
        const double* v = &L.subtet_rst[12 * static_cast<size_t>(t)];
        const int side = m.cuts.has_branch() ? subtet_front_side(npe, nodes, m.cuts.node_branch.data(),
                                                                 m.cuts.front_phi.data(), v)
                                              : 0;
        for (int a = 0; a < npe; ++a) {
          double r[3];
          if (a < 4) {
            for (int c = 0; c < 3; ++c) r[c] = v[3 * a + c];
          } else {
            const int i = kTet10Edge[a - 4][0], j = kTet10Edge[a - 4][1];
            for (int c = 0; c < 3; ++c) r[c] = 0.5 * (v[3 * i + c] + v[3 * j + c]);
          }
          shape_values(npe, r, N);
          double X[3] = {0, 0, 0}, u[3] = {0, 0, 0}, vel[3] = {0, 0, 0};
          for (int b = 0; b < npe; ++b)
            for (int c = 0; c < 3; ++c) {
              X[c] += N[b] * m.X[3 * nodes[b] + c];
              u[c] += N[b] * (s.u[3 * nodes[b] + c] + (enr[b] >= 0 ? s.u[3 * enr[b] + c] : 0.0));
              vel[c] += N[b] * (s.v[3 * nodes[b] + c] + (enr[b] >= 0 ? s.v[3 * enr[b] + c] : 0.0));
            }
          add_branch_field(m, e, N, side, s.u.data(), u);  // front enrichment (none without)
          add_branch_field(m, e, N, side, s.v.data(), vel);
          d.cells.push_back(d.npoint());
          d.cell_rst.insert(d.cell_rst.end(), r, r + 3);
          d.X.insert(d.X.end(), X, X + 3);
          d.u.insert(d.u.end(), u, u + 3);
          d.v.insert(d.v.end(), vel, vel + 3);
        }
        d.cell_elem.push_back(e);
        d.cell_piece.push_back(P);
        d.face_flags.insert(d.face_flags.end(), flags, flags + 4);
      }
    }
  }
  return d;
}

}  // namespace incise
