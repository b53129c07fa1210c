#include "collision/point_weights.h"

#include <cmath>

#include "engine/fem/element.h"
#include "engine/model/front_enrichment.h"

namespace incise {

static_assert(PointWeights::kMax >= 10 * (2 + kBranchFunctions), "tet10: standard, enriched and branch weights");

PointWeights point_dof_weights(const Model& m, int elem, int piece, const double rst[3], int side) {
  const int npe = m.mesh.npe();
  BranchView b;
  if (m.cuts.has_branch()) b = {m.cuts.node_branch.data(), m.cuts.front_phi.data(), m.cuts.front_psi.data()};
  return point_dof_weights(npe, &m.mesh.tet[static_cast<size_t>(elem) * npe],
                           piece >= 0 ? &m.cuts.piece_enr[static_cast<size_t>(piece) * npe] : nullptr, rst, b, side);
}

PointWeights point_dof_weights(int npe, const int* nodes, const int* enr, const double rst[3], const BranchView& branch,
                               int side) {
  double N[10];
  shape_values(npe, rst, N);
  PointWeights w;
  for (int a = 0; a < npe; ++a) {
    if (std::abs(N[a]) < kWeightDrop) continue;
    w.dofnode[w.n] = nodes[a], w.weight[w.n] = N[a], ++w.n;
    if (enr && enr[a] >= 0) w.dofnode[w.n] = enr[a], w.weight[w.n] = N[a], ++w.n;
  }
  if (!branch.node_branch) return w;
  for_each_branch_weight(npe, nodes, branch.node_branch, branch.front_phi, branch.front_psi, N, side,
                         [&](int b, double wt) {
                           if (std::abs(wt) >= kWeightDrop) w.dofnode[w.n] = b, w.weight[w.n] = wt, ++w.n;
                         });
  return w;
}

void point_reference_position(const Model& m, int elem, const double rst[3], double X[3]) {
  const int npe = m.mesh.npe();
  double N[10];
  shape_values(npe, rst, N);
  const int* nodes = &m.mesh.tet[static_cast<size_t>(elem) * npe];
  X[0] = X[1] = X[2] = 0.0;
  for (int a = 0; a < npe; ++a)
    for (int c = 0; c < 3; ++c) X[c] += N[a] * m.X[3 * nodes[a] + c];
}

void point_position(const PointWeights& w, const double X[3], const double* u, double x[3]) {
  for (int c = 0; c < 3; ++c) x[c] = X[c];
  for (int k = 0; k < w.n; ++k)
    for (int c = 0; c < 3; ++c) x[c] += w.weight[k] * u[3 * w.dofnode[k] + c];
}

}  // namespace incise
