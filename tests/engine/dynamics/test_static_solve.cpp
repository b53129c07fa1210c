// The static solve (engine/dynamics/static_solve.h): Newton on the exact
// corotated tangent converges quadratically; the line search keeps a step
// that overshoots from raising the energy; its report says what it did.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "engine/dynamics/static_solve.h"
#include "engine/dynamics/step.h"
#include "engine/mesh/mesh_tools.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

// A corotated tet10 cantilever (per-point rotations) bent by its weight to a
// tip deflection of about a quarter of its length: geometrically nonlinear.
StaticResult solve_cantilever(double g, double tolerance) {
  Scene s = test::basic_scene(2, MaterialModel::Corotated, RotationMode::PerPoint);
  s.material.young = 1e6;
  s.material.poisson = 0.3;
  s.material.density = 1.0;
  s.gravity = {0.0, 0.0, -g};
  s.fixed.push_back(test::box_region({-1, -1, -1}, {0, 2, 2}));
  const Model m = build_model(make_beam(20.0, 1.0, 1.0, 20, 2, 2, 1), s);
  State st;
  Workspace ws;
  init_state(m, st, ws);
  const StaticResult r = solve_static(m, st, ws, tolerance, 40);
  double tip = 0.0;
  for (int n = 0; n < m.nnode; ++n)
    if (m.X[3 * n] > 20.0 - 1e-9) tip = std::min(tip, st.u[3 * n + 2]);
  std::printf("g %g: tip %.3f; %s\n", g, tip, static_report(r).c_str());
  return r;
}

// Quadratic: once the relative residual is below 1e-2, each iteration
// squares it (r_{k+1} <= 10 r_k^2), checked while r_{k+1} > 2e-9: roundoff
// in f_int (the strain's, about eps, times E h^2) leaves the residual at
// 5e-10 of the weight at g = 1. Before the strain was formed from
// displacement gradients (assemble_parallel.cpp, add_identity) it left 4e-8
// and the check stopped at 1e-8. At g = 20 (tip deflection
// 23% of the length, from rest) the first 11 iterations find the basin. A frozen-rotation
// tangent (the previous solve) gives r_{k+1} ~ 0.1-0.5 r_k there, and so
// does a tangent that drops the compressed rotation modes (the dynamics'
// projected one) on this beam, half of which is compressed.
TEST(StaticSolve, NewtonConvergesQuadraticallyOnACorotatedCantilever) {
  for (double g : {1.0, 20.0}) {
    const StaticResult r = solve_cantilever(g, 2e-9);
    ASSERT_TRUE(r.converged) << "g = " << g << ": " << static_report(r);
    int checked = 0;
    for (size_t k = 0; k + 1 < r.residuals.size(); ++k) {
      const double a = r.residuals[k], b = r.residuals[k + 1];
      if (a < 1e-2 && b > 2e-9) {
        EXPECT_LE(b, 10.0 * a * a) << "g = " << g << ", iteration " << k << ": " << static_report(r);
        ++checked;
      }
    }
    EXPECT_GE(checked, 1) << "no iteration in the quadratic range: " << static_report(r);
    EXPECT_LE(r.iterations, g < 2.0 ? 4 : 16) << static_report(r);
    EXPECT_EQ(r.stalled, 0);
  }
}

// The report names the tolerance-independent facts (residuals, line search).
// The advice of an unconverged solve reads its residuals: still falling,
// more iterations; stalled low (a stiff beam at E = 1e8 stops at 2.5e-8 of
// the load, its forces cancelling to roundoff), a looser tolerance; stalled
// high (E = 100 Pa under its weight: 1 -> 15 and no lower in 200
// iterations), no equilibrium near the start. It used to say "raise
// static.max_iterations" in all three.
TEST(StaticSolve, AdviceForAnUnconvergedSolveFollowsItsResiduals) {
  StaticResult falling, floor, high;
  falling.residuals = {1, 1e-2, 1e-4, 1e-6, 1e-7};
  floor.residuals = {1, 1.4, 2.8e-8, 2.4e-8, 2.4e-8, 2.1e-8, 2.9e-8, 2.7e-8};
  high.residuals = {1, 15, 12, 14, 9.4, 11, 13, 10};
  EXPECT_NE(static_failure_advice(falling).find("raise static.max_iterations"), std::string::npos);
  const std::string f = static_failure_advice(floor), h = static_failure_advice(high);
  EXPECT_NE(f.find("stopped falling at 2.1e-08, near double precision's floor"), std::string::npos) << f;
  EXPECT_NE(f.find("loosen static.tolerance to about 8e-08"), std::string::npos) << f;
  EXPECT_EQ(f.find("raise static.max_iterations"), std::string::npos) << f;
  EXPECT_NE(h.find("stopped falling at 9.4e+00: no equilibrium was found near the start"), std::string::npos) << h;
  EXPECT_EQ(h.find("raise static.max_iterations"), std::string::npos) << h;
}

// A steel cantilever (E = 2e11 Pa, 7800 kg/m^3, 0.2 x 0.02 x 0.02 m) under
// its weight, at the origin and 100 m from it (a scanner's or a CAD
// model's coordinates). The strain is formed from displacement gradients
// (assemble_parallel.cpp, add_identity), so its roundoff does not grow with
// E / (rho g h) or with |X| / h: both converge to the default tolerance
// 1e-8, to the same tip deflection within 1e-9 of it. Before, with forces
// summed from positions, the solve stalled at 2.6e-6 of the load at the
// origin and at 2e-3 100 m away.
TEST(StaticSolve, AStiffBodyFarFromTheOriginConvergesToTheDefaultTolerance) {
  double tips[2] = {0.0, 0.0};
  for (int far = 0; far < 2; ++far) {
    const double shift = far ? 100.0 : 0.0;
    Scene s = test::basic_scene(2, MaterialModel::Corotated, RotationMode::PerPoint);
    s.material.young = 2e11;
    s.material.poisson = 0.3;
    s.material.density = 7800.0;
    s.gravity = {0.0, 0.0, -9.81};
    s.fixed.push_back(test::box_region({shift - 1e-9, -1, -1}, {shift + 1e-9, 1, 1}));
    Mesh mesh = make_beam(0.2, 0.02, 0.02, 10, 2, 2, 1);
    for (size_t i = 0; i < mesh.X.size(); i += 3) mesh.X[i] += shift;
    const Model m = build_model(mesh, s);
    State st;
    Workspace ws;
    init_state(m, st, ws);
    const StaticResult r = solve_static(m, st, ws, 1e-8, 10);
    EXPECT_TRUE(r.converged) << "shift " << shift << ": " << static_report(r);
    EXPECT_LE(r.iterations, 4) << static_report(r);
    for (int n = 0; n < m.nnode; ++n)
      if (m.X[3 * n] > shift + 0.2 - 1e-9) tips[far] = std::min(tips[far], st.u[3 * n + 2]);
  }
  // Euler-Bernoulli under its weight: q L^4 / (8 E I) = 2.30e-6 m (shear and
  // the tet10 mesh make it a little larger).
  EXPECT_NEAR(tips[0], -2.30e-6, 0.1e-6);
  EXPECT_NEAR(tips[1], tips[0], 1e-9 * std::abs(tips[0]));
}

TEST(StaticSolve, ReportListsTheResidualsAndTheLineSearch) {
  const StaticResult r = solve_cantilever(1.0, 1e-7);
  ASSERT_TRUE(r.converged);
  const std::string s = static_report(r);
  EXPECT_NE(s.find("residuals 1.0e+00"), std::string::npos) << s;
  EXPECT_NE(s.find("line search shortened"), std::string::npos) << s;
  EXPECT_EQ(r.residuals.size(), static_cast<size_t>(r.iterations) + 1);
}

}  // namespace
}  // namespace incise
