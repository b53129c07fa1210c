#pragma once
// Reference tetrahedra: shape functions, their gradients, cubature rules.
//
// Local coordinates are the barycentric (L0, L1, L2, L3) with L0 = 1 - r - s - t
// and (r, s, t) = (L1, L2, L3), so corner k sits where Lk = 1. Node ordering
// as in engine/mesh/mesh.h (VTK). Shape functions of the book's appendix A.4
// (eq. A.14-A.28) with the numbering mapped to ours:
//   tet4:  N_k = L_k
//   tet10: corners N_k = L_k (2 L_k - 1); mid-edge (i,j): N = 4 L_i L_j.
#include <vector>

namespace incise {

// Values of the npe shape functions at local point (r, s, t).
void shape_values(int npe, const double rst[3], double* N /* (npe) */);
// d N_a / d(r, s, t) at (r, s, t).
void shape_local_gradients(int npe, const double rst[3], double* dN /* (npe, 3) */);

struct Cubature {
  std::vector<double> rst;     // (npoint, 3) local coordinates
  std::vector<double> weight;  // (npoint) weights summing to 1/6 (reference volume)
  int npoint() const { return static_cast<int>(weight.size()); }
};

// 1 point (degree 1), the 4-point rule (degree 2) the book uses for tet10
// stiffness, or a collapsed Gauss-Legendre (Duffy) product rule exact to the
// given degree (used for mass matrices and reference integrals).
const Cubature& cubature_tet1();
const Cubature& cubature_tet4();
Cubature cubature_duffy(int degree);

// Jacobian of the isoparametric map at a local point (book eq. A.32, transposed
// to J_ij = dX_i / d r_j) and the global gradients dN_a/dX = J^-T dN_a/dr
// (eq. A.31). Returns det J.
double shape_global_gradients(int npe, const double* Xe /* (npe, 3) */, const double rst[3],
                              double* dNdX /* (npe, 3) */);

}  // namespace incise
