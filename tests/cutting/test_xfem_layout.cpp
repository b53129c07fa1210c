// X-FEM: separation, free fall of a cut-off piece, masses, pieces and bodies,
// probes on each side, degenerate cuts through nodes and faces.
#include <algorithm>
#include <cmath>
#include <functional>
#include <string>

#include <Eigen/Dense>
#include <gtest/gtest.h>

#include "engine/fem/assemble.h"
#include "engine/fem/assemble_parallel.h"
#include "engine/output/probe.h"
#include "engine/model/front_enrichment.h"
#include "engine/dynamics/step.h"
#include "engine/fem/polar.h"
#include "test_util.h"

namespace incise {
namespace {

// Beam [0,4]x[0,1]x[0,1], 8x2x2 cells, fixed at x = 0, gravity -z.
std::unique_ptr<Simulation> cantilever(int order, std::vector<CutSpec> cuts, MassKind mass = MassKind::Lumped) {
  Scene s = test::block_scene(order);
  s.mass = mass;
  s.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
  s.cuts = std::move(cuts);
  return test::make_sim(make_beam(4, 1, 1, 8, 2, 2, 1), s);
}

// Mean acceleration (z) of the material beyond x > x0, from probes.
double piece_acceleration(const Simulation& sim, double x0) {
  double az = 0;
  int n = 0;
  for (double x = x0 + 0.2; x < 4.0; x += 0.4) {
    const double p[3] = {x, 0.5, 0.5};
    const ProbeHit h = locate_point(sim.model, p);
    az += interpolate_displacement(sim.model, sim.state.a.data(), h)[2];
    ++n;
  }
  return az / n;
}

TEST(Xfem, CutOffPieceFallsFreelyAndNoForceCrossesTheCut) {
  for (int order : {1, 2})
    for (MassKind mk : {MassKind::Lumped, MassKind::Consistent}) {
      // plane x = 2.3 does not conform to the mesh (cells of 0.5)
      auto sim = cantilever(order, {test::plane_cut({2.3, 0, 0}, {1, 0, 0})}, mk);
      const CutUpdate up = update_cuts(*sim, 0.0, 0.0);
      ASSERT_TRUE(up.changed);
      EXPECT_EQ(up.report.bodies, 2);
      EXPECT_GT(up.report.enriched_nodes, 0);
      for (int k = 0; k < 10; ++k) step(sim->model, sim->state, sim->ws);
      const double g = 9.81;
      EXPECT_NEAR(piece_acceleration(*sim, 2.3) / -g, 1.0, 0.01) << "order " << order;
      // the free piece is not stretched: its displacement is uniform (rigid fall)
      const double t = sim->state.time;
      const double p[3] = {3.9, 0.5, 0.5}, q[3] = {2.5, 0.1, 0.9};
      const auto up1 = interpolate_displacement(sim->model, sim->state.u.data(), locate_point(sim->model, p));
      const auto up2 = interpolate_displacement(sim->model, sim->state.u.data(), locate_point(sim->model, q));
      EXPECT_NEAR(up1[2], -0.5 * g * t * t, 1e-3 * 0.5 * g * t * t);
      EXPECT_NEAR(up1[2], up2[2], 1e-6);
    }
}

TEST(Xfem, MassesPositiveAndSumToTheUncutMass) {
  for (int order : {1, 2}) {
    auto sim = cantilever(order, {test::plane_cut({2.3, 0, 0}, {1, 0.2, 0.1})});
    const double total = 4.0 * 1.0;  // rho = 1
    update_cuts(*sim, 0.0, 0.0);
    const Model& m = sim->model;
    ASSERT_FALSE(m.mass_csc.empty());
    // rigid translation: 1' M 1 over one component = total mass
    std::vector<double> one(m.ndof(), 0.0), Mo(m.ndof());
    for (int i = 0; i < m.nnode; ++i) one[3 * i] = 1.0;
    mass_matvec(m, one.data(), Mo.data());
    double mass = 0;
    for (int d = 0; d < m.ndof(); ++d) mass += one[d] * Mo[d];
    EXPECT_NEAR(mass, total, 1e-12 * total);
    for (int d = 0; d < m.ndof(); ++d) EXPECT_GT(m.mass_lumped[d], 0.0);
    // the two sides' masses (phantom view): a unit velocity of one side only
    double side_mass = 0;
    for (int q = m.nnode; q < m.ndofnode; ++q) side_mass += m.mass_lumped[3 * q];
    EXPECT_GT(side_mass, 0.0);
    EXPECT_LT(side_mass, total);
  }
}

TEST(Xfem, ProbesAboveAndBelowTheCutReportEachSide) {
  auto sim = cantilever(2, {test::plane_cut({2.3, 0, 0}, {1, 0, 0})});
  update_cuts(*sim, 0.0, 0.0);
  for (int k = 0; k < 15; ++k) step(sim->model, sim->state, sim->ws);
  const double below[3] = {2.3 - 1e-6, 0.5, 0.5}, above[3] = {2.3 + 1e-6, 0.5, 0.5};
  const ProbeHit hb = locate_point(sim->model, below), ha = locate_point(sim->model, above);
  ASSERT_EQ(hb.elem, ha.elem);  // same element, different pieces
  EXPECT_NE(hb.piece, ha.piece);
  const double ub = interpolate_displacement(sim->model, sim->state.u.data(), hb)[2];
  const double ua = interpolate_displacement(sim->model, sim->state.u.data(), ha)[2];
  const double t = sim->state.time;
  EXPECT_NEAR(ua, -0.5 * 9.81 * t * t, 1e-3 * 0.5 * 9.81 * t * t);  // falling piece
  EXPECT_GT(ub, 0.5 * ua);  // the clamped side hangs on its support
}

TEST(Xfem, CutExactlyThroughNodesAndFacesSeparates) {
  // x = 2.0 is a layer of mesh nodes and faces: no element is crossed, the
  // separation comes from faces lying on the cut.
  for (int order : {1, 2}) {
    auto sim = cantilever(order, {test::plane_cut({2.0, 0, 0}, {1, 0, 0})});
    const CutUpdate up = update_cuts(*sim, 0.0, 0.0);
    EXPECT_EQ(up.report.cut_elements, 0);
    EXPECT_GT(up.report.separated_faces, 0);
    EXPECT_EQ(up.report.bodies, 2);
    for (int k = 0; k < 10; ++k) step(sim->model, sim->state, sim->ws);
    EXPECT_NEAR(piece_acceleration(*sim, 2.0) / -9.81, 1.0, 0.01);
  }
}

TEST(Xfem, CrossingCutsGiveTheRightNumberOfPieces) {
  Scene s = test::block_scene(1);
  const Mesh block = make_beam(2, 2, 1, 4, 4, 2, 1);
  // X: two full planes crossing at the centre -> 4 bodies
  s.cuts = {test::plane_cut({1.03, 0, 0}, {1, 0.1, 0}), test::plane_cut({0, 0.97, 0}, {0.05, 1, 0}, "cuts[1]")};
  auto sim = test::make_sim(block, s);
  EXPECT_EQ(update_cuts(*sim, 0.0, 0.0).report.bodies, 4);
  // T: a full plane and a half plane (polygon) ending on it -> 3 bodies
  CutSpec half;
  half.type = CutSpec::Type::Polygon;
  half.points = {{-1, 0.97, -1}, {1.03, 0.97, -1}, {1.03, 0.97, 2}, {-1, 0.97, 2}};
  half.json_path = "cuts[1]";
  s.cuts = {test::plane_cut({1.03, 0, 0}, {1, 0, 0}), half};
  auto sim2 = test::make_sim(block, s);
  EXPECT_EQ(update_cuts(*sim2, 0.0, 0.0).report.bodies, 3);
}

}  // namespace
}  // namespace incise

#include "engine/output/display_mesh.h"
#include "engine/output/result_grid.h"

namespace incise {
namespace {

TEST(Xfem, DisplayShowsTheCutOpeningWithInnerFacesFlagged) {
  auto sim = cantilever(2, {test::plane_cut({2.3, 0, 0}, {1, 0, 0})});
  const DisplayMesh before = display_mesh(sim->model, sim->state);
  int cut_faces = 0;
  for (unsigned char f : before.face_flags) cut_faces += (f & kFaceCut) != 0;
  EXPECT_EQ(cut_faces, 0);
  update_cuts(*sim, 0.0, 0.0);
  for (int k = 0; k < 10; ++k) step(sim->model, sim->state, sim->ws);
  const DisplayMesh after = display_mesh(sim->model, sim->state);
  EXPECT_GT(after.ncell(), before.ncell());
  // Cut faces exist, and the faces on the two sides have moved apart: the
  // gap between the lowest point of the fixed side's cut face and the free
  // side's, measured in z, is the free fall distance.
  double zmin_fixed = 1e9, zmin_free = 1e9;
  for (int c = 0; c < after.ncell(); ++c)
    for (int k = 0; k < 4; ++k) {
      if (!(after.face_flags[4 * c + k] & kFaceCut)) continue;
      for (int j = 0; j < 3; ++j) {
        const int p = after.cells[c * after.npe() + kTetFace[k][j]];
        // which side: compare the cell's centroid with the cut plane
        double cx = 0;
        for (int a = 0; a < 4; ++a) cx += after.X[3 * after.cells[c * after.npe() + a]] / 4;
        (cx < 2.3 ? zmin_fixed : zmin_free) =
            std::min(cx < 2.3 ? zmin_fixed : zmin_free, after.x(p, 2));
      }
    }
  const double t = sim->state.time;
  EXPECT_LT(zmin_free, zmin_fixed - 0.5 * 0.5 * 9.81 * t * t);
  const VtuGrid g = result_grid(sim->model, sim->state);
  EXPECT_EQ(static_cast<int>(g.types.size()), after.ncell());
}

}  // namespace
}  // namespace incise

#include "cutting/conforming_slit.h"
#include "engine/dynamics/static_solve.h"

namespace incise {
namespace {

// A face-aligned slit through the X-FEM (separated faces) and through a mesh
// with duplicated nodes are the same discrete model: equal displacements.
TEST(Xfem, FaceAlignedSlitEqualsANodeDuplicatedMesh) {
  for (int order : {1, 2})
    for (MaterialModel mm : {MaterialModel::Linear, MaterialModel::Corotated}) {
      Scene s = test::block_scene(order);
      s.material.model = mm;
      s.mass = MassKind::Consistent;
      s.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
      const Mesh beam = make_beam(4, 1, 1, 8, 2, 2, 1);
      // X-FEM: slit polygon x = 2, z >= 0.5
      CutSpec slit;
      slit.type = CutSpec::Type::Polygon;
      slit.points = {{2, -1, 0.5}, {2, 2, 0.5}, {2, 2, 3}, {2, -1, 3}};
      slit.json_path = "cuts[0]";
      s.cuts = {slit};
      auto sim = test::make_sim(beam, s);
      const CutUpdate up = apply_all_cuts(*sim);
      EXPECT_EQ(up.report.cut_elements, 0);
      EXPECT_GT(up.report.separated_faces, 0);
      ASSERT_TRUE(solve_static(sim->model, sim->state, sim->ws, 1e-10, 100).converged);
      // conforming mesh
      Scene sc = s;
      sc.cuts.clear();
      const Mesh dup = duplicate_nodes_along_slit(order == 2 ? raise_to_tet10(beam) : beam, 2.0, 0.5);
      sc.order = order;
      auto ref = test::make_sim(dup, sc);
      ASSERT_TRUE(solve_static(ref->model, ref->state, ref->ws, 1e-10, 100).converged);
      double err = 0, mag = 0;
      for (double x : {0.7, 1.9, 2.1, 3.3, 4.0})
        for (double z : {0.1, 0.9}) {
          const double p[3] = {x, 0.5, z};
          const auto a = interpolate_displacement(sim->model, sim->state.u.data(), locate_point(sim->model, p));
          const auto b = interpolate_displacement(ref->model, ref->state.u.data(), locate_point(ref->model, p));
          for (int d = 0; d < 3; ++d) {
            err = std::max(err, std::abs(a[d] - b[d]));
            mag = std::max(mag, std::abs(b[d]));
          }
        }
      EXPECT_LT(err, 1e-7 * mag) << "order " << order;  // both solved to a 1e-10 residual
      // and the slit is open: at the top the two faces separate
      const double lo[3] = {2 - 1e-9, 0.5, 1.0}, hi[3] = {2 + 1e-9, 0.5, 1.0};
      const double gap = interpolate_displacement(sim->model, sim->state.u.data(), locate_point(sim->model, hi))[0] -
                         interpolate_displacement(sim->model, sim->state.u.data(), locate_point(sim->model, lo))[0];
      EXPECT_GT(std::abs(gap), 1e-3 * mag);
    }
}

}  // namespace
}  // namespace incise

#include <filesystem>
#include <fstream>

#include "engine/util/error.h"

namespace incise {
namespace {

// A scene cut of type "mesh" reading `file`.
CutSpec mesh_cut(const std::string& file) {
  CutSpec c;
  c.type = CutSpec::Type::Mesh;
  c.file = file;
  c.json_path = "cuts[0]";
  return c;
}

TEST(Xfem, TriangleMeshCutFromObjAndStlMatchesThePlane) {
  const auto dir = std::filesystem::temp_directory_path();
  const std::string obj = (dir / "incise_cut_square.obj").string(), stl = (dir / "incise_cut_square.stl").string();
  std::ofstream(obj) << "# square x = 2.3\nv 2.3 -1 -1\nv 2.3 2 -1\nv 2.3 2 2\nv 2.3 -1 2\nf 1 2 3\nf 1 3 4\n";
  std::ofstream(stl) << "solid s\nfacet normal 1 0 0\nouter loop\nvertex 2.3 -1 -1\nvertex 2.3 2 -1\nvertex 2.3 2 2\n"
                        "endloop\nendfacet\nfacet normal 1 0 0\nouter loop\nvertex 2.3 -1 -1\nvertex 2.3 2 2\n"
                        "vertex 2.3 -1 2\nendloop\nendfacet\nendsolid s\n";
  for (const std::string& f : {obj, stl}) {
    auto sim = cantilever(1, {mesh_cut(f)});
    const CutUpdate up = update_cuts(*sim, 0.0, 0.0);
    EXPECT_EQ(up.report.bodies, 2) << f;
    auto ref = cantilever(1, {test::plane_cut({2.3, 0, 0}, {1, 0, 0})});
    const CutUpdate upr = update_cuts(*ref, 0.0, 0.0);
    EXPECT_EQ(up.report.enriched_nodes, upr.report.enriched_nodes);
    EXPECT_EQ(up.report.pieces, upr.report.pieces);
  }
  std::ofstream(obj) << "v 0 0 0\nv 1 0 0\nf 1 2 7\n";
  try {
    read_triangle_surface(obj);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("incise_cut_square.obj:3: face references vertex 7, but only 2 are defined"),
              std::string::npos)
        << e.what();
  }
  std::filesystem::remove(obj);
  std::filesystem::remove(stl);
}

// Triangle surfaces as exported by meshing tools, through the 4 x 1 x 1
// beam: a plane with mixed winding, a plane bent by 10 degrees along a line
// inside the body, and a cylinder's arc. Each severs the beam (two bodies,
// no front element). Mixed winding flipped the nearest-facet level set's
// sign from facet to facet; the bent and curved surfaces left their crossed
// elements as "front" elements (the level set's zero, interpolated along an
// edge, strays from the facets) and separated nothing. A Moebius strip has
// no two sides: refused.
TEST(Xfem, TriangleSurfacesWithMixedWindingBendsAndCurvesSever) {
  const auto dir = std::filesystem::temp_directory_path();
  // Rows of vertices along y at each (x, z) of a profile, as triangles;
  // `mixed` winds every other triangle the other way.
  const auto sheet = [&](const std::string& name, const std::vector<std::array<double, 2>>& xz, bool mixed) {
    const std::string f = (dir / name).string();
    std::ofstream os(f);
    os.precision(17);
    const double ys[3] = {-1.0, 0.5, 2.0};
    for (const auto& p : xz)
      for (double y : ys) os << "v " << p[0] << ' ' << y << ' ' << p[1] << '\n';
    int t = 0;
    for (size_t i = 0; i + 1 < xz.size(); ++i)
      for (int j = 0; j < 2; ++j) {
        const size_t a = 3 * i + j + 1, b = a + 1, c = a + 3, d = a + 4;  // 1-based
        for (const auto& tri : {std::array<size_t, 3>{a, b, d}, std::array<size_t, 3>{a, d, c}})
          if (mixed && t++ % 2) os << "f " << tri[0] << ' ' << tri[2] << ' ' << tri[1] << '\n';
          else os << "f " << tri[0] << ' ' << tri[1] << ' ' << tri[2] << '\n';
      }
    return f;
  };
  const double bend = std::tan(10.0 * M_PI / 180.0);
  std::vector<std::array<double, 2>> arc;
  for (int k = 0; k <= 12; ++k) {
    const double th = (-60.0 + 10.0 * k) * M_PI / 180.0;
    arc.push_back({0.3 + 2.0 * std::cos(th), 0.5 + 2.0 * std::sin(th)});
  }
  const std::string files[3] = {
      sheet("incise_cut_mixed.obj", {{2.3, -1.0}, {2.3, 0.0}, {2.3, 1.0}, {2.3, 2.0}}, true),
      sheet("incise_cut_bent.obj", {{2.3, -1.0}, {2.3, 0.6}, {2.3 + 1.4 * bend, 2.0}}, false),
      sheet("incise_cut_arc.obj", arc, false)};
  for (const std::string& f : files) {
    auto sim = cantilever(2, {mesh_cut(f)});
    const CutUpdate up = update_cuts(*sim, 0.0, 0.0);
    EXPECT_EQ(up.report.bodies, 2) << f;
    EXPECT_EQ(up.report.front_elements, 0) << f;
    EXPECT_GT(up.report.cut_elements, 0) << f;
    std::filesystem::remove(f);
  }
  // A Moebius strip: a band along x, its two ends joined with a half turn.
  const std::string moebius = (dir / "incise_cut_moebius.obj").string();
  {
    std::ofstream os(moebius);
    const int n = 12;
    for (int k = 0; k < n; ++k) {
      const double u = 2.0 * M_PI * k / n, w = 0.3;
      for (double s : {-w, w})
        os << "v " << (1 + s * std::cos(u / 2)) * std::cos(u) << ' ' << (1 + s * std::cos(u / 2)) * std::sin(u) << ' '
           << s * std::sin(u / 2) << '\n';
    }
    for (int k = 0; k < n; ++k) {
      const int a = 2 * k + 1, b = a + 1;
      const int c = k + 1 < n ? a + 2 : 2, d = k + 1 < n ? b + 2 : 1;  // the last band joins the first turned over
      os << "f " << a << ' ' << b << ' ' << d << "\nf " << a << ' ' << d << ' ' << c << '\n';
    }
  }
  try {
    read_triangle_surface(moebius);
    ADD_FAILURE() << "a Moebius strip was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("the triangles have no consistent winding"), std::string::npos) << e.what();
  }
  std::filesystem::remove(moebius);
}

// A V-shaped surface (two sheets folded along y at x = 2.3, z = 0.3, their
// arms leaving the beam's top) cuts its wedge out of the beam. The level set
// was the signed distance to the nearest facet's plane: below the fold the
// nearest point is on the fold line, either arm's plane extended puts some
// of those points on the wedge's side, and the sign flipped from node to
// node ("cuts nothing", or a wedge with holes). Where the nearest point is on
// an edge or a corner the sign is now the angle-weighted pseudonormal's
// (Baerentzen and Aanaes 2005). Both windings, and a sharper fold.
TEST(Xfem, AVNotchSurfaceCutsOutItsWedge) {
  const auto dir = std::filesystem::temp_directory_path();
  for (const double half_width : {0.8, 0.2})
    for (const bool flipped : {false, true}) {
      const std::string f = (dir / "incise_cut_vnotch.obj").string();
      {
        std::ofstream os(f);
        os.precision(17);
        const double xz[3][2] = {{2.3 - half_width, 2.0}, {2.3, 0.3}, {2.3 + half_width, 2.0}};
        for (const auto& p : xz)
          for (double y : {-1.0, 0.5, 2.0}) os << "v " << p[0] << ' ' << y << ' ' << p[1] << '\n';
        for (int i = 0; i < 2; ++i)
          for (int j = 0; j < 2; ++j) {
            const int a = 3 * i + j + 1, b = a + 1, c = a + 3, d = a + 4;
            if (flipped) os << "f " << a << ' ' << d << ' ' << b << "\nf " << a << ' ' << c << ' ' << d << '\n';
            else os << "f " << a << ' ' << b << ' ' << d << "\nf " << a << ' ' << d << ' ' << c << '\n';
          }
      }
      const CutSurface surface(read_triangle_surface(f), "vnotch");
      const double wedge[3] = {2.3, 0.5, 0.8};
      const int sw = surface.value(wedge).sign;
      ASSERT_NE(sw, 0);
      // Every point of a grid around the fold (0.05 apart, the fold's own
      // column included): inside the wedge (above both arms) or outside.
      int wrong = 0, points = 0;
      for (double x = 1.0; x <= 3.6; x += 0.05)
        for (double z = -1.0; z <= 1.5; z += 0.05) {
          const double above = z - (0.3 + std::abs(x - 2.3) * 1.7 / half_width);
          if (std::abs(above) < 1e-6) continue;
          const double p[3] = {x, 0.5, z};
          wrong += surface.value(p).sign != (above > 0 ? sw : -sw);
          ++points;
        }
      EXPECT_EQ(wrong, 0) << "of " << points << " points, half width " << half_width << (flipped ? " flipped" : "");
      auto sim = cantilever(2, {mesh_cut(f)});
      const CutUpdate up = update_cuts(*sim, 0.0, 0.0);
      // The narrow wedge holds no node of the 0.5 m cells: nothing to cut.
      EXPECT_EQ(up.report.bodies, half_width > 0.5 ? 2 : 1) << half_width << (flipped ? " flipped" : "");
      EXPECT_EQ(up.report.front_elements, 0) << half_width << (flipped ? " flipped" : "");
      std::filesystem::remove(f);
    }
}

// One oblique triangle whose corners lie 1 m, 1e4 m or 1e8 m away, through
// the beam: the same plane cuts the same elements. The zero crossings were
// checked against the triangle within 1e-9 h, which its own roundoff (a few
// ulps of 1e8 m) exceeded: the big triangle "cut nothing".
TEST(Xfem, AHugeTriangleCutsAsASmallOneDoes) {
  const auto dir = std::filesystem::temp_directory_path();
  const Eigen::Vector3d n = Eigen::Vector3d(1.0, 0.3, 0.2).normalized(), p0(2.3, 0.5, 0.5);
  const Eigen::Vector3d u = n.cross(Eigen::Vector3d::UnitZ()).normalized(), w = n.cross(u);
  int elements = -1;
  for (const double size : {1.0, 1e4, 1e8}) {
    const std::string f = (dir / "incise_cut_huge.obj").string();
    {
      std::ofstream os(f);
      os.precision(17);
      for (const Eigen::Vector3d& v : {Eigen::Vector3d(p0 + size * (-u - w)), Eigen::Vector3d(p0 + size * (3 * u - w)),
                                       Eigen::Vector3d(p0 + size * (-u + 3 * w))})
        os << "v " << v[0] << ' ' << v[1] << ' ' << v[2] << '\n';
      os << "f 1 2 3\n";
    }
    auto sim = cantilever(2, {mesh_cut(f)});
    const CutUpdate up = update_cuts(*sim, 0.0, 0.0);
    EXPECT_EQ(up.report.bodies, 2) << size;
    EXPECT_EQ(up.report.front_elements, 0) << size;
    if (elements < 0) elements = up.report.cut_elements;
    EXPECT_EQ(up.report.cut_elements, elements) << size;
    std::filesystem::remove(f);
  }
  EXPECT_GT(elements, 0);
}

TEST(Xfem, CutAlongAnEdgeAndAFlapCutTwice) {
  // A plane containing the vertical mesh edge x = 2, y = 0 but no face.
  auto sim = cantilever(2, {test::plane_cut({2.0, 0.0, 0.0}, {1, 0.37, 0})});
  CutUpdate up = update_cuts(*sim, 0.0, 0.0);
  EXPECT_EQ(up.report.bodies, 2);
  for (int k = 0; k < 10; ++k) step(sim->model, sim->state, sim->ws);
  for (double x : sim->state.u) ASSERT_TRUE(std::isfinite(x));
  // Two parallel cuts through the same column of elements: three bodies.
  auto twice = cantilever(1, {test::plane_cut({2.3, 0, 0}, {1, 0, 0}), test::plane_cut({2.4, 0, 0}, {1, 0, 0}, "cuts[1]")});
  up = update_cuts(*twice, 0.0, 0.0);
  EXPECT_EQ(up.report.bodies, 3);
  for (int k = 0; k < 10; ++k) step(twice->model, twice->state, twice->ws);
  // the thin slab between the cuts falls freely too
  const double p[3] = {2.35, 0.5, 0.5};
  const double t = twice->state.time;
  EXPECT_NEAR(interpolate_displacement(twice->model, twice->state.u.data(), locate_point(twice->model, p))[2] /
                  (-0.5 * 9.81 * t * t),
              1.0, 0.01);
}

}  // namespace
}  // namespace incise

namespace incise {
namespace {

TEST(Xfem, NonConvexPolygonIsRefusedWithItsPath) {
  CutSpec L;
  L.type = CutSpec::Type::Polygon;
  L.points = {{0, 0, 0.5}, {1, 0, 0.5}, {1, 0.1, 0.5}, {0.1, 0.1, 0.5}, {0.1, 1, 0.5}, {0, 1, 0.5}};
  L.json_path = "cuts[2]";
  try {
    make_cut_surface(L, 0.0);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("cuts[2].points: polygon must be convex"), std::string::npos) << e.what();
  }
}

TEST(Xfem, ObliqueBladeRebuildsOnlyWhenItCrossesAnElement) {
  // An oblique, planar sweep: the layout must stay bit-identical while the
  // blade advances inside elements, so most frames rebuild nothing.
  auto sim = cantilever(1, {test::swept_blade({Vec3{2.1, -0.5, 1.3}, Vec3{2.4, 1.5, 1.3}},
                                              {Vec3{2.3, -0.5, -0.3}, Vec3{2.6, 1.5, -0.3}})});
  int frames = 0, rebuilds = 0, bodies = 0;
  for (int k = 0; k <= 60; ++k, ++frames) {
    const CutUpdate up = update_cuts(*sim, k / 60.0, k / 60.0);
    rebuilds += up.changed;
    if (up.changed) bodies = up.report.bodies;
  }
  EXPECT_GT(rebuilds, 0);
  EXPECT_LT(rebuilds, frames / 2) << rebuilds << " rebuilds in " << frames << " frames";
  EXPECT_EQ(bodies, 2);  // the finished sweep cuts the end off
}

}  // namespace
}  // namespace incise

namespace incise {
namespace {

// The lumped X-FEM mass is solved directly in consistent_acceleration (an
// arrowhead per node); the result must satisfy M a = f - f_int - D v on the
// free DOFs, with M the full stored matrix, for an arbitrary state; and for
// several right-hand sides at once (lumped_mass_solve_multi).
TEST(Xfem, LumpedAccelerationAfterACutSolvesTheMassSystem) {
  for (int order : {1, 2}) {
    Scene s = test::block_scene(order);
    s.material.rayleigh_mass = 0.5;
    s.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
    s.cuts = {test::plane_cut({2.3, 0, 0}, {1, 0.2, 0.1}), test::plane_cut({0, 0, 0.55}, {0.1, 0, 1}, "cuts[1]")};
    auto sim = test::make_sim(make_beam(4, 1, 1, 8, 2, 2, 1), s);
    ASSERT_TRUE(update_cuts(*sim, 0.0, 0.0).changed);
    const Model& m = sim->model;
    ASSERT_FALSE(m.mass_csc.empty());
    State& st = sim->state;
    for (int d = 0; d < m.ndof(); ++d) {
      st.u[d] = m.constrained[d] ? 0.0 : 1e-3 * std::sin(0.7 * d);
      st.v[d] = m.constrained[d] ? 0.0 : 1e-2 * std::cos(1.3 * d);
    }
    consistent_acceleration(m, st, sim->ws);
    std::vector<double> Ma(m.ndof()), Mv(m.ndof());
    mass_matvec(m, st.a.data(), Ma.data());
    mass_matvec(m, st.v.data(), Mv.data());
    double err = 0, ref = 0;
    for (int d = 0; d < m.ndof(); ++d) {
      if (m.constrained[d]) {
        EXPECT_EQ(st.a[d], 0.0);
        continue;
      }
      const double rhs = m.f_gravity[d] - sim->ws.f_int[d] - s.material.rayleigh_mass * Mv[d];
      err = std::max(err, std::abs(Ma[d] - rhs));
      ref = std::max(ref, std::abs(rhs));
    }
    EXPECT_LT(err, 1e-12 * ref) << "order " << order;
    // The contact kinematics' k columns at once (lumped_mass_solve_multi):
    // M X = B on the free DOFs, 0 on the constrained ones.
    const int n = m.ndof(), k = 3;
    const std::vector<double> B = test::random_vector(n * k, 23);
    std::vector<double> X(B.size()), MX(n);
    ASSERT_TRUE(lumped_mass_solve_multi(m, k, B.data(), X.data()));
    for (int c = 0; c < k; ++c) {
      mass_matvec(m, X.data() + static_cast<size_t>(c) * n, MX.data());
      double e = 0, b = 0;
      for (int d = 0; d < n; ++d) {
        if (m.constrained[d]) {
          EXPECT_EQ(X[static_cast<size_t>(c) * n + d], 0.0);
          continue;
        }
        e = std::max(e, std::abs(MX[d] - B[static_cast<size_t>(c) * n + d]));
        b = std::max(b, std::abs(B[static_cast<size_t>(c) * n + d]));
      }
      EXPECT_LT(e, 1e-12 * b) << "order " << order << ", column " << c;
    }
  }
}

// A cut that severs the beam [0,4]x[0,1]x[0,1] by the plane
// (x - 2.3) + 0.2 y + 0.1 z = 0 leaves two bodies of 2.15 and 1.85 (the
// plane's x averaged over the cross-section: 2.3 - 0.1 - 0.05): each rotation
// slot knows its body, the slots' volumes sum to each, and the rotation
// change is judged per body (decide_newton): the smaller body turned by
// 0.5 rad while the larger stays is all of that body above the threshold,
// though 46% of the tissue.
TEST(Xfem, EachSeveredBodysSlotsAreJudgedByItsOwnVolume) {
  Scene s = test::block_scene(2);
  s.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
  const Mesh mesh = make_beam(4, 1, 1, 8, 2, 2, 1);
  const Model uncut = build_model(mesh, s);
  EXPECT_EQ(uncut.nbody, 1);
  EXPECT_TRUE(uncut.rot_body.empty());
  const auto plane = make_cut_surface(test::plane_cut({2.3, 0, 0}, {1, 0.2, 0.1}), 0.0);
  const CutLayout layout = compute_cut_layout(uncut, {plane.get()}, nullptr);
  ASSERT_EQ(layout.bodies, 2);
  ASSERT_EQ(layout.piece_body.size(), layout.piece_fraction.size());
  const Model m = build_model(mesh, s, &layout);
  ASSERT_EQ(m.nbody, 2);
  ASSERT_EQ(static_cast<int>(m.rot_body.size()), m.nrot);
  const AssemblyPlan plan0 = make_assembly_plan(m, 1);
  double vol[2] = {0, 0}, x_mean[2] = {0, 0};
  for (int r = 0; r < m.nrot; ++r) {
    ASSERT_TRUE(m.rot_body[r] == 0 || m.rot_body[r] == 1);
    vol[m.rot_body[r]] += plan0.slot_volume[r];
    const int e = m.rot_elem[r];
    double xc = 0.0;
    for (int a = 0; a < 4; ++a) xc += 0.25 * m.X[3 * mesh.tet[static_cast<size_t>(e) * mesh.npe() + a]];
    x_mean[m.rot_body[r]] += plan0.slot_volume[r] * xc;
  }
  const int clamped = x_mean[0] / vol[0] < x_mean[1] / vol[1] ? 0 : 1, free_end = 1 - clamped;
  EXPECT_NEAR(vol[clamped], 2.15, 1e-10);
  EXPECT_NEAR(vol[free_end], 1.85, 1e-10);

  State st;
  Workspace ws;
  init_state(m, st, ws);
  const Eigen::Matrix3d Q = Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  for (int r = 0; r < m.nrot; ++r)
    if (m.rot_body[r] == free_end) Eigen::Map<Eigen::Matrix3d>(&st.R[9 * static_cast<size_t>(r)]) = Q;
  const std::vector<double> u(m.ndof(), 0.0);
  const RotationChange rc = rotation_change(m, ws.work.plan, *ws.work.pool, u.data(), st.R.data(), 0.1);
  EXPECT_NEAR(rc.max, 0.5, 1e-9);
  EXPECT_NEAR(rc.above / rc.volume, 1.85 / 4.0, 1e-10);
  EXPECT_NEAR(rc.rms, 0.5 * std::sqrt(1.85 / 4.0), 1e-9);
  EXPECT_NEAR(rc.body_above, 1.0, 1e-12);
  EXPECT_NEAR(rc.body_rms, 0.5, 1e-9);
  // Bodies under half the tissue counted apart: the free end (46%).
  const RotationChange halves = rotation_change(m, ws.work.plan, *ws.work.pool, u.data(), st.R.data(), 0.1, 0.5);
  EXPECT_EQ(halves.body_above, 0.0);
  EXPECT_EQ(halves.body_rms, 0.0);
  EXPECT_NEAR(halves.small_above, 1.0, 1e-12);
  EXPECT_NEAR(halves.small_rms, 0.5, 1e-9);
}

// Newton's stop on the two bodies of the same severed beam, after one
// iteration whose result is the rest shape while one body's frozen rotations
// are turned by 0.5 rad (decide_newton): a body of at least rotation_fraction
// of the tissue iterates again; a smaller one (the free end, 46% of the
// volume, under a fraction of 0.5) iterates again only in a cut frame, and
// otherwise stops and asks for a recovery step (FrameTiming::newton_capped).
TEST(Xfem, ASmallSeveredPieceIteratesInCutFramesAndElseAsksForARecoveryStep) {
  Scene s = test::block_scene(2);
  s.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
  const Mesh mesh = make_beam(4, 1, 1, 8, 2, 2, 1);
  const auto plane = make_cut_surface(test::plane_cut({2.3, 0, 0}, {1, 0.2, 0.1}), 0.0);
  const CutLayout layout = compute_cut_layout(build_model(mesh, s), {plane.get()}, nullptr);
  struct Stop {
    bool done, recover;
  };
  const auto decide = [&](double fraction, bool turn_free_end, bool cut_frame) {
    Scene sc = s;
    sc.rotation_fraction = fraction;
    sc.rotation_rms = 0.0;
    const Model m = build_model(mesh, sc, &layout);
    State st;
    Workspace ws;
    init_state(m, st, ws);
    step(m, st, ws);  // the workspace as a step leaves it
    // The clamped body holds the slots of element 0 (at x = 0).
    const int clamped = m.rot_body[0];
    for (int d = 0; d < m.ndof(); ++d) ws.delta[d] = -st.u[d];  // the iteration's result: u + Delta = 0
    const Eigen::Matrix3d Q = Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
    for (int r = 0; r < m.nrot; ++r) {
      const bool turned = (m.rot_body[r] != clamped) == turn_free_end;
      Eigen::Map<Eigen::Matrix3d>(&st.R[9 * static_cast<size_t>(r)]) = turned ? Q : Eigen::Matrix3d::Identity();
    }
    ws.newton_iterations_done = 1;
    ws.timing.cut_frame = cut_frame;
    decide_newton(m, st, ws);
    return Stop{ws.newton_done, ws.timing.newton_capped};
  };
  for (const bool cut_frame : {false, true}) {
    const Stop big = decide(1e-4, true, cut_frame);
    EXPECT_FALSE(big.done) << "a body above the fraction iterates (cut frame " << cut_frame << ")";
    const Stop clamped = decide(0.5, false, cut_frame);
    EXPECT_FALSE(clamped.done) << "the clamped body (54%) is above the fraction (cut frame " << cut_frame << ")";
  }
  const Stop small_cut = decide(0.5, true, true);
  EXPECT_FALSE(small_cut.done) << "a small piece iterates in a cut frame";
  const Stop small = decide(0.5, true, false);
  EXPECT_TRUE(small.done) << "a small piece stops outside cut frames";
  EXPECT_TRUE(small.recover) << "and asks for a recovery step";
}

// A cut rebuild on a base model equals a build from scratch: same pattern,
// masses and loads (the base only saves recomputation), from an uncut base
// and from a cut one.
TEST(Xfem, RebuildFromTheBaseModelEqualsAFreshBuild) {
  Scene s = test::block_scene(2);
  s.mass = MassKind::Consistent;
  s.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
  const Mesh mesh = make_beam(4, 1, 1, 8, 2, 2, 1);
  const Model uncut = build_model(mesh, s);
  const auto plane = make_cut_surface(test::plane_cut({2.3, 0, 0}, {1, 0.2, 0.1}), 0.0);
  const CutLayout layout = compute_cut_layout(uncut, {plane.get()}, nullptr);
  const Model fresh = build_model(mesh, s, &layout), rebuilt = build_model(mesh, s, &layout, &uncut);
  EXPECT_EQ(fresh.Ap, rebuilt.Ap);
  EXPECT_EQ(fresh.Ai, rebuilt.Ai);
  EXPECT_EQ(fresh.elem_scatter, rebuilt.elem_scatter);
  ASSERT_EQ(fresh.mass_csc.size(), rebuilt.mass_csc.size());
  for (size_t k = 0; k < fresh.mass_csc.size(); ++k) EXPECT_NEAR(fresh.mass_csc[k], rebuilt.mass_csc[k], 1e-14);
  for (int d = 0; d < fresh.ndof(); ++d) EXPECT_NEAR(fresh.f_gravity[d], rebuilt.f_gravity[d], 1e-13);
  EXPECT_TRUE(rebuilt.K0_csc.empty());  // corotated, exact policy: not needed
  // A second cut on top of the first: the base now has enriched columns and
  // elements (the pattern copies its mesh-node columns and unchanged elements).
  const auto plane2 = make_cut_surface(test::plane_cut({0, 0, 0.55}, {0.1, 0, 1}, "cuts[1]"), 0.0);
  const CutLayout layout2 = compute_cut_layout(uncut, {plane.get(), plane2.get()}, nullptr);
  ASSERT_GT(layout2.n_enriched, layout.n_enriched);
  const Model fresh2 = build_model(mesh, s, &layout2), rebuilt2 = build_model(mesh, s, &layout2, &rebuilt);
  EXPECT_EQ(fresh2.Ap, rebuilt2.Ap);
  EXPECT_EQ(fresh2.Ai, rebuilt2.Ai);
  EXPECT_EQ(fresh2.diag, rebuilt2.diag);
  EXPECT_EQ(fresh2.elem_scatter, rebuilt2.elem_scatter);
  EXPECT_EQ(fresh2.elem_scatter_ptr, rebuilt2.elem_scatter_ptr);
  // Elements whose pieces the new cut left alone copy their points, slots and
  // piece stiffness from the base: bit for bit what a fresh build integrates.
  for (const auto& [a, b] : {std::pair<const Model*, const Model*>{&fresh, &rebuilt}, {&fresh2, &rebuilt2}}) {
    EXPECT_EQ(a->elem_dof_ptr, b->elem_dof_ptr);
    EXPECT_EQ(a->elem_dof_node, b->elem_dof_node);
    EXPECT_EQ(a->elem_qp_ptr, b->elem_qp_ptr);
    EXPECT_EQ(a->qp_weight, b->qp_weight);
    EXPECT_EQ(a->qp_grad, b->qp_grad);
    EXPECT_EQ(a->qp_rot, b->qp_rot);
    EXPECT_EQ(a->rot_elem, b->rot_elem);
    EXPECT_EQ(a->rot_body, b->rot_body);
    EXPECT_EQ(a->rot_grad, b->rot_grad);
    EXPECT_EQ(a->rot_K0_ptr, b->rot_K0_ptr);
    EXPECT_EQ(a->rot_K0, b->rot_K0);
    EXPECT_EQ(a->elem_volume, b->elem_volume);
  }
  EXPECT_FALSE(rebuilt2.rot_K0.empty()) << "split elements carry their pieces' rest stiffness";
}

// A beam (4 x 1 x 1 m, 8 x 2 x 2 cells of tet10) uncut, and its layouts
// for a tilted plane at x = 2.3 (one) and for that and a plane near z =
// 0.55 (two): a rebuild on a base that already has enriched columns.
struct TwoCuts {
  Mesh mesh;
  Model uncut;
  CutLayout one, two;
};
TwoCuts two_cuts(const Scene& s) {
  TwoCuts c{make_beam(4, 1, 1, 8, 2, 2, 1), {}, {}, {}};
  c.uncut = build_model(c.mesh, s);
  const auto plane = make_cut_surface(test::plane_cut({2.3, 0, 0}, {1, 0.2, 0.1}), 0.0);
  const auto plane2 = make_cut_surface(test::plane_cut({0, 0, 0.55}, {0.1, 0, 1}, "cuts[1]"), 0.0);
  c.one = compute_cut_layout(c.uncut, {plane.get()}, nullptr);
  c.two = compute_cut_layout(c.uncut, {plane.get(), plane2.get()}, nullptr);
  return c;
}

// A rebuild that takes a spare model's storage (build_model's spare: the
// model the cut before last replaced) equals one without, whatever the
// spare's sizes (larger and smaller than the new model's), for either
// mass; a spare large enough lends its arrays' storage itself.
TEST(Xfem, ARebuildOnASpareModelsStorageEqualsOneWithout) {
  for (const MassKind mass : {MassKind::Lumped, MassKind::Consistent}) {
    Scene s = test::block_scene(2);
    s.mass = mass;
    s.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
    const TwoCuts c = two_cuts(s);
    const Mesh& mesh = c.mesh;
    const Model base = build_model(mesh, s, &c.one, &c.uncut);
    const Model plain = build_model(mesh, s, &c.two, &base);
    for (const Model* donor : {&plain, &c.uncut}) {  // as large as the new model, and smaller
      Model spare = *donor;
      spare.Ai.reserve(spare.Ai.size() + spare.Ai.size() / 4);
      const int* lent = spare.Ai.data();
      const bool fits = spare.Ai.capacity() >= plain.Ai.size();
      const Model m = build_model(mesh, s, &c.two, &base, &spare);
      const char* what = donor == &plain ? "a large spare" : "a small spare";
      EXPECT_EQ(m.Ap, plain.Ap) << what;
      EXPECT_EQ(m.Ai, plain.Ai) << what;
      EXPECT_EQ(m.diag, plain.diag) << what;
      EXPECT_EQ(m.elem_scatter, plain.elem_scatter) << what;
      EXPECT_EQ(m.elem_scatter_ptr, plain.elem_scatter_ptr) << what;
      EXPECT_EQ(m.mass_csc, plain.mass_csc) << what;
      EXPECT_EQ(m.mass_lumped, plain.mass_lumped) << what;
      EXPECT_EQ(m.mass_coupling, plain.mass_coupling) << what;
      EXPECT_EQ(m.elem_mass, plain.elem_mass) << what;
      EXPECT_EQ(m.f_gravity, plain.f_gravity) << what;
      EXPECT_EQ(m.elem_dof_ptr, plain.elem_dof_ptr) << what;
      EXPECT_EQ(m.elem_dof_node, plain.elem_dof_node) << what;
      EXPECT_EQ(m.elem_qp_ptr, plain.elem_qp_ptr) << what;
      EXPECT_EQ(m.qp_weight, plain.qp_weight) << what;
      EXPECT_EQ(m.qp_grad_ptr, plain.qp_grad_ptr) << what;
      EXPECT_EQ(m.qp_grad, plain.qp_grad) << what;
      EXPECT_EQ(m.qp_rot, plain.qp_rot) << what;
      EXPECT_EQ(m.rot_elem, plain.rot_elem) << what;
      EXPECT_EQ(m.rot_grad_ptr, plain.rot_grad_ptr) << what;
      EXPECT_EQ(m.rot_grad, plain.rot_grad) << what;
      EXPECT_EQ(m.rot_K0, plain.rot_K0) << what;
      EXPECT_EQ(m.constrained_entries, plain.constrained_entries) << what;
      EXPECT_TRUE(fits || donor != &plain);
      if (fits) {
        EXPECT_EQ(m.Ai.data(), lent) << what << ": the new pattern is in the spare's storage";
      }
      EXPECT_TRUE(spare.Ai.empty() && spare.qp_grad.empty()) << what << ": the spare gave its arrays up";
    }
  }
}

// A rebuild whose layout joins regions of the old one (a scalpel's bands are
// mapped through the tissue frame by frame, so the pieces are not nested):
// each joined DOF takes the lumped-mass-weighted mean of the old regions'
// values, which keeps every node's lumped momentum sum_R m_R v_R = (M v)_u
// (the regions' masses add up: the new layout is the old one less a plane).
// Old: a slab 2.3 < x < 2.4 cut free between two planes, its DOFs far off
// (a region that barely reaches its node has far-extrapolated nodal
// values); new: the plane at 2.3 only, the slab joined to the beam beyond.
// The last piece visited used to write each node: there, the slab's value.
TEST(Xfem, ARebuildThatJoinsRegionsKeepsEachNodesMomentum) {
  Scene s = test::block_scene(2);
  s.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
  const Mesh mesh = make_beam(4, 1, 1, 8, 2, 2, 1);
  const Model uncut = build_model(mesh, s);
  const auto at_23 = make_cut_surface(test::plane_cut({2.3, 0, 0}, {1, 0, 0}), 0.0);
  const auto at_24 = make_cut_surface(test::plane_cut({2.4, 0, 0}, {1, 0, 0}, "cuts[1]"), 0.0);
  const CutLayout slab_layout = compute_cut_layout(uncut, {at_23.get(), at_24.get()}, nullptr);
  const CutLayout joined_layout = compute_cut_layout(uncut, {at_23.get()}, nullptr);
  const Model from = build_model(mesh, s, &slab_layout, &uncut), to = build_model(mesh, s, &joined_layout, &uncut);
  // A smooth velocity (and u = v / 2, a = 3 v); the slab's DOFs at 0.5.
  const auto smooth = [](const double* X, int c) {
    return 1e-3 * (c == 0 ? X[0] * X[2] : c == 1 ? X[1] - X[0] : -X[0] * X[0]);
  };
  State os;
  size_state(from, os);
  for (int i = 0; i < from.nnode; ++i)
    for (int c = 0; c < 3; ++c) os.v[3 * i + c] = smooth(&from.X[3 * i], c);
  int slab_dofs = 0;
  for (double y = 0.05; y < 1.0; y += 0.1)
    for (double z = 0.05; z < 1.0; z += 0.1) {
      const double p[3] = {2.35, y, z};
      const ProbeHit h = locate_point(from, p);
      ASSERT_GE(h.piece, 0);
      for (int a = 0; a < from.mesh.npe(); ++a) {
        const int q = from.cuts.piece_enr[static_cast<size_t>(h.piece) * from.mesh.npe() + a];
        ASSERT_GE(q, 0) << "the slab is no node's home region";
        const int i = from.cuts.enr_node[q - from.nnode];
        for (int c = 0; c < 3; ++c) os.v[3 * q + c] = 0.5 - smooth(&from.X[3 * i], c);
        ++slab_dofs;
      }
    }
  ASSERT_GT(slab_dofs, 0);
  os.u = os.v;
  for (double& x : os.u) x *= 0.5;
  os.a = os.v;
  for (double& x : os.a) x *= 3.0;
  const Kinematics k = transfer_kinematics(from, os, to);
  ASSERT_EQ(k.v.size(), static_cast<size_t>(to.ndof()));
  std::vector<double> p_old(from.ndof()), p_new(to.ndof());
  mass_matvec(from, os.v.data(), p_old.data());
  mass_matvec(to, k.v.data(), p_new.data());
  double pmax = 0.0;
  for (int d = 0; d < 3 * to.nnode; ++d) pmax = std::max(pmax, std::abs(p_old[d]));
  int joined = 0;
  for (int d = 0; d < 3 * to.nnode; ++d) {
    EXPECT_NEAR(p_new[d], p_old[d], 1e-12 * pmax) << "node " << d / 3 << " component " << d % 3;
    joined += std::abs(k.v[d] - smooth(&to.X[3 * (d / 3)], d % 3)) > 1e-6;
  }
  for (int d = 0; d < to.ndof(); ++d) {
    EXPECT_NEAR(k.u[d], 0.5 * k.v[d], 1e-15);
    EXPECT_NEAR(k.a[d], 3.0 * k.v[d], 1e-14);
  }
  EXPECT_GT(joined, 0) << "no node's home region took the slab in: the test tests nothing";
}

// With lumped mass a rebuild copies the mesh nodes' masses, flags and
// constrained entries from its base and visits only the enriched elements
// and columns: bit for bit what a fresh build computes, through two cuts.
TEST(Xfem, LumpedRebuildCopiesMassesAndConstraintsExactly) {
  Scene s = test::block_scene(2);
  s.mass = MassKind::Lumped;
  s.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
  Prescribed p;
  p.region = test::box({3.9, -1, -1}, {5, 2, 2}, "prescribed[0]");
  p.active = {false, true, false};
  p.displacement = {0, 0.1, 0};
  s.prescribed.push_back(p);
  const TwoCuts c = two_cuts(s);
  const Mesh& mesh = c.mesh;
  const Model rebuilt = build_model(mesh, s, &c.one, &c.uncut);
  for (const auto& [lay, base] : {std::pair<const CutLayout*, const Model*>{&c.one, &c.uncut}, {&c.two, &rebuilt}}) {
    const Model fresh = build_model(mesh, s, lay), next = build_model(mesh, s, lay, base);
    ASSERT_GT(fresh.ndofnode, fresh.nnode);
    EXPECT_EQ(fresh.mass_lumped, next.mass_lumped);
    EXPECT_EQ(fresh.mass_csc, next.mass_csc);
    EXPECT_EQ(fresh.f_gravity, next.f_gravity);
    EXPECT_EQ(fresh.constrained, next.constrained);
    EXPECT_EQ(fresh.fixed_dofs, next.fixed_dofs);
    EXPECT_EQ(fresh.constrained_entries, next.constrained_entries);
    ASSERT_EQ(fresh.prescribed.size(), next.prescribed.size());
    EXPECT_GT(next.prescribed.size(), 0u);
    for (size_t k = 0; k < fresh.prescribed.size(); ++k) EXPECT_EQ(fresh.prescribed[k].dof, next.prescribed[k].dof);
    // The mesh nodes' u DOFs carry the whole body (M g summed over them is
    // the uncut body's weight); the q DOFs the pieces away from each node's
    // home, a part of it.
    double weight = 0, weight_q = 0, weight_uncut = 0;
    for (int d = 2; d < 3 * next.nnode; d += 3) weight += next.f_gravity[d];
    for (int d = 3 * next.nnode + 2; d < next.ndof(); d += 3) weight_q += next.f_gravity[d];
    for (int d = 2; d < c.uncut.ndof(); d += 3) weight_uncut += c.uncut.f_gravity[d];
    EXPECT_NEAR(weight, weight_uncut, 1e-13 * std::abs(weight_uncut));
    EXPECT_LT(weight_q, 0.0);
    EXPECT_GT(weight_q, weight_uncut);
  }
}

TEST(Xfem, ConsistentTangentOfACutModelParallelEqualsSerialAndStepsStably) {
  // A slanted plane cut through a tet10 block under integrator.tangent
  // "consistent": uncut points get the point rotation term, cut pieces (one
  // rotation per piece) the slot form, enriched elements the generic path.
  // The fused parallel assembly must equal the serial reference, and 60
  // swinging frames must stay finite with one Newton iteration each.
  Scene s = test::block_scene(2);
  s.consistent_tangent = true;
  s.material.rayleigh_stiffness = 0.002;
  s.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
  s.cuts = {test::plane_cut({2.1, 0, 0}, {1, 0.3, 0.2})};
  auto sim = test::make_sim(make_beam(4, 1, 1, 8, 2, 2, 1), s);
  ASSERT_TRUE(update_cuts(*sim, 0, 0).changed);
  const Model& m = sim->model;
  const std::vector<double> W = shared_slot_weights(m);
  EXPECT_GT(*std::max_element(W.begin(), W.end()), 0.0) << "cut pieces share a rotation";
  std::vector<double> u(m.ndof(), 0.0);
  for (int n = 0; n < m.ndofnode; ++n) {  // a bend of the standard and enriched DOFs alike
    const double x = m.X[3 * n] + (n >= m.nnode ? 2.5 : 0.0);
    u[3 * n] = -0.05 * x * x;
    u[3 * n + 2] = 0.2 * x * x;
  }
  std::vector<double> Rs = identity_rotations(m.nrot), f0(m.ndof()), K0(m.nnz());
  std::vector<double> R = Rs, f(m.ndof()), K(m.nnz());
  update_rotations(m, u.data(), Rs.data());
  assemble_internal(m, u.data(), Rs.data(), f0.data(), K0.data());
  ThreadPool pool(2);
  AssemblyPlan plan = make_assembly_plan(m, 2);
  assemble_corotated(m, plan, pool, u.data(), R.data(), f.data(), K.data());
  double kn = 0, dk = 0;
  for (int k = 0; k < m.nnz(); ++k) {
    kn = std::max(kn, std::abs(K0[k]));
    dk = std::max(dk, std::abs(K[k] - K0[k]));
  }
  EXPECT_LT(dk, 1e-13 * kn);
  for (int k = 0; k < 60; ++k) {
    step(sim->model, sim->state, sim->ws);
    ASSERT_EQ(sim->ws.newton_iterations_done, 1) << "frame " << k;
  }
  for (double x : sim->state.u) ASSERT_TRUE(std::isfinite(x));
}

// The parallel assembly (condensed pieces' rest stiffness, 1 and 2
// workers) against the serial point-by-point reference assemble_internal,
// under a bend and twist of every DOF (the enriched and branch DOFs get
// their own): forces and tangent to `tol` relative, the matrix-free product
// (the frozen-R tangent when !consistent), and the product fused into the
// assembly's pass (the step's damping force). count(plan) must exceed 4:
// the elements the test is about are condensed.
void expect_assembly_matches_point_by_point(const Model& m, bool consistent, double tol,
                                            const std::function<int(const AssemblyPlan&)>& count,
                                            const std::string& what) {
  std::vector<double> u(m.ndof(), 0.0);
  for (int n = 0; n < m.ndofnode; ++n) {
    const double x = m.X[3 * n] + (n >= m.nnode ? 2.5 : 0.0), y = m.X[3 * n + 1];
    u[3 * n] = -0.05 * x * x + 0.02 * y;
    u[3 * n + 1] = 0.1 * x * y;
    u[3 * n + 2] = 0.2 * x * x - 0.001 * (n % 7);
  }
  std::vector<double> Rs = identity_rotations(m.nrot), f0(m.ndof()), K0(m.nnz());
  const std::vector<double> I = Rs;
  update_rotations(m, u.data(), Rs.data());
  assemble_internal(m, u.data(), Rs.data(), f0.data(), K0.data());
  double fn = 0, kn = 0;
  for (double v : f0) fn = std::max(fn, std::abs(v));
  for (double v : K0) kn = std::max(kn, std::abs(v));
  for (int threads : {1, 2}) {
    ThreadPool pool(threads);
    AssemblyPlan plan = make_assembly_plan(m, threads);
    EXPECT_GT(count(plan), 4) << what;
    std::vector<double> R = I, f(m.ndof()), K(m.nnz());
    assemble_corotated(m, plan, pool, u.data(), R.data(), f.data(), K.data());
    double df = 0, dk = 0;
    for (int d = 0; d < m.ndof(); ++d) df = std::max(df, std::abs(f[d] - f0[d]));
    for (int k = 0; k < m.nnz(); ++k) dk = std::max(dk, std::abs(K[k] - K0[k]));
    EXPECT_LT(df, tol * fn) << what;
    EXPECT_LT(dk, tol * kn) << what;
    std::vector<double> v(m.ndof()), y1(m.ndof()), y2(m.ndof());
    for (int d = 0; d < m.ndof(); ++d) v[d] = std::cos(0.3 * d);
    sym_matvec(m, K0.data(), v.data(), y1.data());
    stiffness_matvec(m, plan, pool, R.data(), v.data(), y2.data());
    if (!consistent) {
      EXPECT_LT(test::rel_diff(y2, y1), tol) << what;
    }
    std::vector<double> Rv = I, fv(m.ndof()), Kv(m.ndof(), 1.0);
    assemble_corotated(m, plan, pool, u.data(), Rv.data(), fv.data(), nullptr, nullptr, v.data(), Kv.data());
    EXPECT_LT(test::rel_diff(Kv, y2), 0.1 * tol) << what;
  }
}

// Split elements assemble from their pieces' rest stiffness (Model::rot_K0:
// R^ K0 (R^T x - X) and R^ K0 R^T per piece) instead of integrating their
// sub-element points. That must equal the serial point-by-point reference
// (assemble_internal): forces, the tangent with either tangent choice, and
// the matrix-free product, for tet4, tet10 and tet10SR, 1 and 2 workers.
TEST(Xfem, SplitElementsAssembleFromTheirPiecesRestStiffness) {
  for (int order : {1, 2})
    for (RotationMode rot : {RotationMode::PerPoint, RotationMode::Single})
      for (bool consistent : {false, true}) {
        if (order == 1 && rot == RotationMode::Single) continue;
        Scene s = test::block_scene(order);
        s.material.rotation = rot;
        s.consistent_tangent = consistent;
        s.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
        s.cuts = {test::plane_cut({2.1, 0, 0}, {1, 0.3, 0.2}), test::plane_cut({0, 0.45, 0}, {0.1, 1, 0.2}, "cuts[1]")};
        auto sim = test::make_sim(make_beam(4, 1, 1, 8, 2, 2, 1), s);
        ASSERT_TRUE(update_cuts(*sim, 0, 0).changed);
        const Model& m = sim->model;
        expect_assembly_matches_point_by_point(
            m, consistent, 1e-13,
            [&](const AssemblyPlan& plan) {
              const int condensed = static_cast<int>(std::count(plan.elem_condensed.begin(), plan.elem_condensed.end(), 1));
              EXPECT_LT(condensed, m.nelem);
              return condensed;
            },
            "order " + std::to_string(order) + " consistent " + std::to_string(consistent));
      }
}

// The pieces of elements with branch DOF nodes (cut_front "enriched": the
// front elements, and the split elements of the ring around them) assemble
// from a rest stiffness over all their DOF nodes, not point by point at 27
// points a sub-tetrahedron; forces, tangent (either choice) and the
// matrix-free product must equal the serial point-by-point reference.
TEST(Xfem, BranchElementsAssembleFromTheirPiecesRestStiffness) {
  for (bool consistent : {false, true}) {
    Scene s = test::block_scene(2);
    s.consistent_tangent = consistent;
    s.front_enrichment = true;
    s.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
    CutSpec slit;  // x = 2.05 from the top down to z = 0.45, inside an element layer
    slit.type = CutSpec::Type::Polygon;
    slit.points = {{2.05, -1, 0.45}, {2.05, 2, 0.45}, {2.05, 2, 3}, {2.05, -1, 3}};
    slit.json_path = "cuts[0]";
    s.cuts = {slit};
    auto sim = test::make_sim(make_beam(4, 1, 1, 7, 3, 3, 1), s);
    ASSERT_TRUE(update_cuts(*sim, 0, 0).changed);
    const Model& m = sim->model;
    ASSERT_TRUE(m.cuts.has_branch());
    expect_assembly_matches_point_by_point(
        m, consistent, 1e-12,
        [&](const AssemblyPlan& plan) {  // the front's elements and the split ring
          int n = 0;
          for (int e = 0; e < m.nelem; ++e) n += plan.elem_condensed[e] && element_has_branch(m, e);
          return n;
        },
        "branch elements, consistent " + std::to_string(consistent));
  }
}

// A cut rebuild that severs nothing recomputes the consistent acceleration
// only near the elements whose pieces changed (consistent_acceleration_near):
// on their DOF nodes it must equal the global M^-1 (f_ext - f_int - D v), and
// every other DOF must keep the acceleration transferred from the old model.
// (One that severs a piece takes the global one:
// HardCases.AStiffBeamsSeveredEndFallsWithoutAKickAlongTheBeam.)
TEST(Xfem, CutFrameAccelerationIsRecomputedNearTheChangedElementsOnly) {
  Scene s = test::block_scene(2);
  s.material.rayleigh_mass = 0.5;
  s.material.rayleigh_stiffness = 0.002;
  s.fixed.push_back(test::box({-1, -1, -1}, {0, 2, 2}));
  s.cuts = {test::swept_blade({Vec3{2.3, -0.5, 1.2}, Vec3{2.3, 1.5, 1.2}}, {Vec3{2.3, -0.5, -0.2}, Vec3{2.3, 1.5, -0.2}})};
  auto sim = test::make_sim(make_beam(4, 1, 1, 8, 2, 2, 1), s);
  ASSERT_TRUE(update_cuts(*sim, 0.0, 0.35).changed);  // the blade a third of the way down
  for (int k = 0; k < 8; ++k) step(sim->model, sim->state, sim->ws);  // the beam swings under gravity
  const Model before = sim->model;
  const Kinematics moved = transfer_kinematics(before, sim->state, before);
  ASSERT_TRUE(update_cuts(*sim, 0.0, 0.75).changed);  // deeper: new split elements
  const Model& m = sim->model;
  const std::vector<double> near = sim->state.a;
  State moved_state;
  moved_state.u = moved.u;
  moved_state.v = moved.v;
  moved_state.a = moved.a;
  moved_state.du = moved.u;  // the last increment is carried by the same map as u
  const Kinematics carried = transfer_kinematics(before, moved_state, m);
  EXPECT_TRUE(carried.du == carried.u);
  EXPECT_EQ(sim->state.du.size(), static_cast<size_t>(m.ndof())) << "the cut kept the state's last increment";
  consistent_acceleration(m, sim->state, sim->ws);
  const std::vector<double> global = sim->state.a;
  double amax = 0;
  for (double x : global) amax = std::max(amax, std::abs(x));
  ASSERT_GT(amax, 0.0);
  std::vector<char> on_changed(m.ndofnode, 0);
  int changed = 0;
  for (int e = 0; e < m.nelem; ++e)
    if (!same_element_pieces(m, before, e)) {
      ++changed;
      for (int k = m.elem_dof_ptr[e]; k < m.elem_dof_ptr[e + 1]; ++k) on_changed[m.elem_dof_node[k]] = 1;
    }
  // The lumped (u, q) blocks couple a mesh node to all its enriched nodes:
  // where a_u is recomputed, so is every a_q of that node.
  for (int q = m.nnode; q < m.ndofnode; ++q)
    if (on_changed[m.cuts.enr_node[q - m.nnode]] == 1) on_changed[q] |= 2;
  EXPECT_GT(changed, 0);
  EXPECT_LT(changed, m.nelem / 4) << "a deeper blade changes a few elements, not the beam";
  int recomputed = 0, kept = 0;
  for (int d = 0; d < m.ndof(); ++d) {
    const bool same_as_global = std::abs(near[d] - global[d]) <= 1e-9 * amax;
    if (on_changed[d / 3]) {
      EXPECT_TRUE(same_as_global) << "DOF " << d << ": " << near[d] << " vs " << global[d];
    }
    if (near[d] == carried.a[d] && !same_as_global) ++kept;
    else if (same_as_global) ++recomputed;
    else ADD_FAILURE() << "DOF " << d << " is neither the global nor the carried acceleration";
  }
  EXPECT_GT(kept, m.ndof() / 2) << "far from the cut the acceleration is left alone";
  EXPECT_GT(recomputed, 0);
}

}  // namespace
}  // namespace incise
