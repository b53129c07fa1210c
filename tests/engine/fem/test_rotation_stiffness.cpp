// The corotated tangent against central differences of the internal force,
// rotations re-extracted at every perturbed configuration.
#include <cmath>
#include <random>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include "engine/fem/assemble.h"
#include "engine/fem/polar.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/fem/rotation_stiffness.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

// u of the homogeneous deformation x = Q diag(stretch) X plus a small random
// field (so every point has its own S), for a 3x2x2 beam.
std::vector<double> deformed(const Model& m, const Eigen::Vector3d& stretch, double noise) {
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> U(-1.0, 1.0);
  std::vector<double> u(m.ndof());
  for (int n = 0; n < m.nnode; ++n) {
    const Eigen::Vector3d X(m.X[3 * n], m.X[3 * n + 1], m.X[3 * n + 2]);
    const Eigen::Vector3d x = Q * stretch.cwiseProduct(X);
    for (int d = 0; d < 3; ++d) u[3 * n + d] = x[d] - X[d] + noise * U(rng);
  }
  return u;
}

std::vector<double> force(const Model& m, const std::vector<double>& u) {
  std::vector<double> R = identity_rotations(m.nrot), f(m.ndof());
  update_rotations(m, u.data(), R.data());
  assemble_internal(m, u.data(), R.data(), f.data(), nullptr);
  return f;
}

Eigen::MatrixXd tangent(const Model& m, const std::vector<double>& u) {
  std::vector<double> R = identity_rotations(m.nrot), f(m.ndof()), K(m.nnz());
  update_rotations(m, u.data(), R.data());
  assemble_internal(m, u.data(), R.data(), f.data(), K.data());
  return test::dense(m, K);
}

TEST(Tangent, StretchedAndTurnedMatchesCentralDifferencesOfTheForce) {
  // Stretched in every direction: every rotation-mode stiffness kappa_k > 0,
  // nothing is projected away, so the tangent is the exact derivative of
  // f_int (rotations included). The frozen-R tangent R K0 R^T misses the
  // rotation term: on this state its error is 0.18 in this norm (measured).
  for (int order : {1, 2}) {
    Scene scene = test::basic_scene(order);
    scene.consistent_tangent = true;
    const Model m = build_model(make_beam(1.0, 0.4, 0.3, 3, 2, 2, 1), scene);
    const std::vector<double> u = deformed(m, {1.3, 1.2, 1.1}, 1e-3);
    const Eigen::MatrixXd K = tangent(m, u);
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> U(-1.0, 1.0);
    std::vector<double> du(m.ndof());
    for (double& v : du) v = U(rng);
    const double h = 1e-6;
    std::vector<double> up(u), um(u);
    for (int d = 0; d < m.ndof(); ++d) {
      up[d] += h * du[d];
      um[d] -= h * du[d];
    }
    const std::vector<double> fp = force(m, up), fm = force(m, um);
    std::vector<double> fd(m.ndof()), Kdu(m.ndof());
    for (int d = 0; d < m.ndof(); ++d) fd[d] = (fp[d] - fm[d]) / (2 * h);
    Eigen::Map<Eigen::VectorXd>(Kdu.data(), m.ndof()) = K * Eigen::Map<const Eigen::VectorXd>(du.data(), m.ndof());
    EXPECT_LT(test::rel_diff(Kdu, fd), 1e-6) << "order " << order;
  }
}

// sum_k coef_k u_k u_k^T of rotation_stiffness_modes.
Eigen::Matrix3d mode_sum(const double* u, const double* coef) {
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
  for (int k = 0; k < 3; ++k) {
    const Eigen::Map<const Eigen::Vector3d> uk(u + 3 * k);
    M += coef[k] * uk * uk.transpose();
  }
  return M;
}

TEST(Tangent, RotationModesAreThePositivePartOfZ) {
  // kappa_k = 2 mu - 2 c / (s_i + s_j) on axis k of S (pair = the other two
  // axes), c = 2 mu - lambda tr(S - I); the modes must sum to w/2 R Z+ R^T.
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
  double u[9], coef[3];
  // Compressed, mu = 1, lambda = 2: S = diag(0.5, 0.6, 1.4), c = 3, pairs 2.0,
  // 1.9, 1.1: kappa -1, -1.16, -3.45, all dropped.
  Eigen::Matrix3d F = R * Eigen::Vector3d(0.5, 0.6, 1.4).asDiagonal();
  EXPECT_FALSE(rotation_stiffness_modes(R.data(), F.data(), 1.0, 2.0, 2.0, u, coef));
  EXPECT_LT(mode_sum(u, coef).norm(), 1e-14);
  // Stretched: S = diag(1.5, 1.4, 1.3), c = -0.4, kappa = 2 + 0.8 / pair, all
  // kept (Z positive definite: the Cholesky path).
  F = R * Eigen::Vector3d(1.5, 1.4, 1.3).asDiagonal();
  ASSERT_TRUE(rotation_stiffness_modes(R.data(), F.data(), 1.0, 2.0, 2.0, u, coef));
  Eigen::Matrix3d expect = R * Eigen::Vector3d(2 + 0.8 / 2.7, 2 + 0.8 / 2.8, 2 + 0.8 / 2.9).asDiagonal() * R.transpose();
  EXPECT_LT((mode_sum(u, coef) - expect).norm(), 1e-12 * expect.norm());
  // Mixed, mu = 1, lambda = 0 (c = 2): S = diag(0.5, 0.6, 3.0), pairs 3.6, 3.5,
  // 1.1: kappa 2 - 4/3.6, 2 - 4/3.5 kept, 2 - 4/1.1 < 0 dropped (eigen path).
  F = R * Eigen::Vector3d(0.5, 0.6, 3.0).asDiagonal();
  ASSERT_TRUE(rotation_stiffness_modes(R.data(), F.data(), 1.0, 0.0, 2.0, u, coef));
  expect = R * Eigen::Vector3d(2 - 4 / 3.6, 2 - 4 / 3.5, 0.0).asDiagonal() * R.transpose();
  EXPECT_LT((mode_sum(u, coef) - expect).norm(), 1e-12 * expect.norm());
  // Inverted (one negative s, two negative pairs): no rotation term.
  F = R * Eigen::Vector3d(-0.5, 0.2, 0.2).asDiagonal();
  EXPECT_FALSE(rotation_stiffness_modes(R.data(), F.data(), 1.0, 2.0, 2.0, u, coef));
}

// rotation_stiffness_matrix (the fused kernels' form) is the modes' sum
// w/2 R Z+ R^T on every path: compressed (none), stretched (Z positive
// definite, no factor), mixed (eigen path), inverted (none), and on random
// states around them.
TEST(Tangent, RotationMatrixIsTheSumOfTheModes) {
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
  std::vector<std::pair<Eigen::Vector3d, double>> cases = {{{0.5, 0.6, 1.4}, 2.0}, {{1.5, 1.4, 1.3}, 2.0},
                                                          {{0.5, 0.6, 3.0}, 0.0}, {{-0.5, 0.2, 0.2}, 2.0}};
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(0.3, 2.5), L(0.0, 5.0);
  for (int k = 0; k < 200; ++k) cases.push_back({{U(rng), U(rng), U(rng)}, L(rng)});
  int kept = 0, eigen_path = 0;
  for (const auto& [s, lambda] : cases) {
    const Eigen::Matrix3d Q = Eigen::AngleAxisd(s[0], Eigen::Vector3d(s[1], -1, s[2]).normalized()).toRotationMatrix();
    const Eigen::Matrix3d F = R * Q * s.asDiagonal() * Q.transpose();  // R S with S not diagonal
    double u[9], coef[3], Y[9];
    const bool modes = rotation_stiffness_modes(R.data(), F.data(), 1.0, lambda, 2.0, u, coef);
    const bool matrix = rotation_stiffness_matrix(R.data(), F.data(), 1.0, lambda, 2.0, Y);
    EXPECT_EQ(matrix, modes) << "S eigenvalues " << s.transpose() << ", lambda " << lambda;
    const Eigen::Matrix3d expect = modes ? mode_sum(u, coef) : Eigen::Matrix3d::Zero();
    EXPECT_LT((Eigen::Map<const Eigen::Matrix3d>(Y) - expect).norm(), 1e-12 * (1.0 + expect.norm()));
    kept += modes;
    eigen_path += modes && (coef[0] != coef[1] || coef[1] != coef[2]);
  }
  EXPECT_GT(kept, 20);
  EXPECT_GT(eigen_path, 5) << "the indefinite (eigen) path is exercised";
}

}  // namespace
}  // namespace incise
