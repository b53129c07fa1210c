#include "engine/model/tissue_locator.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

namespace incise {

namespace {
// floor(t) clamped to [0, n - 1]; NaN (a diverged state's coordinate) and
// the infinities go to an end instead of an undefined cast.
int clamped_index(double t, int n) { return t >= 0 ? (t < n ? static_cast<int>(t) : n - 1) : 0; }
}  // namespace

TissueLocator::TissueLocator(const Model& m, const double* u) : model_(&m) {
  const int npe = m.mesh.npe(), nt = m.mesh.ntet();
  corners_.resize(12 * static_cast<size_t>(nt));
  box_.resize(6 * static_cast<size_t>(nt));
  for (int d = 0; d < 3; ++d) lo_[d] = 1e300, hi_[d] = -1e300;
  for (int e = 0; e < nt; ++e) {
    const int* nodes = &m.mesh.tet[static_cast<size_t>(e) * npe];
    double* c = &corners_[12 * static_cast<size_t>(e)];
    double* b = &box_[6 * static_cast<size_t>(e)];
    for (int d = 0; d < 3; ++d) b[d] = 1e300, b[3 + d] = -1e300;
    for (int k = 0; k < 4; ++k)
      for (int d = 0; d < 3; ++d) {
        c[3 * k + d] = m.X[3 * nodes[k] + d] + (u ? u[3 * nodes[k] + d] : 0.0);
        b[d] = std::min(b[d], c[3 * k + d]);
        b[3 + d] = std::max(b[3 + d], c[3 * k + d]);
      }
    // A point within roundoff of a face counts as inside (below): the box
    // grows by more than that.
    for (int d = 0; d < 3; ++d) {
      const double slack = 1e-6 * (b[3 + d] - b[d]) + 1e-300;
      b[d] -= slack, b[3 + d] += slack;
      lo_[d] = std::min(lo_[d], b[d]);
      hi_[d] = std::max(hi_[d], b[3 + d]);
    }
  }
  if (nt == 0) return;
  // About one cell per element (each box then meets a few): a scalpel's
  // edge is asked every half element along it (blade_sweep.cpp), and a scan
  // of every box for each sample cost O(elements).
  const double ext[3] = {hi_[0] - lo_[0], hi_[1] - lo_[1], hi_[2] - lo_[2]};
  const double side = std::cbrt(std::max(ext[0] * ext[1] * ext[2], 1e-300) / nt);
  for (int d = 0; d < 3; ++d) {
    dim_[d] = std::max(1, clamped_index(ext[d] / std::max(side, 1e-300), 257));  // 1..256
    cell_[d] = ext[d] > 0 ? ext[d] / dim_[d] : 1.0;
  }
  const size_t ncell = static_cast<size_t>(dim_[0]) * dim_[1] * dim_[2];
  std::vector<int> count(ncell + 1, 0);
  const auto range = [&](const double* b, int d, int& i0, int& i1) {
    i0 = clamped_index((b[d] - lo_[d]) / cell_[d], dim_[d]);
    i1 = clamped_index((b[3 + d] - lo_[d]) / cell_[d], dim_[d]);
  };
  for (int pass = 0; pass < 2; ++pass) {
    if (pass == 1) {
      cell_ptr_.assign(ncell + 1, 0);
      for (size_t c = 0; c < ncell; ++c) cell_ptr_[c + 1] = cell_ptr_[c] + count[c];
      cell_elem_.resize(cell_ptr_[ncell]);
      std::fill(count.begin(), count.end(), 0);
    }
    for (int e = 0; e < nt; ++e) {
      const double* b = &box_[6 * static_cast<size_t>(e)];
      int r[3][2];
      for (int d = 0; d < 3; ++d) range(b, d, r[d][0], r[d][1]);
      for (int i = r[0][0]; i <= r[0][1]; ++i)
        for (int j = r[1][0]; j <= r[1][1]; ++j)
          for (int k = r[2][0]; k <= r[2][1]; ++k) {
            const size_t c = (static_cast<size_t>(k) * dim_[1] + j) * dim_[0] + i;
            if (pass == 1) cell_elem_[cell_ptr_[c] + count[c]] = e;
            ++count[c];
          }
    }
  }
}

int TissueLocator::cell_of(const double x[3]) const {
  int i[3];
  for (int d = 0; d < 3; ++d) i[d] = clamped_index((x[d] - lo_[d]) / cell_[d], dim_[d]);
  return (i[2] * dim_[1] + i[1]) * dim_[0] + i[0];
}

// Barycentric coordinates of x in element e's deformed corner tetrahedron.
Eigen::Vector4d TissueLocator::barycentric(int e, const double x[3]) const {
  const double* c = &corners_[12 * static_cast<size_t>(e)];
  Eigen::Matrix3d J;
  for (int d = 0; d < 3; ++d) J.col(d) << c[3 * (d + 1)] - c[0], c[3 * (d + 1) + 1] - c[1], c[3 * (d + 1) + 2] - c[2];
  const Eigen::Vector3d l = J.partialPivLu().solve(Eigen::Vector3d(x[0] - c[0], x[1] - c[1], x[2] - c[2]));
  return Eigen::Vector4d(1.0 - l.sum(), l[0], l[1], l[2]);
}

// The element with the largest smallest barycentric coordinate among
// `all` elements or those whose box holds x; best_min is that coordinate.
int TissueLocator::best_element(const double x[3], bool all, double& best_min, Eigen::Vector4d& best_L) const {
  int best = -1;
  best_min = -1e300;
  const int nt = static_cast<int>(box_.size() / 6);
  const bool in_box = x[0] >= lo_[0] && x[0] <= hi_[0] && x[1] >= lo_[1] && x[1] <= hi_[1] && x[2] >= lo_[2] &&
                      x[2] <= hi_[2];
  if (!all && (!in_box || cell_ptr_.empty())) return -1;
  const int c = all ? 0 : cell_of(x);
  const int n = all ? nt : cell_ptr_[c + 1] - cell_ptr_[c];
  for (int k = 0; k < n; ++k) {
    const int e = all ? k : cell_elem_[cell_ptr_[c] + k];
    const double* b = &box_[6 * static_cast<size_t>(e)];
    if (!all && !(x[0] >= b[0] && x[0] <= b[3] && x[1] >= b[1] && x[1] <= b[4] && x[2] >= b[2] && x[2] <= b[5]))
      continue;
    const Eigen::Vector4d L = barycentric(e, x);
    const double mn = L.minCoeff();
    if (std::isfinite(mn) && mn > best_min) {
      best_min = mn;
      best = e;
      best_L = L;
    }
  }
  return best;
}

bool TissueLocator::inside(const double x[3]) const { return locate(x) >= 0; }

int TissueLocator::locate(const double x[3]) const {
  double mn;
  Eigen::Vector4d L;
  const int e = best_element(x, false, mn, L);
  return e >= 0 && mn >= -1e-9 ? e : -1;
}

std::array<double, 3> TissueLocator::reference_by(int e, const double x[3]) const {
  const Eigen::Vector4d L = barycentric(e, x);
  const Model& m = *model_;
  const int* nodes = &m.mesh.tet[static_cast<size_t>(e) * m.mesh.npe()];
  std::array<double, 3> X{0.0, 0.0, 0.0};
  for (int d = 0; d < 3; ++d)
    for (int k = 0; k < 4; ++k) X[d] += L[k] * m.X[3 * nodes[k] + d];
  return X;
}

std::array<double, 3> TissueLocator::reference(const double x[3], bool* inside) const {
  int e = locate(x);
  *inside = e >= 0;
  if (e < 0) {  // outside: the nearest element's map (the largest smallest coordinate), extrapolated
    double mn;
    Eigen::Vector4d L;
    e = best_element(x, true, mn, L);
  }
  if (e < 0) return {x[0], x[1], x[2]};
  return reference_by(e, x);
}

std::array<double, 3> reference_point(const Model& m, const State& s, const double x[3], bool* inside) {
  return TissueLocator(m, s).reference(x, inside);
}

}  // namespace incise
