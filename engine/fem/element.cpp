#include "engine/fem/element.h"

#include <cmath>
#include <stdexcept>

#include <Eigen/Dense>

#include "engine/mesh/mesh.h"

namespace incise {

namespace {
void barycentric(const double rst[3], double L[4]) {
  L[1] = rst[0];
  L[2] = rst[1];
  L[3] = rst[2];
  L[0] = 1.0 - rst[0] - rst[1] - rst[2];
}
// dL_k / d(r,s,t)
constexpr double kdL[4][3] = {{-1, -1, -1}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
}  // namespace

void shape_values(int npe, const double rst[3], double* N) {
  double L[4];
  barycentric(rst, L);
  if (npe == 4) {
    for (int k = 0; k < 4; ++k) N[k] = L[k];
    return;
  }
  for (int k = 0; k < 4; ++k) N[k] = L[k] * (2.0 * L[k] - 1.0);
  for (int e = 0; e < 6; ++e) N[4 + e] = 4.0 * L[kTet10Edge[e][0]] * L[kTet10Edge[e][1]];
}

void shape_local_gradients(int npe, const double rst[3], double* dN) {
  double L[4];
  barycentric(rst, L);
  if (npe == 4) {
    for (int k = 0; k < 4; ++k)
      for (int d = 0; d < 3; ++d) dN[3 * k + d] = kdL[k][d];
    return;
  }
  for (int k = 0; k < 4; ++k)
    for (int d = 0; d < 3; ++d) dN[3 * k + d] = (4.0 * L[k] - 1.0) * kdL[k][d];
  for (int e = 0; e < 6; ++e) {
    const int i = kTet10Edge[e][0], j = kTet10Edge[e][1];
    for (int d = 0; d < 3; ++d) dN[3 * (4 + e) + d] = 4.0 * (kdL[i][d] * L[j] + L[i] * kdL[j][d]);
  }
}

const Cubature& cubature_tet1() {
  static const Cubature c{{0.25, 0.25, 0.25}, {1.0 / 6.0}};
  return c;
}

const Cubature& cubature_tet4() {
  // Degree-2 rule: barycentric (b, a, a, a) and permutations,
  // a = (5 - sqrt 5) / 20, b = (5 + 3 sqrt 5) / 20, equal weights.
  static const Cubature c = [] {
    const double a = (5.0 - std::sqrt(5.0)) / 20.0, b = (5.0 + 3.0 * std::sqrt(5.0)) / 20.0;
    Cubature r;
    r.rst = {a, a, a, b, a, a, a, b, a, a, a, b};
    r.weight = {1.0 / 24, 1.0 / 24, 1.0 / 24, 1.0 / 24};
    return r;
  }();
  return c;
}

namespace {
// n-point Gauss-Legendre on [0, 1] by Newton on P_n.
void gauss_legendre01(int n, std::vector<double>& x, std::vector<double>& w) {
  x.assign(n, 0.0);
  w.assign(n, 0.0);
  for (int i = 0; i < n; ++i) {
    double z = std::cos(M_PI * (i + 0.75) / (n + 0.5)), dp = 0.0;
    for (int it = 0; it < 100; ++it) {
      double p0 = 1.0, p1 = z;
      for (int k = 2; k <= n; ++k) {
        const double p2 = ((2.0 * k - 1.0) * z * p1 - (k - 1.0) * p0) / k;
        p0 = p1;
        p1 = p2;
      }
      const double pn = n == 1 ? z : p1, pnm1 = n == 1 ? 1.0 : p0;
      dp = n * (z * pn - pnm1) / (z * z - 1.0);
      const double dz = pn / dp;
      z -= dz;
      if (std::abs(dz) < 1e-16) break;
    }
    x[i] = 0.5 * (1.0 - z);
    w[i] = 1.0 / ((1.0 - z * z) * dp * dp);  // = 2/((1-z^2)P'^2) / 2
  }
}
}  // namespace

Cubature cubature_duffy(int degree) {
  // x = u, y = v (1 - u), z = w (1 - u)(1 - v), |J| = (1 - u)^2 (1 - v):
  // a degree-p polynomial becomes degree p+2 in u, so n points with 2n-1 >= p+2.
  const int n = std::max(1, (degree + 4) / 2);
  std::vector<double> g, gw;
  gauss_legendre01(n, g, gw);
  Cubature c;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j)
      for (int k = 0; k < n; ++k) {
        const double u = g[i], v = g[j], w = g[k];
        c.rst.insert(c.rst.end(), {u, v * (1 - u), w * (1 - u) * (1 - v)});
        c.weight.push_back(gw[i] * gw[j] * gw[k] * (1 - u) * (1 - u) * (1 - v));
      }
  return c;
}

double shape_global_gradients(int npe, const double* Xe, const double rst[3], double* dNdX) {
  double dN[30];
  shape_local_gradients(npe, rst, dN);
  Eigen::Matrix3d J = Eigen::Matrix3d::Zero();  // J_ij = dX_i / dr_j
  for (int a = 0; a < npe; ++a)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) J(i, j) += Xe[3 * a + i] * dN[3 * a + j];
  const double det = J.determinant();
  const Eigen::Matrix3d JinvT = J.inverse().transpose();
  for (int a = 0; a < npe; ++a) {
    const Eigen::Vector3d g = JinvT * Eigen::Vector3d(dN[3 * a], dN[3 * a + 1], dN[3 * a + 2]);
    for (int d = 0; d < 3; ++d) dNdX[3 * a + d] = g[d];
  }
  return det;
}

}  // namespace incise
