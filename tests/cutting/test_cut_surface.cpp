// Cut-surface validation (issue 24): OBJ/STL readers, polygon checks, scaled
// normals, and the warning for a cut that cuts nothing.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "cutting/cut_apply.h"
#include "cutting/cut_surface.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/util/error.h"
#include "engine/dynamics/step.h"
#include "test_util.h"

namespace incise {
namespace {

std::string temp_file(const std::string& name, const std::string& text) {
  const std::string p = (std::filesystem::temp_directory_path() / ("incise_cs_" + name)).string();
  std::ofstream(p, std::ios::binary) << text;
  return p;
}

// The message of the Error read_triangle_surface throws ("" if none).
std::string read_error(const std::string& name, const std::string& text) {
  const std::string p = temp_file(name, text);
  try {
    read_triangle_surface(p);
  } catch (const Error& e) {
    std::filesystem::remove(p);
    return e.what();
  }
  std::filesystem::remove(p);
  return "";
}

std::string polygon_error(std::vector<Vec3> pts) {
  CutSpec c;
  c.type = CutSpec::Type::Polygon;
  c.json_path = "cuts[0]";
  c.points = std::move(pts);
  try {
    make_cut_surface(c, 0.0);
  } catch (const Error& e) {
    return e.what();
  }
  return "";
}

#define EXPECT_HAS(msg, part) EXPECT_NE(std::string(msg).find(part), std::string::npos) << (msg)

TEST(CutSurface, ObjFaceIndicesOverflowAndZeroAreRefused) {
  const std::string v = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  EXPECT_HAS(read_error("ovf.obj", v + "f 1 2 4294967298\n"), "incise_cs_ovf.obj:4: face references vertex 4294967298, but only 3 are defined");
  EXPECT_HAS(read_error("ovf2.obj", v + "f 1 2 99999999999999999999999\n"),
             "incise_cs_ovf2.obj:4: face vertex 99999999999999999999999 is not an integer index in range");
  EXPECT_HAS(read_error("zero.obj", v + "f 0 1 2\n"), "face references vertex 0, but only 3 are defined (indices are 1..3, or -1..-3 counting back)");
  EXPECT_HAS(read_error("junk.obj", v + "f 1 2 x3\n"), "face vertex x3 is not an integer index in range");
  EXPECT_HAS(read_error("neg.obj", v + "f -1 -2 -4\n"), "face references vertex -4");
  EXPECT_EQ(read_error("rel.obj", v + "f -3/1/1 -2//2 -1\n"), "");  // relative indices and v/vt/vn forms
}

TEST(CutSurface, ObjFaceArityIsBounded) {
  std::string v, f = "f";
  for (int k = 0; k < 17; ++k) {
    const double a = 2 * 3.141592653589793 * k / 17;
    v += "v " + std::to_string(std::cos(a)) + " " + std::to_string(std::sin(a)) + " 0\n";
    f += " " + std::to_string(k + 1);
  }
  EXPECT_HAS(read_error("big.obj", v + f + "\n"), ":18: face lists more than 16 vertices; allowed: 3 to 16 (triangulate larger polygons)");
  // A face listing millions of indices stops at the 17th.
  std::string huge = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf";
  for (int k = 0; k < 1000000; ++k) huge += " 1";
  EXPECT_HAS(read_error("huge.obj", huge + "\n"), "face lists more than 16 vertices");
  EXPECT_HAS(read_error("two.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n"), ":3: face needs at least 3 vertices, got 2");
  // Quads are fine when planar and convex; a bow-tie or a bent quad is not.
  const std::string sq = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\n";
  const std::string p = temp_file("quad.obj", sq + "f 1 2 3 4\n");
  EXPECT_EQ(read_triangle_surface(p).size(), 2u);
  std::filesystem::remove(p);
  EXPECT_HAS(read_error("bow.obj", sq + "f 1 3 2 4\n"), ":5: face: polygon has zero area");  // its halves cancel
  EXPECT_HAS(read_error("arrow.obj", "v 0 0 0\nv 2 1 0\nv 0 2 0\nv 1 1 0\nf 1 2 3 4\n"),
             ":5: face: polygon must be convex; the turn at its vertex 4 goes the other way");
  EXPECT_HAS(read_error("bent.obj", "v 0 0 0\nv 1 0 0\nv 1 1 0.5\nv 0 1 0\nf 1 2 3 4\n"), "polygon is not planar");
}

TEST(CutSurface, DegenerateTrianglesAreRefused) {
  EXPECT_HAS(read_error("col.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n"),
             ":4: triangle has zero area (its corners are collinear or repeated); remove it");
  EXPECT_HAS(read_error("rep.obj", "v 0 0 0\nv 1 0 0\nf 1 2 2\n"), "triangle has zero area");
  EXPECT_HAS(read_error("col.stl", "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 1 1\nvertex 2 2 2\n"
                                   "endloop\nendfacet\nendsolid s\n"),
             "incise_cs_col.stl:4: triangle has zero area");
}

TEST(CutSurface, StlFacetsHaveExactlyThreeVertices) {
  const std::string head = "solid s\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n";
  EXPECT_HAS(read_error("four.stl", head + "vertex 1 1 0\nvertex 0 1 0\nendloop\nendfacet\n"),
             ":7: a facet lists more than 3 vertices; ASCII STL facets are triangles");
  EXPECT_HAS(read_error("two.stl", head + "endloop\nendfacet\n"), ":6: a facet ends after 2 vertices");
  EXPECT_HAS(read_error("cut.stl", head), ":4: the file ends inside a facet (2 of 3 vertices, no endloop)");
}

TEST(CutSurface, TinyAndHugeTrianglesGetUnitNormals) {
  for (double s : {4e-323, 1e-310, 1e-200, 1e-30, 1.0, 1e30, 1e200}) {  // (the first two subnormal)
    char text[256];
    std::snprintf(text, sizeof text, "v 0 0 0\nv %.17g 0 0\nv 0 %.17g 0\nf 1 2 3\n", s, s);
    const std::string p = temp_file("scale.obj", text);
    const std::vector<Facet> f = read_triangle_surface(p);
    std::filesystem::remove(p);
    ASSERT_EQ(f.size(), 1u) << s;
    EXPECT_DOUBLE_EQ(f[0].n[2], 1.0) << s;
    EXPECT_EQ(f[0].n[0], 0.0) << s;
  }
  // Far from the origin: the corners' differences would overflow.
  const std::string p = temp_file("far.obj", "v -1e308 -1e308 0\nv 1e308 -1e308 0\nv -1e308 1e308 0\nf 1 2 3\n");
  const std::vector<Facet> f = read_triangle_surface(p);
  std::filesystem::remove(p);
  EXPECT_DOUBLE_EQ(f[0].n[2], 1.0);
}

TEST(CutSurface, PolygonsMustBeSimpleConvexPlanarWithArea) {
  // A pentagram turns the same way at every point but crosses itself.
  std::vector<Vec3> star;
  for (int k = 0; k < 5; ++k) {
    const double a = 2 * 3.141592653589793 * (2 * k) / 5;
    star.push_back({std::cos(a), std::sin(a), 0.5});
  }
  EXPECT_HAS(polygon_error(star), "cuts[0].points: polygon is not simple: its edges cross (it winds 2 times around its centre)");
  EXPECT_HAS(polygon_error({{0, 0, 0}, {1, 0, 0}, {2, 0, 0}}), "cuts[0].points: polygon has zero area (its points are collinear)");
  EXPECT_HAS(polygon_error({{1, 1, 1}, {1, 1, 1}, {1, 1, 1}}), "polygon has zero area (all its points coincide)");
  EXPECT_HAS(polygon_error({{0, 0, 0}, {1, 0, 0}, {1, 0, 0}, {0, 1, 0}}),
             "cuts[0].points: polygon repeats a point: points[1] and the next one coincide");
  EXPECT_HAS(polygon_error({{0, 0, 0}, {1, 0, 0}, {1, 1, 0.5}, {0, 1, 0}}), "cuts[0].points[0]: polygon is not planar");
  // Tiny and huge squares: valid, with a unit normal (no underflow, no NaN).
  for (double s : {1e-315, 1e-200, 1e-150, 1e150, 1e300}) {
    CutSpec c;
    c.type = CutSpec::Type::Polygon;
    c.json_path = "cuts[0]";
    c.points = {{0, 0, 0}, {s, 0, 0}, {s, s, 0}, {0, s, 0}};
    const auto surf = make_cut_surface(c, 0.0);
    ASSERT_TRUE(surf) << s;
    ASSERT_EQ(surf->facets().size(), 4u) << s;
    EXPECT_DOUBLE_EQ(surf->facets()[0].n[2], 1.0) << s;
  }
}

TEST(CutSurface, ACutThatCutsNothingIsReported) {
  Scene s = test::block_scene(1);
  s.path = "scene.json";
  s.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
  s.cuts = {test::plane_cut({2.3, 0, 0}, {1, 0, 0}), test::plane_cut({9, 0, 0}, {1, 0, 0}, "cuts[1]")};
  CutSpec poly;  // in the plane x = 2.5 but beside the body (y in [3, 4])
  poly.type = CutSpec::Type::Polygon;
  poly.json_path = "cuts[2]";
  poly.points = {{2.5, 3, 0}, {2.5, 4, 0}, {2.5, 4, 1}, {2.5, 3, 1}};
  s.cuts.push_back(poly);
  // The same beside the body in x = 2.3, a plane through elements (they
  // straddle it, but the polygon's boundary passes through none of them).
  poly.json_path = "cuts[3]";
  for (auto& p : poly.points) p[0] = 2.3;
  s.cuts.push_back(poly);
  auto sim = test::make_sim(make_beam(4, 1, 1, 8, 2, 2, 1), s);
  const std::vector<std::string> w = cuts_that_cut_nothing(*sim);
  ASSERT_EQ(w.size(), 3u);
  EXPECT_EQ(w[0], "scene.json: cuts[1] does not cross the body: it cuts nothing");
  EXPECT_EQ(w[1], "scene.json: cuts[2] does not cross the body: it cuts nothing");
  EXPECT_EQ(w[2], "scene.json: cuts[3] does not cross the body: it cuts nothing");
}


// A triangle with its plane (unit normal by the winding).
Facet facet_of(const Vec3& a, const Vec3& b, const Vec3& c) {
  Facet f;
  f.v = {a, b, c};
  const double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
  const double l = std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  f.n = {n[0] / l, n[1] / l, n[2] / l};
  f.p = a;
  return f;
}

// A surface of many facets (a long incision's has a thousand) is searched
// through an AABB tree. Its queries must return what the scan over every
// facet returns, to the bit: the nearest facet of least distance and, among
// equally near ones, the lowest index (a vertex is at distance 0 from the
// six facets around it); covers and crosses_segment true where any facet
// takes the point or segment. The reference is each facet alone (a surface
// of one facet is scanned, and measures with the same code).
TEST(CutSurfaceTree, QueriesReturnWhatTheScanOverEveryFacetReturns) {
  // A bumpy 14 x 10 height field, with a flat part (exact ties above it).
  const int nx = 14, ny = 10;
  const double h = 0.01;
  auto z = [&](int i, int j) { return i < 5 ? 0.0 : 0.004 * std::sin(1.3 * i) * std::cos(0.9 * j); };
  std::vector<Vec3> vert;
  for (int j = 0; j <= ny; ++j)
    for (int i = 0; i <= nx; ++i) vert.push_back({i * h, j * h, z(i, j)});
  std::vector<Facet> facets;
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const int a = j * (nx + 1) + i, b = a + 1, c = a + nx + 1, d = c + 1;
      facets.push_back(facet_of(vert[a], vert[b], vert[d]));
      facets.push_back(facet_of(vert[a], vert[d], vert[c]));
    }
  const CutSurface s(facets, "field");
  ASSERT_EQ(s.facets().size(), facets.size());
  std::vector<CutSurface> single;
  for (const Facet& f : facets) single.emplace_back(std::vector<Facet>{f}, "one");

  std::vector<Vec3> points = vert;  // on the surface: ties between the facets around a vertex
  for (int j = 0; j < ny; ++j)
    for (int i = 0; i < nx; ++i) {
      const Vec3& a = vert[j * (nx + 1) + i];
      points.push_back({a[0] + 0.5 * h, a[1], a[2]});           // an edge's midpoint (flat part: on it)
      points.push_back({a[0], a[1], a[2] + 0.3 * h});          // above a vertex
      points.push_back({a[0] + 0.25 * h, a[1] + 0.7 * h, -0.02});  // below
    }
  std::uint64_t seed = 12345;
  auto uniform = [&](double lo, double hi) {
    seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
    return lo + (hi - lo) * static_cast<double>(seed >> 11) / 9007199254740992.0;
  };
  for (int k = 0; k < 400; ++k) points.push_back({uniform(-0.05, 0.19), uniform(-0.05, 0.15), uniform(-0.05, 0.05)});

  int ties = 0;
  for (const Vec3& x : points) {
    int first = -1;
    double best = 1e300;
    int at_best = 0;
    for (size_t k = 0; k < facets.size(); ++k) {
      const double d = single[k].distance(x.data());
      if (d < best) best = d, first = static_cast<int>(k), at_best = 1;
      else if (d == best) ++at_best;
    }
    ties += at_best > 1;
    EXPECT_EQ(&s.nearest(x.data()) - s.facets().data(), first) << x[0] << " " << x[1] << " " << x[2];
    EXPECT_EQ(s.distance(x.data()), best);
    for (double tol : {1e-9, 0.2 * h}) {
      bool covered = false;
      for (const CutSurface& o : single) covered = covered || o.covers(x.data(), tol);
      EXPECT_EQ(s.covers(x.data(), tol), covered) << tol;
    }
    // Segments from x to a point across the surface and to a point beside it.
    for (const Vec3& y : {Vec3{x[0] + 0.3 * h, x[1] - 0.2 * h, -x[2] + 0.001}, Vec3{x[0] + 2 * h, x[1], x[2]}}) {
      bool crossed = false;
      for (const CutSurface& o : single) crossed = crossed || o.crosses_segment(x.data(), y.data(), 1e-9);
      EXPECT_EQ(s.crosses_segment(x.data(), y.data(), 1e-9), crossed);
    }
  }
  EXPECT_GT(ties, 100);  // the vertices and the points above the flat part
}

}  // namespace
}  // namespace incise
