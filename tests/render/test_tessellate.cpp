// Curved tet10 faces as flat triangles: positions on the quadratic face,
// normals smooth within a surface, sharp at creases and across a cut.
#include "render/tessellate.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "render_test_util.h"

namespace incise::test {
namespace {

double norm3(const float* v) { return std::sqrt(double(v[0]) * v[0] + double(v[1]) * v[1] + double(v[2]) * v[2]); }

struct Tess {
  Surface s;
  Tessellation t;
  std::vector<float> pos, nrm;
};
Tess run(const DisplayMesh& d, int segments) {
  Tess r;
  r.s = extract_surface(d);
  r.t = build_tessellation(r.s, d, segments);
  std::vector<double> work;
  tessellate(r.s, r.t, d, r.pos, r.nrm, work);
  return r;
}

TEST(Tessellate, TrianglesPerFaceFollowTheSubdivision) {
  const DisplayMesh d10 = display_of(make_beam(1, 1, 1, 1, 1, 1, 2));
  for (int n : {2, 3, 5}) {
    const Tess r = run(d10, n);
    EXPECT_EQ(r.t.tris.size(), 3u * n * n * r.s.nface()) << n;
    EXPECT_EQ(r.t.nvert(), (n + 1) * (n + 2) / 2 * r.s.nface()) << n;
  }
  EXPECT_EQ(run(d10, 1).t.segments, 2) << "curved faces get at least 4 triangles";
  const DisplayMesh d4 = display_of(make_beam(1, 1, 1, 1, 1, 1, 1));
  const Tess r4 = run(d4, 4);
  EXPECT_EQ(r4.t.tris.size(), 3u * r4.s.nface()) << "flat tet4 faces are one triangle";
}

TEST(Tessellate, SphereVerticesLieOnTheCurvedSurfaceWithRadialNormals) {
  const DisplayMesh d = display_of(read_mesh(source_path("assets/meshes/sphere_tet10.msh")));
  const Tess r = run(d, 4);
  ASSERT_GT(r.s.nboundary, 50);
  double worst_r = 0, worst_cos = 1;
  for (int v = 0; v < r.t.nvert(); ++v) {
    const float* p = &r.pos[3 * v];
    const float* n = &r.nrm[3 * v];
    const double rad = norm3(p);
    worst_r = std::max(worst_r, std::fabs(rad - 1.0));
    worst_cos = std::min(worst_cos, (p[0] * n[0] + p[1] * n[1] + p[2] * n[2]) / rad);
    EXPECT_NEAR(norm3(n), 1.0, 1e-6);
  }
  // Quadratic faces follow the unit sphere to about a percent at this coarse
  // size (flat faces of the same mesh would be ~10% inside at face centres).
  EXPECT_LT(worst_r, 0.02);
  EXPECT_GT(worst_cos, 0.99) << "normals must be close to radial";
}

TEST(Tessellate, NormalsAreSharedWhereVerticesCoincideOnOneSurface) {
  const DisplayMesh d = display_of(read_mesh(source_path("assets/meshes/sphere_tet10.msh")));
  const Tess r = run(d, 2);
  std::map<std::array<float, 3>, std::array<float, 3>> seen;
  int shared = 0;
  for (int v = 0; v < r.t.nvert(); ++v) {
    const std::array<float, 3> p{r.pos[3 * v], r.pos[3 * v + 1], r.pos[3 * v + 2]};
    const std::array<float, 3> n{r.nrm[3 * v], r.nrm[3 * v + 1], r.nrm[3 * v + 2]};
    auto [it, fresh] = seen.insert({p, n});
    if (!fresh) {
      ++shared;
      EXPECT_EQ(it->second, n) << "vertex at " << p[0] << " " << p[1] << " " << p[2];
    }
  }
  EXPECT_GT(shared, r.t.nvert() / 2);
}

TEST(Tessellate, BlockEdgesStaySharp) {
  const DisplayMesh d = display_of(make_beam(1, 1, 1, 2, 2, 2, 2));
  const Tess r = run(d, 2);
  // Flat faces of a box: every vertex normal is the face's axis.
  for (int v = 0; v < r.t.nvert(); ++v) {
    const float* n = &r.nrm[3 * v];
    const double m = std::max({std::fabs(n[0]), std::fabs(n[1]), std::fabs(n[2])});
    EXPECT_NEAR(m, 1.0, 1e-6) << "vertex " << v << " has a blended normal at a crease";
  }
}

TEST(Tessellate, CutFacesNeverShareNormalsWithTheBoundary) {
  const DisplayMesh d = split_block(display_of(make_beam(2, 1, 1, 4, 2, 2, 2)), 1.0, 0.2);
  const Tess r = run(d, 2);
  ASSERT_GT(r.s.ncut, 0);
  const int vpf = r.t.verts_per_face;
  std::vector<int> kind(r.t.ngroup, -1);
  for (int v = 0; v < r.t.nvert(); ++v) {
    const int k = v / vpf < r.s.nboundary ? 0 : 1;
    int& g = kind[r.t.group[v]];
    EXPECT_TRUE(g < 0 || g == k) << "group " << r.t.group[v] << " mixes boundary and cut vertices";
    g = k;
    if (k == 1) {
      EXPECT_NEAR(std::fabs(r.nrm[3 * v]), 1.0, 1e-6) << "cut faces are the plane x = 1: normal +-x";
    }
  }
}

}  // namespace
}  // namespace incise::test
