#pragma once
// Helpers for the cutting tests: a block scene, a cut model, steps.
#include <array>
#include <cmath>
#include <memory>
#include <string>

#include "cutting/cut_apply.h"
#include "cutting/cut_stage.h"
#include "cutting/cut_surface.h"
#include "cutting/xfem_layout.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/model/model.h"
#include "engine/scene/scene.h"
#include "tests/engine/test_util.h"

namespace incise::test {

inline Scene block_scene(int order) {
  Scene s;
  s.path = "test-scene";
  s.order = order;
  s.material.young = 1e4;
  s.material.poisson = 0.3;
  s.material.density = 1.0;
  s.gravity = {0.0, 0.0, -9.81};
  return s;
}

inline CutSpec plane_cut(Vec3 p, Vec3 n, const std::string& name = "cuts[0]") {
  CutSpec c;
  c.type = CutSpec::Type::Plane;
  c.point = p;
  const double l = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  c.normal = {n[0] / l, n[1] / l, n[2] / l};
  c.json_path = name;
  return c;
}

inline Region box(Vec3 lo, Vec3 hi, const std::string& name = "fixed[0]") { return box_region(lo, hi, name); }

// A blade edge moving from `start` to `end` (two points each) over `duration` s.
inline CutSpec swept_blade(std::array<Vec3, 2> start, std::array<Vec3, 2> end, double duration = 1.0) {
  CutSpec c;
  c.type = CutSpec::Type::Swept;
  c.edge_start = start;
  c.edge_end = end;
  c.duration = duration;
  c.json_path = "cuts[0]";
  return c;
}

// A Simulation built in memory (no files); its pipeline has the cutting
// stage when the scene declares cuts (as load_checked_simulation sets it up).
inline std::unique_ptr<Simulation> make_sim(const Mesh& mesh, const Scene& scene) {
  auto sim = std::make_unique<Simulation>();
  sim->scene = scene;
  sim->mesh = mesh;
  sim->model = build_model(mesh, scene);
  sim->state.cut_progress.assign(scene.cuts.size(), -1.0);
  sim->ws.runtime = scene.runtime;
  init_state(sim->model, sim->state, sim->ws);
  install_cutting_stage(*sim);
  return sim;
}

}  // namespace incise::test
