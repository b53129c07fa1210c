// Newton's stop over the body (integrator.rotation_tolerance, rotation_fraction,
// rotation_rms; engine/dynamics/step.cpp decide_newton): the rotation change
// measured per slot, weighted by the slots' volumes, and the decisions it
// gives for a few turned points against a turned body.
#include <cmath>
#include <vector>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "engine/dynamics/state.h"
#include "engine/dynamics/step.h"
#include "engine/fem/assemble_parallel.h"
#include "engine/mesh/mesh_tools.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

Scene soft_cantilever() {
  Scene s = test::basic_scene(2, MaterialModel::Corotated);
  s.material.young = 1e4;
  s.material.density = 1.0;
  s.fixed.push_back(test::box_region({-1, -1, -1}, {0, 2, 2}));
  return s;
}

// Slot r's rotation set to the turn by `angle` about a fixed oblique axis.
void turn_slot(State& s, int r, double angle) {
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(angle, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  Eigen::Map<Eigen::Matrix3d>(&s.R[9 * static_cast<size_t>(r)]) = Q;  // column-major, as State::R
}

double body_volume(const Model& m) {
  double v = 0.0;
  for (double e : m.elem_volume) v += e;
  return v;
}

// A beam whose elements grow along it (x -> x (1 + x / 4): volumes
// differ, so a count of slots and their volumes give different means).
Mesh graded_beam() {
  Mesh mesh = make_beam(4.0, 0.5, 0.5, 8, 1, 1, 1);
  for (int a = 0; a < mesh.nnode(); ++a) mesh.X[3 * a] *= 1.0 + 0.25 * mesh.X[3 * a];
  return mesh;
}

// A rigid turn of the whole body by 0.7 rad (rotation_angle_to is exact
// beyond 0.5 rad, tests/engine/fem/test_polar.cpp) is 0.7 everywhere: max
// and RMS 0.7, every slot above 0.1, the slots' volumes summing to the
// body's. One element's slots turned alone (u = 0) give the RMS of 0.7 over
// that element's share of the volume.
TEST(RotationChange, MaxRmsAndTheVolumeAboveAreWeightedBySlotVolume) {
  const Model m = build_model(graded_beam(), soft_cantilever());
  State s;
  Workspace ws;
  init_state(m, s, ws);
  const double V = body_volume(m), angle = 0.7;
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(angle, Eigen::Vector3d(0, 1, 1).normalized()).toRotationMatrix();
  std::vector<double> u(m.ndof(), 0.0);
  for (int a = 0; a < m.nnode; ++a) {
    const Eigen::Vector3d X(m.X[3 * a], m.X[3 * a + 1], m.X[3 * a + 2]);
    const Eigen::Vector3d d = Q * X - X;
    for (int i = 0; i < 3; ++i) u[3 * a + i] = d[i];
  }
  const RotationChange rigid = rotation_change(m, ws.work.plan, *ws.work.pool, u.data(), s.R.data(), 0.1);
  EXPECT_NEAR(rigid.max, angle, 1e-9);
  EXPECT_NEAR(rigid.rms, angle, 1e-9);
  EXPECT_NEAR(rigid.volume, V, 1e-12 * V);
  EXPECT_NEAR(rigid.above, V, 1e-12 * V);

  std::fill(u.begin(), u.end(), 0.0);
  const int e = 5;
  for (int r = 0; r < m.nrot; ++r)
    if (m.rot_elem[r] == e) turn_slot(s, r, angle);
  const RotationChange one = rotation_change(m, ws.work.plan, *ws.work.pool, u.data(), s.R.data(), 0.1);
  const double share = m.elem_volume[e] / V;
  ASSERT_GT(std::abs(share * m.nelem - 1.0), 0.2) << "the element's share of the volume is not its share of the count";
  EXPECT_NEAR(one.max, angle, 1e-9);
  EXPECT_NEAR(one.rms, angle * std::sqrt(share), 1e-9);
  EXPECT_NEAR(one.above, m.elem_volume[e], 1e-12 * V);
  const RotationChange none = rotation_change(m, ws.work.plan, *ws.work.pool, u.data(), s.R.data(), 0.8);
  EXPECT_EQ(none.above, 0.0) << "no slot turned more than the threshold";
}

// decide_newton after one iteration (newton_iterations 1, cap 4) whose result
// is the rest shape while the frozen rotations are turned:
// - one element's slots by 0.5 rad: another iteration under the any-point
//   test (rotation_fraction 0), none once the fraction allowed is above the
//   element's share of the volume;
// - every slot by 0.05 rad (below rotation_tolerance 0.1): another iteration
//   while the RMS test is on below 0.05, none with it off or above.
TEST(NewtonStop, AFewTurnedPointsDoNotDecideAloneAndATurnedBodyDoes) {
  const Mesh mesh = make_beam(4.0, 0.5, 0.5, 8, 1, 1, 1);
  const auto done = [&](double fraction, double rms, int turned_elem, double angle) {
    Scene sc = soft_cantilever();
    sc.rotation_fraction = fraction;
    sc.rotation_rms = rms;
    const Model m = build_model(mesh, sc);
    State s;
    Workspace ws;
    init_state(m, s, ws);
    step(m, s, ws);  // the workspace as a step leaves it
    for (int d = 0; d < m.ndof(); ++d) ws.delta[d] = -s.u[d];  // the iteration's result: u + Delta = 0
    std::fill(s.R.begin(), s.R.end(), 0.0);
    for (int r = 0; r < m.nrot; ++r) {
      turn_slot(s, r, 0.0);
      if (turned_elem < 0 || m.rot_elem[r] == turned_elem) turn_slot(s, r, angle);
    }
    ws.newton_iterations_done = 1;
    decide_newton(m, s, ws);
    return ws.newton_done;
  };
  const Model m = build_model(mesh, soft_cantilever());
  const double share = m.elem_volume[5] / body_volume(m);
  ASSERT_GT(share, 1e-4) << "the default fraction is below one element of this coarse beam";
  EXPECT_FALSE(done(0.0, 0.0, 5, 0.5)) << "any point past 0.1 rad iterates";
  EXPECT_FALSE(done(0.5 * share, 0.0, 5, 0.5)) << "a share above the fraction allowed iterates";
  EXPECT_TRUE(done(2.0 * share, 0.0, 5, 0.5)) << "a share below the fraction allowed stops";
  EXPECT_FALSE(done(0.0, 0.02, -1, 0.05)) << "the body turned by 0.05 rad in the mean iterates";
  EXPECT_TRUE(done(0.0, 0.0, -1, 0.05)) << "below rotation_tolerance everywhere, RMS test off";
  EXPECT_TRUE(done(0.0, 0.06, -1, 0.05)) << "the mean below rotation_rms";
}

}  // namespace
}  // namespace incise
