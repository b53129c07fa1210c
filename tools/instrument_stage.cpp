#include "tools/instrument_stage.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "engine/util/error.h"
#include "engine/runtime/trajectory.h"
#include "engine/util/number_text.h"

namespace incise {
namespace {

// sim.module_data[kStageToolPoses]: one entry per instrument, empty without a trajectory.
struct InstrumentPaths {
  std::vector<std::optional<Trajectory>> trajectory;
};

const InstrumentPaths* paths_of(const Simulation& sim) {
  return static_cast<const InstrumentPaths*>(sim.module_data[kStageToolPoses].get());
}


// A size far from the tissue's scale is a unit mistake (mm for m), not an instrument.
void check_sizes(const Simulation& sim) {
  const double diag = sim.model.body_length;  // the mesh nodes' bounding-box diagonal
  const double lo = 1e-4 * diag, hi = 10.0 * diag;
  auto check = [&](const std::string& where, double value) {
    if (value >= lo && value <= hi) return;
    throw Error(key_origin(sim.scene, where) + ": " + where + " = " + number_text(value) + " is outside [" + number_text(lo) + ", " +
                number_text(hi) + "], 1e-4 to 10 times the mesh's bounding-box diagonal " + number_text(diag) +
                ": an instrument outside any sensible scale (check the units)");
  };
  for (const InstrumentSpec& s : sim.scene.instruments) {
    const std::string& at = s.json_path;
    switch (s.kind) {
      case InstrumentSpec::Kind::Probe:
        check(at + ".radius", s.radius);
        if (s.length > 0.0) check(at + ".length", s.length);  // 0: a sphere
        break;
      case InstrumentSpec::Kind::Scalpel:
        for (int k = 0; k < 3; ++k) check(at + ".blade[" + std::to_string(k) + "]", s.blade[k]);
        break;
      case InstrumentSpec::Kind::Grasper:
        for (int k = 0; k < 3; ++k) check(at + ".jaw_size[" + std::to_string(k) + "]", s.jaw_size[k]);
        check(at + ".opening", s.opening);
        break;
    }
  }
}

}  // namespace

ToolPose instrument_pose(const Simulation& sim, int i, double t) {
  if (i < 0 || i >= static_cast<int>(sim.scene.instruments.size()))
    throw Error("instrument_pose: no instrument " + std::to_string(i) + " (the scene has " +
                std::to_string(sim.scene.instruments.size()) + ")");
  const InstrumentSpec& spec = sim.scene.instruments[static_cast<size_t>(i)];
  if (spec.trajectory.empty()) {
    ToolPose pose;
    pose.p = spec.position;
    pose.q = spec.orientation;
    pose.jaw = spec.jaw;
    return pose;
  }
  const InstrumentPaths* paths = paths_of(sim);
  if (!paths || !paths->trajectory[static_cast<size_t>(i)])
    throw Error("instrument_pose: " + spec.json_path + " has a trajectory but install_instrument_stage has not read it");
  const Trajectory& tr = *paths->trajectory[static_cast<size_t>(i)];
  ToolPose pose = tr.sample(t);
  if (!tr.has_jaw()) pose.jaw = spec.jaw;
  return pose;
}

void tool_poses_stage(Simulation& sim) {
  const double t0 = sim.state.time, t1 = sim.state.time + sim.model.dt;
  for (size_t i = 0; i < sim.tools.size(); ++i) {
    sim.tools[i].before = instrument_pose(sim, static_cast<int>(i), t0);
    sim.tools[i].after = instrument_pose(sim, static_cast<int>(i), t1);
  }
}

void install_instrument_stage(Simulation& sim, const std::vector<ToolFrame>* recorded) {
  const std::vector<InstrumentSpec>& specs = sim.scene.instruments;
  if (specs.empty()) return;
  if (recorded && recorded->size() != specs.size())
    throw Error(sim.scene.path + ": recorded poses of " + std::to_string(recorded->size()) + " instruments, the scene has " +
                std::to_string(specs.size()));
  auto paths = std::make_shared<InstrumentPaths>();
  paths->trajectory.resize(specs.size());
  for (size_t i = 0; i < specs.size(); ++i) {
    if (specs[i].trajectory.empty() || recorded) continue;
    try {
      paths->trajectory[i] = Trajectory::read(specs[i].trajectory);
    } catch (const Error& e) {
      throw Error(sim.scene.path + ": " + specs[i].json_path + ".trajectory: " + e.what());
    }
  }
  check_sizes(sim);
  sim.module_data[kStageToolPoses] = paths;
  sim.tools.assign(specs.size(), ToolFrame{});
  for (size_t i = 0; i < specs.size(); ++i)
    sim.tools[i].before = sim.tools[i].after =
        recorded ? (*recorded)[i].before : instrument_pose(sim, static_cast<int>(i), sim.state.time);
  sim.pipeline.set(kStageToolPoses, tool_poses_stage);
}

}  // namespace incise
