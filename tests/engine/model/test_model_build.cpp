// Precomputed model: stiffness symmetry and rigid modes, mass sums, pattern.
#include <cmath>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include "engine/fem/assemble.h"
#include "engine/util/error.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/model/model.h"
#include "engine/dynamics/state.h"
#include "engine/dynamics/step.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

Mesh one_tet(int order) {
  Mesh m;
  m.order = 1;
  // a generic (not right-angled) tetrahedron
  m.X = {0.1, 0.0, 0.0, 1.2, 0.1, 0.0, 0.3, 0.9, 0.1, 0.2, 0.3, 1.1};
  m.tet = {0, 1, 2, 3};
  return order == 2 ? raise_to_tet10(m) : m;
}

TEST(Model, ElementStiffnessIsSymmetricWithExactlySixZeroModes) {
  for (int order : {1, 2})
    for (RotationMode rot : {RotationMode::PerPoint, RotationMode::Single}) {
      const Model m = build_model(one_tet(order), test::basic_scene(order, MaterialModel::Corotated, rot));
      const Eigen::MatrixXd K = test::dense(m, m.K0_csc);
      EXPECT_EQ(K.rows(), order == 2 ? 30 : 12);
      Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(K);
      const Eigen::VectorXd ev = es.eigenvalues();  // ascending
      const double top = ev.maxCoeff();
      for (int k = 0; k < 6; ++k) EXPECT_LT(std::abs(ev[k]), 1e-11 * top) << "order " << order;
      EXPECT_GT(ev[6], 1e-4 * top) << "order " << order << ": a spurious zero-energy mode";
      // the pattern's upper triangle really is the whole symmetric matrix: K u for
      // a random u from the dense and the sparse product agree
      Eigen::VectorXd u = Eigen::VectorXd::Random(K.rows()), y(K.rows());
      sym_matvec(m, m.K0_csc.data(), u.data(), y.data());
      EXPECT_LT((y - K * u).norm(), 1e-12 * (K * u).norm());
    }
}

TEST(Model, MassesArePositiveAndSumToRhoV) {
  const Mesh beam = make_beam(2.0, 0.5, 0.25, 4, 2, 2, 1);
  for (int order : {1, 2})
    for (MassKind mk : {MassKind::Lumped, MassKind::Consistent}) {
      Scene s = test::basic_scene(order);
      s.material.density = 7.5;
      s.mass = mk;
      const Model m = build_model(beam, s);
      const double expected = 7.5 * 2.0 * 0.5 * 0.25;
      double lumped = 0.0, minm = 1e300;
      for (int d = 0; d < m.ndof(); d += 3) {
        lumped += m.mass_lumped[d];
        minm = std::min(minm, m.mass_lumped[d]);
      }
      EXPECT_NEAR(lumped, expected, 1e-12 * expected);
      EXPECT_GT(minm, 0.0);
      if (order == 2) {  // HRZ on a straight tet10: corner 1/36, mid-edge 4/27 of the element mass
        const double ratio = m.mass_lumped[3 * m.mesh.tet[4]] / m.mass_lumped[3 * m.mesh.tet[0]];
        EXPECT_GT(ratio, 1.0);
      }
      if (mk == MassKind::Consistent) {
        // 1' M 1 per component = total mass; M symmetric positive definite
        const Eigen::MatrixXd M = test::dense(m, m.mass_csc);
        Eigen::VectorXd ones = Eigen::VectorXd::Zero(m.ndof());
        for (int d = 0; d < m.ndof(); d += 3) ones[d] = 1.0;
        EXPECT_NEAR(ones.dot(M * ones), expected, 1e-12 * expected);
        Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> es(M, Eigen::EigenvaluesOnly);
        EXPECT_GT(es.eigenvalues().minCoeff(), 0.0);
      }
      // f_gravity = M g sums to the weight
      s.gravity = {0.0, 0.0, -9.81};
      const Model mg = build_model(beam, s);
      double fz = 0.0;
      for (int d = 2; d < mg.ndof(); d += 3) fz += mg.f_gravity[d];
      EXPECT_NEAR(fz, -9.81 * expected, 1e-11 * 9.81 * expected);
    }
}

TEST(Model, Tet10HrzLumpingOfOneStraightElement) {
  Scene s = test::basic_scene(2);
  const Model m = build_model(one_tet(2), s);
  const double V = m.elem_volume[0];
  for (int a = 0; a < 10; ++a)
    EXPECT_NEAR(m.mass_lumped[3 * a], a < 4 ? V / 36.0 : 4.0 * V / 27.0, 1e-13) << "node " << a;
}

TEST(Model, RegionsSelectTheRightNodesAndEmptyRegionsAreErrors) {
  const Mesh beam = make_beam(1.0, 1.0, 1.0, 2, 2, 2, 1);
  const auto nodes = select_nodes(beam, test::box_region({-1, -1, -1}, {0, 2, 2}), "s.json");
  EXPECT_EQ(nodes.size(), 9u);  // the x = 0 face of a 3x3x3 grid
  Region plane;
  plane.kind = Region::Kind::Plane;
  plane.point = {0.5, 0, 0};
  plane.normal = {1, 0, 0};
  plane.json_path = "fixed[2]";
  EXPECT_EQ(select_nodes(beam, plane, "s.json").size(), 18u);
  try {
    select_nodes(beam, test::box_region({5, 5, 5}, {6, 6, 6}, "fixed[1]"), "s.json");
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("s.json: fixed[1]: selects no mesh node"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace incise

namespace incise {
namespace {

// A node no element uses (a gmsh geometry point, say) carries no mass or
// stiffness: the model holds it fixed instead of handing a singular system
// (or a 0/0 acceleration) to the step.
TEST(Model, NodesInNoElementAreFixedAndTheStepStaysFinite) {
  Mesh mesh = make_beam(1.0, 0.3, 0.3, 3, 1, 1, 1);
  const int unused = mesh.nnode();
  mesh.X.insert(mesh.X.end(), {5.0, 5.0, 5.0});
  Scene s = test::basic_scene(2, MaterialModel::Corotated, RotationMode::PerPoint);
  s.fixed.push_back(test::box_region({-1, -1, -1}, {0, 1, 1}));
  s.gravity = {0.0, 0.0, -9.81};
  const Model m = build_model(mesh, s);
  for (int c = 0; c < 3; ++c) EXPECT_TRUE(m.constrained[3 * unused + c]);
  EXPECT_GE(m.diag[3 * unused], 0);
  State st; Workspace ws;
  init_state(m, st, ws);
  for (int k = 0; k < 3; ++k) step(m, st, ws);
  for (double u : st.u) ASSERT_TRUE(std::isfinite(u));
  EXPECT_EQ(st.u[3 * unused], 0.0);
  double umax = 0.0;  // the beam itself moves under gravity
  for (int n = 0; n < unused; ++n) umax = std::max(umax, std::abs(st.u[3 * n + 2]));
  EXPECT_GT(umax, 0.0);
}

}  // namespace
}  // namespace incise
