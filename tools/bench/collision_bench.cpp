// incise_collision_bench: Google Benchmark of the collision stage on the
// 20k-DOF tet10 organ (assets/meshes/organ_20k.msh with the material and
// render.subdivision of assets/scenes/organ_drag.json), uncut and cut by a
// plane through its middle. One iteration of
//   BM_Refit      vertex positions from the state + BVH refit (two deformed
//                 states alternate, so every vertex moves),
//   BM_Query      query_contacts of a sphere pressed into the top of the organ,
//                 sized to touch about 1, 10 or 50 triangles,
//   BM_Collision  both: the per-frame cost of the collision stage,
//   BM_Rebuild    a new surface and tree (after a cut),
// each with an AABB and an OBBRSS tree; BM_Positions is the first half of
// BM_Refit alone. Counters: triangles, contacts.
// Not part of ctest. Run: build/tools/incise_collision_bench
//   [--benchmark_filter=...] [--benchmark_repetitions=10 --benchmark_report_aggregates_only]
#include <algorithm>
#include <cmath>
#include <memory>
#include <vector>

#include <benchmark/benchmark.h>

#include "collision/contact_query.h"
#include "cutting/cut_surface.h"
#include "cutting/xfem_layout.h"
#include "engine/mesh/mesh_io.h"
#include "engine/model/model.h"
#include "engine/scene/scene.h"

namespace {

using namespace incise;

struct Organ {
  Scene scene;
  Model model;
  State a, b;     // two deformed states
  double lo[3], hi[3];
};

double hi_extent(const Organ& o) { return std::max({o.hi[0] - o.lo[0], o.hi[1] - o.lo[1], o.hi[2] - o.lo[2]}); }

// u = amp * (sin, cos, sin) waves over the organ, differing by phase.
State wave(const Model& m, const Organ& o, double phase) {
  State st;
  st.u.assign(m.ndof(), 0.0);
  st.v.assign(m.ndof(), 0.0);
  st.a.assign(m.ndof(), 0.0);
  const double L = hi_extent(o), amp = 0.01 * L, k = 2 * M_PI / L;
  for (int n = 0; n < m.nnode; ++n) {
    const double* X = &m.X[3 * n];
    st.u[3 * n] = amp * std::sin(k * X[1] + phase);
    st.u[3 * n + 1] = amp * std::cos(k * X[2] + phase);
    st.u[3 * n + 2] = amp * std::sin(k * X[0] + phase);
  }
  for (int q = m.nnode; q < m.ndofnode; ++q) st.u[3 * q] = (phase > 0 ? 0.002 : 0.001) * L;  // the cut opens
  return st;
}

const Organ& organ(bool cut) {
  auto make = [](bool with_cut) {
    auto o = std::make_unique<Organ>();
    o->scene = load_scene(INCISE_SOURCE_DIR "/assets/scenes/organ_drag.json");
    const Mesh mesh = read_mesh(INCISE_SOURCE_DIR "/assets/meshes/organ_20k.msh");
    o->model = build_model(mesh, o->scene);
    for (int d = 0; d < 3; ++d) o->lo[d] = 1e300, o->hi[d] = -1e300;
    for (int n = 0; n < o->model.nnode; ++n)
      for (int d = 0; d < 3; ++d)
        o->lo[d] = std::min(o->lo[d], o->model.X[3 * n + d]), o->hi[d] = std::max(o->hi[d], o->model.X[3 * n + d]);
    if (with_cut) {  // a vertical plane through the middle, a little off the axes
      CutSpec c;
      c.type = CutSpec::Type::Plane;
      c.point = {0.5 * (o->lo[0] + o->hi[0]) + 1e-4, 0, 0};
      const double l = std::sqrt(1 + 0.01 + 0.0025);
      c.normal = {1 / l, 0.1 / l, 0.05 / l};
      c.json_path = "cuts[0]";
      const auto surf = make_cut_surface(c, 0.0);
      const CutLayout layout = compute_cut_layout(o->model, {surf.get()}, nullptr);
      o->model = build_model(mesh, o->scene, &layout, &o->model);
    }
    o->a = wave(o->model, *o, 0.0);
    o->b = wave(o->model, *o, 0.3);
    return o;
  };
  static const std::unique_ptr<Organ> uncut = make(false), with_cut = make(true);
  return cut ? *with_cut : *uncut;
}

// A sphere pressed by half its radius into the triangle whose centroid is
// highest, along its normal, the radius bisected until it touches about
// `want` triangles.
ToolShape touching_sphere(const CollisionModel& cm, int want, int& got) {
  const TissueSurface& s = cm.surface();
  auto centroid_z = [&s](int t) {
    return (s.x[3 * s.tri[3 * t] + 2] + s.x[3 * s.tri[3 * t + 1] + 2] + s.x[3 * s.tri[3 * t + 2] + 2]) / 3;
  };
  int top = 0;
  for (int t = 0; t < s.ntri(); ++t)
    if (centroid_z(t) > centroid_z(top)) top = t;
  Eigen::Vector3d v[3];
  for (int j = 0; j < 3; ++j) {
    const double* x = &s.x[3 * s.tri[3 * top + j]];
    v[j] = Eigen::Vector3d(x[0], x[1], x[2]);
  }
  const Eigen::Vector3d c = (v[0] + v[1] + v[2]) / 3, n = (v[1] - v[0]).cross(v[2] - v[0]).normalized();
  ContactRequest req;
  req.max_contacts = 100000;
  ContactResult res;
  InstrumentSpec spec;
  spec.json_path = "bench";
  ToolPose pose;
  auto count = [&](double r) {
    spec.radius = r;
    const Eigen::Vector3d p = c + 0.5 * r * n;
    pose.p = {p[0], p[1], p[2]};
    query_contacts(cm, make_tool_shape(spec, pose), req, res);
    return static_cast<int>(res.contacts.size());
  };
  double lo = 1e-6, hi = 0.05;
  for (int it = 0; it < 60; ++it) {
    const double mid = std::sqrt(lo * hi);
    (count(mid) < want ? lo : hi) = mid;
  }
  got = count(hi);
  return make_tool_shape(spec, pose);
}

void set_counters(benchmark::State& state, const CollisionModel& cm, int contacts) {
  state.counters["triangles"] = cm.surface().ntri();
  state.counters["contacts"] = contacts;
}

void BM_Positions(benchmark::State& state, bool cut) {
  const Organ& o = organ(cut);
  TissueSurface s(o.model, o.a, o.scene.render.subdivision);
  int k = 0;
  for (auto _ : state) {
    s.update_positions((++k & 1) ? o.b : o.a);
    benchmark::DoNotOptimize(s.x.data());
  }
  state.counters["vertices"] = s.nvert();
  state.counters["weights"] = static_cast<double>(s.vert_weight.size());
}

void BM_Refit(benchmark::State& state, bool cut, TissueBV bv) {
  const Organ& o = organ(cut);
  CollisionModel cm(o.scene.render.subdivision, bv);
  cm.sync(o.model, o.a, 0);
  int k = 0;
  for (auto _ : state) cm.sync(o.model, (++k & 1) ? o.b : o.a, 0);
  if (cm.rebuilds() != 1) state.SkipWithError("a refit frame rebuilt the tree");
  set_counters(state, cm, 0);
}

// A sphere touching about `want` triangles queried each iteration; with
// `refit`, the surface moves first (the collision stage's whole work).
void query_bench(benchmark::State& state, bool cut, TissueBV bv, int want, bool refit) {
  const Organ& o = organ(cut);
  CollisionModel cm(o.scene.render.subdivision, bv);
  cm.sync(o.model, o.a, 0);
  int got = 0;
  const ToolShape tool = touching_sphere(cm, want, got);
  ContactResult res;
  ContactRequest req;
  req.max_contacts = 48;
  int k = 0;
  for (auto _ : state) {
    if (refit) cm.sync(o.model, (++k & 1) ? o.b : o.a, 0);
    query_contacts(cm, tool, req, res);
    benchmark::DoNotOptimize(res.contacts.data());
  }
  set_counters(state, cm, got);
}

void BM_Query(benchmark::State& state, bool cut, TissueBV bv, int want) { query_bench(state, cut, bv, want, false); }
void BM_Collision(benchmark::State& state, bool cut, TissueBV bv, int want) { query_bench(state, cut, bv, want, true); }

void BM_Rebuild(benchmark::State& state, bool cut, TissueBV bv) {
  const Organ& o = organ(cut);
  CollisionModel cm(o.scene.render.subdivision, bv);
  int version = 0;
  for (auto _ : state) cm.sync(o.model, o.a, version++);
  set_counters(state, cm, 0);
}

}  // namespace

#define COLLISION_BENCH(name, ...) \
  BENCHMARK_CAPTURE(name, __VA_ARGS__)->Unit(benchmark::kMicrosecond)->UseRealTime()

COLLISION_BENCH(BM_Positions, uncut, false);
COLLISION_BENCH(BM_Positions, cut, true);
COLLISION_BENCH(BM_Refit, uncut_aabb, false, TissueBV::AABB);
COLLISION_BENCH(BM_Refit, uncut_obbrss, false, TissueBV::OBBRSS);
COLLISION_BENCH(BM_Refit, cut_aabb, true, TissueBV::AABB);
COLLISION_BENCH(BM_Refit, cut_obbrss, true, TissueBV::OBBRSS);
COLLISION_BENCH(BM_Query, uncut_aabb_1, false, TissueBV::AABB, 1);
COLLISION_BENCH(BM_Query, uncut_aabb_10, false, TissueBV::AABB, 10);
COLLISION_BENCH(BM_Query, uncut_aabb_50, false, TissueBV::AABB, 50);
COLLISION_BENCH(BM_Query, uncut_obbrss_1, false, TissueBV::OBBRSS, 1);
COLLISION_BENCH(BM_Query, uncut_obbrss_10, false, TissueBV::OBBRSS, 10);
COLLISION_BENCH(BM_Query, uncut_obbrss_50, false, TissueBV::OBBRSS, 50);
COLLISION_BENCH(BM_Collision, uncut_aabb_1, false, TissueBV::AABB, 1);
COLLISION_BENCH(BM_Collision, uncut_aabb_10, false, TissueBV::AABB, 10);
COLLISION_BENCH(BM_Collision, uncut_aabb_50, false, TissueBV::AABB, 50);
COLLISION_BENCH(BM_Collision, uncut_obbrss_50, false, TissueBV::OBBRSS, 50);
COLLISION_BENCH(BM_Collision, cut_aabb_50, true, TissueBV::AABB, 50);
COLLISION_BENCH(BM_Rebuild, uncut_aabb, false, TissueBV::AABB);
COLLISION_BENCH(BM_Rebuild, uncut_obbrss, false, TissueBV::OBBRSS);
COLLISION_BENCH(BM_Rebuild, cut_aabb, true, TissueBV::AABB);

BENCHMARK_MAIN();
