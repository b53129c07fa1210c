// Contacts of instruments with a cut, deformed block: FCL's triangles equal a
// brute-force test of every triangle; each contact's weights reproduce its
// point and belong to its own side of the cut; depths of known shapes.
#include "collision/contact_query.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <random>
#include <set>
#include <utility>

#include "tests/collision/collision_test_util.h"

namespace incise::test {
namespace {

using Eigen::Vector3d;

InstrumentSpec probe(double r, double length = 0.0) {
  InstrumentSpec s;
  s.json_path = "instruments[0]";
  s.radius = r;
  s.length = length;
  return s;
}

ToolPose at(double x, double y, double z) {
  ToolPose p;
  p.p = {x, y, z};
  return p;
}

ContactRequest all_of(const CollisionModel& cm) {
  ContactRequest r;
  r.max_contacts = cm.surface().ntri() * 2;
  r.max_candidates = cm.surface().ntri();
  return r;
}

Vector3d vert(const TissueSurface& s, int v) { return Vector3d(s.x[3 * v], s.x[3 * v + 1], s.x[3 * v + 2]); }

// Side 0 bends, side 1 bends and moves away by 0.15 (the cut opens).
std::array<double, 3> bend0(const double* X) {
  return {0.03 * X[1] * X[2], -0.02 * X[0] * X[0] + 0.01 * X[2], 0.04 * X[0] * X[1]};
}
std::array<double, 3> bend1(const double* X) {
  const auto u = bend0(X);
  return {u[0] + 0.15, u[1] - 0.01 * X[2] * X[2], u[2] + 0.02 * X[0]};
}

// Both trees: AABB (descended in contact_query.cpp) and OBBRSS (fcl::collide).
TEST(ContactQuery, SphereContactsAfterACutEqualABruteForceOverEveryTriangle) {
  for (auto [order, bv] : {std::pair{2, TissueBV::AABB}, std::pair{1, TissueBV::AABB}, std::pair{2, TissueBV::OBBRSS}}) {
    const Model m = block_model(true, order);
    const Field f[2] = {bend0, bend1};
    const State st = side_state(m, f);
    CollisionModel cm(3, bv);
    cm.sync(m, st, 0);
    const TissueSurface& s = cm.surface();
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> X(0.6, 1.6), Y(-0.3, 1.3), Z(0.4, 1.3), R(0.05, 0.35);
    int total = 0, on_cut = 0, deep = 0;
    ContactResult res;
    for (int trial = 0; trial < 60; ++trial) {
      const double r = R(rng);
      const Vector3d c(X(rng), Y(rng), Z(rng));
      query_contacts(cm, make_tool_shape(probe(r), at(c[0], c[1], c[2])), all_of(cm), res);
      ASSERT_FALSE(res.capped);
      std::map<int, double> got, want;
      for (const TissueContact& k : res.contacts) got[k.tri] = k.depth;
      for (int t = 0; t < s.ntri(); ++t) {
        const Vector3d a = vert(s, s.tri[3 * t]), b = vert(s, s.tri[3 * t + 1]), e = vert(s, s.tri[3 * t + 2]);
        const Vector3d p = ref_closest_point(c, a, b, e);
        const double d = (p - c).norm();
        if (!(d < r)) continue;
        const Vector3d n = (b - a).cross(e - a).normalized();
        // The convention of collision/narrowphase.h: geometric while the centre
        // is outside the face, along the face once it is in or behind its plane.
        want[t] = (c - p).dot(n) > 0 ? r - d : r - (c - p).dot(n);
      }
      ASSERT_EQ(got.size(), want.size()) << "order " << order << (bv == TissueBV::AABB ? " AABB" : " OBBRSS") << " trial " << trial << ": centre " << c.transpose()
                                         << " radius " << r;
      for (const auto& [t, depth] : want) {
        ASSERT_TRUE(got.count(t)) << "FCL missed triangle " << t << " in trial " << trial;
        EXPECT_NEAR(got[t], depth, 1e-9 * depth) << "triangle " << t << " trial " << trial;
      }
      for (const TissueContact& k : res.contacts) {
        on_cut += k.on_cut;
        deep += k.depth > r;
        EXPECT_NEAR(Vector3d(k.normal[0], k.normal[1], k.normal[2]).norm(), 1.0, 1e-14);
      }
      total += static_cast<int>(res.contacts.size());
    }
    EXPECT_GT(total, order == 2 ? 200 : 50);
    EXPECT_GT(on_cut, 10) << "the spheres must reach into the opened cut";
    EXPECT_GT(deep, 0) << "some centres inside the tissue (the face rule)";
  }
}

TEST(ContactQuery, KeepsTheDeepestContactsInOrder) {
  const Model m = block_model(false);
  const Field f[2] = {bend0, bend0};
  CollisionModel cm(2);
  cm.sync(m, side_state(m, f), 0);
  const ToolShape tool = make_tool_shape(probe(0.3), at(0.7, 0.4, 1.1));
  ContactResult all, few;
  query_contacts(cm, tool, all_of(cm), all);
  ASSERT_GT(all.contacts.size(), 8u);
  for (size_t k = 1; k < all.contacts.size(); ++k) EXPECT_GE(all.contacts[k - 1].depth, all.contacts[k].depth);
  ContactRequest req;
  req.max_contacts = 5;
  query_contacts(cm, tool, req, few);
  ASSERT_EQ(few.contacts.size(), 5u);
  for (int k = 0; k < 5; ++k) EXPECT_EQ(few.contacts[k].tri, all.contacts[k].tri);
  EXPECT_EQ(few.candidates, all.candidates);
}

TEST(ContactQuery, WeightsReproduceTheContactPointOnFlatFaces) {
  const Model m = block_model(true);
  // Affine on each side (straight-sided faces stay flat); side 1 moves away.
  const Field f[2] = {affine({0.05, -0.02, 0.01, 0.03, -0.04, 0.02, 0.01, 0.02, 0.03}, {0.01, -0.02, 0.03}),
                      affine({-0.03, 0.02, 0.01, 0.01, 0.05, -0.02, 0.02, 0.0, -0.04}, {0.25, 0.01, -0.02})};
  const State st = side_state(m, f);
  CollisionModel cm(2);
  cm.sync(m, st, 0);
  const TissueSurface& s = cm.surface();
  int checked = 0, cut = 0;
  ContactResult res;
  for (const Vector3d& c :
       {Vector3d(1.1, 0.5, 0.9), Vector3d(1.15, 0.2, 1.1), Vector3d(0.3, -0.05, 0.5), Vector3d(1.7, 0.6, 1.08)}) {
    query_contacts(cm, make_tool_shape(probe(0.2), at(c[0], c[1], c[2])), all_of(cm), res);
    for (const TissueContact& k : res.contacts) {
      double X[3], x[3];
      s.reference_position(k.elem, k.rst, X);
      point_position(k.weights, X, st.u.data(), x);
      for (int d = 0; d < 3; ++d) EXPECT_NEAR(x[d], k.point[d], 1e-12) << "triangle " << k.tri;
      ++checked;
      cut += k.on_cut;
    }
  }
  EXPECT_GT(checked, 20);
  EXPECT_GT(cut, 0);
}

TEST(ContactQuery, AProbeOnOneFaceOfACutMovesThatSideOnly) {
  const Model m = block_model(true);
  std::vector<int> region;
  const Field f[2] = {affine({}, {}), affine({}, {0.3, 0, 0})};  // the cut opens by 0.3 along x
  const State st = side_state(m, f, &region);
  CollisionModel cm(2);
  cm.sync(m, st, 0);
  // In the gap at y = z = 0.5, 0.08 (along x) from side 0's cut face, 0.22 from side 1's.
  const double face_x = 1.05 - 0.1 * 0.5 - 0.05 * 0.5;
  const ToolShape tool = make_tool_shape(probe(0.1), at(face_x + 0.08, 0.5, 0.5));
  ContactResult res;
  query_contacts(cm, tool, all_of(cm), res);
  ASSERT_FALSE(res.contacts.empty());
  const Vector3d plane_n = Vector3d(1, 0.1, 0.05).normalized();
  // The deepest: the triangle under the centre, pushed back along -plane
  // normal (its face's inward normal); its neighbours, touched at an edge
  // at distance d < r, are pushed away from the centre: n . plane_n = -h / d
  // with h = 0.08 / |(1, 0.1, 0.05)| the centre's height over the plane.
  EXPECT_NEAR(res.max_depth(), 0.1 - 0.08 / Vector3d(1, 0.1, 0.05).norm(), 1e-12);
  const double* n0 = res.contacts.front().normal;
  EXPECT_LT((Vector3d(n0[0], n0[1], n0[2]) + plane_n).norm(), 1e-12);
  for (const TissueContact& k : res.contacts) {
    EXPECT_TRUE(k.on_cut);
    const double h = 0.08 / Vector3d(1, 0.1, 0.05).norm(), d = 0.1 - k.depth;
    EXPECT_NEAR(Vector3d(k.normal[0], k.normal[1], k.normal[2]).dot(plane_n), -h / d, 1e-12);
    for (int j = 0; j < k.weights.n; ++j)
      EXPECT_NE(region[k.weights.dofnode[j]], 1) << "side 1's enriched DOF node " << k.weights.dofnode[j];
  }
  // Move side 1 only (its standard DOFs and side 0's enrichment at those
  // nodes compensate): the contacts and their points stay.
  const Field g[2] = {affine({}, {}), affine({0.1, 0.2, 0, 0, -0.1, 0.3, 0.2, 0, 0.1}, {0.5, 0.2, -0.3})};
  const State moved = side_state(m, g);
  for (const TissueContact& k : res.contacts) {
    double X[3], x0[3], x1[3];
    cm.surface().reference_position(k.elem, k.rst, X);
    point_position(k.weights, X, st.u.data(), x0);
    point_position(k.weights, X, moved.u.data(), x1);
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(x1[d], x0[d], 1e-14) << "triangle " << k.tri;
  }
  EXPECT_EQ(cm.sync(m, moved, 0), SyncAction::Refit);
  ContactResult after;
  query_contacts(cm, tool, all_of(cm), after);
  ASSERT_EQ(after.contacts.size(), res.contacts.size());
  for (size_t i = 0; i < res.contacts.size(); ++i) {
    EXPECT_EQ(after.contacts[i].tri, res.contacts[i].tri);
    for (int d = 0; d < 3; ++d) EXPECT_NEAR(after.contacts[i].point[d], res.contacts[i].point[d], 1e-14);
  }
}

TEST(ContactQuery, SphereAndCapsuleDepthOverAFlatRotatedFace) {
  const Model m = block_model(false);
  // A rigid rotation about (1, 2, 2)/3 by 0.3 rad and a shift: faces stay flat.
  const Eigen::Matrix3d Rm = Eigen::AngleAxisd(0.3, Vector3d(1, 2, 2) / 3).toRotationMatrix();
  std::array<double, 9> A;
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) A[3 * i + j] = Rm(i, j) - (i == j ? 1.0 : 0.0);
  const Field f[2] = {affine(A, {0.1, -0.2, 0.3}), affine(A, {0.1, -0.2, 0.3})};
  CollisionModel cm(2);
  cm.sync(m, side_state(m, f), 0);
  // The top face z = 1 of the block, point (0.7, 0.4, 1) and its outward normal.
  const Vector3d top = Rm * Vector3d(0.7, 0.4, 1) + Vector3d(0.1, -0.2, 0.3), n = Rm * Vector3d(0, 0, 1);
  for (double dist : {0.0, 0.03, 0.11, -0.04}) {
    const Vector3d c = top + dist * n;
    ContactResult res;
    query_contacts(cm, make_tool_shape(probe(0.15), at(c[0], c[1], c[2])), ContactRequest{}, res);
    ASSERT_FALSE(res.contacts.empty()) << dist;
    EXPECT_NEAR(res.max_depth(), 0.15 - dist, 1e-12) << "distance " << dist;
    const TissueContact& k = res.contacts.front();
    EXPECT_LT((Vector3d(k.normal[0], k.normal[1], k.normal[2]) + n).norm(), 1e-12);
    EXPECT_NEAR(max_penetration(cm, make_tool_shape(probe(0.15), at(c[0], c[1], c[2]))), 0.15 - dist, 1e-12);
  }
  // A capsule lying along the face (tool z along the rotated x axis), 0.05 above it.
  ToolPose pose;
  const Eigen::Quaterniond q =
      Eigen::Quaterniond(Rm) * Eigen::Quaterniond::FromTwoVectors(Vector3d(0, 0, 1), Vector3d(1, 0, 0));
  pose.q = {q.w(), q.x(), q.y(), q.z()};
  const Vector3d c = Rm * Vector3d(0.4, 0.5, 1.05) + Vector3d(0.1, -0.2, 0.3);
  pose.p = {c[0], c[1], c[2]};
  ContactResult res;
  query_contacts(cm, make_tool_shape(probe(0.1, 0.8), pose), ContactRequest{}, res);
  ASSERT_FALSE(res.contacts.empty());
  EXPECT_NEAR(res.max_depth(), 0.05, 1e-12);
  for (const TissueContact& k : res.contacts) EXPECT_LE(k.depth, 0.05 + 1e-12);
}

TEST(ContactQuery, GrasperJawsPressBothSidesByTheClosedAmount) {
  const Model m = block_model(false);
  const Field f[2] = {affine({}, {}), affine({}, {})};
  CollisionModel cm(2);
  cm.sync(m, side_state(m, f), 0);
  InstrumentSpec g;
  g.kind = InstrumentSpec::Kind::Grasper;
  g.json_path = "instruments[1]";
  g.jaw_size = {0.4, 0.4, 0.4};
  g.opening = 1.4;
  for (double jaw : {0.3, 0.5, 0.8}) {
    ToolPose pose = at(1.0, 0.5, 0.5);
    pose.jaw = jaw;
    ContactResult res;
    query_contacts(cm, make_tool_shape(g, pose), ContactRequest{}, res);
    ASSERT_FALSE(res.contacts.empty());
    const double want = 0.5 - 0.5 * jaw_gap(g, jaw);  // each inner face this far into the block
    for (const TissueContact& k : res.contacts) {
      // Jaw 0 (-y) pushes the y = 0 face along +y, jaw 1 the y = 1 face along -y.
      EXPECT_NEAR(k.depth, want, 1e-12) << "jaw " << jaw;
      EXPECT_NEAR(k.normal[1], k.part == 0 ? 1.0 : -1.0, 1e-15);
      EXPECT_NEAR(k.point[1], k.part == 0 ? 0.0 : 1.0, 1e-15);
    }
    std::set<int> parts;
    for (const TissueContact& k : res.contacts) parts.insert(k.part);
    EXPECT_EQ(parts.size(), 2u);
  }
}

}  // namespace
}  // namespace incise::test
