// Command-line patches of a scene (--set KEY=VALUE) and solver presets
// (engine/scene/scene_patch.cpp): the patch is applied to the JSON before the
// parser runs, so the parser's checks and messages apply, naming the patch.
#include "engine/scene/scene.h"

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <random>
#include <string>
#include <vector>

#include "engine/util/error.h"

namespace fs = std::filesystem;
using incise::Error;
using incise::parse_scene;
using incise::Scene;
using incise::ScenePatch;
using incise::SettingOrigin;
using incise::SolverPolicy;

namespace {

class ScenePatchTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device rd;
    root_ = fs::temp_directory_path() / ("incise_patch_test_" + std::to_string(rd()) + "_" +
                                         std::to_string(std::chrono::steady_clock::now().time_since_epoch().count()));
    fs::create_directories(root_);
    std::ofstream(root_ / "m.vtu") << "placeholder\n";
    path_ = (root_ / "s.json").string();
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }
  static std::string scene(const std::string& extra = "") {
    std::string s = R"({"mesh": {"file": "m.vtu"}, "material": {"young": 3000, "poisson": 0.45, "density": 1000})";
    if (!extra.empty()) s += ", " + extra;
    return s + "}";
  }
  // "--set" patches from their text.
  static std::vector<ScenePatch> sets(std::initializer_list<const char*> texts) {
    std::vector<ScenePatch> out;
    for (const char* t : texts) out.push_back(incise::parse_scene_patch(t));
    return out;
  }
  Scene load(const std::string& text, const std::vector<ScenePatch>& patches) { return parse_scene(text, path_, patches); }
  std::string error_of(const std::string& text, const std::vector<ScenePatch>& patches) {
    try {
      load(text, patches);
    } catch (const Error& e) {
      return e.what();
    }
    ADD_FAILURE() << "no error";
    return "";
  }
  fs::path root_;
  std::string path_;
};

TEST_F(ScenePatchTest, PatchTextIsKeyEqualsValue) {
  const ScenePatch p = incise::parse_scene_patch("solver.policy=lagged");
  EXPECT_EQ(p.key, "solver.policy");
  EXPECT_EQ(p.value, "lagged");
  EXPECT_EQ(p.given, "--set solver.policy=lagged");
  EXPECT_EQ(incise::parse_scene_patch("output.dir=a=b").value, "a=b") << "the first '=' splits";
  try {
    incise::parse_scene_patch("foo");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()),
              "--set foo: expected KEY=VALUE, e.g. --set solver.policy=lagged or --set integrator.dt=0.01");
  }
  EXPECT_THROW(incise::parse_scene_patch("=1"), Error);
  try {
    load(scene(), sets({"solver..policy=exact"}));
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("--set solver..policy=exact: the key \"solver..policy\" has an empty part"),
              std::string::npos)
        << e.what();
  }
}

// A value is JSON when it parses as JSON (numbers, booleans, arrays, quoted
// strings), otherwise the text as a string.
TEST_F(ScenePatchTest, ValuesParseAsJsonElseAsString) {
  const Scene s = load(scene(), sets({"integrator.dt=0.01", "solver.policy=lagged", "solver.background=true",
                                      "gravity=[0, 0, -1]", "solver.late_factor=\"skip\"", "solver.refresh_every=3"}));
  EXPECT_DOUBLE_EQ(s.dt, 0.01);
  EXPECT_EQ(s.solver.policy, SolverPolicy::Lagged);
  EXPECT_TRUE(s.solver.background);
  EXPECT_EQ(s.gravity, (incise::Vec3{0, 0, -1}));
  EXPECT_TRUE(s.solver.skip_late_factor);
  EXPECT_EQ(s.solver.refresh_every, 3);
  // A quoted number is a string, which the parser refuses for an integer key.
  EXPECT_EQ(error_of(scene(), sets({"solver.threads=\"3\""})),
            "--set solver.threads=\"3\": solver.threads must be an integer, got string \"3\"");
  EXPECT_EQ(error_of(scene(), sets({"integrator.dt=nan"})),
            "--set integrator.dt=nan: integrator.dt must be a number, got string \"nan\"");
}

// Issue 24: a --set value or key nested without bound is refused before it
// is parsed (its dump in a message overflowed the stack); the message quotes
// a long patch shortened.
TEST_F(ScenePatchTest, DeepValuesAndKeysRefused) {
  const int n = 100000;
  const std::string deep = "material.young=" + std::string(n, '[') + std::string(n, ']');
  EXPECT_EQ(error_of(scene(), sets({deep.c_str()})),
            "--set " + deep.substr(0, 80) + "... (200015 characters): the value is nested deeper than 64 levels of [ and {");
  std::string key = "a";
  for (int i = 0; i < 1000; ++i) key += ".a";
  const std::string msg = error_of(scene(), sets({(key + "=1").c_str()}));
  EXPECT_NE(msg.find(": the key has 1001 parts, more than 64"), std::string::npos) << msg;
  // 64 levels are fine: the parser then says what is wrong with the value
  const std::string ok = "material.young=" + std::string(64, '[') + std::string(64, ']');
  EXPECT_NE(error_of(scene(), sets({ok.c_str()})).find("material.young must be a number, got array"), std::string::npos);
}

TEST_F(ScenePatchTest, NestedKeysAndArrayIndices) {
  const std::string cut = R"("cuts": [{"type": "plane", "point": [0, 0, 0], "normal": [1, 0, 0], "at_time": 1.0}])";
  EXPECT_DOUBLE_EQ(load(scene(cut), sets({"cuts.0.at_time=0.5"})).cuts[0].at_time, 0.5);
  EXPECT_DOUBLE_EQ(load(scene(cut), sets({"cuts[0].at_time=0.25"})).cuts[0].at_time, 0.25);
  EXPECT_DOUBLE_EQ(load(scene(cut), sets({"cuts.0.normal.0=0", "cuts.0.normal.2=2"})).cuts[0].normal[2], 1.0);
  // a missing section is created; a whole object can be given
  EXPECT_DOUBLE_EQ(load(scene(), sets({"render.camera.fov_deg=45"})).render.fov_deg, 45.0);
  EXPECT_EQ(load(scene(), sets({R"(solver={"policy": "lagged", "refresh_every": 4})"})).solver.refresh_every, 4);
  EXPECT_EQ(error_of(scene(cut), sets({"cuts.3.at_time=1"})),
            "--set cuts.3.at_time=1: cuts has 1 entries; index 3 is out of range");
  EXPECT_EQ(error_of(scene(cut), sets({"cuts.first.at_time=1"})),
            "--set cuts.first.at_time=1: cuts is an array; \"first\" is not an index (0, 1, ...)");
  EXPECT_EQ(error_of(scene(R"("integrator": {"dt": 0.01})"), sets({"integrator.dt.x=1"})),
            "--set integrator.dt.x=1: integrator.dt is a number, not an object: it has no key \"x\"");
  // a bad value inside an indexed entry names the patch and the parser's path
  EXPECT_EQ(error_of(scene(cut), sets({"cuts.0.at_time=-1"})),
            "--set cuts.0.at_time=-1: cuts[0].at_time must be >= 0, got -1");
}

// The parser rejects unknown keys; a patch of one says so, naming the patch.
TEST_F(ScenePatchTest, UnknownKeyIsAnErrorNamingThePatch) {
  const std::string msg = error_of(scene(), sets({"solver.polcy=lagged"}));
  EXPECT_EQ(msg.rfind("--set solver.polcy=lagged: solver.polcy: unknown key; allowed: preset, policy,", 0), 0u) << msg;
  EXPECT_NE(msg.find("did you mean \"policy\"?"), std::string::npos) << msg;
  EXPECT_EQ(error_of(scene(), sets({"foo.bar=1"})).rfind("--set foo.bar=1: foo: unknown key; allowed: mesh,", 0), 0u);
}

TEST_F(ScenePatchTest, BadValueGivesTheParsersMessageNamingThePatch) {
  EXPECT_EQ(error_of(scene(), sets({"solver.policy=lagged2"})),
            "--set solver.policy=lagged2: solver.policy must be one of \"exact\", \"lagged\", \"warped\", "
            "\"warped_cg\", got \"lagged2\"");
  // the checks across keys apply too
  EXPECT_EQ(error_of(scene(), sets({"solver.tolerance=1e-4"})),
            "--set solver.tolerance=1e-4: solver.tolerance: only used by the iterative policies \"lagged\" and "
            "\"warped_cg\"; solver.policy is \"exact\"");
  // an alias flag's patch is named as the user wrote it
  EXPECT_EQ(error_of(scene(), {{"solver.affinity", "cores", "--affinity cores"}}),
            "--affinity cores: solver.affinity must be one of \"none\", \"split\", got \"cores\"");
  // an error of the file itself still names the file
  EXPECT_EQ(error_of(scene(R"("run": {"frames": 0})"), sets({"integrator.dt=0.01"})),
            path_ + ": run.frames must be an integer >= 1, got 0");
}

TEST_F(ScenePatchTest, LaterPatchWinsAndNullRemovesAKey) {
  const std::string lagged = R"("solver": {"policy": "lagged", "refresh_every": 3})";
  EXPECT_EQ(load(scene(lagged), sets({"solver.refresh_every=5", "solver.refresh_every=6"})).solver.refresh_every, 6);
  const Scene s = load(scene(lagged), sets({"solver.refresh_every=null"}));
  EXPECT_EQ(s.solver.refresh_every, 1);
  EXPECT_EQ(s.origin.count("solver.refresh_every"), 0u) << "removed: the default";
  // null then a policy without the key's use: valid
  EXPECT_EQ(load(scene(lagged), sets({"solver.refresh_every=null", "solver.policy=warped"})).solver.policy,
            SolverPolicy::Warped);
}

TEST_F(ScenePatchTest, OriginsNameSceneFilePatchPresetOrDefault) {
  const Scene s = load(scene(R"("solver": {"preset": "realtime", "refresh_every": 3}, "integrator": {"dt": 0.02})"),
                       sets({"solver.tolerance=1e-4"}));
  EXPECT_EQ(s.origin.at("solver.refresh_every").kind, SettingOrigin::Kind::Scene);
  EXPECT_EQ(s.origin.at("integrator.dt").kind, SettingOrigin::Kind::Scene);
  EXPECT_EQ(s.origin.at("solver.tolerance").kind, SettingOrigin::Kind::Patch);
  EXPECT_EQ(s.origin.at("solver.tolerance").detail, "--set solver.tolerance=1e-4");
  EXPECT_EQ(s.origin.at("solver.policy").kind, SettingOrigin::Kind::Preset);
  EXPECT_EQ(s.origin.at("solver.policy").detail, "realtime");
  EXPECT_EQ(s.origin.at("integrator.tangent").kind, SettingOrigin::Kind::Preset);
  EXPECT_EQ(s.origin.count("solver.initial_guess"), 0u) << "not set by anyone: the default";
  // resolved_settings lists every key the policy uses, with its value and origin
  bool saw_refresh = false, saw_guess = false;
  for (const incise::ResolvedSetting& r : incise::resolved_settings(s)) {
    if (r.key == "solver.refresh_every") saw_refresh = r.value == "3" && r.origin.kind == SettingOrigin::Kind::Scene;
    if (r.key == "solver.initial_guess")
      saw_guess = r.value == "\"previous\"" && r.origin.kind == SettingOrigin::Kind::Default;
  }
  EXPECT_TRUE(saw_refresh);
  EXPECT_TRUE(saw_guess);
  for (const incise::ResolvedSetting& r : incise::resolved_settings(load(scene(), {})))
    EXPECT_NE(r.key, "solver.refresh_every") << "exact does not use it";
}

// "realtime" is bench-realtime.sh's configuration, integrator keys included.
TEST_F(ScenePatchTest, RealtimePresetSetsTheMeasuredConfiguration) {
  const Scene s = load(scene(R"("solver": {"preset": "realtime"})"), {});
  const incise::SolverSettings& o = s.solver;
  EXPECT_EQ(s.preset, "realtime");
  EXPECT_EQ(o.policy, SolverPolicy::Lagged);
  EXPECT_TRUE(o.background);
  EXPECT_TRUE(o.warp);
  EXPECT_EQ(o.refresh_every, 2);
  EXPECT_DOUBLE_EQ(o.tolerance, 1e-2);
  EXPECT_EQ(o.max_iterations, 100);
  EXPECT_EQ(s.runtime.threads, 2);
  EXPECT_EQ(o.rescue_after, 20);
  EXPECT_TRUE(o.skip_late_factor);
  EXPECT_EQ(o.factor_copy, incise::FactorCopy::Half);
  EXPECT_TRUE(o.single_factorization);
  EXPECT_EQ(s.runtime.substitution_threads, 2);
  EXPECT_TRUE(s.runtime.split_affinity);
  EXPECT_TRUE(s.runtime.idle_background);
  EXPECT_TRUE(s.consistent_tangent);
  EXPECT_DOUBLE_EQ(s.tangent_reuse, 1e-2);
  EXPECT_TRUE(s.increment_predictor);
  EXPECT_TRUE(s.origin.at("integrator.predictor").kind == incise::SettingOrigin::Kind::Preset)
      << "the preset names the predictor it was measured with";
  // the same through a patch, on a scene without a solver section
  const Scene p = load(scene(), sets({"solver.preset=realtime"}));
  EXPECT_EQ(p.solver.policy, SolverPolicy::Lagged);
  EXPECT_EQ(p.solver.refresh_every, 2);
  EXPECT_TRUE(p.consistent_tangent);
}

TEST_F(ScenePatchTest, ReferencePresetIsExact) {
  const Scene s = load(scene(R"("solver": {"preset": "reference"})"), {});
  EXPECT_EQ(s.solver.policy, SolverPolicy::Exact);
  EXPECT_EQ(s.tangent_reuse, 0.0);
  EXPECT_TRUE(s.consistent_tangent) << "the scene's tangent (the default at poisson 0.45)";
}

// integrator.tangent left unset: consistent for compressible tissue (poisson
// <= 0.45), frozen_rotation above (the consistent one diverges at 0.49 at
// 30 Hz); a scene's own choice stands.
TEST_F(ScenePatchTest, TheDefaultTangentFollowsPoissonsRatio) {
  EXPECT_TRUE(load(scene(), {}).consistent_tangent);
  EXPECT_FALSE(load(scene(), sets({"material.poisson=0.46"})).consistent_tangent);
  EXPECT_FALSE(load(scene(), sets({"material.poisson=0.499"})).consistent_tangent);
  EXPECT_FALSE(load(scene(R"("integrator": {"tangent": "frozen_rotation"})"), {}).consistent_tangent);
  EXPECT_TRUE(load(scene(R"("integrator": {"tangent": "consistent"})"), sets({"material.poisson=0.49"})).consistent_tangent);
}

// A key the scene or a patch sets wins over the preset's.
TEST_F(ScenePatchTest, ExplicitKeysWinOverThePreset) {
  const Scene s = load(scene(R"("solver": {"preset": "realtime", "refresh_every": 4, "threads": 3},
                                 "integrator": {"tangent": "frozen_rotation"})"),
                       sets({"solver.tolerance=1e-5", "integrator.tangent_reuse=0"}));
  EXPECT_EQ(s.solver.refresh_every, 4);
  EXPECT_EQ(s.runtime.threads, 3);
  EXPECT_DOUBLE_EQ(s.solver.tolerance, 1e-5);
  EXPECT_FALSE(s.consistent_tangent);
  EXPECT_EQ(s.tangent_reuse, 0.0);
  EXPECT_TRUE(s.solver.background) << "the rest is the preset's";
  // An explicit policy wins too; the preset's keys that policy does not use are left out.
  const Scene w = load(scene(R"("solver": {"preset": "realtime", "policy": "warped"})"), {});
  EXPECT_EQ(w.solver.policy, SolverPolicy::Warped);
  EXPECT_EQ(w.runtime.threads, 2) << "a key warped uses: the preset's";
  EXPECT_EQ(w.origin.count("solver.refresh_every"), 0u);
  const Scene cg = load(scene(R"("solver": {"preset": "realtime"})"), sets({"solver.policy=warped_cg"}));
  EXPECT_DOUBLE_EQ(cg.solver.tolerance, 1e-2) << "an iterative policy keeps the preset's CG keys";
  EXPECT_FALSE(cg.solver.background);
  // The float copy keeps the preset's single-precision factorization; no
  // copy leaves it out.
  const Scene flt = load(scene(R"("solver": {"preset": "realtime", "factor_copy": "float"})"), {});
  EXPECT_EQ(flt.solver.factor_copy, incise::FactorCopy::Float);
  EXPECT_TRUE(flt.solver.single_factorization);
  const Scene none = load(scene(R"("solver": {"preset": "realtime", "factor_copy": "none"})"), {});
  EXPECT_FALSE(none.solver.single_factorization);
  const Scene older = load(scene(R"("solver": {"preset": "realtime", "single_precision": false})"), {});
  EXPECT_EQ(older.solver.factor_copy, incise::FactorCopy::None);
}

TEST_F(ScenePatchTest, UnknownPresetIsAnError) {
  EXPECT_EQ(error_of(scene(R"("solver": {"preset": "fast"})"), {}),
            path_ + ": solver.preset must be one of \"realtime\", \"reference\", got \"fast\"");
  EXPECT_EQ(error_of(scene(), sets({"solver.preset=fast"})),
            "--set solver.preset=fast: solver.preset must be one of \"realtime\", \"reference\", got \"fast\"");
}

TEST_F(ScenePatchTest, SolverKeysByPolicy) {
  EXPECT_TRUE(incise::solver_key_used_by("refresh_every", SolverPolicy::Lagged));
  EXPECT_FALSE(incise::solver_key_used_by("refresh_every", SolverPolicy::WarpedCG));
  EXPECT_TRUE(incise::solver_key_used_by("tolerance", SolverPolicy::WarpedCG));
  EXPECT_FALSE(incise::solver_key_used_by("tolerance", SolverPolicy::Exact));
  EXPECT_TRUE(incise::solver_key_used_by("threads", SolverPolicy::Warped));
  EXPECT_TRUE(incise::solver_key_used_by("affinity", SolverPolicy::Exact));
}

// compare's reference: whatever preset, solver keys and patches the run has,
// the reference solves exactly, assembles every element, and keeps the run's
// equations (dt, tangent) and assembly threads.
TEST_F(ScenePatchTest, ExactReferencePatchesGiveAnExactReference) {
  struct Case {
    std::string text;
    std::vector<ScenePatch> patches;
  };
  const std::vector<Case> cases{
      {scene(R"("solver": {"preset": "realtime"})"), sets({"solver.refresh_every=3", "integrator.dt=0.02"})},
      {scene(R"("solver": {"policy": "lagged", "refresh_every": 5, "tolerance": 1e-4, "background": true},
                "integrator": {"tangent_reuse": 0.02, "tangent": "consistent"})"),
       {}},
      {scene(), sets({"solver.preset=realtime", "integrator.tangent=frozen_rotation"})},
      {scene(R"("solver": {"policy": "warped_cg", "threads": 3})"), {{"integrator.tangent_reuse", "0.01", "--tangent-reuse 0.01"}}},
  };
  for (const Case& c : cases) {
    const Scene run = load(c.text, c.patches);
    std::vector<ScenePatch> ref_patches = c.patches;
    for (const ScenePatch& p : incise::exact_reference_patches(run)) ref_patches.push_back(p);
    const Scene ref = load(c.text, ref_patches);
    EXPECT_EQ(ref.solver.policy, SolverPolicy::Exact) << c.text;
    EXPECT_EQ(ref.preset, "reference");
    EXPECT_EQ(ref.tangent_reuse, 0.0);
    EXPECT_EQ(ref.consistent_tangent, run.consistent_tangent);
    EXPECT_EQ(ref.increment_predictor, run.increment_predictor);
    EXPECT_EQ(ref.runtime.threads, run.runtime.threads);
    EXPECT_EQ(ref.dt, run.dt);
    EXPECT_EQ(ref.runtime.substitution_threads, 1);
    EXPECT_FALSE(ref.runtime.split_affinity);
  }
}

}  // namespace
