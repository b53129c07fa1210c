#include "cutting/blade_sweep.h"

#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include <Eigen/Dense>

#include "cutting/cut_surface.h"
#include "engine/runtime/trajectory.h"

namespace incise {

namespace {

using Point = std::array<double, 3>;

// The after-row (ns + 1 edge samples at the end) of tool i's last band, and
// the frame that swept it (-1: none).
int last_edge(const State& s, int tool, int ns, std::vector<Point>& row) {
  const int nt = static_cast<int>(s.swept_tool.size());
  int last = nt - 1;
  while (last >= 0 && static_cast<int>(s.swept_tool[last]) != tool) --last;
  // The band's triangles, segment j: (a0_j, b0_j, b1_j), (a0_j, b1_j, a1_j);
  // b1_j is after-row point j + 1 and a1_j point j.
  const int first = last - (2 * ns - 1);
  if (last < 0 || first < 0) return -1;
  row.assign(ns + 1, Point{});
  for (int j = 0; j < ns; ++j) {
    const double* t0 = &s.swept[9 * static_cast<size_t>(first + 2 * j)];
    const double* t1 = t0 + 9;
    for (int d = 0; d < 3; ++d) {
      row[j + 1][d] = t0[6 + d];
      row[j][d] = t1[6 + d];
    }
  }
  return static_cast<int>(s.swept_frame[last]);
}

// The pose a fraction w of the way from a to b (position linear,
// orientation by slerp, as trajectories interpolate).
ToolPose pose_between(const ToolPose& a, const ToolPose& b, double w) {
  ToolPose p = a;
  for (int d = 0; d < 3; ++d) p.p[d] = (1.0 - w) * a.p[d] + w * b.p[d];
  p.q = slerp(a.q, b.q, w);
  return p;
}

}  // namespace

double sweep_spacing(const Mesh& mesh) {
  const int nt = mesh.ntet(), npe = mesh.npe();
  std::vector<double> h(nt);
  for (int e = 0; e < nt; ++e) {
    const int* n = &mesh.tet[static_cast<size_t>(e) * npe];
    Eigen::Matrix3d J;
    for (int c = 0; c < 3; ++c)
      for (int d = 0; d < 3; ++d) J(d, c) = mesh.X[3 * n[c + 1] + d] - mesh.X[3 * n[0] + d];
    h[e] = std::cbrt(std::max(0.0, J.determinant() / 6.0));
  }
  if (h.empty()) return 1e300;
  const size_t k = h.size() / 20;
  std::nth_element(h.begin(), h.begin() + k, h.end());
  return 0.5 * h[k];
}

namespace {
double edge_length(const InstrumentSpec& spec) {
  double l2 = 0;
  for (int d = 0; d < 3; ++d) l2 += (spec.edge[1][d] - spec.edge[0][d]) * (spec.edge[1][d] - spec.edge[0][d]);
  return std::sqrt(l2);
}
}  // namespace

int edge_segments(const InstrumentSpec& spec, double spacing) {
  const double s = std::ceil(edge_length(spec) / (4.0 * spacing));
  return static_cast<int>(std::clamp(s, double(kMinEdgeSegments), double(kMaxEdgeSegments)));
}

int sweep_blades(Simulation& sim, bool* blade_done_changed) {
  int added = 0;
  State& st = sim.state;
  if (blade_done_changed) *blade_done_changed = false;
  std::vector<char> out(sim.scene.instruments.size(), 0);  // a moving blade outside the tissue at the frame's end
  std::unique_ptr<TissueLocator> locator;  // made once, when a blade moved
  std::unique_ptr<TissueLocator> body;     // the reference configuration, made once, when a band may re-cut
  const double h = mean_element_size(sim.model);
  double spacing = -1;
  for (size_t i = 0; i < sim.scene.instruments.size() && i < sim.tools.size(); ++i) {
    const InstrumentSpec& spec = sim.scene.instruments[i];
    if (spec.kind != InstrumentSpec::Kind::Scalpel) continue;
    const ToolFrame& f = sim.tools[i];
    if (spacing < 0) spacing = sweep_spacing(sim.mesh);
    const int ns = edge_segments(spec, spacing);
    const double length = edge_length(spec);
    // Samples along the edge in the tool frame: every `spacing` or finer
    // (m + 1 of them), the band's ns + 1 among them (every r-th).
    const int r = std::max(1, std::min(static_cast<int>(std::ceil(length / spacing / ns)), kMaxEdgeSamples / ns));
    const int m = ns * r;
    std::vector<Point> edge(m + 1);
    for (int q = 0; q <= m; ++q) {
      const double w = static_cast<double>(q) / m;
      for (int d = 0; d < 3; ++d) edge[q][d] = (1.0 - w) * spec.edge[0][d] + w * spec.edge[1][d];
    }
    double moved = 0;
    for (int q = 0; q <= m; q += r) {
      const auto a = tool_to_world(f.before, edge[q]), b = tool_to_world(f.after, edge[q]);
      moved = std::max(moved, std::sqrt((b[0] - a[0]) * (b[0] - a[0]) + (b[1] - a[1]) * (b[1] - a[1]) +
                                        (b[2] - a[2]) * (b[2] - a[2])));
    }
    // A blade at rest (to roundoff: poses computed two ways from a
    // trajectory) sweeps no band, even where the tissue moves under it:
    // joined to the last band's row, mapped through the tissue before it
    // moved, it would make a sliver across the incision whose plane is that
    // motion's, and the level set near the blade would take it (the layout
    // lost the incision's enriched nodes and the energy grew 1e6-fold; test
    // BladeSweep.AScalpelThatStopsAndGoesOnCutsAsIfItHadNot).
    if (!(moved > 1e-9 * length)) continue;
    if (!locator) locator = std::make_unique<TissueLocator>(sim.model, st);
    // Edge samples in the world at the frame's start (row 0) and end (row
    // n), and in between every `spacing` of motion: a blade outside the
    // tissue at both ends of a frame may have passed through it (a thin
    // plate chopped at 1 m/s, an 8 cm organ at 4.5 m/s: nothing was cut).
    const int n = std::clamp(static_cast<int>(std::ceil(moved / spacing)), 1, kMaxSweepSteps);
    std::vector<Point> world(static_cast<size_t>(n + 1) * (m + 1));  // (n + 1, m + 1) samples in the world
    std::vector<int> elem(world.size(), -1);                         // (n + 1, m + 1) the element holding each, or -1
    std::vector<char> in(n + 1, 0);
    for (int k = 0; k <= n; ++k) {
      const ToolPose pose = k == 0 ? f.before : k == n ? f.after : pose_between(f.before, f.after, double(k) / n);
      for (int q = 0; q <= m; ++q) {
        const size_t at = static_cast<size_t>(k) * (m + 1) + q;
        world[at] = tool_to_world(pose, edge[q]);
        elem[at] = locator->locate(world[at].data());
        in[k] = in[k] || elem[at] >= 0;
      }
    }
    out[i] = !in[n];  // (a blade at rest was skipped above: it may rest inside the tissue)
    // The rows from the last one before the blade met the tissue to the
    // first one after it left, mapped to the reference configuration the
    // tissue is in now: a sample in the tissue by the element holding it,
    // one outside by that of the nearest sample in the tissue (on its row,
    // else on the nearest row that has one), extrapolated.
    int k0 = 0;
    while (k0 <= n && !in[k0]) ++k0;
    if (k0 > n) continue;
    int k1 = n;
    while (!in[k1]) --k1;
    k0 = std::max(0, k0 - 1);
    k1 = std::min(n, k1 + 1);
    std::vector<std::vector<Point>> row(n + 1);  // (n + 1) rows of ns + 1 band samples, reference coordinates
    for (int k = k0; k <= k1; ++k) {
      row[k].resize(ns + 1);
      for (int j = 0; j <= ns; ++j) {
        const int q = j * r;
        int e = -1;
        for (int dk = 0; e < 0 && dk <= n; ++dk)
          for (const int kk : {k - dk, k + dk}) {
            if (e >= 0 || kk < 0 || kk > n || !in[kk]) continue;
            const int* at = &elem[static_cast<size_t>(kk) * (m + 1)];
            for (int dq = 0; e < 0 && dq <= m; ++dq) {
              if (q - dq >= 0 && at[q - dq] >= 0) e = at[q - dq];
              else if (q + dq <= m && at[q + dq] >= 0) e = at[q + dq];
            }
          }
        row[k][j] = locator->reference_by(e, world[static_cast<size_t>(k) * (m + 1) + q].data());
      }
    }
    // Continue the last band where it ended, so the bands join without a
    // gap although the tissue moved in between: after a frame that swept
    // one when the edge is within an element of where it ended (it ended
    // elsewhere when the blade left the tissue during that frame); after
    // frames at rest (or out of the tissue) when the edge comes back within
    // half an element of it. A blade held still while the tissue moves under
    // it would otherwise leave a gap of that motion in the incision (7% of
    // an element in BladeSweep.AScalpelThatStops...), or an overlap.
    if (k0 == 0) {
      std::vector<Point> prev;
      const int prev_frame = last_edge(st, static_cast<int>(i), ns, prev);
      if (prev_frame >= 0) {
        double far = 0;
        for (int j = 0; j <= ns; ++j) {
          double d2 = 0;
          for (int d = 0; d < 3; ++d) d2 += (prev[j][d] - row[0][j][d]) * (prev[j][d] - row[0][j][d]);
          far = std::max(far, std::sqrt(d2));
        }
        if (far <= (prev_frame == st.frame - 1 ? 1.0 : 0.5) * h) row[0] = prev;
      }
    }
    // The incision this blade made before this frame.
    const std::unique_ptr<CutSurface> old =
        make_swept_surface(st.swept, st.swept_tool, static_cast<int>(i), spec.json_path);
    // Triangle (a, b, c), as the nearest old facet faces where it continues
    // the incision in about its plane: (b, a, c) when it faced the other way
    // (the blade drawn back; last_edge reads the third corners).
    const auto push = [&](const Point& a, const Point& b, const Point& c) {
      bool flip = false;
      if (old) {
        const Eigen::Vector3d A(a.data()), B(b.data()), C(c.data()), n = (B - A).cross(C - A).normalized();
        const Eigen::Vector3d m = (A + B + C) / 3.0;
        const Facet& f = old->nearest(m.data());
        const Eigen::Vector3d fn(f.n[0], f.n[1], f.n[2]), fp(f.p[0], f.p[1], f.p[2]);
        flip = n.dot(fn) < -0.7 && std::abs((m - fp).dot(fn)) <= 0.25 * h && old->distance(m.data()) <= h;
      }
      for (const auto* p : {flip ? &b : &a, flip ? &a : &b, &c}) st.swept.insert(st.swept.end(), p->begin(), p->end());
      st.swept_tool.push_back(static_cast<double>(i));
      st.swept_frame.push_back(static_cast<double>(st.frame));
      ++added;
    };
    // A band within the incision already made (the blade drawn back along
    // it, or through it again) cuts nothing new: every point of a 3 x 5
    // grid over it that lies in the reference body lies within kReCutReach
    // of the old bands and beside them, not ahead of them (a blade that
    // goes on is ahead by its motion; points outside the body are
    // extrapolations, off by more, and cut nothing). Kept, it lay on the
    // old bands, facing the other way when the blade went back, and the
    // nearest-facet level set between two such sheets changed sign from
    // node to node: a withdrawal cut off a zero-thickness sliver that
    // flailed, cutting back and forth diverged.
    const auto recuts = [&](int k) {
      if (!old) return false;
      if (!body) body = std::make_unique<TissueLocator>(sim.model, nullptr);
      bool any = false;
      for (int a = 0; a <= 2; ++a)
        for (int b = 0; b <= 4; ++b) {
          const double s = 0.5 * a, t = 0.25 * b * ns;
          const int j = std::min(static_cast<int>(t), ns - 1);
          const double w = t - j;
          double x[3];
          for (int d = 0; d < 3; ++d)
            x[d] = (1 - s) * ((1 - w) * row[k][j][d] + w * row[k][j + 1][d]) +
                   s * ((1 - w) * row[k + 1][j][d] + w * row[k + 1][j + 1][d]);
          if (!body->inside(x)) continue;
          any = true;
          // Within reach of the old bands, and beside them rather than
          // ahead: the offset to the nearest one is across its plane.
          const double dist = old->distance(x), across = old->value(x).phi;
          if (!(dist <= kReCutReach * h && dist * dist - across * across <= 0.04 * kReCutReach * kReCutReach * h * h))
            return false;
        }
      return any;
    };
    for (int k = k0; k < k1; ++k) {
      // A band of no area (the edge moved by roundoff, or along itself)
      // cuts nothing.
      bool flat = true;
      for (int j = 0; j < ns; ++j)
        flat = flat && degenerate_triangle(row[k][j].data(), row[k][j + 1].data(), row[k + 1][j + 1].data()) &&
               degenerate_triangle(row[k][j].data(), row[k + 1][j + 1].data(), row[k + 1][j].data());
      if (flat || recuts(k)) continue;
      for (int j = 0; j < ns; ++j) {
        push(row[k][j], row[k][j + 1], row[k + 1][j + 1]);
        push(row[k][j], row[k + 1][j + 1], row[k + 1][j]);
      }
    }
  }
  // A scalpel out of the tissue at the frame's end has finished a stroke
  // when it swept bands since its last one ended (this frame's included).
  for (size_t i = 0; i < out.size() && sim.scene.front_enrichment; ++i) {
    if (!out[i]) continue;
    const double n = static_cast<double>(std::count(st.swept_tool.begin(), st.swept_tool.end(), double(i)));
    double last = 0;
    for (size_t k = 0; k + 1 < st.blade_done.size(); k += 2)
      if (st.blade_done[k] == double(i)) last = st.blade_done[k + 1];
    if (n <= last) continue;
    st.blade_done.insert(st.blade_done.end(), {double(i), n});
    if (blade_done_changed) *blade_done_changed = true;
  }
  return added;
}

}  // namespace incise
