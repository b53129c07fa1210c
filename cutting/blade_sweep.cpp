#include "cutting/blade_sweep.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

#include "cutting/cut_surface.h"

namespace incise {

std::array<double, 3> reference_point(const Model& m, const State& s, const double x[3], bool* inside) {
  const int npe = m.mesh.npe();
  int best = -1;
  double best_min = -1e300;
  Eigen::Vector4d best_L(0.25, 0.25, 0.25, 0.25);
  const Eigen::Vector3d xv(x[0], x[1], x[2]);
  for (int e = 0; e < m.mesh.ntet(); ++e) {
    const int* nodes = &m.mesh.tet[static_cast<size_t>(e) * npe];
    Eigen::Vector3d c[4];
    for (int k = 0; k < 4; ++k)
      for (int d = 0; d < 3; ++d) c[k][d] = m.X[3 * nodes[k] + d] + s.u[3 * nodes[k] + d];
    Eigen::Matrix3d J;
    J << c[1] - c[0], c[2] - c[0], c[3] - c[0];
    const Eigen::Vector3d l = J.partialPivLu().solve(xv - c[0]);
    const Eigen::Vector4d L(1.0 - l.sum(), l[0], l[1], l[2]);
    const double mn = L.minCoeff();
    if (std::isfinite(mn) && mn > best_min) {
      best_min = mn;
      best = e;
      best_L = L;
    }
  }
  std::array<double, 3> X{x[0], x[1], x[2]};
  *inside = best >= 0 && best_min >= -1e-9;
  if (best < 0) return X;
  const int* nodes = &m.mesh.tet[static_cast<size_t>(best) * npe];
  for (int d = 0; d < 3; ++d) {
    X[d] = 0.0;
    for (int k = 0; k < 4; ++k) X[d] += best_L[k] * m.X[3 * nodes[k] + d];
  }
  return X;
}

namespace {

// The after-row (edge samples at the end) of tool i's last band, and the
// frame that swept it (-1: none).
int last_edge(const State& s, int tool, std::array<std::array<double, 3>, kSweepSegments + 1>& row) {
  const int nt = static_cast<int>(s.swept_tool.size());
  int last = nt - 1;
  while (last >= 0 && static_cast<int>(s.swept_tool[last]) != tool) --last;
  // The band's triangles, segment j: (a0_j, b0_j, b1_j), (a0_j, b1_j, a1_j);
  // b1_j is after-row point j + 1 and a1_j point j.
  const int first = last - (2 * kSweepSegments - 1);
  if (last < 0 || first < 0) return -1;
  for (int j = 0; j < kSweepSegments; ++j) {
    const double* t0 = &s.swept[9 * static_cast<size_t>(first + 2 * j)];
    const double* t1 = t0 + 9;
    for (int d = 0; d < 3; ++d) {
      row[j + 1][d] = t0[6 + d];
      row[j][d] = t1[6 + d];
    }
  }
  return static_cast<int>(s.swept_frame[last]);
}

// The cube root of the model's mean element volume.
double element_size(const Model& m) {
  double v = 0;
  for (int e = 0; e < m.nelem; ++e) v += m.elem_volume[e];
  return std::cbrt(v / std::max(1, m.nelem));
}

}  // namespace

int sweep_blades(Simulation& sim) {
  int added = 0;
  State& st = sim.state;
  for (size_t i = 0; i < sim.scene.instruments.size() && i < sim.tools.size(); ++i) {
    const InstrumentSpec& spec = sim.scene.instruments[i];
    if (spec.kind != InstrumentSpec::Kind::Scalpel) continue;
    const ToolFrame& f = sim.tools[i];
    // Edge samples at the frame's start (row 0) and end (row 1), in the
    // world, then mapped to the reference configuration the tissue is in now.
    std::array<std::array<double, 3>, kSweepSegments + 1> row[2];
    double moved = 0, length = 0;
    for (int j = 0; j <= kSweepSegments; ++j) {
      const double w = static_cast<double>(j) / kSweepSegments;
      std::array<double, 3> e{};
      for (int d = 0; d < 3; ++d) e[d] = (1.0 - w) * spec.edge[0][d] + w * spec.edge[1][d];
      row[0][j] = tool_to_world(f.before, e);
      row[1][j] = tool_to_world(f.after, e);
      double m2 = 0;
      for (int d = 0; d < 3; ++d) m2 += (row[1][j][d] - row[0][j][d]) * (row[1][j][d] - row[0][j][d]);
      moved = std::max(moved, std::sqrt(m2));
    }
    for (int d = 0; d < 3; ++d) length += (spec.edge[1][d] - spec.edge[0][d]) * (spec.edge[1][d] - spec.edge[0][d]);
    // A blade at rest (to roundoff: poses computed two ways from a
    // trajectory) sweeps no band, even where the tissue moves under it:
    // joined to the last band's row, mapped through the tissue before it
    // moved, it would make a sliver across the incision whose plane is that
    // motion's, and the level set near the blade would take it (the layout
    // lost the incision's enriched nodes and the energy grew 1e6-fold; test
    // BladeSweep.AScalpelThatStopsAndGoesOnCutsAsIfItHadNot).
    if (!(moved > 1e-9 * std::sqrt(length))) continue;
    bool any_inside = false;
    for (int r = 0; r < 2; ++r)
      for (int j = 0; j <= kSweepSegments; ++j) {
        bool inside = false;
        row[r][j] = reference_point(sim.model, st, row[r][j].data(), &inside);
        any_inside = any_inside || inside;
      }
    if (!any_inside) continue;
    // Continue the last band where it ended, so the bands join without a
    // gap although the tissue moved in between: always after a frame that
    // swept one; after frames at rest (or out of the tissue) when the edge
    // comes back within half an element of it. A blade held still while the
    // tissue moves under it would otherwise leave a gap of that motion in
    // the incision (7% of an element in BladeSweep.AScalpelThatStops...), or
    // an overlap.
    std::array<std::array<double, 3>, kSweepSegments + 1> prev;
    const int prev_frame = last_edge(st, static_cast<int>(i), prev);
    bool join = prev_frame == st.frame - 1;
    if (prev_frame >= 0 && !join) {
      double far = 0;
      for (int j = 0; j <= kSweepSegments; ++j) {
        double d2 = 0;
        for (int d = 0; d < 3; ++d) d2 += (prev[j][d] - row[0][j][d]) * (prev[j][d] - row[0][j][d]);
        far = std::max(far, std::sqrt(d2));
      }
      join = far <= 0.5 * element_size(sim.model);
    }
    if (join) row[0] = prev;
    // A band of no area (the edge moved by roundoff, or along itself) cuts
    // nothing.
    bool flat = true;
    for (int j = 0; j < kSweepSegments; ++j)
      flat = flat && degenerate_triangle(row[0][j].data(), row[0][j + 1].data(), row[1][j + 1].data()) &&
             degenerate_triangle(row[0][j].data(), row[1][j + 1].data(), row[1][j].data());
    if (flat) continue;
    const auto push = [&](const std::array<double, 3>& a, const std::array<double, 3>& b, const std::array<double, 3>& c) {
      for (const auto* p : {&a, &b, &c}) st.swept.insert(st.swept.end(), p->begin(), p->end());
      st.swept_tool.push_back(static_cast<double>(i));
      st.swept_frame.push_back(static_cast<double>(st.frame));
      ++added;
    };
    for (int j = 0; j < kSweepSegments; ++j) {
      push(row[0][j], row[0][j + 1], row[1][j + 1]);
      push(row[0][j], row[1][j + 1], row[1][j]);
    }
  }
  return added;
}

}  // namespace incise
