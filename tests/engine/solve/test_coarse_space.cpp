// The two-level preconditioner's coarse level (engine/solve/coarse_space.h):
// A_c equals P^T A P formed densely, and the coarse correction is exact on
// the coarse space (Q A P y = P y).
#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "engine/mesh/mesh_tools.h"
#include "engine/solve/coarse_space.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

// The dense P (ndof x 3 ncoarse) of the space: constrained rows and the
// columns of constrained corner DOFs zero.
Eigen::MatrixXd dense_P(const Model& m, const CoarseSpace& c) {
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(m.ndof(), 3 * c.ncoarse);
  for (int n = 0; n < m.nnode; ++n)
    for (int s = c.p_ptr[n]; s < c.p_ptr[n + 1]; ++s)
      for (int k = 0; k < 3; ++k)
        if (!m.constrained[3 * n + k] && !c.cfixed[3 * c.p_node[s] + k]) P(3 * n + k, 3 * c.p_node[s] + k) = c.p_w[s];
  return P;
}

Model clamped_beam() {
  Scene s = test::basic_scene(2);
  s.fixed.push_back(test::box_region({-1e-9, -1, -1}, {1e-9, 1, 1}));
  Prescribed one;  // one component of a corner on the far end: a partly constrained node
  one.region = test::box_region({0.999, -1e-9, -1e-9}, {1.001, 1e-9, 1e-9}, "prescribed[0]");
  one.active = {false, true, false};
  s.prescribed.push_back(one);
  return build_model(make_beam(1.0, 0.3, 0.2, 4, 2, 2, 1), s);
}

TEST(CoarseSpace, GalerkinMatrixEqualsDenseTripleProduct) {
  const Model m = clamped_beam();
  CoarseSpace c;
  build_coarse_space(m, c);
  ASSERT_GT(c.ncoarse, 0);
  EXPECT_EQ(c.ncoarse, 5 * 3 * 3) << "the beam's grid vertices";
  const std::vector<double> A = test::system_matrix(m, 3600.0);
  factor_coarse_space(m, A.data(), c);
  const Eigen::MatrixXd Ad = test::dense(m, A);
  const Eigen::MatrixXd P = dense_P(m, c);
  Eigen::MatrixXd Ac = P.transpose() * Ad * P;
  for (int i = 0; i < Ac.rows(); ++i)
    if (c.cfixed[i]) Ac(i, i) = 1.0;
  const int nc = 3 * c.ncoarse;
  Eigen::MatrixXd Cd = Eigen::MatrixXd::Zero(nc, nc);
  for (int col = 0; col < nc; ++col)
    for (int k = c.cAp[col]; k < c.cAp[col + 1]; ++k) Cd(c.cAi[k], col) = Cd(col, c.cAi[k]) = c.cA[k];
  EXPECT_LT((Cd - Ac).norm(), 1e-12 * Ac.norm());
  int fixed = 0;
  for (char f : c.cfixed) fixed += f;
  EXPECT_EQ(fixed, 9 * 3 + 1) << "the clamped face's 9 corners and one component at the far end";
}

TEST(CoarseSpace, CorrectionIsExactOnTheCoarseSpace) {
  const Model m = clamped_beam();
  CoarseSpace c;
  build_coarse_space(m, c);
  const std::vector<double> A = test::system_matrix(m, 3600.0);
  factor_coarse_space(m, A.data(), c);
  const Eigen::MatrixXd P = dense_P(m, c);
  const std::vector<double> yv = test::random_vector(3 * c.ncoarse, 7);
  const Eigen::VectorXd x = P * Eigen::Map<const Eigen::VectorXd>(yv.data(), yv.size());
  const Eigen::VectorXd r = test::dense(m, A) * x;
  std::vector<double> z(m.ndof());
  apply_coarse_space(m, c, r.data(), z.data());
  // float factor: exact to single precision
  EXPECT_LT((Eigen::Map<const Eigen::VectorXd>(z.data(), z.size()) - x).norm(), 1e-5 * x.norm());
}

TEST(CoarseSpace, Tet4ModelsHaveNoCoarserLevel) {
  Scene s = test::basic_scene(1);
  s.fixed.push_back(test::box_region({-1e-9, -1, -1}, {1e-9, 1, 1}));
  const Model m = build_model(make_beam(1.0, 0.3, 0.2, 4, 2, 2, 1), s);
  CoarseSpace c;
  build_coarse_space(m, c);
  EXPECT_EQ(c.ncoarse, 0);
  std::vector<double> r(m.ndof(), 1.0), z(m.ndof(), 5.0);
  apply_coarse_space(m, c, r.data(), z.data());
  for (double v : z) EXPECT_EQ(v, 0.0);
}

}  // namespace
}  // namespace incise
