#include "engine/solve/single_factor.h"

#include <algorithm>
#include <cstring>

#include "engine/util/error.h"
#include "engine/util/headroom.h"

// Reference BLAS/LAPACK (OpenBLAS here), Fortran calling convention: CHOLMOD
// links the same libraries; the hidden string lengths are not read by them.
extern "C" {
void ssyrk_(const char* uplo, const char* trans, const int* n, const int* k, const float* alpha, const float* A,
            const int* lda, const float* beta, float* C, const int* ldc);
void sgemm_(const char* ta, const char* tb, const int* m, const int* n, const int* k, const float* alpha,
            const float* A, const int* lda, const float* B, const int* ldb, const float* beta, float* C,
            const int* ldc);
void strsm_(const char* side, const char* uplo, const char* ta, const char* diag, const int* m, const int* n,
            const float* alpha, const float* A, const int* lda, float* B, const int* ldb);
void spotrf_(const char* uplo, const int* n, float* A, const int* lda, int* info);
void dsyrk_(const char* uplo, const char* trans, const int* n, const int* k, const double* alpha, const double* A,
            const int* lda, const double* beta, double* C, const int* ldc);
void dgemm_(const char* ta, const char* tb, const int* m, const int* n, const int* k, const double* alpha,
            const double* A, const int* lda, const double* B, const int* ldb, const double* beta, double* C,
            const int* ldc);
void dtrsm_(const char* side, const char* uplo, const char* ta, const char* diag, const int* m, const int* n,
            const double* alpha, const double* A, const int* lda, double* B, const int* ldb);
void dpotrf_(const char* uplo, const int* n, double* A, const int* lda, int* info);
}

namespace incise {

namespace {

// The four kernels by precision (the double ones serve factorize_double, the
// algorithm's check against CHOLMOD).
void syrk(const int* n, const int* k, const float* A, const int* lda, float* C, const int* ldc) {
  const float one = 1.0f, zero = 0.0f;
  ssyrk_("L", "N", n, k, &one, A, lda, &zero, C, ldc);
}
void syrk(const int* n, const int* k, const double* A, const int* lda, double* C, const int* ldc) {
  const double one = 1.0, zero = 0.0;
  dsyrk_("L", "N", n, k, &one, A, lda, &zero, C, ldc);
}
void gemm_nt(const int* m, const int* n, const int* k, const float* A, const int* lda, const float* B, const int* ldb,
             float* C, const int* ldc) {
  const float one = 1.0f, zero = 0.0f;
  sgemm_("N", "T", m, n, k, &one, A, lda, B, ldb, &zero, C, ldc);
}
void gemm_nt(const int* m, const int* n, const int* k, const double* A, const int* lda, const double* B,
             const int* ldb, double* C, const int* ldc) {
  const double one = 1.0, zero = 0.0;
  dgemm_("N", "T", m, n, k, &one, A, lda, B, ldb, &zero, C, ldc);
}
void trsm_rltn(const int* m, const int* n, const float* A, const int* lda, float* B, const int* ldb) {
  const float one = 1.0f;
  strsm_("R", "L", "T", "N", m, n, &one, A, lda, B, ldb);
}
void trsm_rltn(const int* m, const int* n, const double* A, const int* lda, double* B, const int* ldb) {
  const double one = 1.0;
  dtrsm_("R", "L", "T", "N", m, n, &one, A, lda, B, ldb);
}
void potrf(const int* n, float* A, const int* lda, int* info) { spotrf_("L", n, A, lda, info); }
void potrf(const int* n, double* A, const int* lda, int* info) { dpotrf_("L", n, A, lda, info); }

// C (m x k, ld m) = X Y^T for small blocks (X: m x nc, ld ldx; Y: k x nc, ld
// ldx), where a BLAS call costs more than its flops: most descendant updates
// of a tet10 mesh are a few rows by a few columns.
template <class T>
void small_update(int m, int k, int nc, const T* X, const T* Y, int ldx, T* C) {
  for (int j = 0; j < k; ++j) {
    T* c = C + static_cast<size_t>(j) * m;
    for (int i = j; i < m; ++i) c[i] = T(0);  // lower part only: the scatter reads i >= j
    for (int t = 0; t < nc; ++t) {
      const T y = Y[j + static_cast<size_t>(t) * ldx];
      const T* x = X + static_cast<size_t>(t) * ldx;
      for (int i = j; i < m; ++i) c[i] += x[i] * y;
    }
  }
}

}  // namespace

void SingleFactorization::analyze(const cholmod_factor* L, int n, const int* Ap, const int* Ai) {
  if (!L || !L->is_super || static_cast<int>(L->n) != n)
    throw Error("single-precision factorization: needs a supernodal symbolic factor of the same size (" +
                std::to_string(n) + " columns)");
  n_ = 0;
  nsuper_ = static_cast<int>(L->nsuper);
  super_ = static_cast<const int*>(L->super);
  pi_ = static_cast<const int*>(L->pi);
  px_ = static_cast<const int*>(L->px);
  ls_ = static_cast<const int*>(L->s);
  const int* perm = static_cast<const int*>(L->Perm);
  std::vector<int> pinv(n);
  for (int k = 0; k < n; ++k) pinv[perm[k]] = k;
  assign_with_headroom(col_super_, n, 0);
  size_t max_rows = 0, max_c = 0;
  for (int s = 0; s < nsuper_; ++s) {
    for (int j = super_[s]; j < super_[s + 1]; ++j) col_super_[j] = s;
    const size_t nsrow = static_cast<size_t>(pi_[s + 1] - pi_[s]);
    const size_t below = nsrow - static_cast<size_t>(super_[s + 1] - super_[s]);
    max_rows = std::max(max_rows, nsrow);
    max_c = std::max(max_c, below * below);  // a descendant's update: at most its rows below its columns, squared
  }
  // A's entries by the supernode of their (permuted) column in L's lower triangle.
  const int nnz = Ap[n];
  std::vector<int> target_col(nnz), target_row(nnz);
  assign_with_headroom(a_ptr_, nsuper_ + 1, 0);
  for (int c = 0; c < n; ++c)
    for (int k = Ap[c]; k < Ap[c + 1]; ++k) {
      const int pr = pinv[Ai[k]], pc = pinv[c];
      target_col[k] = std::min(pr, pc);
      target_row[k] = std::max(pr, pc);
      ++a_ptr_[col_super_[target_col[k]] + 1];
    }
  for (int s = 0; s < nsuper_; ++s) a_ptr_[s + 1] += a_ptr_[s];
  assign_with_headroom(a_src_, nnz, 0);
  assign_with_headroom(a_dst_, nnz, 0);
  std::vector<int> fill(a_ptr_.begin(), a_ptr_.end() - 1);
  for (int k = 0; k < nnz; ++k) a_src_[fill[col_super_[target_col[k]]]++] = k;
  assign_with_headroom(map_, n, -1);
  for (int s = 0; s < nsuper_; ++s) {
    const int nsrow = pi_[s + 1] - pi_[s];
    for (int p = 0; p < nsrow; ++p) map_[ls_[pi_[s] + p]] = p;
    for (int t = a_ptr_[s]; t < a_ptr_[s + 1]; ++t) {
      const int k = a_src_[t];
      const int local_row = map_[target_row[k]];
      if (local_row < 0)
        throw Error("single-precision factorization: an entry of A is outside the symbolic factor's structure "
                    "(the analysis belongs to another pattern)");
      a_dst_[t] = px_[s] + local_row + static_cast<int64_t>(target_col[k] - super_[s]) * nsrow;
    }
    for (int p = 0; p < nsrow; ++p) map_[ls_[pi_[s] + p]] = -1;
  }
  assign_with_headroom(head_, nsuper_, -1);
  assign_with_headroom(next_, nsuper_, -1);
  assign_with_headroom(lpos_, nsuper_, 0);
  assign_with_headroom(relmap_, max_rows, 0);
  c_size_ = std::max<size_t>(max_c, 1);
  assign_with_headroom(C_, c_size_, 0.0f);
  n_ = n;
}

long SingleFactorization::factorize(const double* values, float* Lx) { return numeric(values, Lx, C_.data()); }

long SingleFactorization::factorize_double(const double* values, double* Lx) {
  std::vector<double> C(c_size_);
  return numeric(values, Lx, C.data());
}

template <class T>
long SingleFactorization::numeric(const double* values, T* Lx, T* C) {
  if (!analyzed()) throw Error("single-precision factorization: factorize called before analyze");
  std::fill(head_.begin(), head_.end(), -1);
  for (int s = 0; s < nsuper_; ++s) {
    const int k1 = super_[s], k2 = super_[s + 1], nscol = k2 - k1;
    const int psi = pi_[s], nsrow = pi_[s + 1] - psi;
    T* Ls = Lx + px_[s];  // nsrow x nscol, column-major
    for (int p = 0; p < nsrow; ++p) map_[ls_[psi + p]] = p;
    std::memset(Ls, 0, sizeof(T) * static_cast<size_t>(nsrow) * nscol);
    for (int t = a_ptr_[s]; t < a_ptr_[s + 1]; ++t) Lx[a_dst_[t]] = static_cast<T>(values[a_src_[t]]);
    // Updates of the descendants with rows in [k1, k2): Ls -= L_d(rows >= k1) L_d(rows in [k1, k2))^T.
    for (int d = head_[s]; d >= 0;) {
      const int dnext = next_[d];
      const int pdi = pi_[d], pdend = pi_[d + 1], ndrow = pdend - pdi, ndcol = super_[d + 1] - super_[d];
      const int p1 = pdi + lpos_[d];
      int p2 = p1;
      while (p2 < pdend && ls_[p2] < k2) ++p2;
      const int ndrow1 = p2 - p1, ndrow2 = pdend - p1;
      const T* L1 = Lx + px_[d] + (p1 - pdi);  // rows p1.. of d, ld ndrow
      // C (ndrow2 x ndrow1, ld ndrow2, lower part) = L1 L1(rows < ndrow1)^T
      if (static_cast<long>(ndrow2) * ndrow1 * ndcol < 4096) {
        small_update(ndrow2, ndrow1, ndcol, L1, L1, ndrow, C);
      } else {
        syrk(&ndrow1, &ndcol, L1, &ndrow, C, &ndrow2);
        const int ndrow3 = ndrow2 - ndrow1;
        if (ndrow3 > 0) gemm_nt(&ndrow3, &ndrow1, &ndcol, L1 + ndrow1, &ndrow, L1, &ndrow, C + ndrow1, &ndrow2);
      }
      for (int i = 0; i < ndrow2; ++i) relmap_[i] = map_[ls_[p1 + i]];
      for (int j = 0; j < ndrow1; ++j) {
        T* col = Ls + static_cast<size_t>(relmap_[j]) * nsrow;  // d's row in s's columns: local column relmap_[j]
        const T* c = C + static_cast<size_t>(j) * ndrow2;
        for (int i = j; i < ndrow2; ++i) col[relmap_[i]] -= c[i];
      }
      lpos_[d] = p2 - pdi;
      if (p2 < pdend) {  // d next updates the supernode of its next row
        const int dd = col_super_[ls_[p2]];
        next_[d] = head_[dd];
        head_[dd] = d;
      }
      d = dnext;
    }
    int info = 0;
    potrf(&nscol, Ls, &nsrow, &info);
    if (info != 0) {
      for (int p = 0; p < nsrow; ++p) map_[ls_[psi + p]] = -1;
      return info > 0 ? k1 + info - 1 : k1;
    }
    const int nsrow2 = nsrow - nscol;
    if (nsrow2 > 0) {
      trsm_rltn(&nsrow2, &nscol, Ls, &nsrow, Ls + nscol, &nsrow);
      lpos_[s] = nscol;
      const int dd = col_super_[ls_[psi + nscol]];
      next_[s] = head_[dd];
      head_[dd] = s;
    }
    for (int p = 0; p < nsrow; ++p) map_[ls_[psi + p]] = -1;
  }
  return -1;
}

}  // namespace incise
