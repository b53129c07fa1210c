// The collision surface: the renderer's triangles (same faces, same grid),
// outward, each vertex a material point its weights move.
#include "collision/tissue_surface.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

#include "engine/mesh/mesh_io.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/model/front_enrichment.h"
#include "engine/output/display_mesh.h"
#include "engine/util/error.h"
#include "render/tessellate.h"
#include "tests/collision/collision_test_util.h"

namespace incise::test {
namespace {

// A bent, twisted field (not affine: curved faces stay curved).
std::array<double, 3> bend(const double* X) {
  return {0.05 * X[1] * X[2], -0.04 * X[0] * X[0] + 0.02 * X[2], 0.03 * X[0] * X[1] + 0.01};
}

// The largest distance between the surface's vertices and the renderer's
// tessellation of the full display mesh (n per face edge); +inf where the
// vertex counts or the triangles differ.
double off_the_renderer(const TissueSurface& ts, const Model& m, const State& st, int n) {
  const DisplayMesh d = display_mesh(m, st);
  const Surface surf = extract_surface(d);
  const Tessellation t = build_tessellation(surf, d, n);
  std::vector<float> pos, nrm;
  std::vector<double> work;
  tessellate(surf, t, d, pos, nrm, work);
  EXPECT_EQ(ts.nvert(), t.nvert());
  EXPECT_EQ(ts.ntri() * 3, static_cast<int>(t.tris.size()));
  if (ts.nvert() != t.nvert() || ts.ntri() * 3 != static_cast<int>(t.tris.size()))
    return std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3 * ts.ntri(); ++k)
    if (ts.tri[k] != static_cast<int>(t.tris[k])) return std::numeric_limits<double>::infinity();
  double worst = 0;
  for (int k = 0; k < 3 * ts.nvert(); ++k) worst = std::max(worst, std::abs(ts.x[k] - pos[k]));
  return worst;
}

TEST(TissueSurface, VerticesAreTheRenderersTessellation) {
  const Mesh mesh = read_mesh(std::string(INCISE_SOURCE_DIR) + "/assets/meshes/sphere_tet10.msh");
  Scene s = block_scene(2);
  const Model m = build_model(mesh, s);
  const Field f[2] = {bend, bend};
  const State st = side_state(m, f);
  for (int n : {2, 3}) {
    const TissueSurface ts(m, st, n);
    EXPECT_EQ(ts.ntri(), n * n * ts.nface);
    EXPECT_LT(off_the_renderer(ts, m, st, n), 1e-6) << "float positions of the renderer (radius 1)";
  }
}

TEST(TissueSurface, TrianglesFaceOutOfTheirPieceAndCutFacesAreFlagged) {
  const Model m = block_model(true);
  const Field f[2] = {affine({}, {}), affine({0.02, 0, 0, 0, 0.01, 0, 0, 0, -0.01}, {0.1, 0, 0})};
  const State st = side_state(m, f);
  const TissueSurface ts(m, st, 2);
  ASSERT_GT(ts.nface, ts.nboundary);
  int cut_tris = 0;
  for (int t = 0; t < ts.ntri(); ++t) {
    const int* v = &ts.tri[3 * t];
    Eigen::Vector3d p[3];
    for (int j = 0; j < 3; ++j) p[j] = Eigen::Vector3d(ts.x[3 * v[j]], ts.x[3 * v[j] + 1], ts.x[3 * v[j] + 2]);
    const Eigen::Vector3d n = (p[1] - p[0]).cross(p[2] - p[0]);
    // The piece's material lies behind the face: a point a little inside
    // (centroid of the element's local point pulled towards rst = 1/4) is on
    // the negative side for straight elements.
    double rin[3];
    for (int c = 0; c < 3; ++c) {
      const double rc = (ts.vert_rst[3 * v[0] + c] + ts.vert_rst[3 * v[1] + c] + ts.vert_rst[3 * v[2] + c]) / 3;
      rin[c] = rc;
    }
    EXPECT_EQ(ts.vert_elem[v[0]], ts.vert_elem[v[2]]);
    const bool cut = ts.tri_cut[t];
    cut_tris += cut;
    EXPECT_EQ(cut, ts.tri_face[t] >= ts.nboundary);
    if (cut) {
      // Cut faces lie on the plane in the reference configuration, their
      // normal along -+ the plane normal by side.
      double X[3];
      ts.reference_position(ts.vert_elem[v[0]], rin, X);
      EXPECT_NEAR(block_plane(X), 0.0, 1e-12);
      const Eigen::Vector3d pn = Eigen::Vector3d(1, 0.1, 0.05).normalized();
      const double c = n.normalized().dot(pn);
      EXPECT_NEAR(std::abs(c), 1.0, 0.05) << "triangle " << t;  // the right side is stretched a little
    } else {
      // Boundary faces of the block [0,2]x[0,1]x[0,1]: outward = away from its centre.
      const Eigen::Vector3d centroid = (p[0] + p[1] + p[2]) / 3;
      double X[3];
      ts.reference_position(ts.vert_elem[v[0]], rin, X);
      const Eigen::Vector3d out(X[0] <= 1e-12 ? -1 : X[0] >= 2 - 1e-12 ? 1 : 0, X[1] <= 1e-12 ? -1 : X[1] >= 1 - 1e-12 ? 1 : 0,
                                X[2] <= 1e-12 ? -1 : X[2] >= 1 - 1e-12 ? 1 : 0);
      ASSERT_NEAR(out.norm(), 1.0, 1e-12) << "boundary triangle " << t << " off the block's faces";
      EXPECT_GT(n.normalized().dot(out), 0.99) << "triangle " << t << " at " << centroid.transpose();
    }
  }
  EXPECT_GT(cut_tris, 0);
}

TEST(TissueSurface, CutFaceNormalsPointAcrossTheGapAwayFromTheirSide) {
  const Model m = block_model(true);
  // Side 1 moves +x by 0.2: the gap opens, each cut face looks at the other side.
  const Field f[2] = {affine({}, {}), affine({}, {0.2, 0, 0})};
  const State st = side_state(m, f);
  const TissueSurface ts(m, st, 2);
  int side0 = 0, side1 = 0;
  for (int t = 0; t < ts.ntri(); ++t) {
    if (!ts.tri_cut[t]) continue;
    const int* v = &ts.tri[3 * t];
    Eigen::Vector3d p[3];
    for (int j = 0; j < 3; ++j) p[j] = Eigen::Vector3d(ts.x[3 * v[j]], ts.x[3 * v[j] + 1], ts.x[3 * v[j] + 2]);
    const double nx = (p[1] - p[0]).cross(p[2] - p[0]).normalized()[0];
    const double centre_x = (p[0] + p[1] + p[2])[0] / 3;
    // Side 0 ends at x ~ 1.05 and faces +x; side 1 starts at x ~ 1.25 and faces -x.
    if (nx > 0) {
      ++side0;
      EXPECT_LT(centre_x, 1.2);
    } else {
      ++side1;
      EXPECT_GT(centre_x, 1.09);
    }
  }
  EXPECT_GT(side0, 0);
  EXPECT_EQ(side0, side1) << "the two faces of a straight cut have the same triangles";
}

// With the front enrichment (a slit ending inside elements) the vertices
// move with the branch DOF nodes too, N_a (F - F_a) on their cell's side of
// the cut's plane: the surface is still the renderer's (whose display mesh
// evaluates the same field; with 2 segments the grid points are the cells'
// own face points), and zeroing the branch DOFs moves it.
// The collision surface is rebuilt after every cut from the display cells
// with a flagged face only (DisplayCells::Surface: an organ's inner cells
// are most of them). Its faces, in order, must be the full display mesh's:
// the same cell, piece, local face, local coordinates and positions; and
// its vertices the renderer's. On a block with inner cells, uncut and cut by
// a plane and a slit that ends inside it (split elements, sub-tetrahedra
// inside and on the cut, whole elements with enriched nodes).
TEST(TissueSurface, TheSurfaceCellsGiveTheFullDisplayMeshsFaces) {
  const Mesh mesh = make_beam(2, 1, 1, 8, 4, 4, 2);
  const Scene s = block_scene(2);
  const Model uncut = build_model(mesh, s);
  const auto plane = make_cut_surface(plane_cut({1.05, 0, 0}, {1, 0.1, 0.05}), 0.0);
  CutSpec slit;
  slit.type = CutSpec::Type::Polygon;
  slit.points = {{0.43, -1, 0.35}, {0.43, 2, 0.35}, {0.43, 2, 2}, {0.43, -1, 2}};
  slit.json_path = "cuts[1]";
  const auto slit_surf = make_cut_surface(slit, 0.0);
  const CutLayout layout = compute_cut_layout(uncut, {plane.get(), slit_surf.get()}, nullptr);
  const Model cut = build_model(mesh, s, &layout);
  ASSERT_TRUE(cut.has_cuts());
  for (const Model* m : {&uncut, &cut}) {
    State st;
    st.u.resize(m->ndof());
    for (int d = 0; d < m->ndof(); ++d) st.u[d] = 0.01 * std::sin(0.37 * d + 0.1);
    st.v.assign(m->ndof(), 0.0);
    st.a.assign(m->ndof(), 0.0);
    const DisplayMesh full = display_mesh(*m, st), part = display_mesh(*m, st, DisplayCells::Surface);
    EXPECT_LT(part.ncell(), full.ncell() * 3 / 4) << "the block's inner cells are left out";
    const Surface sf = extract_surface(full), sp = extract_surface(part);
    ASSERT_EQ(sp.nface(), sf.nface());
    ASSERT_EQ(sp.nboundary, sf.nboundary);
    const int npe = full.npe(), npf = sf.npf();
    for (int f = 0; f < sf.nface(); ++f) {
      const int cf = sf.face_cell[f], cp = sp.face_cell[f];
      ASSERT_EQ(full.cell_elem[cf], part.cell_elem[cp]) << f;
      ASSERT_EQ(full.cell_piece[cf], part.cell_piece[cp]) << f;
      ASSERT_EQ(sf.face_local[f], sp.face_local[f]) << f;
      for (int k = 0; k < 3 * npe; ++k)
        ASSERT_EQ(full.cell_rst[3 * npe * static_cast<size_t>(cf) + k], part.cell_rst[3 * npe * static_cast<size_t>(cp) + k]);
      for (int j = 0; j < npf; ++j)
        for (int c = 0; c < 3; ++c)
          ASSERT_EQ(full.x(sf.face_nodes[npf * f + j], c), part.x(sp.face_nodes[npf * f + j], c)) << f;
    }
    const TissueSurface ts(*m, st, 2);
    EXPECT_LT(off_the_renderer(ts, *m, st, 2), 1e-6) << "float positions of the renderer (block 2 x 1 x 1)";
  }
}

TEST(TissueSurface, VerticesFollowTheFrontEnrichmentsBranchDofs) {
  const Mesh mesh = collision_block();  // 2 x 1 x 1, cells 0.5 wide
  const Scene s = block_scene(2);
  const Model uncut = build_model(mesh, s);
  CutSpec slit;  // x = 1.25 (mid-cell), from z = 0.3 (inside a cell) up
  slit.type = CutSpec::Type::Polygon;
  slit.points = {{1.25, -1, 0.3}, {1.25, 2, 0.3}, {1.25, 2, 2}, {1.25, -1, 2}};
  slit.json_path = "cuts[0]";
  const auto surf_cut = make_cut_surface(slit, 0.0);
  const CutLayout layout = compute_cut_layout(uncut, {surf_cut.get()}, nullptr, true);
  const Model m = build_model(mesh, s, &layout);
  ASSERT_TRUE(m.cuts.has_branch());
  State st;
  st.u.resize(m.ndof());
  for (int d = 0; d < m.ndof(); ++d) st.u[d] = 0.01 * std::sin(0.37 * d + 0.1);
  st.v.assign(m.ndof(), 0.0);
  st.a.assign(m.ndof(), 0.0);
  const TissueSurface ts(m, st, 2);
  const double worst = off_the_renderer(ts, m, st, 2);
  State st0 = st;
  for (int i = 0; i < m.nnode; ++i)
    if (m.cuts.node_branch[i] >= 0)
      for (int k = 0; k < kBranchFunctions; ++k)
        for (int c = 0; c < 3; ++c) st0.u[3 * (m.cuts.node_branch[i] + k) + c] = 0.0;
  const TissueSurface ts0(m, st0, 2);
  double moved = 0;
  int sides[2] = {0, 0};
  for (int k = 0; k < 3 * ts.nvert(); ++k) moved = std::max(moved, std::abs(ts.x[k] - ts0.x[k]));
  for (int v = 0; v < ts.nvert(); ++v)
    if (ts.vert_side[v] != 0) ++sides[ts.vert_side[v] > 0];
  std::printf("surface against the renderer %.2e; the branch DOFs move it by up to %.2e; %d / %d vertices on "
              "either side of the front's plane\n",
              worst, moved, sides[0], sides[1]);
  EXPECT_LT(worst, 1e-6) << "float positions of the renderer (block 2 x 1 x 1)";
  EXPECT_GT(moved, 1e-3);
  EXPECT_GT(sides[0], 0);
  EXPECT_GT(sides[1], 0);
}

TEST(TissueSurface, UpdatePositionsFollowsTheStateAndChecksItsSize) {
  const Model m = block_model(true);
  const Field f0[2] = {bend, bend}, rest[2] = {affine({}, {}), affine({}, {})};
  TissueSurface ts(m, side_state(m, rest), 2);
  const State st = side_state(m, f0);
  ts.update_positions(st);
  const TissueSurface fresh(m, st, 2);
  for (int k = 0; k < 3 * ts.nvert(); ++k) ASSERT_EQ(ts.x[k], fresh.x[k]);
  State wrong = st;
  wrong.u.resize(wrong.u.size() - 3);
  try {
    ts.update_positions(wrong);
    FAIL() << "a state of another model must be refused";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("rebuild it after a cut"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace incise::test
