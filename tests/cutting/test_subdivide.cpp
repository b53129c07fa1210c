// Sub-element decomposition of a tetrahedron by one or more planes.
#include <algorithm>
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

// Corner values of ncut random planes, each with corners on both sides.
std::vector<double> random_crossing_planes(std::mt19937& rng, int ncut) {
  std::uniform_real_distribution<double> U(-1, 1);
  std::vector<double> phi(4 * ncut);
  for (int c = 0; c < ncut; ++c) {
    do {
      for (int k = 0; k < 4; ++k) phi[4 * c + k] = U(rng);
    } while (*std::max_element(phi.begin() + 4 * c, phi.begin() + 4 * c + 4) <= 0 ||
             *std::min_element(phi.begin() + 4 * c, phi.begin() + 4 * c + 4) >= 0);
  }
  return phi;
}

TEST(Subdivide, VolumesAddUpAndEverySubTetIsOnItsSide) {
  std::mt19937 rng(11);
  for (int trial = 0; trial < 200; ++trial) {
    const int ncut = 1 + trial % 2;
    const std::vector<double> phi = random_crossing_planes(rng, ncut);
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

// Issue 24: repeated cuts through one element. Each part stays a convex cell,
// so k planes make at most sum_{i<=3} C(k, i) parts (an arrangement of k
// planes), not 2^k; near-parallel cuts make k + 1 slabs.
TEST(Subdivide, TwentyNearParallelCutsMakeSlabsNotAnExponentialTree) {
  // Planes L1 = c_i + eps_i * (L2 - L3) for 20 values c_i in (0.05, 0.95):
  // near-parallel, each crossing the tet, none crossing another inside it
  // (|eps| < 0.001 keeps neighbouring planes apart over the tet).
  for (int ncut : {5, 10, 20}) {
    std::vector<double> phi(4 * ncut);
    for (int c = 0; c < ncut; ++c) {
      const double ci = 0.05 + 0.9 * c / (ncut - 1), eps = 1e-3 * ((c % 3) - 1);
      // phi = L1 - ci - eps (L2 - L3) at the corners L = e_k.
      phi[4 * c + 0] = -ci;
      phi[4 * c + 1] = 1 - ci;
      phi[4 * c + 2] = -ci - eps;
      phi[4 * c + 3] = -ci + eps;
    }
    const SubTets st = subdivide_tet(phi, ncut);
    std::map<std::vector<signed char>, double> cells;
    double vol = 0;
    for (int t = 0; t < st.size(); ++t) {
      EXPECT_GT(st.volume[t], 0.0);
      vol += st.volume[t];
      cells[std::vector<signed char>(st.side.begin() + t * ncut, st.side.begin() + (t + 1) * ncut)] += st.volume[t];
      for (int c = 0; c < ncut; ++c)
        for (int k = 0; k < 4; ++k)
          ASSERT_GE(st.side[t * ncut + c] * side_value(phi, c, &st.rst[12 * t + 3 * k]), -1e-12);
    }
    EXPECT_NEAR(vol, 1.0 / 6.0, 1e-14);
    EXPECT_EQ(static_cast<int>(cells.size()), ncut + 1);  // the slabs
    // A slab is a convex cell of at most 6 faces of at most 6 vertices here:
    // fewer than 4 * 6 cone tets each. The old tree of tets had ~4^k.
    EXPECT_LE(st.size(), 24 * (ncut + 1));
  }
}

TEST(Subdivide, TwentyCrossingCutsStayWithinTheArrangementBound) {
  // Random planes through the tet: every part is a cell of the arrangement.
  std::mt19937 rng(5);
  const int ncut = 20;
  const std::vector<double> phi = random_crossing_planes(rng, ncut);
  const SubTets st = subdivide_tet(phi, ncut);
  std::map<std::vector<signed char>, double> cells;
  double vol = 0;
  for (int t = 0; t < st.size(); ++t) {
    vol += st.volume[t];
    cells[std::vector<signed char>(st.side.begin() + t * ncut, st.side.begin() + (t + 1) * ncut)] += st.volume[t];
  }
  EXPECT_NEAR(vol, 1.0 / 6.0, 1e-13);
  const int bound = 1 + ncut + ncut * (ncut - 1) / 2 + ncut * (ncut - 1) * (ncut - 2) / 6;  // 1351
  EXPECT_LE(static_cast<int>(cells.size()), bound);
  EXPECT_GT(static_cast<int>(cells.size()), ncut + 1);  // they do cross
}

}  // namespace
}  // namespace incise
