// initial: "static" (start_at_static_equilibrium): a soft corotated beam
// clamped at one end and hanging under gravity starts at equilibrium and
// stays there under the dynamics (Newmark keeps a state at rest with zero
// net force at rest), where the same beam released from its unstressed shape
// swings about it; a solve that cannot converge is an error naming the scene.
#include <gtest/gtest.h>

#include <cmath>

#include "engine/dynamics/static_solve.h"
#include "engine/dynamics/step.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/util/error.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

Scene hanging_beam() {
  Scene s = test::basic_scene(2);
  s.material.young = 1e5;
  s.material.poisson = 0.45;
  s.material.density = 1000;
  s.material.rayleigh_mass = 0.5;
  s.gravity = {0, 0, -9.81};
  s.fixed.push_back(test::box_region({-1e-9, -1, -1}, {1e-9, 1, 1}));
  s.consistent_tangent = true;
  return s;
}

double max_abs_diff(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0.0;
  for (size_t i = 0; i < a.size(); ++i) d = std::max(d, std::abs(a[i] - b[i]));
  return d;
}

TEST(InitialStatic, StartsAtEquilibriumAndStaysThere) {
  const Model m = build_model(make_beam(0.1, 0.04, 0.04, 4, 2, 2, 1), hanging_beam());
  State st; Workspace ws;
  init_state(m, st, ws);
  start_at_static_equilibrium(m, st, ws, 1e-8, 100, "beam.json");
  const std::vector<double> u0 = st.u;
  double sag = 0.0;
  for (double x : u0) sag = std::max(sag, std::abs(x));
  EXPECT_GT(sag, 1e-3) << "a soft beam sags under its own weight";
  for (double v : st.v) EXPECT_EQ(v, 0.0);
  double amax = 0.0;
  for (double a : st.a) amax = std::max(amax, std::abs(a));
  EXPECT_LT(amax, 1e-6 * 9.81) << "no net force left at equilibrium";
  for (int k = 0; k < 20; ++k) step(m, st, ws);
  EXPECT_LT(max_abs_diff(st.u, u0), 1e-6 * sag) << "the dynamics keeps the equilibrium";

  State rest; Workspace ws2;  // the same beam released from its unstressed shape swings
  init_state(m, rest, ws2);
  for (int k = 0; k < 20; ++k) step(m, rest, ws2);
  EXPECT_GT(max_abs_diff(rest.u, u0), 0.05 * sag);
}

TEST(InitialStatic, ASolveThatDoesNotConvergeIsAnErrorNamingTheScene) {
  const Model m = build_model(make_beam(0.1, 0.04, 0.04, 4, 2, 2, 1), hanging_beam());
  State st; Workspace ws;
  init_state(m, st, ws);
  try {
    start_at_static_equilibrium(m, st, ws, 1e-12, 1, "beam.json");
    FAIL() << "one iteration cannot reach 1e-12 on a sagging corotated beam";
  } catch (const Error& e) {
    const std::string msg = e.what();
    EXPECT_NE(msg.find("beam.json: initial \"static\": the static solve did not reach static.tolerance 1e-12 in 1 iterations"),
              std::string::npos)
        << msg;
  }
}

}  // namespace
}  // namespace incise
