// Cantilever under its own weight against Euler-Bernoulli: w(L) = q L^4 / (8 E I),
// q = rho g A. Slender (L/h = 20) with nu = 0 so shear (~0.2%) and Poisson
// clamping effects stay far below the 2% tolerance.
#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "engine/mesh/mesh_tools.h"
#include "engine/dynamics/step.h"
#include "engine/dynamics/static_solve.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

double tip_deflection(int order, RotationMode rot, MaterialModel mm, int nx, int nyz) {
  const double L = 20.0, h = 1.0;
  const Mesh mesh = make_beam(L, h, h, nx, nyz, nyz, 1);
  Scene s = test::basic_scene(order, mm, rot);
  s.material.young = 1e6;
  s.material.poisson = 0.0;
  s.material.density = 1.0;
  s.mass = MassKind::Consistent;
  s.gravity = {0.0, 0.0, -1.0};
  s.fixed.push_back(test::box_region({-1, -1, -1}, {0, 2, 2}));
  const Model m = build_model(mesh, s);
  State st; Workspace ws;
  init_state(m, st, ws);
  const StaticResult r = solve_static(m, st, ws, 1e-7, 60);
  std::printf("order %d nx %d: %d iterations, residual %.2e, shortened %d, smallest step %g, stalled %d:", order, nx,
              r.iterations, r.residual, r.shortened, r.smallest_step, r.stalled);
  for (double x : r.residuals) std::printf(" %.1e", x);
  std::printf("\n");
  EXPECT_TRUE(r.converged) << "residual " << r.residual;
  double w = 0;
  int cnt = 0;
  for (int n = 0; n < m.nnode; ++n)
    if (m.X[3 * n] > L - 1e-9) {
      w += st.u[3 * n + 2];
      ++cnt;
    }
  return w / cnt;
}

TEST(Cantilever, Tet10TipDeflectionWithin2PercentOfEulerBernoulli) {
  const double q = 1.0 * 1.0 * 1.0, E = 1e6, I = 1.0 / 12.0, L = 20.0;
  const double w_eb = -q * std::pow(L, 4) / (8 * E * I);  // -0.24 (1.2% of L)
  for (RotationMode rot : {RotationMode::PerPoint, RotationMode::Single}) {
    const double w = tip_deflection(2, rot, MaterialModel::Corotated, 20, 2);
    std::printf("tip deflection / Euler-Bernoulli = %.4f (%s)\n", w / w_eb, rot == RotationMode::Single ? "tet10SR" : "tet10");
    EXPECT_NEAR(w / w_eb, 1.0, 0.02) << "w = " << w << " Euler-Bernoulli " << w_eb;
  }
  const double wl = tip_deflection(2, RotationMode::PerPoint, MaterialModel::Linear, 20, 2);
  EXPECT_NEAR(wl / w_eb, 1.0, 0.02);
}

TEST(Cantilever, Tet4LocksOnTheSameMesh) {
  // The book's point (3.5.2): linear tets are far too stiff in bending at the
  // resolution where tet10 is already within 2%.
  const double w_eb = -1.0 * std::pow(20.0, 4) / (8 * 1e6 / 12.0);
  const double w4 = tip_deflection(1, RotationMode::PerPoint, MaterialModel::Corotated, 20, 2);
  EXPECT_LT(w4 / w_eb, 0.7);
  EXPECT_GT(w4 / w_eb, 0.0);
}

}  // namespace
}  // namespace incise
