#include "engine/solve/cholmod_solver.h"

#include <dlfcn.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <type_traits>

#if defined(__AVX__)
#include <immintrin.h>
#endif

#include "engine/solve/block_recycler.h"
#include "engine/util/error.h"
#include "engine/solve/half.h"
#include "engine/util/headroom.h"
#include "engine/runtime/timing.h"

namespace incise {

namespace {
const char* ordering_name(int o) {
  switch (o) {
    case CHOLMOD_NATURAL: return "natural";
    case CHOLMOD_GIVEN: return "given";
    case CHOLMOD_AMD: return "AMD";
    case CHOLMOD_METIS: return "METIS";
    case CHOLMOD_NESDIS: return "NESDIS";
    case CHOLMOD_COLAMD: return "COLAMD";
    case CHOLMOD_POSTORDERED: return "postordered";
    default: return "unknown";
  }
}

// 4-wide double vectors (GCC/Clang vector extension; AVX with -march=native,
// pairs of SSE2 registers otherwise). Only used inside function bodies, never
// passed by value, so no ABI question arises.
typedef double D4 __attribute__((vector_size(32)));
typedef float F4 __attribute__((vector_size(16)));
#if defined(__AVX__)
// One vcvtps2pd from memory (GCC's generic conversion splits it in halves).
#define INCISE_LOAD_F4(dst, p) (dst) = _mm256_cvtps_pd(_mm_loadu_ps(p))
#else
#define INCISE_LOAD_F4(dst, p)                  \
  do {                                          \
    F4 f_;                                      \
    std::memcpy(&f_, (p), sizeof(F4));          \
    (dst) = __builtin_convertvector(f_, D4);    \
  } while (0)
#endif
// Four binary16 values (the half copy) as doubles: vcvtph2ps then vcvtps2pd.
#if defined(__AVX__) && defined(__F16C__)
#define INCISE_LOAD_H4(dst, p) (dst) = _mm256_cvtps_pd(_mm_cvtph_ps(_mm_loadl_epi64(reinterpret_cast<const __m128i*>(p))))
#else
#define INCISE_LOAD_H4(dst, p)                                                                          \
  do {                                                                                                  \
    (dst) = D4{half_bits_to_float((p)[0]), half_bits_to_float((p)[1]), half_bits_to_float((p)[2]),      \
               half_bits_to_float((p)[3])};                                                             \
  } while (0)
#endif
#define INCISE_LOAD4(dst, p)                                             \
  do {                                                                   \
    if constexpr (std::is_same_v<T, double>) {                           \
      std::memcpy(&(dst), (p), sizeof(D4));                              \
    } else if constexpr (std::is_same_v<T, float>) {                     \
      INCISE_LOAD_F4(dst, p);                                            \
    } else {                                                             \
      INCISE_LOAD_H4(dst, p);                                            \
    }                                                                    \
  } while (0)

// One stored value of L as a double (T = uint16_t: binary16 bits).
template <class T>
inline double stored_value(T v) {
  if constexpr (std::is_same_v<T, uint16_t>) {
#if defined(__F16C__)
    return _cvtsh_ss(v);
#else
    return half_bits_to_float(v);
#endif
  } else {
    return static_cast<double>(v);
  }
}

// Rows i..i+3 of the gathered vector w and of the four columns c0..c3 (both
// passes of the kernel below read this block).
template <class T>
__attribute__((always_inline)) inline void load_rows(const double* w, const T* c0, const T* c1, const T* c2,
                                                     const T* c3, int i, D4& v, D4& a0, D4& a1, D4& a2, D4& a3) {
  std::memcpy(&v, w + i, sizeof(D4));
  INCISE_LOAD4(a0, c0 + i);
  INCISE_LOAD4(a1, c1 + i);
  INCISE_LOAD4(a2, c2 + i);
  INCISE_LOAD4(a3, c3 + i);
}

// x = (P^T L L^T P)^-1 b with L supernodal: a dense column-major block of
// nsrow x nscol per supernode (rows Ls[pi[s]..pi[s+1]), the first nscol being
// the supernode's own columns), its values at Lx + px[s]. T is the stored
// precision of L (double, float for the float copy, uint16_t for the
// binary16 copy); y, w and every accumulation are double. y: n, w: the
// largest nsrow. inv_scale (nsuper, the half copy only, else null): supernode
// sn stores L_sn / s_sn, and with L_sn = s L' the solves need s only on the
// supernode's own rows: forward z1 = (L1'^-1 w1) / s with w2 -= L2' (L1'^-1
// w1), backward z1 = L1'^-T (w1 / s - L2'^T z2).
// Columns are taken four at a time: the forward pass updates each row of the
// gathered vector once per four columns, the backward pass runs four dot
// products (independent dependency chains) over the shared rows, so the loop
// is limited by reading L rather than by add latency.

// The arrays of a supernodal factor the kernels below read.
template <class T>
struct SnFactor {
  const int* super;  // (nsuper + 1) first column of each supernode
  const int* pi;     // (nsuper + 1) into Ls
  const int* px;     // (nsuper + 1) into Lx
  const int* Ls;     // row indices of each supernode
  const T* Lx;
  const double* inv_scale;
};

template <class T>
SnFactor<T> sn_factor(const cholmod_factor* L, const T* Lx, const double* inv_scale) {
  return {static_cast<const int*>(L->super), static_cast<const int*>(L->pi), static_cast<const int*>(L->px),
          static_cast<const int*>(L->s), Lx, inv_scale};
}

// Forward step of supernode sn: its columns of L z = y, then the update of the
// rows below (which belong to its ancestors' columns). w: nsrow scratch.
template <class T>
inline void forward_supernode(const SnFactor<T>& F, int sn, double* y, double* w) {
  auto d = [](T v) { return stored_value(v); };
  const int k1 = F.super[sn], nscol = F.super[sn + 1] - k1, psi = F.pi[sn], nsrow = F.pi[sn + 1] - psi;
  (void)k1;
  const T* B = F.Lx + F.px[sn];
  const int* Ls = F.Ls;
  for (int i = 0; i < nsrow; ++i) w[i] = y[Ls[psi + i]];
  int j = 0;
  for (; j + 4 <= nscol; j += 4) {
    const T* c0 = B + static_cast<size_t>(j) * nsrow;
    const T* c1 = c0 + nsrow;
    const T* c2 = c1 + nsrow;
    const T* c3 = c2 + nsrow;
    const double w0 = w[j] / d(c0[j]);
    const double w1 = (w[j + 1] - d(c0[j + 1]) * w0) / d(c1[j + 1]);
    const double w2 = (w[j + 2] - d(c0[j + 2]) * w0 - d(c1[j + 2]) * w1) / d(c2[j + 2]);
    const double w3 = (w[j + 3] - d(c0[j + 3]) * w0 - d(c1[j + 3]) * w1 - d(c2[j + 3]) * w2) / d(c3[j + 3]);
    w[j] = w0;
    w[j + 1] = w1;
    w[j + 2] = w2;
    w[j + 3] = w3;
    const D4 W0 = {w0, w0, w0, w0}, W1 = {w1, w1, w1, w1}, W2 = {w2, w2, w2, w2}, W3 = {w3, w3, w3, w3};
    int i = j + 4;
    for (; i + 4 <= nsrow; i += 4) {
      D4 v, a0, a1, a2, a3;
      load_rows(w, c0, c1, c2, c3, i, v, a0, a1, a2, a3);
      v -= a0 * W0 + a1 * W1 + a2 * W2 + a3 * W3;
      std::memcpy(w + i, &v, sizeof(D4));
    }
    for (; i < nsrow; ++i) w[i] -= d(c0[i]) * w0 + d(c1[i]) * w1 + d(c2[i]) * w2 + d(c3[i]) * w3;
  }
  for (; j < nscol; ++j) {
    const T* col = B + static_cast<size_t>(j) * nsrow;
    const double wj = w[j] / d(col[j]);
    w[j] = wj;
    for (int i = j + 1; i < nsrow; ++i) w[i] -= d(col[i]) * wj;
  }
  if (F.inv_scale)
    for (int jj = 0; jj < nscol; ++jj) w[jj] *= F.inv_scale[sn];
  for (int i = 0; i < nsrow; ++i) y[Ls[psi + i]] = w[i];
}

// Backward step of supernode sn: its columns of L^T z = y, reading the rows
// below (its ancestors' columns, already solved) and writing its own columns.
template <class T>
inline void backward_supernode(const SnFactor<T>& F, int sn, double* y, double* w) {
  auto d = [](T v) { return stored_value(v); };
  const int k1 = F.super[sn], nscol = F.super[sn + 1] - k1, psi = F.pi[sn], nsrow = F.pi[sn + 1] - psi;
  const T* B = F.Lx + F.px[sn];
  const int* Ls = F.Ls;
  for (int i = 0; i < nsrow; ++i) w[i] = y[Ls[psi + i]];
  if (F.inv_scale)
    for (int jj = 0; jj < nscol; ++jj) w[jj] *= F.inv_scale[sn];
  int j = nscol - 1;
  for (const int top = nscol - nscol % 4; j >= top; --j) {  // the last nscol % 4 columns one by one
    const T* col = B + static_cast<size_t>(j) * nsrow;
    double t = w[j];
    for (int i = j + 1; i < nsrow; ++i) t -= d(col[i]) * w[i];
    w[j] = t / d(col[j]);
  }
  for (; j >= 3; j -= 4) {  // columns j0..j0+3 = j-3..j
    const int j0 = j - 3;
    const T* c0 = B + static_cast<size_t>(j0) * nsrow;
    const T* c1 = c0 + nsrow;
    const T* c2 = c1 + nsrow;
    const T* c3 = c2 + nsrow;
    D4 A0 = {0, 0, 0, 0}, A1 = A0, A2 = A0, A3 = A0;
    int i = j + 1;
    for (; i + 4 <= nsrow; i += 4) {
      D4 v, a0, a1, a2, a3;
      load_rows(w, c0, c1, c2, c3, i, v, a0, a1, a2, a3);
      A0 += a0 * v;
      A1 += a1 * v;
      A2 += a2 * v;
      A3 += a3 * v;
    }
    double t0 = (A0[0] + A0[1]) + (A0[2] + A0[3]), t1 = (A1[0] + A1[1]) + (A1[2] + A1[3]);
    double t2 = (A2[0] + A2[1]) + (A2[2] + A2[3]), t3 = (A3[0] + A3[1]) + (A3[2] + A3[3]);
    for (; i < nsrow; ++i) {
      t0 += d(c0[i]) * w[i];
      t1 += d(c1[i]) * w[i];
      t2 += d(c2[i]) * w[i];
      t3 += d(c3[i]) * w[i];
    }
    const double x3 = (w[j0 + 3] - t3) / d(c3[j0 + 3]);
    const double x2 = (w[j0 + 2] - t2 - d(c2[j0 + 3]) * x3) / d(c2[j0 + 2]);
    const double x1 = (w[j0 + 1] - t1 - d(c1[j0 + 2]) * x2 - d(c1[j0 + 3]) * x3) / d(c1[j0 + 1]);
    const double x0 = (w[j0] - t0 - d(c0[j0 + 1]) * x1 - d(c0[j0 + 2]) * x2 - d(c0[j0 + 3]) * x3) / d(c0[j0]);
    w[j0] = x0;
    w[j0 + 1] = x1;
    w[j0 + 2] = x2;
    w[j0 + 3] = x3;
  }
  for (int jj = 0; jj < nscol; ++jj) y[k1 + jj] = w[jj];
}

template <class T>
void supernodal_substitute(const cholmod_factor* L, const T* Lx, const double* inv_scale, int n, const double* b,
                           double* x, double* y, double* w) {
  const SnFactor<T> F = sn_factor(L, Lx, inv_scale);
  const int* Perm = static_cast<const int*>(L->Perm);
  const int nsuper = static_cast<int>(L->nsuper);
  for (int k = 0; k < n; ++k) y[k] = b[Perm[k]];
  for (int sn = 0; sn < nsuper; ++sn) forward_supernode(F, sn, y, w);  // L z = y
  for (int sn = nsuper - 1; sn >= 0; --sn) backward_supernode(F, sn, y, w);  // L^T z = y
  for (int k = 0; k < n; ++k) x[Perm[k]] = y[k];
}

// Up to 16 right-hand sides at once, interleaved by row in NB blocks of four
// (Y[row * 4 NB + c], padded with zeros): each entry of L is read once for
// all of them, the column loop is four-wide SIMD, and four columns of L are
// applied per load of a row (as in the single kernels). Measured at 20k DOF
// (BM_SubstitutionColumns, float copy, one thread): 16 columns 28 ms against
// 109 ms one by one, 4 columns 10.8 against 25.9 ms. W: (nsrow, 4 NB) gather of
// the supernode's rows. The same arithmetic per column as
// forward_supernode / backward_supernode, summed in another order.
// The interleaved rows are 8-byte aligned only: loads and stores go through
// memcpy. ld4 returns a 32-byte vector, which without -mavx (the sanitizer
// build) GCC flags as an ABI change (-Wpsabi), here and at every use; it is
// always inlined in this file, so no call crosses an ABI (the pragma ends
// after supernodal_substitute_multi).
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpsabi"
__attribute__((always_inline)) inline D4 ld4(const double* p) {
  D4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}
__attribute__((always_inline)) inline void st4(double* p, const D4& v) { std::memcpy(p, &v, sizeof v); }
// c - a b and c + a b, fused where the target has FMA. Written out: left to
// GCC, -mtune=znver3 (avoid-fma-max-bits=256) fused some of these and not
// others by the shape of the loop around them, so a column's bits depended
// on its group's width (forty-first session). Macros, as D4 is never passed
// by value.
#ifdef __FMA__
#define INCISE_FNMA4(a, b, c) _mm256_fnmadd_pd(_mm256_set1_pd(a), (b), (c))
#define INCISE_FMA4(a, b, c) _mm256_fmadd_pd(_mm256_set1_pd(a), (b), (c))
#else
#define INCISE_FNMA4(a, b, c) ((c) - (a) * (b))
#define INCISE_FMA4(a, b, c) ((c) + (a) * (b))
#endif

template <class T, int NB>
void forward_supernode_multi(const SnFactor<T>& F, int sn, double* Y, double* W) {
  auto d = [](T v) { return stored_value(v); };
  constexpr int kp = 4 * NB;
  const int nscol = F.super[sn + 1] - F.super[sn], psi = F.pi[sn], nsrow = F.pi[sn + 1] - psi;
  const T* B = F.Lx + F.px[sn];
  const double sc = F.inv_scale ? F.inv_scale[sn] : 1.0;
  const auto row = [&](int i) { return W + static_cast<size_t>(i) * kp; };
  for (int i = 0; i < nsrow; ++i) std::memcpy(W + static_cast<size_t>(i) * kp, Y + static_cast<size_t>(F.Ls[psi + i]) * kp, sizeof(double) * kp);
  int j = 0;
  for (; j + 4 <= nscol; j += 4) {  // four columns at a time: each row below is loaded and stored once for them
    const T* c0 = B + static_cast<size_t>(j) * nsrow;
    const T* c1 = c0 + nsrow;
    const T* c2 = c1 + nsrow;
    const T* c3 = c2 + nsrow;
    D4 r0[NB], r1[NB], r2[NB], r3[NB];
    for (int b = 0; b < NB; ++b) {
      r0[b] = ld4(row(j) + 4 * b) / d(c0[j]);
      r1[b] = INCISE_FNMA4(d(c0[j + 1]), r0[b], ld4(row(j + 1) + 4 * b)) / d(c1[j + 1]);
      r2[b] = INCISE_FNMA4(d(c0[j + 2]), r0[b], ld4(row(j + 2) + 4 * b));
      r2[b] = INCISE_FNMA4(d(c1[j + 2]), r1[b], r2[b]) / d(c2[j + 2]);
      r3[b] = INCISE_FNMA4(d(c0[j + 3]), r0[b], ld4(row(j + 3) + 4 * b));
      r3[b] = INCISE_FNMA4(d(c1[j + 3]), r1[b], r3[b]);
      r3[b] = INCISE_FNMA4(d(c2[j + 3]), r2[b], r3[b]) / d(c3[j + 3]);
      st4(row(j) + 4 * b, r0[b] * sc);  // the update below uses the unscaled values
      st4(row(j + 1) + 4 * b, r1[b] * sc);
      st4(row(j + 2) + 4 * b, r2[b] * sc);
      st4(row(j + 3) + 4 * b, r3[b] * sc);
    }
    for (int i = j + 4; i < nsrow; ++i) {
      const double l0 = d(c0[i]), l1 = d(c1[i]), l2 = d(c2[i]), l3 = d(c3[i]);
      double* wi = row(i);
      for (int b = 0; b < NB; ++b) {
        D4 v = INCISE_FNMA4(l0, r0[b], ld4(wi + 4 * b));
        v = INCISE_FNMA4(l1, r1[b], v);
        v = INCISE_FNMA4(l2, r2[b], v);
        st4(wi + 4 * b, INCISE_FNMA4(l3, r3[b], v));
      }
    }
  }
  for (; j < nscol; ++j) {
    const T* col = B + static_cast<size_t>(j) * nsrow;
    D4 r[NB];
    for (int b = 0; b < NB; ++b) {
      r[b] = ld4(row(j) + 4 * b) / d(col[j]);
      st4(row(j) + 4 * b, r[b] * sc);
    }
    for (int i = j + 1; i < nsrow; ++i) {
      const double l = d(col[i]);
      double* wi = row(i);
      for (int b = 0; b < NB; ++b) st4(wi + 4 * b, INCISE_FNMA4(l, r[b], ld4(wi + 4 * b)));
    }
  }
  for (int i = 0; i < nsrow; ++i) std::memcpy(Y + static_cast<size_t>(F.Ls[psi + i]) * kp, W + static_cast<size_t>(i) * kp, sizeof(double) * kp);
}

template <class T, int NB>
void backward_supernode_multi(const SnFactor<T>& F, int sn, double* Y, double* W) {
  auto d = [](T v) { return stored_value(v); };
  constexpr int kp = 4 * NB;
  const int k1 = F.super[sn], nscol = F.super[sn + 1] - k1, psi = F.pi[sn], nsrow = F.pi[sn + 1] - psi;
  const T* B = F.Lx + F.px[sn];
  const auto row = [&](int i) { return W + static_cast<size_t>(i) * kp; };
  for (int i = 0; i < nsrow; ++i) std::memcpy(W + static_cast<size_t>(i) * kp, Y + static_cast<size_t>(F.Ls[psi + i]) * kp, sizeof(double) * kp);
  if (F.inv_scale)
    for (int q = 0; q < nscol * kp; ++q) W[q] *= F.inv_scale[sn];
  int j = nscol - 1;
  for (const int top = nscol - nscol % 4; j >= top; --j) {  // the last nscol % 4 columns one by one
    const T* col = B + static_cast<size_t>(j) * nsrow;
    D4 acc[NB];
    for (int b = 0; b < NB; ++b) acc[b] = ld4(row(j) + 4 * b);
    for (int i = j + 1; i < nsrow; ++i) {
      const double l = d(col[i]);
      const double* wi = row(i);
      for (int b = 0; b < NB; ++b) acc[b] = INCISE_FNMA4(l, ld4(wi + 4 * b), acc[b]);
    }
    for (int b = 0; b < NB; ++b) st4(row(j) + 4 * b, acc[b] / d(col[j]));
  }
  for (; j >= 3; j -= 4) {  // columns j0..j0+3 = j-3..j: each row below is loaded once for them
    const int j0 = j - 3;
    const T* c0 = B + static_cast<size_t>(j0) * nsrow;
    const T* c1 = c0 + nsrow;
    const T* c2 = c1 + nsrow;
    const T* c3 = c2 + nsrow;
    D4 a0[NB], a1[NB], a2[NB], a3[NB];
    for (int b = 0; b < NB; ++b) a0[b] = a1[b] = a2[b] = a3[b] = D4{0, 0, 0, 0};
    for (int i = j + 1; i < nsrow; ++i) {
      const double l0 = d(c0[i]), l1 = d(c1[i]), l2 = d(c2[i]), l3 = d(c3[i]);
      const double* wi = row(i);
      for (int b = 0; b < NB; ++b) {
        const D4 v = ld4(wi + 4 * b);
        a0[b] = INCISE_FMA4(l0, v, a0[b]);
        a1[b] = INCISE_FMA4(l1, v, a1[b]);
        a2[b] = INCISE_FMA4(l2, v, a2[b]);
        a3[b] = INCISE_FMA4(l3, v, a3[b]);
      }
    }
    for (int b = 0; b < NB; ++b) {
      const D4 x3 = (ld4(row(j0 + 3) + 4 * b) - a3[b]) / d(c3[j0 + 3]);
      const D4 x2 = INCISE_FNMA4(d(c2[j0 + 3]), x3, ld4(row(j0 + 2) + 4 * b) - a2[b]) / d(c2[j0 + 2]);
      D4 x1 = INCISE_FNMA4(d(c1[j0 + 2]), x2, ld4(row(j0 + 1) + 4 * b) - a1[b]);
      x1 = INCISE_FNMA4(d(c1[j0 + 3]), x3, x1) / d(c1[j0 + 1]);
      D4 x0 = INCISE_FNMA4(d(c0[j0 + 1]), x1, ld4(row(j0) + 4 * b) - a0[b]);
      x0 = INCISE_FNMA4(d(c0[j0 + 2]), x2, x0);
      x0 = INCISE_FNMA4(d(c0[j0 + 3]), x3, x0) / d(c0[j0]);
      st4(row(j0) + 4 * b, x0);
      st4(row(j0 + 1) + 4 * b, x1);
      st4(row(j0 + 2) + 4 * b, x2);
      st4(row(j0 + 3) + 4 * b, x3);
    }
  }
  std::memcpy(Y + static_cast<size_t>(k1) * kp, W, sizeof(double) * nscol * kp);
}

// Columns per pass of a multi-column substitution (CholmodSolver::substitute_multi):
// Y is (n, 16), W (largest supernode rows, 16); up to 24 for a half.
constexpr int kMultiGroup = 16;  // 8 measured the same at 20k (BM_SubstitutionColumns)
// With the worker free, up to 2 x 24 columns go in two halves: a probe's 48
// rows in two passes side by side instead of 16 + 16 on the caller and 16 on
// the worker (multi_groups).
constexpr int kSplitGroup = 24;
constexpr int kWidestGroup = kSplitGroup > kMultiGroup ? kSplitGroup : kMultiGroup;

// Columns c0 .. c0 + kg of B (n each), permuted, into Y (n, kp) row-interleaved (zeros past kg).
void load_group(const int* Perm, int n, int c0, int kg, int kp, const double* B, double* Y) {
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < kp; ++c) Y[static_cast<size_t>(r) * kp + c] = c < kg ? B[static_cast<size_t>(c0 + c) * n + Perm[r]] : 0.0;
}

void store_group(const int* Perm, int n, int c0, int kg, int kp, const double* Y, double* X) {
  for (int r = 0; r < n; ++r)
    for (int c = 0; c < kg; ++c) X[static_cast<size_t>(c0 + c) * n + Perm[r]] = Y[static_cast<size_t>(r) * kp + c];
}

// A group's substitution with nb four-column blocks; progress (if any)
// counts the supernodes done.
template <class T, int NB>
void substitute_group(const SnFactor<T>& F, int nsuper, double* Y, double* W, std::atomic<int>* progress) {
  int done = 0;
  for (int sn = 0; sn < nsuper; ++sn) {
    forward_supernode_multi<T, NB>(F, sn, Y, W);
    if (progress) progress->store(++done, std::memory_order_relaxed);
  }
  for (int sn = nsuper - 1; sn >= 0; --sn) {
    backward_supernode_multi<T, NB>(F, sn, Y, W);
    if (progress) progress->store(++done, std::memory_order_relaxed);
  }
}

template <class T>
void substitute_group(const SnFactor<T>& F, int nsuper, int nb, double* Y, double* W, std::atomic<int>* progress = nullptr) {
  switch (nb) {
    case 1: substitute_group<T, 1>(F, nsuper, Y, W, progress); break;
    case 2: substitute_group<T, 2>(F, nsuper, Y, W, progress); break;
    case 3: substitute_group<T, 3>(F, nsuper, Y, W, progress); break;
    case 4: substitute_group<T, 4>(F, nsuper, Y, W, progress); break;
    case 5: substitute_group<T, 5>(F, nsuper, Y, W, progress); break;
    default: substitute_group<T, 6>(F, nsuper, Y, W, progress); break;
  }
}

// The worker's group of a multi-column substitution, on its own Y2 and W2.
// The forward half of a group over the supernodes `path` only (forward_half_multi).
template <class T, int NB>
void forward_path(const SnFactor<T>& F, const std::vector<int>& path, double* Y, double* W, std::atomic<int>* progress) {
  int done = 0;
  for (int sn : path) {
    forward_supernode_multi<T, NB>(F, sn, Y, W);
    if (progress) progress->store(++done, std::memory_order_relaxed);
  }
}

template <class T>
void forward_path(const SnFactor<T>& F, const std::vector<int>& path, int nb, double* Y, double* W,
                  std::atomic<int>* progress = nullptr) {
  switch (nb) {
    case 1: forward_path<T, 1>(F, path, Y, W, progress); break;
    case 2: forward_path<T, 2>(F, path, Y, W, progress); break;
    case 3: forward_path<T, 3>(F, path, Y, W, progress); break;
    case 4: forward_path<T, 4>(F, path, Y, W, progress); break;
    case 5: forward_path<T, 5>(F, path, Y, W, progress); break;
    default: forward_path<T, 6>(F, path, Y, W, progress); break;
  }
}

template <class T>
void worker_multi(void* p) {
  auto& j = *static_cast<MultiJob*>(p);
  const SnFactor<T> F = sn_factor(j.L, static_cast<const T*>(j.Lx), j.inv_scale);
  if (j.path) forward_path<T>(F, *j.path, j.nb, j.Y2, j.W2, &j.progress);
  else substitute_group<T>(F, static_cast<int>(j.L->nsuper), j.nb, j.Y2, j.W2, &j.progress);
}

#undef INCISE_FNMA4
#undef INCISE_FMA4
#pragma GCC diagnostic pop

// The worker's bins (SubstitutionSplit::bins[1]) for split_substitute, on
// its private copy y2 (the caller's y stays the caller's, so a bin the caller
// gave up on and redid never races with it). Forward: the bin's columns and
// its updates of the top rows. Backward: the bin's columns, reading the top
// ones (y2 is a copy of y after the top was solved).
template <class T>
void worker_forward(void* p) {
  auto& j = *static_cast<SplitJob*>(p);
  const SnFactor<T> F = sn_factor(j.L, static_cast<const T*>(j.Lx), j.inv_scale);
  int done = 0;
  for (const auto& r : j.sp->bins[1])
    for (int sn = r.first; sn <= r.second; ++sn) {
      forward_supernode(F, sn, j.y2, j.w2);
      j.progress.store(++done, std::memory_order_relaxed);
    }
}

template <class T>
void worker_backward(void* p) {
  auto& j = *static_cast<SplitJob*>(p);
  const SnFactor<T> F = sn_factor(j.L, static_cast<const T*>(j.Lx), j.inv_scale);
  int done = 0;
  for (auto r = j.sp->bins[1].rbegin(); r != j.sp->bins[1].rend(); ++r)
    for (int sn = r->second; sn >= r->first; --sn) {
      backward_supernode(F, sn, j.y2, j.w2);
      j.progress.store(++done, std::memory_order_relaxed);
    }
}

template <class T>
void forward_bin(const SnFactor<T>& F, const SubstitutionSplit& sp, int k, double* y, double* w) {
  for (const auto& r : sp.bins[k])
    for (int sn = r.first; sn <= r.second; ++sn) forward_supernode(F, sn, y, w);
}

template <class T>
void backward_bin(const SnFactor<T>& F, const SubstitutionSplit& sp, int k, double* y, double* w) {
  for (auto r = sp.bins[k].rbegin(); r != sp.bins[k].rend(); ++r)
    for (int sn = r->second; sn >= r->first; --sn) backward_supernode(F, sn, y, w);
}

void copy_bin_columns(const cholmod_factor* L, const SubstitutionSplit& sp, int k, const double* from, double* to) {
  const int* super = static_cast<const int*>(L->super);
  for (const auto& r : sp.bins[k]) {
    const int c0 = super[r.first], c1 = super[r.second + 1];
    std::memcpy(to + c0, from + c0, sizeof(double) * (c1 - c0));
  }
}
#undef INCISE_LOAD4
#undef INCISE_LOAD_F4
#undef INCISE_LOAD_H4

// Debian's CHOLMOD runs parts of the supernodal factorization in OpenMP
// teams of a size fixed when it was compiled (4 here), whatever
// OMP_NUM_THREADS says: on a 2-core machine a factorization then ran four
// threads whose futex wake-ups and waits made it 2.4-3.8x slower (10k DOF:
// 130 against 53 ms) and took the stepping thread's core when it ran in the
// background. The engine's threading is explicit (solver.threads, the
// background job), so OpenMP regions run on the thread that enters them:
// max-active-levels 0 makes every parallel region inactive, for the duration
// of a CHOLMOD call (restored afterwards, so a host application's own OpenMP
// on that thread is untouched). The setting is per thread (an OpenMP 5
// data-environment ICV), so every call sets it. Looked up at run time: a
// CHOLMOD built without OpenMP needs nothing. INCISE_KEEP_OMP=1 in the
// environment keeps CHOLMOD's teams (to measure the difference).
class SerialOpenMpRegions {
 public:
  SerialOpenMpRegions() {
    if (!fns().set) return;
    saved_ = fns().get();
    fns().set(0);
  }
  ~SerialOpenMpRegions() {
    if (fns().set) fns().set(saved_);
  }
  SerialOpenMpRegions(const SerialOpenMpRegions&) = delete;
  SerialOpenMpRegions& operator=(const SerialOpenMpRegions&) = delete;

 private:
  struct Fns {
    void (*set)(int) = nullptr;
    int (*get)() = nullptr;
  };
  static const Fns& fns() {
    static const Fns f = [] {
      Fns r;
      if (std::getenv("INCISE_KEEP_OMP")) return r;
      r.get = reinterpret_cast<int (*)()>(dlsym(RTLD_DEFAULT, "omp_get_max_active_levels"));
      r.set = r.get ? reinterpret_cast<void (*)(int)>(dlsym(RTLD_DEFAULT, "omp_set_max_active_levels")) : nullptr;
      return r;
    }();
    return f;
  }
  int saved_ = 0;
};

// OpenBLAS's own threads off (one thread per call), once; looked up with
// dlsym so another BLAS needs nothing.
void single_thread_blas() {
  static const bool done = [] {
    if (auto set = reinterpret_cast<void (*)(int)>(dlsym(RTLD_DEFAULT, "openblas_set_num_threads"))) set(1);
    return true;
  }();
  (void)done;
}

}  // namespace

bool blas_concurrency_safe() {
  static const bool safe = [] {
    // openblas_get_parallel: 0 sequential build, 1 pthreads, 2 OpenMP.
    auto parallel = reinterpret_cast<int (*)()>(dlsym(RTLD_DEFAULT, "openblas_get_parallel"));
    return parallel && parallel() > 0;
  }();
  return safe;
}

CholmodSolver::CholmodSolver() {
  install_cholmod_block_recycler();  // before CHOLMOD's first allocation (block_recycler.h)
  single_thread_blas();
  cholmod_start(&c_);
  c_.supernodal = CHOLMOD_SUPERNODAL;
  c_.print = 0;
  c_.error_handler = nullptr;  // errors are read from c_.status and thrown
}

CholmodSolver::~CholmodSolver() {
  release();  // waits for a bin given up on (the worker outlives this object's use of it)
  cholmod_finish(&c_);
}

void CholmodSolver::configure(FactorMethod method, OrderingMethod ordering) {
  c_.supernodal = method == FactorMethod::Simplicial ? CHOLMOD_SIMPLICIAL : CHOLMOD_SUPERNODAL;
  if (method == FactorMethod::Simplicial) c_.final_ll = 1;  // L L^T, like the supernodal factor
  cholmod_common defaults;
  cholmod_start(&defaults);
  if (ordering == OrderingMethod::Auto) {
    c_.nmethods = defaults.nmethods;
    for (int k = 0; k < CHOLMOD_MAXMETHODS + 1; ++k) c_.method[k] = defaults.method[k];
  } else {
    c_.nmethods = 1;
    c_.method[0].ordering = ordering == OrderingMethod::Amd ? CHOLMOD_AMD : CHOLMOD_METIS;
  }
  cholmod_finish(&defaults);
}

void CholmodSolver::release() {
  settle();
  if (A_) cholmod_free_sparse(&A_, &c_);
  if (L_) cholmod_free_factor(&L_, &c_);
  if (B_) cholmod_free_dense(&B_, &c_);
  if (X_) cholmod_free_dense(&X_, &c_);
  if (Y_) cholmod_free_dense(&Y_, &c_);
  if (E_) cholmod_free_dense(&E_, &c_);
  factorized_ = false;
  copy_valid_ = false;
  single_current_ = false;
  single_.reset();
  work_y_.clear();
  work_w_.clear();
  work_y2_.clear();
  work_y3_.clear();
  split_ = SubstitutionSplit{};
}

void CholmodSolver::set_single_factorization(bool on) {
  if (on && copy_ == FactorCopy::None)
    throw Error("single-precision factorization: needs a factor copy (set_factor_copy(Float or Half) first)");
  single_numeric_ = on;
  stats_.single_precision = on;
}

void CholmodSolver::set_factor_copy(FactorCopy copy) {
  settle();
  if (single_numeric_ && copy == FactorCopy::None)
    throw Error("single-precision factorization: the factor lives in the copy; turn it off before the copy");
  copy_ = copy;
  copy_valid_ = false;  // the next factorize() converts
  if (copy != FactorCopy::Float && !single_numeric_) std::vector<float>().swap(Lx_single_);
  if (copy != FactorCopy::Half) {
    std::vector<uint16_t>().swap(Lx_half_);
    std::vector<double>().swap(half_inv_scale_);
  }
}

void CholmodSolver::analyze(int n, const std::vector<int>& Ap, const std::vector<int>& Ai, const std::vector<int>* perm) {
  release();
  n_ = n;
  const size_t nnz = Ai.size();
  if (perm && perm->size() != static_cast<size_t>(n))
    throw Error("CHOLMOD: a given ordering has " + std::to_string(perm->size()) + " entries for " + std::to_string(n) +
                " columns");
  A_ = cholmod_allocate_sparse(n, n, nnz, /*sorted=*/1, /*packed=*/1, /*stype=*/1, CHOLMOD_REAL, &c_);
  if (!A_) throw Error("CHOLMOD: out of memory allocating a " + std::to_string(n) + " x " + std::to_string(n) + " matrix");
  std::memcpy(A_->p, Ap.data(), sizeof(int) * (n + 1));
  if (nnz > 0) std::memcpy(A_->i, Ai.data(), sizeof(int) * nnz);  // (an empty patch after a cut: no entries, Ai.data() null)
  std::fill(static_cast<double*>(A_->x), static_cast<double*>(A_->x) + nnz, 0.0);
  const SerialOpenMpRegions serial;
  if (perm) {
    const int nmethods = c_.nmethods;
    const auto method0 = c_.method[0];
    c_.nmethods = 1;
    c_.method[0].ordering = CHOLMOD_GIVEN;
    L_ = cholmod_analyze_p(A_, const_cast<int*>(perm->data()), nullptr, 0, &c_);
    c_.nmethods = nmethods;
    c_.method[0] = method0;
  } else {
    L_ = cholmod_analyze(A_, &c_);
  }
  if (!L_ || c_.status < CHOLMOD_OK) throw Error("CHOLMOD: symbolic analysis failed (status " + std::to_string(c_.status) + ")");
  split_ = split_supernodes(L_);  // O(supernodes); used when a worker is set
  sn_of_col_.clear();
  sn_parent_.clear();
  iperm_.clear();
  if (L_->is_super) {  // forward_half_multi's tree: a supernode's parent holds its first row below its own columns
    const int* super = static_cast<const int*>(L_->super);
    const int* pi = static_cast<const int*>(L_->pi);
    const int* Ls = static_cast<const int*>(L_->s);
    const int* Perm = static_cast<const int*>(L_->Perm);
    const int nsuper = static_cast<int>(L_->nsuper);
    sn_of_col_.resize(n);
    sn_parent_.assign(nsuper, -1);
    iperm_.resize(n);
    for (int sn = 0; sn < nsuper; ++sn)
      for (int j = super[sn]; j < super[sn + 1]; ++j) sn_of_col_[j] = sn;
    for (int sn = 0; sn < nsuper; ++sn) {
      const int nscol = super[sn + 1] - super[sn];
      if (pi[sn + 1] - pi[sn] > nscol) sn_parent_[sn] = sn_of_col_[Ls[pi[sn] + nscol]];
    }
    for (int k = 0; k < n; ++k) iperm_[Perm[k]] = k;
    sn_mark_.assign(nsuper, 0);
  }
  stats_.nnz_L = c_.lnz;
  stats_.flops = c_.fl;
  // The method CHOLMOD kept (with nmethods = 0 it tries AMD, then METIS when AMD fills much).
  stats_.ordering = perm ? ordering_name(CHOLMOD_GIVEN)
                         : ordering_name(c_.selected >= 0 && c_.selected <= CHOLMOD_MAXMETHODS ? c_.method[c_.selected].ordering
                                                                                              : L_->ordering);
  stats_.supernodal = L_->is_super;
  stats_.factorizations = 0;
  stats_.factor_ms_total = 0;
  stats_.copy_conversions = 0;
  stats_.copy_ms_total = 0;
  stats_.single_fallbacks = 0;
  stats_.single_factorizations = 0;
  B_ = cholmod_zeros(n, 1, CHOLMOD_REAL, &c_);
}

std::vector<int> CholmodSolver::permutation() const {
  if (!L_) return {};
  const int* p = static_cast<const int*>(L_->Perm);
  return std::vector<int>(p, p + n_);
}

void CholmodSolver::factorize(const double* values) {
  if (!L_) throw Error("CHOLMOD: factorize called before analyze");
  settle();
  factorized_ = false;
  copy_valid_ = false;
  single_current_ = false;
  if (single_numeric_ && L_->is_super) {
    Stopwatch clock;
    if (!single_.analyzed()) single_.analyze(L_, n_, static_cast<const int*>(A_->p), static_cast<const int*>(A_->i));
    resize_with_headroom(Lx_single_, L_->xsize);  // no reallocation after the first (nor per cut: headroom.h)
    const long bad = single_.factorize(values, Lx_single_.data());
    stats_.factor_ms_total += clock.ms();
    ++stats_.factorizations;
    if (bad < 0) {
      ++stats_.single_factorizations;
      factorized_ = single_current_ = true;
      copy_valid_ = copy_ == FactorCopy::Float;
      stats_.stored_L = static_cast<double>(L_->xsize);
      if (copy_ == FactorCopy::Half) convert_copy(Lx_single_.data());  // the float factor, rounded once more
      return;
    }
    ++stats_.single_fallbacks;  // a pivot not positive in float: CHOLMOD in double decides
  }
  // The pattern's own count, not nzmax: CHOLMOD allocates at least one
  // entry, and an empty matrix (a lagged patch with no DOFs) comes with no
  // values at all (values == nullptr: reading nzmax of it crashed).
  const size_t nnz = static_cast<size_t>(static_cast<const int*>(A_->p)[n_]);
  if (nnz > 0) std::memcpy(A_->x, values, sizeof(double) * nnz);
  Stopwatch clock;
  {
    const SerialOpenMpRegions serial;
    cholmod_factorize(A_, L_, &c_);
  }
  stats_.factor_ms_total += clock.ms();
  ++stats_.factorizations;
  factorized_ = false;
  copy_valid_ = false;
  if (c_.status == CHOLMOD_NOT_POSDEF || L_->minor < static_cast<size_t>(n_)) {
    // L->minor is a column of the factor of P A P^T (the fill-reducing
    // order); Perm[k] is the column of A at position k, i.e. the DOF.
    const size_t k = L_->minor;
    const int* perm = static_cast<const int*>(L_->Perm);
    const long dof = k < static_cast<size_t>(n_) ? (perm ? perm[k] : static_cast<long>(k)) : -1;
    std::ostringstream os;
    os << "CHOLMOD: the system matrix is not positive definite";
    if (dof >= 0) os << " at DOF " << dof << " (pivot " << k << " of " << n_ << " in the fill-reducing order)";
    os << "; the model may be unconstrained in a static solve, a material parameter may be extreme, or an "
          "element is degenerate";
    throw NumericalError(os.str(), dof);
  }
  if (c_.status < CHOLMOD_OK) throw Error("CHOLMOD: numeric factorization failed (status " + std::to_string(c_.status) + ")");
  factorized_ = true;
  stats_.stored_L = static_cast<double>(L_->is_super ? L_->xsize : L_->nzmax);
  if (copy_ != FactorCopy::None && L_->is_super) convert_copy(static_cast<const double*>(L_->x));
}

// src: CHOLMOD's double factor, or (single_numeric_, Half) the float one.
template <class T>
void CholmodSolver::convert_copy(const T* src) {
  Stopwatch clock;
  const size_t nx = L_->xsize;
  if (copy_ == FactorCopy::Float) {  // (from double only: a float factor is its own copy)
    Lx_single_.resize(nx);  // same analysis: same xsize, no reallocation after the first
    float* dst = Lx_single_.data();
    for (size_t k = 0; k < nx; ++k) dst[k] = static_cast<float>(src[k]);
  } else {
    // Per supernode: s = the block's largest magnitude, values / s to binary16
    // (|v| <= 1: no overflow in any units; a relative 2^-11 rounding of the
    // entries that matter, those within a few decades of s).
    const int* px = static_cast<const int*>(L_->px);
    const size_t ns = L_->nsuper;
    resize_with_headroom(Lx_half_, nx);  // no reallocation per cut (headroom.h), as the float copy
    resize_with_headroom(half_inv_scale_, ns);
    uint16_t* dst = Lx_half_.data();
    for (size_t sn = 0; sn < ns; ++sn) {
      const size_t k0 = static_cast<size_t>(px[sn]), k1 = static_cast<size_t>(px[sn + 1]);
      double mx = 0.0;
      for (size_t k = k0; k < k1; ++k) mx = std::max(mx, std::fabs(static_cast<double>(src[k])));
      if (!(mx > 0.0) || !std::isfinite(mx)) mx = 1.0;  // a factorize() that succeeded has finite values
      const double inv = 1.0 / mx;
      half_inv_scale_[sn] = inv;
      size_t k = k0;
#if defined(__AVX__) && defined(__F16C__)
      const __m256d vinv = _mm256_set1_pd(inv);
      const auto load4 = [&](size_t at) {
        if constexpr (std::is_same_v<T, float>) return _mm256_cvtps_pd(_mm_loadu_ps(src + at));
        else return _mm256_loadu_pd(src + at);
      };
      for (; k + 8 <= k1; k += 8) {
        const __m128 lo = _mm256_cvtpd_ps(_mm256_mul_pd(load4(k), vinv));
        const __m128 hi = _mm256_cvtpd_ps(_mm256_mul_pd(load4(k + 4), vinv));
        _mm_storeu_si128(reinterpret_cast<__m128i*>(dst + k),
                         _mm256_cvtps_ph(_mm256_set_m128(hi, lo), _MM_FROUND_TO_NEAREST_INT | _MM_FROUND_NO_EXC));
      }
#endif
      for (; k < k1; ++k) dst[k] = float_to_half_bits(static_cast<float>(src[k] * inv));
    }
  }
  copy_valid_ = true;
  stats_.copy_ms_total += clock.ms();
  ++stats_.copy_conversions;
}

void CholmodSolver::prepare_workspace() {
  if (work_y_.size() != static_cast<size_t>(n_)) work_y_.assign(n_, 0.0);
  if (work_w_.empty()) {
    const int* pi = static_cast<const int*>(L_->pi);
    size_t mx = 0;
    for (size_t sn = 0; sn < L_->nsuper; ++sn) mx = std::max(mx, static_cast<size_t>(pi[sn + 1] - pi[sn]));
    work_w_.assign(mx + 1, 0.0);
  }
  if (substitutes_on_two_threads() && work_y2_.size() != static_cast<size_t>(n_)) {
    work_y2_.assign(n_, 0.0);
    work_y3_.assign(n_, 0.0);
    work_w2_.assign(work_w_.size(), 0.0);
    work_top_.assign(split_.top_cols.size(), 0.0);
  }
}

// The substitution on two threads (SubstitutionSplit): the two bins of
// independent subtrees at once, the top supernodes (their common ancestors)
// alone. Forward: the worker's bin updates its copy y2, whose bin columns are
// copied back and whose top rows are merged as y += y2 - y0; then the top.
// Backward: the top first, then both bins. When the worker makes no progress
// for kWorkerStallMs this thread does the worker's bin itself, and while a
// bin it gave up on still runs, all of them: on its own copy y3, from the
// same start values and merged the same way, so the result is the same to
// the bit whoever did the bin (a replay depends on it: docs/replay.md).
template <class T>
void CholmodSolver::split_substitute(const T* Lx, const double* inv_scale, const double* b, double* x) {
  SubstitutionWorker& worker = *worker_;
  const bool worker_free = !worker.busy();  // else a bin given up on still runs on y2
  ++stats_.split_substitutions;
  const SubstitutionSplit& sp = split_;
  const SnFactor<T> F = sn_factor(L_, Lx, inv_scale);
  const int* Perm = static_cast<const int*>(L_->Perm);
  double *y = work_y_.data(), *w = work_w_.data(), *y2 = work_y2_.data(), *y0_top = work_top_.data();
  for (int k = 0; k < n_; ++k) y[k] = b[Perm[k]];
  const size_t ntop = sp.top_cols.size();
  for (size_t i = 0; i < ntop; ++i) y0_top[i] = y[sp.top_cols[i]];
  const uint64_t started = worker_free ? start_bin(Lx, inv_scale, y, &worker_forward<T>) : 0;  // the worker's ticket
  forward_bin(F, sp, 0, y, w);
  const double* y1 = y2;  // where bin 1's forward result is
  if (!(started && worker.await(job_.progress, kWorkerStallMs))) {
    if (started) {
      ++stats_.takeovers;
      left_running_ = started;
    }
    // Bin 1 on y3 from the worker's start values: its own columns (bin 0 left
    // them untouched in y) and the top rows as they were.
    double* y3 = work_y3_.data();
    copy_bin_columns(L_, sp, 1, y, y3);
    for (size_t i = 0; i < ntop; ++i) y3[sp.top_cols[i]] = y0_top[i];
    forward_bin(F, sp, 1, y3, w);
    y1 = y3;
  }
  copy_bin_columns(L_, sp, 1, y1, y);
  for (size_t i = 0; i < ntop; ++i) y[sp.top_cols[i]] += y1[sp.top_cols[i]] - y0_top[i];
  for (int sn : sp.top) forward_supernode(F, sn, y, w);
  split_backward(Lx, inv_scale, y);
  for (int k = 0; k < n_; ++k) x[Perm[k]] = y[k];
}

// The worker's bin of a split pass on its copy y2 of y: job_ set, the task
// started; its ticket (0 if the worker did not take it).
template <class T>
uint64_t CholmodSolver::start_bin(const T* Lx, const double* inv_scale, const double* y, void (*task)(void*)) {
  std::memcpy(work_y2_.data(), y, sizeof(double) * n_);
  job_.L = L_;
  job_.Lx = Lx;
  job_.inv_scale = inv_scale;
  job_.sp = &split_;
  job_.y2 = work_y2_.data();
  job_.w2 = work_w2_.data();
  job_.progress.store(0, std::memory_order_relaxed);
  return worker_->try_start(task, &job_);
}

// L^T y' = y in place (permuted numbering): the top first, then the two bins,
// the worker's on its copy y2 when it is free (as split_substitute's forward
// half; the same bits whoever does the bin).
template <class T>
void CholmodSolver::split_backward(const T* Lx, const double* inv_scale, double* y) {
  SubstitutionWorker& worker = *worker_;
  const SubstitutionSplit& sp = split_;
  const SnFactor<T> F = sn_factor(L_, Lx, inv_scale);
  double *w = work_w_.data(), *y2 = work_y2_.data();
  for (auto it = sp.top.rbegin(); it != sp.top.rend(); ++it) backward_supernode(F, *it, y, w);
  // (a busy worker: a bin given up on still reads job_ and y2)
  const uint64_t started = worker.busy() ? 0 : start_bin(Lx, inv_scale, y, &worker_backward<T>);
  backward_bin(F, sp, 0, y, w);
  if (started && worker.await(job_.progress, kWorkerStallMs)) {
    copy_bin_columns(L_, sp, 1, y2, y);
  } else {
    if (started) {
      ++stats_.takeovers;
      left_running_ = started;
    }
    backward_bin(F, sp, 1, y, w);
  }
}

template <class T>
void CholmodSolver::backward_rows(const T* Lx, const double* inv_scale, const std::vector<int>& rows, const double* z,
                                  double* x) {
  double* y = work_y_.data();
  std::fill(y, y + n_, 0.0);
  for (size_t t = 0; t < rows.size(); ++t) y[rows[t]] = z[t];
  if (substitutes_on_two_threads()) {
    ++stats_.split_substitutions;
    split_backward(Lx, inv_scale, y);
  } else {
    const SnFactor<T> F = sn_factor(L_, Lx, inv_scale);
    for (int sn = static_cast<int>(L_->nsuper) - 1; sn >= 0; --sn) backward_supernode(F, sn, y, work_w_.data());
  }
  const int* Perm = static_cast<const int*>(L_->Perm);
  for (int k = 0; k < n_; ++k) x[Perm[k]] = y[k];
}

void CholmodSolver::backward_half(const std::vector<int>& rows, const double* z, double* x) {
  if (!factorized_) throw Error("CHOLMOD: solve called without a valid factorization");
  if (!L_->is_super) throw Error("CHOLMOD: backward_half needs the supernodal factor forward_half_multi read");
  prepare_workspace();
  with_substitution_factor([&](const auto* Lx, const double* inv_scale) { backward_rows(Lx, inv_scale, rows, z, x); });
}

template <class T>
void CholmodSolver::substitute(const T* Lx, const double* inv_scale, const double* b, double* x) {
  prepare_workspace();
  if (substitutes_on_two_threads())
    split_substitute(Lx, inv_scale, b, x);
  else
    supernodal_substitute(L_, Lx, inv_scale, n_, b, x, work_y_.data(), work_w_.data());
}

void CholmodSolver::set_substitution_worker(SubstitutionWorker* worker) {
  if (worker == worker_) return;
  settle();  // the old worker is still alive (set_substitution_worker's contract)
  worker_ = worker;
}

void CholmodSolver::settle() {
  if (const uint64_t t = left_running_.load(std::memory_order_acquire); t && worker_) worker_->wait(t);
  left_running_.store(0, std::memory_order_release);
}

void CholmodSolver::solve_cholmod(const double* b, double* x) {
  if (!factorized_) throw Error("CHOLMOD: solve called without a valid factorization");
  if (single_current_) throw Error("CHOLMOD: the current factor is single precision only (set_single_factorization); use solve()");
  std::memcpy(B_->x, b, sizeof(double) * n_);
  if (!cholmod_solve2(CHOLMOD_A, L_, B_, nullptr, &X_, nullptr, &Y_, &E_, &c_))
    throw Error("CHOLMOD: solve failed (status " + std::to_string(c_.status) + ")");
  std::memcpy(x, X_->x, sizeof(double) * n_);
}

void CholmodSolver::solve(const double* b, double* x) {
  if (!factorized_) throw Error("CHOLMOD: solve called without a valid factorization");
  if (!L_->is_super) {
    solve_cholmod(b, x);
    return;
  }
  if (single_current_) {  // no double factor exists
    substitute(Lx_single_.data(), nullptr, b, x);
    return;
  }
  substitute(static_cast<const double*>(L_->x), nullptr, b, x);
}

void CholmodSolver::solve_copy_multi(int k, const double* B, double* X) {
  if (!factorized_) throw Error("CHOLMOD: solve called without a valid factorization");
  if (k <= 0) return;
  if (!L_->is_super) {  // simplicial: column by column (cholmod_solve2)
    for (int c = 0; c < k; ++c) solve_copy(B + static_cast<size_t>(c) * n_, X + static_cast<size_t>(c) * n_);
    return;
  }
  settle();
  prepare_workspace();
  resize_with_headroom(multi_y_, static_cast<size_t>(n_) * kWidestGroup);
  resize_with_headroom(multi_w_, work_w_.size() * kWidestGroup);
  with_substitution_factor([&](const auto* Lx, const double* inv_scale) { substitute_multi(Lx, inv_scale, k, B, X); });
}

// The groups of up to 16 columns one after the other; with the substitution
// worker (two substitution threads) the second group on the worker, as a
// whole: with a probe's 23-27 contact rows the pass is compute-bound on one
// core (perf: its kernels and row interleave 17% of organ_instruments'
// run). The caller stores the worker's group into X only once await says
// it finished, and does it itself when the worker makes no progress (a
// group it gave up on may still run on Y2, W2: settle() before they or the
// factor change).
template <class T, class Load, class Pass, class Store>
void CholmodSolver::multi_groups(const T* Lx, const double* inv_scale, int k, const std::vector<int>* path,
                                 const Load& load, const Pass& pass, const Store& store) {
  // With the worker free, 2-48 columns go in two groups of half each (a
  // group's cost is its width: a grasp's 9 rows or a probe's 16 split too).
  // A column's arithmetic does not depend on its group: the same bits.
  const bool two = substitutes_on_two_threads() && !worker_->busy();
  const int size = two && k > 1 && k <= 2 * kSplitGroup ? (k + 1) / 2 : kMultiGroup;
  const int groups = (k + size - 1) / size;
  const auto width = [&](int g, int& c0, int& kg, int& nb) {
    c0 = g * size;
    kg = std::min(size, k - c0);
    nb = (kg + 3) / 4;
  };
  int c0, kg, nb;
  uint64_t started = 0;  // the worker's group's ticket
  const int wg = 1;  // the worker's group (the first is the caller's while the worker wakes)
  if (groups > wg && two) {
    width(wg, c0, kg, nb);
    resize_with_headroom(multi_y2_, multi_y_.size());
    resize_with_headroom(multi_w2_, multi_w_.size());
    load(c0, kg, 4 * nb, multi_y2_.data());
    multi_job_.L = L_;
    multi_job_.Lx = Lx;
    multi_job_.inv_scale = inv_scale;
    multi_job_.nb = nb;
    multi_job_.path = path;
    multi_job_.Y2 = multi_y2_.data();
    multi_job_.W2 = multi_w2_.data();
    multi_job_.progress.store(0, std::memory_order_relaxed);
    started = worker_->try_start(&worker_multi<T>, &multi_job_);
  }
  double *Y = multi_y_.data(), *W = multi_w_.data();
  for (int g = 0; g < groups; ++g) {
    if (started && g == wg) continue;
    width(g, c0, kg, nb);
    load(c0, kg, 4 * nb, Y);
    pass(nb, Y, W);
    store(c0, kg, 4 * nb, Y);
  }
  if (!started) return;
  width(wg, c0, kg, nb);
  if (worker_->await(multi_job_.progress, kWorkerStallMs)) {
    store(c0, kg, 4 * nb, multi_y2_.data());
    return;
  }
  ++stats_.takeovers;
  left_running_ = started;  // (it reads multi_y2_, and the path: settle() before either changes)
  load(c0, kg, 4 * nb, Y);  // (B's columns of that group are not written yet)
  pass(nb, Y, W);
  store(c0, kg, 4 * nb, Y);
}

template <class T>
void CholmodSolver::substitute_multi(const T* Lx, const double* inv_scale, int k, const double* B, double* X) {
  const SnFactor<T> F = sn_factor(L_, Lx, inv_scale);
  const int* Perm = static_cast<const int*>(L_->Perm);
  const int nsuper = static_cast<int>(L_->nsuper);
  multi_groups(
      Lx, inv_scale, k, nullptr, [&](int c0, int kg, int kp, double* Y) { load_group(Perm, n_, c0, kg, kp, B, Y); },
      [&](int nb, double* Y, double* W) { substitute_group<T>(F, nsuper, nb, Y, W); },
      [&](int c0, int kg, int kp, const double* Y) { store_group(Perm, n_, c0, kg, kp, Y, X); });
}

bool CholmodSolver::forward_half_multi(int k, const double* B, const std::vector<int>& nz, std::vector<int>& rows,
                                       std::vector<double>& Z) {
  if (!factorized_) throw Error("CHOLMOD: solve called without a valid factorization");
  if (!L_->is_super || sn_of_col_.empty()) return false;
  settle();
  prepare_workspace();
  const int* super = static_cast<const int*>(L_->super);
  // The supernodes on the paths from nz's columns up (each path stops at one
  // already marked: the rest of it is too).
  sn_path_.clear();
  for (int d : nz)
    for (int sn = sn_of_col_[iperm_[d]]; sn >= 0 && !sn_mark_[sn]; sn = sn_parent_[sn]) {
      sn_mark_[sn] = 1;
      sn_path_.push_back(sn);
    }
  std::sort(sn_path_.begin(), sn_path_.end());  // supernodes are numbered children first
  rows.clear();
  for (int sn : sn_path_) {
    sn_mark_[sn] = 0;
    for (int j = super[sn]; j < super[sn + 1]; ++j) rows.push_back(j);
  }
  resize_with_headroom(multi_y_, static_cast<size_t>(n_) * kWidestGroup);
  resize_with_headroom(multi_w_, work_w_.size() * kWidestGroup);
  with_substitution_factor([&](const auto* Lx, const double* inv_scale) { forward_half(Lx, inv_scale, k, B, rows, Z); });
  return true;
}

// Groups of up to 16 columns, each through the path's supernodes only (a
// row of Y outside `rows` is never read: a supernode's rows below its own
// columns are its ancestors' columns, on the path too); with the
// substitution worker free, two groups of half each, the second on the
// worker, as substitute_multi does (the same bits either way).
template <class T>
void CholmodSolver::forward_half(const T* Lx, const double* inv_scale, int k, const double* B,
                                 const std::vector<int>& rows, std::vector<double>& Z) {
  const SnFactor<T> F = sn_factor(L_, Lx, inv_scale);
  const int* Perm = static_cast<const int*>(L_->Perm);
  const size_t nr = rows.size();
  resize_with_headroom(Z, nr * static_cast<size_t>(k));
  multi_groups(
      Lx, inv_scale, k, &sn_path_,
      [&](int c0, int kg, int kp, double* Y) {
        for (int p : rows)
          for (int c = 0; c < kp; ++c)
            Y[static_cast<size_t>(p) * kp + c] = c < kg ? B[static_cast<size_t>(c0 + c) * n_ + Perm[p]] : 0.0;
      },
      [&](int nb, double* Y, double* W) { forward_path<T>(F, sn_path_, nb, Y, W); },
      [&](int c0, int kg, int kp, const double* Y) {
        for (int c = 0; c < kg; ++c)
          for (size_t t = 0; t < nr; ++t) Z[static_cast<size_t>(c0 + c) * nr + t] = Y[static_cast<size_t>(rows[t]) * kp + c];
      });
}

void CholmodSolver::solve_copy(const double* b, double* x) {
  if (!factorized_) throw Error("CHOLMOD: solve called without a valid factorization");
  if (!copy_valid_) {  // no copy, or a simplicial factor
    solve(b, x);
    return;
  }
  if (copy_ == FactorCopy::Half)
    substitute(Lx_half_.data(), half_inv_scale_.data(), b, x);
  else
    substitute(Lx_single_.data(), nullptr, b, x);
}

}  // namespace incise
