// The renderer's frame loop: what is rebuilt when, the camera framing, the
// background, instruments, and PNG round trips.
#include "render/renderer.h"

#include <filesystem>

#include <gtest/gtest.h>

#include <cmath>

#include "render/camera.h"
#include "render_test_util.h"

namespace incise::test {
namespace {

TEST(Renderer, TopologyIsRebuiltOnlyWhenTheCellStructureChanges) {
  auto r = make_test_renderer(test_settings());
  ASSERT_TRUE(r);
  DisplayMesh d = display_of(make_beam(2, 1, 1, 4, 2, 2, 2));
  r->update(d);
  const Image first = r->render();
  for (int k = 0; k < 3; ++k) {
    for (size_t i = 2; i < d.u.size(); i += 3) d.u[i] -= 0.02 * d.X[i - 2];  // sag
    r->update(d);
  }
  EXPECT_EQ(r->stats().topology_builds, 1);
  EXPECT_EQ(r->stats().position_uploads, 4);
  EXPECT_EQ(r->stats().ncut, 0);
  EXPECT_NE(r->render().rgb, first.rgb) << "new positions must show";
  r->update(split_block(d, 1.0, 0.2));  // a cut: new cells and points
  EXPECT_EQ(r->stats().topology_builds, 2);
  EXPECT_GT(r->stats().ncut, 0);
  r->update(split_block(d, 1.0, 0.3));  // the gap opens further: same structure
  EXPECT_EQ(r->stats().topology_builds, 2);
}

TEST(Renderer, EmptySceneIsTheBackgroundColour) {
  RenderSettings s = test_settings(64, 48);
  auto r = make_test_renderer(s);
  ASSERT_TRUE(r);
  const Image img = r->render();
  ASSERT_EQ(img.width, 64);
  ASSERT_EQ(img.height, 48);
  for (int y = 0; y < img.height; ++y)
    for (int x = 0; x < img.width; ++x)
      for (int c = 0; c < 3; ++c) ASSERT_NEAR(img.at(x, y)[c], 255.0 * s.color_background[c], 1.0);
}

TEST(Renderer, InstrumentsAreDrawnFromShapeAndPose) {
  RenderSettings s = test_settings(120, 120);
  s.camera_position = Vec3{0, -10, 0};
  s.camera_target = Vec3{0, 0, 0};
  auto r = make_test_renderer(s);
  ASSERT_TRUE(r);
  r->set_camera(frame_camera(s, {-1, -1, -1}, {1, 1, 1}));
  InstrumentShape box;
  box.kind = InstrumentShape::Kind::Box;
  box.half_extents = {0.3, 0.3, 0.3};
  box.pose[12] = -1.0;  // translated to x = -1 (left of the image centre)
  InstrumentShape capsule;
  capsule.kind = InstrumentShape::Kind::Capsule;
  capsule.radius = 0.2;
  capsule.length = 1.0;
  capsule.color = Vec3{0.9, 0.1, 0.1};
  capsule.pose = {0, 0, 1, 0, 0, 1, 0, 0, -1, 0, 0, 0, 1.0, 0, 0, 1};  // axis along x, at x = +1
  r->set_instruments({box, capsule});
  const Image img = r->render();
  // Image x grows with world x (camera on -y looking +y, z up).
  const int cy = img.height / 2;
  const unsigned char* left = img.at(img.width / 2 - 25, cy);
  const unsigned char* right = img.at(img.width / 2 + 25, cy);
  EXPECT_GT(left[0], 100);  // yellow: red and green high, blue low
  EXPECT_GT(left[1], 100);
  EXPECT_LT(left[2], 80);
  EXPECT_EQ(dominant(img, img.width / 2 + 25, cy), 0) << int(right[0]) << " " << int(right[1]) << " " << int(right[2]);
  EXPECT_EQ(dominant(img, img.width / 2, cy), 2) << "background between the two";
  r->set_instruments({});
  EXPECT_EQ(dominant(r->render(), img.width / 2 - 25, cy), 2) << "instruments removed";
}

TEST(Renderer, TwoRenderersShareTheDisplayAndOutliveEachOther) {
  RenderSettings s = test_settings(32, 24);
  auto a = make_test_renderer(s);
  ASSERT_TRUE(a);
  s.color_background = {0.9, 0.1, 0.1};
  auto b = make_test_renderer(s);
  ASSERT_TRUE(b);
  EXPECT_EQ(dominant(a->render(), 5, 5), 2);
  EXPECT_EQ(dominant(b->render(), 5, 5), 0);
  a.reset();  // must not end b's display
  EXPECT_EQ(dominant(b->render(), 5, 5), 0);
}

TEST(Camera, AutoFramingKeepsTheBoxInView) {
  for (auto [w, h] : {std::pair{640, 480}, std::pair{200, 600}, std::pair{1280, 400}}) {
    RenderSettings s;
    s.width = w, s.height = h;
    const Vec3 lo{-1, 2, 0}, hi{9, 4, 1};
    const Camera c = frame_camera(s, lo, hi);
    const auto m = view_projection(c, double(w) / h);
    for (int k = 0; k < 8; ++k) {
      const double p[3] = {k & 1 ? hi[0] : lo[0], k & 2 ? hi[1] : lo[1], k & 4 ? hi[2] : lo[2]};
      double clip[4];
      for (int i = 0; i < 4; ++i) clip[i] = m[i] * p[0] + m[4 + i] * p[1] + m[8 + i] * p[2] + m[12 + i];
      ASSERT_GT(clip[3], 0);
      for (int i = 0; i < 3; ++i) EXPECT_LE(std::fabs(clip[i] / clip[3]), 1.0) << w << "x" << h << " corner " << k;
    }
  }
}

TEST(Png, RoundTripAndErrorsNameTheFile) {
  Image img;
  img.width = 7, img.height = 3;
  for (int i = 0; i < 63; ++i) img.rgb.push_back(static_cast<unsigned char>(i * 4));
  const std::string path = output_dir() + "/roundtrip.png";
  write_png(img, path);
  const Image back = read_png(path);
  EXPECT_EQ(back.width, 7);
  EXPECT_EQ(back.height, 3);
  EXPECT_EQ(back.rgb, img.rgb);
  try {
    read_png(source_path("README.md"));
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("README.md: not a readable PNG"), std::string::npos) << e.what();
  }
  // A folder as the path: an error naming it, no temporary file beside it (issue 24).
  const std::filesystem::path folder = output_dir() + "/png_folder";
  std::filesystem::create_directories(folder);
  try {
    write_png(img, folder.string());
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), folder.string() + ": cannot write: it is a directory");
  }
  for (const auto& f : std::filesystem::directory_iterator(output_dir()))
    EXPECT_EQ(f.path().filename().string().find("png_folder.tmp"), std::string::npos) << f.path();
}

}  // namespace
}  // namespace incise::test
