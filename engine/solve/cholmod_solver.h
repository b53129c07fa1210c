#pragma once
// CHOLMOD supernodal Cholesky of a symmetric matrix stored as the upper
// triangle in compressed columns. The symbolic analysis (fill-reducing
// ordering, elimination tree, supernodes) is done once per sparsity pattern;
// numeric factorizations reuse it. Solves reuse their workspace
// (cholmod_solve2), so a frame allocates nothing here.
#include <atomic>
#include <cstdint>
#include <string>
#include <vector>

#include <cholmod.h>

#include "engine/scene/scene.h"
#include "engine/solve/single_factor.h"
#include "engine/solve/split_substitution.h"

namespace incise {

struct FactorStats {
  double nnz_L = 0;        // entries in L (CHOLMOD's lnz)
  double stored_L = 0;     // values stored for L after a factorization (supernodal: L->xsize, >= nnz_L)
  double flops = 0;        // flop count of one numeric factorization
  std::string ordering;    // the ordering CHOLMOD chose
  bool supernodal = true;
  int factorizations = 0;       // numeric factorizations done with this object
  double factor_ms_total = 0;   // their wall time (on whichever thread ran them)
  // Conversions of the factor to its reduced-precision copy (set_factor_copy) and
  // their total wall time, done inside factorize() on the same thread, after
  // factor_ms_total's clock stopped (so not included in it).
  int copy_conversions = 0;
  double copy_ms_total = 0;
  // set_single_factorization: numeric factorizations done in float, and those
  // that met a non-positive pivot in float and were redone by CHOLMOD in double.
  bool single_precision = false;
  int single_factorizations = 0;  // done in float (of `factorizations`)
  int single_fallbacks = 0;
  // Substitutions split over two threads, and bins of theirs this thread did
  // itself because the worker made no progress for kWorkerStallMs.
  int split_substitutions = 0;
  int takeovers = 0;
};

// How long a substitution's caller waits for a worker that makes no progress
// before doing its bin itself (CholmodSolver::set_substitution_worker). A
// bin's supernodes take microseconds each, and a woken worker starts within
// 0.1 ms in nine cases of ten here; a worker the kernel left runnable behind
// another thread of normal priority waited up to a 4 ms tick (HZ=250).
constexpr double kWorkerStallMs = 0.1;

// Whether BLAS may run on two threads at once: true for an OpenBLAS built
// with threading (Debian's libopenblas0-pthread or -openmp, whose buffer
// allocator is thread-safe), false for the serial build (measured: two
// supernodal factorizations on two threads gave wrong factors in 78-94 of
// 460 rounds, tests/engine/solve/test_cholmod_solver.cpp) and for any BLAS that does not
// say (no openblas_get_parallel). The first CholmodSolver also sets a
// threaded OpenBLAS to one thread per call: the engine's own threads already
// fill the cores, and the background factorization must not take the
// stepping thread's core.
bool blas_concurrency_safe();

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
  // With `perm` (perm[k] = the column eliminated k-th) that ordering is used
  // as given (CHOLMOD_GIVEN, still postordered): no ordering search.
  void analyze(int n, const std::vector<int>& Ap, const std::vector<int>& Ai, const std::vector<int>* perm = nullptr);
  // The fill-reducing permutation of the current analysis (perm[k] = the
  // column eliminated k-th); empty before analyze.
  std::vector<int> permutation() const;
  // Numeric factorization with these values (nnz). Throws incise::Error if the
  // matrix is not positive definite, naming the failing column (a DOF).
  void factorize(const double* values);
  // x = A^-1 b with the current factor (x and b may alias). A supernodal factor
  // is solved by our own substitution (no BLAS): a serial OpenBLAS is not
  // safe on two threads at once (measured: docs/numerics.md, "Solver"), the
  // lagged policy's background factorization is BLAS-heavy, and our loop
  // splits over two threads and reads a float copy. A simplicial factor goes
  // through cholmod_solve2 (which uses no BLAS for it).
  void solve(const double* b, double* x);
  // The same through cholmod_solve2 (reference for tests and timing).
  void solve_cholmod(const double* b, double* x);

  // Reduced-precision copy of the factor, for use as a preconditioner (the
  // lagged policy's CG): a substitution reads L twice, so its bytes set its
  // time. FactorCopy::Float rounds L's values to float (measured 1.2-1.4x
  // faster per substitution at 10-20k DOF, docs/benchmarks.md, Issue 4);
  // FactorCopy::Half to IEEE binary16 after dividing each supernode's block
  // by its largest magnitude (s, kept per supernode), so the 5-bit exponent
  // never overflows whatever the units, and entries below 6e-8 s flush to 0
  // (docs/numerics.md, "Half-precision factor copy"). Configure-time (default
  // None; takes effect at the next factorize()): factorize() converts a
  // supernodal factor's values (L->x) right after the numeric factorization,
  // on the thread that runs factorize(), with no BLAS; its time is
  // FactorStats::copy_ms_total (1.7-3% of a factorization). A simplicial
  // factor gets no copy. Turning it off frees the copy.
  void set_factor_copy(FactorCopy copy);
  FactorCopy factor_copy() const { return copy_; }
  void set_single_precision(bool on) { set_factor_copy(on ? FactorCopy::Float : FactorCopy::None); }
  bool single_precision() const { return copy_ != FactorCopy::None; }
  // Numeric factorizations in single precision (engine/solve/single_factor.h) on
  // CHOLMOD's supernodal analysis, straight into the float copy: no double
  // factor exists, solve() reads the float one. With the half copy the float
  // factor is then rounded to it (the substitutions read that). For a
  // preconditioner only (the lagged policy's solver.factor_precision
  // "single"). Needs a copy (set_factor_copy first; throws otherwise) and a supernodal
  // analysis (a simplicial one factors in double as before). A pivot that is
  // not positive in float is retried by CHOLMOD in double (counted in
  // FactorStats::single_fallbacks), so only a matrix that is not positive
  // definite in double throws. Takes effect at the next factorize().
  void set_single_factorization(bool on);
  bool single_factorization() const { return single_numeric_; }
  // x ~= A^-1 b by the same substitution as solve(), reading the copy (x and
  // b may alias). Vectors and accumulations stay double; only L's entries
  // are rounded (relative u = 2^-24 = 6e-8 in float, 2^-11 = 4.9e-4 in half),
  // so the result solves a perturbed system (A + E) x = b with |E| <~ u |L|
  // |L^T|: a relative error of at most about u * cond(A). Measured on tet10
  // beams of 3-7k DOF (cond 4e4-5e5, tests/engine/test_single_factor.cpp):
  // float 8e-9 to 8e-8 relative to solve(), half 4e-4 to 1e-3 (0.8-2 u). Meant as a
  // preconditioner (CG still converges to any tolerance, at worst in a few
  // more iterations), not as a direct solver for ill-conditioned systems.
  // Without a copy (None, or a simplicial factor) it is solve(). Allocates
  // nothing after the first call.
  void solve_copy(const double* b, double* x);
  // A copy of the current factor exists (solve_copy reads it).
  bool has_factor_copy() const { return factorized_ && copy_valid_; }
  // X = A^-1 B for k right-hand sides at once (B, X: n x k column-major, may
  // alias), through the copy when there is one (as solve_copy), else the
  // factor. A supernodal factor is read once per group of 16 columns (the
  // contact compliance's columns: a substitution's time is reading L, so k
  // columns cost far less than k substitutions); a simplicial one solves them
  // one by one. With the substitution worker (set_substitution_worker) the
  // second group runs on it, with the same bits. Allocates only when k or n
  // grows.
  void solve_copy_multi(int k, const double* B, double* X);

  // The forward half of solve_copy_multi for k columns B (n x k,
  // column-major) that are zero outside the DOFs `nz` (original numbering):
  // Z = L^-1 P B, so that B_i^T A^-1 B_j = Z_i . Z_j (A = P^T L L^T P; the
  // copy's, as solve_copy). Only the supernodes on the elimination-tree
  // paths from those DOFs to the roots are visited: the rest of Z is zero.
  // `rows` gets the permuted rows those supernodes hold (Z's only nonzero
  // rows) and Z (|rows| x k, column-major) their values. False, leaving both
  // untouched, for a simplicial factor (no supernodal tree): solve in full.
  bool forward_half_multi(int k, const double* B, const std::vector<int>& nz, std::vector<int>& rows,
                          std::vector<double>& Z);
  // The backward half to it: x = P^T L^-T z for z given on forward_half_multi's
  // `rows` (zero elsewhere), from the same factor. With z = Z c, x = A^-1 B c
  // (the copy's A, as solve_copy) for one read of L instead of two: the
  // contact stage's correction (contact_solve.cpp, lcp_round). On two
  // threads as solve_copy. Throws for a simplicial factor.
  void backward_half(const std::vector<int>& rows, const double* z, double* x);
  // Substitutions (solve, solve_copy) on two threads: this thread and the
  // worker (not owned; null = one thread), over the split of the current
  // analysis (engine/solve/split_substitution.h). Results equal the one-thread
  // substitution's to roundoff (the top rows add the two bins' updates in
  // another order), and are the same to the bit whichever thread did which
  // bin. A factor whose tree does not split stays on one thread.
  // This thread never waits for a worker that makes no progress: after
  // kWorkerStallMs without any it does the worker's bin itself (counted in
  // FactorStats::takeovers), and while a bin it gave up on still runs on
  // the worker, it does both bins itself; this object waits for
  // it before its factor, copies or buffers change, and in its destructor.
  // So a worker must outlive the solvers it was given to, or be taken from
  // them first (set_substitution_worker(nullptr)).
  void set_substitution_worker(SubstitutionWorker* worker);
  const SubstitutionSplit& substitution_split() const { return split_; }
  bool substitutes_on_two_threads() const { return worker_ && split_.valid() && L_ && L_->is_super; }

  bool analyzed() const { return L_ != nullptr; }
  // For tests' roundoff bounds: CHOLMOD's factor (its values are the double
  // factor unless single_factorization is on) and the float values (the
  // copy or the single factorization; null without), both in L's layout.
  const cholmod_factor* factor() const { return L_; }
  const float* float_values() const { return copy_valid_ && !Lx_single_.empty() ? Lx_single_.data() : nullptr; }
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
  std::vector<double> multi_y_, multi_w_;  // solve_copy_multi: (n, 16) and (largest supernode rows, 16), row-interleaved
  std::vector<double> multi_y2_, multi_w2_;  // the same for the worker's group
  MultiJob multi_job_;                       // what the worker's group reads (here: it may outlive the call)
  template <class T>
  void substitute_multi(const T* Lx, const double* inv_scale, int k, const double* B, double* X);
  // forward_half_multi: the supernodal tree of the current analysis (set by
  // analyze) and the visit's marks and list.
  std::vector<int> sn_of_col_;   // (n) supernode holding each permuted column
  std::vector<int> sn_parent_;   // (nsuper) parent supernode, -1 at a root
  std::vector<int> iperm_;       // (n) permuted position of each DOF
  std::vector<char> sn_mark_;    // (nsuper) on a path this call
  std::vector<int> sn_path_;     // the marked supernodes, ascending (children before parents)
  template <class T>
  void forward_half(const T* Lx, const double* inv_scale, int k, const double* B, const std::vector<int>& rows,
                    std::vector<double>& Z);
  // The groups of up to 16 columns of a multi-column pass (substitute_multi,
  // forward_half; path: the forward half's supernodes, null for a whole
  // substitution): load(c0, kg, kp, Y) interleaves a group's columns,
  // pass(nb, Y, W) runs it here, store(c0, kg, kp, Y) takes its results.
  template <class T, class Load, class Pass, class Store>
  void multi_groups(const T* Lx, const double* inv_scale, int k, const std::vector<int>* path, const Load& load,
                    const Pass& pass, const Store& store);
  SubstitutionWorker* worker_ = nullptr;   // set_substitution_worker
  SubstitutionSplit split_;                // of the current analysis
  std::vector<double> work_y2_, work_w2_, work_top_;  // the worker's y copy and gather, the top rows' start values
  std::vector<double> work_y3_;  // (n) this thread's copy for the worker's bin when it does it itself
  // What the worker's bin reads (here, not on the caller's stack: a bin
  // given up on may run after the call returned).
  SplitJob job_;
  // The ticket of a bin or group given up on, which may still run on worker_
  // (0: none). Atomic: a background factorization settles the slot it takes
  // over on its own thread.
  std::atomic<uint64_t> left_running_{0};
  void settle();  // waits for that task only: before the factor, the copies or the buffers change
  FactorCopy copy_ = FactorCopy::None;  // set_factor_copy
  bool copy_valid_ = false;              // the copy holds the current factor's values
  std::vector<float> Lx_single_;         // (L->xsize) Float: float copy of a supernodal L->x
  std::vector<uint16_t> Lx_half_;        // (L->xsize) Half: binary16 of L->x / s, s per supernode
  std::vector<double> half_inv_scale_;   // (L->nsuper) Half: 1 / s
  bool single_numeric_ = false;          // set_single_factorization
  bool single_current_ = false;          // the current factor exists in float only (Lx_single_)
  SingleFactorization single_;           // its scatter map and workspace, per analysis
  void prepare_workspace();
  template <class T>
  void split_substitute(const T* Lx, const double* inv_scale, const double* b, double* x);
  // f(Lx, inv_scale) with the values the substitutions read: the binary16
  // copy with its scales, the float copy, or CHOLMOD's double factor.
  template <class F>
  void with_substitution_factor(const F& f) {
    if (copy_valid_ && copy_ == FactorCopy::Half)
      f(Lx_half_.data(), half_inv_scale_.data());
    else if (copy_valid_ || single_current_)
      f(Lx_single_.data(), static_cast<const double*>(nullptr));
    else
      f(static_cast<const double*>(L_->x), static_cast<const double*>(nullptr));
  }
  template <class T>
  void split_backward(const T* Lx, const double* inv_scale, double* y);
  template <class T>
  uint64_t start_bin(const T* Lx, const double* inv_scale, const double* y, void (*task)(void*));
  template <class T>
  void backward_rows(const T* Lx, const double* inv_scale, const std::vector<int>& rows, const double* z, double* x);
  template <class T>
  void substitute(const T* Lx, const double* inv_scale, const double* b, double* x);
  template <class T>
  void convert_copy(const T* src);  // L's values (L->xsize) into the copy
  FactorStats stats_;
  void release();
};

}  // namespace incise
