#include "engine/display_mesh.h"

namespace incise {

DisplayMesh display_mesh(const Model& m, const State& s) {
  DisplayMesh d;
  d.order = m.mesh.order;
  const int nn = m.nnode;
  d.X.assign(m.X.begin(), m.X.begin() + 3 * nn);
  d.u.assign(s.u.begin(), s.u.begin() + 3 * nn);
  d.v.assign(s.v.begin(), s.v.begin() + 3 * nn);
  d.cells = m.mesh.tet;
  d.cell_elem.resize(m.mesh.ntet());
  for (int e = 0; e < m.mesh.ntet(); ++e) d.cell_elem[e] = e;
  d.face_flags.assign(m.tet_face_boundary.begin(), m.tet_face_boundary.end());  // kFaceBoundary == 1
  return d;
}

}  // namespace incise
