// Convergence under refinement against an analytic solution: linear
// elasticity on the unit cube, u = A (phi, phi, phi) with
// phi = sin(pi x) sin(pi y) sin(pi z) (zero on the boundary), loaded by the
// body force b = -div sigma(u). L2 displacement error orders: tet10 ~ 3,
// tet4 ~ 2; required >= 2.5 and >= 1.5.
#include <cmath>

#include <gtest/gtest.h>

#include "engine/fem/element.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/dynamics/step.h"
#include "engine/dynamics/static_solve.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

constexpr double kA = 0.01;

void exact(const double* X, double* u) {
  const double phi = std::sin(M_PI * X[0]) * std::sin(M_PI * X[1]) * std::sin(M_PI * X[2]);
  u[0] = u[1] = u[2] = kA * phi;
}

// b = -[(lambda + mu) grad(div u) + mu Lap(u)], div u = A (phi_x + phi_y + phi_z).
void body_force(const double* X, double lambda, double mu, double* b) {
  const double p = M_PI, sx = std::sin(p * X[0]), sy = std::sin(p * X[1]), sz = std::sin(p * X[2]);
  const double cx = std::cos(p * X[0]), cy = std::cos(p * X[1]), cz = std::cos(p * X[2]);
  const double phi = sx * sy * sz;
  // second derivatives H_ij of phi
  const double H[3][3] = {{-p * p * phi, p * p * cx * cy * sz, p * p * cx * sy * cz},
                          {p * p * cx * cy * sz, -p * p * phi, p * p * sx * cy * cz},
                          {p * p * cx * sy * cz, p * p * sx * cy * cz, -p * p * phi}};
  for (int i = 0; i < 3; ++i) {
    const double grad_div = kA * (H[i][0] + H[i][1] + H[i][2]);
    const double lap = kA * (-3 * p * p * phi);
    b[i] = -((lambda + mu) * grad_div + mu * lap);
  }
}

double l2_error(int order, int n) {
  const Mesh mesh = make_beam(1, 1, 1, n, n, n, 1);
  Scene s = test::basic_scene(order, MaterialModel::Linear);
  for (int d = 0; d < 3; ++d) {
    Vec3 lo{-1, -1, -1}, hi{2, 2, 2};
    hi[d] = 0.0;
    s.fixed.push_back(test::box_region(lo, hi));
    lo = {-1, -1, -1};
    hi = {2, 2, 2};
    lo[d] = 1.0;
    s.fixed.push_back(test::box_region(lo, hi));
  }
  Model m = build_model(mesh, s);
  // consistent load of the body force, integrated exactly enough (degree 8)
  const Cubature cub = cubature_duffy(8);
  const int npe = m.mesh.npe();
  std::fill(m.f_gravity.begin(), m.f_gravity.end(), 0.0);
  std::vector<double> Xe(3 * npe), N(npe), g(3 * npe);
  auto position = [&](const double* rst, double* x) {
    shape_values(npe, rst, N.data());
    x[0] = x[1] = x[2] = 0;
    for (int a = 0; a < npe; ++a)
      for (int d = 0; d < 3; ++d) x[d] += N[a] * Xe[3 * a + d];
  };
  for (int e = 0; e < m.nelem; ++e) {
    const int* nodes = &m.mesh.tet[e * npe];
    for (int a = 0; a < npe; ++a)
      for (int d = 0; d < 3; ++d) Xe[3 * a + d] = m.X[3 * nodes[a] + d];
    for (int q = 0; q < cub.npoint(); ++q) {
      const double w = cub.weight[q] * shape_global_gradients(npe, Xe.data(), &cub.rst[3 * q], g.data());
      double x[3], b[3];
      position(&cub.rst[3 * q], x);
      body_force(x, m.lambda, m.mu, b);
      for (int a = 0; a < npe; ++a)
        for (int d = 0; d < 3; ++d) m.f_gravity[3 * nodes[a] + d] += w * N[a] * b[d];
    }
  }
  State st; Workspace ws;
  init_state(m, st, ws);
  EXPECT_TRUE(solve_static(m, st, ws, 1e-12, 2).converged);
  double err2 = 0;
  for (int e = 0; e < m.nelem; ++e) {
    const int* nodes = &m.mesh.tet[e * npe];
    for (int a = 0; a < npe; ++a)
      for (int d = 0; d < 3; ++d) Xe[3 * a + d] = m.X[3 * nodes[a] + d];
    for (int q = 0; q < cub.npoint(); ++q) {
      const double w = cub.weight[q] * shape_global_gradients(npe, Xe.data(), &cub.rst[3 * q], g.data());
      double x[3], ue[3], uh[3] = {0, 0, 0};
      position(&cub.rst[3 * q], x);
      exact(x, ue);
      for (int a = 0; a < npe; ++a)
        for (int d = 0; d < 3; ++d) uh[d] += N[a] * st.u[3 * nodes[a] + d];
      for (int d = 0; d < 3; ++d) err2 += w * (uh[d] - ue[d]) * (uh[d] - ue[d]);
    }
  }
  return std::sqrt(err2);
}

TEST(Convergence, Tet10L2OrderAtLeast2p5) {
  const double e1 = l2_error(2, 3), e2 = l2_error(2, 6);
  const double order = std::log(e1 / e2) / std::log(2.0);
  RecordProperty("tet10_order", std::to_string(order));
  std::printf("tet10 L2 error h=1/3: %.3e  h=1/6: %.3e  order %.2f\n", e1, e2, order);
  EXPECT_GE(order, 2.5);
}

TEST(Convergence, Tet4L2OrderAtLeast1p5) {
  const double e1 = l2_error(1, 4), e2 = l2_error(1, 8);
  const double order = std::log(e1 / e2) / std::log(2.0);
  std::printf("tet4 L2 error h=1/4: %.3e  h=1/8: %.3e  order %.2f\n", e1, e2, order);
  EXPECT_GE(order, 1.5);
}

}  // namespace
}  // namespace incise
