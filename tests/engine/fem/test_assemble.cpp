// Corotated forces are rotation invariant; the linear model shows ghost forces.
#include <cmath>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "engine/fem/assemble.h"
#include "engine/fem/polar.h"
#include "engine/mesh/mesh_tools.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

struct Forces {
  double corotated, linear_ghost, scale;
};

// Rigidly rotate a small beam by 90 degrees about an oblique axis and compare
// |f_int| with |K0 u|, the force a linear model produces for that displacement.
Forces rigid_rotation_forces(int order, RotationMode rot, double stretch) {
  Mesh mesh = make_beam(1.0, 0.4, 0.3, 3, 2, 2, 1);
  Scene s = test::basic_scene(order, MaterialModel::Corotated, rot);
  const Model m = build_model(mesh, s);
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  std::vector<double> u(m.ndof()), f(m.ndof()), R(9 * m.nrot), fl(m.ndof());
  for (int n = 0; n < m.nnode; ++n) {
    Eigen::Vector3d X(m.X[3 * n], m.X[3 * n + 1], m.X[3 * n + 2]);
    Eigen::Vector3d Xs = X;
    Xs[0] *= stretch;
    const Eigen::Vector3d x = Q * Xs;
    for (int d = 0; d < 3; ++d) u[3 * n + d] = x[d] - X[d];
  }
  for (int r = 0; r < m.nrot; ++r)
    for (int k = 0; k < 9; ++k) R[9 * r + k] = k % 4 == 0 ? 1.0 : 0.0;
  update_rotations(m, u.data(), R.data());
  assemble_internal(m, u.data(), R.data(), f.data(), nullptr);
  sym_matvec(m, m.K0_csc.data(), u.data(), fl.data());
  Eigen::Map<Eigen::VectorXd> F(f.data(), m.ndof()), FL(fl.data(), m.ndof());
  return {F.norm(), FL.norm(), FL.norm()};
}

TEST(Corotation, RigidRotationGivesNoElasticForce) {
  for (int order : {1, 2})
    for (RotationMode rot : {RotationMode::PerPoint, RotationMode::Single}) {
      const Forces f = rigid_rotation_forces(order, rot, 1.0);
      EXPECT_LT(f.corotated, 1e-9 * f.scale) << "order " << order;
      EXPECT_GT(f.linear_ghost, 0.0);
    }
}

TEST(Corotation, RotatedStretchGivesTheSameForceMagnitudeAsTheUnrotatedStretch) {
  // Invariance beyond zero: a stretched-and-rotated beam has the corotated
  // force of the stretched beam, rotated (same norm).
  for (int order : {1, 2}) {
    Mesh mesh = make_beam(1.0, 0.4, 0.3, 3, 2, 2, 1);
    const Model m = build_model(mesh, test::basic_scene(order));
    const Eigen::Matrix3d Q = Eigen::AngleAxisd(1.0, Eigen::Vector3d(0.3, -1, 0.5).normalized()).toRotationMatrix();
    std::vector<double> u1(m.ndof()), u2(m.ndof()), f1(m.ndof()), f2(m.ndof()), R1(9 * m.nrot), R2(9 * m.nrot);
    for (int n = 0; n < m.nnode; ++n) {
      Eigen::Vector3d X(m.X[3 * n], m.X[3 * n + 1], m.X[3 * n + 2]), xs = X;
      xs[0] *= 1.1;
      xs[1] += 0.05 * X[0] * X[0];
      const Eigen::Vector3d xr = Q * xs;
      for (int d = 0; d < 3; ++d) {
        u1[3 * n + d] = xs[d] - X[d];
        u2[3 * n + d] = xr[d] - X[d];
      }
    }
    for (auto* R : {&R1, &R2})
      for (int r = 0; r < m.nrot; ++r)
        for (int k = 0; k < 9; ++k) (*R)[9 * r + k] = k % 4 == 0 ? 1.0 : 0.0;
    update_rotations(m, u1.data(), R1.data());
    update_rotations(m, u2.data(), R2.data());
    assemble_internal(m, u1.data(), R1.data(), f1.data(), nullptr);
    assemble_internal(m, u2.data(), R2.data(), f2.data(), nullptr);
    double err = 0, ref = 0;
    for (int n = 0; n < m.nnode; ++n) {
      const Eigen::Vector3d a = Q * Eigen::Vector3d(f1[3 * n], f1[3 * n + 1], f1[3 * n + 2]);
      const Eigen::Vector3d b(f2[3 * n], f2[3 * n + 1], f2[3 * n + 2]);
      err += (a - b).squaredNorm();
      ref += a.squaredNorm();
    }
    EXPECT_GT(ref, 0.0);
    EXPECT_LT(std::sqrt(err / ref), 1e-10) << "order " << order;
  }
}

TEST(Corotation, LinearModelShowsGhostForcesUnderRotation) {
  // The linear model sees a 90-degree turn as a large strain: its force
  // exceeds that of a real 1% stretch many times over; the corotated one is 0.
  Mesh mesh = make_beam(1.0, 0.4, 0.3, 3, 2, 2, 1);
  for (MaterialModel mm : {MaterialModel::Linear, MaterialModel::Corotated}) {
    const Model m = build_model(mesh, test::basic_scene(2, mm));
    auto force = [&](const Eigen::Matrix3d& Fmap) {
      std::vector<double> u(m.ndof()), f(m.ndof()), R = identity_rotations(m.nrot);
      for (int n = 0; n < m.nnode; ++n) {
        const Eigen::Vector3d X(m.X[3 * n], m.X[3 * n + 1], m.X[3 * n + 2]), x = Fmap * X;
        for (int d = 0; d < 3; ++d) u[3 * n + d] = x[d] - X[d];
      }
      update_rotations(m, u.data(), R.data());
      assemble_internal(m, u.data(), R.data(), f.data(), nullptr);
      return Eigen::Map<Eigen::VectorXd>(f.data(), m.ndof()).norm();
    };
    const Eigen::Matrix3d Q = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
    S(0, 0) = 1.01;
    const double ghost = force(Q), stretch = force(S);
    if (mm == MaterialModel::Linear) {
      EXPECT_GT(ghost, 20.0 * stretch);
    } else {
      EXPECT_LT(ghost, 1e-9 * stretch);
    }
  }
}

}  // namespace
}  // namespace incise
