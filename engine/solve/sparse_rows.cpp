#include "engine/solve/sparse_rows.h"

namespace incise {

void rows_at(const Model& m, const std::vector<int>& g2l, int nrows, SparseRows& rows) {
  std::vector<char> col_in(m.ndof(), 0);
  for (int e = 0; e < m.nelem; ++e) {
    bool touch = false;
    for (int k = m.elem_dof_ptr[e]; k < m.elem_dof_ptr[e + 1] && !touch; ++k) touch = g2l[3 * m.elem_dof_node[k]] >= 0;
    if (touch)
      for (int k = m.elem_dof_ptr[e]; k < m.elem_dof_ptr[e + 1]; ++k)
        for (int c = 0; c < 3; ++c) col_in[3 * m.elem_dof_node[k] + c] = 1;
  }
  std::vector<int> cols;
  for (int c = 0; c < m.ndof(); ++c)
    if (col_in[c]) cols.push_back(c);
  std::vector<int> cnt(nrows + 1, 0);
  for (int c : cols)
    for (int k = m.Ap[c]; k < m.Ap[c + 1]; ++k) {
      const int r = m.Ai[k];
      if (g2l[r] >= 0) ++cnt[g2l[r] + 1];
      if (r != c && g2l[c] >= 0) ++cnt[g2l[c] + 1];
    }
  for (int i = 0; i < nrows; ++i) cnt[i + 1] += cnt[i];
  rows.ptr = cnt;
  rows.col.assign(cnt.back(), 0);
  rows.k.assign(cnt.back(), 0);
  for (int c : cols)
    for (int k = m.Ap[c]; k < m.Ap[c + 1]; ++k) {
      const int r = m.Ai[k];
      if (g2l[r] >= 0) rows.col[cnt[g2l[r]]] = c, rows.k[cnt[g2l[r]]++] = k;
      if (r != c && g2l[c] >= 0) rows.col[cnt[g2l[c]]] = r, rows.k[cnt[g2l[c]]++] = k;
    }
}

void submatrix_pattern(const Model& m, const std::vector<int>& dofs, const std::vector<int>& g2l, std::vector<int>& Pp,
                       std::vector<int>& Pi, std::vector<int>& src) {
  for (int C : dofs) {
    for (int k = m.Ap[C]; k < m.Ap[C + 1]; ++k)
      if (g2l[m.Ai[k]] >= 0) {
        Pi.push_back(g2l[m.Ai[k]]);
        src.push_back(k);
      }
    Pp.push_back(static_cast<int>(Pi.size()));
  }
}

}  // namespace incise
