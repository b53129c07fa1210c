#include "engine/solve/condensed_dofs.h"

#include <algorithm>
#include <string>

#include "engine/util/error.h"

namespace incise {

namespace {

// (mesh node) 1 where a region of the node's support is below `fraction` of it.
std::vector<char> weak_nodes(const Model& m, double fraction) {
  const CutLayout& L = m.cuts;
  const int npe = m.mesh.npe();
  std::vector<double> total(m.nnode, 0.0), home(m.nnode, 0.0);
  std::vector<double> enr(L.n_enriched, 0.0);  // support of each enriched DOF node
  for (int e = 0; e < m.nelem; ++e) {
    const int* nodes = &m.mesh.tet[static_cast<size_t>(e) * npe];
    for (int P = L.elem_piece_ptr[e]; P < L.elem_piece_ptr[e + 1]; ++P) {
      const double vol = L.piece_fraction[P] * m.elem_volume[e];
      for (int a = 0; a < npe; ++a) {
        const int q = L.piece_enr[static_cast<size_t>(P) * npe + a];
        total[nodes[a]] += vol;
        if (q < 0) home[nodes[a]] += vol;
        else enr[q - m.nnode] += vol;
      }
    }
  }
  std::vector<char> weak(m.nnode, 0);
  for (int a = 0; a < m.nnode; ++a) weak[a] = home[a] < fraction * total[a];
  for (int j = 0; j < L.n_enriched; ++j) {
    const int a = L.enr_node[j];
    // A branch DOF node (front enrichment) holds no piece of its own: not a region.
    const bool branch = L.has_branch() && L.node_branch[a] >= 0 && m.nnode + j >= L.node_branch[a];
    if (!branch && enr[j] < fraction * total[a]) weak[a] = 1;
  }
  return weak;
}

}  // namespace

void build_condensed_dofs(const Model& m, double fraction, CondensedDofs& s) {
  s.dof.clear();
  s.src.clear();
  s.factored = false;
  if (!(fraction > 0.0) || !m.has_cuts()) return;
  const std::vector<char> weak = weak_nodes(m, fraction);
  std::vector<int> g2l(m.ndof(), -1);
  for (int n = 0; n < m.ndofnode; ++n) {
    const int a = n < m.nnode ? n : m.cuts.enr_node[n - m.nnode];
    if (!weak[a]) continue;
    for (int c = 0; c < 3; ++c) {
      g2l[3 * n + c] = static_cast<int>(s.dof.size());
      s.dof.push_back(3 * n + c);
    }
  }
  if (s.dof.empty()) return;
  const int ns = static_cast<int>(s.dof.size());
  rows_at(m, g2l, ns, s.rows);
  std::vector<int> Pp(1, 0), Pi;
  submatrix_pattern(m, s.dof, g2l, Pp, Pi, s.src);
  // BLAS-free simplicial: S is small, and BLAS may not run beside the
  // background factorization (blas_concurrency_safe).
  s.factor.configure(FactorMethod::Simplicial, OrderingMethod::Amd);
  s.factor.analyze(ns, Pp, Pi);
  s.A.assign(Pi.size(), 0.0);
  s.v.assign(ns, 0.0);
}

void factor_condensed_dofs(CondensedDofs& s, const double* A) {
  s.factored = false;
  if (s.empty()) return;
  for (size_t t = 0; t < s.src.size(); ++t) s.A[t] = A[s.src[t]];
  try {
    s.factor.factorize(s.A.data());
  } catch (const NumericalError& e) {  // S's own numbering: its global DOF
    const bool known = e.dof >= 0 && e.dof < static_cast<long>(s.dof.size());
    throw NumericalError(std::string(e.what()) + " (the DOFs condensed next to a tiny cut piece, solver.condense_below)",
                         known ? s.dof[static_cast<size_t>(e.dof)] : -1);
  }
  s.factored = true;
}

void condensed_q_subtract(CondensedDofs& s, const double* A, const double* b, double* q, double* y) {
  const int ns = static_cast<int>(s.dof.size());
  for (int i = 0; i < ns; ++i) q[i] = b[s.dof[i]];
  s.factor.solve(q, q);
  for (int i = 0; i < ns; ++i)  // A symmetric: S's rows are its columns
    for (int t = s.rows.ptr[i]; t < s.rows.ptr[i + 1]; ++t) y[s.rows.col[t]] -= A[s.rows.k[t]] * q[i];
}

void condensed_split_rhs(CondensedDofs& s, int n, const double* A, const double* b, double* y, double* x) {
  // x = Q b (S-supported); y = b - A x.
  std::copy(b, b + n, y);
  condensed_q_subtract(s, A, b, s.v.data(), y);
  std::fill(x, x + n, 0.0);
  for (size_t i = 0; i < s.dof.size(); ++i) x[s.dof[i]] = s.v[i];
}

void condensed_project(CondensedDofs& s, const double* A, double* z) {
  const int ns = static_cast<int>(s.dof.size());
  for (int i = 0; i < ns; ++i) {
    double acc = 0.0;
    for (int t = s.rows.ptr[i]; t < s.rows.ptr[i + 1]; ++t) acc += A[s.rows.k[t]] * z[s.rows.col[t]];
    s.v[i] = acc;
  }
  s.factor.solve(s.v.data(), s.v.data());
  for (int i = 0; i < ns; ++i) z[s.dof[i]] -= s.v[i];
}

void condensed_add_q(CondensedDofs& s, const double* r, double* x) {
  const int ns = static_cast<int>(s.dof.size());
  for (int i = 0; i < ns; ++i) s.v[i] = r[s.dof[i]];
  s.factor.solve(s.v.data(), s.v.data());
  for (int i = 0; i < ns; ++i) x[s.dof[i]] += s.v[i];
}

}  // namespace incise
