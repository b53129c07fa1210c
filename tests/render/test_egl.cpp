// The EGL context: chosen automatically and reported, forced by name, and a
// clear error when the forced platform is not available.
#include "render/egl_context.h"

#include <gtest/gtest.h>

#include "render/gl.h"
#include "render_test_util.h"

namespace incise::test {
namespace {

TEST(Egl, AutoGivesAnOpenGl33CoreContextAndSaysWhich) {
  try {
    EglContext ctx(EglPlatform::Auto);
    EXPECT_NE(ctx.platform(), EglPlatform::Auto);
    EXPECT_NE(ctx.description().find(egl_platform_name(ctx.platform())), std::string::npos) << ctx.description();
    GLint major = 0, minor = 0;
    glGetIntegerv(GL_MAJOR_VERSION, &major);
    glGetIntegerv(GL_MINOR_VERSION, &minor);
    EXPECT_GE(major * 10 + minor, 33) << ctx.description();
    std::printf("EGL: %s\n", ctx.description().c_str());
  } catch (const Error& e) {
    FAIL() << "EGL could not initialise: " << e.what()
           << "\nThe render tests need Mesa's surfaceless EGL (libegl-mesa0, libgl1-mesa-dri) or a GPU.";
  }
}

TEST(Egl, SurfacelessMesaCanBeForced) {
  try {
    EglContext ctx(EglPlatform::Surfaceless);
    EXPECT_EQ(ctx.platform(), EglPlatform::Surfaceless);
  } catch (const Error& e) {
    FAIL() << "surfaceless Mesa EGL is what CI renders with: " << e.what();
  }
}

TEST(Egl, ForcedDevicePlatformWorksOrSaysWhyNot) {
  try {
    EglContext ctx(EglPlatform::Device);
    EXPECT_EQ(ctx.platform(), EglPlatform::Device);  // a GPU is present
  } catch (const Error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("no EGL display can be had (platform device)"), std::string::npos) << m;
    EXPECT_NE(m.find("device platform:"), std::string::npos) << m;
    EXPECT_NE(m.find("INCISE_EGL_PLATFORM"), std::string::npos) << m;
  }
}

TEST(Egl, PlatformNamesAreChecked) {
  EXPECT_EQ(parse_egl_platform("device", "x"), EglPlatform::Device);
  EXPECT_EQ(parse_egl_platform("surfaceless", "x"), EglPlatform::Surfaceless);
  EXPECT_EQ(parse_egl_platform("auto", "x"), EglPlatform::Auto);
  try {
    parse_egl_platform("gpu", "INCISE_EGL_PLATFORM");
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_STREQ(e.what(), "INCISE_EGL_PLATFORM must be one of \"auto\", \"device\", \"surfaceless\", got \"gpu\"");
  }
}

}  // namespace
}  // namespace incise::test
