// Beams, tet4 -> tet10, mesh quality and mesh checks.
#include <gtest/gtest.h>
#include <filesystem>
#include <fstream>

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <map>
#include <set>
#include <string>
#include <utility>

#include "engine/util/error.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/fem/element.h"
#include "engine/mesh/mesh_io.h"
#include "tests/engine/error_of.h"

namespace incise {
namespace {

using test::error_of;

TEST(MeshTools, BeamVolumeCountsAndEqualKuhnTets) {
  const double lx = 0.7, ly = 0.3, lz = 1.1;
  for (int order : {1, 2}) {
    Mesh m = make_beam(lx, ly, lz, 3, 2, 4, order);
    EXPECT_EQ(m.order, order);
    EXPECT_EQ(m.ntet(), 6 * 3 * 2 * 4);
    if (order == 1) {
      EXPECT_EQ(m.nnode(), 4 * 3 * 5);
    }
    EXPECT_NO_THROW(check_mesh(m));
    MeshQuality q = mesh_quality(m);
    EXPECT_NEAR(q.total_volume, lx * ly * lz, 1e-14);
    const double each = lx * ly * lz / m.ntet();  // Kuhn tets of a cell have equal volume
    EXPECT_NEAR(q.min_volume, each, 1e-15);
    EXPECT_NEAR(q.max_volume, each, 1e-15);
  }
  // Exactly the box corners, no rounding at the far end.
  Mesh m = make_beam(lx, ly, lz, 3, 7, 9, 1);
  EXPECT_EQ(*std::max_element(m.X.begin(), m.X.end()), lz);
  EXPECT_EQ(m.X[3 * (m.nnode() - 1)], lx);
  EXPECT_EQ(m.X[3 * (m.nnode() - 1) + 1], ly);
}

TEST(MeshTools, BeamIsConforming) {
  const int nx = 3, ny = 2, nz = 2;
  Mesh m = make_beam(1, 1, 1, nx, ny, nz, 1);
  std::map<std::array<int, 3>, int> faces;  // sorted corner ids -> number of tets
  for (int e = 0; e < m.ntet(); ++e)
    for (int skip = 0; skip < 4; ++skip) {
      std::array<int, 3> f;
      for (int a = 0, k = 0; a < 4; ++a)
        if (a != skip) f[k++] = m.tet[4 * e + a];
      std::sort(f.begin(), f.end());
      ++faces[f];
    }
  int boundary = 0;
  for (const auto& [f, n] : faces) {
    EXPECT_LE(n, 2);
    boundary += n == 1;
  }
  // Each boundary square is two triangles; any hanging face would add more.
  EXPECT_EQ(boundary, 2 * 2 * (nx * ny + ny * nz + nx * nz));
}

TEST(MeshTools, RaiseToTet10AddsOneSharedNodePerEdge) {
  Mesh m = make_beam(2, 1, 1, 2, 2, 3, 1);
  std::set<std::pair<int, int>> edges;
  for (int e = 0; e < m.ntet(); ++e)
    for (const auto& ed : kTet10Edge) {
      int i = m.tet[4 * e + ed[0]], j = m.tet[4 * e + ed[1]];
      edges.insert({std::min(i, j), std::max(i, j)});
    }
  Mesh q = raise_to_tet10(m);
  EXPECT_EQ(q.order, 2);
  EXPECT_EQ(q.nnode(), m.nnode() + static_cast<int>(edges.size()));
  EXPECT_EQ(q.ntet(), m.ntet());
  for (int e = 0; e < q.ntet(); ++e) {
    for (int a = 0; a < 4; ++a) EXPECT_EQ(q.tet[10 * e + a], m.tet[4 * e + a]);
    for (int k = 0; k < 6; ++k)
      for (int c = 0; c < 3; ++c) {
        int i = q.tet[10 * e + kTet10Edge[k][0]], j = q.tet[10 * e + kTet10Edge[k][1]];
        EXPECT_EQ(q.X[3 * q.tet[10 * e + 4 + k] + c], 0.5 * (q.X[3 * i + c] + q.X[3 * j + c]));
      }
  }
  EXPECT_NO_THROW(check_mesh(q));
  // Already quadratic: unchanged.
  Mesh again = raise_to_tet10(q);
  EXPECT_EQ(again.tet, q.tet);
  EXPECT_EQ(again.X, q.X);
}

// One tet10 whose nodes sit on the quadratic map phi(x) = x + a x^2 per
// component, so the element reproduces phi exactly and
// volume = integral of (1+2a x)(1+2a y)(1+2a z) over the unit tet.
Mesh curved_tet10(double a) {
  const double ref[10][3] = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {.5, 0, 0},
                             {.5, .5, 0}, {0, .5, 0}, {0, 0, .5}, {.5, 0, .5}, {0, .5, .5}};
  Mesh m;
  m.order = 2;
  for (const auto& p : ref)
    for (double x : p) m.X.push_back(x + a * x * x);
  for (int i = 0; i < 10; ++i) m.tet.push_back(i);
  return m;
}

// Lowering undoes raising: the corner nodes, in order, and the same tets.
TEST(MeshTools, LowerToTet4KeepsTheCornerNodes) {
  const Mesh m = make_beam(2.0, 1.0, 1.0, 3, 2, 2, 1);
  const Mesh q = raise_to_tet10(m);
  ASSERT_GT(q.nnode(), m.nnode());
  const Mesh l = lower_to_tet4(q);
  EXPECT_EQ(l.order, 1);
  EXPECT_EQ(l.X, m.X);  // raise_to_tet10 appends mid-edge nodes after the corners
  EXPECT_EQ(l.tet, m.tet);
  EXPECT_EQ(lower_to_tet4(m).tet, m.tet);
  // A tet10 mesh whose corners are not its first nodes: renumbered compactly.
  Mesh shuffled = q;
  const int n = q.nnode();
  std::vector<int> perm(static_cast<size_t>(n));
  for (int i = 0; i < n; ++i) perm[static_cast<size_t>(i)] = n - 1 - i;  // old -> new
  for (int i = 0; i < n; ++i)
    for (int c = 0; c < 3; ++c) shuffled.X[3 * static_cast<size_t>(perm[static_cast<size_t>(i)]) + c] = q.X[3 * static_cast<size_t>(i) + c];
  for (int& v : shuffled.tet) v = perm[static_cast<size_t>(v)];
  const Mesh ls = lower_to_tet4(shuffled);
  EXPECT_EQ(ls.nnode(), m.nnode());
  for (int e = 0; e < m.ntet(); ++e)
    for (int a = 0; a < 4; ++a)
      for (int c = 0; c < 3; ++c)
        EXPECT_EQ(ls.X[3 * static_cast<size_t>(ls.tet[4 * static_cast<size_t>(e) + a]) + c],
                  m.X[3 * static_cast<size_t>(m.tet[4 * static_cast<size_t>(e) + a]) + c]);
}

TEST(MeshTools, Tet10VolumeIntegratesCurvedGeometryExactly) {
  const double a = 0.2;
  // 1/6 + 3a/12 + 4*3a^2/120 + 8a^3/720 (monomial integrals over the unit tet)
  const double exact = 1.0 / 6 + 3 * a / 12 + 12 * a * a / 120 + 8 * a * a * a / 720;
  MeshQuality q = mesh_quality(curved_tet10(a));
  EXPECT_NEAR(q.total_volume, exact, 1e-15);
  EXPECT_NO_THROW(check_mesh(curved_tet10(a)));
}

TEST(MeshTools, DihedralAnglesOfKuhnAndRegularTets) {
  MeshQuality q = mesh_quality(make_beam(1, 1, 1, 2, 2, 2, 1));
  EXPECT_NEAR(q.min_dihedral_deg, 45.0, 1e-12);
  EXPECT_NEAR(q.max_dihedral_deg, 90.0, 1e-12);
  EXPECT_GE(q.worst_tet, 0);

  Mesh reg;
  reg.X = {1, 1, 1, 1, -1, -1, -1, 1, -1, -1, -1, 1};
  reg.tet = {0, 1, 2, 3};
  if (mesh_quality(reg).min_volume < 0) std::swap(reg.tet[2], reg.tet[3]);
  q = mesh_quality(reg);
  const double expect = std::acos(1.0 / 3) * 180 / M_PI;  // 70.53 deg
  EXPECT_NEAR(q.min_dihedral_deg, expect, 1e-12);
  EXPECT_NEAR(q.max_dihedral_deg, expect, 1e-12);
  EXPECT_NEAR(q.total_volume, 8.0 / 3, 1e-14);
}

TEST(MeshTools, WorstTetIsTheFlattestOne) {
  Mesh m = make_beam(1, 1, 1, 1, 1, 1, 1);
  m.X.insert(m.X.end(), {3, 0, 0, 4, 0, 0, 3.5, 1, 0, 3.5, 0.5, 0.05});  // a sliver-ish tet
  m.tet.insert(m.tet.end(), {8, 9, 10, 11});
  MeshQuality q = mesh_quality(m);
  EXPECT_EQ(q.worst_tet, 6);
  EXPECT_LT(q.min_dihedral_deg, 10.0);
  const std::string text = format_quality(q);
  EXPECT_NE(text.find("nodes 12, tetrahedra 7"), std::string::npos) << text;
  EXPECT_NE(text.find("(element 6)"), std::string::npos) << text;
}

TEST(MeshTools, CheckMeshNamesTheInvertedElement) {
  Mesh m = make_beam(1, 1, 1, 2, 1, 1, 1);
  m.source = "beam.msh";
  std::swap(m.tet[4 * 5 + 1], m.tet[4 * 5 + 2]);
  std::string e = error_of([&] { check_mesh(m); });
  EXPECT_EQ(e.rfind("beam.msh: element 5 (nodes ", 0), 0u) << e;
  EXPECT_NE(e.find("<= 0: inverted or degenerate"), std::string::npos) << e;
}

TEST(MeshTools, CheckMeshRejectsDegenerateOutOfRangeAndNonFinite) {
  Mesh m = make_beam(1, 1, 1, 1, 1, 1, 1);
  Mesh flat = m;
  flat.tet[4 * 2 + 3] = flat.tet[4 * 2 + 2];  // repeated node: zero volume
  EXPECT_NE(error_of([&] { check_mesh(flat); }).find("element 2 (nodes"), std::string::npos);
  Mesh range = m;
  range.tet[4 * 3 + 1] = 8;
  EXPECT_NE(error_of([&] { check_mesh(range); }).find("element 3 references node 8, but only 8 nodes are defined"),
            std::string::npos);
  Mesh inf = m;
  inf.X[3 * 4 + 2] = INFINITY;
  EXPECT_NE(error_of([&] { check_mesh(inf); }).find("node 4 has a non-finite coordinate"), std::string::npos);
}

TEST(MeshTools, CheckMeshCatchesMisplacedOrMisorderedMidNodes) {
  Mesh m = make_beam(1, 1, 1, 1, 1, 1, 2);
  // Mid node of edge (0,1) of element 0 pulled close to corner 0: the
  // Jacobian turns negative at that corner.
  Mesh moved = m;
  const int* t = &moved.tet[0];
  for (int c = 0; c < 3; ++c)
    moved.X[3 * t[4] + c] = moved.X[3 * t[0] + c] + 0.1 * (moved.X[3 * t[1] + c] - moved.X[3 * t[0] + c]);
  std::string e = error_of([&] { check_mesh(moved); });
  EXPECT_NE(e.find("element 0 (nodes"), std::string::npos) << e;
  EXPECT_NE(e.find("Jacobian determinant"), std::string::npos) << e;
  // Gmsh's order read without the 8 <-> 9 swap.
  Mesh swapped = m;
  std::swap(swapped.tet[8], swapped.tet[9]);
  e = error_of([&] { check_mesh(swapped); });
  EXPECT_NE(e.find("element 0 (nodes"), std::string::npos) << e;
}

TEST(MeshTools, MakeBeamRejectsBadArguments) {
  EXPECT_NE(error_of([] { make_beam(0, 1, 1, 1, 1, 1, 1); }).find("lengths must be positive"), std::string::npos);
  EXPECT_NE(error_of([] { make_beam(1, 1, NAN, 1, 1, 1, 1); }).find("lengths must be positive"), std::string::npos);
  EXPECT_NE(error_of([] { make_beam(1, 1, 1, 1, 0, 1, 1); }).find("cell counts"), std::string::npos);
  EXPECT_NE(error_of([] { make_beam(1, 1, 1, 1, 1, 1, 3); }).find("order must be 1 or 2"), std::string::npos);
}

}  // namespace
}  // namespace incise


namespace incise {
namespace {

// The reference tet as a tet10 with its mid-edge nodes at `mid` (6 points).
Mesh reference_tet10(const std::array<std::array<double, 3>, 6>& mid) {
  Mesh m;
  m.order = 2;
  m.X = {0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1};
  for (const auto& p : mid) m.X.insert(m.X.end(), p.begin(), p.end());
  for (int a = 0; a < 10; ++a) m.tet.push_back(a);
  return m;
}

const std::array<std::array<double, 3>, 6> kStraightMids = {
    {{0.5, 0, 0}, {0.5, 0.5, 0}, {0, 0.5, 0}, {0, 0, 0.5}, {0.5, 0, 0.5}, {0, 0.5, 0.5}}};

// Issue 24: a tet10 that folds between its nodes passed (det J was checked
// at the corners and mid-edge nodes only).
TEST(MeshTools, CheckMeshRefusesATet10FoldedBetweenItsNodes) {
  // det J > 0 at all 10 nodes (min 0.162) but -0.162 at a stiffness point.
  Mesh fold = reference_tet10({{{0.2, -0.08, 0.22}, {0.76, 0.76, 0.25}, {-0.21, 0.23, -0.34},
                                {0.15, -0.09, 0.19}, {0.71, -0.08, 0.65}, {-0.05, 0.82, 0.5}}});
  fold.source = "fold.msh";
  const std::string e = error_of([&] { check_mesh(fold); });
  EXPECT_EQ(e.rfind("fold.msh: element 0 (nodes 0 1 2 3 4 5 6 7 8 9) has Jacobian determinant -0.162 <= 0 at a "
                    "stiffness quadrature point (barycentric 0.5854 0.1382 0.1382 0.1382): the element folds",
                    0),
            0u)
      << e;
  // Curved but valid: one mid-edge node bulging outward.
  Mesh curved = reference_tet10(kStraightMids);
  curved.X[3 * 4 + 1] = -0.2;  // node 4 of edge (0,1) at (0.5, -0.2, 0)
  EXPECT_NO_THROW(check_mesh(curved));
  EXPECT_GT(mesh_quality(curved).min_volume, 1.0 / 6);
}

// A mid-edge node pushed past the opposite face, read from a file: the error
// names the file, the element's line and id, the point and det J.
TEST(MeshTools, CheckMeshNamesTheFileLineAndIdOfAFoldedTet10) {
  const std::string p = (std::filesystem::temp_directory_path() / "incise_fold_tet10.msh").string();
  std::ofstream(p) << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n10\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n"
                      "5 0.5 0.6 0.6\n6 0.5 0.5 0\n7 0 0.5 0\n8 0 0 0.5\n9 0 0.5 0.5\n10 0.5 0 0.5\n$EndNodes\n"
                      "$Elements\n1\n77 11 2 0 1 1 2 3 4 5 6 7 8 9 10\n$EndElements\n";
  const Mesh m = read_mesh(p);
  std::filesystem::remove(p);
  const std::string e = error_of([&] { check_mesh(m); });
  EXPECT_EQ(e.rfind(p + ":19: element 0 (nodes 0 1 2 3 4 5 6 7 9 8; id 77 in the file) has Jacobian determinant -3.8 <= 0 "
                    "at its node 1 (corner)",
                    0),
            0u)
      << e;
}

// The stiffness points check_mesh() uses are the engine's 4-point rule.
TEST(MeshTools, Tet10CheckPointsIncludeTheStiffnessRule) {
  const std::vector<std::array<double, 4>> pts = tet10_check_points_barycentric();
  ASSERT_EQ(pts.size(), 4u + 6u + 4u + 27u);
  const Cubature& c = cubature_tet4();
  ASSERT_EQ(c.npoint(), 4);
  for (int q = 0; q < 4; ++q) {
    bool found = false;
    for (int k = 10; k < 14; ++k)
      found = found || (std::abs(pts[k][1] - c.rst[3 * q]) < 1e-15 && std::abs(pts[k][2] - c.rst[3 * q + 1]) < 1e-15 &&
                        std::abs(pts[k][3] - c.rst[3 * q + 2]) < 1e-15);
    EXPECT_TRUE(found) << "cubature_tet4 point " << q;
  }
}

// Duplicate vertices that an export did not merge leave the elements on
// either side unconnected; load_simulation warns with what this finds.
TEST(MeshTools, CoincidentNodesAreFoundOnlyWhereElementsUseThem) {
  Mesh m = make_beam(1, 1, 1, 2, 1, 1, 1);
  EXPECT_EQ(coincident_nodes(m).count, 0);
  // A copy of node 1 at the end, used by the last element in its place, and
  // an unused copy of node 2 (not counted: no element uses it).
  const int n = m.nnode();
  for (int src : {1, 2})
    for (int d = 0; d < 3; ++d) m.X.push_back(m.X[3 * src + d]);
  int replaced = 0;
  for (int a = 0; a < 4; ++a) {
    int& node = m.tet[m.tet.size() - 4 + a];
    if (node == 1) node = n, ++replaced;
  }
  ASSERT_EQ(replaced, 1) << "the last element uses node 1";
  bool other_uses_1 = false;
  for (size_t k = 0; k + 4 < m.tet.size(); ++k) other_uses_1 = other_uses_1 || m.tet[k] == 1;
  ASSERT_TRUE(other_uses_1);
  const CoincidentNodes c = coincident_nodes(m);
  EXPECT_EQ(c.count, 1);
  EXPECT_EQ(c.a, 1);
  EXPECT_EQ(c.b, n);
}

}  // namespace
}  // namespace incise
