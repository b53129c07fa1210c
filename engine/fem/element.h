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

// Maps a point of sub-tet `sub` (4 x 3 corners in an element's local
// coordinates; rst_q: the point's coordinates in the sub-tet, as a cubature
// gives them) to the element's local coordinates r.
inline void map_to_element(const double* sub, const double* rst_q, double* r) {
  const double L[4] = {1.0 - rst_q[0] - rst_q[1] - rst_q[2], rst_q[0], rst_q[1], rst_q[2]};
  for (int d = 0; d < 3; ++d) r[d] = L[0] * sub[d] + L[1] * sub[3 + d] + L[2] * sub[6 + d] + L[3] * sub[9 + d];
}

// Signed volume of a sub-tetrahedron given by its 4 corners v (4 x 3) in an
// element's local coordinates (the reference tetrahedron has 1/6).
inline double subtet_ref_volume(const double* v) {
  double a[3], b[3], c[3];
  for (int d = 0; d < 3; ++d) {
    a[d] = v[3 + d] - v[d];
    b[d] = v[6 + d] - v[d];
    c[d] = v[9 + d] - v[d];
  }
  return (a[0] * (b[1] * c[2] - b[2] * c[1]) - a[1] * (b[0] * c[2] - b[2] * c[0]) + a[2] * (b[0] * c[1] - b[1] * c[0])) / 6.0;
}

}  // namespace incise
