#include "engine/solve/coarse_space.h"

#include <algorithm>
#include <cstring>

#include "engine/model/model.h"
#include "engine/util/error.h"

namespace incise {

namespace {

// Whether c was built for this model's mesh nodes and standard columns (a cut
// appends enriched DOFs after them and leaves those columns as they were).
bool coarse_space_fits(const Model& m, const CoarseSpace& c) {
  const size_t ns = 3 * static_cast<size_t>(m.nnode);
  return c.nnode == m.nnode && c.std_Ap.size() == ns + 1 && m.Ap.size() > ns &&
         std::memcmp(c.std_Ap.data(), m.Ap.data(), (ns + 1) * sizeof(int)) == 0;
}

// P: a corner is its own coarse node; a mid-edge node is half of each end.
void interpolation(const Model& m, CoarseSpace& c) {
  const Mesh& mesh = m.mesh;
  std::vector<int> coarse_of(m.nnode, -1);
  c.ncoarse = 0;
  for (int e = 0; e < mesh.ntet(); ++e)
    for (int k = 0; k < 4; ++k) {
      const int n = mesh.tet[10 * e + k];
      if (coarse_of[n] < 0) coarse_of[n] = c.ncoarse++;
    }
  std::vector<int> a(m.nnode, -1), b(m.nnode, -1);  // a mid-edge node's corners
  for (int e = 0; e < mesh.ntet(); ++e)
    for (int k = 4; k < 10; ++k) {
      const int n = mesh.tet[10 * e + k];
      if (coarse_of[n] < 0 && a[n] < 0) {
        a[n] = coarse_of[mesh.tet[10 * e + kTet10Edge[k - 4][0]]];
        b[n] = coarse_of[mesh.tet[10 * e + kTet10Edge[k - 4][1]]];
      }
    }
  c.p_ptr.assign(1, 0);
  c.p_node.clear();
  c.p_w.clear();
  for (int n = 0; n < m.nnode; ++n) {
    if (coarse_of[n] >= 0) {
      c.p_node.push_back(coarse_of[n]);
      c.p_w.push_back(1.0);
    } else if (a[n] >= 0) {
      c.p_node.insert(c.p_node.end(), {a[n], b[n]});
      c.p_w.insert(c.p_w.end(), {0.5, 0.5});
    }
    c.p_ptr.push_back(static_cast<int>(c.p_node.size()));
  }
  // A coarse DOF whose corner DOF is constrained is left out (identity in A_c).
  c.cfixed.assign(3 * static_cast<size_t>(c.ncoarse), 0);
  for (int n = 0; n < m.nnode; ++n)
    if (coarse_of[n] >= 0)
      for (int k = 0; k < 3; ++k) c.cfixed[3 * coarse_of[n] + k] = m.constrained[3 * n + k];
}

// The fine node blocks of the standard columns (ni <= nj) and the position of
// row 3 ni in each of the three columns of nj (the pattern is node-blocked:
// every column of a node lists the same node rows, so the offset is shared).
void fine_blocks(const Model& m, CoarseSpace& c) {
  c.blk_ni.clear();
  c.blk_nj.clear();
  c.blk_k.clear();
  for (int nj = 0; nj < m.nnode; ++nj) {
    if (c.p_ptr[nj] == c.p_ptr[nj + 1]) continue;
    const int col = 3 * nj;
    for (int k = m.Ap[col]; k < m.Ap[col + 1]; ++k) {
      const int i = m.Ai[k];
      if (i % 3 != 0) continue;
      const int ni = i / 3;
      if (c.p_ptr[ni] == c.p_ptr[ni + 1]) continue;
      const int off = k - m.Ap[col];
      for (int cc = 0; cc < 3; ++cc) {
        const int kc = m.Ap[col + cc] + off;
        const int rows = ni < nj ? 3 : cc + 1;
        for (int r = 0; r < rows; ++r)
          if (kc + r >= m.Ap[col + cc + 1] || m.Ai[kc + r] != i + r)
            throw Error("coarse space: the sparsity pattern is not node-blocked at DOF node " + std::to_string(nj) +
                        " (internal error)");
        c.blk_k.push_back(kc);
      }
      c.blk_ni.push_back(ni);
      c.blk_nj.push_back(nj);
    }
  }
}

// Each fine block's coarse blocks (upper, I <= J) and the coarse pattern.
void coarse_pattern(CoarseSpace& c) {
  const long long nc = c.ncoarse;
  std::vector<long long> key;
  c.tgt_ptr.assign(1, 0);
  c.tgt_w.clear();
  c.tgt_mode.clear();
  const int nblk = static_cast<int>(c.blk_ni.size());
  for (int b = 0; b < nblk; ++b) {
    const int ni = c.blk_ni[b], nj = c.blk_nj[b];
    for (int s = c.p_ptr[ni]; s < c.p_ptr[ni + 1]; ++s)
      for (int t = c.p_ptr[nj]; t < c.p_ptr[nj + 1]; ++t) {
        const int I = c.p_node[s], J = c.p_node[t];
        // Full A_c(I, J) += w B and, off the fine diagonal, A_c(J, I) += w B^T;
        // kept: the upper block. On the fine diagonal B is symmetric and the
        // ordered pair (J, I) adds the same block: only I <= J is taken.
        if (ni == nj && I > J) continue;
        const unsigned char mode = ni == nj ? 0 : (I < J ? 0 : I > J ? 1 : 2);
        key.push_back(std::min(I, J) * nc + std::max(I, J));
        c.tgt_w.push_back(c.p_w[s] * c.p_w[t]);
        c.tgt_mode.push_back(mode);
      }
    c.tgt_ptr.push_back(static_cast<int>(key.size()));
  }
  std::vector<long long> blocks = key;
  std::sort(blocks.begin(), blocks.end());
  blocks.erase(std::unique(blocks.begin(), blocks.end()), blocks.end());
  c.tgt_blk.resize(key.size());
  for (size_t t = 0; t < key.size(); ++t)
    c.tgt_blk[t] = static_cast<int>(std::lower_bound(blocks.begin(), blocks.end(), key[t]) - blocks.begin());
  const int ncb = static_cast<int>(blocks.size());
  c.cblk_I.resize(ncb);
  c.cblk_J.resize(ncb);
  for (int k = 0; k < ncb; ++k) c.cblk_I[k] = static_cast<int>(blocks[k] / nc), c.cblk_J[k] = static_cast<int>(blocks[k] % nc);
  c.cblk.assign(9 * static_cast<size_t>(ncb), 0.0);
  // CSC upper triangle over 3 ncoarse columns: column 3 J + cc holds the rows
  // of blocks (I, J), I < J (3 each), then rows 3 J .. 3 J + cc.
  std::vector<std::vector<int>> by_col(c.ncoarse);
  for (int k = 0; k < ncb; ++k) by_col[c.cblk_J[k]].push_back(k);  // ascending I (blocks sorted by I, then J)
  const int n = 3 * c.ncoarse;
  c.cAp.assign(n + 1, 0);
  c.cAi.clear();
  c.cblk_k.assign(3 * static_cast<size_t>(ncb), 0);
  for (int J = 0; J < c.ncoarse; ++J) {
    std::sort(by_col[J].begin(), by_col[J].end(), [&](int x, int y) { return c.cblk_I[x] < c.cblk_I[y]; });
    for (int cc = 0; cc < 3; ++cc) {
      for (int k : by_col[J]) {
        const int I = c.cblk_I[k];
        c.cblk_k[3 * k + cc] = static_cast<int>(c.cAi.size());
        const int rows = I < J ? 3 : cc + 1;
        for (int r = 0; r < rows; ++r) c.cAi.push_back(3 * I + r);
      }
      c.cAp[3 * J + cc + 1] = static_cast<int>(c.cAi.size());
    }
  }
  c.cA.assign(c.cAi.size(), 0.0);
  c.rc.assign(n, 0.0);
}

}  // namespace

void build_coarse_space(const Model& m, CoarseSpace& c) {
  if (m.mesh.order != 2) {  // a tet4 model: no coarser level
    c.nnode = m.nnode;
    c.ncoarse = 0;
    c.std_Ap.clear();
    return;
  }
  if (coarse_space_fits(m, c) && c.ncoarse > 0) return;
  c.nnode = m.nnode;
  c.std_Ap.assign(m.Ap.begin(), m.Ap.begin() + 3 * static_cast<size_t>(m.nnode) + 1);
  interpolation(m, c);
  fine_blocks(m, c);
  coarse_pattern(c);
  // Supernodal (BLAS) only where BLAS may run beside the background job.
  // Single precision where supernodal (as the lagged fine factor): half the
  // time of a double factor, and a preconditioner needs no more.
  const bool super = blas_concurrency_safe();
  c.factor.set_single_factorization(false);
  c.factor.set_factor_copy(super ? FactorCopy::Float : FactorCopy::None);
  c.factor.set_single_factorization(super);
  c.factor.configure(super ? FactorMethod::Supernodal : FactorMethod::Simplicial, OrderingMethod::Amd);
  c.factor.analyze(3 * c.ncoarse, c.cAp, c.cAi);
}

void factor_coarse_space(const Model& m, const double* A, CoarseSpace& c) {
  if (c.ncoarse == 0) return;
  std::fill(c.cblk.begin(), c.cblk.end(), 0.0);
  const int nblk = static_cast<int>(c.blk_ni.size());
  const char* fixed = m.constrained.data();
  for (int b = 0; b < nblk; ++b) {
    const int ni = c.blk_ni[b], nj = c.blk_nj[b];
    double B[9];  // column-major: B[r + 3 cc] = A(3 ni + r, 3 nj + cc); constrained rows and columns 0 (P drops them)
    for (int cc = 0; cc < 3; ++cc) {
      const int k = c.blk_k[3 * b + cc];
      for (int r = 0; r < 3; ++r) {
        double v = ni < nj || r <= cc ? A[k + r] : 0.0;  // a diagonal block's lower part: mirrored below
        if (fixed[3 * ni + r] || fixed[3 * nj + cc]) v = 0.0;
        B[r + 3 * cc] = v;
      }
    }
    if (ni == nj)
      for (int cc = 0; cc < 3; ++cc)
        for (int r = cc + 1; r < 3; ++r) B[r + 3 * cc] = B[cc + 3 * r];
    double modes[3][9];  // B, B^T, B + B^T (tgt_mode)
    for (int cc = 0; cc < 3; ++cc)
      for (int r = 0; r < 3; ++r) {
        modes[0][r + 3 * cc] = B[r + 3 * cc];
        modes[1][r + 3 * cc] = B[cc + 3 * r];
        modes[2][r + 3 * cc] = B[r + 3 * cc] + B[cc + 3 * r];
      }
    for (int t = c.tgt_ptr[b]; t < c.tgt_ptr[b + 1]; ++t) {
      double* D = &c.cblk[9 * static_cast<size_t>(c.tgt_blk[t])];
      const double w = c.tgt_w[t];
      const double* S = modes[c.tgt_mode[t]];
      for (int q = 0; q < 9; ++q) D[q] += w * S[q];
    }
  }
  const int ncb = static_cast<int>(c.cblk_I.size());
  for (int k = 0; k < ncb; ++k) {
    const int I = c.cblk_I[k], J = c.cblk_J[k];
    for (int cc = 0; cc < 3; ++cc) {
      const int pos = c.cblk_k[3 * k + cc];
      const int rows = I < J ? 3 : cc + 1;
      for (int r = 0; r < rows; ++r) {
        const int dr = 3 * I + r, dc = 3 * J + cc;
        double v = c.cblk[9 * static_cast<size_t>(k) + r + 3 * cc];
        if (c.cfixed[dr] || c.cfixed[dc]) v = dr == dc ? 1.0 : 0.0;
        c.cA[pos + r] = v;
      }
    }
  }
  c.factor.factorize(c.cA.data());
}

void apply_coarse_space(const Model& m, CoarseSpace& c, const double* r, double* z) {
  const int n = m.ndof();
  if (c.ncoarse == 0) {
    std::fill(z, z + n, 0.0);
    return;
  }
  const char* fixed = m.constrained.data();
  std::fill(c.rc.begin(), c.rc.end(), 0.0);
  for (int node = 0; node < m.nnode; ++node)
    for (int s = c.p_ptr[node]; s < c.p_ptr[node + 1]; ++s) {
      const double w = c.p_w[s];
      double* rc = &c.rc[3 * static_cast<size_t>(c.p_node[s])];
      for (int k = 0; k < 3; ++k)
        if (!fixed[3 * node + k]) rc[k] += w * r[3 * node + k];
    }
  for (size_t k = 0; k < c.rc.size(); ++k)
    if (c.cfixed[k]) c.rc[k] = 0.0;
  if (c.factor.has_factor_copy()) c.factor.solve_copy(c.rc.data(), c.rc.data());
  else c.factor.solve(c.rc.data(), c.rc.data());
  for (int node = 0; node < m.nnode; ++node)
    for (int k = 0; k < 3; ++k) {
      double v = 0.0;
      for (int s = c.p_ptr[node]; s < c.p_ptr[node + 1]; ++s) v += c.p_w[s] * c.rc[3 * static_cast<size_t>(c.p_node[s]) + k];
      z[3 * node + k] = fixed[3 * node + k] ? 0.0 : v;
    }
  std::fill(z + 3 * static_cast<size_t>(m.nnode), z + n, 0.0);  // enriched DOFs: not in the coarse space
}

}  // namespace incise
