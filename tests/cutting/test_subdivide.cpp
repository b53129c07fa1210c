// Sub-element decomposition of a tetrahedron by one or two planes.
#include <cmath>
#include <map>
#include <random>

#include <gtest/gtest.h>

#include "cutting/subdivide.h"

namespace incise {
namespace {

double side_value(const std::vector<double>& phi, int c, const double* r) {
  const double L[4] = {1 - r[0] - r[1] - r[2], r[0], r[1], r[2]};
  double v = 0;
  for (int k = 0; k < 4; ++k) v += L[k] * phi[4 * c + k];
  return v;
}

TEST(Subdivide, VolumesAddUpAndEverySubTetIsOnItsSide) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> U(-1, 1);
  for (int trial = 0; trial < 200; ++trial) {
    const int ncut = 1 + trial % 2;
    std::vector<double> phi(4 * ncut);
    for (int c = 0; c < ncut; ++c) {
      do {
        for (int k = 0; k < 4; ++k) phi[4 * c + k] = U(rng);
      } while (*std::max_element(phi.begin() + 4 * c, phi.begin() + 4 * c + 4) <= 0 ||
               *std::min_element(phi.begin() + 4 * c, phi.begin() + 4 * c + 4) >= 0);
    }
    const SubTets st = subdivide_tet(phi, ncut);
    double vol = 0;
    for (int t = 0; t < st.size(); ++t) {
      EXPECT_GT(st.volume[t], 0.0);
      vol += st.volume[t];
      for (int c = 0; c < ncut; ++c)
        for (int k = 0; k < 4; ++k)
          EXPECT_GE(st.side[t * ncut + c] * side_value(phi, c, &st.rst[12 * t + 3 * k]), -1e-12);
    }
    EXPECT_NEAR(vol, 1.0 / 6.0, 1e-14);
  }
}

TEST(Subdivide, PieceVolumesMatchTheExactCornerCut) {
  // Plane L0 = 1/2 cuts corner 0 off: its piece is a tet of volume (1/2)^3 / 6.
  // phi = L0 - 1/2 at the corners: (1/2, -1/2, -1/2, -1/2).
  const SubTets st = subdivide_tet({0.5, -0.5, -0.5, -0.5}, 1);
  double pos = 0, neg = 0;
  int cut_faces = 0;
  for (int t = 0; t < st.size(); ++t) {
    (st.side[t] > 0 ? pos : neg) += st.volume[t];
    for (int k = 0; k < 4; ++k) cut_faces += st.face[4 * t + k] == kSubFaceCut;
  }
  EXPECT_NEAR(pos, 0.125 / 6.0, 1e-15);
  EXPECT_NEAR(neg, 0.875 / 6.0, 1e-15);
  EXPECT_GE(cut_faces, 2);  // the cut triangle, seen from both sides
}

TEST(Subdivide, DegenerateCutsThroughCornersAndEdges) {
  // Through corner 0 and the opposite edge midpoints: phi = (0, 1, -1, 0):
  // corners 0 and 3 on the plane; two halves of equal volume.
  const SubTets st = subdivide_tet({0.0, 1.0, -1.0, 0.0}, 1);
  double pos = 0, neg = 0;
  for (int t = 0; t < st.size(); ++t) (st.side[t] > 0 ? pos : neg) += st.volume[t];
  EXPECT_NEAR(pos, 1.0 / 12.0, 1e-15);
  EXPECT_NEAR(neg, 1.0 / 12.0, 1e-15);
  // A cut 1e-12 from corner 0 leaves a piece of volume ~1e-36 / 6, kept.
  const double d = 1e-12;
  const SubTets tiny = subdivide_tet({d, d - 1, d - 1, d - 1}, 1);
  double small = 0;
  for (int t = 0; t < tiny.size(); ++t)
    if (tiny.side[t] > 0) small += tiny.volume[t];
  EXPECT_NEAR(small / (std::pow(d, 3) / 6.0), 1.0, 1e-6);
}

TEST(Subdivide, TwoCrossingCutsGiveFourSides) {
  // L1 - L2 = 0 and L0 - L3 = 0 cross inside the tet.
  const SubTets st = subdivide_tet({0, 1, -1, 0, 1, 0, 0, -1}, 2);
  std::map<std::pair<int, int>, double> vol;
  for (int t = 0; t < st.size(); ++t) vol[{st.side[2 * t], st.side[2 * t + 1]}] += st.volume[t];
  EXPECT_EQ(vol.size(), 4u);
  for (const auto& [k, v] : vol) EXPECT_NEAR(v, 1.0 / 24.0, 1e-15);
}

}  // namespace
}  // namespace incise
