// Scene loader: a full scene's values and defaults, and one test per kind of
// malformed input checking that the message names the file, the JSON path,
// what is allowed and what was found.
#include "engine/scene/scene.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <random>
#include <sstream>
#include <string>

#include "engine/util/error.h"

namespace fs = std::filesystem;
using incise::ContactSettings;
using incise::Error;
using incise::parse_scene;
using incise::Scene;

namespace {

// A fresh folder per test (tests may run in parallel processes) holding
// meshes/m.vtu and scenes/, so "../meshes/m.vtu" from a scene resolves.
class SceneTest : public ::testing::Test {
 protected:
  void SetUp() override {
    std::random_device rd;
    auto stamp = std::chrono::steady_clock::now().time_since_epoch().count();
    root_ = fs::temp_directory_path() /
            ("incise_scene_test_" + std::to_string(rd()) + "_" + std::to_string(stamp));
    fs::create_directories(root_ / "meshes");
    fs::create_directories(root_ / "scenes");
    std::ofstream(root_ / "meshes" / "m.vtu") << "placeholder\n";
    scene_path_ = (root_ / "scenes" / "s.json").string();
  }
  void TearDown() override {
    std::error_code ec;
    fs::remove_all(root_, ec);
  }

  // A minimal valid scene with `extra` spliced in as further top-level keys.
  static std::string minimal(const std::string& extra = "") {
    std::string s = R"({"mesh": {"file": "../meshes/m.vtu"},
      "material": {"young": 3000, "poisson": 0.45, "density": 1000})";
    if (!extra.empty()) s += ", " + extra;
    return s + "}";
  }

  // A scene with the material object replaced by `material`.
  static std::string with_material(const std::string& material) {
    return R"({"mesh": {"file": "../meshes/m.vtu"}, "material": )" + material + "}";
  }

  // The error message parse_scene throws for `text` (fails the test if none).
  std::string error_of(const std::string& text) {
    try {
      parse_scene(text, scene_path_);
    } catch (const Error& e) {
      return e.what();
    }
    ADD_FAILURE() << "no error for:\n" << text;
    return "";
  }

  // Checks the message is "<scene path>: <rest>" exactly.
  void expect_error(const std::string& text, const std::string& rest) {
    EXPECT_EQ(error_of(text), scene_path_ + ": " + rest);
  }

  // Checks the message starts with the scene path and contains `part`.
  void expect_error_contains(const std::string& text, const std::string& part) {
    std::string msg = error_of(text);
    EXPECT_EQ(msg.rfind(scene_path_ + ": ", 0), 0u) << msg;
    EXPECT_NE(msg.find(part), std::string::npos) << "message: " << msg << "\nexpected part: " << part;
  }

  fs::path root_;
  std::string scene_path_;
};

std::string resolved(const fs::path& p) { return p.lexically_normal().string(); }

}  // namespace

// --- valid scenes ----------------------------------------------------------

TEST_F(SceneTest, FullSceneParsesAllValues) {
  const std::string text = R"({
    "mesh": {"file": "../meshes/m.vtu", "order": 1},
    "material": {"model": "linear", "rotation": "single", "young": 1e5, "poisson": -0.2,
                 "density": 1.5, "rayleigh": {"mass": 0.1, "stiffness": 0.01}},
    "mass": "consistent",
    "gravity": [0, -9.81, 1.5],
    "fixed": [
      {"box": [[-1e-9, -1, -1], [1e-9, 1, 1]]},
      {"plane": {"point": [0, 0, 0], "normal": [0, 0, 2]}},
      {"nodes": [0, 5, 7]}
    ],
    "prescribed": [
      {"nodes": [3], "displacement": {"x": 0.01, "z": -0.02}, "ramp": 0.5},
      {"box": [[0, 0, 0], [1, 1, 1]], "displacement": {"y": 0}}
    ],
    "integrator": {"dt": 0.001, "newton_iterations": 3},
    "solver": {"policy": "exact"},
    "static": {"tolerance": 1e-6, "max_iterations": 20},
    "run": {"frames": 90},
    "output": {"dir": "../out", "every": 5, "vtu": false}
  })";
  Scene s = parse_scene(text, scene_path_);
  EXPECT_EQ(s.path, scene_path_);
  EXPECT_EQ(s.mesh_file, resolved(root_ / "meshes" / "m.vtu"));
  EXPECT_EQ(s.order, 1);
  EXPECT_EQ(s.material.model, incise::MaterialModel::Linear);
  EXPECT_EQ(s.material.rotation, incise::RotationMode::Single);
  EXPECT_DOUBLE_EQ(s.material.young, 1e5);
  EXPECT_DOUBLE_EQ(s.material.poisson, -0.2);
  EXPECT_DOUBLE_EQ(s.material.density, 1.5);
  EXPECT_DOUBLE_EQ(s.material.rayleigh_mass, 0.1);
  EXPECT_DOUBLE_EQ(s.material.rayleigh_stiffness, 0.01);
  EXPECT_EQ(s.mass, incise::MassKind::Consistent);
  EXPECT_EQ(s.gravity, (incise::Vec3{0, -9.81, 1.5}));

  ASSERT_EQ(s.fixed.size(), 3u);
  EXPECT_EQ(s.fixed[0].kind, incise::Region::Kind::Box);
  EXPECT_EQ(s.fixed[0].lo, (incise::Vec3{-1e-9, -1, -1}));
  EXPECT_EQ(s.fixed[0].hi, (incise::Vec3{1e-9, 1, 1}));
  EXPECT_EQ(s.fixed[0].json_path, "fixed[0]");
  EXPECT_EQ(s.fixed[1].kind, incise::Region::Kind::Plane);
  EXPECT_EQ(s.fixed[1].point, (incise::Vec3{0, 0, 0}));
  EXPECT_EQ(s.fixed[1].normal, (incise::Vec3{0, 0, 1}));  // scaled to unit length
  EXPECT_EQ(s.fixed[2].kind, incise::Region::Kind::Nodes);
  EXPECT_EQ(s.fixed[2].nodes, (std::vector<int>{0, 5, 7}));

  ASSERT_EQ(s.prescribed.size(), 2u);
  const auto& p0 = s.prescribed[0];
  EXPECT_EQ(p0.region.kind, incise::Region::Kind::Nodes);
  EXPECT_EQ(p0.region.json_path, "prescribed[0]");
  EXPECT_EQ(p0.region.nodes, (std::vector<int>{3}));
  EXPECT_EQ(p0.active, (std::array<bool, 3>{true, false, true}));
  EXPECT_DOUBLE_EQ(p0.displacement[0], 0.01);
  EXPECT_DOUBLE_EQ(p0.displacement[2], -0.02);
  EXPECT_DOUBLE_EQ(p0.ramp, 0.5);
  const auto& p1 = s.prescribed[1];
  EXPECT_EQ(p1.region.kind, incise::Region::Kind::Box);
  EXPECT_EQ(p1.active, (std::array<bool, 3>{false, true, false}));
  EXPECT_DOUBLE_EQ(p1.ramp, 0.0);

  EXPECT_DOUBLE_EQ(s.dt, 0.001);
  EXPECT_EQ(s.newton_iterations, 3);
  EXPECT_EQ(s.solver.policy, incise::SolverPolicy::Exact);
  EXPECT_DOUBLE_EQ(s.static_tolerance, 1e-6);
  EXPECT_EQ(s.static_max_iterations, 20);
  EXPECT_EQ(s.frames, 90);
  EXPECT_EQ(s.output.dir, resolved(root_ / "out"));
  EXPECT_EQ(s.output.every, 5);
  EXPECT_FALSE(s.output.write_vtu);
}

TEST_F(SceneTest, MinimalSceneGetsDefaults) {
  Scene s = parse_scene(minimal(), scene_path_);
  EXPECT_EQ(s.order, 2);
  EXPECT_EQ(s.material.model, incise::MaterialModel::Corotated);
  EXPECT_EQ(s.material.rotation, incise::RotationMode::PerPoint);
  EXPECT_DOUBLE_EQ(s.material.young, 3000);
  EXPECT_DOUBLE_EQ(s.material.poisson, 0.45);
  EXPECT_DOUBLE_EQ(s.material.density, 1000);
  EXPECT_EQ(s.material.rayleigh_mass, 0.0);
  EXPECT_EQ(s.material.rayleigh_stiffness, 0.0);
  EXPECT_EQ(s.mass, incise::MassKind::Lumped);
  EXPECT_EQ(s.gravity, (incise::Vec3{0, 0, -9.81}));
  EXPECT_TRUE(s.fixed.empty());
  EXPECT_TRUE(s.prescribed.empty());
  EXPECT_DOUBLE_EQ(s.dt, 1.0 / 30.0);
  EXPECT_EQ(s.newton_iterations, 1);
  EXPECT_EQ(s.solver.policy, incise::SolverPolicy::Exact);
  EXPECT_DOUBLE_EQ(s.static_tolerance, 1e-8);
  EXPECT_EQ(s.static_max_iterations, 50);
  EXPECT_EQ(s.frames, 60);
  EXPECT_EQ(s.output.dir, "");
  EXPECT_EQ(s.output.every, 1);
  EXPECT_TRUE(s.output.write_vtu);
}

TEST_F(SceneTest, IntegralFloatAcceptedAsInteger) {
  Scene s = parse_scene(minimal(R"("run": {"frames": 30.0})"), scene_path_);
  EXPECT_EQ(s.frames, 30);
}

TEST_F(SceneTest, AbsoluteMeshPathKept) {
  std::string abs = (root_ / "meshes" / "m.vtu").string();
  Scene s = parse_scene(R"({"mesh": {"file": ")" + abs +
                            R"("}, "material": {"young": 1, "poisson": 0, "density": 1}})",
                        scene_path_);
  EXPECT_EQ(s.mesh_file, resolved(abs));
}

TEST_F(SceneTest, LoadSceneReadsFile) {
  std::ofstream(scene_path_) << minimal(R"("run": {"frames": 7})");
  Scene s = incise::load_scene(scene_path_);
  EXPECT_EQ(s.frames, 7);
  EXPECT_EQ(s.mesh_file, resolved(root_ / "meshes" / "m.vtu"));
}

// The bundled default scene loads as it ships (its real mesh included).
TEST_F(SceneTest, BundledBeamGravitySceneIsValid) {
  const std::string path = std::string(INCISE_SOURCE_DIR) + "/assets/scenes/beam_gravity.json";
  Scene s = incise::load_scene(path);
  EXPECT_TRUE(fs::exists(s.mesh_file)) << s.mesh_file;
  EXPECT_EQ(s.order, 2);
  EXPECT_EQ(s.material.model, incise::MaterialModel::Corotated);
  ASSERT_EQ(s.fixed.size(), 1u);
  EXPECT_NEAR(s.dt, 1.0 / 30.0, 1e-12);
}

// --- file-level errors -------------------------------------------------------

TEST_F(SceneTest, MissingSceneFile) {
  const std::string path = (root_ / "no_such.json").string();
  try {
    incise::load_scene(path);
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), path + ": cannot open scene file: No such file or directory");
  }
}

TEST_F(SceneTest, InvalidJsonNamesFileAndPosition) {
  std::string msg = error_of("{\"mesh\": {\"file\": \"a\"},\n \"material\" 3}");
  EXPECT_EQ(msg.rfind(scene_path_ + ": invalid JSON at byte ", 0), 0u) << msg;
  EXPECT_NE(msg.find("line 2"), std::string::npos) << msg;
}

TEST_F(SceneTest, NumberTooLargeRejected) {
  expect_error_contains(with_material(R"({"young": 1e999, "poisson": 0.3, "density": 1})"),
                        "invalid JSON");
}

TEST_F(SceneTest, TopLevelNotObject) {
  expect_error("[1, 2]", "the scene must be a JSON object, got array [1,2]");
}

// Issue 24: 100,000 nested arrays overflowed the stack while the error
// message dumped them; the depth is checked before anything recurses.
TEST_F(SceneTest, DeepNestingRejectedBeforeParsing) {
  const int n = 100000;
  EXPECT_EQ(error_of(std::string(n, '[') + std::string(n, ']')), scene_path_ + ":1: nested deeper than 64 levels of [ and {");
  // inside the scene's object (one level), on its fourth line; brackets in strings do not count
  const std::string deep = std::string(64, '[') + std::string(64, ']');
  const std::string shallow = std::string(63, '[') + std::string(63, ']');
  EXPECT_EQ(error_of(minimal("\n\"gravity\": \"[[[[[[\",\n \"x\": " + deep)),
            scene_path_ + ":4: nested deeper than 64 levels of [ and {");
  expect_error_contains(minimal("\"x\": " + shallow), "x: unknown key");
}

TEST_F(SceneTest, DuplicateKeyRejected) {
  expect_error_contains(
      with_material(R"({"young": 1, "young": 2, "poisson": 0.3, "density": 1})"),
      "duplicate key \"young\"");
}

// --- mesh ----------------------------------------------------------------------

TEST_F(SceneTest, MissingMeshFile) {
  expect_error(R"({"mesh": {"order": 2}, "material": {"young": 1, "poisson": 0.3, "density": 1}})",
               "mesh.file: required key is missing (expected a mesh file path string)");
}

// A NUL inside a path ended it where the file system reads it:
// "m.vtu\u0000.x" read m.vtu, and an output.dir with one failed with an
// error that named only the cut-off path.
TEST_F(SceneTest, AStringWithANulCharacterIsRefusedNamingItsField) {
  expect_error(R"({"mesh": {"file": "../meshes/m.vtu\u0000.x"}, "material": {"young": 1, "poisson": 0.3, "density": 1}})",
               "mesh.file must not contain a NUL character (\\u0000), got \"../meshes/m.vtu\\u0000.x\"");
  expect_error_contains(minimal(R"("output": {"dir": "out\u0000x"})"), "output.dir must not contain a NUL character");
}

TEST_F(SceneTest, MissingMeshSection) {
  expect_error(R"({"material": {"young": 1, "poisson": 0.3, "density": 1}})",
               "mesh: required key is missing (expected an object with file and order)");
}

TEST_F(SceneTest, MeshFileNotFound) {
  expect_error(R"({"mesh": {"file": "../meshes/nope.vtu"},
                  "material": {"young": 1, "poisson": 0.3, "density": 1}})",
               "mesh.file: file not found: " + resolved(root_ / "meshes" / "nope.vtu"));
}

TEST_F(SceneTest, MeshOrderMustBeOneOrTwo) {
  expect_error(R"({"mesh": {"file": "../meshes/m.vtu", "order": 3},
                  "material": {"young": 1, "poisson": 0.3, "density": 1}})",
               "mesh.order must be 1 or 2, got 3");
}

// --- material ------------------------------------------------------------------

TEST_F(SceneTest, PoissonHalfRejected) {
  expect_error(with_material(R"({"young": 3000, "poisson": 0.5, "density": 1000})"),
               "material.poisson must be in (-1, 0.5), got 0.5");
}

TEST_F(SceneTest, PoissonMinusOneRejected) {
  expect_error(with_material(R"({"young": 3000, "poisson": -1, "density": 1000})"),
               "material.poisson must be in (-1, 0.5), got -1");
}

TEST_F(SceneTest, NegativeYoungRejected) {
  expect_error(with_material(R"({"young": -5, "poisson": 0.3, "density": 1000})"),
               "material.young must be > 0, got -5");
}

TEST_F(SceneTest, ZeroDensityRejected) {
  expect_error(with_material(R"({"young": 5, "poisson": 0.3, "density": 0})"),
               "material.density must be > 0, got 0");
}

TEST_F(SceneTest, MissingYoung) {
  expect_error(with_material(R"({"poisson": 0.3, "density": 1000})"),
               "material.young: required key is missing (expected a number > 0)");
}

TEST_F(SceneTest, StringWhereNumberExpected) {
  expect_error(with_material(R"({"young": "3000", "poisson": 0.3, "density": 1000})"),
               "material.young must be a number, got string \"3000\"");
}

TEST_F(SceneTest, NullWhereNumberExpected) {
  expect_error(with_material(R"({"young": 1, "poisson": null, "density": 1000})"),
               "material.poisson must be a number, got null");
}

TEST_F(SceneTest, NegativeRayleighRejected) {
  expect_error(with_material(
                   R"({"young": 1, "poisson": 0.3, "density": 1, "rayleigh": {"mass": -0.1}})"),
               "material.rayleigh.mass must be >= 0, got -0.1");
}

TEST_F(SceneTest, BadEnumListsAllowedValues) {
  expect_error(
      with_material(R"({"model": "neohookean", "young": 1, "poisson": 0.3, "density": 1})"),
      "material.model must be one of \"linear\", \"corotated\", got \"neohookean\"");
  expect_error(
      with_material(R"({"rotation": "polar", "young": 1, "poisson": 0.3, "density": 1})"),
      "material.rotation must be one of \"per_point\", \"single\", got \"polar\"");
  expect_error(minimal(R"("mass": "diagonal")"),
               "mass must be one of \"lumped\", \"consistent\", got \"diagonal\"");
}

TEST_F(SceneTest, SolverPolicyListsAllowedValues) {
  expect_error(minimal(R"("solver": {"policy": "cg"})"),
               "solver.policy must be one of \"exact\", \"lagged\", \"warped\", \"warped_cg\", got \"cg\"");
}

TEST_F(SceneTest, SolverSettingsParsed) {
  Scene s = parse_scene(minimal(R"("solver": {"policy": "lagged", "refresh_every": 4, "background": true,
      "tolerance": 1e-7, "max_iterations": 30, "threads": 1, "factorization": "simplicial", "ordering": "metis"})"),
                        scene_path_);
  EXPECT_EQ(s.solver.policy, incise::SolverPolicy::Lagged);
  EXPECT_EQ(s.solver.refresh_every, 4);
  EXPECT_TRUE(s.solver.background);
  EXPECT_DOUBLE_EQ(s.solver.tolerance, 1e-7);
  EXPECT_EQ(s.solver.max_iterations, 30);
  EXPECT_EQ(s.runtime.threads, 1);
  EXPECT_EQ(s.solver.factor, incise::FactorMethod::Simplicial);
  EXPECT_EQ(s.solver.ordering, incise::OrderingMethod::Metis);
  Scene w = parse_scene(minimal(R"("solver": {"policy": "warped_cg", "tolerance": 1e-3})"), scene_path_);
  EXPECT_EQ(w.solver.policy, incise::SolverPolicy::WarpedCG);
  EXPECT_EQ(w.runtime.threads, 2);
}

TEST_F(SceneTest, SolverSettingsChecked) {
  expect_error(minimal(R"("solver": {"policy": "lagged", "refresh_every": 0})"),
               "solver.refresh_every must be an integer >= 1, got 0");
  expect_error(minimal(R"("solver": {"policy": "lagged", "tolerance": 1.5})"),
               "solver.tolerance must be in (0, 1), got 1.5");
  expect_error(minimal(R"("solver": {"policy": "lagged", "tolerance": 0})"), "solver.tolerance must be > 0, got 0");
  expect_error(minimal(R"("solver": {"policy": "lagged", "background": 1})"),
               "solver.background must be a boolean (true or false), got number 1");
  expect_error(minimal(R"("solver": {"threads": 0})"), "solver.threads must be an integer >= 1, got 0");
  expect_error(minimal(R"("solver": {"threads": 65})"), "solver.threads must be an integer in [1, 64], got 65");
  expect_error(minimal(R"("solver": {"ordering": "nesdis"})"),
               "solver.ordering must be one of \"auto\", \"amd\", \"metis\", got \"nesdis\"");
  expect_error(minimal(R"("solver": {"factorization": "dense"})"),
               "solver.factorization must be one of \"auto\", \"supernodal\", \"simplicial\", got \"dense\"");
  expect_error(minimal(R"("solver": {"policy": "exact", "tolerance": 1e-6})"),
               "solver.tolerance: only used by the iterative policies \"lagged\" and \"warped_cg\"; "
               "solver.policy is \"exact\"");
  expect_error(minimal(R"("solver": {"policy": "warped", "refresh_every": 3})"),
               "solver.refresh_every: only used by solver.policy \"lagged\"; solver.policy is \"warped\"");
  expect_error_contains(minimal(R"("solver": {"polcy": "exact"})"), "did you mean \"policy\"?");
}

// --- unknown keys and types ----------------------------------------------------

TEST_F(SceneTest, UnknownTopLevelKey) {
  expect_error(minimal(R"("materal": {})"),
               "materal: unknown key; allowed: mesh, material, mass, gravity, fixed, "
               "prescribed, integrator, solver, static, run, output, cuts, cut_front, cut_stabilization, render, instruments, contact, "
               "haptics, initial; did you mean "
               "\"material\"?");
}

TEST_F(SceneTest, CutStabilizationIsAWeightFromZeroToOne) {
  EXPECT_DOUBLE_EQ(parse_scene(minimal(), scene_path_).cut_stabilization, 0.1);
  EXPECT_DOUBLE_EQ(parse_scene(minimal(R"("cut_stabilization": 0)"), scene_path_).cut_stabilization, 0.0);
  expect_error(minimal(R"("cut_stabilization": 1.5)"),
               "cut_stabilization must be in [0, 1] (the weight of a small cut piece's field over its element; 0 = off), "
               "got 1.5");
  expect_error_contains(minimal(R"("cut_stabilization": -0.1)"), "cut_stabilization");
}

TEST_F(SceneTest, InitialIsRestOrStatic) {
  EXPECT_FALSE(parse_scene(minimal(""), scene_path_).initial_static);
  EXPECT_FALSE(parse_scene(minimal(R"("initial": "rest")"), scene_path_).initial_static);
  EXPECT_TRUE(parse_scene(minimal(R"("initial": "static")"), scene_path_).initial_static);
  expect_error_contains(minimal(R"("initial": "equilibrium")"), "initial must be one of \"rest\", \"static\"");
}

TEST_F(SceneTest, UnknownNestedKey) {
  expect_error_contains(with_material(R"({"young": 1, "poisson": 0.3, "density": 1, "yung": 2})"),
                        "material.yung: unknown key; allowed: model, rotation, young, poisson, "
                        "density, rayleigh");
  expect_error_contains(minimal(R"("integrator": {"dt": 0.01, "substeps": 2})"),
                        "integrator.substeps: unknown key; allowed: dt, newton_iterations");
}

TEST_F(SceneTest, WrongTypeForSection) {
  expect_error(minimal(R"("integrator": [0.01])"),
               "integrator must be an object, got array [0.01]");
  expect_error(minimal(R"("output": {"vtu": "yes"})"),
               "output.vtu must be a boolean (true or false), got string \"yes\"");
  expect_error(minimal(R"("fixed": {"box": []})"),
               "fixed must be an array, got object {\"box\":[]}");
}

TEST_F(SceneTest, GravityNeedsThreeNumbers) {
  expect_error(minimal(R"("gravity": [0, -9.81])"),
               "gravity must be an array of 3 numbers [x, y, z], got array of 2 values");
  expect_error(minimal(R"("gravity": [0, 0, "g"])"),
               "gravity[2] must be a number, got string \"g\"");
}

// --- regions -------------------------------------------------------------------

TEST_F(SceneTest, BoxMinGreaterThanMax) {
  expect_error(minimal(R"("fixed": [{"nodes": [1]}, {"box": [[0, 0, 1], [1, 1, 0]]}])"),
               "fixed[1].box: min must be <= max in each component; got z min 1 > max 0");
}

TEST_F(SceneTest, BoxWrongShape) {
  expect_error(minimal(R"("fixed": [{"box": [[0, 0, 0]]}])"),
               "fixed[0].box must be [[xmin, ymin, zmin], [xmax, ymax, zmax]], got array of "
               "1 values");
  expect_error(minimal(R"("fixed": [{"nodes": [1]}, {"box": [[0, 0, 0], [1, 1, true]]}])"),
               "fixed[1].box[1][2] must be a number, got boolean true");
}

TEST_F(SceneTest, PlaneNormalZero) {
  expect_error(minimal(R"("fixed": [{"plane": {"point": [0, 0, 0], "normal": [0, 0, 0]}}])"),
               "fixed[0].plane.normal must be a nonzero vector, got [0,0,0]");
}

TEST_F(SceneTest, PlaneMissingPoint) {
  expect_error(minimal(R"("fixed": [{"plane": {"normal": [1, 0, 0]}}])"),
               "fixed[0].plane.point: required key is missing (expected [x, y, z])");
}

TEST_F(SceneTest, NodesMustBeNonNegativeIntegers) {
  expect_error(minimal(R"("fixed": [{"nodes": [0, -3]}])"),
               "fixed[0].nodes[1] must be a non-negative node id (0-based), got -3");
  expect_error(minimal(R"("fixed": [{"nodes": [0, 1.5]}])"),
               "fixed[0].nodes[1] must be an integer, got 1.5");
  expect_error(minimal(R"("fixed": [{"nodes": []}])"),
               "fixed[0].nodes must list at least one node id, got []");
}

TEST_F(SceneTest, RegionNeedsExactlyOneKind) {
  expect_error(minimal(R"("fixed": [{}])"),
               "fixed[0]: needs exactly one of box, plane, nodes; got none");
  expect_error(minimal(R"("fixed": [{"nodes": [1], "box": [[0,0,0],[1,1,1]]}])"),
               "fixed[0]: needs exactly one of box, plane, nodes; got box and nodes");
  expect_error(minimal(R"("fixed": [{"nodes": [1], "displacement": {"x": 1}}])"),
               "fixed[0].displacement: unknown key; allowed: box, plane, nodes");
}

TEST_F(SceneTest, PrescribedNeedsAComponent) {
  expect_error(minimal(R"("prescribed": [{"nodes": [1], "displacement": {}}])"),
               "prescribed[0].displacement: needs at least one of x, y, z (an absent "
               "component stays free), got {}");
  expect_error(minimal(R"("prescribed": [{"nodes": [1]}])"),
               "prescribed[0].displacement: required key is missing (expected an object with "
               "x, y and/or z)");
  expect_error(minimal(R"("prescribed": [{"nodes": [1], "displacement": {"w": 1}}])"),
               "prescribed[0].displacement.w: unknown key; allowed: x, y, z");
}

TEST_F(SceneTest, PrescribedNegativeRamp) {
  expect_error(minimal(R"("prescribed": [{"nodes": [1], "displacement": {"x": 1}, "ramp": -1}])"),
               "prescribed[0].ramp must be >= 0, got -1");
}

// --- integrator, static, run, output --------------------------------------------

TEST_F(SceneTest, NewtonIterationsZero) {
  expect_error(minimal(R"("integrator": {"newton_iterations": 0})"),
               "integrator.newton_iterations must be an integer >= 1, got 0");
}

TEST_F(SceneTest, DtMustBePositiveAndAtMostOne) {
  expect_error(minimal(R"("integrator": {"dt": 0})"),
               "integrator.dt must be in (0, 1] seconds, got 0");
  expect_error(minimal(R"("integrator": {"dt": -0.01})"),
               "integrator.dt must be in (0, 1] seconds, got -0.01");
  expect_error(minimal(R"("integrator": {"dt": 2})"),
               "integrator.dt must be in (0, 1] seconds, got 2");
}

TEST_F(SceneTest, StaticSettingsChecked) {
  expect_error(minimal(R"("static": {"tolerance": 0})"), "static.tolerance must be > 0, got 0");
  expect_error(minimal(R"("static": {"max_iterations": 0})"),
               "static.max_iterations must be an integer >= 1, got 0");
}

TEST_F(SceneTest, RunAndOutputChecked) {
  expect_error(minimal(R"("run": {"frames": 0})"), "run.frames must be an integer >= 1, got 0");
  expect_error(minimal(R"("output": {"every": 0})"),
               "output.every must be an integer >= 1, got 0");
  expect_error(minimal(R"("output": {"dir": ""})"),
               "output.dir must be a non-empty string, got \"\"");
}

TEST_F(SceneTest, CutsParseWithDefaultsAndResolvedFiles) {
  std::ofstream(root_ / "meshes" / "cut.obj") << "v 0 0 0\n";
  const Scene s = parse_scene(minimal(R"("cuts": [
      {"type": "plane", "point": [1, 0, 0], "normal": [2, 0, 0]},
      {"type": "polygon", "points": [[0,0,0],[1,0,0],[1,1,0]], "at_time": 0.5},
      {"type": "mesh", "file": "../meshes/cut.obj"},
      {"type": "swept", "edge_start": [[0,0,1],[0,1,1]], "edge_end": [[0,0,0],[0,1,0]], "duration": 2}])"),
                              scene_path_);
  ASSERT_EQ(s.cuts.size(), 4u);
  EXPECT_EQ(s.cuts[0].type, incise::CutSpec::Type::Plane);
  EXPECT_DOUBLE_EQ(s.cuts[0].normal[0], 1.0);  // normalised
  EXPECT_DOUBLE_EQ(s.cuts[1].at_time, 0.5);
  EXPECT_EQ(s.cuts[2].file, resolved(root_ / "meshes" / "cut.obj"));
  EXPECT_DOUBLE_EQ(s.cuts[3].duration, 2.0);
  EXPECT_EQ(s.cuts[3].json_path, "cuts[3]");
}

TEST_F(SceneTest, CutErrorsNameThePathAndWhatIsAllowed) {
  expect_error(minimal(R"("cuts": [{"type": "knife"}])"),
               R"(cuts[0].type must be one of "plane", "polygon", "mesh", "swept", got "knife")");
  expect_error(minimal(R"("cuts": [{"type": "plane", "point": [0,0,0], "normal": [0,0,0]}])"),
               "cuts[0].normal must be a nonzero vector, got [0,0,0]");
  expect_error(minimal(R"("cuts": [{"type": "polygon", "points": [[0,0,0],[1,0,0]]}])"),
               "cuts[0].points must list at least 3 points, got 2");
  expect_error_contains(minimal(R"("cuts": [{"type": "mesh", "file": "nope.obj"}])"), "cuts[0].file: file not found:");
  expect_error(minimal(R"("cuts": [{"type": "plane", "point": [0,0,0], "normal": [1,0,0], "at_time": -1}])"),
               "cuts[0].at_time must be >= 0, got -1");
  expect_error_contains(minimal(R"("cuts": [{"type": "swept", "edge_start": [[0,0,0]], "edge_end": [[0,0,0],[1,1,1]]}])"),
                        "cuts[0].edge_start must be two points");
  expect_error_contains(minimal(R"("cuts": [{"type": "plane", "point": [0,0,0], "normal": [1,0,0], "pointt": 1}])"),
                        "cuts[0].pointt: unknown key");
}

// --- instruments and contact ------------------------------------------------------

TEST_F(SceneTest, InstrumentsParseWithDefaults) {
  std::ofstream(root_ / "scenes" / "cut.csv") << "t,x,y,z,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n";
  const Scene s = parse_scene(minimal(R"("instruments": [
      {"type": "probe", "radius": 0.01},
      {"type": "probe", "name": "tip", "radius": 0.02, "length": 0.1, "contact": false,
       "pose": {"position": [1, 2, 3], "orientation": [0, 0, 0, 1.0000002]}},
      {"type": "scalpel", "blade": [0.04, 0.001, 0.01], "trajectory": "cut.csv"},
      {"type": "scalpel", "blade": [0.04, 0.001, 0.01], "edge": [[0, 0, 0], [0, 0, 0.01]], "contact": false},
      {"type": "grasper", "jaw_size": [0.01, 0.002, 0.03], "opening": 0.02},
      {"type": "grasper", "jaw_size": [0.01, 0.002, 0.03], "opening": 0.02, "jaw": 1, "grasp_at": 1}])"),
                              scene_path_);
  ASSERT_EQ(s.instruments.size(), 6u);
  const auto& probe = s.instruments[0];
  EXPECT_EQ(probe.kind, incise::InstrumentSpec::Kind::Probe);
  EXPECT_EQ(probe.name, "instruments[0]");
  EXPECT_EQ(probe.json_path, "instruments[0]");
  EXPECT_EQ(probe.radius, 0.01);
  EXPECT_EQ(probe.length, 0.0);
  EXPECT_TRUE(probe.contact);
  EXPECT_TRUE(probe.trajectory.empty());
  EXPECT_EQ(probe.position, (incise::Vec3{0, 0, 0}));
  EXPECT_EQ(probe.orientation, (std::array<double, 4>{1, 0, 0, 0}));
  const auto& tip = s.instruments[1];
  EXPECT_EQ(tip.name, "tip");
  EXPECT_EQ(tip.length, 0.1);
  EXPECT_FALSE(tip.contact);
  EXPECT_EQ(tip.position, (incise::Vec3{1, 2, 3}));
  EXPECT_EQ(tip.orientation, (std::array<double, 4>{0, 0, 0, 1}));  // normalised (norm 1 + 2e-7 accepted)
  const auto& scalpel = s.instruments[2];
  EXPECT_EQ(scalpel.kind, incise::InstrumentSpec::Kind::Scalpel);
  EXPECT_EQ(scalpel.trajectory, resolved(root_ / "scenes" / "cut.csv"));
  EXPECT_FALSE(scalpel.contact) << "a blade cuts, it does not push";
  EXPECT_EQ(scalpel.edge[0], (incise::Vec3{-0.02, 0, 0})) << "default: the blade's lower edge";
  EXPECT_EQ(scalpel.edge[1], (incise::Vec3{0.02, 0, 0}));
  EXPECT_EQ(s.instruments[3].edge[1], (incise::Vec3{0, 0, 0.01}));
  const auto& grasper = s.instruments[4];
  EXPECT_EQ(grasper.kind, incise::InstrumentSpec::Kind::Grasper);
  EXPECT_EQ(grasper.jaw_size, (incise::Vec3{0.01, 0.002, 0.03}));
  EXPECT_EQ(grasper.opening, 0.02);
  EXPECT_EQ(grasper.jaw, 0.0);
  EXPECT_EQ(grasper.grasp_at, 0.9);
  EXPECT_TRUE(grasper.contact);
  EXPECT_EQ(s.instruments[5].jaw, 1.0);
  EXPECT_EQ(s.instruments[5].grasp_at, 1.0);
  // No "contact" object: the defaults.
  EXPECT_EQ(s.contact.max_rows, 48);
  EXPECT_EQ(s.contact.friction, 0.0);
  EXPECT_EQ(s.contact.pgs_iterations, 200);
}

TEST_F(SceneTest, InstrumentErrorsNameThePathAndWhatIsAllowed) {
  expect_error(minimal(R"("instruments": {})"), "instruments must be an array, got object {}");
  expect_error(minimal(R"("instruments": [{"radius": 1}])"),
               R"(instruments[0].type: required key is missing (expected "probe", "scalpel" or "grasper"))");
  expect_error(minimal(R"("instruments": [{"type": "forceps"}])"),
               R"(instruments[0].type must be one of "probe", "scalpel", "grasper", got "forceps")");
  expect_error(minimal(R"("instruments": [{"type": "probe"}])"),
               "instruments[0].radius: required key is missing (expected a number > 0)");
  expect_error(minimal(R"("instruments": [{"type": "probe", "radius": 0}])"), "instruments[0].radius must be > 0, got 0");
  expect_error(minimal(R"("instruments": [{"type": "probe", "radius": 1, "length": -1}])"),
               "instruments[0].length must be >= 0, got -1");
  expect_error(minimal(R"("instruments": [{"type": "probe", "radius": 1, "blade": [1, 1, 1]}])"),
               "instruments[0].blade: unknown key; allowed: type, name, trajectory, pose, contact, radius, length");
  expect_error(minimal(R"("instruments": [{"type": "scalpel", "blade": [1, 1, 1], "jaw": 0.5}])"),
               "instruments[0].jaw: unknown key; allowed: type, name, trajectory, pose, contact, blade, edge");
  expect_error(minimal(R"("instruments": [{"type": "scalpel", "blade": [1, 0, 1]}])"), "instruments[0].blade[1] must be > 0, got 0");
  expect_error(minimal(R"("instruments": [{"type": "scalpel", "blade": [1, 1]}])"),
               "instruments[0].blade must be an array of 3 numbers [x, y, z], got array of 2 values");
  expect_error(minimal(R"("instruments": [{"type": "scalpel", "blade": [1, 1, 1], "edge": [[1, 0, 0], [1, 0, 0]]}])"),
               "instruments[0].edge must have nonzero length (two distinct points), got [[1,0,0],[1,0,0]]");
  expect_error(minimal(R"("instruments": [{"type": "scalpel", "blade": [1, 1, 1], "edge": [[1, 0, 0]]}])"),
               "instruments[0].edge must be two points [[x, y, z], [x, y, z]], got array [[1,0,0]]");
  expect_error(minimal(R"("instruments": [{"type": "scalpel", "blade": [1, 1, 1], "contact": true}])"),
               "instruments[0].contact: a scalpel's blade cuts rather than pushes, so contact must be false (or absent), got true");
  expect_error(minimal(R"("instruments": [{"type": "grasper", "opening": 1}])"),
               "instruments[0].jaw_size: required key is missing (expected [W, T, J], each > 0)");
  expect_error(minimal(R"("instruments": [{"type": "grasper", "jaw_size": [1, 1, 1]}])"),
               "instruments[0].opening: required key is missing (expected a number > 0)");
  expect_error(minimal(R"("instruments": [{"type": "grasper", "jaw_size": [1, 1, 1], "opening": 1, "jaw": 1.5}])"),
               "instruments[0].jaw must be in [0, 1] (0 open .. 1 closed), got 1.5");
  expect_error(minimal(R"("instruments": [{"type": "grasper", "jaw_size": [1, 1, 1], "opening": 1, "grasp_at": 0}])"),
               "instruments[0].grasp_at must be in (0, 1], got 0");
  expect_error(minimal(R"("instruments": [{"type": "probe", "radius": 1, "contact": 1}])"),
               "instruments[0].contact must be a boolean (true or false), got number 1");
  expect_error(minimal(R"("instruments": [{"type": "probe", "radius": 1, "name": ""}])"),
               "instruments[0].name must be a non-empty string, got \"\"");
}

TEST_F(SceneTest, InstrumentPosesAndTrajectoriesChecked) {
  expect_error(minimal(R"("instruments": [{"type": "probe", "radius": 1, "pose": {"orientation": [1, 0, 0, 0.1]}}])"),
               "instruments[0].pose.orientation must be a unit quaternion [w, x, y, z] (norm 1 within 1e-3), got norm 1.004987562");
  expect_error(minimal(R"("instruments": [{"type": "probe", "radius": 1, "pose": {"orientation": [0, 0, 0, 0]}}])"),
               "instruments[0].pose.orientation must be a unit quaternion [w, x, y, z] (norm 1 within 1e-3), got norm 0");
  expect_error(minimal(R"("instruments": [{"type": "probe", "radius": 1, "pose": {"orientation": [1, 0, 0]}}])"),
               "instruments[0].pose.orientation must be a unit quaternion [w, x, y, z], got array of 3 values");
  expect_error(minimal(R"("instruments": [{"type": "probe", "radius": 1, "pose": {"orientation": [1, 0, 0, "nan"]}}])"),
               "instruments[0].pose.orientation[3] must be a number, got string \"nan\"");
  expect_error(minimal(R"("instruments": [{"type": "probe", "radius": 1, "pose": {"rotation": [1, 0, 0, 0]}}])"),
               "instruments[0].pose.rotation: unknown key; allowed: position, orientation");
  expect_error(minimal(R"("instruments": [{"type": "probe", "radius": 1, "trajectory": "nope.csv"}])"),
               "instruments[0].trajectory: file not found: " + resolved(root_ / "scenes" / "nope.csv"));
  expect_error(minimal(R"("instruments": [{"type": "probe", "radius": 1, "trajectory": "../meshes"}])"),
               "instruments[0].trajectory: is not a regular file: " + resolved(root_ / "meshes"));
  std::ofstream(root_ / "scenes" / "t.csv") << "t,x,y,z,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n";
  expect_error(minimal(R"("instruments": [{"type": "probe", "radius": 1, "trajectory": "t.csv", "pose": {}}])"),
               "instruments[0].pose: give either pose or trajectory (the trajectory sets the pose of every frame), not both");
}

TEST_F(SceneTest, ContactSettingsParsedAndChecked) {
  const Scene s = parse_scene(
      minimal(R"("contact": {"max_rows": 10, "friction": 0.3, "pgs_iterations": 50, "refine_rounds": 3})"), scene_path_);
  EXPECT_EQ(s.contact.max_rows, 10);
  EXPECT_EQ(s.contact.friction, 0.3);
  EXPECT_EQ(s.contact.pgs_iterations, 50);
  EXPECT_EQ(s.contact.refine_rounds, 3);
  EXPECT_EQ(parse_scene(minimal(R"("contact": {})"), scene_path_).contact.refine_rounds, 0);
  EXPECT_EQ(s.contact.rows, ContactSettings::Rows::Face) << "the default";
  EXPECT_EQ(s.contact.compliance_reuse, 0.1) << "the default";
  EXPECT_EQ(parse_scene(minimal(R"("contact": {"compliance_reuse": 0})"), scene_path_).contact.compliance_reuse, 0.0);
  expect_error(minimal(R"("contact": {"compliance_reuse": 1.5})"), "contact.compliance_reuse must be in [0, 1], got 1.5");
  expect_error(minimal(R"("contact": {"compliance_reuse": -0.1})"), "contact.compliance_reuse must be >= 0, got -0.1");
  EXPECT_EQ(parse_scene(minimal(R"("contact": {"rows": "triangle"})"), scene_path_).contact.rows,
            ContactSettings::Rows::Triangle);
  EXPECT_EQ(parse_scene(minimal(R"("contact": {"rows": "face_deepest"})"), scene_path_).contact.rows,
            ContactSettings::Rows::FaceDeepest);
  expect_error(minimal(R"("contact": {"rows": "node"})"),
               "contact.rows must be one of \"face\", \"face_deepest\", \"triangle\", got \"node\"");
  expect_error(minimal(R"("contact": {"refine_rounds": 21})"), "contact.refine_rounds must be an integer in [0, 20], got 21");
  expect_error(minimal(R"("contact": {"refine_rounds": -1})"), "contact.refine_rounds must be an integer >= 0, got -1");
  expect_error(minimal(R"("contact": {"max_rows": 0})"), "contact.max_rows must be an integer >= 1, got 0");
  expect_error(minimal(R"("contact": {"max_rows": 2.5})"), "contact.max_rows must be an integer, got 2.5");
  expect_error(minimal(R"("contact": {"friction": -0.1})"), "contact.friction must be >= 0, got -0.1");
  expect_error(minimal(R"("contact": {"pgs_iterations": 0})"), "contact.pgs_iterations must be an integer >= 1, got 0");
  expect_error(minimal(R"("contact": {"stiffness": 1})"),
               "contact.stiffness: unknown key; allowed: rows, max_rows, friction, pgs_iterations, refine_rounds, "
               "compliance_reuse, sweep, speculative");
  EXPECT_FALSE(s.contact.sweep) << "the default";
  EXPECT_FALSE(s.contact.speculative) << "the default";
  const Scene on = parse_scene(minimal(R"("contact": {"sweep": true, "speculative": true})"), scene_path_);
  EXPECT_TRUE(on.contact.sweep);
  EXPECT_TRUE(on.contact.speculative);
  expect_error(minimal(R"("contact": {"sweep": 1})"), "contact.sweep must be a boolean (true or false), got number 1");
  expect_error(minimal(R"("contact": [])"), "contact must be an object, got array []");
}

// --- render ---------------------------------------------------------------------

TEST_F(SceneTest, RenderDefaultsWhenAbsent) {
  Scene s = parse_scene(minimal(), scene_path_);
  EXPECT_EQ(s.render.width, 640);
  EXPECT_EQ(s.render.height, 480);
  EXPECT_EQ(s.render.subdivision, 2);
  EXPECT_FALSE(s.render.camera_position.has_value());
  EXPECT_FALSE(s.render.camera_target.has_value());
  EXPECT_FALSE(s.render.light_direction.has_value());
  EXPECT_DOUBLE_EQ(s.render.fov_deg, 30.0);
}

TEST_F(SceneTest, RenderFullSection) {
  Scene s = parse_scene(minimal(R"("render": {"width": 320, "height": 240, "subdivision": 4,
      "camera": {"position": [1, -5, 2], "target": [1, 0, 0], "up": [0, 0, 2], "fov_deg": 40},
      "light": {"direction": [0, 0, -3], "ambient": 0.1},
      "colors": {"tissue": [1, 0.5, 0.5], "interior": [0.5, 0, 0], "background": [0, 0, 0], "instrument": [0.2, 0.2, 0.2]}})"),
                        scene_path_);
  EXPECT_EQ(s.render.width, 320);
  EXPECT_EQ(s.render.height, 240);
  EXPECT_EQ(s.render.subdivision, 4);
  EXPECT_EQ(*s.render.camera_position, (incise::Vec3{1, -5, 2}));
  EXPECT_EQ(*s.render.camera_target, (incise::Vec3{1, 0, 0}));
  EXPECT_EQ(s.render.camera_up, (incise::Vec3{0, 0, 1}));  // normalised
  EXPECT_EQ(*s.render.light_direction, (incise::Vec3{0, 0, -1}));
  EXPECT_DOUBLE_EQ(s.render.ambient, 0.1);
  EXPECT_DOUBLE_EQ(s.render.fov_deg, 40.0);
  EXPECT_EQ(s.render.color_interior, (incise::Vec3{0.5, 0, 0}));
  EXPECT_EQ(s.render.color_background, (incise::Vec3{0, 0, 0}));
}

TEST_F(SceneTest, RenderErrorsNamePathAndAllowed) {
  expect_error(minimal(R"("render": {"width": 8})"), "render.width must be an integer in [16, 8192], got 8");
  expect_error(minimal(R"("render": {"subdivision": 1})"), "render.subdivision must be an integer in [2, 16], got 1");
  expect_error(minimal(R"("render": {"camera": {"fov_deg": 180}})"),
               "render.camera.fov_deg must be in (0, 180) degrees, got 180");
  expect_error(minimal(R"("render": {"camera": {"up": [0, 0, 0]}})"),
               "render.camera.up must be a nonzero vector, got [0,0,0]");
  expect_error(minimal(R"("render": {"camera": {"position": [0, 0, 5], "target": [0, 0, 0]}})"),
               "render.camera.up must not be parallel to the viewing direction target - position");
  expect_error(minimal(R"("render": {"camera": {"position": [1, 2, 3], "target": [1, 2, 3]}})"),
               "render.camera.target must differ from camera.position, got [1,2,3]");
  expect_error(minimal(R"("render": {"colors": {"tissue": [1, 2, 0]}})"),
               "render.colors.tissue[1] must be in [0, 1] (colours are [r, g, b] in [0, 1]), got 2");
  expect_error(minimal(R"("render": {"light": {"ambient": -0.5}})"), "render.light.ambient must be in [0, 1], got -0.5");
  expect_error(minimal(R"("render": {"colors": {"tisue": [1, 1, 1]}})"),
               "render.colors.tisue: unknown key; allowed: tissue, interior, background, instrument; did you mean "
               "\"tissue\"?");
  expect_error(minimal(R"("render": {"camera": {"position": "auto"}})"),
               "render.camera.position must be an array of 3 numbers [x, y, z], got string \"auto\"");
  expect_error(minimal(R"("render": [])"), "render must be an object, got array []");
}

TEST_F(SceneTest, AdaptiveNewtonKeys) {
  const Scene s = parse_scene(minimal(R"("integrator": {"newton_iterations": 2, "max_newton_iterations": 6, "rotation_tolerance": 0.05})"),
                              scene_path_);
  EXPECT_EQ(s.newton_iterations, 2);
  EXPECT_EQ(s.max_newton_iterations, 6);
  EXPECT_DOUBLE_EQ(s.rotation_tolerance, 0.05);
  expect_error(minimal(R"("integrator": {"rotation_tolerance": -1})"), "integrator.rotation_tolerance must be >= 0, got -1");
  expect_error(minimal(R"("integrator": {"max_newton_iterations": 0})"),
               "integrator.max_newton_iterations must be an integer >= 1, got 0");
}

TEST_F(SceneTest, NewtonStopOverTheBodyKeys) {
  const Scene d = parse_scene(minimal(R"("integrator": {})"), scene_path_);
  EXPECT_DOUBLE_EQ(d.rotation_fraction, 1e-4);
  EXPECT_DOUBLE_EQ(d.rotation_rms, 0.02);
  const Scene s = parse_scene(minimal(R"("integrator": {"rotation_fraction": 0, "rotation_rms": 0.005})"), scene_path_);
  EXPECT_DOUBLE_EQ(s.rotation_fraction, 0.0);
  EXPECT_DOUBLE_EQ(s.rotation_rms, 0.005);
  expect_error(minimal(R"("integrator": {"rotation_fraction": 1})"),
               "integrator.rotation_fraction must be in [0, 1) (a fraction of the body's volume; 0 = any point), got 1");
  expect_error(minimal(R"("integrator": {"rotation_rms": -0.1})"), "integrator.rotation_rms must be >= 0, got -0.1");
}

TEST_F(SceneTest, TangentReuseKey) {
  EXPECT_DOUBLE_EQ(parse_scene(minimal(R"("integrator": {})"), scene_path_).tangent_reuse, 0.0);
  EXPECT_DOUBLE_EQ(parse_scene(minimal(R"("integrator": {"tangent_reuse": 0.003})"), scene_path_).tangent_reuse, 0.003);
  expect_error(minimal(R"("integrator": {"tangent_reuse": 0.5})"),
               "integrator.tangent_reuse must be in [0, 0.5) (a change of the deformation gradient; 0 = off), got 0.5");
  expect_error(minimal(R"("integrator": {"tangent_reuse": -1})"), "integrator.tangent_reuse must be >= 0, got -1");
}

TEST_F(SceneTest, SubstitutionThreadsKey) {
  EXPECT_EQ(parse_scene(minimal(R"("solver": {"policy": "lagged"})"), scene_path_).runtime.substitution_threads, 1);
  EXPECT_EQ(parse_scene(minimal(R"("solver": {"substitution_threads": 2})"), scene_path_).runtime.substitution_threads, 2);
  expect_error(minimal(R"("solver": {"substitution_threads": 3})"), "solver.substitution_threads must be 1 or 2, got 3");
  expect_error(minimal(R"("solver": {"substitution_threads": 0})"),
               "solver.substitution_threads must be an integer >= 1, got 0");
}

TEST_F(SceneTest, FactorCopyKeyAndItsOlderSwitch) {
  using incise::FactorCopy;
  EXPECT_EQ(parse_scene(minimal(R"("solver": {"policy": "lagged"})"), scene_path_).solver.factor_copy, FactorCopy::Float);
  EXPECT_EQ(parse_scene(minimal(R"("solver": {"policy": "lagged", "factor_copy": "half"})"), scene_path_).solver.factor_copy,
            FactorCopy::Half);
  EXPECT_EQ(parse_scene(minimal(R"("solver": {"policy": "lagged", "factor_copy": "none"})"), scene_path_).solver.factor_copy,
            FactorCopy::None);
  EXPECT_EQ(parse_scene(minimal(R"("solver": {"policy": "lagged", "single_precision": false})"), scene_path_).solver.factor_copy,
            FactorCopy::None);
  EXPECT_EQ(parse_scene(minimal(R"("solver": {"policy": "lagged", "single_precision": true})"), scene_path_).solver.factor_copy,
            FactorCopy::Float);
  expect_error_contains(minimal(R"("solver": {"policy": "lagged", "factor_copy": "bfloat16"})"),
                        R"(solver.factor_copy must be one of "none", "float", "half")");
  expect_error(minimal(R"("solver": {"policy": "lagged", "factor_copy": "half", "single_precision": true})"),
               R"(solver.factor_copy: give either factor_copy or single_precision (the older switch between "float" and "none"), not both)");
  expect_error(minimal(R"("solver": {"factor_copy": "half"})"),
               R"(solver.factor_copy: only used by solver.policy "lagged"; solver.policy is "exact")");
}

TEST_F(SceneTest, InitialGuessKey) {
  EXPECT_TRUE(parse_scene(minimal(R"("solver": {"policy": "lagged"})"), scene_path_).solver.previous_guess);
  EXPECT_FALSE(parse_scene(minimal(R"("solver": {"policy": "warped_cg", "initial_guess": "zero"})"), scene_path_)
                   .solver.previous_guess);
  expect_error_contains(minimal(R"("solver": {"policy": "lagged", "initial_guess": "last"})"),
                        R"(solver.initial_guess must be one of "zero", "previous")");
  expect_error(minimal(R"("solver": {"initial_guess": "zero"})"),
               R"(solver.initial_guess: only used by the iterative policies "lagged" and "warped_cg"; solver.policy is "exact")");
}

TEST_F(SceneTest, AffinityKey) {
  EXPECT_FALSE(parse_scene(minimal(""), scene_path_).runtime.split_affinity);
  EXPECT_TRUE(parse_scene(minimal(R"("solver": {"affinity": "split"})"), scene_path_).runtime.split_affinity);
  EXPECT_TRUE(parse_scene(minimal(R"("solver": {"policy": "lagged", "affinity": "split"})"), scene_path_).runtime.split_affinity);
  expect_error_contains(minimal(R"("solver": {"affinity": "pinned"})"), R"(solver.affinity must be one of "none", "split")");
}

TEST_F(SceneTest, FactorPrecisionKey) {
  EXPECT_FALSE(parse_scene(minimal(R"("solver": {"policy": "lagged"})"), scene_path_).solver.single_factorization);
  EXPECT_TRUE(parse_scene(minimal(R"("solver": {"policy": "lagged", "factor_precision": "single"})"), scene_path_)
                  .solver.single_factorization);
  EXPECT_FALSE(parse_scene(minimal(R"("solver": {"policy": "lagged", "factor_precision": "double"})"), scene_path_)
                   .solver.single_factorization);
  expect_error_contains(minimal(R"("solver": {"policy": "lagged", "factor_precision": "half"})"),
                        R"(solver.factor_precision must be one of "double", "single")");
  EXPECT_TRUE(parse_scene(minimal(R"("solver": {"policy": "lagged", "factor_copy": "half", "factor_precision": "single"})"),
                          scene_path_)
                  .solver.single_factorization);
  expect_error(minimal(R"("solver": {"policy": "lagged", "factor_copy": "none", "factor_precision": "single"})"),
               R"(solver.factor_precision: "single" factors straight into the float copy, so solver.factor_copy must be "float" (the default) or "half", not "none")");
  expect_error(minimal(R"("solver": {"policy": "lagged", "factor_precision": "single", "factorization": "simplicial"})"),
               R"(solver.factor_precision: "single" factors supernodes; solver.factorization "simplicial" has none (use "supernodal" or "auto"))");
  expect_error(minimal(R"("solver": {"factor_precision": "single"})"),
               R"(solver.factor_precision: only used by solver.policy "lagged"; solver.policy is "exact")");
}

TEST_F(SceneTest, TangentNewmarkRescueAndLateFactorKeys) {
  Scene s = parse_scene(minimal(R"("integrator": {"tangent": "consistent", "newmark_gamma": 0.6})"), scene_path_);
  EXPECT_TRUE(s.consistent_tangent);
  EXPECT_DOUBLE_EQ(s.newmark_gamma, 0.6);
  EXPECT_DOUBLE_EQ(s.newmark_beta, 0.3025);  // (gamma + 1/2)^2 / 4
  s = parse_scene(minimal(R"("solver": {"policy": "lagged", "background": true, "rescue_after": 20, "late_factor": "skip"})"),
                  scene_path_);
  EXPECT_EQ(s.solver.rescue_after, 20);
  EXPECT_TRUE(s.solver.skip_late_factor);
  expect_error(minimal(R"("integrator": {"tangent": "exact"})"),
               "integrator.tangent must be one of \"frozen_rotation\", \"consistent\", got \"exact\"");
  EXPECT_TRUE(s.recovery_steps);  // the default: backward Euler after a severing cut or a capped Newton iteration
  EXPECT_FALSE(parse_scene(minimal(R"("integrator": {"recovery": "none"})"), scene_path_).recovery_steps);
  expect_error(minimal(R"("integrator": {"recovery": "bdf2"})"),
               "integrator.recovery must be one of \"none\", \"backward_euler\", got \"bdf2\"");
  expect_error(minimal(R"("integrator": {"newmark_gamma": 0.4})"),
               "integrator.newmark_gamma must be in [0.5, 1] (0.5 = no numerical damping), got 0.4");
  expect_error(minimal(R"("integrator": {"newmark_gamma": 0.6, "newmark_beta": 0.25})"),
               "integrator.newmark_beta must be in [newmark_gamma / 2, 1] (unconditionally stable), got 0.25");
  expect_error(minimal(R"("solver": {"rescue_after": 5})"),
               "solver.rescue_after: only used by solver.policy \"lagged\"; solver.policy is \"exact\"");
  expect_error(minimal(R"("solver": {"policy": "lagged", "rescue_after": -1})"),
               "solver.rescue_after must be an integer >= 0, got -1");
  expect_error_contains(minimal(R"("solver": {"policy": "lagged", "late_factor": "sometimes"})"),
                        "solver.late_factor must be one of \"wait\", \"skip\"");
  // Issue 20's knobs: the coarse level (lagged) and the frame budget (CG policies).
  s = parse_scene(minimal(R"("solver": {"policy": "lagged", "coarse": "corners", "frame_iterations": 8})"), scene_path_);
  EXPECT_TRUE(s.solver.coarse);
  EXPECT_EQ(s.solver.frame_iterations, 8);
  s = parse_scene(minimal(R"("solver": {"policy": "warped_cg", "frame_iterations": 3})"), scene_path_);
  EXPECT_EQ(s.solver.frame_iterations, 3);
  expect_error(minimal(R"("solver": {"policy": "warped_cg", "coarse": "corners"})"),
               "solver.coarse: only used by solver.policy \"lagged\"; solver.policy is \"warped_cg\"");
  expect_error(minimal(R"("solver": {"frame_iterations": 4})"),
               "solver.frame_iterations: only used by the iterative policies \"lagged\" and \"warped_cg\"; solver.policy is \"exact\"");
  expect_error(minimal(R"("solver": {"policy": "lagged", "frame_iterations": -2})"),
               "solver.frame_iterations must be an integer >= 0, got -2");
  expect_error_contains(minimal(R"("solver": {"policy": "lagged", "coarse": "aggregates"})"),
                        "solver.coarse must be one of \"none\", \"corners\"");
  // Issue 24: condensing the DOFs next to tiny cut pieces (lagged; a fraction in [0, 1)).
  EXPECT_EQ(parse_scene(minimal(R"("solver": {"policy": "lagged"})"), scene_path_).solver.condense_below, 0.05);
  s = parse_scene(minimal(R"("solver": {"policy": "lagged", "condense_below": 0})"), scene_path_);
  EXPECT_EQ(s.solver.condense_below, 0.0);
  expect_error(minimal(R"("solver": {"policy": "lagged", "condense_below": 1})"),
               "solver.condense_below must be in [0, 1), got 1");
  EXPECT_EQ(parse_scene(minimal(R"("solver": {"policy": "lagged"})"), scene_path_).solver.contact_patch, 0);
  EXPECT_EQ(parse_scene(minimal(R"("solver": {"policy": "lagged", "contact_patch": 2})"), scene_path_).solver.contact_patch, 2);
  expect_error(minimal(R"("solver": {"policy": "lagged", "contact_patch": 4})"),
               "solver.contact_patch must be an integer in [0, 3], got 4");
  expect_error(minimal(R"("solver": {"contact_patch": 1})"),
               "solver.contact_patch: only used by solver.policy \"lagged\"; solver.policy is \"exact\"");
  expect_error(minimal(R"("solver": {"condense_below": 0.1})"),
               "solver.condense_below: only used by solver.policy \"lagged\"; solver.policy is \"exact\"");
  // The lagged policy's two-valued string keys: default (true), the other
  // value (false), a bad value, and the key under another policy.
  struct Choice {
    const char* key;
    bool incise::SolverSettings::*field;
    const char* other;
    const char* allowed;
  };
  for (const Choice& c : {Choice{"patch", &incise::SolverSettings::multiplicative_patch, "additive", R"("additive", "multiplicative")"},
                          Choice{"cut_ordering", &incise::SolverSettings::carry_ordering, "search", R"("search", "carried")"}}) {
    const std::string key = c.key;
    EXPECT_TRUE(parse_scene(minimal(R"("solver": {"policy": "lagged"})"), scene_path_).solver.*c.field) << key;
    const std::string other = "\"" + key + "\": \"" + c.other + "\"";
    EXPECT_FALSE(parse_scene(minimal(R"("solver": {"policy": "lagged", )" + other + "}"), scene_path_).solver.*c.field)
        << key;
    expect_error_contains(minimal(R"("solver": {"policy": "lagged", ")" + key + R"(": "neither"})"),
                          "solver." + key + " must be one of " + c.allowed);
    expect_error(minimal(R"("solver": {)" + other + "}"),
                 "solver." + key + R"(: only used by solver.policy "lagged"; solver.policy is "exact")");
  }
  // background_priority is a run-time setting: it lands in Scene::runtime, not in the Model's solver.
  EXPECT_TRUE(parse_scene(minimal(R"("solver": {"policy": "lagged"})"), scene_path_).runtime.idle_background);
  EXPECT_FALSE(parse_scene(minimal(R"("solver": {"policy": "lagged", "background_priority": "normal"})"), scene_path_)
                   .runtime.idle_background);
  expect_error_contains(minimal(R"("solver": {"policy": "lagged", "background_priority": "neither"})"),
                        R"(solver.background_priority must be one of "normal", "idle")");
  expect_error(minimal(R"("solver": {"background_priority": "normal"})"),
               R"(solver.background_priority: only used by solver.policy "lagged"; solver.policy is "exact")");
}

// --- haptics -------------------------------------------------------------------

TEST_F(SceneTest, HapticsParseWithDefaults) {
  std::ofstream(root_ / "scenes" / "p.csv") << "t,x,y,z,qw,qx,qy,qz\n0,0,0,0,1,0,0,0\n";
  std::ofstream(root_ / "scenes" / "rec.csv") << "t,x,y,z,qw,qx,qy,qz,jaw,buttons\n0.001,0,0,0,1,0,0,0,0,0\n";
  const std::string tools = R"("instruments": [{"type": "probe", "radius": 0.01},
      {"type": "probe", "name": "tip", "radius": 0.01, "trajectory": "p.csv"}], )";
  Scene none = parse_scene(minimal(tools.substr(0, tools.size() - 2)), scene_path_);
  EXPECT_EQ(none.haptics.device, incise::HapticsSpec::Device::None) << "no key, no device";
  const Scene s = parse_scene(minimal(tools + R"("haptics": {"device": "scripted", "instrument": "tip"})"), scene_path_);
  EXPECT_EQ(s.haptics.device, incise::HapticsSpec::Device::Scripted);
  EXPECT_EQ(s.haptics.instrument, 1);
  EXPECT_EQ(s.haptics.trajectory, resolved(root_ / "scenes" / "p.csv")) << "the instrument's own trajectory";
  EXPECT_EQ(s.haptics.rate_hz, 1000.0);
  EXPECT_EQ(s.haptics.max_force, 3.3);
  EXPECT_EQ(s.haptics.stiffness, 1000.0);
  EXPECT_EQ(s.haptics.damping, 0.5);
  EXPECT_EQ(s.haptics.scale, 1.0);
  EXPECT_FALSE(s.haptics.center.has_value());
  EXPECT_TRUE(s.haptics.realtime);
  const Scene r = parse_scene(minimal(tools + R"("haptics": {"device": "replay", "stream": "rec.csv", "max_force": 8,
      "coupling": {"stiffness": 500, "damping": 0}, "guard": {"center": [0, 0, 0.1], "workspace_radius": 0.3,
      "max_speed": 1, "reacquire": 0.5}, "rate_hz": 2000, "realtime": false, "offset": [0, 0, 0.2], "scale": 2})"),
                              scene_path_);
  EXPECT_EQ(r.haptics.device, incise::HapticsSpec::Device::Replay);
  EXPECT_EQ(r.haptics.instrument, 0) << "default: the first instrument";
  EXPECT_EQ(r.haptics.stream, resolved(root_ / "scenes" / "rec.csv"));
  EXPECT_EQ(r.haptics.max_force, 8.0);
  EXPECT_EQ(r.haptics.stiffness, 500.0);
  EXPECT_EQ(r.haptics.damping, 0.0);
  EXPECT_EQ(*r.haptics.center, (incise::Vec3{0, 0, 0.1}));
  EXPECT_EQ(r.haptics.workspace_radius, 0.3);
  EXPECT_EQ(r.haptics.max_speed, 1.0);
  EXPECT_EQ(r.haptics.reacquire, 0.5);
  EXPECT_EQ(r.haptics.rate_hz, 2000.0);
  EXPECT_FALSE(r.haptics.realtime);
  EXPECT_EQ(r.haptics.offset, (incise::Vec3{0, 0, 0.2}));
  EXPECT_EQ(r.haptics.scale, 2.0);
  const Scene o = parse_scene(minimal(tools + R"("haptics": {"device": "openigtlink", "port": 0})"), scene_path_);
  EXPECT_EQ(o.haptics.device, incise::HapticsSpec::Device::OpenIGTLink);
  EXPECT_EQ(o.haptics.port, 0);
  EXPECT_EQ(o.haptics.scale, 0.001) << "trackers send millimetres";
}

TEST_F(SceneTest, HapticsErrorsNameTheKeyAndWhatIsAllowed) {
  const std::string probe = R"("instruments": [{"type": "probe", "name": "probe", "radius": 0.01}], )";
  expect_error(minimal(R"("haptics": {"device": "scripted"})"),
               "haptics: a haptic device drives an instrument, and the scene declares none (add one under \"instruments\")");
  expect_error(minimal(probe + R"("haptics": {})"),
               R"(haptics.device: required key is missing (expected "scripted", "replay" or "openigtlink"))");
  expect_error(minimal(probe + R"("haptics": {"device": "phantom"})"),
               R"(haptics.device must be one of "scripted", "replay", "openigtlink", got "phantom")");
  expect_error(minimal(probe + R"("haptics": {"device": "scripted"})"),
               "haptics.trajectory: required key is missing (a scripted device follows a keyframe CSV; instruments[0] has no "
               "trajectory to take)");
  expect_error(minimal(probe + R"("haptics": {"device": "scripted", "trajectory": "x.csv", "instrument": "knife"})"),
               R"(haptics.instrument must name an instrument ("probe"), got "knife")");
  expect_error(minimal(probe + R"("haptics": {"device": "replay"})"),
               "haptics.stream: required key is missing (expected a recorded device stream (CSV))");
  expect_error(minimal(probe + R"("haptics": {"device": "replay", "port": 1})"),
               "haptics.port: unknown key; allowed: device, instrument, rate_hz, max_force, scale, offset, coupling, guard, "
               "realtime, stream");
  expect_error(minimal(probe + R"("haptics": {"device": "openigtlink", "port": 70000})"),
               "haptics.port must be a TCP port in [0, 65535] (0: any free one), got 70000");
  expect_error(minimal(probe + R"("haptics": {"device": "openigtlink", "rate_hz": 50})"),
               "haptics.rate_hz must be in [100, 10000] Hz, got 50");
  expect_error(minimal(probe + R"("haptics": {"device": "openigtlink", "max_force": 0})"), "haptics.max_force must be > 0, got 0");
  expect_error(minimal(probe + R"("haptics": {"device": "openigtlink", "coupling": {"stiffness": -1}})"),
               "haptics.coupling.stiffness must be > 0, got -1");
  expect_error(minimal(probe + R"("haptics": {"device": "openigtlink", "guard": {"max_sped": 1}})"),
               "haptics.guard.max_sped: unknown key; allowed: center, workspace_radius, max_speed, max_turn, reacquire, "
               "glide_speed; did you mean \"max_speed\"?");
}
