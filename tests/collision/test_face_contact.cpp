// A round tool's row point on a face (collision/face_contact.h): it moves
// continuously with the tool where the face's deepest point jumps, it is
// the deepest point where symmetry puts it there, and it carries the
// tool's own normal and depth at that material point.
#include "collision/face_contact.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

#include "collision/collision_model.h"
#include "tests/collision/collision_test_util.h"

namespace incise::test {
namespace {

using Eigen::Vector3d;

// The block's top (z = 1) raised into a bowl z = 1 + k rho^2 around
// (1, 0.5): quadratic, so the tet10 faces hold it exactly. With k = 1 / (2 r)
// a sphere of radius r lowered into it by delta is inside every point of
// the bowl near its bottom by delta - rho^4 / (8 r^3): nearly the same depth
// everywhere, the case where a face's deepest point is ill-posed (a probe
// the tissue wraps). The small sphere stays over the top; the large one
// (as wide as the block) also reaches over its edges onto the side faces,
// where a face's contact is a thin sliver between the samples.
struct Bowl {
  double radius, delta;
};
constexpr Bowl kSmall{0.25, 0.01}, kLarge{0.5, 0.03};

State bowl_state(const Model& m, const Bowl& b) {
  const double k = 1.0 / (2.0 * b.radius);
  const Field f[2] = {[k](const double* X) {
                        const double dx = X[0] - 1.0, dy = X[1] - 0.5;
                        return std::array<double, 3>{0.0, 0.0, k * (dx * dx + dy * dy)};
                      },
                      nullptr};
  return side_state(m, f);
}

ToolShape sphere_at(const Bowl& b, double x) {
  InstrumentSpec s;
  s.json_path = "instruments[0]";
  s.radius = b.radius;
  ToolPose p;
  p.p = {x, 0.5, 1.0 + b.radius - b.delta};
  return make_tool_shape(s, p);
}

// Per face, the deepest contact and the weighted row point.
struct Rows {
  std::map<int, Vector3d> deepest, weighted;
  std::map<int, TissueContact> row;
};

Rows rows_at(const CollisionModel& cm, const State& st, const Bowl& b, double x) {
  const ToolShape tool = sphere_at(b, x);
  ContactRequest req;
  req.max_contacts = 2 * cm.surface().ntri();
  req.max_candidates = cm.surface().ntri();
  ContactResult res;
  query_contacts(cm, tool, req, res);
  Rows out;
  for (const TissueContact& c : res.contacts) {
    if (out.deepest.count(c.face)) continue;  // deepest first
    out.deepest[c.face] = Vector3d(c.point[0], c.point[1], c.point[2]);
    TissueContact w = c;
    weight_round_face_contact(cm.surface(), tool.part[0], st.u.data(), w);
    out.weighted[c.face] = Vector3d(w.point[0], w.point[1], w.point[2]);
    out.row[c.face] = w;
  }
  return out;
}

// Sweeping the sphere across the bowl by 1e-3 at a time: the weighted point
// of every face in contact moves by at most a few times the sphere's step
// (a thin contact at the rim moves fast, but continuously), while some
// face's deepest point jumps across the face (measured: deepest 65 and 217
// times the step, weighted 1.3 and 6.1; with the face's single deepest
// point as the weighted point's fallback for a touch between samples it
// was 79 on the large sphere: the triangles' own nearest points now).
TEST(FaceContact, TheWeightedPointMovesContinuouslyWhereTheDeepestPointJumps) {
  const Model m = block_model(false);
  for (const Bowl& b : {kSmall, kLarge}) {
    const State st = bowl_state(m, b);
    CollisionModel cm(2);
    cm.sync(m, st, 0);
    const double step = 1e-3;
    double worst_weighted = 0.0, worst_deepest = 0.0;
    Rows last = rows_at(cm, st, b, 0.8);
    for (int i = 1; i <= 400; ++i) {
      const Rows now = rows_at(cm, st, b, 0.8 + i * step);
      for (const auto& [face, p] : now.weighted) {
        if (!last.weighted.count(face)) continue;
        worst_weighted = std::max(worst_weighted, (p - last.weighted.at(face)).norm() / step);
        worst_deepest = std::max(worst_deepest, (now.deepest.at(face) - last.deepest.at(face)).norm() / step);
      }
      last = now;
    }
    std::printf("[ r = %g: largest move of a face's row point per unit of the sphere's: weighted %.3g, deepest %.3g ]\n",
                b.radius, worst_weighted, worst_deepest);
    EXPECT_LT(worst_weighted, 10.0) << "r = " << b.radius;
    EXPECT_GT(worst_deepest, 50.0) << "r = " << b.radius << ": the case must make the deepest point jump";
  }
}

// Each row carries the sphere's own geometry at its material point: the
// point is x(rst) of the face's element (its weights reproduce it), the
// normal (x - c) / |x - c| and the depth r - |x - c|; over the bowl's
// bottom, centred on a face corner shared by four faces, the rows sit
// symmetrically around the centre.
TEST(FaceContact, TheRowCarriesTheToolsNormalAndDepthAtItsMaterialPoint) {
  const Model m = block_model(false);
  const State st = bowl_state(m, kSmall);
  CollisionModel cm(2);
  cm.sync(m, st, 0);
  const Rows rows = rows_at(cm, st, kSmall, 1.0);
  const Vector3d centre(1.0, 0.5, 1.0 + kSmall.radius - kSmall.delta);
  ASSERT_GE(rows.row.size(), 4u);
  Vector3d sum(0, 0, 0);
  double wsum = 0.0;
  for (const auto& [face, c] : rows.row) {
    const Vector3d x(c.point[0], c.point[1], c.point[2]), n(c.normal[0], c.normal[1], c.normal[2]);
    double X[3], xr[3];
    point_reference_position(m, c.elem, c.rst, X);
    point_position(c.weights, X, st.u.data(), xr);
    EXPECT_LT((Vector3d(xr[0], xr[1], xr[2]) - x).norm(), 1e-12) << "face " << face;
    EXPECT_NEAR(n.norm(), 1.0, 1e-12);
    EXPECT_LT((n - (x - centre).normalized()).norm(), 1e-12) << "face " << face;
    EXPECT_NEAR(c.depth, kSmall.radius - (x - centre).norm(), 1e-12) << "face " << face;
    EXPECT_GT(c.depth, 0.0);
    EXPECT_LE(c.depth, kSmall.delta + 1e-12) << "no deeper than the bowl's bottom";
    sum += c.depth * x;
    wsum += c.depth;
  }
  const Vector3d mean = sum / wsum;
  EXPECT_NEAR(mean[0], 1.0, 1e-9) << "symmetric about x = 1";
  EXPECT_NEAR(mean[1], 0.5, 1e-9) << "symmetric about y = 0.5";
}

}  // namespace
}  // namespace incise::test
