#pragma once
// Supernodal Cholesky factorization in single precision, on the supernodal
// symbolic analysis CHOLMOD made (ordering, supernodes, row structure: its
// L->super, L->pi, L->px, L->s), for the lagged policy's preconditioner
// (solver.factor_precision "single"). CHOLMOD 3 (Debian 12) factors in double
// only; its factor was then rounded to a float copy for the substitutions
// anyway. Factoring in float halves the bytes every update moves and doubles
// the width of each BLAS vector instruction (sgemm/ssyrk/strsm/spotrf).
//
// The algorithm is the left-looking supernodal one CHOLMOD's own numeric
// factorization uses (Davis, "Direct Methods for Sparse Linear Systems",
// SIAM 2006, sec. 9.1; Ng and Peyton 1993): supernodes in order; each
// gathers its columns of P A P^T, subtracts the updates of every earlier
// supernode with rows in its column range (one ssyrk + sgemm per such
// descendant, scattered through a relative map), then factors its diagonal
// block (spotrf) and solves its rows below (strsm). The result has CHOLMOD's
// supernodal layout, so CholmodSolver's substitutions read it unchanged.
//
// Accuracy: L L^T = P (A + E) P^T with |E| <~ c n u |L| |L^T|, u = 2^-24
// (Higham, "Accuracy and Stability of Numerical Algorithms", Thm 10.3): as
// a CG preconditioner only the iteration count can change, never the
// tolerance the solve reaches.
#include <cstdint>
#include <vector>

#include <cholmod.h>

namespace incise {

class SingleFactorization {
 public:
  // Prepares the scatter of A's entries (n x n, upper triangle in compressed
  // columns: Ap, Ai) into the supernodal layout of L, a supernodal symbolic
  // factor of the same pattern (cholmod_analyze). O(nnz(A) + nnz(L) rows).
  void analyze(const cholmod_factor* L, int n, const int* Ap, const int* Ai);
  bool analyzed() const { return n_ > 0; }
  void reset() { n_ = 0; }  // the symbolic factor it read is gone
  // Lx (L->xsize floats) <- the supernodal factor of P A P^T, A's values in
  // the pattern given to analyze. Returns -1, or the first permuted column
  // whose pivot was not positive (Lx is then partial; the DOF is
  // L->Perm[column]). Allocates nothing
  // after the first call of an analysis.
  long factorize(const double* values, float* Lx);
  // The same algorithm in double (allocates its update buffer): a check of
  // the algorithm against CHOLMOD's own double factor, not a product path.
  long factorize_double(const double* values, double* Lx);

 private:
  int n_ = 0;
  int nsuper_ = 0;
  const int* super_ = nullptr;  // (nsuper + 1) first column of each supernode (CHOLMOD's arrays, L outlives us)
  const int* pi_ = nullptr;     // (nsuper + 1) into ls_
  const int* px_ = nullptr;     // (nsuper + 1) into Lx
  const int* ls_ = nullptr;     // row indices of each supernode, its own columns first
  std::vector<int> col_super_;  // (n) supernode of each (permuted) column
  std::vector<int> a_ptr_;      // (nsuper + 1) into a_src_ / a_dst_
  std::vector<int> a_src_;      // (nnz(A)) A's entries grouped by the supernode they land in
  std::vector<int64_t> a_dst_;  // (nnz(A)) their position in Lx
  // Numeric workspace.
  std::vector<int> head_, next_, lpos_, map_, relmap_;
  std::vector<float> C_;  // one descendant's update, (rows below its first row in s) x (rows in s's columns)
  size_t c_size_ = 0;
  template <class T>
  long numeric(const double* values, T* Lx, T* C);
};

}  // namespace incise
