#include "haptics/contact_model.h"

#include <algorithm>
#include <cmath>

namespace incise {
namespace {
// Per solve: a tick's warm start (the last tick's lambda) leaves little to
// do; the cap bounds a tick at 48 rows to about 2 x 50 x 48^2 multiply-adds.
constexpr int kMaxSweeps = 50;
}  // namespace

void fill_contact_model(const Simulation& sim, int tool, double k, HapticContactModel& out) {
  const ContactRows& c = sim.ws.contacts;
  const int r = c.nrow();
  out.frame = sim.state.frame;
  out.time = sim.state.time;
  out.x0 = sim.tools[static_cast<size_t>(tool)].after.p;
  out.sim_force = {0.0, 0.0, 0.0};
  out.rows = 0;
  const bool solved = r > 0 && sim.ws.contact_W.size() == static_cast<size_t>(r) * r &&
                      c.lambda.size() == static_cast<size_t>(r) && sim.ws.delta.size() >= static_cast<size_t>(sim.model.ndof());
  if (!solved) return;
  // Row selection without allocating: active rows (pushing contacts,
  // grasps) in a first pass, the others after, while there is room.
  std::array<int, kMaxHapticRows> pick{};
  int n = 0;
  for (int pass = 0; pass < 2 && n < kMaxHapticRows; ++pass)
    for (int i = 0; i < r && n < kMaxHapticRows; ++i) {
      if (c.tool[i] != tool || c.kind[i] == RowKind::Friction) continue;
      // A row on constrained DOFs only (a fixed face) still pushes through the spring.
      if (!(sim.ws.contact_W[static_cast<size_t>(i) * r + i] + 1.0 / k > 0.0)) continue;
      const bool active = c.kind[i] == RowKind::Grasp || c.lambda[i] > 0.0;
      if (active == (pass == 0)) pick[n++] = i;
    }
  out.rows = n;
  for (int a = 0; a < n; ++a) {
    const int i = pick[a];
    double hd = 0.0;
    for (int e = c.ptr[i]; e < c.ptr[i + 1]; ++e) hd += c.coef[e] * sim.ws.delta[c.dof[e]];
    const double s = hd - c.target[i];  // < 0 on a row whose tool yields to its spring
    const double* d = &c.dir[3 * static_cast<size_t>(i)];
    out.bilateral[a] = c.kind[i] == RowKind::Grasp;
    out.lambda0[a] = c.lambda[i];
    double wl = 0.0;
    for (int b = 0; b < n; ++b) wl += sim.ws.contact_W[static_cast<size_t>(i) * r + pick[b]] * c.lambda[pick[b]];
    // The tool's rows left out (friction, beyond kMaxHapticRows) keep their
    // lambda0; through the spring they still move this row's gap: the pull
    // of all the tool's rows less that of the picked ones.
    double held = 0.0;
    for (int j = 0; j < r; ++j)
      if (c.tool[j] == tool) held += (d[0] * c.dir[3 * j] + d[1] * c.dir[3 * j + 1] + d[2] * c.dir[3 * j + 2]) * c.lambda[j];
    for (int b = 0; b < n; ++b) {
      const int j = pick[b];
      held -= (d[0] * c.dir[3 * j] + d[1] * c.dir[3 * j + 1] + d[2] * c.dir[3 * j + 2]) * c.lambda[j];
    }
    held /= k;
    out.q0[a] = s + d[0] * out.x0[0] + d[1] * out.x0[1] + d[2] * out.x0[2] - wl + held;
    for (int q = 0; q < 3; ++q) {
      out.D[3 * a + q] = d[q];
      out.sim_force[q] -= c.lambda[i] * d[q];
    }
  }
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b) {
      const double dd = out.D[3 * a] * out.D[3 * b] + out.D[3 * a + 1] * out.D[3 * b + 1] + out.D[3 * a + 2] * out.D[3 * b + 2];
      out.Wc[static_cast<size_t>(a) * n + b] = sim.ws.contact_W[static_cast<size_t>(pick[a]) * r + pick[b]] + dd / k;
    }
}

std::array<double, 3> coupling_force(const HapticContactModel& m, const std::array<double, 3>& x, double* lambda,
                                     int* sweeps) {
  const int n = m.rows;
  std::array<double, kMaxHapticRows> q;
  double qmax = 0.0;
  for (int i = 0; i < n; ++i) {
    q[i] = m.q0[i] - (m.D[3 * i] * x[0] + m.D[3 * i + 1] * x[1] + m.D[3 * i + 2] * x[2]);
    qmax = std::max(qmax, std::abs(q[i]));
  }
  const double tol = 1e-9 * qmax;
  int sweep = 0;
  while (n > 0 && sweep < kMaxSweeps) {
    ++sweep;
    double moved = 0.0;
    for (int i = 0; i < n; ++i) {
      const double* w = &m.Wc[static_cast<size_t>(i) * n];
      double g = q[i];
      for (int j = 0; j < n; ++j) g += w[j] * lambda[j];
      double li = lambda[i] - g / w[i];
      if (!m.bilateral[i]) li = std::max(0.0, li);
      moved = std::max(moved, std::abs(li - lambda[i]) * w[i]);
      lambda[i] = li;
    }
    if (moved <= tol) break;
  }
  if (sweeps) *sweeps = sweep;
  std::array<double, 3> f{0.0, 0.0, 0.0};
  for (int i = 0; i < n; ++i)
    for (int d = 0; d < 3; ++d) f[d] -= lambda[i] * m.D[3 * i + d];
  return f;
}

}  // namespace incise
