// Issue 24, as a careless user or an attacker runs the command line: deep
// JSON, absurd or non-finite options, outputs that cannot be written or come
// from a failed run, numerical failures; each must end in a clear error and
// leave nothing half-written.
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "engine/util/error.h"
#include "tests/tools/cli_test_util.h"
#include "tests/tools/temp_dir_test.h"
#include "tools/frame_outputs.h"

namespace fs = std::filesystem;

namespace {

using incise::test::incise;
using incise::test::Result;

class CliErrors : public incise::test::TempDirTest {
 protected:
  // A corotated tet4 cantilever (L = 4, 1 x 1) fixed at x = 0, under gravity.
  void beam_scene(const std::string& material = R"("young": 1e5, "poisson": 0.3, "density": 1)",
                  const std::string& extra = "") const {
    ASSERT_EQ(incise("mesh beam --size 4 1 1 --cells 4 2 2 --out " + path("beam.vtu")).code, 0);
    write("scene.json", incise::test::beam_scene_json(1, R"("model": "corotated", )" + material, extra));
  }
  // Every file below the test's folder whose name contains `part`.
  std::vector<std::string> files_with(const std::string& part) const {
    std::vector<std::string> out;
    for (const auto& e : fs::recursive_directory_iterator(dir_))
      if (e.path().filename().string().find(part) != std::string::npos) out.push_back(e.path().string());
    return out;
  }
};

// A scene nested 100,000 arrays deep overflowed the stack while the error was
// formatted; now it is refused before it is parsed.
TEST_F(CliErrors, DeeplyNestedSceneIsAnError) {
  const int n = 100000;
  write("deep.json", std::string(n, '[') + std::string(n, ']'));
  const Result r = incise("run " + path("deep.json") + " --frames 1");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find(path("deep.json") + ":1: nested deeper than 64 levels of [ and {"), std::string::npos) << r.out;
  // the same through --set (one argument holds at most 128 KiB: 60,000 levels)
  beam_scene();
  const Result s = incise("run " + path("scene.json") + " --frames 1 --set 'material.young=" +
                          std::string(60000, '[') + std::string(60000, ']') + "'");
  EXPECT_EQ(s.code, 1) << s.out.substr(0, 400);
  EXPECT_NE(s.out.find("(120015 characters): the value is nested deeper than 64 levels of [ and {"), std::string::npos)
      << s.out.substr(0, 400);
}

// An output path that is a folder: a clear error, and no temporary file left
// beside it (bench --json, --trace; static --out).
TEST_F(CliErrors, OutputPathThatIsAFolderLeavesNoTemporaryFile) {
  beam_scene();
  fs::create_directories(path("taken"));
  write("p.csv", "1,0.5,0.5\n");
  for (const std::string& args : {"bench " + path("scene.json") + " --frames 2 --json " + path("taken"),
                                  "bench " + path("scene.json") + " --frames 2 --trace " + path("taken"),
                                  "static " + path("scene.json") + " --probe " + path("p.csv") + " --out " + path("taken")}) {
    const Result r = incise(args);
    EXPECT_EQ(r.code, 1) << args << "\n" << r.out;
    EXPECT_NE(r.out.find(path("taken") + ": cannot write: it is a directory"), std::string::npos) << args << "\n" << r.out;
    EXPECT_TRUE(files_with(".tmp").empty()) << args << ": " << files_with(".tmp").front();
  }
  // a file where an output folder should be made: an error, not an internal one
  write("afile", "");
  const Result r = incise("run " + path("scene.json") + " --frames 1 --out " + path("afile"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("incise: error: " + path("afile") + ": cannot create directories: Not a directory"), std::string::npos)
      << r.out;
  const Result rec = incise("run " + path("scene.json") + " --frames 1 --record " + path("taken"));
  EXPECT_EQ(rec.code, 1) << rec.out;
  EXPECT_NE(rec.out.find(path("taken") + ": cannot move the replay into place"), std::string::npos) << rec.out;
  EXPECT_TRUE(files_with(".tmp").empty()) << files_with(".tmp").front();
}

// NaN, inf, overflowing and absurd values of options are refused with the
// range allowed, before anything is allocated (--frames 1000000000 and mesh
// beam --cells 100000 100000 100000 ran out of memory: std::bad_alloc).
TEST_F(CliErrors, NonFiniteAndAbsurdOptionsAreRefusedWithTheRange) {
  beam_scene();
  const std::string scene = path("scene.json");
  const std::pair<std::string, std::string> cases[] = {
      {"run " + scene + " --frames 1000000000", "--frames: must be an integer from 1 to 1000000 (9.3 h at 30 Hz), got 1000000000"},
      {"run " + scene + " --frames 99999999999999999999", "--frames: must be an integer from 1 to 1000000"},
      {"run " + scene + " --frames nan", "--frames: must be an integer from 1 to 1000000"},
      {"run " + scene + " --pace nan", "--pace: must be 0 (back to back) or a rate from 0.001 to 100000 Hz, got nan"},
      {"run " + scene + " --pace inf", "--pace: must be 0 (back to back) or a rate from 0.001 to 100000 Hz, got inf"},
      {"run " + scene + " --pace 1e-300", "--pace: must be 0 (back to back) or a rate from 0.001 to 100000 Hz, got 1e-300"},
      {"bench " + scene + " --bandwidth-gbs 1e400", "--bandwidth-gbs: must be a finite number from 0.01 to 100000, got 1e400"},
      {"bench " + scene + " --warmup -1", "--warmup: must be an integer from 0 to 1000000"},
      {"replay " + scene + " --tolerance nan", "--tolerance: must be a finite number from 0 to 1000000, got nan"},
      {"render " + scene + " --frame 2147483648 --out x.png", "--frame: must be an integer from 0 to 1000000"},
      {"mesh beam --size nan 1 1 --cells 1 1 1 --out " + path("b.vtu"), "--size: must be a finite number from 1e-06 to 1000000, got nan"},
      {"mesh beam --size 1 inf 1 --cells 1 1 1 --out " + path("b.vtu"), "--size: must be a finite number from 1e-06 to 1000000, got inf"},
      {"mesh beam --size 1 1 1 --cells 100000 100000 100000 --out " + path("b.vtu"),
       "mesh beam: --cells 100000 100000 100000 makes 6e+15 tetrahedra (6 a cell), more than the 10000000 allowed"},
      {"mesh beam --size 1 1 1 --cells 1 1 3000000000 --out " + path("b.vtu"), "--cells: must be an integer from 1 to 1666666"},
      {"mesh tetrahedralize " + scene + " --size nan --out " + path("b.vtu"), "--size: must be a finite number from 1e-09 to 1000000000, got nan"},
      {"mesh tetrahedralize " + scene + " --size 1 --quality 0.5 --out " + path("b.vtu"), "--quality: must be a finite number from 1.1 to 10"},
      // options that did nothing without another, in silence
      {"static " + scene + " --out " + path("b.vtu"), "--out requires --probe"},
      {"run " + scene + " --frames 1 --haptics-dir " + path("h"), "--haptics-dir requires --haptics"},
      {"render " + scene + " --out " + path("x.jpg"), "--out: the image is written as PNG: the file must end in .png, got "},
  };
  for (const auto& [args, want] : cases) {
    const Result r = incise(args);
    EXPECT_NE(r.code, 0) << args;
    EXPECT_NE(r.out.find(want), std::string::npos) << args << "\n" << r.out;
  }
  EXPECT_FALSE(fs::exists(path("b.vtu")));
  // the scene's run.frames has the same bound
  const Result r = incise("run " + scene + " --set run.frames=1000000000");
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("--set run.frames=1000000000: run.frames must be at most 1000000 (9.3 h at 30 Hz), got 1000000000"),
            std::string::npos) << r.out;
}

// A run that fails (here in its first step: a density whose mass term
// overflows) removes the series it started: frame 0's .vtu and the .pvd
// listing it were left behind. The error names the node and the value.
TEST_F(CliErrors, FailedRunRemovesItsOutputsAndNamesTheInput) {
  beam_scene(R"("young": 1e5, "poisson": 0.3, "density": 1e300)");
  const Result r = incise("run " + path("scene.json") + " --frames 3 --out " + path("out"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("incise: error: step: non-finite residual at frame 0 (t = 0) at DOF "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("; at node "), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("; check material.density = 1e+300 (extreme: materials are 1 to 2e4 kg/m^3), material.young = "
                       "100000, material.poisson = 0.3, integrator.dt = 0.0333333"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("removed the 2 output file(s) of the failed run (" + path("out/scene.pvd") + ")"), std::string::npos)
      << r.out;
  ASSERT_TRUE(fs::is_directory(path("out")));
  EXPECT_TRUE(fs::is_empty(path("out"))) << fs::directory_iterator(path("out"))->path();
}

// Runs into a folder that holds an earlier run's series of the same name:
// one that fails leaves it whole (it removed that run's first files, and
// the .pvd listing the rest); one that succeeds replaces it whole (a
// shorter run left the longer one's last .vtu files beside its own).
TEST_F(CliErrors, AFailedRunLeavesAnEarlierSeriesWholeAndASuccessfulOneReplacesIt) {
  beam_scene();
  const auto vtus = [&] {
    int n = 0;
    for (const auto& e : fs::directory_iterator(path("out"))) n += e.path().extension() == ".vtu";
    return n;
  };
  ASSERT_EQ(incise("run " + path("scene.json") + " --frames 4 --out " + path("out")).code, 0);
  ASSERT_EQ(vtus(), 5);
  const Result bad = incise("run " + path("scene.json") + " --frames 3 --set material.density=1e300 --out " + path("out"));
  EXPECT_EQ(bad.code, 1) << bad.out;
  EXPECT_EQ(vtus(), 5);
  EXPECT_TRUE(fs::exists(path("out/scene.pvd")));
  EXPECT_TRUE(files_with("incise-partial").empty()) << "the failed run's staging folder is removed";
  ASSERT_EQ(incise("run " + path("scene.json") + " --frames 2 --out " + path("out")).code, 0);
  EXPECT_EQ(vtus(), 3);
  std::ifstream pvd(path("out/scene.pvd"));
  const std::string listed((std::istreambuf_iterator<char>(pvd)), std::istreambuf_iterator<char>());
  EXPECT_NE(listed.find("scene_000002.vtu"), std::string::npos) << listed;
}

// The initial static solve (initial: "static") names the value too.
TEST_F(CliErrors, InitialStaticFailureNamesTheInput) {
  beam_scene(R"("young": 1e5, "poisson": 0.3, "density": 1e300)", R"(, "initial": "static")");
  const Result r = incise("run " + path("scene.json") + " --frames 1 --out " + path("out"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("incise: error: " + path("scene.json") + ": initial \"static\": static: non-finite residual at "
                       "iteration 0 at DOF "),
            std::string::npos) << r.out;
  EXPECT_NE(r.out.find("; check material.density = 1e+300 (extreme"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(path("out")));
}

// "not positive definite" names the node and, first, the value out of range:
// a modulus of 1e30 against a density of 1 leaves the mass term below
// roundoff (the dynamic step), and nothing holds the body (static).
TEST_F(CliErrors, NotPositiveDefiniteNamesTheNodeAndTheExtremeValue) {
  beam_scene(R"("young": 1e30, "poisson": 0.3, "density": 1)");
  write("free.json", R"({"mesh": {"file": "beam.vtu", "order": 1},
    "material": {"model": "linear", "young": 1e30, "poisson": 0.3, "density": 1}, "gravity": [0, 0, -1]})");
  const std::string extreme = "; check material.young = 1e+30 (extreme: tissues to steel are 1e2 to 2e11 Pa), "
                              "material.poisson = 0.3, material.density = 1, integrator.dt = 0.0333333";
  const Result dyn = incise("run " + path("free.json") + " --frames 2");
  EXPECT_EQ(dyn.code, 1) << dyn.out;
  EXPECT_NE(dyn.out.find("incise: error: frame 0: CHOLMOD: the system matrix is not positive definite at DOF "),
            std::string::npos) << dyn.out;
  EXPECT_NE(dyn.out.find("; at node "), std::string::npos) << dyn.out;
  EXPECT_NE(dyn.out.find(" (x = "), std::string::npos) << dyn.out;
  EXPECT_NE(dyn.out.find(extreme), std::string::npos) << dyn.out;
  const Result st = incise("static " + path("free.json"));
  EXPECT_EQ(st.code, 1) << st.out;
  EXPECT_NE(st.out.find("incise: error: " + path("free.json") + ": CHOLMOD: the system matrix is not positive definite"),
            std::string::npos) << st.out;
  EXPECT_NE(st.out.find(extreme), std::string::npos) << st.out;
}

// static that does not converge writes nothing unless --keep-unconverged
// asks for the last iterate; it exits 1 either way, with the iterations and
// the residual.
TEST_F(CliErrors, UnconvergedStaticWritesOnlyWithKeepUnconverged) {
  beam_scene(R"("young": 1e5, "poisson": 0.3, "density": 1)", R"(, "static": {"max_iterations": 1})");
  write("p.csv", "1,0.5,0.5\n");
  const std::string args = "static " + path("scene.json") + " --probe " + path("p.csv") + " --out " + path("u.csv") +
                           " --vtu " + path("u.vtu");
  const Result r = incise(args);
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find(": static solve did not reach static.tolerance 1e-08 in 1 iterations (relative residual "),
            std::string::npos) << r.out;
  EXPECT_NE(r.out.find("; nothing was written (--keep-unconverged writes the last iterate)"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(path("u.csv")));
  EXPECT_FALSE(fs::exists(path("u.vtu")));
  const Result k = incise(args + " --keep-unconverged");
  EXPECT_EQ(k.code, 1) << k.out;
  EXPECT_NE(k.out.find("; --keep-unconverged wrote the last iterate"), std::string::npos) << k.out;
  EXPECT_TRUE(fs::exists(path("u.csv")));
  EXPECT_TRUE(fs::exists(path("u.vtu")));
  EXPECT_NE(incise("static --help").out.find("--keep-unconverged"), std::string::npos);
}

// study.json and the point results are read with a depth limit and checked:
// a plan of another shape failed an assertion in nlohmann's operator[]
// (abort), a malformed point was an internal error.
TEST_F(CliErrors, MalformedStudyFilesAreErrorsNamingTheFile) {
  fs::create_directories(path("st/points"));
  write("st/study.json", R"({"points": 3, "frames": [1]})");
  Result r = incise("study --collect " + path("st"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find(path("st/study.json") + ": not a study plan: scene must be a string"), std::string::npos) << r.out;
  r = incise("study --point 0 --out " + path("st"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find(path("st/study.json") + ": not a study plan"), std::string::npos) << r.out;
  write("st/study.json", std::string(100000, '[') + std::string(100000, ']'));
  r = incise("study --collect " + path("st"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find(path("st/study.json") + ":1: nested deeper than 64 levels"), std::string::npos) << r.out;
  // a real study, then a point result of another shape
  beam_scene();
  // (dt values that reach frame 1 of the base dt, 1/30 s, in whole steps: StudyCli.ADtSweepComparesAtEqualTimes)
  ASSERT_EQ(incise("study " + path("scene.json") + " --sweep dt=0.0166666666666667,0.0333333333333333 --frames 1 --out " +
                   path("s2")).code,
            0);
  write("s2/points/point_1.json", R"({"point": 1, "frame_ms": 3})");
  r = incise("study --collect " + path("s2"));
  EXPECT_EQ(r.code, 1) << r.out;
  EXPECT_NE(r.out.find("study: a point result in " + path("s2") + "/points is malformed: "), std::string::npos) << r.out;
}

// A non-finite value never reaches an output file.
TEST(FrameOutputs, NonFiniteFieldIsRefused) {
  incise::VtuGrid g;
  g.points = {0, 0, 0, 1, 0, 0};
  g.point_data.push_back({"displacement", 3, {0, 0, 0, 0, std::nan(""), 0}});
  try {
    incise::check_output_finite(g, "out/s_000001.vtu");
    FAIL() << "no error";
  } catch (const incise::Error& e) {
    EXPECT_EQ(std::string(e.what()), "out/s_000001.vtu: the output field displacement at point 1 is not finite; it is not written");
  }
  g.point_data[0].values[4] = 0;
  g.points[3] = INFINITY;
  EXPECT_THROW(incise::check_output_finite(g, "x"), incise::Error);
  g.points[3] = 1;
  EXPECT_NO_THROW(incise::check_output_finite(g, "x"));
}

}  // namespace

namespace {

// cut_front "enriched" (issue 21): incise static solves with it (lumped or
// consistent mass) and reports the front elements; frames run with a cut
// that does not move and refuse a swept one and instruments; a value not
// allowed is an error naming the key.
TEST_F(CliErrors, EnrichedCutFrontRunsStaticFramesSweptCutsAndInstruments) {
  ASSERT_EQ(incise("mesh beam --size 4 1 1 --cells 7 3 3 --out " + path("beam.vtu")).code, 0);
  const std::string slit =
      R"(, "mass": "consistent", "cut_front": "enriched",
      "cuts": [{"type": "polygon", "points": [[2, -1, 0.45], [2, 2, 0.45], [2, 2, 3], [2, -1, 3]]}])";
  write("scene.json", incise::test::beam_scene_json(2, R"("model": "linear", "young": 1e5, "poisson": 0.3, "density": 1)", slit));
  const Result st = incise("static " + path("scene.json"));
  EXPECT_EQ(st.code, 0) << st.out;
  EXPECT_NE(st.out.find(" front elements enriched ("), std::string::npos) << st.out;
  // Frames run with a cut that does not move, with a probe too, and with a
  // swept cut (enriched once complete) and with a scalpel (its incision's
  // front enriched once the blade is out of the tissue).
  EXPECT_EQ(incise("run " + path("scene.json") + " --frames 3").code, 0);
  const Result probe = incise("run " + path("scene.json") + " --frames 3 --set " +
                              R"('instruments=[{"type": "probe", "radius": 0.1, "pose": {"position": [2.3, 0.5, 1.05]}}]')");
  EXPECT_EQ(probe.code, 0) << probe.out;
  write("swept.json",
        incise::test::beam_scene_json(2, R"("model": "linear", "young": 1e5, "poisson": 0.3, "density": 1)",
                                      R"(, "cut_front": "enriched", "cuts": [{"type": "swept",
      "edge_start": [[2, -1, 1.5], [2, 2, 1.5]], "edge_end": [[2, -1, 0.45], [2, 2, 0.45]], "duration": 0.1}])"));
  const Result swept = incise("run " + path("swept.json") + " --frames 6");
  EXPECT_EQ(swept.code, 0) << swept.out;
  const Result scalpel =
      incise("run " + path("scene.json") + " --frames 3 --set " +
             R"('instruments=[{"type": "scalpel", "blade": [0.3, 0.01, 0.1], "pose": {"position": [1, 0.5, 1.2]}}]')");
  EXPECT_EQ(scalpel.code, 0) << scalpel.out;
  const Result bad = incise("static " + path("scene.json") + " --set cut_front=edges");
  EXPECT_EQ(bad.code, 1) << bad.out;
  EXPECT_NE(bad.out.find("cut_front"), std::string::npos) << bad.out;
  EXPECT_NE(bad.out.find("\"enriched\""), std::string::npos) << bad.out;
}

}  // namespace
