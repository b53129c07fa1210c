// DOF weights of a material point: they move it as the engine's own
// interpolation does (engine/output/probe.h), and only with its own piece.
#include "collision/point_weights.h"

#include <gtest/gtest.h>

#include <random>
#include <set>

#include "engine/output/probe.h"
#include "tests/collision/collision_test_util.h"

namespace incise::test {
namespace {

TEST(PointWeights, ReproduceTheEngineInterpolationInEveryPiece) {
  for (bool cut : {false, true}) {
    const Model m = block_model(cut);
    const Field f[2] = {affine({0.1, -0.2, 0.05, 0.3, 0.02, -0.1, 0.0, 0.2, 0.1}, {0.01, 0.02, -0.03}),
                        affine({-0.05, 0.1, 0.0, 0.1, -0.2, 0.3, 0.2, 0.0, 0.1}, {0.2, -0.1, 0.05})};
    const State st = side_state(m, f);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> U(0.0, 1.0);
    int checked = 0;
    for (int e = 0; e < m.nelem; ++e) {
      const int p0 = cut ? m.cuts.elem_piece_ptr[e] : -1, p1 = cut ? m.cuts.elem_piece_ptr[e + 1] : 0;
      for (int P = p0; P < std::max(p0 + 1, p1); ++P) {
        double rst[3] = {U(rng), U(rng), U(rng)};
        const double s = rst[0] + rst[1] + rst[2];
        if (s > 1)
          for (double& r : rst) r /= 1.5 * s;
        ProbeHit hit;
        hit.elem = e, hit.piece = P;
        for (int c = 0; c < 3; ++c) hit.rst[c] = rst[c];
        const auto u_ref = interpolate_displacement(m, st.u.data(), hit);
        const PointWeights w = point_dof_weights(m, e, P, rst);
        double X[3], x[3];
        point_reference_position(m, e, rst, X);
        point_position(w, X, st.u.data(), x);
        for (int c = 0; c < 3; ++c) EXPECT_NEAR(x[c] - X[c], u_ref[c], 1e-14) << "elem " << e << " piece " << P;
        // Only mesh nodes and this piece's enriched DOF nodes carry weight.
        std::set<int> allowed(m.mesh.tet.begin() + e * 10, m.mesh.tet.begin() + e * 10 + 10);
        if (P >= 0)
          for (int a = 0; a < 10; ++a)
            if (m.cuts.piece_enr[P * 10 + a] >= 0) allowed.insert(m.cuts.piece_enr[P * 10 + a]);
        for (int k = 0; k < w.n; ++k) EXPECT_TRUE(allowed.count(w.dofnode[k])) << "dof node " << w.dofnode[k];
        ++checked;
      }
    }
    EXPECT_GT(checked, m.nelem - 1);
  }
}

TEST(PointWeights, DropTheZerosOfNodesOffAFace) {
  const Model m = block_model(false);
  // Face 0 (opposite corner 0): L0 = 0, so corner 0 and the mid-edge nodes
  // 4, 6, 7 (edges 0-1, 0-2, 0-3) have exactly no weight.
  const double rst[3] = {0.2, 0.35, 0.45};  // L0 = 0 up to roundoff
  const PointWeights w = point_dof_weights(m, 0, -1, rst);
  EXPECT_EQ(w.n, 6);
  double sum = 0;
  for (int k = 0; k < w.n; ++k) sum += w.weight[k];
  EXPECT_NEAR(sum, 1.0, 1e-15) << "the shape functions are a partition of unity";
}

}  // namespace
}  // namespace incise::test
