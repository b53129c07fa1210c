#include "cutting/blade_sweep.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Dense>

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

int sweep_blades(Simulation& sim) {
  int added = 0;
  for (size_t i = 0; i < sim.scene.instruments.size() && i < sim.tools.size(); ++i) {
    const InstrumentSpec& spec = sim.scene.instruments[i];
    if (spec.kind != InstrumentSpec::Kind::Scalpel) continue;
    const ToolFrame& f = sim.tools[i];
    if (f.before.p == f.after.p && f.before.q == f.after.q) continue;  // no motion, no band
    // Edge samples at the frame's start (row 0) and end (row 1), mapped to
    // the reference configuration the tissue is in now.
    std::array<std::array<double, 3>, 2 * (kSweepSegments + 1)> P;
    bool any_inside = false;
    for (int row = 0; row < 2; ++row)
      for (int j = 0; j <= kSweepSegments; ++j) {
        const double w = static_cast<double>(j) / kSweepSegments;
        std::array<double, 3> e{};
        for (int d = 0; d < 3; ++d) e[d] = (1.0 - w) * spec.edge[0][d] + w * spec.edge[1][d];
        const std::array<double, 3> x = tool_to_world(row == 0 ? f.before : f.after, e);
        bool inside = false;
        P[row * (kSweepSegments + 1) + j] = reference_point(sim.model, sim.state, x.data(), &inside);
        any_inside = any_inside || inside;
      }
    if (!any_inside) continue;
    const auto push = [&](const std::array<double, 3>& a, const std::array<double, 3>& b, const std::array<double, 3>& c) {
      for (const auto* p : {&a, &b, &c}) sim.state.swept.insert(sim.state.swept.end(), p->begin(), p->end());
      sim.state.swept_tool.push_back(static_cast<double>(i));
      ++added;
    };
    for (int j = 0; j < kSweepSegments; ++j) {
      const auto &a0 = P[j], &b0 = P[j + 1], &a1 = P[kSweepSegments + 1 + j], &b1 = P[kSweepSegments + 2 + j];
      push(a0, b0, b1);
      push(a0, b1, a1);
    }
  }
  return added;
}

}  // namespace incise
