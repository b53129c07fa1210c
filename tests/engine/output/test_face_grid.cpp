// The face grid shared by the renderer and the collision surface.
#include "engine/output/face_grid.h"

#include <gtest/gtest.h>

#include "engine/util/error.h"

namespace incise {
namespace {

TEST(FaceGrid, CountsWeightsAndCounterClockwiseTrianglesCoveringTheFace) {
  for (int n : {1, 2, 3, 5}) {
    const FaceGrid g = face_grid(n);
    ASSERT_EQ(g.verts_per_face, (n + 1) * (n + 2) / 2);
    ASSERT_EQ(g.tris_per_face, n * n);
    ASSERT_EQ(g.weights.size(), 3u * g.verts_per_face);
    ASSERT_EQ(g.tris.size(), 3u * g.tris_per_face);
    for (int v = 0; v < g.verts_per_face; ++v) {
      EXPECT_EQ(g.steps[3 * v] + g.steps[3 * v + 1] + g.steps[3 * v + 2], n);
      for (int k = 0; k < 3; ++k) EXPECT_EQ(g.weights[3 * v + k], static_cast<double>(g.steps[3 * v + k]) / n);
    }
    // In (xi, eta) = (L1, L2) every triangle has area 1 / (2 n^2) > 0
    // (counter-clockwise like the face's corners); together they cover 1/2.
    double total = 0;
    for (int t = 0; t < g.tris_per_face; ++t) {
      const int* v = &g.tris[3 * t];
      const double* a = &g.weights[3 * v[0]];
      const double* b = &g.weights[3 * v[1]];
      const double* c = &g.weights[3 * v[2]];
      const double area = 0.5 * ((b[1] - a[1]) * (c[2] - a[2]) - (b[2] - a[2]) * (c[1] - a[1]));
      EXPECT_NEAR(area, 0.5 / (n * n), 1e-15) << "n " << n << " triangle " << t;
      total += area;
    }
    EXPECT_NEAR(total, 0.5, 1e-14);
  }
  EXPECT_EQ(face_segments(2, 1), 2) << "curved faces get at least 4 triangles";
  EXPECT_EQ(face_segments(2, 5), 5);
  EXPECT_EQ(face_segments(1, 5), 1) << "flat faces are one triangle";
  EXPECT_THROW(face_grid(0), Error);
}

}  // namespace
}  // namespace incise
