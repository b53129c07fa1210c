#pragma once
// Helpers for the collision tests: a tet10 block cut through by a plane, and
// states that move each side of the cut with its own displacement field.
#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <vector>

#include <Eigen/Dense>

#include "cutting/cut_surface.h"
#include "cutting/xfem_layout.h"
#include "engine/dynamics/step.h"  // init_state, which tests/cutting/test_util.h uses
#include "engine/dynamics/state.h"
#include "engine/fem/element.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/model/model.h"
#include "tests/cutting/test_util.h"

namespace incise::test {

// A block 0.1 x 0.1 x 0.05 m (4x4x2 cells, raised to tet10 by the scene) of
// soft tissue (nu = 0.45, rho = 1000) fixed at its base, damped (Rayleigh
// mass `rayleigh_mass`, stiffness 0.01 s) so that it settles: the
// instruments' tests press, grasp and cut it.
inline Mesh tissue_block_mesh() { return make_beam(0.1, 0.1, 0.05, 4, 4, 2, 1); }
inline Scene tissue_block_scene(double young, double rayleigh_mass) {
  Scene s = block_scene(2);
  s.material.young = young;
  s.material.poisson = 0.45;
  s.material.density = 1000;
  s.material.rayleigh_mass = rayleigh_mass;
  s.material.rayleigh_stiffness = 0.01;
  s.fixed.push_back(box({-1, -1, -1}, {1, 1, 0}));
  return s;
}

// Straight-sided block [0,2]x[0,1]x[0,1] (4x2x2 cells, 6 tetrahedra each).
inline Mesh collision_block() { return make_beam(2, 1, 1, 4, 2, 2, 1); }

// Model of the block (tet10, or tet4 for order 1); with `cut`, cut through by
// the plane through (1.05, 0, 0) with normal (1, 0.1, 0.05): two bodies,
// x < plane on side 0, x > plane on side 1.
inline Model block_model(bool cut, int order = 2) {
  const Scene s = block_scene(order);
  const Mesh mesh = collision_block();
  const Model uncut = build_model(mesh, s);
  if (!cut) return uncut;
  const auto plane = make_cut_surface(plane_cut({1.05, 0, 0}, {1, 0.1, 0.05}), 0.0);
  const CutLayout layout = compute_cut_layout(uncut, {plane.get()}, nullptr);
  return build_model(mesh, s, &layout);
}

inline double block_plane(const double X[3]) {  // signed, > 0 on side 1
  return (X[0] - 1.05) * 1.0 + X[1] * 0.1 + X[2] * 0.05;
}

using Field = std::function<std::array<double, 3>(const double* X)>;

// A displacement in which side s of the cut moves by field[s] (evaluated at
// the reference position of each node): u_a = field_home(a)(X_a) and, for
// the enriched DOF node of region r at node a, q = field_r(X_a) - field_home(a)(X_a)
// (engine/model/cut_layout.h). Without cuts, field[0] everywhere.
// region_out: (ndofnode) the side each enriched DOF node moves (-1 for mesh nodes).
inline State side_state(const Model& m, const Field field[2], std::vector<int>* region_out = nullptr) {
  State st;
  st.u.assign(m.ndof(), 0.0);
  st.v.assign(m.ndof(), 0.0);
  st.a.assign(m.ndof(), 0.0);
  const int npe = m.mesh.npe();
  std::vector<int> home(m.nnode, 0), region(m.ndofnode, -1);
  if (m.has_cuts()) {
    const CutLayout& L = m.cuts;
    for (int e = 0; e < m.nelem; ++e)
      for (int P = L.elem_piece_ptr[e]; P < L.elem_piece_ptr[e + 1]; ++P) {
        // The piece's side from a point inside it: its first sub-tetrahedron's
        // centroid, or the element's centroid for a whole element.
        double rst[3] = {0.25, 0.25, 0.25}, N[10], X[3] = {0, 0, 0};
        if (L.piece_subtet_ptr[P + 1] > L.piece_subtet_ptr[P]) {
          const double* v = &L.subtet_rst[12 * static_cast<size_t>(L.piece_subtet_ptr[P])];
          for (int c = 0; c < 3; ++c) rst[c] = 0.25 * (v[c] + v[3 + c] + v[6 + c] + v[9 + c]);
        }
        shape_values(npe, rst, N);
        for (int a = 0; a < npe; ++a)
          for (int c = 0; c < 3; ++c) X[c] += N[a] * m.X[3 * m.mesh.tet[e * npe + a] + c];
        const int side = block_plane(X) > 0 ? 1 : 0;
        for (int a = 0; a < npe; ++a) {
          const int node = m.mesh.tet[e * npe + a], q = L.piece_enr[P * npe + a];
          if (q < 0)
            home[node] = side;
          else
            region[q] = side;
        }
      }
  }
  for (int n = 0; n < m.nnode; ++n) {
    const auto f = field[home[n]](&m.X[3 * n]);
    for (int c = 0; c < 3; ++c) st.u[3 * n + c] = f[c];
  }
  for (int q = m.nnode; q < m.ndofnode; ++q) {
    const int n = m.cuts.enr_node[q - m.nnode];
    const auto f = field[region[q]](&m.X[3 * n]), g = field[home[n]](&m.X[3 * n]);
    for (int c = 0; c < 3; ++c) st.u[3 * q + c] = f[c] - g[c];
  }
  if (region_out) *region_out = region;
  return st;
}

// Affine u = A X + b.
inline Field affine(std::array<double, 9> A, std::array<double, 3> b) {
  return [A, b](const double* X) {
    std::array<double, 3> u;
    for (int i = 0; i < 3; ++i) u[i] = A[3 * i] * X[0] + A[3 * i + 1] * X[1] + A[3 * i + 2] * X[2] + b[i];
    return u;
  };
}

}  // namespace incise::test

namespace incise::test {

// Distance from p to triangle (a, b, c) by another route than the library's
// Voronoi regions: the projection onto the plane when it falls inside (by
// solving for its barycentric coordinates), else the nearest of the three
// edges (point-segment by clamped projection). Returns the closest point.
inline Eigen::Vector3d ref_closest_point(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                         const Eigen::Vector3d& c) {
  Eigen::Matrix<double, 3, 2> E;
  E << b - a, c - a;
  const Eigen::Vector2d l = (E.transpose() * E).ldlt().solve(E.transpose() * (p - a));
  if (l[0] >= 0 && l[1] >= 0 && l[0] + l[1] <= 1) return a + E * l;
  Eigen::Vector3d best(0, 0, 0);
  double dbest = 1e300;
  const Eigen::Vector3d v[3] = {a, b, c};
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d s = v[k], e = v[(k + 1) % 3] - v[k];
    const double t = std::clamp(e.dot(p - s) / e.squaredNorm(), 0.0, 1.0);
    const Eigen::Vector3d q = s + t * e;
    if ((q - p).norm() < dbest) dbest = (q - p).norm(), best = q;
  }
  return best;
}

}  // namespace incise::test
