#pragma once
// The scene's JSON before it is parsed: command-line patches (--set KEY=VALUE)
// and the expansion of solver.preset. Used by engine/scene/scene.cpp; the
// public API is load_scene / parse_scene with patches (engine/scene/scene.h).
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "engine/scene/scene.h"

namespace incise {

// A patch as applied: the JSON path it set, in the parser's notation
// ("cuts[0].at_time"), and the patch itself.
struct AppliedPatch {
  std::string path;
  const ScenePatch* patch = nullptr;
};

// Applies the patches in order. Intermediate objects that are missing are
// created; a value "null" removes the key. Throws incise::Error naming the
// patch as given when its key cannot be reached (an index out of range, a key
// below a number).
std::vector<AppliedPatch> apply_scene_patches(nlohmann::json& root, const std::vector<ScenePatch>& patches);

// The last patch that set `where` (a JSON path of the parser) or an object
// around it, or that set a key below `where`; nullptr when none did.
const ScenePatch* patch_for(const std::vector<AppliedPatch>& applied, const std::string& where);

// The solver.* and integrator.* keys of a preset ("realtime", "reference");
// nullptr for another name.
const nlohmann::json* solver_preset(const std::string& name);
const std::vector<std::string>& solver_preset_names();

// Adds to root["solver"] and root["integrator"] each key of the preset that
// they lack and that the resolved solver.policy uses (a preset's lagged keys
// are left out when the scene sets another policy; its factor_precision
// "single" when the scene's factor copy is not float). Returns the JSON paths
// it added ("solver.refresh_every"). `name` must be a preset.
std::vector<std::string> expand_solver_preset(nlohmann::json& root, const std::string& name);

}  // namespace incise
