#pragma once
// Shared helpers for the render tests: display meshes built in code
// (display_fixtures.h: an uncut body, and a block cut by hand into two halves
// with a gap until X-FEM cutting produces the real thing), a renderer that fails loudly when
// EGL is missing, and golden-image comparison.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <memory>
#include <string>

#include "tests/engine/output/display_fixtures.h"
#include "engine/output/display_mesh.h"
#include "engine/util/error.h"
#include "engine/mesh/mesh_io.h"
#include "engine/mesh/mesh_tools.h"
#include "engine/model/model.h"
#include "engine/dynamics/state.h"
#include "render/image.h"
#include "render/renderer.h"

namespace incise::test {

inline std::string source_path(const std::string& rel) { return std::string(INCISE_SOURCE_DIR) + "/" + rel; }

// A renderer for the tests; EGL must work here (CI is this kind of machine:
// Mesa's surfaceless platform on llvmpipe), so a failure is a test failure.
inline std::unique_ptr<Renderer> make_test_renderer(const RenderSettings& s) {
  try {
    return std::make_unique<Renderer>(s);
  } catch (const Error& e) {
    ADD_FAILURE() << "EGL could not initialise, so nothing can be rendered: " << e.what()
                  << "\nThe render tests need Mesa's surfaceless EGL (libegl-mesa0, libgl1-mesa-dri) or a GPU.";
    return nullptr;
  }
}

// Colours far apart in hue so tests can classify pixels by dominant channel.
inline RenderSettings test_settings(int w = 160, int h = 120) {
  RenderSettings r;
  r.width = w;
  r.height = h;
  r.color_tissue = {0.35, 0.85, 0.35};     // green
  r.color_interior = {0.90, 0.15, 0.15};   // red
  r.color_background = {0.15, 0.20, 0.70}; // blue
  r.color_instrument = {0.80, 0.80, 0.20}; // yellow
  return r;
}

// 0 red, 1 green, 2 blue: the dominant channel of pixel (x, y).
inline int dominant(const Image& img, int x, int y) {
  const unsigned char* p = img.at(x, y);
  return p[0] >= p[1] && p[0] >= p[2] ? 0 : (p[1] >= p[2] ? 1 : 2);
}

inline std::string output_dir() {
  std::filesystem::create_directories(INCISE_TEST_OUTPUT_DIR);
  return INCISE_TEST_OUTPUT_DIR;
}

// Compares with assets/golden/NAME.png: fails when more than max_fraction of
// the pixels differ by more than threshold (0-255) in any channel, writing
// NAME.actual.png and NAME.diff.png (differing pixels red) into the test output
// folder. INCISE_UPDATE_GOLDEN=1 rewrites the golden instead.
inline void expect_matches_golden(const Image& img, const std::string& name, int threshold = 40,
                                  double max_fraction = 0.01) {
  const std::string golden = source_path("assets/golden/" + name + ".png");
  const char* update = std::getenv("INCISE_UPDATE_GOLDEN");
  if (update && std::string(update) == "1") {
    std::filesystem::create_directories(source_path("assets/golden"));
    write_png(img, golden);
    std::printf("updated golden %s\n", golden.c_str());
    return;
  }
  const std::string actual = output_dir() + "/" + name + ".actual.png";
  if (!std::filesystem::exists(golden)) {
    write_png(img, actual);
    ADD_FAILURE() << "no golden image " << golden << " (this render is in " << actual
                  << "); run the test with INCISE_UPDATE_GOLDEN=1 to create it";
    return;
  }
  const Image ref = read_png(golden);
  if (ref.width != img.width || ref.height != img.height) {
    write_png(img, actual);
    ADD_FAILURE() << name << ": size " << img.width << "x" << img.height << " differs from the golden's " << ref.width
                  << "x" << ref.height << " (" << golden << ")";
    return;
  }
  Image diff = img;
  int differing = 0, worst = 0;
  for (size_t i = 0; i < img.rgb.size(); i += 3) {
    int d = 0;
    for (int c = 0; c < 3; ++c) d = std::max(d, std::abs(int(img.rgb[i + c]) - int(ref.rgb[i + c])));
    worst = std::max(worst, d);
    const bool bad = d > threshold;
    differing += bad;
    const unsigned char grey = static_cast<unsigned char>((img.rgb[i] + img.rgb[i + 1] + img.rgb[i + 2]) / 6);
    diff.rgb[i] = bad ? 255 : grey;
    diff.rgb[i + 1] = bad ? 0 : grey;
    diff.rgb[i + 2] = bad ? 0 : grey;
  }
  const double fraction = static_cast<double>(differing) / (img.width * img.height);
  if (fraction > max_fraction) {
    const std::string diff_path = output_dir() + "/" + name + ".diff.png";
    write_png(img, actual);
    write_png(diff, diff_path);
    ADD_FAILURE() << name << ": " << 100.0 * fraction << "% of pixels differ by more than " << threshold
                  << " (allowed " << 100.0 * max_fraction << "%, worst difference " << worst << ") from " << golden
                  << "\n  actual: " << actual << "\n  diff:   " << diff_path
                  << "\n  if the change is intended: INCISE_UPDATE_GOLDEN=1 ctest --test-dir build -R Golden";
  }
}

}  // namespace incise::test
