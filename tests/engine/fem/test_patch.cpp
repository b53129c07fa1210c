// Patch tests: boundary nodes prescribed from an exact field, interior nodes
// must reproduce it. tet4 and tet10: linear fields; tet10: a quadratic field
// with the constant body force that equilibrates it.
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "engine/mesh/mesh_tools.h"
#include "engine/dynamics/state.h"
#include "engine/dynamics/static_solve.h"
#include "engine/dynamics/step.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

// A 3x3x3-cell cube with interior corner nodes jittered (straight tet edges kept).
Mesh distorted_cube() {
  Mesh m = make_beam(1.0, 1.0, 1.0, 3, 3, 3, 1);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-0.08, 0.08);
  for (int n = 0; n < m.nnode(); ++n) {
    bool interior = true;
    for (int d = 0; d < 3; ++d) interior = interior && m.X[3 * n + d] > 1e-9 && m.X[3 * n + d] < 1 - 1e-9;
    if (interior)
      for (int d = 0; d < 3; ++d) m.X[3 * n + d] += U(rng);
  }
  return m;
}

using Field = void (*)(const double* X, double* u);

// Static linear solve with every boundary node prescribed from `field`; returns
// max nodal error over all nodes relative to max |u|.
double patch_error(int order, Field field, Vec3 gravity) {
  const Mesh mesh = distorted_cube();
  Scene s = test::basic_scene(order, MaterialModel::Linear);
  s.mass = MassKind::Consistent;  // f = M g is the consistent body-force load
  s.gravity = gravity;
  // prescribe boundary nodes through a node-list region per component
  const Mesh used = order == 2 ? raise_to_tet10(mesh) : mesh;
  Region r;
  r.kind = Region::Kind::Nodes;
  r.json_path = "prescribed[0]";
  for (int n = 0; n < used.nnode(); ++n) {
    bool boundary = false;
    for (int d = 0; d < 3; ++d)
      boundary = boundary || used.X[3 * n + d] < 1e-9 || used.X[3 * n + d] > 1 - 1e-9;
    if (boundary) {
      double u[3];
      field(&used.X[3 * n], u);
      for (int d = 0; d < 3; ++d) {
        Prescribed p;
        p.region = r;
        p.region.nodes = {n};
        p.active[d] = true;
        p.displacement[d] = u[d];
        s.prescribed.push_back(p);
      }
    }
  }
  const Model m = build_model(mesh, s);
  State st; Workspace ws;
  init_state(m, st, ws);
  const StaticResult res = solve_static(m, st, ws, 1e-12, 3);
  EXPECT_TRUE(res.converged);
  double err = 0, umax = 0;
  for (int n = 0; n < m.nnode; ++n) {
    double u[3];
    field(&m.X[3 * n], u);
    for (int d = 0; d < 3; ++d) {
      err = std::max(err, std::abs(st.u[3 * n + d] - u[d]));
      umax = std::max(umax, std::abs(u[d]));
    }
  }
  return err / umax;
}

void linear_field(const double* X, double* u) {
  u[0] = 0.01 + 0.02 * X[0] - 0.03 * X[1] + 0.015 * X[2];
  u[1] = -0.02 + 0.01 * X[0] + 0.025 * X[1] - 0.01 * X[2];
  u[2] = 0.005 - 0.02 * X[0] + 0.01 * X[1] + 0.03 * X[2];
}

// u = k (x^2 + y z, x y, z^2): div u = 3x + 2z, Laplacian = k (2, 0, 2).
constexpr double kQ = 0.01;
void quadratic_field(const double* X, double* u) {
  u[0] = kQ * (X[0] * X[0] + X[1] * X[2]);
  u[1] = kQ * X[0] * X[1];
  u[2] = kQ * X[2] * X[2];
}

TEST(Patch, LinearFieldIsExactForTet4AndTet10) {
  EXPECT_LT(patch_error(1, linear_field, {0, 0, 0}), 1e-10);
  EXPECT_LT(patch_error(2, linear_field, {0, 0, 0}), 1e-10);
}

TEST(Patch, QuadraticFieldIsExactForTet10Only) {
  // Equilibrium div(sigma) + rho g = 0 with div(sigma) = (lambda + mu) grad(div u) + mu Lap(u)
  //   = k ((lambda + mu) (3, 0, 2) + mu (2, 0, 2)), rho = 1.
  const Scene s = test::basic_scene(2);
  const double E = s.material.young, nu = s.material.poisson;
  const double mu = E / (2 * (1 + nu)), lambda = E * nu / ((1 + nu) * (1 - 2 * nu));
  const Vec3 g = {-kQ * (3 * (lambda + mu) + 2 * mu), 0.0, -kQ * (2 * (lambda + mu) + 2 * mu)};
  EXPECT_LT(patch_error(2, quadratic_field, g), 1e-10);
  // tet4 cannot represent it: the same test fails by far (so the check has teeth)
  EXPECT_GT(patch_error(1, quadratic_field, g), 1e-3);
}

}  // namespace
}  // namespace incise
