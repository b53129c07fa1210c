#include "engine/scene/scene_patch.h"

#include <cctype>

#include "engine/util/error.h"
#include "engine/util/json_depth.h"

namespace incise {
namespace {

using json = nlohmann::json;

bool starts_with(const std::string& s, const std::string& prefix) { return s.compare(0, prefix.size(), prefix) == 0; }

// `inner` is `outer` or a key or index below it ("solver.policy" in "solver").
bool within(const std::string& inner, const std::string& outer) {
  return inner == outer || starts_with(inner, outer + ".") || starts_with(inner, outer + "[");
}

// "cuts[0].at_time" and "cuts.0.at_time" -> {"cuts", "0", "at_time"}.
std::vector<std::string> split_key(const ScenePatch& p) {
  std::string k;
  for (char c : p.key) {
    if (c == '[') k += '.';
    else if (c != ']') k += c;
  }
  std::vector<std::string> out(1);
  for (char c : k) {
    if (c == '.') out.emplace_back();
    else out.back() += c;
  }
  if (out.size() > static_cast<size_t>(kMaxJsonDepth))
    throw Error(p.given + ": the key has " + std::to_string(out.size()) + " parts, more than " +
                std::to_string(kMaxJsonDepth) + " (a scene nests fewer than 10 levels)");
  for (const auto& c : out)
    if (c.empty()) throw Error(p.given + ": the key \"" + p.key + "\" has an empty part (expected a.b.c, cuts.0.at_time)");
  return out;
}

// The value as JSON when it is valid JSON, otherwise the text as a string.
json patch_value(const ScenePatch& p) {
  const std::string& text = p.value;
  if (json_too_deep(text))
    throw Error(p.given + ": the value is nested deeper than " + std::to_string(kMaxJsonDepth) + " levels of [ and {");
  json v = json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (v.is_discarded()) return json(text);
  return v;
}

bool is_index(const std::string& c) {
  if (c.empty() || c.size() > 9) return false;
  for (char ch : c)
    if (!std::isdigit(static_cast<unsigned char>(ch))) return false;
  return true;
}

std::string type_of(const json& v) { return v.is_number() ? "number" : v.type_name(); }

}  // namespace

ScenePatch parse_scene_patch(const std::string& text) {
  // Messages quote the patch as given: a long value is shortened there.
  const std::string shown =
      text.size() > 100 ? text.substr(0, 80) + "... (" + std::to_string(text.size()) + " characters)" : text;
  const size_t eq = text.find('=');
  if (eq == std::string::npos)
    throw Error("--set " + shown + ": expected KEY=VALUE, e.g. --set solver.policy=lagged or --set integrator.dt=0.01");
  if (eq == 0) throw Error("--set " + shown + ": the key before '=' is empty (expected KEY=VALUE)");
  return {text.substr(0, eq), text.substr(eq + 1), "--set " + shown};
}

std::vector<AppliedPatch> apply_scene_patches(json& root, const std::vector<ScenePatch>& patches) {
  std::vector<AppliedPatch> applied;
  for (const ScenePatch& p : patches) {
    const std::vector<std::string> parts = split_key(p);
    json value = patch_value(p);
    json* cur = &root;
    std::string path;
    for (size_t i = 0; i < parts.size(); ++i) {
      const std::string& c = parts[i];
      const bool last = i + 1 == parts.size();
      if (cur->is_object()) {
        path = path.empty() ? c : path + "." + c;
        if (last) {
          if (value.is_null()) cur->erase(c);
          else (*cur)[c] = std::move(value);
        } else {
          if (!cur->contains(c)) (*cur)[c] = json::object();
          cur = &(*cur)[c];
        }
      } else if (cur->is_array()) {
        if (!is_index(c))
          throw Error(p.given + ": " + path + " is an array; \"" + c + "\" is not an index (0, 1, ...)");
        const size_t k = std::stoul(c);
        if (k > cur->size() || (k == cur->size() && !last))
          throw Error(p.given + ": " + path + " has " + std::to_string(cur->size()) + " entries; index " + c +
                      " is out of range");
        path += "[" + c + "]";
        if (last) {
          if (value.is_null()) throw Error(p.given + ": null removes object keys, not array entries");
          if (k == cur->size()) cur->push_back(std::move(value));
          else (*cur)[k] = std::move(value);
        } else {
          cur = &(*cur)[k];
        }
      } else {
        throw Error(p.given + ": " + path + " is a " + type_of(*cur) + ", not an object: it has no key \"" + c + "\"");
      }
    }
    applied.push_back({path, &p});
  }
  return applied;
}

namespace {
// A patch that set `patched` set `where`: the key itself, an object around
// it, or a key below it.
bool patch_reaches(const std::string& patched, const std::string& where) {
  return within(where, patched) || (!where.empty() && within(patched, where));
}
}  // namespace

const ScenePatch* patch_for(const std::vector<AppliedPatch>& applied, const std::string& where) {
  for (auto it = applied.rbegin(); it != applied.rend(); ++it)
    if (patch_reaches(it->path, where)) return it->patch;
  return nullptr;
}

std::string key_origin(const Scene& scene, const std::string& where) {
  for (auto it = scene.patched.rbegin(); it != scene.patched.rend(); ++it)
    if (patch_reaches(it->first, where)) return it->second;
  return scene.path;
}

const std::vector<std::string>& solver_preset_names() {
  static const std::vector<std::string> names{"realtime", "reference"};
  return names;
}

const json* solver_preset(const std::string& name) {
  // realtime: tools/scripts/bench-realtime.sh's measured configuration
  // (docs/benchmarks.md). refresh_every 2 suits about 10k DOF: a background
  // factorization is taken 2 frames after it starts; the script sets 1 at
  // 3k, 3 at 20k and 4 at 30k DOF (a scene sets solver.refresh_every).
  static const json realtime = {
      {"solver",
       {{"policy", "lagged"},
        {"background", true},
        {"refresh_every", 2},
        {"warp", true},
        // 1e-2 with the increment predictor: CG's test is relative to the
        // first residual, which dt v inflated; the same error against exact
        // as 1e-3 from dt v (docs/numerics.md, "The Newton predictor").
        {"tolerance", 1e-2},
        {"max_iterations", 100},
        {"matrix_precision", "single"},
        // 2: the assembly and CG's products on a helper CPU too; the worker
        // stands down while the background factorization is late or a
        // cut-ahead runs (SolverWork::apply_stand_down). hang-20k median
        // frame 9.1-9.4 -> 7.0-7.3 ms (docs/benchmarks.md, "Two assembly workers").
        {"threads", 2},
        {"rescue_after", 20},
        {"late_factor", "skip"},
        // half: the float factor rounded to binary16 once more; substitutions
        // -25% at 20k DOF, the same CG iterations and error against exact
        // (docs/numerics.md, "the factor copy").
        {"factor_copy", "half"},
        {"factor_precision", "single"},
        {"substitution_threads", 2},
        {"affinity", "split"},
        {"background_priority", "idle"}}},
      {"integrator", {{"tangent", "consistent"}, {"tangent_reuse", 0.01}, {"predictor", "increment"}}}};
  // reference: the exact solve and every element assembled each Newton
  // iteration; the tangent stays the scene's.
  static const json reference = {{"solver", {{"policy", "exact"}}}, {"integrator", {{"tangent_reuse", 0}}}};
  if (name == "realtime") return &realtime;
  if (name == "reference") return &reference;
  return nullptr;
}

std::vector<std::string> expand_solver_preset(json& root, const std::string& name) {
  const json* preset = solver_preset(name);
  std::vector<std::string> added;
  if (!preset) return added;
  json& solver = root["solver"];
  // The policy the parser will see: the scene's (or a patch's), else the preset's.
  SolverPolicy policy = SolverPolicy::Exact;
  const json& pp = solver.contains("policy") ? solver["policy"] : (*preset)["solver"].value("policy", json("exact"));
  for (SolverPolicy q : {SolverPolicy::Exact, SolverPolicy::Lagged, SolverPolicy::Warped, SolverPolicy::WarpedCG})
    if (pp.is_string() && pp.get<std::string>() == policy_name(q)) policy = q;
  auto factor_copy = [&]() -> std::string {
    if (solver.contains("factor_copy") && solver["factor_copy"].is_string()) return solver["factor_copy"].get<std::string>();
    if (solver.contains("single_precision") && solver["single_precision"].is_boolean())
      return solver["single_precision"].get<bool>() ? "float" : "none";
    return "float";
  };
  // nlohmann's objects iterate in key order: factor_copy before factor_precision.
  for (auto it = (*preset)["solver"].begin(); it != (*preset)["solver"].end(); ++it) {
    const std::string& k = it.key();
    if (solver.contains(k) || !solver_key_used_by(k, policy)) continue;
    if (k == "factor_copy" && solver.contains("single_precision")) continue;
    if (k == "factor_precision" && *it == "single" &&
        (factor_copy() == "none" || solver.value("factorization", json("auto")) == "simplicial"))
      continue;
    solver[k] = *it;
    added.push_back("solver." + k);
  }
  json& integrator = root["integrator"];
  if (integrator.is_null()) integrator = json::object();
  if (!integrator.is_object()) return added;  // the parser says what is wrong
  for (auto it = (*preset)["integrator"].begin(); it != (*preset)["integrator"].end(); ++it) {
    if (integrator.contains(it.key())) continue;
    integrator[it.key()] = *it;
    added.push_back("integrator." + it.key());
  }
  return added;
}

}  // namespace incise
