#include "cutting/front_transfer.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Sparse>

#include "engine/dynamics/step.h"
#include "engine/fem/element.h"
#include "engine/model/front_enrichment.h"
#include "engine/output/probe.h"

namespace incise {

namespace {

// The DOF nodes of model m carrying the field at local point rst of piece P
// of element e (corner coordinates Xe), with their weights and gradients
// (g: n x 3): N_a on node a's standard DOF and on its enriched DOF node in
// P, N_a (F_k - F_k(x_a)) on its branch DOF nodes (F_k with the sign of phi
// at the point, as the model's own gradients), whose gradient is grad N_a (F_k -
// F_k(x_a)) + N_a (dF_k/dphi grad phi + dF_k/dpsi grad psi) as the model's
// own points have it (model_build.cpp add_branch_gradients). Returns the
// count (<= 2 npe + npe kBranchFunctions) and the Jacobian determinant in
// *detJ (when not null).
constexpr int kMaxWeights = 2 * 10 + 10 * kBranchFunctions;
int field_basis(const Model& m, int e, int P, const double rst[3], const double* Xe, int* dof, double* w, double* g,
                double* detJ) {
  const int npe = m.mesh.npe();
  const int* nodes = &m.mesh.tet[static_cast<size_t>(e) * npe];
  double N[10], dN[30];
  shape_values(npe, rst, N);
  const double det = shape_global_gradients(npe, Xe, rst, dN);
  if (detJ) *detJ = det;
  int n = 0;
  const auto put = [&](int j, double wt, const double* gr) {
    dof[n] = j, w[n] = wt;
    for (int d = 0; d < 3; ++d) g[3 * n + d] = gr[d];
    ++n;
  };
  for (int a = 0; a < npe; ++a) {
    put(nodes[a], N[a], &dN[3 * a]);
    const int q = P >= 0 && m.has_cuts() ? m.cuts.piece_enr[static_cast<size_t>(P) * npe + a] : -1;
    if (q >= 0) put(q, N[a], &dN[3 * a]);
  }
  if (!element_has_branch(m, e)) return n;
  double phi[10], psi[10], ph = 0, ps = 0, gph[3] = {0, 0, 0}, gps[3] = {0, 0, 0};
  front_node_values(m, e, phi, psi);
  for (int a = 0; a < npe; ++a) {
    ph += N[a] * phi[a], ps += N[a] * psi[a];
    for (int d = 0; d < 3; ++d) gph[d] += dN[3 * a + d] * phi[a], gps[d] += dN[3 * a + d] * psi[a];
  }
  const BranchValue F = branch_function(ph, ps);
  for (int a = 0; a < npe; ++a) {
    const int b = m.cuts.node_branch[nodes[a]];
    if (b < 0) continue;
    const BranchValue Fa = branch_function(phi[a], psi[a]);
    for (int k = 0; k < kBranchFunctions; ++k) {
      double gr[3];
      for (int d = 0; d < 3; ++d)
        gr[d] = dN[3 * a + d] * (F.F[k] - Fa.F[k]) + N[a] * (F.dphi[k] * gph[d] + F.dpsi[k] * gps[d]);
      put(b + k, N[a] * (F.F[k] - Fa.F[k]), gr);
    }
  }
  return n;
}

// Whether the elements S (in_s) have the same pieces and the same fronts
// (branch DOF nodes and level sets at their nodes) in both models: then the
// old field is the new one with the same nodal and branch values.
bool same_fronts(const Model& from, const Model& to, const std::vector<char>& in_s) {
  if (!from.cuts.has_branch() || !to.cuts.has_branch()) return false;
  const int npe = to.mesh.npe();
  for (int e = 0; e < to.nelem; ++e) {
    if (!in_s[e]) continue;
    if (!same_subtets(from, to, e)) return false;
    for (int a = 0; a < npe; ++a) {
      const int i = to.mesh.tet[static_cast<size_t>(e) * npe + a];
      if ((from.cuts.node_branch[i] >= 0) != (to.cuts.node_branch[i] >= 0) ||
          from.cuts.front_phi[i] != to.cuts.front_phi[i] || from.cuts.front_psi[i] != to.cuts.front_psi[i])
        return false;
    }
  }
  return true;
}

// Whether the fronts in S (in_s) are all new and S's elements keep their
// pieces: no element of S has a branch DOF node in `from`, and each has
// the same pieces in both models, their enriched DOF nodes paired one to
// one (the new model splits its front elements into sub-tetrahedra for
// integration only). Then the old space is the new one's with the branch
// DOFs at 0, and the nodal transfer is exact: a front enriched where it
// stopped (a swept cut's at the end of its sweep, a scalpel's stroke once
// the blade is out) needs no projection.
bool fronts_only_added(const Model& from, const Model& to, const std::vector<char>& in_s) {
  for (int e = 0; e < to.nelem; ++e)
    if (in_s[e] && (element_has_branch(from, e) || !same_piece_regions(to, from, e))) return false;
  return true;
}

}  // namespace

void project_near_fronts(const Model& from, const State& os, const Model& to, int nf, Kinematics& ns) {
  if (!from.cuts.has_branch() && !to.cuts.has_branch()) return;
  const int npe = to.mesh.npe(), nnode = to.nnode;
  std::vector<char> in_s(to.nelem, 0), fixed(nnode, 0);
  double vol = 0;
  int ns_elem = 0;
  for (int e = 0; e < to.nelem; ++e) in_s[e] = element_has_branch(from, e) || element_has_branch(to, e);
  for (int e = 0; e < to.nelem; ++e) {
    if (in_s[e]) vol += to.elem_volume[e], ++ns_elem;
    if (!in_s[e])
      for (int a = 0; a < npe; ++a) fixed[to.mesh.tet[static_cast<size_t>(e) * npe + a]] = 1;
  }
  if (ns_elem == 0) return;
  if (same_fronts(from, to, in_s)) {
    // Another cut's rebuild: the DOFs of S's inner nodes copy over one by
    // one (mesh nodes to themselves, enriched ones by dofnode_map, branch
    // ones by node), exact: their supports keep their pieces, so their
    // regions and home regions too. The boundary nodes keep the nodal
    // transfer (a cut beside S may change their home region).
    const std::vector<int> map = dofnode_map(from, to);
    const std::vector<double>* oldf[4] = {&os.u, &os.v, &os.a, &os.du};
    std::vector<double>* newf[4] = {&ns.u, &ns.v, &ns.a, &ns.du};
    for (int e = 0; e < to.nelem; ++e)
      for (int k = to.elem_dof_ptr[e]; in_s[e] && k < to.elem_dof_ptr[e + 1]; ++k) {
        const int j = to.elem_dof_node[k], i = j < nnode ? j : to.cuts.enr_node[j - nnode];
        if (fixed[i]) continue;
        const int b = to.cuts.node_branch[i], o = b >= 0 && j >= b && j < b + kBranchFunctions
                                                     ? from.cuts.node_branch[i] + (j - b)
                                                     : map[j];
        if (o < 0) continue;
        for (int f = 0; f < nf; ++f)
          for (int d = 0; d < 3; ++d) (*newf[f])[3 * j + d] = (*oldf[f])[3 * o + d];
      }
    return;
  }
  if (fronts_only_added(from, to, in_s)) {
    std::vector<double>* newf[4] = {&ns.u, &ns.v, &ns.a, &ns.du};
    for (int i = 0; i < nnode; ++i) {
      const int b = to.cuts.node_branch[i];
      for (int j = b; b >= 0 && j < b + kBranchFunctions; ++j)
        for (int f = 0; f < nf; ++f) std::fill_n(newf[f]->begin() + 3 * static_cast<size_t>(j), 3, 0.0);
    }
    return;
  }
  const double beta = 1e-2 / std::pow(vol / ns_elem, 2.0 / 3.0);
  std::vector<int> col(to.ndofnode, -1), node_of;  // free DOF node -> unknown index
  for (int e = 0; e < to.nelem; ++e)
    for (int k = to.elem_dof_ptr[e]; in_s[e] && k < to.elem_dof_ptr[e + 1]; ++k) {
      const int j = to.elem_dof_node[k], i = j < nnode ? j : to.cuts.enr_node[j - nnode];
      if (fixed[i] || col[j] >= 0) continue;
      col[j] = static_cast<int>(node_of.size());
      node_of.push_back(j);
    }
  const int nu = static_cast<int>(node_of.size());
  if (nu == 0) return;
  const std::vector<double>* oldf[4] = {&os.u, &os.v, &os.a, &os.du};
  std::vector<double>* newf[4] = {&ns.u, &ns.v, &ns.a, &ns.du};
  Eigen::MatrixXd Ru = Eigen::MatrixXd::Zero(3 * nu, 1), Rm = Eigen::MatrixXd::Zero(nu, 3 * (nf - 1));
  std::vector<Eigen::Triplet<double>> Mt, Kt;  // (nu, nu) L2, (3 nu, 3 nu) elastic matrices
  const double stiff = to.lambda + 2 * to.mu;
  const Cubature& cub = branch_cubature();
  const CutLayout& L = to.cuts;
  double Xe[30];
  std::vector<double> Me, Ke;
  std::vector<int> loc(to.ndofnode, -1);
  for (int e = 0; e < to.nelem; ++e) {
    if (!in_s[e]) continue;
    const int* nodes = &to.mesh.tet[static_cast<size_t>(e) * npe];
    for (int a = 0; a < npe; ++a)
      for (int d = 0; d < 3; ++d) Xe[3 * a + d] = to.mesh.X[3 * nodes[a] + d];
    // Local matrices over the element's DOF nodes (loc: DOF node -> local index).
    const int d0 = to.elem_dof_ptr[e], nl = to.elem_dof_ptr[e + 1] - d0;
    for (int i = 0; i < nl; ++i) loc[to.elem_dof_node[d0 + i]] = i;
    Me.assign(static_cast<size_t>(nl) * nl, 0.0);
    Ke.assign(9 * static_cast<size_t>(nl) * nl, 0.0);
    for (int P = L.elem_piece_ptr[e]; P < L.elem_piece_ptr[e + 1]; ++P)
      for (int t = L.piece_subtet_ptr[P]; t < L.piece_subtet_ptr[P + 1]; ++t) {
        const double* v = &L.subtet_rst[12 * static_cast<size_t>(t)];
        double c[3] = {0, 0, 0};
        for (int k = 0; k < 4; ++k)
          for (int d = 0; d < 3; ++d) c[d] += 0.25 * v[3 * k + d];
        const int old_piece = from.has_cuts() ? piece_containing(from, e, c) : -1;
        const double vol6 = 6.0 * std::abs(subtet_ref_volume(v));
        for (int q = 0; q < cub.npoint(); ++q) {
          double rst[3], detJ = 0;
          map_to_element(v, &cub.rst[3 * q], rst);
          int dof[kMaxWeights], dof_old[kMaxWeights];
          double w[kMaxWeights], g[3 * kMaxWeights], w_old[kMaxWeights], g_old[3 * kMaxWeights];
          const int n = field_basis(to, e, P, rst, Xe, dof, w, g, &detJ);
          const int n_old = field_basis(from, e, old_piece, rst, Xe, dof_old, w_old, g_old, nullptr);
          const double wq = cub.weight[q] * vol6 * detJ;
          for (int k = 0; k < nf; ++k) {
            // The old field less the new one with the nodal values: value
            // (3) and gradient (3 x 3); the systems solve for the change.
            double r[3] = {0, 0, 0}, gr[9] = {0};
            const double* f = oldf[k]->data();
            for (int j = 0; j < n_old; ++j)
              for (int d = 0; d < 3; ++d) {
                r[d] += w_old[j] * f[3 * dof_old[j] + d];
                for (int x = 0; x < 3; ++x) gr[3 * d + x] += g_old[3 * j + x] * f[3 * dof_old[j] + d];
              }
            const double* fn = newf[k]->data();
            for (int j = 0; j < n; ++j)
              for (int d = 0; d < 3; ++d) {
                r[d] -= w[j] * fn[3 * dof[j] + d];
                for (int x = 0; x < 3; ++x) gr[3 * d + x] -= g[3 * j + x] * fn[3 * dof[j] + d];
              }
            // u: the stress of the residual, sigma = lambda tr(G) I + mu (G + G^T).
            double sig[9] = {0};
            if (k == 0) {
              const double tr = gr[0] + gr[4] + gr[8];
              for (int d = 0; d < 3; ++d)
                for (int x = 0; x < 3; ++x)
                  sig[3 * d + x] = to.mu * (gr[3 * d + x] + gr[3 * x + d]) + (d == x ? to.lambda * tr : 0.0);
            }
            for (int j = 0; j < n; ++j) {
              const int i = col[dof[j]];
              if (i < 0) continue;
              for (int d = 0; d < 3; ++d) {
                if (k == 0) {
                  double h1 = beta * stiff * w[j] * r[d];
                  for (int x = 0; x < 3; ++x) h1 += g[3 * j + x] * sig[3 * d + x];
                  Ru(3 * i + d, 0) += wq * h1;
                } else {
                  Rm(i, 3 * (k - 1) + d) += wq * w[j] * r[d];
                }
              }
            }
          }
          for (int a = 0; a < n; ++a) {
            const int i = loc[dof[a]];
            if (col[dof[a]] < 0) continue;
            for (int b = 0; b < n; ++b) {
              const int j = loc[dof[b]];
              if (col[dof[b]] < 0) continue;
              Me[i * nl + j] += wq * w[a] * w[b];
              // the elasticity block of (a, b): lambda g_a g_b^T + mu (g_b g_a^T + (g_a . g_b) I)
              const double* ga = &g[3 * a];
              const double* gb = &g[3 * b];
              const double dot = ga[0] * gb[0] + ga[1] * gb[1] + ga[2] * gb[2];
              for (int c = 0; c < 3; ++c)
                for (int d = 0; d < 3; ++d)
                  Ke[(3 * i + c) * 3 * nl + 3 * j + d] +=
                      wq * (to.lambda * ga[c] * gb[d] + to.mu * (ga[d] * gb[c] + (c == d ? dot : 0.0)) +
                            (c == d ? beta * stiff * w[a] * w[b] : 0.0));
            }
          }
        }
      }
    for (int i = 0; i < nl; ++i)
      for (int j = 0; j < nl; ++j) {
        const int ci = col[to.elem_dof_node[d0 + i]], cj = col[to.elem_dof_node[d0 + j]];
        if (ci < 0 || cj < 0) continue;
        Mt.emplace_back(ci, cj, Me[i * nl + j]);
        for (int c = 0; c < 3; ++c)
          for (int d = 0; d < 3; ++d) Kt.emplace_back(3 * ci + c, 3 * cj + d, Ke[(3 * i + c) * 3 * nl + 3 * j + d]);
      }
    for (int i = 0; i < nl; ++i) loc[to.elem_dof_node[d0 + i]] = -1;
  }
  Eigen::SparseMatrix<double> M(nu, nu), H(3 * nu, 3 * nu);
  M.setFromTriplets(Mt.begin(), Mt.end());
  H.setFromTriplets(Kt.begin(), Kt.end());
  // Each solved for the change from the nodal values, with a 1e-10 relative diagonal shift (a DOF of a
  // sliver piece, a near-null combination of branch functions stays near
  // its nodal value) and two refinement steps on the unshifted system.
  const auto solve = [&](const Eigen::SparseMatrix<double>& A, const Eigen::MatrixXd& R, Eigen::MatrixXd* D) {
    Eigen::SparseMatrix<double> As = A;
    double dmax = 0;
    for (int i = 0; i < A.rows(); ++i) dmax = std::max(dmax, A.coeff(i, i));
    for (int i = 0; i < A.rows(); ++i) As.coeffRef(i, i) += 1e-10 * A.coeff(i, i) + 1e-14 * dmax;
    const Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(As);
    if (ldlt.info() != Eigen::Success) return false;
    *D = ldlt.solve(R);
    for (int it = 0; it < 2; ++it) *D += ldlt.solve(R - A * *D);
    return D->allFinite();
  };
  Eigen::MatrixXd Du, Dm;
  const bool ok_u = solve(H, Ru, &Du), ok_m = nf < 2 || solve(M, Rm, &Dm);
  // The velocity's L2 projection, with the model's (lumped) mass, may hold
  // far more kinetic energy than the old field: DOFs of sliver pieces are
  // near-null in L2 but not in the lumped mass (a slit 0.7% of an element
  // from a node layer taken back to faces: 3.6 -> 183 of kinetic energy).
  // A transfer must not make energy: the corrections of v (and a, du with
  // it) are scaled back, by the largest alpha <= 1 that keeps the kinetic
  // energy at most the old model's (or the nodal transfer's, if more).
  double alpha = 1.0;
  if (ok_m && nf >= 2) {
    const size_t n = ns.v.size();
    std::vector<double> D(n, 0.0), MD(n), Mv(n), Mo(os.v.size());
    for (int j = 0; j < nu; ++j)
      for (int d = 0; d < 3; ++d) D[3 * static_cast<size_t>(node_of[j]) + d] = Dm(j, d);
    mass_matvec(to, D.data(), MD.data());
    mass_matvec(to, ns.v.data(), Mv.data());
    mass_matvec(from, os.v.data(), Mo.data());
    double t0 = 0, b = 0, c = 0, t_old = 0;
    for (size_t i = 0; i < n; ++i) t0 += 0.5 * ns.v[i] * Mv[i], b += D[i] * Mv[i], c += 0.5 * D[i] * MD[i];
    for (size_t i = 0; i < os.v.size(); ++i) t_old += 0.5 * os.v[i] * Mo[i];
    // T(alpha) = t0 + alpha b + alpha^2 c <= bound, with T(0) = t0 <= bound.
    const double bound = std::max(t_old, t0);
    if (t0 + b + c > bound && c > 0) alpha = std::clamp((-b + std::sqrt(std::max(0.0, b * b + 4 * c * (bound - t0)))) / (2 * c), 0.0, 1.0);
  }
  for (int j = 0; j < nu; ++j)
    for (int d = 0; d < 3; ++d) {
      if (ok_u) (*newf[0])[3 * node_of[j] + d] += Du(3 * j + d, 0);
      for (int k = 1; ok_m && k < nf; ++k) (*newf[k])[3 * node_of[j] + d] += alpha * Dm(j, 3 * (k - 1) + d);
    }
}

}  // namespace incise
