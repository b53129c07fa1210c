// Which faces are drawn: exactly the flagged ones, boundary before cut, and
// the signature that decides when the topology is rebuilt.
#include "engine/output/surface_extract.h"

#include <gtest/gtest.h>

#include <set>

#include "tests/engine/output/display_fixtures.h"

namespace incise::test {
namespace {

TEST(SurfaceExtract, DrawsExactlyTheFlaggedFaces) {
  DisplayMesh d = display_of(make_beam(2, 1, 1, 2, 1, 1, 2));
  // Unflag one boundary face and flag two inner faces as cut.
  std::set<std::pair<int, int>> want_boundary, want_cut;
  int inner_flagged = 0;
  for (int c = 0; c < d.ncell(); ++c)
    for (int k = 0; k < 4; ++k) {
      unsigned char& f = d.face_flags[4 * c + k];
      if (c == 0 && f == kFaceBoundary) f = 0;  // every cell of a 2x1x1 beam touches the boundary
      if (f == 0 && inner_flagged < 2 && c > 0) f = kFaceCut, ++inner_flagged;
      if (f & kFaceCut) want_cut.insert({c, k});
      else if (f & kFaceBoundary) want_boundary.insert({c, k});
    }
  ASSERT_EQ(inner_flagged, 2);
  const Surface s = extract_surface(d);
  ASSERT_EQ(s.nboundary, static_cast<int>(want_boundary.size()));
  ASSERT_EQ(s.ncut, 2);
  ASSERT_EQ(s.face_nodes.size(), 6u * s.nface());
  std::set<std::pair<int, int>> got_boundary, got_cut;
  for (int f = 0; f < s.nface(); ++f) {
    const int c = s.face_cell[f];
    // Find the local face from the corner ids (kTetFace order, kTet10FaceMid mids).
    int k_found = -1;
    for (int k = 0; k < 4; ++k) {
      bool same = true;
      for (int j = 0; j < 3; ++j) {
        same &= s.face_nodes[6 * f + j] == d.cells[10 * c + kTetFace[k][j]];
        same &= s.face_nodes[6 * f + 3 + j] == d.cells[10 * c + kTet10FaceMid[k][j]];
      }
      if (same) k_found = k;
    }
    ASSERT_GE(k_found, 0) << "face " << f << " is not a face of cell " << c << " in kTetFace order";
    (f < s.nboundary ? got_boundary : got_cut).insert({c, k_found});
  }
  EXPECT_EQ(got_boundary, want_boundary);
  EXPECT_EQ(got_cut, want_cut);
}

TEST(SurfaceExtract, BeamBoundaryFaceCountAndOutwardOrientation) {
  const DisplayMesh d = display_of(make_beam(3, 1, 1, 3, 1, 1, 1));
  const Surface s = extract_surface(d);
  // Kuhn split: 2 triangles per cube face; 3x1x1 cubes have 14 cube faces outside.
  EXPECT_EQ(s.nboundary, 28);
  EXPECT_EQ(s.ncut, 0);
  EXPECT_EQ(s.npf(), 3);
  for (int f = 0; f < s.nface(); ++f) {
    double p[3][3], n[3], c[3] = {0, 0, 0};
    for (int j = 0; j < 3; ++j)
      for (int i = 0; i < 3; ++i) p[j][i] = d.X[3 * s.face_nodes[3 * f + j] + i], c[i] += p[j][i] / 3;
    const double a[3] = {p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]};
    const double b[3] = {p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]};
    n[0] = a[1] * b[2] - a[2] * b[1], n[1] = a[2] * b[0] - a[0] * b[2], n[2] = a[0] * b[1] - a[1] * b[0];
    // Outward: the normal points away from the box centre (1.5, 0.5, 0.5).
    EXPECT_GT(n[0] * (c[0] - 1.5) + n[1] * (c[1] - 0.5) + n[2] * (c[2] - 0.5), 0.0) << "face " << f;
  }
}

TEST(SurfaceExtract, SignatureChangesWithStructureOnly) {
  const DisplayMesh d = display_of(make_beam(2, 1, 1, 2, 1, 1, 2));
  DisplayMesh moved = d;
  for (double& u : moved.u) u += 0.1;
  EXPECT_EQ(topology_signature(d), topology_signature(moved)) << "motion must not rebuild the topology";
  DisplayMesh reflagged = d;
  reflagged.face_flags[0] ^= kFaceCut;
  EXPECT_NE(topology_signature(d), topology_signature(reflagged));
  const DisplayMesh cut = split_block(d, 1.0, 0.1);
  EXPECT_NE(topology_signature(d), topology_signature(cut));
}

}  // namespace
}  // namespace incise::test
