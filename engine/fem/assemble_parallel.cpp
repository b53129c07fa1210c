#include "engine/fem/assemble_parallel.h"

#include <algorithm>
#include <cassert>
#include <cmath>
#include <cstring>

#include <Eigen/Core>

#include "engine/fem/assemble.h"
#include "engine/util/headroom.h"
#include "engine/fem/node_block_matvec.h"
#include "engine/fem/polar.h"
#include "engine/fem/rotation_stiffness.h"

namespace incise {

namespace {

// Rotation slots of each element (counting sort of rot_elem) and the largest element.
void element_slots(const Model& m, AssemblyPlan& p) {
  p.elem_rot_ptr.assign(m.nelem + 1, 0);
  for (int r = 0; r < m.nrot; ++r) ++p.elem_rot_ptr[m.rot_elem[r] + 1];
  for (int e = 0; e < m.nelem; ++e) p.elem_rot_ptr[e + 1] += p.elem_rot_ptr[e];
  p.elem_rot.assign(m.nrot, 0);
  {
    std::vector<int> next(p.elem_rot_ptr.begin(), p.elem_rot_ptr.end() - 1);
    for (int r = 0; r < m.nrot; ++r) p.elem_rot[next[m.rot_elem[r]]++] = r;
  }
  for (int e = 0; e < m.nelem; ++e) p.max_elem_nodes = std::max(p.max_elem_nodes, m.elem_dof_ptr[e + 1] - m.elem_dof_ptr[e]);
  p.slot_volume.assign(m.nrot, 0.0);
  for (size_t q = 0; q < m.qp_rot.size(); ++q)
    if (!m.qp_extension[q]) p.slot_volume[m.qp_rot[q]] += m.qp_weight[q];
}

// Block of each element: slabs of equal element count across the longest
// axis of the mesh's bounding box (by element centroid), so the separator
// layer is the smallest cross-section. Enriched DOF nodes (X = 0) do not move
// centroids much: the corner nodes dominate.
std::vector<int> slab_blocks(const Model& m, int T) {
  std::vector<int> block_of(m.nelem, 0);
  if (T <= 1) return block_of;
  double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
  for (int node = 0; node < m.nnode; ++node)
    for (int d = 0; d < 3; ++d) {
      lo[d] = std::min(lo[d], m.X[3 * node + d]);
      hi[d] = std::max(hi[d], m.X[3 * node + d]);
    }
  int axis = 0;
  for (int d = 1; d < 3; ++d)
    if (hi[d] - lo[d] > hi[axis] - lo[axis]) axis = d;
  std::vector<std::pair<double, int>> key(m.nelem);
  for (int e = 0; e < m.nelem; ++e) {
    double c = 0.0;
    int cnt = 0;
    for (int k = m.elem_dof_ptr[e]; k < m.elem_dof_ptr[e + 1]; ++k)
      if (m.elem_dof_node[k] < m.nnode) c += m.X[3 * m.elem_dof_node[k] + axis], ++cnt;
    key[e] = {cnt ? c / cnt : 0.0, e};
  }
  std::sort(key.begin(), key.end());
  for (int t = 0; t < T; ++t) {
    int b, e;
    ThreadPool::split(m.nelem, T, t, b, e);
    for (int k = b; k < e; ++k) block_of[key[k].second] = t;
  }
  return block_of;
}

// Fills block_ptr/block_elem with each block's interior elements and returns
// the separators: a DOF node touched by two blocks makes its elements separators.
std::vector<int> split_blocks(const Model& m, const std::vector<int>& block_of, AssemblyPlan& p) {
  std::vector<int> node_block(m.ndofnode, -1);  // -2 = touched by several blocks
  for (int e = 0; e < m.nelem; ++e)
    for (int k = m.elem_dof_ptr[e]; k < m.elem_dof_ptr[e + 1]; ++k) {
      int& nb = node_block[m.elem_dof_node[k]];
      if (nb == -1) nb = block_of[e];
      else if (nb != block_of[e]) nb = -2;
    }
  std::vector<std::vector<int>> blocks(p.nthreads);
  std::vector<int> separators;
  for (int e = 0; e < m.nelem; ++e) {
    bool interior = true;
    for (int k = m.elem_dof_ptr[e]; k < m.elem_dof_ptr[e + 1]; ++k) interior = interior && node_block[m.elem_dof_node[k]] >= 0;
    (interior ? blocks[block_of[e]] : separators).push_back(e);
  }
  p.block_ptr.assign(1, 0);
  for (auto& b : blocks) {
    p.block_elem.insert(p.block_elem.end(), b.begin(), b.end());
    p.block_ptr.push_back(static_cast<int>(p.block_elem.size()));
  }
  return separators;
}

// Greedy colouring of the separators (the smallest colour none of its nodes
// has yet) into color_ptr/color_elem.
void color_separators(const Model& m, const std::vector<int>& separators, AssemblyPlan& p) {
  std::vector<std::vector<int>> node_colors(m.ndofnode);
  std::vector<int> color(separators.size());
  int ncolor = 0;
  std::vector<char> used;
  for (size_t s = 0; s < separators.size(); ++s) {
    const int e = separators[s];
    used.assign(ncolor + 1, 0);
    for (int k = m.elem_dof_ptr[e]; k < m.elem_dof_ptr[e + 1]; ++k)
      for (int c : node_colors[m.elem_dof_node[k]]) used[c] = 1;
    int c = 0;
    while (used[c]) ++c;
    color[s] = c;
    ncolor = std::max(ncolor, c + 1);
    for (int k = m.elem_dof_ptr[e]; k < m.elem_dof_ptr[e + 1]; ++k) node_colors[m.elem_dof_node[k]].push_back(c);
  }
  p.color_ptr.assign(ncolor + 1, 0);
  for (int c : color) ++p.color_ptr[c + 1];
  for (int c = 0; c < ncolor; ++c) p.color_ptr[c + 1] += p.color_ptr[c];
  p.color_elem.assign(separators.size(), 0);
  std::vector<int> next(p.color_ptr.begin(), p.color_ptr.end() - 1);
  for (size_t s = 0; s < separators.size(); ++s) p.color_elem[next[color[s]]++] = separators[s];
}

// Each worker's element scratch, sized for the largest element.
void size_scratch(const Model& m, AssemblyPlan& p) {
  for (int e = 0; e < m.nelem; ++e) {
    p.max_elem_slots = std::max(p.max_elem_slots, p.elem_rot_ptr[e + 1] - p.elem_rot_ptr[e]);
    for (int k = p.elem_rot_ptr[e]; k < p.elem_rot_ptr[e + 1]; ++k)  // slots numbered element by element
      assert(p.elem_rot[k] == p.elem_rot[p.elem_rot_ptr[e]] + (k - p.elem_rot_ptr[e]));
  }
  const int n = p.max_elem_nodes;
  p.scratch.assign(p.nthreads, std::vector<double>(18 * n + 9 * n * (n + 1) / 2 + 9 * p.max_elem_slots + 16));
}

// A point whose slot is its own with the same gradients (tet10 per_point)
// has the F its rotation was extracted from: element_terms keeps it.
void slot_F_flags(const Model& m, AssemblyPlan& p) {
  p.qp_slot_F.assign(m.qp_rot.size(), 0);
  std::vector<int> users(m.nrot, 0);
  for (int r : m.qp_rot) ++users[r];
  for (size_t q = 0; q < m.qp_rot.size(); ++q) {
    const int r = m.qp_rot[q];
    const int len = m.qp_grad_ptr[q + 1] - m.qp_grad_ptr[q];
    p.qp_slot_F[q] = users[r] == 1 && m.rot_grad_ptr[r + 1] - m.rot_grad_ptr[r] == len &&
                     std::memcmp(&m.qp_grad[m.qp_grad_ptr[q]], &m.rot_grad[m.rot_grad_ptr[r]], len * sizeof(double)) == 0;
  }
}

// Condensed elements: every slot has a rest stiffness (Model::rot_K0).
void condensed_elements(const Model& m, AssemblyPlan& p) {
  p.elem_condensed.assign(m.nelem, 0);
  if (m.rot_K0_ptr.empty()) return;
  for (int e = 0; e < m.nelem; ++e) {
    bool all = p.elem_rot_ptr[e + 1] > p.elem_rot_ptr[e];
    for (int k = p.elem_rot_ptr[e]; k < p.elem_rot_ptr[e + 1]; ++k)
      all = all && m.rot_K0_ptr[p.elem_rot[k] + 1] > m.rot_K0_ptr[p.elem_rot[k]];
    p.elem_condensed[e] = all;
  }
}

// sym_matvec: ranges of whole node columns (node_block_matvec) of about
// equal nnz; workers t > 0 scatter into their own buffer.
void matvec_ranges(const Model& m, AssemblyPlan& p) {
  const int T = p.nthreads;
  p.matvec_col_ptr.assign(T + 1, m.ndof());
  p.matvec_col_ptr[0] = 0;
  for (int t = 1, c = 0; t < T; ++t) {
    const long long target = static_cast<long long>(m.nnz()) * t / T;
    while (c < m.ndof() && m.Ap[c] < target) c += 3;
    p.matvec_col_ptr[t] = std::min(c, m.ndof());
  }
  p.matvec_buf.assign(T, std::vector<double>());
  for (int t = 1; t < T; ++t) p.matvec_buf[t].assign(m.ndof(), 0.0);
}

}  // namespace

AssemblyPlan make_assembly_plan(const Model& m, int nthreads) {
  AssemblyPlan p;
  p.nthreads = std::max(1, nthreads);
  element_slots(m, p);
  const std::vector<int> separators = split_blocks(m, slab_blocks(m, p.nthreads), p);
  color_separators(m, separators, p);
  size_scratch(m, p);
  p.qp_own_rot = point_rotation_flags(m);
  slot_F_flags(m, p);
  p.slot_weight = shared_slot_weights(m);
  condensed_elements(m, p);
  matvec_ranges(m, p);
  p.body_sums.assign(p.nthreads, std::vector<double>(3 * static_cast<size_t>(m.nbody), 0.0));
  // Room after each worker's sums, so no two workers' sums share a cache line.
  for (auto& b : p.body_sums) b.reserve(b.size() + 16);
  return p;
}

namespace {

using Mat3 = Eigen::Matrix3d;

// F(i, j) = sum_a x[3a + i] g[3a + j], column-major.
template <int NN>
inline void grad_sum(int n_dyn, const double* x, const double* g, double* F) {
  const int n = NN > 0 ? NN : n_dyn;
  double f[9] = {0, 0, 0, 0, 0, 0, 0, 0, 0};
  for (int a = 0; a < n; ++a)
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) f[i + 3 * j] += x[3 * a + i] * g[3 * a + j];
  std::memcpy(F, f, sizeof f);
}

// Deformation gradients are kept as G = F - I = sum_a u_a g_a^T (u: the
// element's DOF nodes' displacements). sum_a X_a g_a^T = I holds at every
// point and slot by construction (the isoparametric map; enriched and branch
// DOF nodes have X = 0). Summing positions X_a + u_a instead loses |X| / h
// digits to cancellation, and forming I + G loses G's below eps: strain
// errors of 1e-14 and 1e-16, stress errors E times that, which stopped the
// static solve of a beam at E = 1e8 Pa at 2.5e-8 of its load (2e11: 5e-5).
inline void add_identity(const double* G, double* F) {
  std::memcpy(F, G, 9 * sizeof(double));
  F[0] += 1.0, F[4] += 1.0, F[8] += 1.0;
}

// P = w R sig(E); sig = mu (E + E^T) + lambda tr(E) I, E = R^T G, or with
// `strain` (G = F - I) R^T F - I = R^T G + (R^T - I): the strain formed
// without the cancellation of R^T F - I.
inline void rotated_stress(const double* R, const double* G, double w, double mu, double lambda, bool strain, double* P) {
  const Eigen::Map<const Mat3> Rm(R), Gm(G);
  Mat3 E = Rm.transpose() * Gm;
  if (strain) E += Rm.transpose() - Mat3::Identity();
  Mat3 sig = mu * (E + E.transpose());
  sig.diagonal().array() += lambda * E.trace();
  Eigen::Map<Mat3> Pm(P);
  Pm.noalias() = w * (Rm * sig);
}

// A condensed slot (Model::rot_K0, over k nodes: the npe mesh nodes in the
// piece's displacements d_a = in_a + in_{p(a)}, p = the slot's partner list,
// or all the element's DOF nodes with p = -1):
// t_a = sum_b K0_ab (R^T d_b + (R^T - I) X_b), the piece's R^T x - X with
// in = displacements (not positions: see add_identity), and out
// gains R t_a at a and at p(a) (X = null: the product R^ K0 R^T in). K0 holds blocks
// a <= b, row-major; y and t are (k, 3) scratch.
void condensed_slot_force(int k, const double* K0, const int* partner, const double* R, const double* in,
                          const double* X, const int* nodes, double* y, double* t, double* out) {
  const Eigen::Map<const Mat3> Rm(R);
  const Mat3 RtmI = Rm.transpose() - Mat3::Identity();
  for (int a = 0; a < k; ++a) {
    Eigen::Vector3d d = Eigen::Map<const Eigen::Vector3d>(in + 3 * a);
    if (partner[a] >= 0) d += Eigen::Map<const Eigen::Vector3d>(in + 3 * partner[a]);
    Eigen::Map<Eigen::Vector3d> ya(y + 3 * a);
    ya.noalias() = Rm.transpose() * d;
    if (X) ya.noalias() += RtmI * Eigen::Map<const Eigen::Vector3d>(X + 3 * nodes[a]);
  }
  // t = K0 y from the upper blocks: (a, b) adds K_ab y_b to t_a and K_ab^T y_a to t_b.
  std::fill(t, t + 3 * k, 0.0);
  const double* blk = K0;
  for (int a = 0; a < k; ++a)
    for (int b = a; b < k; ++b, blk += 9) {
      const double* yb = y + 3 * b;
      for (int i = 0; i < 3; ++i) t[3 * a + i] += blk[3 * i] * yb[0] + blk[3 * i + 1] * yb[1] + blk[3 * i + 2] * yb[2];
      if (b == a) continue;
      const double* ya = y + 3 * a;
      for (int j = 0; j < 3; ++j) t[3 * b + j] += blk[j] * ya[0] + blk[3 + j] * ya[1] + blk[6 + j] * ya[2];
    }
  for (int a = 0; a < k; ++a) {
    const Eigen::Vector3d v = Rm * Eigen::Map<const Eigen::Vector3d>(t + 3 * a);
    Eigen::Map<Eigen::Vector3d>(out + 3 * nodes[a]) += v;
    if (partner[a] >= 0) Eigen::Map<Eigen::Vector3d>(out + 3 * nodes[partner[a]]) += v;
  }
}

// Kl (the element's n DOF nodes, blocks i <= j, row-major) += E^T R^ K0 R^T E
// with E the map d_a = u_a + q_{p(a)}: each block B = R K0_ab R^T lands on
// (a, b), (a, p(b)), (p(a), b) and (p(a), p(b)), transposed where the row
// node comes after the column node; for a = b (B symmetric) the (p(a), a)
// copy is (a, p(a))'s transpose and is not added again.
void condensed_slot_stiffness(int n, int k, const double* K0, const int* partner, const double* R, double* Kl) {
  const Eigen::Map<const Mat3> Rm(R);
  const auto at = [n](int i, int j) { return 9 * (i * n - i * (i - 1) / 2 + (j - i)); };
  const double* k0 = K0;
  for (int a = 0; a < k; ++a)
    for (int b = a; b < k; ++b, k0 += 9) {
      const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> K(k0);
      const Eigen::Matrix<double, 3, 3, Eigen::RowMajor> B = Rm * K * Rm.transpose();
      const int I[2] = {a, partner[a]}, J[2] = {b, partner[b]};
      for (int i : I)
        for (int j : J) {
          if (i < 0 || j < 0 || (a == b && i > j)) continue;
          if (i <= j) Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(Kl + at(i, j)) += B;
          else Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(Kl + at(j, i)) += B.transpose();
        }
    }
}

// K += the element's blocks Kl; with a cache, K += Kl - kept (when `cached`)
// and Kl is kept.
inline void scatter_blocks(const Model& m, int e, int nblk, const double* Kl, double* K, TangentCache* cache,
                           bool cached) {
  const int* sc = &m.elem_scatter[m.elem_scatter_ptr[e]];
  if (!cache) {
    for (int k = 0; k < 9 * nblk; ++k)
      if (sc[k] >= 0) K[sc[k]] += Kl[k];
    return;
  }
  double* kept = &cache->Kl[cache->kl_ptr[e]];
  for (int k = 0; k < 9 * nblk; ++k) {
    if (sc[k] >= 0) K[sc[k]] += cached ? Kl[k] - kept[k] : Kl[k];
    kept[k] = Kl[k];
  }
}

// Fetches the element's lines of K ahead of the scatter into it. The scatter
// misses the caches (K is 3-6 MB at 10-20k DOF, and the frame's solves stream
// 12-28 MB of factor between two assemblies; perf put 28% of element_terms on
// the load of K[sc[k]]): fetched now, the lines arrive while the element's
// rotations and blocks are computed. Entries (0,0), (1,1), (2,2) of a 3x3
// block lie in its three columns, whose three rows are contiguous. organ-20k
// drag, one thread, three alternating pairs: fastest assembly 24.6-26.5 ->
// 23.6-24.2 ms.
inline void prefetch_element_K(const Model& m, int e, double* K) {
  const int* sc = &m.elem_scatter[m.elem_scatter_ptr[e]];
  const int nsc = m.elem_scatter_ptr[e + 1] - m.elem_scatter_ptr[e];
  for (int k = 0; k < nsc; k += 9)
    for (int c = 0; c < 9; c += 4)
      if (sc[k + c] >= 0) __builtin_prefetch(K + sc[k + c], 1, 3);
}

// The rotations of element e's slots (identity for the linear model), each
// from its slot's F = I + G, G = sum_a u_a g_a^T, which Fs (slots, 9) keeps
// (as G) for the points that share it (qp_slot_F); four slots at a time (a
// tet10's points: extract_rotations' lanes). keep (in/out) stays true
// while every |F - cache F| <= theta (a NaN: false); `probe` compares into
// would_keep instead and stores F (as G) in the cache. Returns the SVD
// fallbacks.
template <int NN>
inline int element_rotations(const Model& m, const AssemblyPlan& plan, int e, int n, const double* ue, double* Rall,
                             double* Fs, TangentCache* cache, bool probe, bool& keep, bool& would_keep) {
  const int k0 = plan.elem_rot_ptr[e], k1 = plan.elem_rot_ptr[e + 1];
  if (m.material.model == MaterialModel::Linear) {
    for (int k = k0; k < k1; ++k) Eigen::Map<Mat3>(Rall + 9 * plan.elem_rot[k]).setIdentity();
    return 0;
  }
  int fallbacks = 0;
  for (int c = k0; c < k1; c += 4) {
    const int count = std::min(4, k1 - c);
    double Ff[36], Rr[36];  // (count, 9)
    for (int j = 0; j < count; ++j) {
      const int r = plan.elem_rot[c + j];
      double* F = Fs + 9 * (c + j - k0);  // G, F - I
      grad_sum<NN>(n, ue, &m.rot_grad[m.rot_grad_ptr[r]], F);
      add_identity(F, Ff + 9 * j);
      std::copy(Rall + 9 * r, Rall + 9 * r + 9, Rr + 9 * j);
    }
    fallbacks += extract_rotations(count, Ff, Rr);
    for (int j = 0; j < count; ++j) {
      const int r = plan.elem_rot[c + j];
      std::copy(Rr + 9 * j, Rr + 9 * j + 9, Rall + 9 * r);
      const double* F = Fs + 9 * (c + j - k0);
      if (keep)
        for (int i = 0; i < 9; ++i)
          if (!(std::fabs(F[i] - cache->F[9 * static_cast<size_t>(r) + i]) <= cache->theta)) keep = false;
      if (probe) {
        double* Fr = &cache->F[9 * static_cast<size_t>(r)];
        for (int i = 0; i < 9; ++i)
          if (!(std::fabs(F[i] - Fr[i]) <= cache->theta)) would_keep = false;
        std::copy(F, F + 9, Fr);
      }
    }
  }
  return fallbacks;
}

// Kl (nblk blocks) = 0 plus the rotation term of each shared slot with
// slot_weight > 0 (h, t: scratch); with a cache, stores each slot's F, the F
// the new blocks are made at.
template <int NN>
inline void slot_rotation_terms(const Model& m, const AssemblyPlan& plan, int e, int n, const double* ue,
                                const double* Rall, TangentCache* cache, double* Kl, double* h, double* t) {
  std::fill(Kl, Kl + 9 * (n * (n + 1) / 2), 0.0);
  if (m.material.model == MaterialModel::Linear) return;
  for (int k = plan.elem_rot_ptr[e]; k < plan.elem_rot_ptr[e + 1]; ++k) {
    const int r = plan.elem_rot[k];
    const bool store_F = cache != nullptr;
    if (!store_F && !(plan.slot_weight[r] > 0.0)) continue;
    double G[9], F[9];
    grad_sum<NN>(n, ue, &m.rot_grad[m.rot_grad_ptr[r]], G);
    if (store_F) std::copy(G, G + 9, cache->F.begin() + 9 * static_cast<size_t>(r));
    add_identity(G, F);
    if (plan.slot_weight[r] > 0.0)  // a shared slot's rotation term (h is free until the points)
      add_slot_rotation_stiffness(n, Rall + 9 * r, F, &m.rot_grad[m.rot_grad_ptr[r]], m.mu, m.lambda,
                                  plan.slot_weight[r], Kl, h, t, plan.exact_rotation_term);
  }
}

// A split element: its pieces' rest stiffness rotated (Model::rot_K0, over d
// or over all its DOF nodes) gives
// the forces into f and, with Kl, the blocks (y, t: scratch).
inline void condensed_element_terms(const Model& m, const AssemblyPlan& plan, int e, int n, const int* nodes,
                                    const double* ue, const double* Rall, double* f, double* Kl, double* y, double* t) {
  for (int k = plan.elem_rot_ptr[e]; k < plan.elem_rot_ptr[e + 1]; ++k) {
    const int r = plan.elem_rot[k];
    const double* K0 = &m.rot_K0[m.rot_K0_ptr[r]];
    const int* partner = m.slot_partner(r);
    condensed_slot_force(m.slot_K0_nodes(r), K0, partner, Rall + 9 * r, ue, m.X.data(), nodes, y, t, f);
    if (Kl) condensed_slot_stiffness(n, m.slot_K0_nodes(r), K0, partner, Rall + 9 * r, Kl);
  }
}

// y += a split element's pieces' R K0 R^T v (ve: v at its nodes; t1, t2: (k, 3) scratch).
inline void condensed_element_matvec(const Model& m, const AssemblyPlan& plan, int e, const int* nodes,
                                     const double* Rall, const double* ve, double* y, double* t1, double* t2) {
  for (int k = plan.elem_rot_ptr[e]; k < plan.elem_rot_ptr[e + 1]; ++k) {
    const int r = plan.elem_rot[k];
    condensed_slot_force(m.slot_K0_nodes(r), &m.rot_K0[m.rot_K0_ptr[r]], m.slot_partner(r), Rall + 9 * r, ve, nullptr, nodes,
                         t1, t2, y);
  }
}

// f_a += P g_a for the element's n DOF nodes (P the point's weighted stress).
template <int NN>
inline void add_point_force(int n_dyn, const int* nodes, const double* P, const double* g, double* f) {
  const int n = NN > 0 ? NN : n_dyn;
  for (int a = 0; a < n; ++a) {
    const double g0 = g[3 * a], g1 = g[3 * a + 1], g2 = g[3 * a + 2];
    double* fa = f + 3 * nodes[a];
    fa[0] += P[0] * g0 + P[3] * g1 + P[6] * g2;
    fa[1] += P[1] * g0 + P[4] * g1 + P[7] * g2;
    fa[2] += P[2] * g0 + P[5] * g1 + P[8] * g2;
  }
}

// y_a += (w R sig(R^T G)) g_a with G = sum_b v_b (x) g_b: a point's part of
// R K0 R^T v (stiffness_matvec, and the damping product of the assembly).
template <int NN>
inline void add_point_product(int n_dyn, const int* nodes, const double* R, const double* g, double w, double mu,
                              double lambda, const double* ve, double* y) {
  double G[9], P[9];
  grad_sum<NN>(n_dyn, ve, g, G);
  rotated_stress(R, G, w, mu, lambda, /*strain=*/false, P);
  add_point_force<NN>(n_dyn, nodes, P, g, y);
}

// Rotated gradients h_a = R g_a, (n, 3).
template <int NN>
inline void rotate_gradients(int n_dyn, const double* R, const double* g, double* h) {
  const int n = NN > 0 ? NN : n_dyn;
  for (int a = 0; a < n; ++a) {
    const double g0 = g[3 * a], g1 = g[3 * a + 1], g2 = g[3 * a + 2];
    h[3 * a] = R[0] * g0 + R[3] * g1 + R[6] * g2;
    h[3 * a + 1] = R[1] * g0 + R[4] * g1 + R[7] * g2;
    h[3 * a + 2] = R[2] * g0 + R[5] * g1 + R[8] * g2;
  }
}

// A point's blocks K_ab = w (lambda h_a h_b^T + mu h_b h_a^T + mu (g_a . g_b) I)
// added to Kl (wl = w lambda, wm = w mu). With Y (not null), the rotation
// term (rotation_stiffness.h) fused in: sum_k coef_k (u_k x h_a)(u_k x h_b)^T
// = [h_a]x Y [h_b]x^T with Y = sum_k coef_k u_k u_k^T (3x3), so with
// G = [h_a]x Y block row i gains h_b x (row i of G): 18 products per block
// instead of three rank-1 updates of a dense element matrix.
template <int NN>
inline void add_point_blocks(int n_dyn, const double* g, const double* h, double wl, double wm, const double* Y,
                             double* Kl) {
  const int n = NN > 0 ? NN : n_dyn;
  double* blk = Kl;
  for (int a = 0; a < n; ++a) {
    const double ha0 = h[3 * a], ha1 = h[3 * a + 1], ha2 = h[3 * a + 2];
    const double la0 = wl * ha0, la1 = wl * ha1, la2 = wl * ha2;
    const double ma0 = wm * ha0, ma1 = wm * ha1, ma2 = wm * ha2;
    const double ga0 = wm * g[3 * a], ga1 = wm * g[3 * a + 1], ga2 = wm * g[3 * a + 2];
    if (!Y) {
      for (int b = a; b < n; ++b, blk += 9) {
        const double hb0 = h[3 * b], hb1 = h[3 * b + 1], hb2 = h[3 * b + 2];
        const double gg = ga0 * g[3 * b] + ga1 * g[3 * b + 1] + ga2 * g[3 * b + 2];
        blk[0] += la0 * hb0 + hb0 * ma0 + gg;
        blk[1] += la0 * hb1 + hb0 * ma1;
        blk[2] += la0 * hb2 + hb0 * ma2;
        blk[3] += la1 * hb0 + hb1 * ma0;
        blk[4] += la1 * hb1 + hb1 * ma1 + gg;
        blk[5] += la1 * hb2 + hb1 * ma2;
        blk[6] += la2 * hb0 + hb2 * ma0;
        blk[7] += la2 * hb1 + hb2 * ma1;
        blk[8] += la2 * hb2 + hb2 * ma2 + gg;
      }
      continue;
    }
    // G = [h_a]x Y, row-major (Y symmetric, column-major = row-major).
    double G[9];
    for (int l = 0; l < 3; ++l) {
      G[l] = ha1 * Y[3 * l + 2] - ha2 * Y[3 * l + 1];
      G[3 + l] = ha2 * Y[3 * l] - ha0 * Y[3 * l + 2];
      G[6 + l] = ha0 * Y[3 * l + 1] - ha1 * Y[3 * l];
    }
    for (int b = a; b < n; ++b, blk += 9) {
      const double hb0 = h[3 * b], hb1 = h[3 * b + 1], hb2 = h[3 * b + 2];
      const double gg = ga0 * g[3 * b] + ga1 * g[3 * b + 1] + ga2 * g[3 * b + 2];
      blk[0] += la0 * hb0 + hb0 * ma0 + gg + (hb1 * G[2] - hb2 * G[1]);
      blk[1] += la0 * hb1 + hb0 * ma1 + (hb2 * G[0] - hb0 * G[2]);
      blk[2] += la0 * hb2 + hb0 * ma2 + (hb0 * G[1] - hb1 * G[0]);
      blk[3] += la1 * hb0 + hb1 * ma0 + (hb1 * G[5] - hb2 * G[4]);
      blk[4] += la1 * hb1 + hb1 * ma1 + gg + (hb2 * G[3] - hb0 * G[5]);
      blk[5] += la1 * hb2 + hb1 * ma2 + (hb0 * G[4] - hb1 * G[3]);
      blk[6] += la2 * hb0 + hb2 * ma0 + (hb1 * G[8] - hb2 * G[7]);
      blk[7] += la2 * hb1 + hb2 * ma1 + (hb2 * G[6] - hb0 * G[8]);
      blk[8] += la2 * hb2 + hb2 * ma2 + gg + (hb0 * G[7] - hb1 * G[6]);
    }
  }
}

// Cubature point q of element e: its force into f and, with Kl, its blocks
// (h, t: scratch). Its G = F - I is its slot's kept in Fs where qp_slot_F
// says so.
// With fv: fv += the point's part of R K0 R^T v (ve: the element's v, (n, 3)),
// the stress of v's gradient with the same R (element_matvec's product).
template <int NN>
inline void point_terms(const Model& m, const AssemblyPlan& plan, int e, int q, int n, const int* nodes,
                        const double* ue, const double* Rall, const double* Fs, double* f, double* Kl, double* h,
                        double* t, const double* ve, double* fv) {
  const bool linear = m.material.model == MaterialModel::Linear;
  const double mu = m.mu, lambda = m.lambda;
  const double w = m.qp_weight[q];
  const double* g = &m.qp_grad[m.qp_grad_ptr[q]];
  const double* R = Rall + 9 * m.qp_rot[q];
  double Gq[9], P[9];
  const double* G = Gq;
  if (plan.qp_slot_F[q] && !linear) G = Fs + 9 * (m.qp_rot[q] - plan.elem_rot[plan.elem_rot_ptr[e]]);
  else grad_sum<NN>(n, ue, g, Gq);
  rotated_stress(R, G, w, mu, lambda, /*strain=*/true, P);
  add_point_force<NN>(n, nodes, P, g, f);
  if (fv) add_point_product<NN>(n, nodes, R, g, w, mu, lambda, ve, fv);
  if (!Kl) return;  // a kept element: forces only
  rotate_gradients<NN>(n, R, g, h);
  double F[9], Y[9];
  add_identity(G, F);
  const bool rot = NN > 0 && plan.qp_own_rot[q] && rotation_stiffness_matrix(R, F, mu, lambda, w, Y, plan.exact_rotation_term);
  add_point_blocks<NN>(n, g, h, w * lambda, w * mu, rot ? Y : nullptr, Kl);
  if constexpr (NN == 0) {
    double uk[9], coef[3];
    if (plan.qp_own_rot[q] && rotation_stiffness_modes(R, F, mu, lambda, w, uk, coef, plan.exact_rotation_term))
      add_rotation_stiffness(n, h, uk, coef, Kl, t);
  }
}

// With `cache` (tangent_reuse, valid): the element's blocks are recomputed only
// when some slot's F moved more than cache->theta from the F they were made
// at, and K then gains the difference; *updated says whether they were.
// With fv: fv += the element's R K0 R^T v with the rotations just extracted
// (stiffness_matvec's product, in the same pass: the damping force).
template <int NN>
int element_terms(const Model& m, const AssemblyPlan& plan, int e, const double* u, double* Rall, double* f, double* K,
                  double* scratch, TangentCache* cache = nullptr, bool* updated = nullptr,
                  bool* keepable = nullptr, const double* v = nullptr, double* fv = nullptr) {
  const int b0 = m.elem_dof_ptr[e];
  const int n = NN > 0 ? NN : m.elem_dof_ptr[e + 1] - b0;
  const int* nodes = &m.elem_dof_node[b0];
  double* ue = scratch;      // (n, 3) displacements of the element's DOF nodes
  double* h = ue + 3 * n;    // (n, 3) rotated gradients
  double* Kl = h + 3 * n;    // blocks a <= b, 9 each, row-major
  double* t = Kl + 9 * n * (n + 1) / 2;  // (n, 3, 3) rotation-mode vectors (rotation_stiffness.h)
  double* Fs = t + 9 * n;                // (slots, 9) each slot's G = F - I, for the points that share it (qp_slot_F)
  double* ve = Fs + 9 * plan.max_elem_slots;  // (n, 3) v at the element's nodes, with fv
  const int nblk = n * (n + 1) / 2;
  for (int a = 0; a < n; ++a)
    for (int i = 0; i < 3; ++i) ue[3 * a + i] = u[3 * nodes[a] + i];
  if (fv)
    for (int a = 0; a < n; ++a)
      for (int i = 0; i < 3; ++i) ve[3 * a + i] = v[3 * nodes[a] + i];
  if (K && !(cache && cache->valid && !cache->bypass)) prefetch_element_K(m, e, K);
  // probe (TangentCache::bypass): blocks recomputed and added to K directly,
  // F kept per slot only to tell whether the element would have been kept.
  const bool probe = K && cache && cache->bypass;
  const bool cached = K && cache && cache->valid && !probe;
  bool keep = cached;  // every |F - F_then| entry of the element's slots <= theta (a NaN: not kept)
  bool would_keep = probe;
  const int fallbacks = element_rotations<NN>(m, plan, e, n, ue, Rall, Fs, cache, probe, keep, would_keep);
  if (keepable) *keepable = would_keep;
  if (probe) cache = nullptr;  // from here on a full assembly's element
  // The element's tangent is (re)computed without a valid cache, or when a
  // slot moved past theta (or has no kept F: NaN after a cut's rebuild).
  if (keep) K = nullptr;
  if (updated) *updated = K != nullptr;
  double* Kout = K ? Kl : nullptr;  // the element's blocks, when they are made
  if (K) slot_rotation_terms<NN>(m, plan, e, n, ue, Rall, cache, Kl, h, t);
  if (plan.elem_condensed[e]) {
    condensed_element_terms(m, plan, e, n, nodes, ue, Rall, f, Kout, h, t);
    if (fv) condensed_element_matvec(m, plan, e, nodes, Rall, ve, fv, h, t);
  } else {
    for (int q = m.elem_qp_ptr[e]; q < m.elem_qp_ptr[e + 1]; ++q)
      point_terms<NN>(m, plan, e, q, n, nodes, ue, Rall, Fs, f, Kout, h, t, ve, fv);
  }
  if (K) scatter_blocks(m, e, nblk, Kl, K, cache, cached);
  return fallbacks;
}

template <int NN>
void element_matvec(const Model& m, const AssemblyPlan& plan, int e, const double* Rall, const double* v, double* y, double* scratch) {
  const int b0 = m.elem_dof_ptr[e];
  const int n = NN > 0 ? NN : m.elem_dof_ptr[e + 1] - b0;
  const int* nodes = &m.elem_dof_node[b0];
  double* ve = scratch;
  for (int a = 0; a < n; ++a)
    for (int i = 0; i < 3; ++i) ve[3 * a + i] = v[3 * nodes[a] + i];
  if (plan.elem_condensed[e]) {
    condensed_element_matvec(m, plan, e, nodes, Rall, ve, y, ve + 3 * n, ve + 6 * n);
    return;
  }
  for (int q = m.elem_qp_ptr[e]; q < m.elem_qp_ptr[e + 1]; ++q)
    add_point_product<NN>(n, nodes, Rall + 9 * m.qp_rot[q], &m.qp_grad[m.qp_grad_ptr[q]], m.qp_weight[q], m.mu,
                          m.lambda, ve, y);
}

// Runs body(e, tid) over every element with the plan's race-free schedule,
// after zeroing `zero_a` (na) and `zero_b` (nb) in parallel.
template <class Body>
void for_each_element(const AssemblyPlan& plan, ThreadPool& pool, double* zero_a, int na, double* zero_b, int nb,
                      const Body& body) {
  pool.run([&](int tid) {
    const int T = pool.active();  // <= plan.nthreads: a stood-down worker's block goes to the others
    int b, e;
    if (zero_a) {
      ThreadPool::split(na, T, tid, b, e);
      std::fill(zero_a + b, zero_a + e, 0.0);
    }
    if (zero_b) {
      ThreadPool::split(nb, T, tid, b, e);
      std::fill(zero_b + b, zero_b + e, 0.0);
    }
    pool.barrier();
    for (int blk = tid; blk < plan.nthreads; blk += T)
      for (int k = plan.block_ptr[blk]; k < plan.block_ptr[blk + 1]; ++k) body(plan.block_elem[k], tid);
    for (int c = 0; c < plan.ncolors(); ++c) {
      pool.barrier();
      ThreadPool::split(plan.color_ptr[c + 1] - plan.color_ptr[c], T, tid, b, e);
      for (int k = plan.color_ptr[c] + b; k < plan.color_ptr[c] + e; ++k) body(plan.color_elem[k], tid);
    }
  });
}

}  // namespace

int assemble_corotated(const Model& m, AssemblyPlan& plan, ThreadPool& pool, const double* u, double* R, double* f,
                       double* K, TangentCache* cache, const double* v, double* fv) {
  if (pool.size() != plan.nthreads) plan = make_assembly_plan(m, pool.size());
  if (fv) std::fill(fv, fv + m.ndof(), 0.0);
  if (cache && (!K || !(cache->theta > 0.0))) cache = nullptr;
  const bool probe = cache && cache->bypass;
  if (probe) {
    if (cache->F.size() != 9 * static_cast<size_t>(m.nrot))  // a new model: no F of the last frame
      assign_with_headroom(cache->F, 9 * static_cast<size_t>(m.nrot), std::nan(""));
  } else if (cache && !cache->valid) {  // a full assembly that fills the cache
    assign_with_headroom(cache->Kl, m.elem_scatter.size(), 0.0);  // (a cut's spare buffers: cut_apply.cpp)
    cache->kl_ptr.assign(m.elem_scatter_ptr.begin(), m.elem_scatter_ptr.end() - 1);
    cache->kl_garbage = 0;
    assign_with_headroom(cache->F, 9 * static_cast<size_t>(m.nrot), 0.0);
  }
  const bool keep_K = cache && cache->valid && !probe;  // K holds the kept blocks' sum: updated, not rebuilt
  // Each worker's counts on a cache line of its own: counted per element,
  // side by side they made the two cores trade one line 3 times an element.
  struct alignas(64) Counts {
    int fallbacks = 0, updated = 0, keepable = 0;
  };
  Counts counts[64];
  for_each_element(plan, pool, f, m.ndof(), keep_K ? nullptr : K, keep_K || !K ? 0 : m.nnz(), [&](int e, int tid) {
    double* s = plan.scratch[tid].data();
    const int n = m.elem_dof_ptr[e + 1] - m.elem_dof_ptr[e];
    bool updated = false, keepable = false;
    Counts& c = counts[tid];
    c.fallbacks += n == 10 ? element_terms<10>(m, plan, e, u, R, f, K, s, cache, &updated, &keepable, v, fv)
                           : n == 4 ? element_terms<4>(m, plan, e, u, R, f, K, s, cache, &updated, &keepable, v, fv)
                                    : element_terms<0>(m, plan, e, u, R, f, K, s, cache, &updated, &keepable, v, fv);
    c.updated += updated;
    c.keepable += keepable;
  });
  int total = 0, updated = 0, keepable = 0;
  for (int t = 0; t < pool.active(); ++t)
    total += counts[t].fallbacks, updated += counts[t].updated, keepable += counts[t].keepable;
  if (cache) {
    cache->updated = updated;
    if (probe) {
      // Back to keeping blocks (a filling assembly next) once a tenth of the
      // elements would have been kept this frame.
      cache->would_keep = keepable;
      if (10 * keepable > m.nelem) {
        cache->bypass = false;
        // What a keeping assembly would have recomputed: a cut's carry
        // (cut_apply.cpp) reads it to tell whether the body still moves.
        cache->last_partial = m.nelem - keepable;
      }
    } else {
      cache->valid = true;
      if (keep_K) {
        cache->last_partial = updated;
        // Nine tenths recomputed: keeping blocks costs more than it saves
        // (reading and writing 4 KB per tet10 element); bypass until the
        // motion calms.
        if (10 * updated > 9 * m.nelem) cache->bypass = true, cache->valid = false;
      }
    }
  }
  return total;
}

void stiffness_matvec(const Model& m, AssemblyPlan& plan, ThreadPool& pool, const double* R, const double* v,
                      double* y) {
  if (pool.size() != plan.nthreads) plan = make_assembly_plan(m, pool.size());
  for_each_element(plan, pool, y, m.ndof(), nullptr, 0, [&](int e, int tid) {
    double* s = plan.scratch[tid].data();
    const int n = m.elem_dof_ptr[e + 1] - m.elem_dof_ptr[e];
    if (n == 10) element_matvec<10>(m, plan, e, R, v, y, s);
    else if (n == 4) element_matvec<4>(m, plan, e, R, v, y, s);
    else element_matvec<0>(m, plan, e, R, v, y, s);
  });
}

namespace {
// The element's displacements gathered once for all its slots (a slot at a time
// gathered them per slot: 4 times for a tet10 per_point); each slot's angle
// (four at a time: rotation_angles_to's lanes) into the worker's largest and
// its body's volume-weighted sums (body: V a^2, V, V above the threshold).
template <int NN>
void element_rotation_change(const Model& m, const AssemblyPlan& plan, int e, const double* u, const double* Rall,
                             double* ue, double threshold, double& max, double* body) {
  const int b0 = m.elem_dof_ptr[e];
  const int n = NN > 0 ? NN : m.elem_dof_ptr[e + 1] - b0;
  const int* nodes = &m.elem_dof_node[b0];
  for (int a = 0; a < n; ++a)
    for (int i = 0; i < 3; ++i) ue[3 * a + i] = u[3 * nodes[a] + i];
  const int k0 = plan.elem_rot_ptr[e], k1 = plan.elem_rot_ptr[e + 1];
  for (int c = k0; c < k1; c += 4) {
    double F[36], R[36], angle[4];  // (4, 9), (4, 9), (4)
    int slot[4], count = 0;
    for (int k = c; k < std::min(c + 4, k1); ++k) {
      const int r = plan.elem_rot[k];
      double G[9];
      grad_sum<NN>(n, ue, &m.rot_grad[m.rot_grad_ptr[r]], G);
      add_identity(G, F + 9 * count);
      // An inverted point's rotation (the inversion-safe one, polar.h) jumps
      // as F passes through det F = 0 and does not settle with more Newton
      // iterations; it is counted (FrameTiming::inverted_points), not checked.
      if (!(Eigen::Map<const Mat3>(F + 9 * count).determinant() > 0.0)) continue;
      std::copy(Rall + 9 * r, Rall + 9 * r + 9, R + 9 * count);
      slot[count++] = r;
    }
    rotation_angles_to(count, F, R, angle);
    for (int j = 0; j < count; ++j) {
      const double a = angle[j];
      if (!(a >= 0.0)) continue;  // NaN
      const int r = slot[j];
      const double v = plan.slot_volume[r];
      max = std::max(max, a);
      double* b = body + 3 * (m.rot_body.empty() ? 0 : m.rot_body[r]);
      b[0] += v * a * a;
      b[1] += v;
      if (a > threshold) b[2] += v;
    }
  }
}
}  // namespace

RotationChange rotation_change(const Model& m, AssemblyPlan& plan, ThreadPool& pool, const double* u, const double* R,
                               double threshold, double small) {
  RotationChange out;
  if (m.material.model == MaterialModel::Linear) return out;
  if (pool.size() != plan.nthreads) plan = make_assembly_plan(m, pool.size());
  double part_max[64] = {0};  // per worker (solver.threads <= 64)
  pool.run([&](int tid) {
    // One element range per worker of the pool, summed apart; with workers
    // stood down (ThreadPool::active) an active one takes theirs too: the
    // same sums in the same order.
    double* ue = plan.scratch[tid].data();
    for (int part = tid; part < plan.nthreads; part += pool.active()) {
      int b, e;
      ThreadPool::split(m.nelem, plan.nthreads, part, b, e);
      double* body = plan.body_sums[part].data();
      std::fill(plan.body_sums[part].begin(), plan.body_sums[part].end(), 0.0);
      double max = 0.0;  // the range's own (part_max's entries share a cache line)
      for (int el = b; el < e; ++el) {
        const int n = m.elem_dof_ptr[el + 1] - m.elem_dof_ptr[el];
        if (n == 10) element_rotation_change<10>(m, plan, el, u, R, ue, threshold, max, body);
        else if (n == 4) element_rotation_change<4>(m, plan, el, u, R, ue, threshold, max, body);
        else element_rotation_change<0>(m, plan, el, u, R, ue, threshold, max, body);
      }
      part_max[part] = max;
    }
  });
  for (int t = 0; t < plan.nthreads; ++t) out.max = std::max(out.max, part_max[t]);
  // The ranges' sums into range 0's, and the totals first (the small
  // bodies' threshold is a share of the volume).
  std::vector<double>& sums = plan.body_sums[0];
  for (int t = 1; t < plan.nthreads; ++t)
    for (size_t i = 0; i < sums.size(); ++i) sums[i] += plan.body_sums[t][i];
  for (int k = 0; k < m.nbody; ++k) out.rms += sums[3 * k], out.volume += sums[3 * k + 1], out.above += sums[3 * k + 2];
  for (int k = 0; k < m.nbody; ++k) {
    const double sq = sums[3 * k], vol = sums[3 * k + 1], above = sums[3 * k + 2];
    if (!(vol > 0.0)) continue;
    const bool is_small = vol < small * out.volume;
    double& rms = is_small ? out.small_rms : out.body_rms;
    double& share = is_small ? out.small_above : out.body_above;
    rms = std::max(rms, std::sqrt(sq / vol));
    share = std::max(share, above / vol);
  }
  out.rms = out.volume > 0.0 ? std::sqrt(out.rms / out.volume) : 0.0;
  return out;
}

void element_subset_forces(const Model& m, AssemblyPlan& plan, const std::vector<int>& elems, const double* u,
                           double* R, double* f, const double* v, double* Kv) {
  double* s = plan.scratch[0].data();
  for (int e : elems) {
    const int n = m.elem_dof_ptr[e + 1] - m.elem_dof_ptr[e];
    if (n == 10) element_terms<10>(m, plan, e, u, R, f, nullptr, s);
    else if (n == 4) element_terms<4>(m, plan, e, u, R, f, nullptr, s);
    else element_terms<0>(m, plan, e, u, R, f, nullptr, s);
    if (!v) continue;
    if (n == 10) element_matvec<10>(m, plan, e, R, v, Kv, s);
    else if (n == 4) element_matvec<4>(m, plan, e, R, v, Kv, s);
    else element_matvec<0>(m, plan, e, R, v, Kv, s);
  }
}

template <class T>
void parallel_sym_matvec(const Model& m, AssemblyPlan& plan, ThreadPool& pool, const T* A, const double* x,
                         double* y) {
  if (pool.size() != plan.nthreads) plan = make_assembly_plan(m, pool.size());
  const int n = m.ndof();
  pool.run([&](int tid) {
    // The plan's column ranges, one per worker of the pool; with workers stood
    // down (ThreadPool::active) an active one takes theirs too, in turn: each
    // range writes only what it zeroed, so the bits are the same.
    for (int part = tid; part < plan.nthreads; part += pool.active()) {
      const int c0 = plan.matvec_col_ptr[part], c1 = plan.matvec_col_ptr[part + 1];
      // Range 0 owns y[0, c1) outright (its rows r <= c < c1); the others scatter
      // rows below their range into a private buffer merged afterwards.
      double* ys = part == 0 ? y : plan.matvec_buf[part].data();
      if (part == 0) std::fill(y, y + c1, 0.0);
      else std::fill(ys, ys + c0, 0.0);
      std::fill(y + c0, y + c1, 0.0);
      node_block_matvec(m.Ap.data(), m.Ai.data(), A, x, c0 / 3, c1 / 3, c0, ys, y);
    }
    pool.barrier();
    // Merge the buffers: rows [0, c0_t) of range t's buffer.
    int b, e;
    ThreadPool::split(n, pool.active(), tid, b, e);
    for (int t = 1; t < plan.nthreads; ++t) {
      const int lim = std::min(e, plan.matvec_col_ptr[t]);
      const double* bt = plan.matvec_buf[t].data();
      for (int r = b; r < lim; ++r) y[r] += bt[r];
    }
  });
}

void sym_matvec_parallel(const Model& m, AssemblyPlan& plan, ThreadPool& pool, const double* A, const double* x,
                         double* y) {
  parallel_sym_matvec(m, plan, pool, A, x, y);
}

void sym_matvec_parallel(const Model& m, AssemblyPlan& plan, ThreadPool& pool, const float* A, const double* x,
                         double* y) {
  parallel_sym_matvec(m, plan, pool, A, x, y);
}

}  // namespace incise
