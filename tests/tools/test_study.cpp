// incise study (tools/study.h, tools/cmd_study.cpp): the sweep plan, the
// reference, the Pareto front on a hand-checked table, and a study of a
// cantilever whose error falls as its mesh is refined, resumed and collected.
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>

#include <gtest/gtest.h>

#include "engine/util/error.h"
#include "tests/tools/cli_test_util.h"
#include "tests/tools/temp_dir_test.h"
#include "tools/study.h"

namespace incise {
namespace {

TEST(Study, ParetoFrontOfAHandCheckedTable) {
  // (ms, error): a (1, 0.5) b (2, 0.1) c (2, 0.3) d (4, 0.1) e (8, 0.01)
  // f (3, nan) g (0.5, 0.5): g dominates a (cheaper, as wrong); c is beaten
  // by b; d ties b's error at twice the cost; f has no error.
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<double> cost = {1, 2, 2, 4, 8, 3, 0.5};
  const std::vector<double> err = {0.5, 0.1, 0.3, 0.1, 0.01, nan, 0.5};
  EXPECT_EQ(pareto_front(cost, err), (std::vector<int>{6, 1, 4}));
  // Two identical points are both on it (neither is strictly better).
  EXPECT_EQ(pareto_front({1, 1}, {0.2, 0.2}), (std::vector<int>{0, 1}));
  EXPECT_TRUE(pareto_front({}, {}).empty());
}

TEST(Study, SweepsAliasesFinestValuesAndPointOrder) {
  const Sweep o = parse_sweep("order=1,2");
  EXPECT_EQ(o.key, "mesh.order");
  EXPECT_EQ(finest_value(o), 1);
  const Sweep t = parse_sweep("tolerance=1e-3,1e-8,1e-6");
  EXPECT_EQ(t.key, "solver.tolerance");
  EXPECT_EQ(finest_value(t), 1);
  EXPECT_EQ(finest_value(parse_sweep("policy=lagged,exact,warped_cg")), 1);
  EXPECT_EQ(finest_value(parse_sweep("preset=realtime,reference,accurate")), 1);
  EXPECT_EQ(finest_value(parse_sweep("mesh=c.msh,m.msh,f.msh")), 2);  // files: coarse to fine
  EXPECT_EQ(finest_value(parse_sweep("dt=0.033,0.01")), 1);
  EXPECT_EQ(parse_sweep("integrator.rotation_tolerance=0.1,0").key, "integrator.rotation_tolerance");
  for (const char* bad : {"order", "=1,2", "order=", "order=1,,2", "order=1,1"})
    EXPECT_THROW(parse_sweep(bad), Error) << bad;
  const std::vector<Sweep> sw = {o, t};
  const auto pts = study_points(sw);
  ASSERT_EQ(pts.size(), 6u);
  EXPECT_EQ(pts[0], (std::vector<int>{0, 0}));
  EXPECT_EQ(pts[1], (std::vector<int>{0, 1}));  // the last sweep varies fastest
  EXPECT_EQ(pts[3], (std::vector<int>{1, 0}));
  EXPECT_EQ(reference_point(sw), 4);  // order 2, tolerance 1e-8
  EXPECT_EQ(pts[4], (std::vector<int>{1, 1}));
}

TEST(Study, RelativeL2SkipsSamplesOutsideEitherMesh) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  // sample 1 is outside the first mesh: only samples 0 and 2 count.
  const std::vector<double> a = {1, 0, 0, nan, nan, nan, 0, 2, 0};
  const std::vector<double> b = {0, 0, 0, 5, 5, 5, 0, 1, 0};
  EXPECT_NEAR(relative_l2(a, b), std::sqrt(2.0 / 1.0), 1e-15);
  EXPECT_TRUE(std::isnan(relative_l2({nan, 0, 0}, {1, 0, 0})));
}

class StudyCli : public test::TempDirTest {};

std::string read_all(const std::string& p) {
  std::ifstream is(p);
  std::stringstream ss;
  ss << is.rdbuf();
  return ss.str();
}

// A dt sweep compares at equal times: --frames are frames of the base
// scene's dt, so the point at dt / 2 is sampled at twice the frame number.
// Sampled at the same frame numbers (other times), the swinging cantilever
// showed an "error" of 0.66 between dt = 1/30 and 1/60 at frame 5; at equal
// times the halved step changes it by a few percent. A dt that does not
// reach a sampled time in whole steps is an error naming it.
TEST_F(StudyCli, ADtSweepComparesAtEqualTimes) {
  ASSERT_EQ(test::incise("mesh beam --size 0.2 0.05 0.05 --cells 4 1 1 --out " + path("b.vtu")).code, 0);
  write("scene.json", R"({"mesh": {"file": "b.vtu", "order": 2},
    "material": {"model": "corotated", "young": 1e5, "poisson": 0.3, "density": 1000, "rayleigh": {"mass": 2.0, "stiffness": 0}},
    "mass": "lumped", "gravity": [0, 0, -9.81], "fixed": [{"box": [[-1, -1, -1], [0, 1, 1]]}]})");
  const test::Result r = test::incise("study " + path("scene.json") + " --sweep dt=0.0333333333333333,0.0166666666666667 --frames 5 --out " + path("s"));
  ASSERT_EQ(r.code, 0) << r.out;
  std::istringstream is(read_all(path("s/study.csv")));
  std::string line;
  std::getline(is, line);
  ASSERT_EQ(line, "point,dt,status,dof,median_ms,p99_ms,error_at_5,probe_error,energy_drift,pareto");
  std::getline(is, line);  // dt = 1/30 against the reference dt = 1/60
  std::vector<std::string> f;
  std::stringstream ls(line);
  for (std::string c; std::getline(ls, c, ',');) f.push_back(c);
  ASSERT_GE(f.size(), 7u) << line;
  EXPECT_EQ(f[2], "ok") << line;
  EXPECT_GT(std::stod(f[6]), 0.0) << line;
  EXPECT_LT(std::stod(f[6]), 0.1) << line;
  // A --set dt for every point is the base dt: no sweep, nothing to map.
  const test::Result set = test::incise("study " + path("scene.json") + " --set integrator.dt=0.03 --sweep order=1,2 --frames 3 --out " + path("u"));
  EXPECT_EQ(set.code, 0) << set.out;
  const test::Result bad = test::incise("study " + path("scene.json") + " --sweep dt=0.0333333333333333,0.025 --frames 5 --out " + path("t"));
  EXPECT_NE(bad.out.find("study: integrator.dt 0.025 does not reach frame 5 of the base scene's dt"), std::string::npos) << bad.out;
  // Refused before any point ran, and nothing written (it used to run the
  // points before the bad one and fail only there).
  EXPECT_NE(bad.code, 0);
  EXPECT_EQ(bad.out.find("point 0"), std::string::npos) << bad.out;
  EXPECT_FALSE(std::filesystem::exists(path("t"))) << bad.out;
}

// A soft tet10 cantilever swinging under gravity at three mesh resolutions
// and both orders: the error at frame 10 against the finest (order 2, 16 x 4
// x 4) falls as the tet10 mesh is refined; the reference row has error 0 and
// is on the front; the probe points have an error too; a second run resumes
// (runs nothing); another plan in the same folder is refused.
TEST_F(StudyCli, MeshRefinementLowersTheErrorAndTheStudyResumes) {
  for (int n : {4, 8, 16}) {
    const std::string cells = std::to_string(n) + " " + std::to_string(n / 4) + " " + std::to_string(n / 4);
    ASSERT_EQ(test::incise("mesh beam --size 0.2 0.05 0.05 --cells " + cells + " --out " + path("b" + std::to_string(n) + ".vtu")).code, 0);
  }
  write("scene.json", R"({"mesh": {"file": "b4.vtu", "order": 2},
    "material": {"model": "corotated", "young": 1e5, "poisson": 0.3, "density": 1000, "rayleigh": {"mass": 2.0, "stiffness": 0}},
    "mass": "lumped", "gravity": [0, 0, -9.81], "fixed": [{"box": [[-1, -1, -1], [0, 1, 1]]}]})");
  write("probe.csv", "x,y,z\n0.2,0.025,0.025\n0.1,0.0,0.05\n");  // the free end's centre, a top edge point
  const std::string args = "study " + path("scene.json") + " --sweep mesh=b4.vtu,b8.vtu,b16.vtu --sweep order=1,2 --frames 3,10 --probe " +
                           path("probe.csv") + " --out " + path("s");
  const test::Result r = test::incise(args);
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("ETA"), std::string::npos) << "progress expected: " << r.out;
  const std::string csv = read_all(path("s/study.csv"));
  std::istringstream is(csv);
  std::string line;
  std::getline(is, line);
  EXPECT_EQ(line, "point,mesh,order,status,dof,median_ms,p99_ms,error_at_3,error_at_10,probe_error,energy_drift,pareto");
  std::vector<double> err2;  // order 2, coarse to fine
  while (std::getline(is, line)) {
    std::vector<std::string> f;
    std::stringstream ls(line);
    for (std::string c; std::getline(ls, c, ',');) f.push_back(c);
    ASSERT_EQ(f.size(), 12u) << line;
    EXPECT_EQ(f[3], "ok") << line;
    if (f[2] == "2") err2.push_back(std::stod(f[8]));
    ASSERT_FALSE(f[9].empty()) << "probe error expected: " << line;
    EXPECT_GE(std::stod(f[9]), 0.0);
    if (f[1] == "b16.vtu" && f[2] == "2") {
      EXPECT_EQ(std::stod(f[8]), 0.0) << "the reference against itself";
      EXPECT_EQ(f[11], "1") << "the most accurate point is on the front";
    }
  }
  ASSERT_EQ(err2.size(), 3u);
  EXPECT_GT(err2[0], 1.5 * err2[1]) << csv;
  EXPECT_GT(err2[1], 0.0);
  EXPECT_TRUE(std::filesystem::is_regular_file(path("s/study.md")));
  // Resumed: every point is done, nothing runs again; --list has nothing left.
  const test::Result again = test::incise(args);
  ASSERT_EQ(again.code, 0) << again.out;
  EXPECT_NE(again.out.find("6 point(s) were done before"), std::string::npos) << again.out;
  EXPECT_EQ(test::incise(args + " --list").out.find("--point"), std::string::npos);
  // Another plan in the same folder.
  const test::Result other = test::incise("study " + path("scene.json") + " --sweep order=1,2 --out " + path("s"));
  EXPECT_NE(other.code, 0);
  EXPECT_NE(other.out.find("holds a different study"), std::string::npos) << other.out;
}

}  // namespace
}  // namespace incise
