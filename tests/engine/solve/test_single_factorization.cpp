// The single-precision supernodal factorization (engine/solve/single_factor.h,
// CholmodSolver::set_single_factorization): on SPD tet10 beam matrices its
// solves are within a float-roundoff bound of CHOLMOD's double factor, its
// factor differs from the rounded double one (it was really computed in
// float), CG preconditioned by it reaches double precision, two-thread
// substitutions read it, a pivot that fails in float falls back to CHOLMOD
// and an indefinite matrix still throws CHOLMOD's error.
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "engine/fem/assemble.h"
#include "engine/solve/cholmod_solver.h"
#include "engine/util/error.h"
#include "engine/solve/single_factor.h"
#include "tests/engine/test_util.h"

namespace incise {
namespace {

using test::random_vector;
using test::rel_diff;
using test::system_matrix;

struct Case {
  const char* name;
  int nx, nyz;
  double cM;  // 4 / dt^2 at 30 Hz (dynamic) or 0 (static)
};
// Static 3k: cond(A) ~ 5e5 (tests/engine/test_single_factor.cpp), the hardest.
const Case kCases[] = {{"dynamic 3k", 10, 3, 3600.0}, {"static 3k", 10, 3, 0.0}, {"dynamic 7k", 14, 4, 3600.0}};

// |A x - b| / |b|.
double residual(const Model& m, const std::vector<double>& A, const std::vector<double>& x, const std::vector<double>& b) {
  std::vector<double> Ax(b.size());
  sym_matvec(m, A.data(), x.data(), Ax.data());
  double r = 0, nb = 0;
  for (size_t i = 0; i < b.size(); ++i) r += (Ax[i] - b[i]) * (Ax[i] - b[i]), nb += b[i] * b[i];
  return std::sqrt(r / nb);
}

// The algorithm itself, run in double on CHOLMOD's analysis, reproduces
// CHOLMOD's double factor entry by entry to roundoff (so the float results
// below differ from it by rounding, not by a missed update); in float every
// entry is within 1e-4 of the largest of its supernode.
TEST(SingleFactorization, SameAlgorithmInDoubleReproducesCholmodsFactor) {
  for (const Case& c : kCases) {
    SCOPED_TRACE(c.name);
    const Model m = test::tissue_beam(c.nx, c.nyz);
    std::vector<double> A = system_matrix(m, c.cM);
    const int n = m.ndof();
    cholmod_common cc;
    cholmod_start(&cc);
    cc.supernodal = CHOLMOD_SUPERNODAL;
    cholmod_sparse* S = cholmod_allocate_sparse(n, n, A.size(), 1, 1, 1, CHOLMOD_REAL, &cc);
    std::copy(m.Ap.begin(), m.Ap.end(), static_cast<int*>(S->p));
    std::copy(m.Ai.begin(), m.Ai.end(), static_cast<int*>(S->i));
    std::copy(A.begin(), A.end(), static_cast<double*>(S->x));
    cholmod_factor* L = cholmod_analyze(S, &cc);
    ASSERT_TRUE(L && L->is_super);
    SingleFactorization sf;
    sf.analyze(L, n, m.Ap.data(), m.Ai.data());
    ASSERT_TRUE(cholmod_factorize(S, L, &cc));
    const double* ref = static_cast<const double*>(L->x);
    std::vector<double> Ld(L->xsize);
    std::vector<float> Lf(L->xsize);
    EXPECT_EQ(sf.factorize_double(A.data(), Ld.data()), -1);
    EXPECT_EQ(sf.factorize(A.data(), Lf.data()), -1);
    const int* px = static_cast<const int*>(L->px);
    double worst_d = 0, worst_f = 0;
    for (size_t sn = 0; sn < L->nsuper; ++sn) {
      double mx = 0;
      for (int k = px[sn]; k < px[sn + 1]; ++k) mx = std::max(mx, std::fabs(ref[k]));
      for (int k = px[sn]; k < px[sn + 1]; ++k) {
        worst_d = std::max(worst_d, std::fabs(Ld[k] - ref[k]) / mx);
        worst_f = std::max(worst_f, std::fabs(Lf[k] - ref[k]) / mx);
      }
    }
    std::printf("[ %s: %zu supernodes, double algorithm %.2g, float %.2g (relative to each supernode's largest) ]\n",
                c.name, static_cast<size_t>(L->nsuper), worst_d, worst_f);
    EXPECT_LT(worst_d, 1e-12);
    EXPECT_LT(worst_f, 1e-4);
    EXPECT_GT(worst_f, 1e-9);  // really float
    cholmod_free_factor(&L, &cc);
    cholmod_free_sparse(&S, &cc);
    cholmod_finish(&cc);
  }
}

TEST(SingleFactorization, SolvesWithinFloatRoundoffOfTheDoubleFactor) {
  for (const Case& c : kCases) {
    SCOPED_TRACE(c.name);
    const Model m = test::tissue_beam(c.nx, c.nyz);
    const std::vector<double> A = system_matrix(m, c.cM);
    const int n = m.ndof();
    CholmodSolver d, s, r;  // CHOLMOD double; single; CHOLMOD double rounded to float
    s.set_factor_copy(FactorCopy::Float);
    s.set_single_factorization(true);
    r.set_factor_copy(FactorCopy::Float);
    for (CholmodSolver* f : {&d, &s, &r}) {
      f->analyze(n, m.Ap, m.Ai);
      f->factorize(A.data());
    }
    ASSERT_TRUE(s.stats().supernodal);
    EXPECT_TRUE(s.stats().single_precision);
    EXPECT_EQ(s.stats().single_fallbacks, 0);
    EXPECT_EQ(s.stats().copy_conversions, 0);  // no double factor to convert
    EXPECT_TRUE(s.has_factor_copy());
    EXPECT_THROW(s.solve_cholmod(random_vector(n, 1).data(), std::vector<double>(n).data()), Error);
    double worst = 0, worst_res = 0, worst_rounded = 0;
    for (unsigned seed = 1; seed <= 3; ++seed) {
      const std::vector<double> b = random_vector(n, seed);
      std::vector<double> xd(n), xs(n), xc(n), xr(n);
      d.solve(b.data(), xd.data());
      s.solve(b.data(), xs.data());
      s.solve_copy(b.data(), xc.data());
      r.solve_copy(b.data(), xr.data());
      EXPECT_EQ(xs, xc);  // solve() reads the float factor: the only one
      worst = std::max(worst, rel_diff(xs, xd));
      worst_res = std::max(worst_res, residual(m, A, xs, b));
      worst_rounded = std::max(worst_rounded, rel_diff(xr, xd));
      // Computed in float, not the rounded double factor: the two differ by
      // far more than double roundoff.
      EXPECT_GT(rel_diff(xs, xr), 1e-10);
    }
    // A float Cholesky solves (A + E) x = b with |E| <~ c n u |L||L^T|
    // (Higham, Thm 10.3), so the forward error is up to c n u cond(A).
    // Measured (3 right-hand sides): dynamic 3k 2.9e-6 (residual 1.5e-5),
    // static 3k (cond ~5e5) 1.4e-3 (2.5e-4), dynamic 7k 2.4e-5 (1.8e-5),
    // against 8e-9 to 8e-8 for the rounded double factor. Bounds: 4x the
    // worst of each kind (the lagged factor is already 1e-3-1e-2 away from
    // the current matrix, so this is far below what CG notices).
    std::printf("[ %s: n = %d, single %.3g (residual %.3g), rounded double %.3g ]\n", c.name, n, worst, worst_res,
                worst_rounded);
    const bool dynamic = c.cM > 0;
    EXPECT_LT(worst, dynamic ? 1e-4 : 6e-3);
    EXPECT_LT(worst_res, dynamic ? 1e-4 : 1e-3);
    EXPECT_GT(worst, worst_rounded);  // a float factorization rounds more than rounding the double factor once
  }
}

// CG on A (static: cond ~5e5) preconditioned by the single factor reaches
// |r| <= 1e-12 |b| in a few iterations: only the count, never the attained
// tolerance, depends on the preconditioner's precision.
TEST(SingleFactorization, PreconditionedCGConvergesToDoublePrecision) {
  const Model m = test::tissue_beam(10, 3);
  const int n = m.ndof();
  const std::vector<double> A = system_matrix(m, 0.0);
  CholmodSolver f;
  f.set_factor_copy(FactorCopy::Float);
  f.set_single_factorization(true);
  f.analyze(n, m.Ap, m.Ai);
  f.factorize(A.data());
  const std::vector<double> b = random_vector(n, 7);
  double rel = 1;
  const int it = test::preconditioned_cg(
      m, A, b, [&](const double* r, double* z) { f.solve(r, z); }, 30, 1e-12, &rel);
  std::printf("[ CG with the single-precision factor: %d iterations to %.2g ]\n", it, rel);
  EXPECT_LE(rel, 1e-12);
  EXPECT_LE(it, 8);
}

// Two-thread substitutions (split_substitution.h) read the float factor too.
TEST(SingleFactorization, TwoThreadSubstitutionMatchesOneThread) {
  const Model m = test::tissue_beam(14, 4);
  const int n = m.ndof();
  const std::vector<double> A = system_matrix(m, 3600.0);
  SubstitutionWorker worker;
  CholmodSolver one, two;
  for (CholmodSolver* f : {&one, &two}) {
    f->set_factor_copy(FactorCopy::Float);
    f->set_single_factorization(true);
  }
  two.set_substitution_worker(&worker);
  for (CholmodSolver* f : {&one, &two}) {
    f->analyze(n, m.Ap, m.Ai);
    f->factorize(A.data());
  }
  ASSERT_TRUE(two.substitutes_on_two_threads());
  const std::vector<double> b = random_vector(n, 9);
  std::vector<double> x1(n), x2(n);
  one.solve(b.data(), x1.data());
  two.solve(b.data(), x2.data());
  EXPECT_LT(rel_diff(x2, x1), 1e-12);  // same float factor, sums in another order
}

// Settings that cannot hold: no float copy; another copy while single.
TEST(SingleFactorization, NeedsTheFloatCopy) {
  CholmodSolver f;
  f.set_factor_copy(FactorCopy::None);
  EXPECT_THROW(f.set_single_factorization(true), Error);
  f.set_factor_copy(FactorCopy::Float);
  f.set_single_factorization(true);
  EXPECT_THROW(f.set_factor_copy(FactorCopy::Half), Error);
  f.set_single_factorization(false);
  EXPECT_NO_THROW(f.set_factor_copy(FactorCopy::Half));
}

// An indefinite matrix: the float pivot fails, CHOLMOD in double is asked
// (one fallback) and throws its error naming the DOF; a later SPD matrix on
// the same analysis factors in float again.
TEST(SingleFactorization, IndefiniteMatrixFallsBackToCholmodAndThrows) {
  const Model m = test::tissue_beam(6, 2);
  const int n = m.ndof();
  std::vector<double> A = system_matrix(m, 3600.0);
  CholmodSolver f;
  f.set_factor_copy(FactorCopy::Float);
  f.set_single_factorization(true);
  f.analyze(n, m.Ap, m.Ai);
  const std::vector<double> good = A;
  int bad_dof = -1;
  for (int d = n / 2; d < n && bad_dof < 0; ++d)
    if (!m.constrained[d]) bad_dof = d;
  ASSERT_GE(bad_dof, 0);
  A[m.diag[bad_dof]] = -A[m.diag[bad_dof]];
  try {
    f.factorize(A.data());
    ADD_FAILURE() << "an indefinite matrix was factored";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("not positive definite"), std::string::npos) << e.what();
  }
  EXPECT_EQ(f.stats().single_fallbacks, 1);
  EXPECT_FALSE(f.factorized());
  f.factorize(good.data());
  EXPECT_TRUE(f.factorized());
  EXPECT_EQ(f.stats().single_fallbacks, 1);
  EXPECT_EQ(f.stats().copy_conversions, 0);
  const std::vector<double> b = random_vector(n, 4);
  std::vector<double> x(n);
  f.solve(b.data(), x.data());
  EXPECT_LT(residual(m, good, x, b), 1e-5);
}

}  // namespace
}  // namespace incise
