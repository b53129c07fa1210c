// Golden images on Mesa llvmpipe (tolerance: share of pixels differing by more
// than a threshold), plus numeric checks of what the pictures must show.
// Regenerate after an intended change: INCISE_UPDATE_GOLDEN=1 ctest -R Golden
#include <gtest/gtest.h>

#include <cmath>

#include "cutting/cut_stage.h"
#include "engine/dynamics/step.h"
#include "engine/output/display_mesh.h"
#include "render/camera.h"
#include "tools/frame_loop.h"
#include "render_test_util.h"

namespace incise::test {
namespace {

// Pixel of world point p, or {-1, -1} behind the camera.
std::array<int, 2> project(const Camera& c, const Image& img, const Vec3& p) {
  const auto m = view_projection(c, double(img.width) / img.height);
  double clip[4];
  for (int i = 0; i < 4; ++i) clip[i] = m[i] * p[0] + m[4 + i] * p[1] + m[8 + i] * p[2] + m[12 + i];
  if (clip[3] <= 0) return {-1, -1};
  return {static_cast<int>((clip[0] / clip[3] + 1) * 0.5 * img.width),
          static_cast<int>((1 - clip[1] / clip[3]) * 0.5 * img.height)};
}

bool is_background(const Image& img, int x, int y, const Vec3& bg) {
  const unsigned char* p = img.at(x, y);
  for (int c = 0; c < 3; ++c)
    if (std::abs(p[c] - 255.0 * bg[c]) > 8) return false;
  return true;
}

// Silhouette radius along 180 rays from the centroid of the non-background
// pixels: (max - min) / mean.
double silhouette_spread(const Image& img, const Vec3& bg) {
  double cx = 0, cy = 0;
  int n = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      if (!is_background(img, x, y, bg)) cx += x, cy += y, ++n;
  if (n == 0) return 1e9;
  cx /= n, cy /= n;
  double rmin = 1e9, rmax = 0, rsum = 0;
  for (int k = 0; k < 180; ++k) {
    const double a = 2 * M_PI * k / 180;
    double r = 0;
    for (double t = 0; t < img.width; t += 0.25) {
      const int x = static_cast<int>(std::lround(cx + t * std::cos(a))), y = static_cast<int>(std::lround(cy + t * std::sin(a)));
      if (x < 0 || y < 0 || x >= img.width || y >= img.height || is_background(img, x, y, bg)) break;
      r = t;
    }
    rmin = std::min(rmin, r), rmax = std::max(rmax, r), rsum += r;
  }
  return (rmax - rmin) / (rsum / 180);
}

Mesh corners_only(const Mesh& m10) {
  Mesh m4;
  m4.order = 1;
  m4.X = m10.X;
  for (int e = 0; e < m10.ntet(); ++e)
    for (int k = 0; k < 4; ++k) m4.tet.push_back(m10.tet[10 * e + k]);
  return m4;
}

TEST(Golden, UncutBlock) {
  RenderSettings s;
  s.width = 160, s.height = 120;
  auto r = make_test_renderer(s);
  ASSERT_TRUE(r);
  r->update(display_of(make_beam(2, 1, 1, 4, 2, 2, 2)));
  const Image img = r->render();
  EXPECT_EQ(r->stats().ncut, 0);
  expect_matches_golden(img, "block");
}

TEST(Golden, Tet10SphereIsRound) {
  const Mesh sphere = read_mesh(source_path("assets/meshes/sphere_tet10.msh"));
  RenderSettings s;
  s.width = 160, s.height = 120;
  {
    auto r = make_test_renderer(s);
    ASSERT_TRUE(r);
    r->update(display_of(sphere));
    expect_matches_golden(r->render(), "sphere");
  }
  // Roundness at a finer resolution: the camera looks at the centre, so the
  // silhouette of a true sphere is a circle. Flat faces of the same mesh
  // (its corner nodes only) show their polygon.
  s.width = s.height = 400;
  auto r = make_test_renderer(s);
  ASSERT_TRUE(r);
  r->update(display_of(sphere));
  const double spread10 = silhouette_spread(r->render(), s.color_background);
  r->update(display_of(corners_only(sphere)));
  const double spread4 = silhouette_spread(r->render(), s.color_background);
  std::printf("silhouette radius spread: tet10 %.4f, tet4 %.4f\n", spread10, spread4);
  EXPECT_LT(spread10, 0.03);
  EXPECT_LT(spread10, 0.5 * spread4) << "curved faces must be rounder than flat ones";
}

// A real X-FEM cut: the block [0,2]x[0,1]x[0,1] is cut by the plane x = 1.1
// (inside elements), the left end is held and a body force along +x pulls the
// right piece 0.25 away in 10 frames. Before the cut no interior face shows.
TEST(Golden, CutBlockGapIsVisible) {
  RenderSettings s = test_settings();
  const double cut_x = 1.1, gap = 0.25, mid = cut_x + 0.5 * gap;
  s.camera_position = Vec3{mid + 0.6, -2.5, 2.5};  // right of the gap: sees the left half's cut face
  s.camera_target = Vec3{mid, 0.5, 0.4};
  auto r = make_test_renderer(s);
  ASSERT_TRUE(r);
  Scene sc;
  sc.path = "golden-cut";
  sc.order = 2;
  sc.material.young = 1e7;
  sc.material.poisson = 0.3;
  sc.material.density = 1.0;
  const double frames = 10, t = frames / 30.0;
  sc.gravity = {2.0 * gap / (t * t), 0, 0};  // 1/2 g t^2 = gap
  Region held;
  held.kind = Region::Kind::Box;
  held.lo = {-1, -1, -1};
  held.hi = {0, 2, 2};
  held.json_path = "fixed[0]";
  sc.fixed = {held};
  CutSpec plane;
  plane.type = CutSpec::Type::Plane;
  plane.point = {cut_x, 0, 0};
  plane.normal = {1, 0, 0};
  plane.at_time = 1e-9;  // after the first frame has been rendered uncut
  plane.json_path = "cuts[0]";
  sc.cuts = {plane};
  Simulation sim;
  sim.scene = sc;
  sim.mesh = make_beam(2, 1, 1, 4, 2, 2, 1);
  sim.model = build_model(sim.mesh, sc);
  sim.state.cut_progress.assign(1, -1.0);
  init_state(sim.model, sim.state, sim.ws);
  install_cutting_stage(sim);
  r->update(display_mesh(sim.model, sim.state));
  const Image before = r->render();
  EXPECT_EQ(r->stats().ncut, 0);
  int interior_before = 0;
  for (int y = 0; y < before.height; ++y)
    for (int x = 0; x < before.width; ++x) interior_before += dominant(before, x, y) == 0;
  EXPECT_EQ(interior_before, 0) << "no inner face before the cut";
  for (int k = 0; k < frames; ++k) advance_frame(sim);
  r->update(display_mesh(sim.model, sim.state));
  const Image img = r->render();
  ASSERT_GT(r->stats().ncut, 0);
  expect_matches_golden(img, "cut_block");
  // Along the middle of the gap, on the top (z = 1) and front (y = 0) sides,
  // no pixel shows tissue: only background or the interior colour.
  int checked = 0;
  for (double t2 = 0.1; t2 <= 0.9; t2 += 0.05)
    for (const Vec3& p : {Vec3{mid, t2, 1.0}, Vec3{mid, 0.0, t2}}) {
      const auto px = project(r->camera(), img, p);
      ASSERT_TRUE(px[0] >= 0 && px[0] < img.width && px[1] >= 0 && px[1] < img.height);
      EXPECT_NE(dominant(img, px[0], px[1]), 1) << "tissue colour in the gap at pixel " << px[0] << ", " << px[1];
      ++checked;
    }
  EXPECT_GT(checked, 20);
  int interior = 0, tissue = 0;
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x) interior += dominant(img, x, y) == 0, tissue += dominant(img, x, y) == 1;
  EXPECT_GT(interior, 100) << "the cut face must show in the interior colour";
  EXPECT_GT(tissue, 1000);
}

}  // namespace
}  // namespace incise::test
