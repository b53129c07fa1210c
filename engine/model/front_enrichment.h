#pragma once
// The cut-front enrichment function (engine/model/cut_layout.h, node_branch):
// F = sqrt(r) sin(theta / 2), (r, theta) the polar coordinates of
// (psi, phi) about the front line, phi the distance to the cut's plane, psi
// the in-plane distance to the front (> 0 ahead). The discontinuous one of
// the four crack-tip functions of Moes, Dolbow & Belytschko (1999), eq. (13);
// [preprint] sec. 4 enriches with Heaviside functions only. Without
// trigonometry: sin(theta / 2) = sign(phi) sqrt((1 - psi / r) / 2), so
//   F = sign(phi) sqrt((r - psi) / 2),
//   dF/dphi = sqrt((r + psi) / 2) / (2 r),   dF/dpsi = -F / (2 r).
// Behind the front (psi < 0) F jumps by 2 sqrt(r) across phi = 0; ahead
// (psi > 0) it is continuous; at the front it is 0.
#include <algorithm>
#include <cmath>

#include "engine/mesh/mesh.h"

#include "engine/model/model.h"

namespace incise {

struct BranchValue {
  double F = 0, dphi = 0, dpsi = 0;
};

// side: the sign taken for phi == 0 (a point exactly on the cut's plane).
inline BranchValue branch_function(double phi, double psi, int side = 1) {
  const double r = std::sqrt(phi * phi + psi * psi);
  if (!(r > 0)) return {};
  const double s = phi > 0 ? 1.0 : phi < 0 ? -1.0 : side;
  BranchValue v;
  v.F = s * std::sqrt(std::max(0.0, 0.5 * (r - psi)));
  v.dphi = std::sqrt(std::max(0.0, 0.5 * (r + psi))) / (2 * r);
  v.dpsi = -v.F / (2 * r);
  return v;
}

// phi and psi at element e's nodes (npe each): the corner values, and at a
// tet10 mid-edge node the mean of its corners'. Interpolated with the
// element's shape functions they are linear in the local coordinates (as the
// sub-element split sees them), also in a curved element.
inline void front_node_values(const Model& m, int e, double* phi, double* psi) {
  const int npe = m.mesh.npe();
  const int* nodes = &m.mesh.tet[static_cast<size_t>(e) * npe];
  for (int a = 0; a < npe; ++a) {
    const int i = a < 4 ? nodes[a] : nodes[kTet10Edge[a - 4][0]], j = a < 4 ? i : nodes[kTet10Edge[a - 4][1]];
    phi[a] = 0.5 * (m.cuts.front_phi[i] + m.cuts.front_phi[j]);
    psi[a] = 0.5 * (m.cuts.front_psi[i] + m.cuts.front_psi[j]);
  }
}

// Whether element e has a node with a branch DOF node.
inline bool element_has_branch(const Model& m, int e) {
  if (!m.cuts.has_branch()) return false;
  const int npe = m.mesh.npe();
  for (int a = 0; a < npe; ++a)
    if (m.cuts.node_branch[m.mesh.tet[static_cast<size_t>(e) * npe + a]] >= 0) return true;
  return false;
}

}  // namespace incise
