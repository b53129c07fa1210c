#include "engine/output/probe.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

#include "engine/fem/element.h"
#include "engine/model/front_enrichment.h"

namespace incise {

ProbeHit locate_point(const Model& m, const double x[3]) {
  const Mesh& mesh = m.mesh;
  const int npe = mesh.npe();
  ProbeHit best;
  double best_min = -1e300;
  double Xe[30], N[10], dN[30];
  for (int e = 0; e < mesh.ntet(); ++e) {
    const int* nodes = &mesh.tet[static_cast<size_t>(e) * npe];
    double lo[3] = {1e300, 1e300, 1e300}, hi[3] = {-1e300, -1e300, -1e300};
    for (int a = 0; a < npe; ++a)
      for (int d = 0; d < 3; ++d) {
        Xe[3 * a + d] = mesh.X[3 * nodes[a] + d];
        lo[d] = std::min(lo[d], Xe[3 * a + d]);
        hi[d] = std::max(hi[d], Xe[3 * a + d]);
      }
    bool inside_box = true;
    for (int d = 0; d < 3; ++d) {
      const double pad = 1e-9 * (hi[d] - lo[d]) + 1e-300;
      inside_box = inside_box && x[d] >= lo[d] - pad && x[d] <= hi[d] + pad;
    }
    if (!inside_box) continue;
    // Newton on X(rst) = x, starting at the centroid (one step is exact for straight elements).
    Eigen::Vector3d r(0.25, 0.25, 0.25);
    for (int it = 0; it < 20; ++it) {
      shape_values(npe, r.data(), N);
      shape_local_gradients(npe, r.data(), dN);
      Eigen::Vector3d res(-x[0], -x[1], -x[2]);
      Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
      for (int a = 0; a < npe; ++a)
        for (int i = 0; i < 3; ++i) {
          res[i] += N[a] * Xe[3 * a + i];
          for (int j = 0; j < 3; ++j) J(i, j) += Xe[3 * a + i] * dN[3 * a + j];
        }
      const Eigen::Vector3d dr = J.partialPivLu().solve(res);
      r -= dr;
      if (dr.norm() < 1e-14) break;
    }
    const double L[4] = {1.0 - r.sum(), r[0], r[1], r[2]};
    const double minL = *std::min_element(L, L + 4);
    if (minL > best_min && std::isfinite(minL)) {
      best_min = minL;
      best.elem = e;
      for (int d = 0; d < 3; ++d) best.rst[d] = r[d];
    }
  }
  if (best_min < -1e-9) best.elem = -1;
  if (best.elem >= 0) best.piece = piece_containing(m, best.elem, best.rst);
  return best;
}

int piece_containing(const Model& m, int e, const double rst[3]) {
  if (!m.has_cuts()) return -1;
  const CutLayout& L = m.cuts;
  int best = -1;
  double best_min = -1e300;
  for (int P = L.elem_piece_ptr[e]; P < L.elem_piece_ptr[e + 1]; ++P)
    for (int t = L.piece_subtet_ptr[P]; t < L.piece_subtet_ptr[P + 1]; ++t) {
      const double* v = &L.subtet_rst[12 * static_cast<size_t>(t)];
      Eigen::Matrix3d A;
      for (int k = 0; k < 3; ++k)
        for (int d = 0; d < 3; ++d) A(d, k) = v[3 * (k + 1) + d] - v[d];
      const Eigen::Vector3d l = A.partialPivLu().solve(Eigen::Vector3d(rst[0] - v[0], rst[1] - v[1], rst[2] - v[2]));
      const double mn = std::min({1.0 - l.sum(), l[0], l[1], l[2]});
      if (std::isfinite(mn) && mn > best_min) {
        best_min = mn;
        best = P;
      }
    }
  return best;
}

std::array<double, 3> interpolate_displacement(const Model& m, const double* u, const ProbeHit& hit) {
  std::array<double, 3> out{0, 0, 0};
  const int npe = m.mesh.npe();
  double N[10];
  shape_values(npe, hit.rst, N);
  const int* nodes = &m.mesh.tet[static_cast<size_t>(hit.elem) * npe];
  const int* enr = hit.piece >= 0 ? &m.cuts.piece_enr[static_cast<size_t>(hit.piece) * npe] : nullptr;
  for (int a = 0; a < npe; ++a)
    for (int d = 0; d < 3; ++d)
      out[d] += N[a] * (u[3 * nodes[a] + d] + (enr && enr[a] >= 0 ? u[3 * enr[a] + d] : 0.0));
  // Front enrichment; a point exactly on the cut's plane behind the front is
  // taken on its + side.
  add_branch_field(m, hit.elem, N, 0, u, out.data());
  return out;
}

}  // namespace incise
