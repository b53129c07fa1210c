// The solver's sparse products on cut models: the node-blocked symmetric
// product (engine/fem/node_block_matvec.h) relies on the pattern's layout, and the
// lumped mass product on M being its diagonal plus the u-q couplings
// (Model::mass_coupling). Both are checked against a plain entry-by-entry
// product of the stored upper triangle, on a fresh cut model and on a cut
// rebuild from a base (build_pattern_from_base, the incremental lumped mass).
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "engine/fem/assemble.h"
#include "engine/fem/assemble_parallel.h"
#include "engine/dynamics/step.h"
#include "tests/cutting/test_util.h"

namespace incise {
namespace {

// y = A x from the upper triangle, one entry at a time.
std::vector<double> reference_product(const Model& m, const std::vector<double>& A, const std::vector<double>& x) {
  std::vector<double> y(m.ndof(), 0.0);
  for (int c = 0; c < m.ndof(); ++c)
    for (int k = m.Ap[c]; k < m.Ap[c + 1]; ++k) {
      const int r = m.Ai[k];
      y[r] += A[k] * x[c];
      if (r != c) y[c] += A[k] * x[r];
    }
  return y;
}

double rel_diff(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0.0, n = 0.0;
  for (size_t i = 0; i < a.size(); ++i) d += (a[i] - b[i]) * (a[i] - b[i]), n += b[i] * b[i];
  return std::sqrt(d / n);
}

// Column 3c + j: rows 3r..3r+2 for each row node r < c (ascending), then 3c..3c+j.
void expect_node_blocked(const Model& m) {
  for (int c = 0; c < m.ndofnode; ++c) {
    const int L = m.Ap[3 * c + 1] - m.Ap[3 * c] - 1;
    ASSERT_EQ(L % 3, 0) << "node " << c;
    for (int j = 0; j < 3; ++j) {
      const int k0 = m.Ap[3 * c + j];
      ASSERT_EQ(m.Ap[3 * c + j + 1] - k0, L + j + 1) << "column " << 3 * c + j;
      for (int t = 0; t < L; ++t) {
        ASSERT_EQ(m.Ai[k0 + t], m.Ai[m.Ap[3 * c] + t]) << "column " << 3 * c + j;
        if (t % 3) {
          ASSERT_EQ(m.Ai[k0 + t], m.Ai[k0 + t - 1] + 1);
        } else if (t) {
          ASSERT_GT(m.Ai[k0 + t], m.Ai[k0 + t - 1]);
        }
      }
      for (int i = 0; i <= j; ++i) ASSERT_EQ(m.Ai[k0 + L + i], 3 * c + i);
    }
  }
}

void check_products(const Model& m) {
  expect_node_blocked(m);
  std::vector<double> x(m.ndof()), A(m.nnz());
  for (int d = 0; d < m.ndof(); ++d) x[d] = std::sin(0.37 * d + 0.1);
  for (int k = 0; k < m.nnz(); ++k) A[k] = std::cos(0.11 * k);  // any symmetric matrix in the pattern
  const std::vector<double> ref = reference_product(m, A, x);
  std::vector<double> y(m.ndof());
  sym_matvec(m, A.data(), x.data(), y.data());
  EXPECT_LT(rel_diff(y, ref), 1e-14);
  for (int threads : {1, 2, 3}) {  // column ranges end on node boundaries
    ThreadPool pool(threads);
    AssemblyPlan plan = make_assembly_plan(m, threads);
    std::fill(y.begin(), y.end(), 7.0);  // overwritten, not accumulated
    sym_matvec_parallel(m, plan, pool, A.data(), x.data(), y.data());
    EXPECT_LT(rel_diff(y, ref), 1e-14) << threads << " workers";
  }
  // Lumped mass with enrichment: the compact product is the stored matrix's.
  ASSERT_EQ(m.mass_kind, MassKind::Lumped);
  ASSERT_FALSE(m.mass_csc.empty());
  EXPECT_GT(m.mass_coupling.size(), 0u);
  for (int d = 0; d < m.ndof(); ++d) ASSERT_EQ(m.mass_lumped[d], m.mass_csc[m.diag[d]]) << "DOF " << d;
  std::vector<double> Mx(m.ndof());
  mass_matvec(m, x.data(), Mx.data());
  EXPECT_LT(rel_diff(Mx, reference_product(m, m.mass_csc, x)), 1e-15);
}

TEST(SparseProducts, NodeBlockedAndLumpedMassProductsMatchTheStoredMatrixOnCutModels) {
  Scene s = test::block_scene(2);
  s.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
  s.cuts = {test::swept_blade({Vec3{2.3, -0.5, 1.2}, Vec3{2.3, 1.5, 1.2}}, {Vec3{2.3, -0.5, -0.2}, Vec3{2.3, 1.5, -0.2}})};
  auto sim = test::make_sim(make_beam(4, 1, 1, 8, 2, 2, 1), s);
  ASSERT_TRUE(update_cuts(*sim, 0.0, 0.5).changed);  // a fresh cut model
  check_products(sim->model);
  ASSERT_TRUE(update_cuts(*sim, 0.0, 0.8).changed);  // rebuilt from the last one
  check_products(sim->model);
}

}  // namespace
}  // namespace incise
