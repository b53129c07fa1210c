#include "engine/scene/scene.h"

#include <algorithm>
#include <cmath>
#include <climits>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <set>
#include <sstream>
#include <utility>

#include <nlohmann/json.hpp>

#include "engine/scene/scene_patch.h"
#include "engine/util/error.h"
#include "engine/util/file_io.h"
#include "engine/util/json_depth.h"
#include "engine/util/number_text.h"

namespace incise {
namespace {

using json = nlohmann::json;
namespace fs = std::filesystem;

// A value as it appears in the file, shortened for messages.
std::string show(const json& v) {
  std::string s = v.dump();
  if (s.size() > 60) s = s.substr(0, 57) + "...";
  return s;
}

// "number", "integer", "string", ... with the value itself where short.
std::string describe(const json& v) {
  if (v.is_null()) return "null";
  std::string type = v.is_number() ? "number" : v.type_name();
  return type + " " + show(v);
}

std::string join(const std::vector<std::string>& items, const char* sep = ", ") {
  std::string out;
  for (size_t i = 0; i < items.size(); ++i) {
    if (i) out += sep;
    out += items[i];
  }
  return out;
}

size_t edit_distance(const std::string& a, const std::string& b) {
  std::vector<size_t> prev(b.size() + 1), cur(b.size() + 1);
  for (size_t j = 0; j <= b.size(); ++j) prev[j] = j;
  for (size_t i = 1; i <= a.size(); ++i) {
    cur[0] = i;
    for (size_t j = 1; j <= b.size(); ++j) {
      size_t sub = prev[j - 1] + (a[i - 1] == b[j - 1] ? 0 : 1);
      cur[j] = std::min({prev[j] + 1, cur[j - 1] + 1, sub});
    }
    std::swap(prev, cur);
  }
  return prev[b.size()];
}

// Builds JSON paths and throws errors that start with the scene path, or
// with the command-line patch that set the key at fault.
class Parser {
 public:
  explicit Parser(std::string scene_path, const std::vector<AppliedPatch>* patches = nullptr)
      : path_(std::move(scene_path)), patches_(patches) {}

  // The keys solver.preset added, and its name (for messages).
  void set_preset(std::string name, std::vector<std::string> keys) {
    preset_ = std::move(name);
    preset_keys_ = std::move(keys);
  }

  [[noreturn]] void fail(const std::string& where, const std::string& what) const {
    // `what` starts with " must ..." or ": ...".
    if (std::find(preset_keys_.begin(), preset_keys_.end(), where) != preset_keys_.end())
      throw Error(path_ + ": " + where + " (from solver.preset \"" + preset_ + "\")" + what);
    if (patches_)
      if (const ScenePatch* pt = patch_for(*patches_, where)) throw Error(pt->given + ": " + where + what);
    throw Error(path_ + ": " + where + what);
  }

  static std::string key(const std::string& parent, const std::string& k) {
    return parent.empty() ? k : parent + "." + k;
  }
  static std::string index(const std::string& parent, size_t i) {
    return parent + "[" + std::to_string(i) + "]";
  }

  // --- structure -----------------------------------------------------------

  const json& object(const json& v, const std::string& where) const {
    if (!v.is_object()) fail(where, " must be an object, got " + describe(v));
    return v;
  }

  void allowed_keys(const json& obj, const std::string& where,
                    const std::vector<std::string>& allowed) const {
    for (auto it = obj.begin(); it != obj.end(); ++it) {
      if (std::find(allowed.begin(), allowed.end(), it.key()) != allowed.end()) continue;
      std::string msg = ": unknown key; allowed: " + join(allowed);
      // Suggest the closest allowed key for a likely typo.
      std::string best;
      size_t best_d = 3;
      for (const auto& a : allowed) {
        size_t d = edit_distance(it.key(), a);
        size_t len = std::max(it.key().size(), a.size());
        if (d < best_d && 3 * d <= len) best_d = d, best = a;
      }
      if (!best.empty()) msg += "; did you mean \"" + best + "\"?";
      fail(key(where, it.key()), msg);
    }
  }

  const json& required(const json& obj, const std::string& where, const std::string& k,
                       const std::string& expected) const {
    auto it = obj.find(k);
    if (it == obj.end()) fail(key(where, k), ": required key is missing (expected " + expected + ")");
    return *it;
  }

  const json& array(const json& v, const std::string& where) const {
    if (!v.is_array()) fail(where, " must be an array, got " + describe(v));
    return v;
  }

  // --- scalars -------------------------------------------------------------

  double number(const json& v, const std::string& where) const {
    if (!v.is_number()) fail(where, " must be a number, got " + describe(v));
    double x = v.get<double>();
    if (!std::isfinite(x)) fail(where, " must be a finite number, got " + show(v));
    return x;
  }

  int integer(const json& v, const std::string& where) const {
    if (!v.is_number()) fail(where, " must be an integer, got " + describe(v));
    if (v.is_number_unsigned()) {
      if (v.get<unsigned long long>() > static_cast<unsigned long long>(INT_MAX))
        fail(where, " is too large, got " + show(v));
      return static_cast<int>(v.get<unsigned long long>());
    }
    if (v.is_number_integer()) {
      long long x = v.get<long long>();
      if (x > INT_MAX || x < INT_MIN) fail(where, " is out of range, got " + show(v));
      return static_cast<int>(x);
    }
    double x = v.get<double>();  // accept 3.0, not 3.5
    if (!std::isfinite(x) || x != std::floor(x)) fail(where, " must be an integer, got " + show(v));
    if (x > INT_MAX || x < INT_MIN) fail(where, " is out of range, got " + show(v));
    return static_cast<int>(x);
  }

  bool boolean(const json& v, const std::string& where) const {
    if (!v.is_boolean()) fail(where, " must be a boolean (true or false), got " + describe(v));
    return v.get<bool>();
  }

  std::string string(const json& v, const std::string& where) const {
    if (!v.is_string()) fail(where, " must be a string, got " + describe(v));
    // No field takes a NUL ("\u0000"): in a path the file system stops
    // there, and "organ.msh\u0000.vtu" read organ.msh with an error that
    // named neither the field nor the reason.
    if (v.get_ref<const std::string&>().find('\0') != std::string::npos)
      fail(where, " must not contain a NUL character (\\u0000), got " + show(v));
    return v.get<std::string>();
  }

  std::string nonempty_string(const json& v, const std::string& where) const {
    std::string s = string(v, where);
    if (s.empty()) fail(where, " must be a non-empty string, got \"\"");
    return s;
  }

  // One of a fixed set of strings; returns its position in `allowed`.
  size_t choice(const json& v, const std::string& where,
                const std::vector<std::string>& allowed) const {
    std::vector<std::string> quoted;
    for (const auto& a : allowed) quoted.push_back("\"" + a + "\"");
    if (!v.is_string())
      fail(where, " must be one of " + join(quoted) + ", got " + describe(v));
    auto it = std::find(allowed.begin(), allowed.end(), v.get<std::string>());
    if (it == allowed.end()) fail(where, " must be one of " + join(quoted) + ", got " + show(v));
    return static_cast<size_t>(it - allowed.begin());
  }

  double positive(const json& v, const std::string& where) const {
    double x = number(v, where);
    if (!(x > 0.0)) fail(where, " must be > 0, got " + show(v));
    return x;
  }

  double nonnegative(const json& v, const std::string& where) const {
    double x = number(v, where);
    if (!(x >= 0.0)) fail(where, " must be >= 0, got " + show(v));
    return x;
  }

  int nonnegative_int(const json& v, const std::string& where) const {
    int n = integer(v, where);
    if (n < 0) fail(where, " must be an integer >= 0, got " + show(v));
    return n;
  }

  int at_least_one(const json& v, const std::string& where) const {
    int n = integer(v, where);
    if (n < 1) fail(where, " must be an integer >= 1, got " + show(v));
    return n;
  }

  // Two points [[x, y, z], [x, y, z]]: a blade edge (swept cuts, scalpels).
  std::array<Vec3, 2> segment(const json& v, const std::string& where) const {
    if (!v.is_array() || v.size() != 2) fail(where, " must be two points [[x, y, z], [x, y, z]], got " + describe(v));
    return {vec3(v[0], index(where, 0)), vec3(v[1], index(where, 1))};
  }
  // Trajectory files are not read by a replay (its recorded poses stand in).
  void set_trajectories_needed(bool needed) { trajectories_needed_ = needed; }
  // A trajectory file: existing_file, or only resolved where not needed.
  std::string trajectory_file(const json& v, const std::string& where) const {
    return trajectories_needed_ ? existing_file(v, where) : resolve(nonempty_string(v, where));
  }
  // A file named relative to the scene's folder that must exist (cut
  // surfaces, trajectories): its resolved path.
  std::string existing_file(const json& v, const std::string& where) const {
    const std::string f = resolve(nonempty_string(v, where));
    std::error_code ec;
    const auto st = fs::status(f, ec);
    if (ec || !fs::exists(st)) fail(where, ": file not found: " + f);
    if (!fs::is_regular_file(st)) fail(where, ": is not a regular file: " + f);
    return f;
  }
  Vec3 vec3(const json& v, const std::string& where) const {
    if (!v.is_array() || v.size() != 3) {
      std::string got = v.is_array() ? "array of " + std::to_string(v.size()) + " values"
                                     : describe(v);
      fail(where, " must be an array of 3 numbers [x, y, z], got " + got);
    }
    Vec3 out{};
    for (size_t i = 0; i < 3; ++i) out[i] = number(v[i], index(where, i));
    return out;
  }

  // --- paths ---------------------------------------------------------------

  // Relative paths are taken from the scene file's folder.
  std::string resolve(const std::string& p) const {
    fs::path file(p);
    if (file.is_absolute()) return file.lexically_normal().string();
    fs::path base = fs::path(path_).parent_path();
    return (base / file).lexically_normal().string();
  }

  const std::string& scene_path() const { return path_; }

 private:
  std::string path_;
  const std::vector<AppliedPatch>* patches_ = nullptr;
  std::string preset_;
  std::vector<std::string> preset_keys_;
  bool trajectories_needed_ = true;
};

// --- sections ----------------------------------------------------------------

void parse_mesh(const Parser& p, const json& v, Scene& s) {
  const std::string at = "mesh";
  p.object(v, at);
  p.allowed_keys(v, at, {"file", "order"});
  std::string file =
      p.nonempty_string(p.required(v, at, "file", "a mesh file path string"), at + ".file");
  s.mesh_file = p.resolve(file);
  std::error_code ec;
  auto st = fs::status(s.mesh_file, ec);
  if (ec || !fs::exists(st)) p.fail(at + ".file", ": file not found: " + s.mesh_file);
  if (fs::is_directory(st)) p.fail(at + ".file", ": is a directory, not a mesh file: " + s.mesh_file);
  if (auto it = v.find("order"); it != v.end()) {
    int order = p.integer(*it, at + ".order");
    if (order != 1 && order != 2) p.fail(at + ".order", " must be 1 or 2, got " + show(*it));
    s.order = order;
  }
}

void parse_material(const Parser& p, const json& v, Material& m) {
  const std::string at = "material";
  p.object(v, at);
  p.allowed_keys(v, at, {"model", "rotation", "young", "poisson", "density", "rayleigh"});
  if (auto it = v.find("model"); it != v.end())
    m.model = p.choice(*it, at + ".model", {"linear", "corotated"}) == 0
                  ? MaterialModel::Linear
                  : MaterialModel::Corotated;
  if (auto it = v.find("rotation"); it != v.end())
    m.rotation = p.choice(*it, at + ".rotation", {"per_point", "single"}) == 0
                     ? RotationMode::PerPoint
                     : RotationMode::Single;
  m.young = p.positive(p.required(v, at, "young", "a number > 0"), at + ".young");
  {
    const json& nu = p.required(v, at, "poisson", "a number in (-1, 0.5)");
    m.poisson = p.number(nu, at + ".poisson");
    if (!(m.poisson > -1.0 && m.poisson < 0.5))
      p.fail(at + ".poisson", " must be in (-1, 0.5), got " + show(nu));
  }
  m.density = p.positive(p.required(v, at, "density", "a number > 0"), at + ".density");
  if (auto it = v.find("rayleigh"); it != v.end()) {
    const std::string r = at + ".rayleigh";
    p.object(*it, r);
    p.allowed_keys(*it, r, {"mass", "stiffness"});
    if (auto m_it = it->find("mass"); m_it != it->end())
      m.rayleigh_mass = p.nonnegative(*m_it, r + ".mass");
    if (auto k_it = it->find("stiffness"); k_it != it->end())
      m.rayleigh_stiffness = p.nonnegative(*k_it, r + ".stiffness");
  }
}

// Reads the one region key (box, plane or nodes) of a fixed/prescribed entry.
Region parse_region(const Parser& p, const json& v, const std::string& at) {
  Region r;
  r.json_path = at;
  std::vector<std::string> present;
  for (const char* k : {"box", "plane", "nodes"})
    if (v.contains(k)) present.push_back(k);
  if (present.size() != 1) {
    p.fail(at, present.empty()
                   ? ": needs exactly one of box, plane, nodes; got none"
                   : ": needs exactly one of box, plane, nodes; got " + join(present, " and "));
  }
  const std::string k = present[0];
  const std::string rp = Parser::key(at, k);
  const json& rv = v.at(k);
  if (k == "box") {
    r.kind = Region::Kind::Box;
    if (!rv.is_array() || rv.size() != 2) {
      std::string got = rv.is_array() ? "array of " + std::to_string(rv.size()) + " values"
                                      : describe(rv);
      p.fail(rp, " must be [[xmin, ymin, zmin], [xmax, ymax, zmax]], got " + got);
    }
    r.lo = p.vec3(rv[0], Parser::index(rp, 0));
    r.hi = p.vec3(rv[1], Parser::index(rp, 1));
    static const char* axis = "xyz";
    for (size_t i = 0; i < 3; ++i) {
      if (r.lo[i] > r.hi[i]) {
        p.fail(rp, ": min must be <= max in each component; got " + std::string(1, axis[i]) +
                       " min " + show(rv[0][i]) + " > max " + show(rv[1][i]));
      }
    }
  } else if (k == "plane") {
    r.kind = Region::Kind::Plane;
    p.object(rv, rp);
    p.allowed_keys(rv, rp, {"point", "normal"});
    r.point = p.vec3(p.required(rv, rp, "point", "[x, y, z]"), rp + ".point");
    const json& nj = p.required(rv, rp, "normal", "[nx, ny, nz], nonzero");
    Vec3 n = p.vec3(nj, rp + ".normal");
    double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    if (!(len > 0.0) || !std::isfinite(len))
      p.fail(rp + ".normal", " must be a nonzero vector, got " + show(nj));
    for (double& c : n) c /= len;  // unit length: the selection tolerance is a distance
    r.normal = n;
  } else {
    r.kind = Region::Kind::Nodes;
    p.array(rv, rp);
    if (rv.empty()) p.fail(rp, " must list at least one node id, got []");
    for (size_t i = 0; i < rv.size(); ++i) {
      const std::string ip = Parser::index(rp, i);
      int id = p.integer(rv[i], ip);
      if (id < 0) p.fail(ip, " must be a non-negative node id (0-based), got " + show(rv[i]));
      r.nodes.push_back(id);
    }
  }
  return r;
}

void parse_fixed(const Parser& p, const json& v, Scene& s) {
  p.array(v, "fixed");
  for (size_t i = 0; i < v.size(); ++i) {
    const std::string at = Parser::index("fixed", i);
    p.object(v[i], at);
    p.allowed_keys(v[i], at, {"box", "plane", "nodes"});
    s.fixed.push_back(parse_region(p, v[i], at));
  }
}

void parse_prescribed(const Parser& p, const json& v, Scene& s) {
  p.array(v, "prescribed");
  for (size_t i = 0; i < v.size(); ++i) {
    const std::string at = Parser::index("prescribed", i);
    const json& e = v[i];
    p.object(e, at);
    p.allowed_keys(e, at, {"box", "plane", "nodes", "displacement", "ramp"});
    Prescribed pr;
    pr.region = parse_region(p, e, at);
    const std::string dp = at + ".displacement";
    const json& d = p.required(e, at, "displacement", "an object with x, y and/or z");
    p.object(d, dp);
    p.allowed_keys(d, dp, {"x", "y", "z"});
    static const char* names[3] = {"x", "y", "z"};
    for (size_t c = 0; c < 3; ++c) {
      if (auto it = d.find(names[c]); it != d.end()) {
        pr.active[c] = true;
        pr.displacement[c] = p.number(*it, dp + "." + names[c]);
      }
    }
    if (!pr.active[0] && !pr.active[1] && !pr.active[2])
      p.fail(dp, ": needs at least one of x, y, z (an absent component stays free), got {}");
    if (auto it = e.find("ramp"); it != e.end()) pr.ramp = p.nonnegative(*it, at + ".ramp");
    s.prescribed.push_back(std::move(pr));
  }
}

void parse_integrator(const Parser& p, const json& v, Scene& s) {
  const std::string at = "integrator";
  p.object(v, at);
  p.allowed_keys(v, at, {"dt", "newton_iterations", "max_newton_iterations", "rotation_tolerance", "newmark_gamma",
                          "newmark_beta", "tangent", "tangent_reuse", "predictor", "line_search",
                          "residual_tolerance", "rotation_fraction", "rotation_rms", "recovery"});
  if (auto it = v.find("dt"); it != v.end()) {
    double dt = p.number(*it, at + ".dt");
    if (!(dt > 0.0 && dt <= 1.0))
      p.fail(at + ".dt", " must be in (0, 1] seconds, got " + show(*it));
    s.dt = dt;
  }
  if (auto it = v.find("newton_iterations"); it != v.end())
    s.newton_iterations = p.at_least_one(*it, at + ".newton_iterations");
  if (auto it = v.find("max_newton_iterations"); it != v.end())
    s.max_newton_iterations = p.at_least_one(*it, at + ".max_newton_iterations");
  if (auto it = v.find("rotation_tolerance"); it != v.end())
    s.rotation_tolerance = p.nonnegative(*it, at + ".rotation_tolerance");
  if (auto it = v.find("rotation_fraction"); it != v.end()) {
    s.rotation_fraction = p.nonnegative(*it, at + ".rotation_fraction");
    if (!(s.rotation_fraction < 1.0))
      p.fail(at + ".rotation_fraction", " must be in [0, 1) (a fraction of the body's volume; 0 = any point), got " + show(*it));
  }
  if (auto it = v.find("rotation_rms"); it != v.end()) s.rotation_rms = p.nonnegative(*it, at + ".rotation_rms");
  if (auto it = v.find("tangent"); it != v.end())
    s.consistent_tangent = p.choice(*it, at + ".tangent", {"frozen_rotation", "consistent"}) == 1;
  if (auto it = v.find("line_search"); it != v.end()) s.line_search = p.boolean(*it, at + ".line_search");
  if (auto it = v.find("residual_tolerance"); it != v.end())
    s.residual_tolerance = p.nonnegative(*it, at + ".residual_tolerance");
  if (auto it = v.find("predictor"); it != v.end())
    s.increment_predictor = p.choice(*it, at + ".predictor", {"velocity", "increment"}) == 1;
  if (auto it = v.find("tangent_reuse"); it != v.end()) {
    s.tangent_reuse = p.nonnegative(*it, at + ".tangent_reuse");
    if (!(s.tangent_reuse < 0.5))
      p.fail(at + ".tangent_reuse", " must be in [0, 0.5) (a change of the deformation gradient; 0 = off), got " + show(*it));
  }
  if (auto it = v.find("newmark_gamma"); it != v.end()) {
    const double g = p.number(*it, at + ".newmark_gamma");
    if (!(g >= 0.5 && g <= 1.0)) p.fail(at + ".newmark_gamma", " must be in [0.5, 1] (0.5 = no numerical damping), got " + show(*it));
    s.newmark_gamma = g;
  }
  // beta defaults to (gamma + 1/2)^2 / 4: unconditionally stable, and the
  // high-frequency limit of the amplification is then as small as gamma allows.
  s.newmark_beta = 0.25 * (s.newmark_gamma + 0.5) * (s.newmark_gamma + 0.5);
  if (auto it = v.find("newmark_beta"); it != v.end()) {
    const double b = p.number(*it, at + ".newmark_beta");
    if (!(b >= 0.5 * s.newmark_gamma && b <= 1.0))
      p.fail(at + ".newmark_beta", " must be in [newmark_gamma / 2, 1] (unconditionally stable), got " + show(*it));
    s.newmark_beta = b;
  }
  if (auto it = v.find("recovery"); it != v.end())
    s.recovery_steps = p.choice(*it, at + ".recovery", {"none", "backward_euler"}) == 1;
}

// solver.* keys that only some policies use (the parser refuses them under another).
const std::vector<std::string> kIterativeKeys{"tolerance", "max_iterations", "initial_guess", "frame_iterations",
                                              "matrix_precision"};
const std::vector<std::string> kLaggedKeys{"refresh_every", "background",    "warp",        "single_precision",
                                           "factor_copy",   "factor_precision", "rescue_after", "late_factor",
                                           "patch",         "cut_ordering",  "background_priority", "coarse",
                                           "condense_below", "contact_patch"};

bool listed(const std::vector<std::string>& keys, const std::string& k) {
  return std::find(keys.begin(), keys.end(), k) != keys.end();
}

void parse_solver(const Parser& p, const json& v, Scene& s) {
  const std::string at = "solver";
  p.object(v, at);
  p.allowed_keys(v, at, {"preset", "policy", "refresh_every", "background", "warp", "single_precision", "factor_copy", "rescue_after", "late_factor",
                         "patch", "cut_ordering", "background_priority", "tolerance", "max_iterations", "threads", "substitution_threads",
                         "factorization", "ordering", "factor_precision", "initial_guess", "affinity", "coarse",
                         "frame_iterations", "condense_below", "contact_patch", "matrix_precision"});
  SolverSettings& o = s.solver;
  RuntimeSettings& rt = s.runtime;
  if (auto it = v.find("preset"); it != v.end()) s.preset = solver_preset_names()[p.choice(*it, at + ".preset", solver_preset_names())];
  if (auto it = v.find("policy"); it != v.end())
    o.policy = static_cast<SolverPolicy>(p.choice(*it, at + ".policy", {"exact", "lagged", "warped", "warped_cg"}));
  if (auto it = v.find("refresh_every"); it != v.end())
    o.refresh_every = p.at_least_one(*it, at + ".refresh_every");
  if (auto it = v.find("background"); it != v.end()) o.background = p.boolean(*it, at + ".background");
  if (auto it = v.find("warp"); it != v.end()) o.warp = p.boolean(*it, at + ".warp");
  if (auto it = v.find("single_precision"); it != v.end())
    o.factor_copy = p.boolean(*it, at + ".single_precision") ? FactorCopy::Float : FactorCopy::None;
  if (auto it = v.find("factor_copy"); it != v.end()) {
    if (v.contains("single_precision"))
      p.fail(at + ".factor_copy", ": give either factor_copy or single_precision (the older switch between \"float\" and \"none\"), not both");
    o.factor_copy = static_cast<FactorCopy>(p.choice(*it, at + ".factor_copy", {"none", "float", "half"}));
  }
  if (auto it = v.find("factor_precision"); it != v.end()) {
    o.single_factorization = p.choice(*it, at + ".factor_precision", {"double", "single"}) == 1;
    if (o.single_factorization && o.factor_copy == FactorCopy::None)
      p.fail(at + ".factor_precision", ": \"single\" factors straight into the float copy, so solver.factor_copy must be "
                                       "\"float\" (the default) or \"half\", not \"none\"");
  }
  if (auto it = v.find("rescue_after"); it != v.end()) o.rescue_after = p.nonnegative_int(*it, at + ".rescue_after");
  if (auto it = v.find("late_factor"); it != v.end())
    o.skip_late_factor = p.choice(*it, at + ".late_factor", {"wait", "skip"}) == 1;
  if (auto it = v.find("patch"); it != v.end())
    o.multiplicative_patch = p.choice(*it, at + ".patch", {"additive", "multiplicative"}) == 1;
  if (auto it = v.find("cut_ordering"); it != v.end())
    o.carry_ordering = p.choice(*it, at + ".cut_ordering", {"search", "carried"}) == 1;
  if (auto it = v.find("background_priority"); it != v.end())
    rt.idle_background = p.choice(*it, at + ".background_priority", {"normal", "idle"}) == 1;
  if (auto it = v.find("affinity"); it != v.end())
    rt.split_affinity = p.choice(*it, at + ".affinity", {"none", "split"}) == 1;
  if (auto it = v.find("tolerance"); it != v.end()) {
    o.tolerance = p.positive(*it, at + ".tolerance");
    if (!(o.tolerance < 1.0)) p.fail(at + ".tolerance", " must be in (0, 1), got " + show(*it));
  }
  if (auto it = v.find("max_iterations"); it != v.end())
    o.max_iterations = p.at_least_one(*it, at + ".max_iterations");
  if (auto it = v.find("frame_iterations"); it != v.end())
    o.frame_iterations = p.nonnegative_int(*it, at + ".frame_iterations");
  if (auto it = v.find("matrix_precision"); it != v.end())
    o.single_matrix = p.choice(*it, at + ".matrix_precision", {"double", "single"}) == 1;
  if (auto it = v.find("condense_below"); it != v.end()) {
    o.condense_below = p.nonnegative(*it, at + ".condense_below");
    if (!(o.condense_below < 1.0)) p.fail(at + ".condense_below", " must be in [0, 1), got " + show(*it));
  }
  if (auto it = v.find("contact_patch"); it != v.end()) {
    o.contact_patch = p.nonnegative_int(*it, at + ".contact_patch");
    if (o.contact_patch > 3) p.fail(at + ".contact_patch", " must be an integer in [0, 3], got " + show(*it));
  }
  if (auto it = v.find("coarse"); it != v.end()) o.coarse = p.choice(*it, at + ".coarse", {"none", "corners"}) == 1;
  if (auto it = v.find("initial_guess"); it != v.end())
    o.previous_guess = p.choice(*it, at + ".initial_guess", {"zero", "previous"}) == 1;
  if (auto it = v.find("threads"); it != v.end()) {
    rt.threads = p.at_least_one(*it, at + ".threads");
    if (rt.threads > 64) p.fail(at + ".threads", " must be an integer in [1, 64], got " + show(*it));
  }
  if (auto it = v.find("substitution_threads"); it != v.end()) {
    rt.substitution_threads = p.at_least_one(*it, at + ".substitution_threads");
    if (rt.substitution_threads > 2) p.fail(at + ".substitution_threads", " must be 1 or 2, got " + show(*it));
  }
  if (auto it = v.find("factorization"); it != v.end())
    o.factor = static_cast<FactorMethod>(p.choice(*it, at + ".factorization", {"auto", "supernodal", "simplicial"}));
  if (auto it = v.find("ordering"); it != v.end())
    o.ordering = static_cast<OrderingMethod>(p.choice(*it, at + ".ordering", {"auto", "amd", "metis"}));
  if (o.single_factorization && o.factor == FactorMethod::Simplicial)
    p.fail(at + ".factor_precision", ": \"single\" factors supernodes; solver.factorization \"simplicial\" has none "
                                     "(use \"supernodal\" or \"auto\")");
  const bool iterative = o.policy == SolverPolicy::Lagged || o.policy == SolverPolicy::WarpedCG;
  for (const std::string& k : kIterativeKeys)
    if (v.contains(k) && !iterative)
      p.fail(Parser::key(at, k), ": only used by the iterative policies \"lagged\" and \"warped_cg\"; solver.policy is \"" +
                                     std::string(policy_name(o.policy)) + "\"");
  for (const std::string& k : kLaggedKeys)
    if (v.contains(k) && o.policy != SolverPolicy::Lagged)
      p.fail(Parser::key(at, k), ": only used by solver.policy \"lagged\"; solver.policy is \"" +
                                     std::string(policy_name(o.policy)) + "\"");
}

void parse_static(const Parser& p, const json& v, Scene& s) {
  const std::string at = "static";
  p.object(v, at);
  p.allowed_keys(v, at, {"tolerance", "max_iterations"});
  if (auto it = v.find("tolerance"); it != v.end())
    s.static_tolerance = p.positive(*it, at + ".tolerance");
  if (auto it = v.find("max_iterations"); it != v.end())
    s.static_max_iterations = p.at_least_one(*it, at + ".max_iterations");
}

void parse_run(const Parser& p, const json& v, Scene& s) {
  const std::string at = "run";
  p.object(v, at);
  p.allowed_keys(v, at, {"frames"});
  if (auto it = v.find("frames"); it != v.end()) {
    s.frames = p.at_least_one(*it, at + ".frames");
    if (s.frames > kMaxFrames)
      p.fail(at + ".frames", " must be at most " + std::to_string(kMaxFrames) + " (9.3 h at 30 Hz), got " + show(*it));
  }
}

void parse_output(const Parser& p, const json& v, Scene& s) {
  const std::string at = "output";
  p.object(v, at);
  p.allowed_keys(v, at, {"dir", "every", "vtu", "vtu_format"});
  if (auto it = v.find("dir"); it != v.end())
    s.output.dir = p.resolve(p.nonempty_string(*it, at + ".dir"));
  if (auto it = v.find("every"); it != v.end())
    s.output.every = p.at_least_one(*it, at + ".every");
  if (auto it = v.find("vtu"); it != v.end()) s.output.write_vtu = p.boolean(*it, at + ".vtu");
  if (auto it = v.find("vtu_format"); it != v.end())
    s.output.vtu_ascii = p.choice(*it, at + ".vtu_format", {"binary", "ascii"}) == 1;
}

void parse_cuts(const Parser& p, const json& v, Scene& s) {
  p.array(v, "cuts");
  for (size_t i = 0; i < v.size(); ++i) {
    const std::string at = Parser::index("cuts", i);
    const json& e = p.object(v[i], at);
    CutSpec c;
    c.json_path = at;
    const size_t type = p.choice(p.required(e, at, "type", "\"plane\", \"polygon\", \"mesh\" or \"swept\""),
                                 at + ".type", {"plane", "polygon", "mesh", "swept"});
    if (auto it = e.find("at_time"); it != e.end()) c.at_time = p.nonnegative(*it, at + ".at_time");
    if (type == 0) {
      c.type = CutSpec::Type::Plane;
      p.allowed_keys(e, at, {"type", "at_time", "point", "normal"});
      c.point = p.vec3(p.required(e, at, "point", "[x, y, z]"), at + ".point");
      const json& nj = p.required(e, at, "normal", "[nx, ny, nz], nonzero");
      Vec3 n = p.vec3(nj, at + ".normal");
      const double len = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
      if (!(len > 0.0)) p.fail(at + ".normal", " must be a nonzero vector, got " + show(nj));
      for (double& x : n) x /= len;
      c.normal = n;
    } else if (type == 1) {
      c.type = CutSpec::Type::Polygon;
      p.allowed_keys(e, at, {"type", "at_time", "points"});
      const json& pts = p.array(p.required(e, at, "points", "an array of >= 3 points [x, y, z]"), at + ".points");
      if (pts.size() < 3) p.fail(at + ".points", " must list at least 3 points, got " + std::to_string(pts.size()));
      for (size_t k = 0; k < pts.size(); ++k) c.points.push_back(p.vec3(pts[k], Parser::index(at + ".points", k)));
    } else if (type == 2) {
      c.type = CutSpec::Type::Mesh;
      p.allowed_keys(e, at, {"type", "at_time", "file"});
      c.file = p.existing_file(p.required(e, at, "file", "a triangle surface .obj or .stl"), at + ".file");
    } else {
      c.type = CutSpec::Type::Swept;
      p.allowed_keys(e, at, {"type", "at_time", "edge_start", "edge_end", "duration"});
      auto edge = [&](const char* k) {
        return p.segment(p.required(e, at, k, "[[x, y, z], [x, y, z]], the blade edge's two ends"), Parser::key(at, k));
      };
      c.edge_start = edge("edge_start");
      c.edge_end = edge("edge_end");
      if (auto it = e.find("duration"); it != e.end()) c.duration = p.nonnegative(*it, at + ".duration");
    }
    s.cuts.push_back(std::move(c));
  }
}

// A unit quaternion [w, x, y, z] (within 1e-3, as trajectories: 4 decimals
// pass), returned normalised.
std::array<double, 4> unit_quaternion(const Parser& p, const json& v, const std::string& where) {
  if (!v.is_array() || v.size() != 4) {
    std::string got = v.is_array() ? "array of " + std::to_string(v.size()) + " values" : describe(v);
    p.fail(where, " must be a unit quaternion [w, x, y, z], got " + got);
  }
  std::array<double, 4> q{};
  for (size_t i = 0; i < 4; ++i) q[i] = p.number(v[i], Parser::index(where, i));
  const double n = std::sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
  if (!(std::abs(n - 1.0) <= 1e-3)) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.10g", n);
    p.fail(where, " must be a unit quaternion [w, x, y, z] (norm 1 within 1e-3), got norm " + std::string(buf));
  }
  for (double& c : q) c /= n;
  return q;
}

// [a, b, c], each > 0 (blade and jaw sizes).
Vec3 positive_vec3(const Parser& p, const json& v, const std::string& where) {
  Vec3 out = p.vec3(v, where);
  for (size_t i = 0; i < 3; ++i) out[i] = p.positive(v[i], Parser::index(where, i));
  return out;
}

void parse_instruments(const Parser& p, const json& v, Scene& s) {
  p.array(v, "instruments");
  for (size_t i = 0; i < v.size(); ++i) {
    const std::string at = Parser::index("instruments", i);
    const json& e = p.object(v[i], at);
    InstrumentSpec t;
    t.json_path = at;
    t.name = at;
    const size_t type = p.choice(p.required(e, at, "type", "\"probe\", \"scalpel\" or \"grasper\""), at + ".type",
                                 {"probe", "scalpel", "grasper"});
    const std::vector<std::string> common{"type", "name", "trajectory", "pose", "contact"};
    const std::vector<std::vector<std::string>> own{
        {"radius", "length"}, {"blade", "edge"}, {"jaw", "jaw_size", "opening", "grasp_at"}};
    std::vector<std::string> allowed = common;
    allowed.insert(allowed.end(), own[type].begin(), own[type].end());
    p.allowed_keys(e, at, allowed);
    t.kind = static_cast<InstrumentSpec::Kind>(type);
    if (auto it = e.find("name"); it != e.end()) t.name = p.nonempty_string(*it, at + ".name");
    if (auto it = e.find("trajectory"); it != e.end()) {
      t.trajectory = p.trajectory_file(*it, at + ".trajectory");
      if (e.contains("pose"))
        p.fail(at + ".pose", ": give either pose or trajectory (the trajectory sets the pose of every frame), not both");
    }
    if (auto it = e.find("pose"); it != e.end()) {
      const std::string pp = at + ".pose";
      p.object(*it, pp);
      p.allowed_keys(*it, pp, {"position", "orientation"});
      if (auto c = it->find("position"); c != it->end()) t.position = p.vec3(*c, pp + ".position");
      if (auto c = it->find("orientation"); c != it->end()) t.orientation = unit_quaternion(p, *c, pp + ".orientation");
    }
    if (t.kind == InstrumentSpec::Kind::Probe) {
      t.radius = p.positive(p.required(e, at, "radius", "a number > 0"), at + ".radius");
      if (auto it = e.find("length"); it != e.end()) t.length = p.nonnegative(*it, at + ".length");
    } else if (t.kind == InstrumentSpec::Kind::Scalpel) {
      t.blade = positive_vec3(p, p.required(e, at, "blade", "[L, T, H], each > 0"), at + ".blade");
      t.edge = {Vec3{-0.5 * t.blade[0], 0.0, 0.0}, Vec3{0.5 * t.blade[0], 0.0, 0.0}};
      if (auto it = e.find("edge"); it != e.end()) {
        t.edge = p.segment(*it, at + ".edge");
        if (t.edge[0] == t.edge[1]) p.fail(at + ".edge", " must have nonzero length (two distinct points), got " + show(*it));
      }
    } else {
      if (auto it = e.find("jaw"); it != e.end()) {
        t.jaw = p.number(*it, at + ".jaw");
        if (!(t.jaw >= 0.0 && t.jaw <= 1.0)) p.fail(at + ".jaw", " must be in [0, 1] (0 open .. 1 closed), got " + show(*it));
      }
      t.jaw_size = positive_vec3(p, p.required(e, at, "jaw_size", "[W, T, J], each > 0"), at + ".jaw_size");
      t.opening = p.positive(p.required(e, at, "opening", "a number > 0"), at + ".opening");
      if (auto it = e.find("grasp_at"); it != e.end()) {
        t.grasp_at = p.number(*it, at + ".grasp_at");
        if (!(t.grasp_at > 0.0 && t.grasp_at <= 1.0)) p.fail(at + ".grasp_at", " must be in (0, 1], got " + show(*it));
      }
    }
    t.contact = t.kind != InstrumentSpec::Kind::Scalpel;
    if (auto it = e.find("contact"); it != e.end()) {
      const bool c = p.boolean(*it, at + ".contact");
      if (c && t.kind == InstrumentSpec::Kind::Scalpel)
        p.fail(at + ".contact", ": a scalpel's blade cuts rather than pushes, so contact must be false (or absent), got true");
      t.contact = c;
    }
    s.instruments.push_back(std::move(t));
  }
}

void parse_contact(const Parser& p, const json& v, Scene& s) {
  const std::string at = "contact";
  p.object(v, at);
  p.allowed_keys(v, at,
                 {"rows", "max_rows", "friction", "pgs_iterations", "refine_rounds", "compliance_reuse", "sweep",
                  "speculative"});
  if (auto it = v.find("sweep"); it != v.end()) s.contact.sweep = p.boolean(*it, at + ".sweep");
  if (auto it = v.find("speculative"); it != v.end()) s.contact.speculative = p.boolean(*it, at + ".speculative");
  if (auto it = v.find("compliance_reuse"); it != v.end()) {
    s.contact.compliance_reuse = p.nonnegative(*it, at + ".compliance_reuse");
    if (s.contact.compliance_reuse > 1) p.fail(at + ".compliance_reuse", " must be in [0, 1], got " + show(*it));
  }
  if (auto it = v.find("rows"); it != v.end())
    s.contact.rows = static_cast<ContactSettings::Rows>(p.choice(*it, at + ".rows", {"face", "face_deepest", "triangle"}));
  if (auto it = v.find("max_rows"); it != v.end()) s.contact.max_rows = p.at_least_one(*it, at + ".max_rows");
  if (auto it = v.find("friction"); it != v.end()) s.contact.friction = p.nonnegative(*it, at + ".friction");
  if (auto it = v.find("pgs_iterations"); it != v.end())
    s.contact.pgs_iterations = p.at_least_one(*it, at + ".pgs_iterations");
  if (auto it = v.find("refine_rounds"); it != v.end()) {
    s.contact.refine_rounds = p.nonnegative_int(*it, at + ".refine_rounds");
    if (s.contact.refine_rounds > 20) p.fail(at + ".refine_rounds", " must be an integer in [0, 20], got " + show(*it));
  }
}

void parse_haptics(const Parser& p, const json& v, Scene& s) {
  const std::string at = "haptics";
  HapticsSpec& h = s.haptics;
  p.object(v, at);
  const size_t type = p.choice(p.required(v, at, "device", "\"scripted\", \"replay\" or \"openigtlink\""),
                               at + ".device", {"scripted", "replay", "openigtlink"});
  const std::vector<std::string> own[3] = {{"trajectory"}, {"stream"}, {"port"}};
  std::vector<std::string> allowed{"device", "instrument", "rate_hz", "max_force", "scale", "offset", "coupling", "guard", "realtime"};
  allowed.insert(allowed.end(), own[type].begin(), own[type].end());
  p.allowed_keys(v, at, allowed);
  h.device = static_cast<HapticsSpec::Device>(type + 1);
  if (s.instruments.empty())
    p.fail(at, ": a haptic device drives an instrument, and the scene declares none (add one under \"instruments\")");
  if (auto it = v.find("instrument"); it != v.end()) {
    const std::string name = p.nonempty_string(*it, at + ".instrument");
    std::vector<std::string> names;
    h.instrument = -1;
    for (size_t i = 0; i < s.instruments.size(); ++i) {
      names.push_back("\"" + s.instruments[i].name + "\"");
      if (s.instruments[i].name == name && h.instrument < 0) h.instrument = static_cast<int>(i);
    }
    if (h.instrument < 0) p.fail(at + ".instrument", " must name an instrument (" + join(names) + "), got " + show(*it));
  }
  const InstrumentSpec& tool = s.instruments[static_cast<size_t>(h.instrument)];
  if (h.device == HapticsSpec::Device::Scripted) {
    if (auto it = v.find("trajectory"); it != v.end()) h.trajectory = p.trajectory_file(*it, at + ".trajectory");
    else h.trajectory = tool.trajectory;
    if (h.trajectory.empty())
      p.fail(at + ".trajectory", ": required key is missing (a scripted device follows a keyframe CSV; " + tool.json_path +
                                     " has no trajectory to take)");
  }
  if (h.device == HapticsSpec::Device::Replay)
    h.stream = p.existing_file(p.required(v, at, "stream", "a recorded device stream (CSV)"), at + ".stream");
  if (h.device == HapticsSpec::Device::OpenIGTLink) {
    h.scale = 0.001;
    if (auto it = v.find("port"); it != v.end()) {
      h.port = p.integer(*it, at + ".port");
      if (h.port < 0 || h.port > 65535) p.fail(at + ".port", " must be a TCP port in [0, 65535] (0: any free one), got " + show(*it));
    }
  }
  if (auto it = v.find("rate_hz"); it != v.end()) {
    h.rate_hz = p.number(*it, at + ".rate_hz");
    if (!(h.rate_hz >= 100.0 && h.rate_hz <= 10000.0)) p.fail(at + ".rate_hz", " must be in [100, 10000] Hz, got " + show(*it));
  }
  if (auto it = v.find("max_force"); it != v.end()) h.max_force = p.positive(*it, at + ".max_force");
  if (auto it = v.find("scale"); it != v.end()) h.scale = p.positive(*it, at + ".scale");
  if (auto it = v.find("offset"); it != v.end()) h.offset = p.vec3(*it, at + ".offset");
  if (auto it = v.find("realtime"); it != v.end()) h.realtime = p.boolean(*it, at + ".realtime");
  if (auto it = v.find("coupling"); it != v.end()) {
    const std::string cp = at + ".coupling";
    p.object(*it, cp);
    p.allowed_keys(*it, cp, {"stiffness", "damping"});
    if (auto c = it->find("stiffness"); c != it->end()) h.stiffness = p.positive(*c, cp + ".stiffness");
    if (auto c = it->find("damping"); c != it->end()) h.damping = p.nonnegative(*c, cp + ".damping");
  }
  if (auto it = v.find("guard"); it != v.end()) {
    const std::string gp = at + ".guard";
    p.object(*it, gp);
    p.allowed_keys(*it, gp, {"center", "workspace_radius", "max_speed", "max_turn", "reacquire", "glide_speed"});
    if (auto c = it->find("center"); c != it->end()) h.center = p.vec3(*c, gp + ".center");
    if (auto c = it->find("workspace_radius"); c != it->end()) h.workspace_radius = p.positive(*c, gp + ".workspace_radius");
    if (auto c = it->find("max_speed"); c != it->end()) h.max_speed = p.positive(*c, gp + ".max_speed");
    if (auto c = it->find("reacquire"); c != it->end()) h.reacquire = p.nonnegative(*c, gp + ".reacquire");
    if (auto c = it->find("max_turn"); c != it->end()) h.max_turn = p.positive(*c, gp + ".max_turn");
    if (auto c = it->find("glide_speed"); c != it->end()) h.glide_speed = p.positive(*c, gp + ".glide_speed");
  }
}

void parse_render(const Parser& p, const json& v, Scene& s) {
  const std::string at = "render";
  RenderSettings& r = s.render;
  p.object(v, at);
  p.allowed_keys(v, at, {"width", "height", "subdivision", "camera", "light", "colors"});
  auto in_range = [&](const json& x, const std::string& where, int lo, int hi) {
    const int n = p.integer(x, where);
    if (n < lo || n > hi)
      p.fail(where, " must be an integer in [" + std::to_string(lo) + ", " + std::to_string(hi) + "], got " + show(x));
    return n;
  };
  auto nonzero = [&](const json& x, const std::string& where, bool normalize) {
    Vec3 d = p.vec3(x, where);
    const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    if (!(len > 0.0) || !std::isfinite(len)) p.fail(where, " must be a nonzero vector, got " + show(x));
    if (normalize)
      for (double& c : d) c /= len;
    return d;
  };
  if (auto it = v.find("width"); it != v.end()) r.width = in_range(*it, at + ".width", 16, 8192);
  if (auto it = v.find("height"); it != v.end()) r.height = in_range(*it, at + ".height", 16, 8192);
  if (auto it = v.find("subdivision"); it != v.end()) r.subdivision = in_range(*it, at + ".subdivision", 2, 16);
  if (auto it = v.find("camera"); it != v.end()) {
    const std::string cp = at + ".camera";
    p.object(*it, cp);
    p.allowed_keys(*it, cp, {"position", "target", "up", "fov_deg"});
    if (auto c = it->find("position"); c != it->end()) r.camera_position = p.vec3(*c, cp + ".position");
    if (auto c = it->find("target"); c != it->end()) r.camera_target = p.vec3(*c, cp + ".target");
    if (auto c = it->find("up"); c != it->end()) r.camera_up = nonzero(*c, cp + ".up", true);
    if (auto c = it->find("fov_deg"); c != it->end()) {
      r.fov_deg = p.number(*c, cp + ".fov_deg");
      if (!(r.fov_deg > 0.0 && r.fov_deg < 180.0)) p.fail(cp + ".fov_deg", " must be in (0, 180) degrees, got " + show(*c));
    }
    if (r.camera_position && r.camera_target) {
      const Vec3 &a = *r.camera_position, &b = *r.camera_target;
      const Vec3 d{b[0] - a[0], b[1] - a[1], b[2] - a[2]};
      const Vec3& u = r.camera_up;
      const Vec3 x{d[1] * u[2] - d[2] * u[1], d[2] * u[0] - d[0] * u[2], d[0] * u[1] - d[1] * u[0]};
      if (d == Vec3{0.0, 0.0, 0.0}) p.fail(cp + ".target", " must differ from camera.position, got " + show((*it)["target"]));
      if (x == Vec3{0.0, 0.0, 0.0}) p.fail(cp + ".up", " must not be parallel to the viewing direction target - position");
    }
  }
  if (auto it = v.find("light"); it != v.end()) {
    const std::string lp = at + ".light";
    p.object(*it, lp);
    p.allowed_keys(*it, lp, {"direction", "ambient"});
    if (auto c = it->find("direction"); c != it->end()) r.light_direction = nonzero(*c, lp + ".direction", true);
    if (auto c = it->find("ambient"); c != it->end()) {
      r.ambient = p.number(*c, lp + ".ambient");
      if (!(r.ambient >= 0.0 && r.ambient <= 1.0)) p.fail(lp + ".ambient", " must be in [0, 1], got " + show(*c));
    }
  }
  if (auto it = v.find("colors"); it != v.end()) {
    const std::string cp = at + ".colors";
    p.object(*it, cp);
    p.allowed_keys(*it, cp, {"tissue", "interior", "background", "instrument"});
    auto rgb = [&](const char* k, Vec3& out) {
      auto c = it->find(k);
      if (c == it->end()) return;
      const std::string where = Parser::key(cp, k);
      out = p.vec3(*c, where);
      for (size_t i = 0; i < 3; ++i)
        if (!(out[i] >= 0.0 && out[i] <= 1.0))
          p.fail(Parser::index(where, i), " must be in [0, 1] (colours are [r, g, b] in [0, 1]), got " + show((*c)[i]));
    };
    rgb("tissue", r.color_tissue);
    rgb("interior", r.color_interior);
    rgb("background", r.color_background);
    rgb("instrument", r.color_instrument);
  }
}

// nlohmann messages start with "[json.exception.parse_error.101] "; drop that.
std::string strip_id(const std::string& what) {
  if (what.rfind("[json.exception.", 0) == 0) {
    size_t end = what.find("] ");
    if (end != std::string::npos) return what.substr(end + 2);
  }
  return what;
}

// Parses text, rejecting duplicate keys (nlohmann would keep the last one silently).
json parse_text(const std::string& text, const std::string& path) {
  check_json_depth(text, path);  // before anything recurses over the document
  std::vector<std::set<std::string>> open;  // keys seen in each enclosing object
  auto callback = [&](int, json::parse_event_t ev, json& parsed) -> bool {
    switch (ev) {
      case json::parse_event_t::object_start:
        open.emplace_back();
        break;
      case json::parse_event_t::object_end:
        if (!open.empty()) open.pop_back();
        break;
      case json::parse_event_t::key:
        if (!open.empty() && parsed.is_string() &&
            !open.back().insert(parsed.get<std::string>()).second) {
          throw Error(path + ": duplicate key \"" + parsed.get<std::string>() +
                      "\"; each key may appear once per object");
        }
        break;
      default:
        break;
    }
    return true;
  };
  try {
    return json::parse(text, callback, /*allow_exceptions=*/true, /*ignore_comments=*/false);
  } catch (const json::parse_error& e) {
    throw Error(path + ": invalid JSON at byte " + std::to_string(e.byte) + ": " +
                strip_id(e.what()));
  } catch (const json::exception& e) {  // e.g. a number too large for a double
    throw Error(path + ": invalid JSON: " + strip_id(e.what()));
  }
}

}  // namespace

const char* policy_name(SolverPolicy p) {
  switch (p) {
    case SolverPolicy::Exact: return "exact";
    case SolverPolicy::Lagged: return "lagged";
    case SolverPolicy::Warped: return "warped";
    case SolverPolicy::WarpedCG: return "warped_cg";
  }
  return "unknown";
}

bool solver_key_used_by(const std::string& key, SolverPolicy policy) {
  if (listed(kLaggedKeys, key)) return policy == SolverPolicy::Lagged;
  if (listed(kIterativeKeys, key)) return policy == SolverPolicy::Lagged || policy == SolverPolicy::WarpedCG;
  return true;
}

Scene parse_scene(const std::string& json_text, const std::string& path, const std::vector<ScenePatch>& patches,
                  bool trajectories_needed) {
  json root = parse_text(json_text, path);
  if (!root.is_object()) throw Error(path + ": the scene must be a JSON object, got " + describe(root));
  const std::vector<AppliedPatch> applied = apply_scene_patches(root, patches);
  Parser p(path, &applied);
  p.set_trajectories_needed(trajectories_needed);
  p.allowed_keys(root, "",
                 {"mesh", "material", "mass", "gravity", "fixed", "prescribed", "integrator",
                  "solver", "static", "run", "output", "cuts", "cut_front", "cut_stabilization", "render", "instruments",
                  "contact", "haptics", "initial"});

  Scene s;
  s.path = path;
  for (const AppliedPatch& a : applied) s.patched.emplace_back(a.path, a.patch->given);
  // solver.preset fills the solver.* and integrator.* keys left unset.
  std::vector<std::string> from_preset;
  std::string preset;
  if (auto it = root.find("solver"); it != root.end() && it->is_object() && it->contains("preset")) {
    preset = solver_preset_names()[p.choice((*it)["preset"], "solver.preset", solver_preset_names())];
    from_preset = expand_solver_preset(root, preset);
    p.set_preset(preset, from_preset);
  }
  for (const char* section : {"solver", "integrator"}) {
    auto sec = root.find(section);
    if (sec == root.end() || !sec->is_object()) continue;
    for (auto it = sec->begin(); it != sec->end(); ++it) {
      const std::string k = std::string(section) + "." + it.key();
      SettingOrigin o{SettingOrigin::Kind::Scene, ""};
      if (std::find(from_preset.begin(), from_preset.end(), k) != from_preset.end())
        o = {SettingOrigin::Kind::Preset, preset};
      else if (const ScenePatch* pt = patch_for(applied, k))
        o = {SettingOrigin::Kind::Patch, pt->given};
      s.origin[k] = o;
    }
  }
  parse_mesh(p, p.required(root, "", "mesh", "an object with file and order"), s);
  parse_material(p, p.required(root, "", "material", "an object with young, poisson, density"),
                 s.material);
  if (auto it = root.find("mass"); it != root.end())
    s.mass = p.choice(*it, "mass", {"lumped", "consistent"}) == 0 ? MassKind::Lumped
                                                                   : MassKind::Consistent;
  if (auto it = root.find("gravity"); it != root.end()) s.gravity = p.vec3(*it, "gravity");
  if (auto it = root.find("fixed"); it != root.end()) parse_fixed(p, *it, s);
  if (auto it = root.find("prescribed"); it != root.end()) parse_prescribed(p, *it, s);
  // integrator.tangent left unset: consistent for compressible tissue (nu <=
  // 0.45), frozen_rotation above (the consistent one diverges at nu >= 0.49
  // at 30 Hz). A swinging soft beam cut while it moved blew up under the
  // frozen one (Newton at its cap in 53 of 60 frames, 324 inverted points)
  // and not under the consistent one (docs/numerics.md).
  s.consistent_tangent = s.material.poisson <= 0.45;
  if (auto it = root.find("integrator"); it != root.end()) parse_integrator(p, *it, s);
  if (auto it = root.find("solver"); it != root.end()) parse_solver(p, *it, s);
  if (auto it = root.find("static"); it != root.end()) parse_static(p, *it, s);
  if (auto it = root.find("initial"); it != root.end()) s.initial_static = p.choice(*it, "initial", {"rest", "static"}) == 1;
  if (auto it = root.find("cut_front"); it != root.end())
    s.front_enrichment = p.choice(*it, "cut_front", {"faces", "enriched"}) == 1;
  if (auto it = root.find("cut_stabilization"); it != root.end()) {
    s.cut_stabilization = p.nonnegative(*it, "cut_stabilization");
    if (!(s.cut_stabilization <= 1.0))
      p.fail("cut_stabilization", " must be in [0, 1] (the weight of a small cut piece's field over its element; 0 = off), got " + show(*it));
  }
  if (auto it = root.find("run"); it != root.end()) parse_run(p, *it, s);
  if (auto it = root.find("output"); it != root.end()) parse_output(p, *it, s);
  if (auto it = root.find("cuts"); it != root.end()) parse_cuts(p, *it, s);
  if (auto it = root.find("render"); it != root.end()) parse_render(p, *it, s);
  if (auto it = root.find("instruments"); it != root.end()) parse_instruments(p, *it, s);
  if (auto it = root.find("contact"); it != root.end()) parse_contact(p, *it, s);
  if (auto it = root.find("haptics"); it != root.end()) parse_haptics(p, *it, s);
  return s;
}

Scene load_scene(const std::string& path, const std::vector<ScenePatch>& patches) {
  return parse_scene(read_input_file(path, kMaxSceneBytes, "scene file"), path, patches);
}

namespace {
std::string quoted(const char* x) { return std::string("\"") + x + "\""; }
}  // namespace

std::vector<ResolvedSetting> resolved_settings(const Scene& s) {
  const SolverSettings& o = s.solver;
  const RuntimeSettings& rt = s.runtime;
  std::vector<std::pair<std::string, std::string>> kv;
  if (!s.preset.empty()) kv.push_back({"solver.preset", "\"" + s.preset + "\""});
  kv.push_back({"solver.policy", quoted(policy_name(o.policy))});
  const char* copies[] = {"none", "float", "half"};
  const std::vector<std::pair<std::string, std::string>> all{
      {"refresh_every", std::to_string(o.refresh_every)},
      {"background", o.background ? "true" : "false"},
      {"warp", o.warp ? "true" : "false"},
      {"factor_copy", quoted(copies[static_cast<int>(o.factor_copy)])},
      {"factor_precision", quoted(o.single_factorization ? "single" : "double")},
      {"rescue_after", std::to_string(o.rescue_after)},
      {"late_factor", quoted(o.skip_late_factor ? "skip" : "wait")},
      {"patch", quoted(o.multiplicative_patch ? "multiplicative" : "additive")},
      {"cut_ordering", quoted(o.carry_ordering ? "carried" : "search")},
      {"background_priority", quoted(rt.idle_background ? "idle" : "normal")},
      {"tolerance", number_text(o.tolerance)},
      {"max_iterations", std::to_string(o.max_iterations)},
      {"initial_guess", quoted(o.previous_guess ? "previous" : "zero")},
      {"frame_iterations", std::to_string(o.frame_iterations)},
      {"matrix_precision", quoted(o.single_matrix ? "single" : "double")},
      {"coarse", quoted(o.coarse ? "corners" : "none")},
      {"condense_below", number_text(o.condense_below)},
      {"contact_patch", std::to_string(o.contact_patch)},
      {"threads", std::to_string(rt.threads)},
      {"substitution_threads", std::to_string(rt.substitution_threads)},
      {"affinity", quoted(rt.split_affinity ? "split" : "none")},
      {"factorization", quoted(o.factor == FactorMethod::Auto ? "auto" : o.factor == FactorMethod::Supernodal ? "supernodal" : "simplicial")},
      {"ordering", quoted(o.ordering == OrderingMethod::Auto ? "auto" : o.ordering == OrderingMethod::Amd ? "amd" : "metis")}};
  for (const auto& [k, v] : all)
    if (solver_key_used_by(k, o.policy)) kv.push_back({"solver." + k, v});
  kv.push_back({"integrator.dt", number_text(s.dt)});
  kv.push_back({"integrator.newton_iterations", std::to_string(s.newton_iterations)});
  kv.push_back({"integrator.max_newton_iterations", std::to_string(s.max_newton_iterations)});
  kv.push_back({"integrator.rotation_tolerance", number_text(s.rotation_tolerance)});
  kv.push_back({"integrator.rotation_fraction", number_text(s.rotation_fraction)});
  kv.push_back({"integrator.rotation_rms", number_text(s.rotation_rms)});
  kv.push_back({"integrator.line_search", s.line_search ? "true" : "false"});
  kv.push_back({"integrator.residual_tolerance", number_text(s.residual_tolerance)});
  kv.push_back({"integrator.tangent", quoted(s.consistent_tangent ? "consistent" : "frozen_rotation")});
  kv.push_back({"integrator.tangent_reuse", number_text(s.tangent_reuse)});
  kv.push_back({"integrator.predictor", quoted(s.increment_predictor ? "increment" : "velocity")});
  kv.push_back({"integrator.newmark_gamma", number_text(s.newmark_gamma)});
  kv.push_back({"integrator.newmark_beta", number_text(s.newmark_beta)});
  kv.push_back({"integrator.recovery", quoted(s.recovery_steps ? "backward_euler" : "none")});
  std::vector<ResolvedSetting> out;
  for (auto& [k, v] : kv) {
    auto it = s.origin.find(k);
    if (it == s.origin.end() && k == "solver.factor_copy") it = s.origin.find("solver.single_precision");  // the older key
    out.push_back({k, v, it == s.origin.end() ? SettingOrigin{} : it->second});
  }
  return out;
}

std::vector<ScenePatch> exact_reference_patches(const Scene& run) {
  const std::string why = "compare reference: ";
  const std::string solver = "{\"preset\": \"reference\", \"threads\": " + std::to_string(run.runtime.threads) + "}";
  const std::string tangent = run.consistent_tangent ? "consistent" : "frozen_rotation";
  const std::string predictor = run.increment_predictor ? "increment" : "velocity";
  return {{"solver", solver, why + "solver=" + solver},
          {"integrator.tangent", tangent, why + "integrator.tangent=" + tangent},
          {"integrator.predictor", predictor, why + "integrator.predictor=" + predictor},
          {"integrator.tangent_reuse", "0", why + "integrator.tangent_reuse=0"}};
}

}  // namespace incise
