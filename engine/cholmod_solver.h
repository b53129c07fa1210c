#pragma once
// CHOLMOD supernodal Cholesky of a symmetric matrix stored as the upper
// triangle in compressed columns. The symbolic analysis (fill-reducing
// ordering, elimination tree, supernodes) is done once per sparsity pattern;
// numeric factorizations reuse it. Solves reuse their workspace
// (cholmod_solve2), so a frame allocates nothing here.
#include <string>
#include <vector>

#include <cholmod.h>

#include "engine/scene.h"

namespace incise {

struct FactorStats {
  double nnz_L = 0;        // entries in L (CHOLMOD's lnz)
  double flops = 0;        // flop count of one numeric factorization
  std::string ordering;    // the ordering CHOLMOD chose
  bool supernodal = true;
  int factorizations = 0;       // numeric factorizations done with this object
  double factor_ms_total = 0;   // their wall time (on whichever thread ran them)
};

class CholmodSolver {
 public:
  CholmodSolver();
  ~CholmodSolver();
  CholmodSolver(const CholmodSolver&) = delete;
  CholmodSolver& operator=(const CholmodSolver&) = delete;

  // Supernodal/simplicial and the fill-reducing ordering, before analyze.
  // Auto/Auto is CHOLMOD's default choice (AMD, or METIS when its fill is lower)
  // with the supernodal method.
  void configure(FactorMethod method, OrderingMethod ordering);
  // Symbolic analysis of the pattern (n x n, upper triangle, sorted rows).
  void analyze(int n, const std::vector<int>& Ap, const std::vector<int>& Ai);
  // Numeric factorization with these values (nnz). Throws incise::Error if the
  // matrix is not positive definite, naming the failing column (a DOF).
  void factorize(const double* values);
  // x = A^-1 b with the current factor (x and b may alias). A supernodal factor
  // is solved by our own substitution (no BLAS): Debian's serial OpenBLAS has
  // no locks, so BLAS must not run on two threads at once, and the lagged
  // policy's background factorization is BLAS-heavy. A simplicial factor goes
  // through cholmod_solve2 (which uses no BLAS for it).
  void solve(const double* b, double* x);
  // The same through cholmod_solve2 (reference for tests and timing).
  void solve_cholmod(const double* b, double* x);

  bool analyzed() const { return L_ != nullptr; }
  bool factorized() const { return factorized_; }
  int size() const { return n_; }
  const FactorStats& stats() const { return stats_; }

 private:
  cholmod_common c_;
  cholmod_sparse* A_ = nullptr;
  cholmod_factor* L_ = nullptr;
  cholmod_dense* B_ = nullptr;
  cholmod_dense* X_ = nullptr;
  cholmod_dense* Y_ = nullptr;  // solve2 workspace
  cholmod_dense* E_ = nullptr;  // solve2 workspace
  int n_ = 0;
  bool factorized_ = false;
  std::vector<double> work_y_, work_w_;  // own substitution: permuted vector, supernode gather
  FactorStats stats_;
  void release();
};

}  // namespace incise
