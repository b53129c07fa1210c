#include "collision/grasp.h"

#include <algorithm>
#include <array>
#include <cmath>

#include "collision/tool_shape.h"
#include "engine/output/probe.h"

namespace incise {

void update_grasp(const Model& model, const InstrumentSpec& spec, const ToolFrame& tool, const TissueSurface& surface,
                  int model_version, Grasp& grasp, const std::vector<HeldPoint>* imposed, bool pressed) {
  // Closed from grasp_at on, or, holding, down to the jaw it took hold at;
  // jaws that pressed the tissue from both sides while closing take it now.
  const double at = grasp.holding ? std::min(grasp.took_at, spec.grasp_at) : spec.grasp_at;
  const bool closing_onto = pressed && tool.after.jaw > 0.0 && tool.after.jaw >= tool.before.jaw;
  const bool closed = tool.after.jaw >= at || (!grasp.holding && (closing_onto || imposed));
  if (!closed) {
    grasp.holding = false;
    grasp.closed_empty = false;
    grasp.held.clear();
    return;
  }
  if (!grasp.holding) grasp.took_at = std::min(tool.after.jaw, spec.grasp_at);
  if (grasp.holding) {
    if (grasp.model_version != model_version) {  // a cut renumbered the pieces
      for (HeldPoint& h : grasp.held) h.piece = piece_containing(model, h.elem, h.rst);
      grasp.model_version = model_version;
    }
    return;
  }
  if (imposed) {
    grasp.held = *imposed;
    for (HeldPoint& h : grasp.held) h.piece = model.has_cuts() ? piece_containing(model, h.elem, h.rst) : -1;
    grasp.holding = !grasp.held.empty();
    grasp.model_version = model_version;
    return;
  }
  // Closing now: the vertices between the jaws, in the tool frame at the
  // frame's start (where the tissue is).
  const double gap = jaw_gap(spec, tool.before.jaw);
  const double hx = 0.5 * spec.jaw_size[0], hy = 0.5 * gap + spec.jaw_size[1], hz = 0.5 * spec.jaw_size[2];
  struct Candidate {
    double d2;                 // squared distance from the tool's origin
    int v;                     // surface vertex
    std::array<double, 3> l;   // its place in the tool frame
  };
  std::vector<Candidate> inside;
  for (int v = 0; v < surface.nvert(); ++v) {
    const std::array<double, 3> l =
        world_to_tool(tool.before, {surface.x[3 * v], surface.x[3 * v + 1], surface.x[3 * v + 2]});
    if (std::abs(l[0]) <= hx && std::abs(l[1]) <= hy && std::abs(l[2]) <= hz)
      inside.push_back({l[0] * l[0] + l[1] * l[1] + l[2] * l[2], v, l});
  }
  if (inside.empty()) {  // closed on nothing: taken when tissue comes between the closed jaws
    grasp.closed_empty = tool.after.jaw >= spec.grasp_at;
    return;
  }
  grasp.closed_empty = false;
  std::sort(inside.begin(), inside.end(), [](const Candidate& a, const Candidate& b) {
    return a.d2 != b.d2 ? a.d2 < b.d2 : a.v < b.v;
  });
  // A vertex appears once per face it lies on: keep distinct material positions.
  grasp.held.clear();
  for (const Candidate& cand : inside) {
    if (static_cast<int>(grasp.held.size()) == kMaxHeldPoints) break;
    const std::array<double, 3>& l = cand.l;
    bool dup = false;
    for (const HeldPoint& h : grasp.held)
      dup = dup || (std::abs(h.local[0] - l[0]) + std::abs(h.local[1] - l[1]) + std::abs(h.local[2] - l[2]) <
                    1e-9 * (spec.opening + spec.jaw_size[0]));
    if (dup) continue;
    HeldPoint h;
    h.elem = surface.vert_elem[cand.v];
    h.piece = surface.vert_piece[cand.v];
    h.side = surface.vert_side[cand.v];
    for (int d = 0; d < 3; ++d) {
      h.rst[d] = surface.vert_rst[3 * cand.v + d];
      h.local[d] = l[d];
    }
    grasp.held.push_back(h);
  }
  grasp.holding = true;
  grasp.model_version = model_version;
}

void add_grasp_rows(const State& state, const Grasp& grasp, const ToolFrame& tool_frame, double dt, int tool,
                    const TissueSurface& surface, ContactRows& rows) {
  if (!grasp.holding) return;
  for (size_t i = 0; i < grasp.held.size(); ++i) {
    const HeldPoint& h = grasp.held[i];
    const PointWeights w = surface.point_weights(h.elem, h.piece, h.rst, h.side);
    double X[3], x[3];
    surface.reference_position(h.elem, h.rst, X);
    point_position(w, X, state.u.data(), x);
    const std::array<double, 3> goal = tool_to_world(tool_frame.after, {h.local[0], h.local[1], h.local[2]});
    const std::array<double, 3> was = tool_to_world(tool_frame.before, {h.local[0], h.local[1], h.local[2]});
    for (int c = 0; c < 3; ++c) {
      double dir[3] = {0, 0, 0};
      dir[c] = 1.0;
      rows.begin_row(RowKind::Grasp, goal[c] - x[c], tool, x, dir, 0.0, -1, (goal[c] - was[c]) / dt);
      rows.key.back() = row_key(tool, c, static_cast<long long>(i));
      for (int k = 0; k < w.n; ++k) rows.add(3 * w.dofnode[k] + c, w.weight[k]);
    }
  }
}

}  // namespace incise
