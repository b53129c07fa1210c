// Closed-form contact geometry against independent references: closest
// points, and the depth/normal convention for spheres, capsules and boxes.
#include "collision/narrowphase.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>

#include <Eigen/Geometry>

#include "tests/collision/collision_test_util.h"

namespace incise::test {
namespace {

using Eigen::Vector3d;

Vector3d random_vec(std::mt19937& rng, double scale) {
  std::uniform_real_distribution<double> U(-scale, scale);
  return Vector3d(U(rng), U(rng), U(rng));
}

TEST(Narrowphase, ClosestPointOnTriangleMatchesProjectionOrEdges) {
  std::mt19937 rng(3);
  for (int k = 0; k < 2000; ++k) {
    const Vector3d a = random_vec(rng, 1), b = random_vec(rng, 1), c = random_vec(rng, 1), p = random_vec(rng, 2);
    double bary[3];
    const Vector3d q = closest_point_on_triangle(p, a, b, c, bary);
    const Vector3d r = ref_closest_point(p, a, b, c);
    EXPECT_NEAR((q - p).norm(), (r - p).norm(), 1e-12) << "case " << k;
    EXPECT_LT((q - (bary[0] * a + bary[1] * b + bary[2] * c)).norm(), 1e-14);
    EXPECT_NEAR(bary[0] + bary[1] + bary[2], 1.0, 1e-14);
    for (double l : bary) EXPECT_GE(l, -1e-15);
  }
}

TEST(Narrowphase, SegmentTriangleDistanceIsTheMinimumAlongTheSegment) {
  std::mt19937 rng(5);
  for (int k = 0; k < 500; ++k) {
    const Vector3d a = random_vec(rng, 1), b = random_vec(rng, 1), c = random_vec(rng, 1);
    const Vector3d p = random_vec(rng, 1.5), q = random_vec(rng, 1.5);
    double t, bary[3];
    const double d2 = closest_segment_triangle(p, q, a, b, c, t, bary);
    // The distance to a convex set is convex along the segment: ternary search.
    auto dist = [&](double s) {
      const Vector3d x = p + s * (q - p);
      return (ref_closest_point(x, a, b, c) - x).norm();
    };
    double lo = 0, hi = 1;
    for (int it = 0; it < 200; ++it) {
      const double m1 = lo + (hi - lo) / 3, m2 = hi - (hi - lo) / 3;
      (dist(m1) < dist(m2) ? hi : lo) = (dist(m1) < dist(m2) ? m2 : m1);
    }
    const double ref = std::min({dist(0.0), dist(1.0), dist(0.5 * (lo + hi))});
    EXPECT_NEAR(std::sqrt(d2), ref, 1e-9) << "case " << k;
    // The reported pair is at that distance.
    const Vector3d x = bary[0] * a + bary[1] * b + bary[2] * c, y = p + t * (q - p);
    EXPECT_NEAR((x - y).norm(), std::sqrt(d2), 1e-12);
  }
}

// Triangle in the plane z = 0, outward normal +z.
const Vector3d T0(-1, -1, 0), T1(2, -1, 0), T2(-1, 2, 0);

TEST(Narrowphase, SphereOverAFacePushesTheTissueInwardByRadiusMinusDistance) {
  TriangleContact c;
  const Vector3d centre(0.2, 0.1, 0.3);
  ASSERT_TRUE(round_triangle_contact(centre, centre, 0.5, T0, T1, T2, c));
  EXPECT_NEAR(c.depth, 0.5 - 0.3, 1e-15);
  EXPECT_LT((c.normal - Vector3d(0, 0, -1)).norm(), 1e-15);
  EXPECT_LT((c.point - Vector3d(0.2, 0.1, 0)).norm(), 1e-15);
  EXPECT_FALSE(round_triangle_contact(Vector3d(0, 0, 0.5), Vector3d(0, 0, 0.5), 0.5, T0, T1, T2, c)) << "touching is no contact";
}

TEST(Narrowphase, ASphereThroughTheFaceStillPushesInward) {
  // Centre 0.2 below the face: the tissue point must go down by r + 0.2, not up.
  TriangleContact c;
  const Vector3d centre(0.2, 0.1, -0.2);
  ASSERT_TRUE(round_triangle_contact(centre, centre, 0.5, T0, T1, T2, c));
  EXPECT_NEAR(c.depth, 0.7, 1e-15);
  EXPECT_LT((c.normal - Vector3d(0, 0, -1)).norm(), 1e-15);
  // Continuous through the face: just above and just below agree.
  TriangleContact up, down;
  ASSERT_TRUE(round_triangle_contact(Vector3d(0.2, 0.1, 1e-9), Vector3d(0.2, 0.1, 1e-9), 0.5, T0, T1, T2, up));
  ASSERT_TRUE(round_triangle_contact(Vector3d(0.2, 0.1, -1e-9), Vector3d(0.2, 0.1, -1e-9), 0.5, T0, T1, T2, down));
  EXPECT_NEAR(up.depth, down.depth, 3e-9);
  EXPECT_LT((up.normal - down.normal).norm(), 1e-12);
}

// The exit of a ray from a sphere and a capsule, against a scan of the
// distance to the axis along the ray refined by bisection.
TEST(Narrowphase, ARaysExitFromARoundSolidIsTheFarEndOfItsInsideInterval) {
  const double inf = std::numeric_limits<double>::infinity();
  // A sphere: from its centre, r along any direction; a ray past it misses.
  EXPECT_NEAR(round_exit_distance(Vector3d(1, 2, 3), Vector3d(1, 2, 3), 0.5, Vector3d(1, 2, 3), Vector3d(0, 0, -1)),
              0.5, 1e-15);
  EXPECT_NEAR(round_exit_distance(Vector3d(0, 0, 0), Vector3d(0, 0, 0), 0.5, Vector3d(0.3, 0, 2), Vector3d(0, 0, -1)),
              2 + 0.4, 1e-14);
  EXPECT_EQ(round_exit_distance(Vector3d(0, 0, 0), Vector3d(0, 0, 0), 0.5, Vector3d(0.6, 0, 2), Vector3d(0, 0, -1)),
            -inf);
  std::mt19937 rng(7);
  auto axis_distance = [](const Vector3d& a, const Vector3d& b, const Vector3d& y) {
    const Vector3d ab = b - a;
    const double l2 = ab.squaredNorm(), t = l2 > 0 ? std::clamp((y - a).dot(ab) / l2, 0.0, 1.0) : 0.0;
    return (a + t * ab - y).norm();
  };
  int hits = 0;
  for (int trial = 0; trial < 200; ++trial) {
    const Vector3d a = random_vec(rng, 1), b = trial % 4 == 0 ? a : Vector3d(random_vec(rng, 1)), x = random_vec(rng, 2);
    const double r = 0.2 + 0.5 * std::abs(random_vec(rng, 1)[0]);
    // Aimed near the axis's midpoint: most rays cross the solid, some miss.
    const Vector3d n = (0.5 * (a + b) + random_vec(rng, 0.8) - x).normalized();
    double last_in = -inf;
    const int m = 40000;
    for (int k = 0; k <= m; ++k) {
      const double sv = -10 + 20.0 * k / m;
      if (axis_distance(a, b, x + sv * n) <= r) last_in = sv;
    }
    const double got = round_exit_distance(a, b, r, x, n);
    if (last_in == -inf) {
      EXPECT_EQ(got, -inf) << trial;
      continue;
    }
    ++hits;
    double lo = last_in, hi = last_in + 20.0 / m;
    for (int it = 0; it < 60; ++it) (axis_distance(a, b, x + 0.5 * (lo + hi) * n) <= r ? lo : hi) = 0.5 * (lo + hi);
    EXPECT_NEAR(got, lo, 1e-9) << trial;
  }
  EXPECT_GT(hits, 100);
  EXPECT_LT(hits, 200) << "some rays miss";
}

TEST(Narrowphase, SphereBesideAnEdgeGetsTheGeometricNormal) {
  // Centre beyond edge T0-T1 (y = -1), above the plane: closest point on the edge.
  TriangleContact c;
  const Vector3d centre(0.5, -1.3, 0.4);
  ASSERT_TRUE(round_triangle_contact(centre, centre, 0.6, T0, T1, T2, c));
  EXPECT_NEAR(c.depth, 0.6 - 0.5, 1e-15);
  EXPECT_LT((c.point - Vector3d(0.5, -1, 0)).norm(), 1e-15);
  EXPECT_LT((c.normal - Vector3d(0, 0.6, -0.8)).norm(), 1e-15);
}

TEST(Narrowphase, CapsuleLyingOnAFaceAndPokingThroughIt) {
  TriangleContact c;
  // Axis parallel to the face at height 0.1: depth r - 0.1.
  ASSERT_TRUE(round_triangle_contact(Vector3d(-0.5, 0, 0.1), Vector3d(0.5, 0, 0.1), 0.25, T0, T1, T2, c));
  EXPECT_NEAR(c.depth, 0.15, 1e-15);
  EXPECT_LT((c.normal - Vector3d(0, 0, -1)).norm(), 1e-15);
  // Axis through the face, its lower end 0.3 under it (further than r from
  // the crossing): the face goes to the tangent plane of the part of the
  // tool within r of its point, r below the crossing along the axis.
  ASSERT_TRUE(round_triangle_contact(Vector3d(0, 0, 0.5), Vector3d(0.1, 0, -0.3), 0.25, T0, T1, T2, c));
  EXPECT_NEAR(c.depth, 0.25 + 0.25 * 0.8 / std::hypot(0.1, 0.8), 1e-14);
  EXPECT_LT((c.normal - Vector3d(0, 0, -1)).norm(), 1e-15);
  EXPECT_NEAR(c.point.z(), 0.0, 1e-15);
  // A 2 m shaft through the face at 45 degrees, pierced at its middle:
  // r (1 + sin 45), not r + 0.7 (its lower end's tangent plane).
  ASSERT_TRUE(round_triangle_contact(Vector3d(-0.7, 0, 0.7), Vector3d(0.7, 0, -0.7), 0.25, T0, T1, T2, c));
  EXPECT_NEAR(c.depth, 0.25 * (1 + std::sqrt(0.5)), 1e-14);
  // A vertical shaft whose tip is 3 under the face: 2r, not r + 3.
  ASSERT_TRUE(round_triangle_contact(Vector3d(0, 0, -3), Vector3d(0, 0, 2), 0.25, T0, T1, T2, c));
  EXPECT_NEAR(c.depth, 0.5, 1e-14);
}

// A shaft pressed down beside a face (the face's edge at y = -1, the
// vertical axis 0.3 beyond it): the face is pushed aside, radially, by r - d,
// whichever side of the face's plane the axis's nearest point lies on.
// The face rule took a face tilted a little past the axis for one the shaft
// came through and pushed it below the tip: depth r + 0.8 here.
TEST(Narrowphase, AShaftBesideAFacePushesItAsideWhicheverWayTheFaceTilts) {
  const double r = 0.4;
  const Vector3d tip(0.5, -1.3, -0.8), top(0.5, -1.3, 2.0);
  int behind = 0;
  for (double tilt : {-0.05, 0.0, 0.05}) {
    const Eigen::Matrix3d R = Eigen::AngleAxisd(tilt, Vector3d(1, 0, 0)).toRotationMatrix();
    const Vector3d v0 = R * T0, v1 = R * T1, v2 = R * T2, n = (v1 - v0).cross(v2 - v0).normalized();
    TriangleContact c;
    ASSERT_TRUE(round_triangle_contact(tip, top, r, v0, v1, v2, c)) << tilt;
    const Vector3d y = nearest_on_segment(tip, top, c.point);
    const double d = (c.point - y).norm();
    behind += (y - c.point).dot(n) < 0;
    EXPECT_NEAR(d, 1.3 - std::cos(tilt), 1e-12) << tilt;  // the edge's nearest point
    EXPECT_NEAR(c.depth, r - d, 1e-14) << tilt;
    EXPECT_LT((c.normal - (c.point - y) / d).norm(), 1e-14) << tilt;
    EXPECT_LT(std::abs(c.normal.z()), 0.06) << tilt;  // sideways, not down
  }
  EXPECT_GE(behind, 1) << "one tilt puts the axis behind the face's plane";
  // The tip (an end of the axis) under the face's interior keeps the face
  // rule: the tissue must clear it.
  TriangleContact c;
  ASSERT_TRUE(round_triangle_contact(Vector3d(0, 0, -0.1), Vector3d(0, 0, 2), r, T0, T1, T2, c));
  EXPECT_NEAR(c.depth, r + 0.1, 1e-14);
  EXPECT_LT((c.normal - Vector3d(0, 0, -1)).norm(), 1e-15);
}

// A sphere whose centre is behind the plane of a triangle it lies beside
// (nearest point on the edge y = -1): the face rule pushes the triangle to
// the sphere's far tangent plane; with edges_geometric (triangle rows) it
// is pushed away from the centre, as off an edge above the plane.
TEST(Narrowphase, ASphereBehindAnEdgesPlaneIsGeometricWithEdgesGeometric) {
  const Vector3d centre(0.5, -1.3, -0.2);
  const double r = 0.6;
  TriangleContact c;
  ASSERT_TRUE(round_triangle_contact(centre, centre, r, T0, T1, T2, c));
  EXPECT_NEAR(c.depth, r + 0.2, 1e-15);
  EXPECT_LT((c.normal - Vector3d(0, 0, -1)).norm(), 1e-15);
  ASSERT_TRUE(round_triangle_contact(centre, centre, r, T0, T1, T2, c, true));
  EXPECT_LT((c.point - Vector3d(0.5, -1, 0)).norm(), 1e-15);
  EXPECT_NEAR(c.depth, r - std::hypot(0.3, 0.2), 1e-15);
  EXPECT_LT((c.normal - Vector3d(0, 0.3, 0.2) / std::hypot(0.3, 0.2)).norm(), 1e-15);
  // Over the triangle's interior the face rule stays either way.
  ASSERT_TRUE(round_triangle_contact(Vector3d(0, 0, -0.2), Vector3d(0, 0, -0.2), r, T0, T1, T2, c, true));
  EXPECT_NEAR(c.depth, r + 0.2, 1e-15);
  EXPECT_LT((c.normal - Vector3d(0, 0, -1)).norm(), 1e-15);
}

TEST(Narrowphase, BoxPressedIntoAFaceHasDepthAlongTheInwardNormal) {
  TriangleContact c;
  const Eigen::Matrix3d I = Eigen::Matrix3d::Identity();
  const Vector3d half(0.2, 0.1, 0.3);
  // Bottom face at z = -0.05.
  ASSERT_TRUE(box_triangle_contact(Vector3d(0, 0, 0.25), I, half, T0, T1, T2, c));
  EXPECT_NEAR(c.depth, 0.05, 1e-15);
  EXPECT_LT((c.normal - Vector3d(0, 0, -1)).norm(), 1e-15);
  EXPECT_NEAR(c.point.z(), 0.0, 1e-15);
  EXPECT_LE(std::abs(c.point.x()), 0.2 + 1e-15);
  // Deeper than its half height: still inward, depth = the bottom face's.
  ASSERT_TRUE(box_triangle_contact(Vector3d(0, 0, -0.2), I, half, T0, T1, T2, c));
  EXPECT_NEAR(c.depth, 0.5, 1e-15);
  EXPECT_LT((c.normal - Vector3d(0, 0, -1)).norm(), 1e-15);
  // A box off the triangle's prism gives nothing.
  EXPECT_FALSE(box_triangle_contact(Vector3d(3, 3, 0), I, half, T0, T1, T2, c));
}

TEST(Narrowphase, TiltedBoxCornerDepthAndAPartlyOverhangingBox) {
  TriangleContact c;
  // Unit cube turned so its diagonal (1,1,1) points along -z: the lowest
  // corner is sqrt(3)/2 under the centre.
  const Eigen::Matrix3d R =
      Eigen::Quaterniond::FromTwoVectors(Vector3d(1, 1, 1).normalized(), Vector3d(0, 0, -1)).toRotationMatrix();
  const Vector3d half(0.5, 0.5, 0.5);
  ASSERT_TRUE(box_triangle_contact(Vector3d(0, 0, 0.8), R, half, T0, T1, T2, c));
  EXPECT_NEAR(c.depth, std::sqrt(3.0) / 2 - 0.8, 1e-14);
  EXPECT_LT((c.point - Vector3d(0, 0, 0)).norm(), 1e-14);
  // A flat box overhanging the edge x + y = 1 of the triangle: only the part
  // over the triangle counts, and its lowest point there is the bottom face.
  const Eigen::Matrix3d tilt = Eigen::AngleAxisd(0.1, Vector3d(0, 1, 0)).toRotationMatrix();  // lower towards +x
  ASSERT_TRUE(box_triangle_contact(Vector3d(1.4, 0, 0.05), tilt, Vector3d(1, 0.2, 0.1), T0, T1, T2, c));
  // Bottom face: z = 0.05 - 0.1 cos(0.1) + (x - 1.4) (-sin 0.1)... lowest over the triangle where x is largest:
  // on the triangle's hypotenuse x + y = 1 at y = -0.2 cos-free (box y in [-0.2, 0.2]): x = 1.2.
  const double zc = 0.05, s = std::sin(0.1), co = std::cos(0.1);
  // Box point b = centre + tilt * (lx, ly, -0.1): z = zc - s lx - 0.1 co, x = 1.4 + co lx - 0.1 s.
  const double lx = (1.2 - 1.4 + 0.1 * s) / co;
  EXPECT_NEAR(c.depth, -(zc - s * lx - 0.1 * co), 1e-12);
  EXPECT_NEAR(c.point.x() + c.point.y(), 1.0, 1e-12);
}

}  // namespace
}  // namespace incise::test
