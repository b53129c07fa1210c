#include "collision/grasp.h"

#include <algorithm>
#include <array>
#include <cmath>

#include <Eigen/Dense>

#include "collision/tool_shape.h"
#include "engine/output/probe.h"

namespace incise {

void update_grasp(const Model& model, const InstrumentSpec& spec, const ToolFrame& tool, const TissueSurface& surface,
                  int model_version, Grasp& grasp) {
  const bool closed = tool.after.jaw >= spec.grasp_at;
  if (!closed) {
    grasp.holding = false;
    grasp.held.clear();
    return;
  }
  if (grasp.holding) {
    if (grasp.model_version != model_version) {  // a cut renumbered the pieces
      for (HeldPoint& h : grasp.held) h.piece = piece_containing(model, h.elem, h.rst);
      grasp.model_version = model_version;
    }
    return;
  }
  // Closing now: the surface between the jaws, as the centroids of the
  // surface triangles there, each weighted by its area (a one-point rule per
  // triangle: the held patch's rows then integrate over its area, and on a
  // tet10 face the load reaches corner and midside nodes in proportion, not
  // as equal point loads on whatever grid vertices lie between the jaws).
  // Taken in the tool frame at the frame's start (where the tissue is).
  const double gap = jaw_gap(spec, tool.before.jaw);
  const double hx = 0.5 * spec.jaw_size[0], hy = 0.5 * gap + spec.jaw_size[1], hz = 0.5 * spec.jaw_size[2];
  struct Candidate {
    double d2;                 // squared distance from the tool's origin
    int t;                     // surface triangle
    double area;
    std::array<double, 3> l;   // its centroid in the tool frame
  };
  std::vector<Candidate> inside;
  for (int t = 0; t < surface.ntri(); ++t) {
    const int* v = &surface.tri[3 * static_cast<size_t>(t)];
    if (surface.vert_elem[v[0]] != surface.vert_elem[v[1]] || surface.vert_elem[v[0]] != surface.vert_elem[v[2]] ||
        surface.vert_piece[v[0]] != surface.vert_piece[v[1]] || surface.vert_piece[v[0]] != surface.vert_piece[v[2]])
      continue;  // not one material patch (does not occur for the face grids)
    double c[3], e1[3], e2[3];
    for (int d = 0; d < 3; ++d) {
      const double x0 = surface.x[3 * v[0] + d], x1 = surface.x[3 * v[1] + d], x2 = surface.x[3 * v[2] + d];
      c[d] = (x0 + x1 + x2) / 3.0;
      e1[d] = x1 - x0;
      e2[d] = x2 - x0;
    }
    const std::array<double, 3> l = world_to_tool(tool.before, {c[0], c[1], c[2]});
    if (!(std::abs(l[0]) <= hx && std::abs(l[1]) <= hy && std::abs(l[2]) <= hz)) continue;
    const double nx = e1[1] * e2[2] - e1[2] * e2[1], ny = e1[2] * e2[0] - e1[0] * e2[2], nz = e1[0] * e2[1] - e1[1] * e2[0];
    const double area = 0.5 * std::sqrt(nx * nx + ny * ny + nz * nz);
    if (!(area > 0.0)) continue;  // a degenerate triangle holds nothing
    inside.push_back({l[0] * l[0] + l[1] * l[1] + l[2] * l[2], t, area, l});
  }
  if (inside.empty()) return;  // closed on nothing: nothing held until it opens and closes again
  std::sort(inside.begin(), inside.end(), [](const Candidate& a, const Candidate& b) {
    return a.d2 != b.d2 ? a.d2 < b.d2 : a.t < b.t;
  });
  grasp.held.clear();
  for (const Candidate& cand : inside) {
    if (static_cast<int>(grasp.held.size()) == kMaxHeldPoints) break;
    const int* v = &surface.tri[3 * static_cast<size_t>(cand.t)];
    HeldPoint h;
    h.elem = surface.vert_elem[v[0]];
    h.piece = surface.vert_piece[v[0]];
    for (int d = 0; d < 3; ++d) {
      h.rst[d] = (surface.vert_rst[3 * v[0] + d] + surface.vert_rst[3 * v[1] + d] + surface.vert_rst[3 * v[2] + d]) / 3.0;
      h.local[d] = cand.l[d];
    }
    h.area = cand.area;
    grasp.held.push_back(h);
  }
  grasp.holding = true;
  grasp.model_version = model_version;
}

void add_grasp_rows(const State& state, const Grasp& grasp, const ToolFrame& tool_frame, double dt, int tool,
                    const TissueSurface& surface, ContactRows& rows) {
  if (!grasp.holding || grasp.held.empty()) return;
  const int n = static_cast<int>(grasp.held.size());
  // Per held point: its weights, its area, where it is (x), where the jaws
  // carry it (goal) and where they had it at the frame's start (was).
  std::array<PointWeights, kMaxHeldPoints> w;
  std::array<double, kMaxHeldPoints> a;
  std::array<Eigen::Vector3d, kMaxHeldPoints> x, goal, was;
  double A = 0.0;
  for (int p = 0; p < n; ++p) A += grasp.held[static_cast<size_t>(p)].area;
  Eigen::Vector3d xm = Eigen::Vector3d::Zero(), gm = Eigen::Vector3d::Zero(), wm = Eigen::Vector3d::Zero();
  for (int p = 0; p < n; ++p) {
    const HeldPoint& h = grasp.held[static_cast<size_t>(p)];
    w[p] = surface.point_weights(h.elem, h.piece, h.rst);
    a[p] = h.area / A;
    double X[3], xp[3];
    surface.reference_position(h.elem, h.rst, X);
    point_position(w[p], X, state.u.data(), xp);
    const std::array<double, 3> g = tool_to_world(tool_frame.after, {h.local[0], h.local[1], h.local[2]});
    const std::array<double, 3> b = tool_to_world(tool_frame.before, {h.local[0], h.local[1], h.local[2]});
    x[p] = Eigen::Vector3d(xp[0], xp[1], xp[2]);
    goal[p] = Eigen::Vector3d(g[0], g[1], g[2]);
    was[p] = Eigen::Vector3d(b[0], b[1], b[2]);
    xm += a[p] * x[p], gm += a[p] * goal[p], wm += a[p] * was[p];
  }
  // Mean translation: H_c Delta = sum_p a_p N_p Delta_c (a_p = area / total).
  for (int c = 0; c < 3; ++c) {
    double dir[3] = {0, 0, 0};
    dir[c] = 1.0;
    rows.begin_row(RowKind::Grasp, gm[c] - xm[c], tool, xm.data(), dir, 0.0, -1, (gm[c] - wm[c]) / dt);
    for (int p = 0; p < n; ++p)
      for (int k = 0; k < w[p].n; ++k) rows.add(3 * w[p].dofnode[k] + c, a[p] * w[p].weight[k]);
  }
  // Rotation: the weighted least-squares rigid fit Delta_p ~ t + omega x r_p
  // (r_p = x_p - mean) gives J omega = sum_p a_p r_p x Delta_p with
  // J = sum_p a_p (|r_p|^2 I - r_p r_p^T); along a principal axis e of J
  // (eigenvalue j_e), omega_e = sum_p a_p (e x r_p) . Delta_p / j_e, and the
  // row reads omega_e rho_e with rho_e = sqrt(j_e).
  Eigen::Matrix3d J = Eigen::Matrix3d::Zero();
  for (int p = 0; p < n; ++p) {
    const Eigen::Vector3d r = x[p] - xm;
    J += a[p] * (r.squaredNorm() * Eigen::Matrix3d::Identity() - r * r.transpose());
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(J);
  const double jmax = eig.eigenvalues().maxCoeff();
  if (!(jmax > 0.0)) return;  // one point: its translation is all there is
  for (int e_i = 0; e_i < 3; ++e_i) {
    const double je = eig.eigenvalues()[e_i];
    if (!(je > 1e-6 * jmax)) continue;  // points on a line: no rotation about it
    const Eigen::Vector3d e = eig.eigenvectors().col(e_i);
    const double rho = std::sqrt(je);
    double target = 0.0, vel = 0.0;
    std::array<Eigen::Vector3d, kMaxHeldPoints> coef;
    for (int p = 0; p < n; ++p) {
      coef[p] = a[p] * e.cross(x[p] - xm) / rho;
      target += coef[p].dot(goal[p] - x[p]);
      vel += coef[p].dot(goal[p] - was[p]) / dt;
    }
    const double none[3] = {0, 0, 0};
    rows.begin_row(RowKind::Grasp, target, tool, xm.data(), none, 0.0, -1, vel);
    for (int p = 0; p < n; ++p)
      for (int k = 0; k < w[p].n; ++k)
        for (int c = 0; c < 3; ++c)
          if (coef[p][c] != 0.0) rows.add(3 * w[p].dofnode[k] + c, w[p].weight[k] * coef[p][c]);
  }
}

}  // namespace incise
