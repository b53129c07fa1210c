#pragma once
// The DOF nodes that move a material point of the tissue, and by how much.
// In piece P of element e ([preprint] eq. (42) in the per-piece form of
// engine/model/cut_layout.h)
//   x(rst) = X(rst) + sum_a N_a(rst) (u_a + q_enr(P,a)),
// so the point moves with weight N_a on mesh node a and with the same weight
// on P's enriched DOF node at a, when it has one. Another piece's enriched
// DOF nodes never appear: a point on one side of a cut moves with that side.
// With the front enrichment (engine/model/front_enrichment.h) a point of an
// element holding branch DOF nodes also moves with weight N_a (F(x) - F_a)
// on node a's, F taken on the point's side of the front's cut plane.
// Used by the collision surface (per vertex), its contacts and grasps.
#include "engine/model/model.h"

namespace incise {

struct PointWeights {
  static constexpr int kMax = 30;  // 3 npe for tet10: every node standard, enriched and branch
  int n = 0;
  int dofnode[kMax];   // DOF node (dof = 3 dofnode + c), mesh nodes < model.nnode <= enriched
  double weight[kMax];
};

// Shape-function values below this are dropped: they are the exact zeros of
// the nodes off a face (L_k = 0 up to roundoff in rst), not motion.
inline constexpr double kWeightDrop = 1e-14;

// The front enrichment's data a point's weights need (a view of
// CutLayout::node_branch, front_phi, front_psi; null without).
struct BranchView {
  const int* node_branch = nullptr;
  const double* front_phi = nullptr;
  const double* front_psi = nullptr;
};

// Weights of local point rst of element elem, in piece `piece` (-1: a model
// without cuts, or the element's standard field only); side: the side of
// the front's cut plane the point belongs to (+1, -1; 0: the sign of phi
// there), for elements with branch DOF nodes.
PointWeights point_dof_weights(const Model& model, int elem, int piece, const double rst[3], int side = 0);
// The same from the element's npe mesh nodes and its piece's enriched DOF
// nodes (npe entries, -1 = none; nullptr = no piece).
PointWeights point_dof_weights(int npe, const int* nodes, const int* enr, const double rst[3],
                               const BranchView& branch = {}, int side = 0);

// Reference position X(rst) = sum_a N_a(rst) X_a of the point.
void point_reference_position(const Model& model, int elem, const double rst[3], double X[3]);

// Current position x = X + sum_k w_k u(dofnode_k); u is (ndofnode, 3).
void point_position(const PointWeights& w, const double X[3], const double* u, double x[3]);

}  // namespace incise
