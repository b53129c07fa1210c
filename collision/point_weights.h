#pragma once
// The DOF nodes that move a material point of the tissue, and by how much.
// In piece P of element e ([preprint] eq. (42) in the per-piece form of
// engine/model/cut_layout.h)
//   x(rst) = X(rst) + sum_a N_a(rst) (u_a + q_enr(P,a)),
// so the point moves with weight N_a on mesh node a and with the same weight
// on P's enriched DOF node at a, when it has one. Another piece's enriched
// DOF nodes never appear: a point on one side of a cut moves with that side.
// Used by the collision surface (per vertex), its contacts and grasps.
#include "engine/model/model.h"

namespace incise {

struct PointWeights {
  static constexpr int kMax = 20;  // 2 npe for tet10: every node standard and enriched
  int n = 0;
  int dofnode[kMax];   // DOF node (dof = 3 dofnode + c), mesh nodes < model.nnode <= enriched
  double weight[kMax];
};

// Shape-function values below this are dropped: they are the exact zeros of
// the nodes off a face (L_k = 0 up to roundoff in rst), not motion.
inline constexpr double kWeightDrop = 1e-14;

// Weights of local point rst of element elem, in piece `piece` (-1: a model
// without cuts, or the element's standard field only).
PointWeights point_dof_weights(const Model& model, int elem, int piece, const double rst[3]);
// The same from the element's npe mesh nodes and its piece's enriched DOF
// nodes (npe entries, -1 = none; nullptr = no piece).
PointWeights point_dof_weights(int npe, const int* nodes, const int* enr, const double rst[3]);

// Reference position X(rst) = sum_a N_a(rst) X_a of the point.
void point_reference_position(const Model& model, int elem, const double rst[3], double X[3]);

// Current position x = X + sum_k w_k u(dofnode_k); u is (ndofnode, 3).
void point_position(const PointWeights& w, const double X[3], const double* u, double x[3]);

}  // namespace incise
