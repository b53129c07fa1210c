// The incise command line, run as a user runs it: files in, files and
// messages out, exit codes.
#include <cctype>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <map>
#include <array>
#include <vector>
#include <algorithm>
#include <cmath>

#include <gtest/gtest.h>

#include "tests/tools/cli_test_util.h"
#include "tests/tools/temp_dir_test.h"
#include <nlohmann/json.hpp>

#include "engine/mesh/mesh_io.h"
#include "engine/mesh/mesh_tools.h"

namespace fs = std::filesystem;

namespace {

using incise::test::incise;
using incise::test::Result;

class Cli : public incise::test::TempDirTest {
 protected:
  // A linear cantilever (L = 4, 1 x 1) fixed at x = 0, under gravity.
  void cantilever_scene(const std::string& extra = "") const {
    ASSERT_EQ(incise("mesh beam --size 4 1 1 --cells 8 2 2 --out " + path("beam.vtu")).code, 0);
    write("scene.json", incise::test::beam_scene_json(2, R"("model": "linear", "young": 1e5, "poisson": 0.3, "density": 1)",
                                                      R"(, "mass": "consistent")" + extra));
  }
};

// incise --version: the project's version (CMakeLists.txt) and the libraries found.
TEST_F(Cli, VersionNamesTheBuildAndTheLibraries) {
  const Result r = incise("--version");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(r.out.rfind("incise 0.", 0), 0u) << r.out;
  for (const char* want : {"build: ", "CHOLMOD ", "BLAS: ", "FCL ", "EGL: ", "OpenIGTLink: "})
    EXPECT_NE(r.out.find(want), std::string::npos) << want << " missing: " << r.out;
}

TEST_F(Cli, MeshBeamWritesAReadableMesh) {
  const Result r = incise("mesh beam --size 2 1 1 --cells 4 2 2 --order 2 --out " + path("b.msh"));
  ASSERT_EQ(r.code, 0) << r.out;
  const incise::Mesh m = incise::read_mesh(path("b.msh"));
  EXPECT_EQ(m.order, 2);
  EXPECT_EQ(m.ntet(), 4 * 2 * 2 * 6);
  EXPECT_EQ(m.nnode(), 9 * 5 * 5);  // tet10 nodes of a Kuhn grid = the 2x finer lattice
  EXPECT_NE(r.out.find("dihedral"), std::string::npos) << "quality report expected: " << r.out;
}

// A closed sphere (an icosahedron subdivided 4 times, radius r, its
// polyhedral volume 0.2% under the sphere's) as ASCII STL; `open` drops one
// triangle.
std::string sphere_stl(bool open, bool obj = false, double r = 0.05) {
  const double t = (1 + std::sqrt(5.0)) / 2;
  std::vector<std::array<double, 3>> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                                          {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  std::vector<std::array<int, 3>> f = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                                       {11, 10, 2}, {10, 7, 6}, {7, 1, 8},   {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                                       {3, 8, 9},   {4, 9, 5},  {2, 4, 11},  {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  auto unit = [](std::array<double, 3> p) {
    const double l = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
    return std::array<double, 3>{p[0] / l, p[1] / l, p[2] / l};
  };
  for (auto& p : v) p = unit(p);
  for (int level = 0; level < 4; ++level) {
    std::map<std::pair<int, int>, int> mid;
    auto m = [&](int a, int b) {
      const auto key = std::minmax(a, b);
      auto it = mid.find(key);
      if (it != mid.end()) return it->second;
      v.push_back(unit({v[a][0] + v[b][0], v[a][1] + v[b][1], v[a][2] + v[b][2]}));
      return mid[key] = static_cast<int>(v.size()) - 1;
    };
    std::vector<std::array<int, 3>> g;
    for (const auto& [a, b, c] : f) {
      const int ab = m(a, b), bc = m(b, c), ca = m(c, a);
      g.push_back({a, ab, ca}), g.push_back({b, bc, ab}), g.push_back({c, ca, bc}), g.push_back({ab, bc, ca});
    }
    f = g;
  }
  std::ostringstream os;
  if (obj) {  // the same surface as an indexed OBJ
    for (const auto& p : v) os << "v " << r * p[0] << ' ' << r * p[1] << ' ' << r * p[2] << '\n';
    for (size_t k = open ? 1 : 0; k < f.size(); ++k) os << "f " << f[k][0] + 1 << ' ' << f[k][1] + 1 << ' ' << f[k][2] + 1 << '\n';
    return os.str();
  }
  os << "solid sphere\n";
  for (size_t k = open ? 1 : 0; k < f.size(); ++k) {
    os << " facet normal 0 0 0\n  outer loop\n";
    for (int i : f[k]) os << "   vertex " << r * v[i][0] << ' ' << r * v[i][1] << ' ' << r * v[i][2] << '\n';
    os << "  endloop\n endfacet\n";
  }
  os << "endsolid sphere\n";
  return os.str();
}

// incise mesh tetrahedralize (TetGen): a closed sphere becomes a tet10 mesh
// of its volume (within 1% of the sphere's) without an inverted element; an
// open surface is an error saying so; an inner shell's inside is a cavity;
// a size that would make too many tetrahedra is refused before TetGen runs.
TEST_F(Cli, TetrahedralizeFillsAClosedSurfaceAndRefusesAnOpenOne) {
  if (std::system("command -v tetgen > /dev/null 2>&1") != 0) GTEST_SKIP() << "tetgen not installed";
  write("sphere.stl", sphere_stl(false));
  const Result r = incise("mesh tetrahedralize " + path("sphere.stl") + " --size 0.01 --out " + path("s.msh"));
  ASSERT_EQ(r.code, 0) << r.out;
  const incise::Mesh m = incise::read_mesh(path("s.msh"));
  EXPECT_EQ(m.order, 2);
  EXPECT_NO_THROW(incise::check_mesh(m));  // positive Jacobians
  auto volume = [](const incise::Mesh& mesh) {  // of the corner tetrahedra (straight edges)
    double vol = 0;
    for (int e = 0; e < mesh.ntet(); ++e) {
      const int* t = &mesh.tet[static_cast<size_t>(mesh.npe()) * static_cast<size_t>(e)];
      double d[3][3];
      for (int k = 0; k < 3; ++k)
        for (int c = 0; c < 3; ++c) d[k][c] = mesh.X[3 * t[k + 1] + c] - mesh.X[3 * t[0] + c];
      vol += (d[0][0] * (d[1][1] * d[2][2] - d[1][2] * d[2][1]) - d[0][1] * (d[1][0] * d[2][2] - d[1][2] * d[2][0]) +
              d[0][2] * (d[1][0] * d[2][1] - d[1][1] * d[2][0])) / 6.0;
    }
    return vol;
  };
  const double sphere = 4.0 / 3.0 * M_PI * 0.05 * 0.05 * 0.05;
  EXPECT_NEAR(volume(m) / sphere, 1.0, 0.01);
  // The 5120 triangles of the surface set the size when --size is coarser
  // (0.05, the sphere's radius, asks for about 100 tetrahedra): a note says so.
  const std::string finer = "TetGen keeps the surface's triangles and grades the inside from them";
  EXPECT_EQ(r.out.find(finer), std::string::npos) << r.out;
  const Result coarse = incise("mesh tetrahedralize " + path("sphere.stl") + " --size 0.05 --order 1 --out " + path("c.vtu"));
  ASSERT_EQ(coarse.code, 0) << coarse.out;
  EXPECT_NE(coarse.out.find(finer), std::string::npos) << coarse.out;
  write("sphere.obj", sphere_stl(false, true));  // OBJ goes through an OFF file
  const Result o = incise("mesh tetrahedralize " + path("sphere.obj") + " --size 0.01 --order 1 --out " + path("o4.vtu"));
  ASSERT_EQ(o.code, 0) << o.out;
  const incise::Mesh m4 = incise::read_mesh(path("o4.vtu"));
  EXPECT_EQ(m4.order, 1);
  EXPECT_NEAR(volume(m4) / sphere, 1.0, 0.01);
  write("open.stl", sphere_stl(true));
  const Result bad = incise("mesh tetrahedralize " + path("open.stl") + " --size 0.01 --out " + path("o.msh"));
  EXPECT_NE(bad.code, 0);
  EXPECT_NE(bad.out.find("open.stl: TetGen made no tetrahedra: the surface is not closed"), std::string::npos) << bad.out;
  EXPECT_FALSE(fs::exists(path("o.msh")));
  // A binary STL (TetGen reads ASCII only; it aborted and the message blamed the surface's shape).
  {
    std::ofstream os(path("bin.stl"), std::ios::binary);
    const char header[80] = "binary STL";
    os.write(header, 80);
    const std::uint32_t n = 1;
    os.write(reinterpret_cast<const char*>(&n), 4);
    const float tri[12] = {0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1, 0};
    os.write(reinterpret_cast<const char*>(tri), sizeof tri);
    os.write("\0\0", 2);
  }
  const Result binary = incise("mesh tetrahedralize " + path("bin.stl") + " --size 0.01 --out " + path("b.msh"));
  EXPECT_NE(binary.code, 0);
  EXPECT_NE(binary.out.find("bin.stl: a binary STL (1 triangles); TetGen reads ASCII STL only"), std::string::npos)
      << binary.out;
  EXPECT_FALSE(fs::exists(path("b.msh")));
  // A sphere inside a sphere: the inner one's inside is a cavity, left
  // empty unless --fill-cavities (TetGen fills every closed region).
  const double inner = 4.0 / 3.0 * M_PI * 0.02 * 0.02 * 0.02;
  write("hollow.stl", sphere_stl(false, false, 0.05) + sphere_stl(false, false, 0.02));
  const Result h = incise("mesh tetrahedralize " + path("hollow.stl") + " --size 0.01 --order 1 --out " + path("h.vtu"));
  ASSERT_EQ(h.code, 0) << h.out;
  EXPECT_NE(h.out.find("left 1 enclosed region(s) empty"), std::string::npos) << h.out;
  EXPECT_NEAR(volume(incise::read_mesh(path("h.vtu"))) / (sphere - inner), 1.0, 0.01);
  const Result hf = incise("mesh tetrahedralize " + path("hollow.stl") + " --size 0.01 --order 1 --fill-cavities --out " +
                           path("hf.vtu"));
  ASSERT_EQ(hf.code, 0) << hf.out;
  EXPECT_NEAR(volume(incise::read_mesh(path("hf.vtu"))) / sphere, 1.0, 0.01);
  // A --size that would ask TetGen for 1e13 tetrahedra is refused before it
  // runs (it used to run out of memory, and the error blamed the surface).
  const Result huge = incise("mesh tetrahedralize " + path("sphere.stl") + " --size 1e-5 --out " + path("x.msh"));
  EXPECT_NE(huge.code, 0);
  EXPECT_NE(huge.out.find("sphere.stl: --size 1e-05 asks for about 1.3e+13 tetrahedra"), std::string::npos) << huge.out;
  EXPECT_NE(huge.out.find("use --size 0.0011 or larger"), std::string::npos) << huge.out;
  EXPECT_FALSE(fs::exists(path("x.msh")));
}

TEST_F(Cli, MeshConvertRaisesToTet10) {
  ASSERT_EQ(incise("mesh beam --size 1 1 1 --cells 2 2 2 --out " + path("a.vtk")).code, 0);
  const Result r = incise("mesh convert " + path("a.vtk") + " " + path("a.vtu") + " --order 2");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_EQ(incise::read_mesh(path("a.vtu")).nnode(), 125);
}

TEST_F(Cli, StaticProbeReportsInterpolatedDisplacement) {
  cantilever_scene();
  write("probe.csv", "x,y,z\n4,0.5,0.5\n2,0.5,0.5\n0,0.5,0.5\n");
  const Result r = incise("static " + path("scene.json") + " --probe " + path("probe.csv") + " --out " + path("u.csv"));
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream is(path("u.csv"));
  std::string header, line;
  std::getline(is, header);
  EXPECT_EQ(header, "x,y,z,ux,uy,uz");
  double uz[3];
  for (int k = 0; k < 3; ++k) {
    ASSERT_TRUE(std::getline(is, line));
    double x, y, z, ux, uy;
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf,%lf,%lf", &x, &y, &z, &ux, &uy, &uz[k]), 6) << line;
  }
  // Euler-Bernoulli: w(L) = q L^4 / (8 E I) = 1 * 256 / (8e5 / 12) = 3.84e-3;
  // w(L/2) / w(L) = 17/48 for a uniform load.
  EXPECT_NEAR(uz[0] / -3.84e-3, 1.0, 0.05);
  EXPECT_NEAR(uz[1] / uz[0], 17.0 / 48.0, 0.03);
  EXPECT_EQ(uz[2], 0.0);
}

TEST_F(Cli, StaticProbeOutsideTheMeshIsAnErrorNamingThePoint) {
  cantilever_scene();
  write("probe.csv", "1,0.5,0.5\n5,0.5,0.5\n");
  const Result r = incise("static " + path("scene.json") + " --probe " + path("probe.csv"));
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("probe.csv: point 2 (5, 0.5, 0.5) is outside the mesh"), std::string::npos) << r.out;
}

TEST_F(Cli, RunWritesSeriesAndTimingJson) {
  cantilever_scene();
  const Result r = incise("run " + path("scene.json") + " --frames 3 --out " + path("out"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_TRUE(fs::exists(path("out/scene.pvd")));
  int vtu = 0;
  for (const auto& e : fs::directory_iterator(path("out"))) vtu += e.path().extension() == ".vtu";
  EXPECT_EQ(vtu, 4);  // frame 0 and three steps
  std::ifstream js(path("out/timing.json"));
  const auto j = nlohmann::json::parse(js);
  EXPECT_EQ(j["frames"], 3);
  EXPECT_EQ(j["refactorizations"], 1) << "a linear scene factors once";
  // output.every 3 over 4 frames: frames 0, 3 and the last (it
  // was left out), the series' files numbered in order.
  const Result e = incise("run " + path("scene.json") + " --frames 4 --set output.every=3 --out " + path("every"));
  ASSERT_EQ(e.code, 0) << e.out;
  std::ifstream pvd(path("every/scene.pvd"));
  const std::string listed((std::istreambuf_iterator<char>(pvd)), std::istreambuf_iterator<char>());
  int datasets = 0;
  for (size_t at = listed.find("<DataSet"); at != std::string::npos; at = listed.find("<DataSet", at + 1)) ++datasets;
  EXPECT_EQ(datasets, 3) << listed;
  EXPECT_NE(listed.find("file=\"scene_000002.vtu\""), std::string::npos) << listed;
  // --record-states without --record did nothing, in silence.
  const Result rs = incise("run " + path("scene.json") + " --frames 1 --record-states 3");
  EXPECT_NE(rs.code, 0);
  EXPECT_NE(rs.out.find("--record-states requires --record"), std::string::npos) << rs.out;
}

TEST_F(Cli, BenchJsonHasTheDocumentedFields) {
  cantilever_scene();
  const Result r = incise("bench " + path("scene.json") + " --frames 5 --json " + path("b.json"));
  ASSERT_EQ(r.code, 0) << r.out;
  std::ifstream js(path("b.json"));
  const auto j = nlohmann::json::parse(js);
  for (const char* k : {"median_ms", "p95_ms", "p99_ms", "max_ms", "over_budget"}) EXPECT_TRUE(j["frame"].contains(k)) << k;
  for (const char* s : {"tool_poses", "collision", "cutting", "assembly", "factorization", "solve", "integration",
                        "contact_publish", "render", "record"})
    for (const char* k : {"median_ms", "p95_ms", "p99_ms", "max_ms", "runs"}) EXPECT_TRUE(j["stages"][s].contains(k)) << s << k;
  EXPECT_EQ(j["stages"]["cutting"]["runs"].get<int>(), 0) << "no cut in the scene: no cutting stage";
  EXPECT_EQ(j["stages"]["render"]["runs"].get<int>(), 0) << "no --render: no render stage";
  EXPECT_EQ(j["stages"]["integration"]["runs"].get<int>(), j["frames"].get<int>());
  EXPECT_EQ(j["stages"]["factorization"]["runs"].get<int>(), 1) << "a linear scene factors once";
  EXPECT_EQ(j["dof"], 3 * 17 * 5 * 5);
  EXPECT_GT(j["factor"]["nnz_L"].get<double>(), 0.0);
  EXPECT_GT(j["factor"]["flops"].get<double>(), 0.0);
  // a linear scene never refactorizes: factorization is 0 ms after frame 1
  EXPECT_EQ(j["stages"]["factorization"]["median_ms"].get<double>(), 0.0);
  EXPECT_EQ(j["stages"]["render"]["max_ms"].get<double>(), 0.0) << "no --render: nothing is drawn";
}

// A probe pressing the cantilever's free end: the frame has the tool-poses,
// collision and contact stages, and the JSON their statistics.
TEST_F(Cli, BenchWithAProbeReportsTheInstruments) {
  write("press.csv", "t,x,y,z,qw,qx,qy,qz\n0, 3.5, 0.5, 1.3, 1, 0, 0, 0\n0.2, 3.5, 0.5, 1.1, 1, 0, 0, 0\n");
  cantilever_scene(R"(, "instruments": [{"type": "probe", "radius": 0.2, "trajectory": "press.csv"}])");
  const Result r = incise("bench " + path("scene.json") + " --frames 8 --json " + path("b.json") + " --trace " + path("t.csv"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("instruments: "), std::string::npos) << r.out;
  std::ifstream trace(path("t.csv"));
  std::string header;
  std::getline(trace, header);
  EXPECT_NE(header.find(",contact_ms,"), std::string::npos) << header;
  EXPECT_NE(header.find(",contacts,grasp_rows,pgs_sweeps,max_depth,contact_force,bvh_rebuilds"), std::string::npos) << header;
  std::ifstream js(path("b.json"));
  const auto j = nlohmann::json::parse(js);
  for (const char* s : {"tool_poses", "collision"}) EXPECT_EQ(j["stages"][s]["runs"].get<int>(), 8) << s;
  EXPECT_GT(j["stages"]["contact"]["runs"].get<int>(), 0);
  EXPECT_GT(j["instruments"]["contacts_max"].get<int>(), 0);
  EXPECT_EQ(j["instruments"]["bvh_rebuilds"].get<int>(), 1) << "no cut: built once";
  EXPECT_EQ(j["instruments"]["bvh_refits"].get<int>(), 7);
}

// --pace 30 starts a frame every 1/30 s, as the real-time loop does: 6 frames
// (1 warm-up) take at least 5 periods of wall time, and the JSON says so.
TEST_F(Cli, BenchPaceStartsFramesAtTheGivenRate) {
  cantilever_scene();
  const auto t0 = std::chrono::steady_clock::now();
  const Result r = incise("bench " + path("scene.json") + " --frames 5 --warmup 1 --pace 30 --json " + path("p.json"));
  const double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("frames started at 30 Hz"), std::string::npos) << r.out;
  EXPECT_GE(s, 5.0 / 30.0);
  std::ifstream js(path("p.json"));
  EXPECT_EQ(nlohmann::json::parse(js)["pace_hz"].get<double>(), 30.0);
  const Result bad = incise("bench " + path("scene.json") + " --frames 1 --pace -1");
  EXPECT_NE(bad.code, 0);
  EXPECT_NE(bad.out.find("--pace"), std::string::npos) << bad.out;
}

TEST_F(Cli, BenchRenderTimesTheRenderStage) {
  cantilever_scene(R"(, "render": {"width": 64, "height": 48})");
  const Result r = incise("bench " + path("scene.json") + " --frames 3 --render --json " + path("b.json"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("render: 64x48, EGL "), std::string::npos) << r.out;
  std::ifstream js(path("b.json"));
  const auto j = nlohmann::json::parse(js);
  EXPECT_GT(j["stages"]["render"]["median_ms"].get<double>(), 0.0);
}

TEST_F(Cli, RenderWritesThePngOfFrameK) {
  cantilever_scene();
  const Result r = incise("render " + path("scene.json") + " --frame 2 --out " + path("f.png") +
                          " --width 96 --height 64 --egl-platform surfaceless");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("EGL surfaceless"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("frame 2 (t = 0.0667 s)"), std::string::npos) << r.out;
  std::ifstream png(path("f.png"), std::ios::binary);
  char head[24] = {};
  png.read(head, sizeof head);
  EXPECT_EQ(std::string(head + 1, 3), "PNG");
  auto be32 = [&](int at) {
    return (unsigned char)head[at] << 24 | (unsigned char)head[at + 1] << 16 | (unsigned char)head[at + 2] << 8 |
           (unsigned char)head[at + 3];
  };
  EXPECT_EQ(be32(16), 96);  // IHDR width, height
  EXPECT_EQ(be32(20), 64);
}

TEST_F(Cli, RunRenderWritesOneFramePerStepAndABadPlatformIsAnError) {
  cantilever_scene(R"(, "render": {"width": 48, "height": 32})");
  const Result r = incise("run " + path("scene.json") + " --frames 3 --render " + path("frames"));
  ASSERT_EQ(r.code, 0) << r.out;
  for (const char* f : {"frame_00000.png", "frame_00001.png", "frame_00002.png", "frame_00003.png"})
    EXPECT_TRUE(fs::exists(path("frames/") + f)) << f;
  EXPECT_FALSE(fs::exists(path("frames/frame_00004.png")));
  const Result bad = incise("render " + path("scene.json") + " --out " + path("x.png") + " --egl-platform gpu");
  EXPECT_NE(bad.code, 0);
  EXPECT_NE(bad.out.find("--egl-platform"), std::string::npos) << bad.out;
}

TEST_F(Cli, BenchReportsTheSolverFields) {
  cantilever_scene();
  const Result r = incise("bench " + path("scene.json") + " --frames 4 --policy lagged --refresh-every 2 --json " +
                          path("b.json") + " --bandwidth-gbs 5");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("GFLOP/s"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("GB/s"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("CG: iterations/frame"), std::string::npos) << r.out;
  std::ifstream js(path("b.json"));
  const auto j = nlohmann::json::parse(js);
  EXPECT_EQ(j["solver"]["policy"], "lagged");
  for (const char* k : {"median", "p99", "max"}) EXPECT_TRUE(j["solver"]["iterations"].contains(k)) << k;
  EXPECT_GT(j["factor"]["gflops"].get<double>(), 0.0);
  EXPECT_GT(j["solve"]["gbs"].get<double>(), 0.0);
  EXPECT_DOUBLE_EQ(j["solver"]["bandwidth_gbs"].get<double>(), 5.0);
  EXPECT_GT(j["frame"]["bandwidth_multiple"].get<double>(), 0.0);
  EXPECT_TRUE(j["frame"].contains("median_ms"));
}

// --factor-copy and --substitution-threads reach the solver (the summary
// names them) and a bad value is refused naming the option.
TEST_F(Cli, BenchFactorCopyOption) {
  cantilever_scene();
  const Result r =
      incise("bench " + path("scene.json") + " --frames 3 --policy lagged --factor-copy half --substitution-threads 2");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("half-precision factor copy"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("substitutions on 2 threads"), std::string::npos) << r.out;
  const Result bad = incise("bench " + path("scene.json") + " --frames 1 --policy lagged --factor-copy bf16");
  EXPECT_NE(bad.code, 0);
  EXPECT_NE(bad.out.find("--factor-copy"), std::string::npos) << bad.out;
}

// --factor-precision single reaches the solver: the summary and the factor
// line say so, the JSON counts no fallback; with --factor-copy half the scene
// parser refuses it, naming the flag and the key it needs.
TEST_F(Cli, BenchFactorPrecisionOption) {
  cantilever_scene();
  const Result r = incise("bench " + path("scene.json") + " --frames 3 --policy lagged --factor-precision single --json " +
                          path("s.json"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("factored in single precision"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("in single precision)"), std::string::npos) << r.out;
  std::ifstream js(path("s.json"));
  const auto j = nlohmann::json::parse(js);
  EXPECT_TRUE(j["factor"]["single_precision_factorization"].get<bool>());
  EXPECT_EQ(j["factor"]["single_precision_fallbacks"].get<int>(), 0);
  EXPECT_EQ(j["factor"]["single_precision_factorizations"].get<int>(), j["factor"]["factorizations"].get<int>());
  const Result bad =
      incise("bench " + path("scene.json") + " --frames 1 --policy lagged --factor-precision single --factor-copy none");
  EXPECT_NE(bad.code, 0);
  EXPECT_NE(bad.out.find("--factor-precision single: solver.factor_precision"), std::string::npos) << bad.out;
  EXPECT_NE(bad.out.find("solver.factor_copy must be \"float\""), std::string::npos) << bad.out;
}

// --affinity split reaches the solver: the summary names the stepping
// thread's CPU (or says why nothing was pinned); a bad value is refused.
TEST_F(Cli, BenchAffinityOption) {
  cantilever_scene();
  const Result r = incise("bench " + path("scene.json") + " --frames 2 --affinity split");
  ASSERT_EQ(r.code, 0) << r.out;
  const bool pinned = r.out.find("stepping thread on CPU") != std::string::npos;
  const bool refused = r.out.find("affinity split not applied (fewer than two CPUs)") != std::string::npos;
  EXPECT_TRUE(pinned != refused) << r.out;
  EXPECT_EQ(incise("bench " + path("scene.json") + " --frames 2").out.find("stepping thread on CPU"), std::string::npos);
  const Result bad = incise("bench " + path("scene.json") + " --frames 1 --affinity cores");
  EXPECT_NE(bad.code, 0);
  EXPECT_NE(bad.out.find("--affinity"), std::string::npos) << bad.out;
}

TEST_F(Cli, ComparePrintsTheErrorAtEachFrame) {
  cantilever_scene();
  const Result r = incise("compare " + path("scene.json") + " --policy warped,lagged --frames 1,3 --json " + path("c.json"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("--- warped"), std::string::npos) << r.out;
  std::ifstream js(path("c.json"));
  const auto j = nlohmann::json::parse(js);
  ASSERT_EQ(j["policies"].size(), 2u);
  // linear scene: warped is the exact factor, lagged converges to 1e-6
  EXPECT_LT(j["policies"][0]["errors"][1]["rel_l2_error"].get<double>(), 1e-12);
  EXPECT_LT(j["policies"][1]["errors"][1]["rel_l2_error"].get<double>(), 1e-5);
  EXPECT_EQ(j["policies"][1]["errors"][1]["frame"], 3);
  EXPECT_NE(incise("compare " + path("scene.json") + " --policy cg").code, 0) << "an unknown policy is rejected";
}

TEST_F(Cli, MalformedSceneGivesItsMessageAndExitCode1) {
  cantilever_scene();
  write("bad.json", R"({"mesh": {"file": "beam.vtu"}, "material": {"young": 1, "poisson": 0.5, "density": 1}})");
  const Result r = incise("run " + path("bad.json") + " --frames 1");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("bad.json: material.poisson must be in (-1, 0.5), got 0.5"), std::string::npos) << r.out;
}

}  // namespace

namespace {

TEST_F(Cli, RunWithACutWritesTheOpeningAndReportsTheCutFrame) {
  cantilever_scene(R"(, "cuts": [{"type": "plane", "point": [2.3, 0, 0], "normal": [1, 0, 0], "at_time": 0.05}])");
  const Result r = incise("bench " + path("scene.json") + " --frames 6 --json " + path("b.json"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("cut frame"), std::string::npos) << r.out;
  std::ifstream js(path("b.json"));
  const auto j = nlohmann::json::parse(js);
  EXPECT_EQ(j["cut_frames"]["count"], 1);
  EXPECT_GT(j["enriched_dof"].get<int>(), 0);
  const Result run = incise("run " + path("scene.json") + " --frames 3 --out " + path("out"));
  ASSERT_EQ(run.code, 0) << run.out;
  const incise::Mesh first = incise::read_mesh(path("out/scene_000000.vtu"));
  const incise::Mesh last = incise::read_mesh(path("out/scene_000003.vtu"));
  EXPECT_GT(last.ntet(), first.ntet());  // cut elements are written as their sub-elements
}

TEST_F(Cli, BenchTraceHasOneRowPerTimedFrameWithTheCutParts) {
  cantilever_scene(R"(, "cuts": [{"type": "plane", "point": [2.3, 0, 0], "normal": [1, 0, 0], "at_time": 0.1}])");
  const Result r = incise("bench " + path("scene.json") + " --frames 6 --warmup 1 --trace " + path("t.csv"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("  acceleration"), std::string::npos) << "the cutting stage's parts: " << r.out;
  std::ifstream is(path("t.csv"));
  std::string header, line;
  std::getline(is, header);
  EXPECT_EQ(header.rfind("frame,frame_ms,cut_frame,tool_poses_ms,collision_ms,cutting_ms,", 0), 0u) << header;
  EXPECT_NE(header.find("cut_model_ms"), std::string::npos) << header;
  EXPECT_NE(header.find(",patch_dofs,tangent_updates"), std::string::npos) << header;
  ASSERT_GE(header.size(), 17u);
  EXPECT_EQ(header.substr(header.size() - 17), ",assembly_workers") << header;
  int rows = 0, cut_rows = 0, first = -1, both_workers = 0;
  while (std::getline(is, line)) {
    ++rows;
    // solver.threads 2 (the default); 1 in a frame whose cut-ahead ran on a helper.
    const int workers = std::stoi(line.substr(line.rfind(',') + 1));
    EXPECT_TRUE(workers == 1 || workers == 2) << line;
    both_workers += workers == 2;
    const int frame = std::stoi(line.substr(0, line.find(',')));
    if (first < 0) first = frame;
    std::stringstream ss(line);
    std::string field;
    std::getline(ss, field, ',');
    std::getline(ss, field, ',');
    std::getline(ss, field, ',');
    cut_rows += field == "1";
  }
  EXPECT_EQ(rows, 6);
  EXPECT_GT(both_workers, 0) << "exact: no background job, so the workers stand down only beside a cut-ahead";
  EXPECT_EQ(first, 2) << "rows are numbered after the warm-up frame";
  EXPECT_EQ(cut_rows, 1);  // the plane cut at 0.1 s, frame 3 or 4
  const Result bad = incise("bench " + path("scene.json") + " --frames 1 --trace " + path("no/such/dir/t.csv"));
  EXPECT_EQ(bad.code, 1);
  EXPECT_NE(bad.out.find("no/such/dir/t.csv: cannot write: No such file or directory"), std::string::npos) << bad.out;
}

TEST_F(Cli, StaticWithACutProbesEachSide) {
  cantilever_scene(R"(, "cuts": [{"type": "polygon", "points": [[2.3,-1,0.5],[2.3,2,0.5],[2.3,2,2],[2.3,-1,2]]}])");
  write("probe.csv", "x,y,z\n2.2999,0.5,0.9\n2.3001,0.5,0.9\n");
  const Result r = incise("static " + path("scene.json") + " --probe " + path("probe.csv") + " --out " + path("u.csv"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("cuts:"), std::string::npos) << r.out;
  std::ifstream is(path("u.csv"));
  std::string line;
  std::getline(is, line);
  double ux[2];
  for (double& v : ux) {
    std::getline(is, line);
    double x, y, z;
    ASSERT_EQ(std::sscanf(line.c_str(), "%lf,%lf,%lf,%lf", &x, &y, &z, &v), 4) << line;
  }
  // The slit opens at the top under gravity: the two faces move apart in x.
  EXPECT_GT(std::abs(ux[1] - ux[0]), 1e-5);
}

// The settings block of run/bench/compare ("settings ..." and its indented
// lines); strip_markers: without the origin markers " [...]" and with every
// run of white space (line breaks included) as one space.
std::string settings_block(const std::string& out, bool strip_markers) {
  const size_t at = out.find("\nsettings");
  if (at == std::string::npos) return "";
  std::istringstream is(out.substr(at + 1));
  std::string line, block;
  std::getline(is, line);  // the heading
  while (std::getline(is, line) && line.rfind("  ", 0) == 0) block += line + "\n";
  if (!strip_markers) return block;
  std::string plain;
  for (size_t i = 0; i < block.size(); ++i) {
    if (block[i] == ' ' && i + 1 < block.size() && block[i + 1] == '[') {
      i = block.find(']', i);
      continue;
    }
    const bool space = std::isspace(static_cast<unsigned char>(block[i]));
    if (!space) plain += block[i];
    else if (!plain.empty() && plain.back() != ' ') plain += ' ';
  }
  return plain;
}

// The solver flags are aliases of --set: both give the same resolved settings.
TEST_F(Cli, SolverFlagsGiveTheSameSettingsAsSet) {
  cantilever_scene();
  const Result flags = incise("bench " + path("scene.json") +
                              " --frames 1 --policy lagged --refresh-every 2 --tolerance 1e-4 --max-iterations 30"
                              " --background --warp --factor-copy half --tangent-reuse 0.01 --threads 1"
                              " --rescue-after 5 --late-factor skip --patch additive --cut-ordering search"
                              " --background-priority normal --affinity none --initial-guess zero"
                              " --substitution-threads 2 --factorization supernodal --ordering amd");
  const Result sets = incise("bench " + path("scene.json") +
                             " --frames 1 --set solver.policy=lagged --set solver.refresh_every=2"
                             " --set solver.tolerance=1e-4 --set solver.max_iterations=30 --set solver.background=true"
                             " --set solver.warp=true --set solver.factor_copy=half --set integrator.tangent_reuse=0.01"
                             " --set solver.threads=1 --set solver.rescue_after=5 --set solver.late_factor=skip"
                             " --set solver.patch=additive --set solver.cut_ordering=search"
                             " --set solver.background_priority=normal --set solver.affinity=none"
                             " --set solver.initial_guess=zero --set solver.substitution_threads=2"
                             " --set solver.factorization=supernodal --set solver.ordering=amd");
  ASSERT_EQ(flags.code, 0) << flags.out;
  ASSERT_EQ(sets.code, 0) << sets.out;
  const std::string block = settings_block(flags.out, true);
  EXPECT_NE(block.find("refresh_every 2, background true, warp true, factor_copy \"half\""), std::string::npos) << block;
  EXPECT_NE(block.find("tangent_reuse 0.01"), std::string::npos) << block;
  EXPECT_EQ(block, settings_block(sets.out, true));
  EXPECT_NE(flags.out.find("refresh_every 2 [--refresh-every]"), std::string::npos) << flags.out;
  EXPECT_NE(sets.out.find("refresh_every 2 [--set]"), std::string::npos) << sets.out;
  // --single-precision is the older switch of solver.single_precision
  const Result older = incise("bench " + path("scene.json") + " --frames 1 --policy lagged --single-precision false");
  ASSERT_EQ(older.code, 0) << older.out;
  EXPECT_NE(older.out.find("factor_copy \"none\" [--single-precision]"), std::string::npos) << older.out;
}

// bench and run print every resolved solver/integrator value with its origin.
TEST_F(Cli, BenchAndRunPrintTheResolvedSettings) {
  cantilever_scene(R"(, "solver": {"preset": "realtime"}, "integrator": {"dt": 0.02})");
  const Result r = incise("bench " + path("scene.json") + " --frames 2 --set solver.refresh_every=3");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("settings (solver.preset \"realtime\")"), std::string::npos) << r.out;
  const std::string block = settings_block(r.out, false);
  for (const char* part : {"preset \"realtime\" [scene]", "policy \"lagged\" [preset]", "refresh_every 3 [--set]",
                           "tolerance 0.01 [preset]", "dt 0.02 [scene]", "tangent \"consistent\" [preset]",
                           "tangent_reuse 0.01 [preset]", "predictor \"increment\" [preset]", "initial_guess \"previous\","})
    EXPECT_NE(block.find(part), std::string::npos) << part << "\n" << block;
  const Result run = incise("run " + path("scene.json") + " --frames 1 --set solver.preset=reference");
  ASSERT_EQ(run.code, 0) << run.out;
  EXPECT_NE(settings_block(run.out, false).find("policy \"exact\" [preset]"), std::string::npos) << run.out;
}

// integrator.predictor "increment" with frozen-rotation solves a fixed number
// of times a step (no adaptive Newton) is warned about; with the adaptive
// check, the consistent tangent or the velocity predictor it is not.
TEST_F(Cli, TheIncrementPredictorWithOneFrozenSolveIsWarnedAbout) {
  ASSERT_EQ(incise("mesh beam --size 4 1 1 --cells 4 1 1 --out " + path("beam.vtu")).code, 0);
  write("scene.json", incise::test::beam_scene_json(2, R"("model": "corotated", "young": 1e5, "poisson": 0.3, "density": 1)",
                                                    R"(, "integrator": {"predictor": "increment", "rotation_tolerance": 0, )"
                                                    R"("tangent": "frozen_rotation"})"));
  const std::string warning = "warning: integrator.predictor \"increment\" with the frozen-rotation tangent";
  const Result r = incise("run " + path("scene.json") + " --frames 1");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find(warning), std::string::npos) << r.out;
  for (const char* set : {"integrator.rotation_tolerance=0.1", "integrator.tangent=consistent", "integrator.predictor=velocity"}) {
    const Result ok = incise("run " + path("scene.json") + " --frames 1 --set " + set);
    ASSERT_EQ(ok.code, 0) << ok.out;
    EXPECT_EQ(ok.out.find(warning), std::string::npos) << set << "\n" << ok.out;
  }
}

// Near-incompressible tissue cut under an iterative policy is warned about
// (tools/cmd_summary.cpp: measured unstable on organ_instruments); the same
// scene under the reference preset, or compressible, or without a cut, is not.
TEST_F(Cli, ANearIncompressibleCutUnderTheRealtimePresetIsWarnedAbout) {
  ASSERT_EQ(incise("mesh beam --size 4 1 1 --cells 4 1 1 --out " + path("beam.vtu")).code, 0);
  const std::string cut = R"(, "cuts": [{"type": "plane", "point": [2, 0.5, 0.5], "normal": [1, 0, 0], "at_time": 0.0}])";
  const auto scene = [&](const char* nu, const std::string& extra) {
    write("scene.json", incise::test::beam_scene_json(
                            2, std::string(R"("model": "corotated", "young": 1e5, "poisson": )") + nu + R"(, "density": 1)",
                            R"(, "solver": {"preset": "realtime"})" + extra));
  };
  const std::string warning = "warning: near-incompressible tissue (material.poisson 0.498 > 0.495) cut under solver.policy lagged";
  scene("0.498", cut);
  const Result r = incise("run " + path("scene.json") + " --frames 1");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find(warning), std::string::npos) << r.out;
  const Result ref = incise("run " + path("scene.json") + " --frames 1 --set solver.preset=reference");
  ASSERT_EQ(ref.code, 0) << ref.out;
  EXPECT_EQ(ref.out.find("warning: near-incompressible"), std::string::npos) << ref.out;
  scene("0.49", cut);  // held under realtime once small pieces integrate over their element
  const Result soft = incise("run " + path("scene.json") + " --frames 1");
  EXPECT_EQ(soft.out.find("warning: near-incompressible"), std::string::npos) << soft.out;
  scene("0.498", "");
  const Result uncut = incise("run " + path("scene.json") + " --frames 1");
  EXPECT_EQ(uncut.out.find("warning: near-incompressible"), std::string::npos) << uncut.out;
}

TEST_F(Cli, SetErrorsNameThePatch) {
  cantilever_scene();
  Result r = incise("run " + path("scene.json") + " --frames 1 --set solver.policy=lagged2");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("incise: error: --set solver.policy=lagged2: solver.policy must be one of \"exact\", \"lagged\""),
            std::string::npos)
      << r.out;
  r = incise("bench " + path("scene.json") + " --frames 1 --set foo");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("--set foo: expected KEY=VALUE"), std::string::npos) << r.out;
  r = incise("static " + path("scene.json") + " --set static.tolerence=1e-6");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("--set static.tolerence=1e-6: static.tolerence: unknown key; allowed: tolerance, max_iterations; "
                       "did you mean \"tolerance\"?"),
            std::string::npos)
      << r.out;
  r = incise("compare " + path("scene.json") + " --policy lagged --refresh-every 0 --frames 1");
  EXPECT_EQ(r.code, 1);
  EXPECT_NE(r.out.find("--refresh-every 0: solver.refresh_every must be an integer >= 1, got 0"), std::string::npos)
      << r.out;
}

// compare's reference is exact whatever the scene's preset: under the
// realtime preset (lagged, CG to 1e-3, tangent reuse) a run with --policy
// exact and no tangent reuse agrees with it to roundoff, while the scene's
// own lagged run does not.
TEST_F(Cli, CompareReferenceIsExactUnderARealtimePreset) {
  ASSERT_EQ(incise("mesh beam --size 4 1 1 --cells 8 2 2 --out " + path("beam.vtu")).code, 0);
  write("scene.json", R"({"mesh": {"file": "beam.vtu", "order": 2},
      "material": {"model": "corotated", "young": 1e5, "poisson": 0.3, "density": 100},
      "gravity": [0, 0, -10], "fixed": [{"box": [[-1, -1, -1], [0, 2, 2]]}],
      "solver": {"preset": "realtime"}})");
  const Result exact =
      incise("compare " + path("scene.json") + " --policy exact --tangent-reuse 0 --frames 1,3 --json " + path("e.json"));
  ASSERT_EQ(exact.code, 0) << exact.out;
  // The reference's block (printed first): exact, reuse off, no lagged key.
  const std::string ref = settings_block(exact.out, false);
  EXPECT_NE(ref.find("policy \"exact\" [preset]"), std::string::npos) << ref;
  EXPECT_NE(ref.find("tangent_reuse 0 [compare reference]"), std::string::npos) << ref;
  EXPECT_EQ(ref.find("refresh_every"), std::string::npos) << ref;
  std::ifstream ej(path("e.json"));
  const auto je = nlohmann::json::parse(ej);
  for (const auto& row : je["policies"][0]["errors"]) EXPECT_LT(row["rel_l2_error"].get<double>(), 1e-10) << row;
  // No --policy: the scene's own (lagged from the preset) against the same reference.
  const Result own = incise("compare " + path("scene.json") + " --frames 1,3 --json " + path("o.json"));
  ASSERT_EQ(own.code, 0) << own.out;
  EXPECT_NE(own.out.find("--- lagged"), std::string::npos) << own.out;
  std::ifstream oj(path("o.json"));
  const auto jo = nlohmann::json::parse(oj);
  EXPECT_EQ(jo["policies"][0]["policy"], "lagged");
  const double err = jo["policies"][0]["errors"][1]["rel_l2_error"].get<double>();
  EXPECT_GT(err, 1e-12) << "lagged CG to 1e-3 is not the exact solve";
  EXPECT_LT(err, 1e-2);
}

// --reference-set changes the reference alone: a converged reference (a
// tight rotation tolerance, more iterations, the line search) against the
// scene's own exact run, which stops at the default 0.1 rad and so differs
// from it, while without it the two agree to roundoff.
TEST_F(Cli, CompareReferenceSetChangesTheReferenceOnly) {
  ASSERT_EQ(incise("mesh beam --size 4 1 1 --cells 8 2 2 --out " + path("beam.vtu")).code, 0);
  write("scene.json", R"({"mesh": {"file": "beam.vtu", "order": 2},
      "material": {"model": "corotated", "young": 1e4, "poisson": 0.3, "density": 100},
      "gravity": [0, 0, -10], "fixed": [{"box": [[-1, -1, -1], [0, 2, 2]]}]})");
  const std::string base = "compare " + path("scene.json") + " --policy exact --frames 1,10";
  const Result conv = incise(base + " --reference-set integrator.line_search=true --reference-set "
                                    "integrator.rotation_tolerance=1e-6 --reference-set "
                                    "integrator.max_newton_iterations=30 --json " + path("c.json"));
  ASSERT_EQ(conv.code, 0) << conv.out;
  const std::string ref = settings_block(conv.out, false);
  EXPECT_NE(ref.find("rotation_tolerance 1e-06 [--reference-set]"), std::string::npos) << ref;
  EXPECT_NE(ref.find("line_search true [--reference-set]"), std::string::npos) << ref;
  const std::string pol = conv.out.substr(conv.out.find("--- exact"));
  EXPECT_NE(pol.find("rotation_tolerance 0.1,"), std::string::npos) << pol;
  EXPECT_NE(pol.find("line_search false"), std::string::npos) << pol;
  std::ifstream cj(path("c.json"));
  const auto jc = nlohmann::json::parse(cj);
  EXPECT_GT(jc["policies"][0]["errors"][1]["rel_l2_error"].get<double>(), 1e-6) << "stopped at 0.1 rad";
  ASSERT_EQ(incise(base + " --json " + path("s.json")).code, 0);
  std::ifstream sj(path("s.json"));
  const auto js = nlohmann::json::parse(sj);
  EXPECT_LT(js["policies"][0]["errors"][1]["rel_l2_error"].get<double>(), 1e-12) << "the same settings";
  const Result bad = incise(base + " --reference-set integrator.line_search");
  EXPECT_NE(bad.code, 0);
  EXPECT_NE(bad.out.find("--reference-set integrator.line_search: expected KEY=VALUE"), std::string::npos) << bad.out;
}

// One set of flags serves every compared policy: a lagged-only flag is left
// out of the warped run (and says so) instead of failing it.
TEST_F(Cli, CompareLeavesOutFlagsAPolicyDoesNotUse) {
  cantilever_scene(R"(, "solver": {"policy": "lagged", "refresh_every": 2})");
  const Result r = incise("compare " + path("scene.json") + " --policy lagged,warped --max-iterations 80 --frames 1");
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("warped: without --max-iterations 80 (solver.max_iterations is not used by that policy)"),
            std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("warped: without the scene's solver.refresh_every"), std::string::npos) << r.out;
}

}  // namespace

namespace {

// --haptics: the scene's scripted device on its thread, frames paced at 1/dt;
// the force log, device stream, events and figures written, the tick
// statistics printed. A scene without a device starts no haptic thread.
TEST_F(Cli, RunHapticsWritesTheForceLogAndTickStatistics) {
  write("press.csv", "t,x,y,z,qw,qx,qy,qz\n0, 3.5, 0.5, 1.3, 1, 0, 0, 0\n0.2, 3.5, 0.5, 1.1, 1, 0, 0, 0\n");
  cantilever_scene(R"(, "instruments": [{"type": "probe", "name": "probe", "radius": 0.2, "trajectory": "press.csv"}],
      "haptics": {"device": "scripted", "realtime": false, "guard": {"workspace_radius": 10}})");
  const Result r = incise("run " + path("scene.json") + " --frames 9 --haptics --haptics-dir " + path("h"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("haptics: scripted (" + path("press.csv") + ") drives probe at 1000 Hz; SCHED_OTHER"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("frames started at 30 Hz"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("haptics: tick compute median"), std::string::npos) << r.out;
  std::ifstream log(path("h/haptics_force.csv"));
  std::string header, line;
  std::getline(log, header);
  EXPECT_EQ(header, "t,fx,fy,fz,tick_us,late_us");
  int rows = 0;
  while (std::getline(log, line)) ++rows;
  // 9 frames at 30 Hz are 0.3 s of 1 kHz ticks; on a loaded machine late
  // ticks skip the deadlines they missed (overrun events), so not all 300
  EXPECT_GT(rows, 30);
  std::ifstream js(path("h/haptics.json"));
  const auto j = nlohmann::json::parse(js);
  EXPECT_EQ(j["ticks"].get<int>(), rows);
  EXPECT_EQ(j["allocations"].get<int>(), 0);
  EXPECT_GT(j["force_max_n"].get<double>(), 0.1) << "the probe pressed the beam";
  EXPECT_LE(j["force_max_n"].get<double>(), 3.3 * (1 + 1e-12)) << "clamped to haptics.max_force";
  EXPECT_TRUE(fs::exists(path("h/haptics_device.csv")));
  EXPECT_TRUE(fs::exists(path("h/haptics_events.csv")));
  EXPECT_NE(r.out.find("contact_publish"), std::string::npos);
}

// SIGTERM (or Ctrl-C's SIGINT) during a long haptic run: it stops after the
// frame in progress, finishes the series, the tick logs and timing.json for
// the frames done, leaves no temporary file, and exits with 128 + 15. (A
// background job of a non-interactive shell ignores SIGINT, so the test
// sends SIGTERM.)
TEST_F(Cli, InterruptedRunFinishesItsOutputsForTheFramesDone) {
  write("press.csv", "t,x,y,z,qw,qx,qy,qz\n0, 3.5, 0.5, 1.3, 1, 0, 0, 0\n0.2, 3.5, 0.5, 1.1, 1, 0, 0, 0\n");
  cantilever_scene(R"(, "instruments": [{"type": "probe", "name": "probe", "radius": 0.2, "trajectory": "press.csv"}],
      "haptics": {"device": "scripted", "realtime": false, "guard": {"workspace_radius": 10}},
      "output": {"vtu": true, "every": 1})");
  // 1,000,000 frames paced at 30 Hz would take 9 hours: interrupted once
  // the third frame's file is there.
  const std::string cmd = "( " + std::string(INCISE_BINARY) + " run " + path("scene.json") +
                          " --frames 1000000 --haptics --out " + path("o") + " > " + path("run.log") +
                          " 2>&1 & pid=$!; for i in $(seq 600); do [ -f " + path("o/scene_000003.vtu") +
                          " ] && break; sleep 0.1; done; kill -TERM $pid; wait $pid; echo $? > " + path("rc") + " )";
  ASSERT_EQ(std::system(cmd.c_str()), 0);
  std::ifstream rc(path("rc")), log(path("run.log"));
  int code = -1;
  rc >> code;
  const std::string out((std::istreambuf_iterator<char>(log)), {});
  EXPECT_EQ(code, 128 + 15) << out;
  EXPECT_NE(out.find("interrupted by SIGTERM: stopped after frame "), std::string::npos) << out;
  // every frame the .pvd lists is there, and timing.json covers the frames done
  std::ifstream pvd(path("o/scene.pvd"));
  const std::string series((std::istreambuf_iterator<char>(pvd)), {});
  int listed = 0;
  for (size_t at = series.find("file=\""); at != std::string::npos; at = series.find("file=\"", at + 1)) {
    const size_t end = series.find('"', at + 6);
    EXPECT_TRUE(fs::exists(path("o/" + series.substr(at + 6, end - at - 6)))) << series.substr(at, end - at);
    ++listed;
  }
  EXPECT_GE(listed, 4);
  EXPECT_TRUE(fs::exists(path("o/timing.json")));
  std::ifstream js(path("o/haptics.json"));
  const auto j = nlohmann::json::parse(js);
  EXPECT_GT(j["ticks"].get<int>(), 0);
  for (const auto& e : fs::recursive_directory_iterator(dir_))
    EXPECT_EQ(e.path().string().find(".tmp"), std::string::npos) << e.path();
}

TEST_F(Cli, RunHapticsWithoutADeviceStartsNoThread) {
  cantilever_scene();
  const Result r = incise("run " + path("scene.json") + " --frames 2 --haptics --haptics-dir " + path("h"));
  ASSERT_EQ(r.code, 0) << r.out;
  EXPECT_NE(r.out.find("declares no haptic device (\"haptics\"): no haptic thread"), std::string::npos) << r.out;
  EXPECT_FALSE(fs::exists(path("h/haptics_force.csv")));
  EXPECT_EQ(r.out.find("frames started at"), std::string::npos) << "not paced without a device";
}

}  // namespace
