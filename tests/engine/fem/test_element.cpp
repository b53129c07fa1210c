// Reference element: shape functions, gradients and cubature rules.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "engine/fem/element.h"
#include "engine/mesh/mesh.h"

namespace incise {
namespace {

const double kCorners[4][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};

TEST(Element, ShapeFunctionsAreNodalAndPartitionOfUnity) {
  for (int npe : {4, 10}) {
    for (int k = 0; k < npe; ++k) {
      double rst[3];
      if (k < 4) {
        for (int d = 0; d < 3; ++d) rst[d] = kCorners[k][d];
      } else {
        const int i = kTet10Edge[k - 4][0], j = kTet10Edge[k - 4][1];
        for (int d = 0; d < 3; ++d) rst[d] = 0.5 * (kCorners[i][d] + kCorners[j][d]);
      }
      double N[10];
      shape_values(npe, rst, N);
      for (int a = 0; a < npe; ++a) EXPECT_NEAR(N[a], a == k ? 1.0 : 0.0, 1e-15) << npe << " node " << k;
    }
    const double p[3] = {0.1, 0.2, 0.3};
    double N[10], dN[30];
    shape_values(npe, p, N);
    shape_local_gradients(npe, p, dN);
    double sum = 0, gsum[3] = {0, 0, 0};
    for (int a = 0; a < npe; ++a) {
      sum += N[a];
      for (int d = 0; d < 3; ++d) gsum[d] += dN[3 * a + d];
    }
    EXPECT_NEAR(sum, 1.0, 1e-15);
    for (double g : gsum) EXPECT_NEAR(g, 0.0, 1e-14);
  }
}

TEST(Element, LocalGradientsMatchFiniteDifferences) {
  const double p[3] = {0.21, 0.17, 0.33}, h = 1e-6;
  double dN[30];
  shape_local_gradients(10, p, dN);
  for (int d = 0; d < 3; ++d) {
    double pp[3] = {p[0], p[1], p[2]}, pm[3] = {p[0], p[1], p[2]}, Np[10], Nm[10];
    pp[d] += h;
    pm[d] -= h;
    shape_values(10, pp, Np);
    shape_values(10, pm, Nm);
    for (int a = 0; a < 10; ++a) EXPECT_NEAR(dN[3 * a + d], (Np[a] - Nm[a]) / (2 * h), 1e-8);
  }
}

// Exact integral over the reference tet: int r^i s^j t^k = i! j! k! / (i+j+k+3)!
double exact_monomial(int i, int j, int k) {
  return std::tgamma(i + 1) * std::tgamma(j + 1) * std::tgamma(k + 1) / std::tgamma(i + j + k + 4);
}
double integrate(const Cubature& c, int i, int j, int k) {
  double s = 0;
  for (int q = 0; q < c.npoint(); ++q)
    s += c.weight[q] * std::pow(c.rst[3 * q], i) * std::pow(c.rst[3 * q + 1], j) * std::pow(c.rst[3 * q + 2], k);
  return s;
}

TEST(Element, CubatureRulesAreExactToTheirDegree) {
  struct Case { Cubature c; int degree; };
  const Case cases[] = {{cubature_tet1(), 1}, {cubature_tet4(), 2}, {cubature_duffy(4), 4}, {cubature_duffy(7), 7}};
  for (const auto& cs : cases)
    for (int i = 0; i <= cs.degree; ++i)
      for (int j = 0; i + j <= cs.degree; ++j)
        for (int k = 0; i + j + k <= cs.degree; ++k)
          EXPECT_NEAR(integrate(cs.c, i, j, k), exact_monomial(i, j, k), 1e-15)
              << "degree " << cs.degree << " monomial " << i << j << k;
  // and the 4-point rule is not exact at degree 3 (so the test above can fail)
  EXPECT_GT(std::abs(integrate(cubature_tet4(), 3, 0, 0) - exact_monomial(3, 0, 0)), 1e-5);
}

TEST(Element, GlobalGradientsReproduceLinearFieldOnCurvedTet10) {
  // A curved tet10 (mid-edge nodes moved off the chords) still reproduces a
  // linear field exactly: sum_a (c . X_a) grad N_a = c (isoparametric property).
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> U(-0.05, 0.05);
  double Xe[30];
  for (int a = 0; a < 4; ++a)
    for (int d = 0; d < 3; ++d) Xe[3 * a + d] = kCorners[a][d] * 2.0;
  for (int e = 0; e < 6; ++e)
    for (int d = 0; d < 3; ++d)
      Xe[3 * (4 + e) + d] = 0.5 * (Xe[3 * kTet10Edge[e][0] + d] + Xe[3 * kTet10Edge[e][1] + d]) + U(rng);
  const double c[3] = {0.3, -1.1, 2.0};
  const double p[3] = {0.2, 0.3, 0.1};
  double g[30];
  ASSERT_GT(shape_global_gradients(10, Xe, p, g), 0.0);
  double grad[3] = {0, 0, 0};
  for (int a = 0; a < 10; ++a) {
    const double val = c[0] * Xe[3 * a] + c[1] * Xe[3 * a + 1] + c[2] * Xe[3 * a + 2];
    for (int d = 0; d < 3; ++d) grad[d] += val * g[3 * a + d];
  }
  for (int d = 0; d < 3; ++d) EXPECT_NEAR(grad[d], c[d], 1e-13);
}

}  // namespace
}  // namespace incise
