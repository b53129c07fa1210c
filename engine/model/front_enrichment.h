#pragma once
// The cut-front enrichment functions (engine/model/cut_layout.h,
// node_branch): the four crack-tip functions of Moes, Dolbow & Belytschko
// (1999), eq. (13), sqrt(r) {sin, cos}(theta/2) {1, sin theta}, (r, theta)
// the polar coordinates of (psi, phi) about the front line, phi the distance
// to the cut's plane, psi the in-plane distance to the front (> 0 ahead).
// [preprint] sec. 4 enriches with Heaviside functions only. The first jumps
// by 2 sqrt(r) across phi = 0 behind the front (psi < 0) and is continuous
// ahead (psi > 0); all are 0 at the front; the others are continuous and
// span the rest of the near-front field.
#include <algorithm>
#include <cmath>
#include <vector>

#include "engine/fem/element.h"
#include "engine/mesh/mesh.h"
#include "engine/model/model.h"

namespace incise {

// The crack-tip functions, with their derivatives by phi and psi. With
// s = sign(phi), sin(theta/2) = s sqrt((r - psi) / (2 r)), cos(theta/2) =
// sqrt((r + psi) / (2 r)), sin(theta) = phi / r:
//   F0 = sqrt(r) sin(theta/2) = s sqrt((r - psi) / 2)   (discontinuous)
//   F1 = sqrt(r) cos(theta/2) = sqrt((r + psi) / 2)
//   F2 = F0 sin(theta),  F3 = F1 sin(theta)
// dF0 = (F1, -F0) / 2r, dF1 = (F0, F1) / 2r (by phi, psi; phi = 2 F0 F1).
// kBranchFunctions of them are enriched (one DOF node each): F0 only, on the
// nodes of the front elements and of the ring of elements around them
// (cutting/xfem_layout.cpp). With all four (front elements only) the slit
// study (tools/study_slit_fronts.cpp) stopped converging (errors of 1-4% at
// every level; F0 and F1: erratic); with F0, the ring and branch_cubature it
// converges at order 1.3-2.3 with 0.16-0.48x the conforming mesh's error
// (docs/benchmarks.md, "Issue 21: branch elements integrated with 27 points"). Likely cause, not verified: where F1..F3
// are smooth over a node's support, N_a (F_k - F_k(x_a)) summed over the
// nodes is F_k minus its interpolant, almost zero: a near-null direction
// of the stiffness (F0 jumps across the cut, so it has none there). With
// the ring and all four, CHOLMOD found the slit's stiffness not positive
// definite (nineteenth session), which fits.
inline constexpr int kTipFunctions = 4;

// The cubature for the sub-tetrahedra of elements with branch DOF nodes
// that have a corner within kBranchCubatureReach of their diameter from the
// front line (model_build.cpp; the state transfer, cutting/cut_apply.cpp,
// takes it everywhere): the 27-point collapsed Gauss-Legendre product rule
// (cubature_duffy(3)), not the 4-point rule of the other elements. The branch functions are not
// polynomial (their gradients grow as r^-1/2 toward the front line, on the
// faces and edges of these elements): under the 4-point rule the branch
// DOFs took large, nearly cancelling values whose energy the rule did not
// see. A scalpel's incision enriched while the blade rested (tried in the
// twenty-first session, docs/cutting.md): a rebuild without the branch DOFs
// when the blade went on found 1.3x the model's strain energy in them, an
// energy jump of 84% of the gravity work; 0.9% with this rule (each
// sub-tetrahedron's 8 children with the 4-point rule: 5.9%, 64 children:
// 1.2%; the 64- and 125-point product rules: 2.9%, 0.75%). A second cut
// taking an enriched front to faces: 0.24 -> 0.21 of the gravity work
// (FrontEnrichment.ASecondCutThroughTheFrontTakesItToFaces...).
// Reach 0.5: on the 3k-DOF partial slit (assets/scenes/beam_partial_slit.json)
// the enriched frame's assembly took 16 ms against 4.9 with the 4-point
// rule and 27 with the 27-point rule in every branch element, all point by
// point (since the split branch elements' pieces rotate a rest stiffness,
// build_slot_stiffness: 5 ms, the whole ring elements' points most of it); the
// ASecondCut... energy change and the 1e-12 h fronts' difference are those
// of every element (0.207, 5.2e-3); at reach 0.25 they are the 4-point
// rule's (0.242, 3.6e-4).
inline constexpr double kBranchCubatureReach = 0.5;
const Cubature& branch_cubature();
inline constexpr int kBranchFunctions = 1;
struct BranchValue {
  double F[kTipFunctions] = {0}, dphi[kTipFunctions] = {0}, dpsi[kTipFunctions] = {0};
};

// side: the sign taken for phi == 0 (a point exactly on the cut's plane).
inline BranchValue branch_function(double phi, double psi, int side = 1) {
  BranchValue v;
  const double r = std::sqrt(phi * phi + psi * psi);
  if (!(r > 0)) return v;
  const double s = phi > 0 ? 1.0 : phi < 0 ? -1.0 : side;
  const double f0 = s * std::sqrt(std::max(0.0, 0.5 * (r - psi))), f1 = std::sqrt(std::max(0.0, 0.5 * (r + psi)));
  const double sn = phi / r, dsn_phi = psi * psi / (r * r * r), dsn_psi = -phi * psi / (r * r * r);
  v.F[0] = f0;
  v.dphi[0] = f1 / (2 * r);
  v.dpsi[0] = -f0 / (2 * r);
  v.F[1] = f1;
  v.dphi[1] = f0 / (2 * r);
  v.dpsi[1] = f1 / (2 * r);
  for (int k = 0; k < 2; ++k) {
    v.F[2 + k] = v.F[k] * sn;
    v.dphi[2 + k] = v.dphi[k] * sn + v.F[k] * dsn_phi;
    v.dpsi[2 + k] = v.dpsi[k] * sn + v.F[k] * dsn_psi;
  }
  return v;
}

// phi and psi at element e's nodes (npe each): the corner values, and at a
// tet10 mid-edge node the mean of its corners'. Interpolated with the
// element's shape functions they are linear in the local coordinates (as the
// sub-element split sees them), also in a curved element.
// From the element's npe mesh nodes and the per-node level sets
// (CutLayout::front_phi, front_psi), without a Model (the collision
// surface keeps copies).
inline void front_node_values(int npe, const int* nodes, const double* front_phi, const double* front_psi, double* phi,
                              double* psi) {
  for (int a = 0; a < npe; ++a) {
    const int i = a < 4 ? nodes[a] : nodes[kTet10Edge[a - 4][0]], j = a < 4 ? i : nodes[kTet10Edge[a - 4][1]];
    phi[a] = 0.5 * (front_phi[i] + front_phi[j]);
    psi[a] = 0.5 * (front_psi[i] + front_psi[j]);
  }
}
inline void front_node_values(const Model& m, int e, double* phi, double* psi) {
  const int npe = m.mesh.npe();
  front_node_values(npe, &m.mesh.tet[static_cast<size_t>(e) * npe], m.cuts.front_phi.data(), m.cuts.front_psi.data(),
                    phi, psi);
}

// Whether any of an element's npe mesh nodes has branch DOF nodes.
inline bool nodes_have_branch(int npe, const int* nodes, const int* node_branch) {
  for (int a = 0; a < npe; ++a)
    if (node_branch[nodes[a]] >= 0) return true;
  return false;
}

// The branch part of the field at a point with shape values N of an element
// with these nodes: f(b, w) for each branch DOF node b and its weight
// w = N_a (F_k(x) - F_k(x_a)). side: +1 or -1, the side of the cut's plane
// a point on it belongs to (a sub-tetrahedron's, where the caller knows it:
// a corner on the plane has a phi of either sign in roundoff; taken where
// |phi| <= 1e-9 of the element's largest, elsewhere phi's sign); 0: the
// sign of phi there (+ when exactly 0). Nothing when no node has branch
// DOF nodes.
template <class Fn>
void for_each_branch_weight(int npe, const int* nodes, const int* node_branch, const double* front_phi,
                            const double* front_psi, const double* N, int side, Fn&& f) {
  if (!nodes_have_branch(npe, nodes, node_branch)) return;
  double phi[10], psi[10], ph = 0, ps = 0, scale = 0;
  front_node_values(npe, nodes, front_phi, front_psi, phi, psi);
  for (int a = 0; a < npe; ++a) ph += N[a] * phi[a], ps += N[a] * psi[a], scale = std::max(scale, std::abs(phi[a]));
  // The caller's side only where phi is 0 to roundoff: elsewhere phi's own
  // sign, as the model's gradients take it (a sub-tetrahedron ahead of the
  // front may straddle the plane, and its side would mirror F there).
  const bool on_plane = std::abs(ph) <= 1e-9 * scale;
  const BranchValue F = side != 0 && on_plane ? branch_function(side * std::abs(ph), ps, side) : branch_function(ph, ps);
  for (int a = 0; a < npe; ++a) {
    const int b = node_branch[nodes[a]];
    if (b < 0) continue;
    const BranchValue Fa = branch_function(phi[a], psi[a]);
    for (int k = 0; k < kBranchFunctions; ++k) f(b + k, N[a] * (F.F[k] - Fa.F[k]));
  }
}

// Of an element's DOF nodes `local` (n; the first npe its mesh nodes): for
// each j, the element node a whose branch DOF node it is and the function
// k, into owner[j], fk[j] (owner -1: not a branch DOF node).
inline void branch_owners(const Model& m, const int* local, int n, std::vector<int>& owner, std::vector<int>& fk) {
  const int npe = m.mesh.npe();
  owner.assign(n, -1);
  fk.assign(n, 0);
  for (int j = npe; j < n; ++j)
    for (int a = 0; a < npe; ++a) {
      const int b = m.cuts.node_branch[local[a]], k = local[j] - b;
      if (b < 0 || k < 0 || k >= kBranchFunctions) continue;
      owner[j] = a;
      fk[j] = k;
    }
}

// Whether element e has a node with a branch DOF node.
inline bool element_has_branch(const Model& m, int e) {
  const int npe = m.mesh.npe();
  return m.cuts.has_branch() && nodes_have_branch(npe, &m.mesh.tet[static_cast<size_t>(e) * npe], m.cuts.node_branch.data());
}

// The side of the front's cut plane (the sign of phi, + at 0) local point
// rst of element e lies on; 0 when e has no branch DOF node.
// From the element's npe mesh nodes and the CutLayout arrays (no Model).
inline int front_side(int npe, const int* nodes, const int* node_branch, const double* front_phi, const double rst[3]) {
  if (!nodes_have_branch(npe, nodes, node_branch)) return 0;
  const double f = (1 - rst[0] - rst[1] - rst[2]) * front_phi[nodes[0]] + rst[0] * front_phi[nodes[1]] +
                   rst[1] * front_phi[nodes[2]] + rst[2] * front_phi[nodes[3]];
  return f < 0 ? -1 : 1;
}
inline int front_side(const Model& m, int e, const double rst[3]) {
  if (!m.cuts.has_branch()) return 0;
  const int npe = m.mesh.npe();
  return front_side(npe, &m.mesh.tet[static_cast<size_t>(e) * npe], m.cuts.node_branch.data(), m.cuts.front_phi.data(),
                    rst);
}

// The side of a sub-tetrahedron v (4 x 3 local coordinates) of an element:
// its centroid's (its corners on the plane take that side; 0 without
// branch DOF nodes). The display and the collision surface take it for
// every point of the sub-tetrahedron.
inline int subtet_front_side(int npe, const int* nodes, const int* node_branch, const double* front_phi,
                             const double* v) {
  double c[3] = {0, 0, 0};
  for (int k = 0; k < 4; ++k)
    for (int d = 0; d < 3; ++d) c[d] += 0.25 * v[3 * k + d];
  return front_side(npe, nodes, node_branch, front_phi, c);
}

// Adds the branch DOFs' part of a field at a point of element e (N: the
// shape values there) to out: sum_a,k N_a (F_k(x) - F_k(x_a)) w_(b_a + k),
// w a DOF vector (u or v); side as for for_each_branch_weight.
inline void add_branch_field(const Model& m, int e, const double* N, int side, const double* w, double out[3]) {
  if (!m.cuts.has_branch()) return;
  const int npe = m.mesh.npe();
  for_each_branch_weight(npe, &m.mesh.tet[static_cast<size_t>(e) * npe], m.cuts.node_branch.data(),
                         m.cuts.front_phi.data(), m.cuts.front_psi.data(), N, side, [&](int b, double wt) {
                           for (int d = 0; d < 3; ++d) out[d] += wt * w[3 * b + d];
                         });
}

}  // namespace incise
