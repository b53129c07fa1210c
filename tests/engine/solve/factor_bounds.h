#pragma once
// Roundoff bounds of supernodal Cholesky factors and of solves with them, for
// the reduced-precision tests (test_single_factor.cpp, float and binary16
// copies of the double factor; test_single_factorization.cpp, the factor
// computed in float). Every bound is computed from the matrix and its factor
// (unit roundoff times |L||L^T|, the longest inner product, ||A^-1||), not
// fixed to what one machine measured:
//
//  - Factor (Higham, "Accuracy and Stability of Numerical Algorithms", 2nd
//    ed., Thm 10.3): the computed L^ of P A P^T satisfies
//    L^ L^^T = P A P^T + dA with |dA| <= gamma_{r+1} |L^||L^^T| entrywise,
//    gamma_m = m u / (1 - m u), where r is the length of the longest inner
//    product the factorization forms: at most the largest number of entries
//    in a row of L (max_row_count; Thm 10.3 states it with n, the dense
//    case). This holds for any order of the summations (blocked BLAS, FMA).
//    factor_backward_error measures max |dA| / (|L^||L^^T|) on L's pattern
//    (which holds the patterns of A and of L L^T): an algorithm that drops
//    an update or uses a wrong pivot has an O(1) ratio there.
//  - Solve (Higham Thm 10.4 / 7.3, Oettli-Prager): x^ solves (A + dA) x^ = b
//    with |dA| <= E for the E of the factor's rounding, so the residual is
//    |b - A x^| <= E |x^| componentwise: the largest ratio omega
//    (solve_backward_error) is <= 1. The forward error follows as
//    ||x^ - x|| = ||A^-1 (b - A x^)|| <= ||A^-1||_2 omega ||E |x^| ||_2
//    (bound_norm): cond(A) times the backward error. With omega = 1 (the a
//    priori worst case, gamma_r with r in the hundreds) it exceeds 1 on the
//    static beam (cond ~5e5); with the omega measured it is a rigorous bound
//    on the forward error that a bug cannot escape either (omega <= 1 is
//    asserted, and a wrong pivot or a dropped update makes omega >> 1).
#include <algorithm>
#include <cmath>
#include <vector>

#include <cholmod.h>

#include "engine/fem/assemble.h"
#include "engine/model/model.h"
#include "engine/solve/cholmod_solver.h"
#include "tests/engine/test_util.h"

namespace incise::test {

constexpr double kUnitDouble = 1.1102230246251565e-16;  // 2^-53
constexpr double kUnitFloat = 5.9604644775390625e-08;   // 2^-24
constexpr double kUnitHalf = 4.8828125e-04;             // 2^-11

inline double gamma_bound(double m, double u) { return m * u / (1.0 - m * u); }

// CHOLMOD's supernodal layout: supernode s holds columns super[s] .. super[s+1]-1,
// rows ls[pi[s] ..] (its own columns first), values at px[s] column-major with
// leading dimension nsrow(s) (the upper part of the diagonal block unused).
struct Supernodes {
  int n = 0, nsuper = 0;
  const int *super = nullptr, *pi = nullptr, *px = nullptr, *ls = nullptr, *perm = nullptr;
  size_t xsize = 0;
  std::vector<int> col_super;  // (n) supernode of each permuted column
  explicit Supernodes(const cholmod_factor* L)
      : n(static_cast<int>(L->n)),
        nsuper(static_cast<int>(L->nsuper)),
        super(static_cast<const int*>(L->super)),
        pi(static_cast<const int*>(L->pi)),
        px(static_cast<const int*>(L->px)),
        ls(static_cast<const int*>(L->s)),
        perm(static_cast<const int*>(L->Perm)),
        xsize(L->xsize),
        col_super(n) {
    for (int s = 0; s < nsuper; ++s)
      for (int j = super[s]; j < super[s + 1]; ++j) col_super[j] = s;
  }
  int nscol(int s) const { return super[s + 1] - super[s]; }
  int nsrow(int s) const { return pi[s + 1] - pi[s]; }
  // Calls f(position in the values, row, column) for every entry of L's lower pattern.
  template <class F>
  void for_each_entry(F f) const {
    for (int s = 0; s < nsuper; ++s) {
      const int m = nsrow(s), k1 = super[s];
      for (int c = 0; c < nscol(s); ++c)
        for (int a = c; a < m; ++a) f(static_cast<size_t>(px[s]) + static_cast<size_t>(c) * m + a, ls[pi[s] + a], k1 + c);
    }
  }
};

// The most entries in one row of L: no inner product of the factorization
// (nor of L L^T) has more terms.
inline int max_row_count(const Supernodes& S) {
  std::vector<int> count(S.n, 0);
  for (int s = 0; s < S.nsuper; ++s)
    for (int a = 0; a < S.nsrow(s); ++a) count[S.ls[S.pi[s] + a]] += std::min(a + 1, S.nscol(s));
  return *std::max_element(count.begin(), count.end());
}

// max over L's pattern of |(P A P^T - L L^T)_ij| / (|L||L^T|)_ij for the
// factor values Lx (CHOLMOD's supernodal layout) of A (the model's upper
// triangle, values A). The products are summed in double.
template <class T>
double factor_backward_error(const Supernodes& S, const T* Lx, const Model& m, const std::vector<double>& A) {
  const size_t nx = S.xsize;
  std::vector<double> prod(nx, 0.0), absprod(nx, 0.0), Ap(nx, 0.0);
  std::vector<int> where(S.n, -1);
  int cur = -1;
  auto map_rows_of = [&](int t) {
    if (t == cur) return;
    for (int q = 0; q < S.nsrow(t); ++q) where[S.ls[S.pi[t] + q]] = q;
    cur = t;
  };
  for (int s = 0; s < S.nsuper; ++s) {
    const int m_s = S.nsrow(s), nc = S.nscol(s);
    const int* R = S.ls + S.pi[s];
    const T* V = Lx + S.px[s];
    for (int b = 0; b < m_s; ++b) {
      const int j = R[b], t = S.col_super[j];
      map_rows_of(t);
      const size_t tb = static_cast<size_t>(S.px[t]) + static_cast<size_t>(j - S.super[t]) * S.nsrow(t);
      const int cmax = std::min(b + 1, nc);  // the columns of s left of (or at) column j
      for (int a = b; a < m_s; ++a) {
        double sum = 0, asum = 0;
        for (int c = 0; c < cmax; ++c) {
          const double p = static_cast<double>(V[static_cast<size_t>(c) * m_s + a]) * V[static_cast<size_t>(c) * m_s + b];
          sum += p;
          asum += std::fabs(p);
        }
        const size_t pos = tb + where[R[a]];
        prod[pos] += sum;
        absprod[pos] += asum;
      }
    }
  }
  std::vector<int> pinv(S.n);
  for (int k = 0; k < S.n; ++k) pinv[S.perm[k]] = k;
  for (int c = 0; c < m.ndof(); ++c)
    for (int k = m.Ap[c]; k < m.Ap[c + 1]; ++k) {
      const int i = std::max(pinv[m.Ai[k]], pinv[c]), j = std::min(pinv[m.Ai[k]], pinv[c]);
      const int t = S.col_super[j];
      map_rows_of(t);
      Ap[static_cast<size_t>(S.px[t]) + static_cast<size_t>(j - S.super[t]) * S.nsrow(t) + where[i]] += A[k];
    }
  double worst = 0;
  S.for_each_entry([&](size_t pos, int, int) {
    if (absprod[pos] > 0) worst = std::max(worst, std::fabs(Ap[pos] - prod[pos]) / absprod[pos]);
  });
  return worst;
}

// y = W v (transpose: W^T v) for a lower-triangular W in the supernodal
// layout (values w), in the permuted numbering.
inline void lower_times(const Supernodes& S, const std::vector<double>& w, const std::vector<double>& v,
                        std::vector<double>& y, bool transpose) {
  y.assign(S.n, 0.0);
  for (int s = 0; s < S.nsuper; ++s) {
    const int m_s = S.nsrow(s), k1 = S.super[s];
    const int* R = S.ls + S.pi[s];
    for (int c = 0; c < S.nscol(s); ++c)
      for (int a = c; a < m_s; ++a) {
        const double x = w[static_cast<size_t>(S.px[s]) + static_cast<size_t>(c) * m_s + a];
        if (transpose)
          y[k1 + c] += x * v[R[a]];
        else
          y[R[a]] += x * v[k1 + c];
      }
  }
}

// The entrywise bound E of a solve's perturbation dA, as a sum of terms
// coef * W1 W2^T (W lower, supernodal layout, permuted), applied to vectors
// in the original numbering.
struct PerturbationBound {
  const Supernodes* S = nullptr;
  struct Term {
    double coef;
    const std::vector<double>* W1;
    const std::vector<double>* W2;
  };
  std::vector<Term> terms;
  std::vector<double> times(const std::vector<double>& x) const {
    const int n = S->n;
    std::vector<double> z(n), t, u, y(n, 0.0), out(n);
    for (int k = 0; k < n; ++k) z[k] = x[S->perm[k]];
    for (const Term& tm : terms) {
      lower_times(*S, *tm.W2, z, t, true);
      lower_times(*S, *tm.W1, t, u, false);
      for (int k = 0; k < n; ++k) y[k] += tm.coef * u[k];
    }
    for (int k = 0; k < n; ++k) out[S->perm[k]] = y[k];
    return out;
  }
};

// max_i |b - A x|_i / (E |x|)_i: <= 1 when x solves (A + dA) x = b with |dA| <= E.
inline double solve_backward_error(const Model& m, const std::vector<double>& A, const PerturbationBound& E,
                                   const std::vector<double>& x, const std::vector<double>& b) {
  const int n = m.ndof();
  std::vector<double> Ax(n), ax(n);
  sym_matvec(m, A.data(), x.data(), Ax.data());
  for (int i = 0; i < n; ++i) ax[i] = std::fabs(x[i]);
  const std::vector<double> Ex = E.times(ax);
  double worst = 0;
  for (int i = 0; i < n; ++i) {
    const double r = std::fabs(b[i] - Ax[i]);
    if (r > 0) worst = std::max(worst, Ex[i] > 0 ? r / Ex[i] : INFINITY);
  }
  return worst;
}

inline double norm2(const std::vector<double>& v) {
  double s = 0;
  for (double x : v) s += x * x;
  return std::sqrt(s);
}

// ||A^-1||_2 = 1 / lambda_min(A) by power iteration on A^-1 (solve: x = A^-1 b
// in double). The iterates rise to it from below; the loop runs until two
// successive ones agree to 1e-6, and the value returned is raised by 1e-3 to
// cover what remains.
template <class Solve>
double inverse_norm(int n, Solve solve) {
  std::vector<double> x = random_vector(n, 12), y(n);
  double prev = 0, est = 0;
  for (int it = 0; it < 500; ++it) {
    solve(x.data(), y.data());
    const double ny = norm2(y);
    est = ny / norm2(x);
    for (int i = 0; i < n; ++i) x[i] = y[i] / ny;
    if (it > 5 && std::fabs(est - prev) <= 1e-6 * est) break;
    prev = est;
  }
  return est * (1.0 + 1e-3);
}

// ||A||_inf (the largest row sum of |A|), >= ||A||_2 for a symmetric A.
inline double norm_inf(const Model& m, const std::vector<double>& A) {
  std::vector<double> row(m.ndof(), 0.0);
  for (int c = 0; c < m.ndof(); ++c)
    for (int k = m.Ap[c]; k < m.Ap[c + 1]; ++k) {
      row[c] += std::fabs(A[k]);
      if (m.Ai[k] != c) row[m.Ai[k]] += std::fabs(A[k]);
    }
  return *std::max_element(row.begin(), row.end());
}

// ||E |x| ||_2: with |b - A x| <= omega E |x| (omega = solve_backward_error),
// ||x - A^-1 b||_2 <= ||A^-1||_2 omega ||E |x| ||_2 (Higham Sec. 7.1).
inline double bound_norm(const PerturbationBound& E, const std::vector<double>& x) {
  std::vector<double> ax(x.size());
  for (size_t i = 0; i < x.size(); ++i) ax[i] = std::fabs(x[i]);
  return norm2(E.times(ax));
}

// |values| of a supernodal factor as doubles (the upper part of the diagonal blocks zero).
template <class T>
std::vector<double> abs_values(const Supernodes& S, const T* Lx) {
  std::vector<double> w(S.xsize, 0.0);
  S.for_each_entry([&](size_t pos, int, int) { w[pos] = std::fabs(static_cast<double>(Lx[pos])); });
  return w;
}

// The perturbation of a solve with a reduced-precision copy of CHOLMOD's
// double factor L (CholmodSolver::solve_copy), a priori from L and the copy's
// rounding: the copy is L + dL with |dL| <= M, where
//   float:    M = 2^-24 |L| (round to nearest),
//   binary16: M = (2^-11 + 2^-23) |L| + 2^-24 s, s the largest magnitude of
//             the entry's supernode (the copy rounds L / s to float, then to
//             binary16: relative 2^-11 + 2^-24 in the normal range; below
//             2^-14 s the subnormals' absolute 2^-25 s, flushing to 0 under it).
// Then (L + dL)(L + dL)^T - A = dL L^T + L dL^T + dL dL^T + (L L^T - A), so
// |dA| <= M|L^T| + |L|M^T + M M^T + gamma_{r+1}(2^-53) |L||L^T| (the double
// factor, Thm 10.3), plus gamma_{2r+1}(2^-53) (|L| + M)(|L| + M)^T for the
// two substitutions in double (Thm 8.5).
class CopyBound {
 public:
  CopyBound(const cholmod_factor* L, FactorCopy copy, double inv_norm)
      : sn(L), r(max_row_count(sn)), inv_norm_(inv_norm) {
    const double* Lx = static_cast<const double*>(L->x);
    absL = abs_values(sn, Lx);
    M.assign(sn.xsize, 0.0);
    for (int s = 0; s < sn.nsuper; ++s) {
      double mx = 0;
      for (int k = sn.px[s]; k < sn.px[s + 1]; ++k) mx = std::max(mx, absL[k]);
      for (int k = sn.px[s]; k < sn.px[s + 1]; ++k)
        M[k] = copy == FactorCopy::Half ? (kUnitHalf + 2 * kUnitFloat) * absL[k] + kUnitFloat * mx : kUnitFloat * absL[k];
    }
    Lp.resize(sn.xsize);
    for (size_t k = 0; k < sn.xsize; ++k) Lp[k] = absL[k] + M[k];
    const double gd = gamma_bound(r + 1, kUnitDouble), gs = gamma_bound(2 * r + 1, kUnitDouble);
    backward.S = reference.S = &sn;
    backward.terms = {{1.0, &M, &absL}, {1.0, &absL, &M}, {1.0, &M, &M}, {gd, &absL, &absL}, {gs, &Lp, &Lp}};
    reference.terms = {{gamma_bound(3 * r + 1, kUnitDouble), &absL, &absL}};
  }
  CopyBound(const CopyBound&) = delete;
  CopyBound& operator=(const CopyBound&) = delete;
  // The bound on |x_copy - x_double| / |x_double| for an x_copy whose
  // backward error (solve_backward_error with `backward`) is omega <= 1:
  // ||A^-1|| (omega ||E |x_copy| || + ||E_ref |x_copy| ||) / ||x_double||, E_ref
  // the double reference solve's own gamma_{3r+1}(2^-53) |L||L^T|.
  double forward_error(const std::vector<double>& x_copy, const std::vector<double>& x_double, double omega) const {
    return inv_norm_ * (omega * bound_norm(backward, x_copy) + bound_norm(reference, x_copy)) / norm2(x_double);
  }

  Supernodes sn;
  int r;
  std::vector<double> absL, M, Lp;
  PerturbationBound backward, reference;

 private:
  double inv_norm_;
};

}  // namespace incise::test
