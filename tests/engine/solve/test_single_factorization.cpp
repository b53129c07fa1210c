// The single-precision supernodal factorization (engine/solve/single_factor.h,
// CholmodSolver::set_single_factorization): on SPD tet10 beam matrices its
// solves are within a float-roundoff bound of CHOLMOD's double factor, its
// factor differs from the rounded double one (it was really computed in
// float), CG preconditioned by it reaches double precision, two-thread
// substitutions read it, it rounds into the half copy as well as CHOLMOD's
// double factor does, a pivot that fails in float falls back to CHOLMOD
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
#include "tests/engine/solve/factor_bounds.h"
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
// below differ from it by rounding, not by a missed update), and in float it
// is backward stable with the bound of Higham's Thm 10.3 (factor_bounds.h):
// L^ L^^T = P A P^T + dA, |dA| <= gamma_{r+2} |L^||L^^T| with u = 2^-24 and r
// the longest inner product (the most entries in a row of L; + 1 for
// rounding A's values to float). A dropped update or a wrong pivot leaves an
// O(1) ratio |dA| / (|L^||L^^T|) on the entries it touches.
//
// The entries' forward error is not bounded usefully a priori (the
// perturbation bound of the Cholesky factor grows with cond(A), ~5e5 for the
// static beam: Higham Thm 10.8 gives > 1 there); the float run measures it
// per unit of backward error (alpha = forward / backward, a condition
// estimate of this factor for this matrix), and the double algorithm's
// difference from CHOLMOD's factor, both backward stable in double, must be
// within alpha * 2 gamma_{r+1}(2^-53): the float run's forward error scaled to
// the worst-case backward error of the two double factorizations.
//
// Measured (release with and without -march=native, and the ASan/UBSan
// build): r = 986 (3k) and 1715 (7k), so gamma_{r+2}(float) = 5.9e-5 and
// 1.0e-4; float backward errors 3.3e-7 .. 4.5e-7, 130-240x below (a few u:
// the rounding errors of the r terms mostly cancel); double algorithm and
// CHOLMOD 8e-16 .. 1.6e-15 against gamma_{r+1}(double) = 1.1e-13 and 1.9e-13
// (70-140x below); double algorithm against CHOLMOD 1.1e-15 .. 2.1e-15
// (dynamic), 1.1e-14 .. 1.3e-14 (static) against 1.8e-12 .. 6e-11 (850-7000x
// below). The float forward error on the static beam, relative to each
// supernode's largest entry, is 8.6e-5 with -march=native, 9.0e-5 without
// and 1.19e-4 on the fresh 2-core Xeon of issue 16 (OpenBLAS picks its
// kernels by CPU): what the former fixed bound 1e-4 compared.
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
    const test::Supernodes sn(L);
    const int r = test::max_row_count(sn);
    const double bound_f = test::gamma_bound(r + 2, test::kUnitFloat);
    const double bound_d = test::gamma_bound(r + 1, test::kUnitDouble);
    const double back_f = test::factor_backward_error(sn, Lf.data(), m, A);
    const double back_d = test::factor_backward_error(sn, Ld.data(), m, A);
    const double back_ref = test::factor_backward_error(sn, ref, m, A);
    // Forward differences, relative to each supernode's largest entry.
    const int* px = static_cast<const int*>(L->px);
    double worst_d = 0, worst_f = 0;
    for (size_t s = 0; s < L->nsuper; ++s) {
      double mx = 0;
      for (int k = px[s]; k < px[s + 1]; ++k) mx = std::max(mx, std::fabs(ref[k]));
      for (int k = px[s]; k < px[s + 1]; ++k) {
        worst_d = std::max(worst_d, std::fabs(Ld[k] - ref[k]) / mx);
        worst_f = std::max(worst_f, std::fabs(Lf[k] - ref[k]) / mx);
      }
    }
    const double alpha = worst_f / std::max(back_f, test::kUnitFloat);
    const double bound_fwd_d = alpha * 2.0 * bound_d;
    SCOPED_TRACE(::testing::Message() << "r = " << r << ", backward: float " << back_f << " (bound " << bound_f
                                      << "), double " << back_d << ", CHOLMOD " << back_ref << " (bound " << bound_d
                                      << "); forward: float " << worst_f << ", double " << worst_d << " (bound "
                                      << bound_fwd_d << ")");
    std::printf("[ %s: r = %d; backward float %.2g (bound %.2g), double %.2g, CHOLMOD %.2g (bound %.2g); forward "
                "float %.3g, double %.2g (bound %.2g) ]\n",
                c.name, r, back_f, bound_f, back_d, back_ref, bound_d, worst_f, worst_d, bound_fwd_d);
    EXPECT_LE(back_f, bound_f);
    EXPECT_LE(back_d, bound_d);
    EXPECT_LE(back_ref, bound_d);
    EXPECT_LE(worst_d, bound_fwd_d);
    EXPECT_GT(worst_f, test::kUnitFloat / 64);  // really float: far above the double's roundoff
    EXPECT_GT(back_f, 64 * bound_d);
    cholmod_free_factor(&L, &cc);
    cholmod_free_sparse(&S, &cc);
    cholmod_finish(&cc);
  }
}

// A float Cholesky solves (A + dA) x = b with |dA| <= E = (gamma_{r+2}(2^-24)
// + gamma_{2r+1}(2^-53)) |L^||L^^T| (Higham Thm 10.3 for the factor, Thm 8.5
// for the two substitutions, done in double; factor_bounds.h). So each
// residual entry is within (E |x|)_i (backward error <= 1: a wrong pivot or
// a dropped update breaks it by orders of magnitude), and the forward error
// against the double solve is within ||A^-1||_2 ||E' |x| ||_2 / ||x||_2, E'
// adding the double solve's own gamma_{3r+1}(2^-53) |L||L^T|; with the
// measured backward error omega (<= 1) in place of 1 (factor_bounds.h):
// ||A^-1|| (omega ||E |x| || + ||E_ref |x| ||) / ||x_double||. With omega = 1
// it would exceed 1 on the static beam (cond ~5e5, r ~ 1000).
//
// Measured (release with and without -march=native, ASan; 3 right-hand
// sides): componentwise backward errors 8.3e-4 (dynamic 3k), 6.5e-4 (static
// 3k), 5.9e-4 (dynamic 7k) of the a priori bound (~1500x below: gamma_r is
// the worst case of r ~ 1000 roundings, these are a few u); forward errors
// 2.5e-6 .. 2.9e-6, 1.4e-3, 2.4e-5 .. 2.5e-5 against 4.2e-4, 4.7e-2, 1.0e-3
// (30-170x below; the former fixed bounds were 1e-4 / 6e-3), and 8e-9 to
// 8e-8 for the rounded double factor.
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
    ASSERT_NE(s.float_values(), nullptr);
    const test::Supernodes sn(s.factor());
    const int rc = test::max_row_count(sn);
    const std::vector<double> absL = test::abs_values(sn, s.float_values());
    test::PerturbationBound E{&sn, {{test::gamma_bound(rc + 2, test::kUnitFloat) +
                                         test::gamma_bound(2 * rc + 1, test::kUnitDouble),
                                     &absL, &absL}}};
    const test::PerturbationBound Eref{&sn, {{test::gamma_bound(3 * rc + 1, test::kUnitDouble), &absL, &absL}}};
    const double inv_norm = test::inverse_norm(n, [&](const double* r, double* z) { d.solve(r, z); });
    double worst = 0, worst_res = 0, worst_rounded = 0, worst_back = 0, worst_ratio = 0, bound_fwd = 0;
    for (unsigned seed = 1; seed <= 3; ++seed) {
      const std::vector<double> b = random_vector(n, seed);
      std::vector<double> xd(n), xs(n), xc(n), xr(n);
      d.solve(b.data(), xd.data());
      s.solve(b.data(), xs.data());
      s.solve_copy(b.data(), xc.data());
      r.solve_copy(b.data(), xr.data());
      EXPECT_EQ(xs, xc);  // solve() reads the float factor: the only one
      const double omega = test::solve_backward_error(m, A, E, xs, b);
      const double e = rel_diff(xs, xd);
      const double fb =
          inv_norm * (omega * test::bound_norm(E, xs) + test::bound_norm(Eref, xs)) / test::norm2(xd);
      worst = std::max(worst, e);
      bound_fwd = std::max(bound_fwd, fb);
      worst_ratio = std::max(worst_ratio, e / fb);
      worst_res = std::max(worst_res, residual(m, A, xs, b));
      worst_back = std::max(worst_back, omega);
      worst_rounded = std::max(worst_rounded, rel_diff(xr, xd));
      // Computed in float, not the rounded double factor: the two differ by
      // far more than double roundoff.
      EXPECT_GT(rel_diff(xs, xr), 1e-10);
    }
    std::printf("[ %s: n = %d, r = %d, single %.3g (bound %.3g; residual %.3g, backward %.3g of its bound), rounded "
                "double %.3g ]\n",
                c.name, n, rc, worst, bound_fwd, worst_res, worst_back, worst_rounded);
    EXPECT_LE(worst_back, 1.0);
    EXPECT_LE(worst_ratio, 1.0);
    EXPECT_GT(worst, worst_rounded);  // a float factorization rounds more than rounding the double factor once
  }
}

// CG to 1e-12 on the static 3k beam (cond ~5e5), preconditioned by a
// single-precision factorization with the given copy: solve_copy() (what the
// substitutions read) or solve() (the float factor). Returns the iterations.
int static_beam_cg(FactorCopy copy, bool through_copy, int max_iterations, double* rel) {
  const Model m = test::tissue_beam(10, 3);
  const int n = m.ndof();
  const std::vector<double> A = system_matrix(m, 0.0);
  CholmodSolver f;
  f.set_factor_copy(copy);
  f.set_single_factorization(true);
  f.analyze(n, m.Ap, m.Ai);
  f.factorize(A.data());
  const auto precondition = [&](const double* r, double* z) {
    if (through_copy) f.solve_copy(r, z);
    else f.solve(r, z);
  };
  return test::preconditioned_cg(m, A, random_vector(n, 7), precondition, max_iterations, 1e-12, rel);
}

// CG on A (static: cond ~5e5) preconditioned by the single factor reaches
// |r| <= 1e-12 |b| in a few iterations: only the count, never the attained
// tolerance, depends on the preconditioner's precision.
TEST(SingleFactorization, PreconditionedCGConvergesToDoublePrecision) {
  double rel = 1;
  const int it = static_beam_cg(FactorCopy::Float, /*through_copy=*/false, 30, &rel);
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

// SingleFactorization::factorize returns the permuted column of the first
// pivot that is not positive: L->Perm of it is the DOF whose diagonal was
// negated (the only pivot that can fail), in float and in double.
TEST(SingleFactorization, FailedPivotIsThePermutedColumnOfTheBadDof) {
  const Model m = test::tissue_beam(6, 2);
  const int n = m.ndof();
  std::vector<double> A = system_matrix(m, 3600.0);
  cholmod_common cc;
  cholmod_start(&cc);
  cc.supernodal = CHOLMOD_SUPERNODAL;
  cholmod_sparse* S = cholmod_allocate_sparse(n, n, A.size(), 1, 1, 1, CHOLMOD_REAL, &cc);
  std::copy(m.Ap.begin(), m.Ap.end(), static_cast<int*>(S->p));
  std::copy(m.Ai.begin(), m.Ai.end(), static_cast<int*>(S->i));
  cholmod_factor* L = cholmod_analyze(S, &cc);
  ASSERT_TRUE(L && L->is_super);
  const int* perm = static_cast<const int*>(L->Perm);
  int bad = -1, position = -1;
  for (int k = 0; k < n && bad < 0; ++k)
    if (perm[k] != k && perm[k] >= n / 2 && !m.constrained[perm[k]]) bad = perm[k], position = k;
  ASSERT_GE(bad, 0);
  A[m.diag[bad]] = -A[m.diag[bad]];
  SingleFactorization sf;
  sf.analyze(L, n, m.Ap.data(), m.Ai.data());
  std::vector<float> Lf(L->xsize);
  std::vector<double> Ld(L->xsize);
  EXPECT_EQ(sf.factorize(A.data(), Lf.data()), position);
  EXPECT_EQ(sf.factorize_double(A.data(), Ld.data()), position);
  cholmod_free_factor(&L, &cc);
  cholmod_free_sparse(&S, &cc);
  cholmod_finish(&cc);
}

// Settings that cannot hold: no copy at all (the float factor lives in one).
TEST(SingleFactorization, NeedsACopy) {
  CholmodSolver f;
  f.set_factor_copy(FactorCopy::None);
  EXPECT_THROW(f.set_single_factorization(true), Error);
  f.set_factor_copy(FactorCopy::Float);
  f.set_single_factorization(true);
  EXPECT_THROW(f.set_factor_copy(FactorCopy::None), Error);
  EXPECT_NO_THROW(f.set_factor_copy(FactorCopy::Half));
  f.set_single_factorization(false);
  EXPECT_NO_THROW(f.set_factor_copy(FactorCopy::None));
}

// With the half copy the float factor is rounded once more, to binary16 with
// a scale per supernode, and the substitutions read that: solve() still
// reads the float factor (bit for bit the float copy's solve), solve_copy()
// is as far from the double solve as CHOLMOD's double factor rounded to
// half (measured 3.9-9.7e-4 both ways, 0.8-2 eps_half; the float factor's own
// error is 2.5e-6 to 1.2e-3, cond(A) 4e4 to 5e5) plus the float factor's, it
// differs from the float solve by the half rounding, and PCG still reaches 1e-12.
TEST(SingleFactorization, HalfCopyRoundsTheFloatFactor) {
  for (const Case& c : kCases) {
    SCOPED_TRACE(c.name);
    const Model m = test::tissue_beam(c.nx, c.nyz);
    const std::vector<double> A = system_matrix(m, c.cM);
    const int n = m.ndof();
    CholmodSolver d, s, h, r;  // double; single, float copy; single, half copy; double rounded to half
    s.set_factor_copy(FactorCopy::Float);
    s.set_single_factorization(true);
    h.set_factor_copy(FactorCopy::Half);
    h.set_single_factorization(true);
    r.set_factor_copy(FactorCopy::Half);
    for (CholmodSolver* f : {&d, &s, &h, &r}) {
      f->analyze(n, m.Ap, m.Ai);
      f->factorize(A.data());
    }
    EXPECT_EQ(h.stats().single_factorizations, 1);
    EXPECT_EQ(h.stats().copy_conversions, 1);  // float -> half
    ASSERT_TRUE(h.has_factor_copy());
    double e_h = 0, e_r = 0, e_s = 0, e_hs = 0;
    for (unsigned seed = 1; seed <= 3; ++seed) {
      const std::vector<double> b = random_vector(n, seed);
      std::vector<double> xd(n), xs(n), xhs(n), xh(n), xr(n);
      d.solve(b.data(), xd.data());
      s.solve_copy(b.data(), xs.data());
      h.solve(b.data(), xhs.data());
      h.solve_copy(b.data(), xh.data());
      r.solve_copy(b.data(), xr.data());
      EXPECT_EQ(xhs, xs);  // the float factor is kept
      e_h = std::max(e_h, rel_diff(xh, xd));
      e_r = std::max(e_r, rel_diff(xr, xd));
      e_s = std::max(e_s, rel_diff(xs, xd));
      e_hs = std::max(e_hs, rel_diff(xh, xs));
    }
    std::printf("[ %s: half copy of the float factor %.3g, of the double one %.3g, float factor %.3g; half against "
                "float %.3g ]\n",
                c.name, e_h, e_r, e_s, e_hs);
    EXPECT_LE(e_h, 1.5 * e_r + e_s);
    EXPECT_GT(e_hs, 0.3 * e_r);  // it reads the half copy, not the float factor
  }
  double rel = 1;
  const int it = static_beam_cg(FactorCopy::Half, /*through_copy=*/true, 60, &rel);
  std::printf("[ CG with the half copy of the float factor: %d iterations to %.2g ]\n", it, rel);
  EXPECT_LE(rel, 1e-12);
  EXPECT_LE(it, 12);  // 8 measured, as CHOLMOD's double factor rounded to half (HalfFactor)
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
  // The only non-positive pivot is that DOF's (test_cholmod_solver.cpp,
  // IndefiniteMatrixIsAnErrorNamingTheDof): the error names it, not its
  // position in the fill-reducing order.
  const std::vector<int> perm = f.permutation();
  int position = -1;
  for (int k = 0; k < n; ++k)
    if (perm[k] == bad_dof) position = k;
  const std::string expected = "at DOF " + std::to_string(bad_dof) + " (pivot " + std::to_string(position);
  try {
    f.factorize(A.data());
    ADD_FAILURE() << "an indefinite matrix was factored";
  } catch (const NumericalError& e) {
    EXPECT_EQ(e.dof, bad_dof);
    const std::string what = e.what();
    EXPECT_NE(what.find("not positive definite"), std::string::npos) << what;
    EXPECT_NE(what.find(expected), std::string::npos) << what << "\nexpected: " << expected;
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
