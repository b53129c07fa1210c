#include "render/egl_context.h"

#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <cstdlib>
#include <cstring>
#include <vector>

#include "engine/util/error.h"
#include "render/gl.h"

namespace incise {
namespace {

std::string egl_error_name(EGLint e) {
  switch (e) {
    case EGL_SUCCESS: return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED: return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS: return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC: return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE: return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG: return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT: return "EGL_BAD_CONTEXT";
    case EGL_BAD_DISPLAY: return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH: return "EGL_BAD_MATCH";
    case EGL_BAD_PARAMETER: return "EGL_BAD_PARAMETER";
    default: return "EGL error " + std::to_string(e);
  }
}

bool has_extension(const char* list, const char* name) {
  if (!list) return false;
  const size_t n = std::strlen(name);
  for (const char* p = list; (p = std::strstr(p, name)) != nullptr; p += n)
    if ((p == list || p[-1] == ' ') && (p[n] == ' ' || p[n] == '\0')) return true;
  return false;
}

// A display that eglInitialize accepted, or a reason why none was found.
struct Candidate {
  EGLDisplay display = EGL_NO_DISPLAY;
  std::string why_not;
};

Candidate try_device(PFNEGLGETPLATFORMDISPLAYEXTPROC get_display, const char* client_ext) {
  Candidate c;
  if (!has_extension(client_ext, "EGL_EXT_device_enumeration") || !has_extension(client_ext, "EGL_EXT_platform_device")) {
    c.why_not = "EGL_EXT_device_enumeration / EGL_EXT_platform_device not offered";
    return c;
  }
  auto query_devices = reinterpret_cast<PFNEGLQUERYDEVICESEXTPROC>(eglGetProcAddress("eglQueryDevicesEXT"));
  auto query_string = reinterpret_cast<PFNEGLQUERYDEVICESTRINGEXTPROC>(eglGetProcAddress("eglQueryDeviceStringEXT"));
  EGLint n = 0;
  if (!query_devices || !query_string || !query_devices(0, nullptr, &n) || n <= 0) {
    c.why_not = "no EGL device enumerated";
    return c;
  }
  std::vector<EGLDeviceEXT> devices(n);
  query_devices(n, devices.data(), &n);
  int software = 0;
  for (EGLint i = 0; i < n; ++i) {
    // Mesa lists a software device too; that is what surfaceless gives, so
    // "device" means hardware here.
    if (has_extension(query_string(devices[i], EGL_EXTENSIONS), "EGL_MESA_device_software")) {
      ++software;
      continue;
    }
    EGLDisplay d = get_display(EGL_PLATFORM_DEVICE_EXT, devices[i], nullptr);
    if (d != EGL_NO_DISPLAY && eglInitialize(d, nullptr, nullptr)) {
      c.display = d;
      return c;
    }
    c.why_not += "device " + std::to_string(i) + ": eglInitialize failed (" + egl_error_name(eglGetError()) + "); ";
  }
  c.why_not += std::to_string(n) + " device(s), " + std::to_string(software) + " of them software only";
  return c;
}

Candidate try_surfaceless(PFNEGLGETPLATFORMDISPLAYEXTPROC get_display, const char* client_ext) {
  Candidate c;
  if (!has_extension(client_ext, "EGL_MESA_platform_surfaceless")) {
    c.why_not = "EGL_MESA_platform_surfaceless not offered (is libegl-mesa0 installed?)";
    return c;
  }
  EGLDisplay d = get_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
  if (d == EGL_NO_DISPLAY) {
    c.why_not = "eglGetPlatformDisplayEXT failed (" + egl_error_name(eglGetError()) + ")";
  } else if (!eglInitialize(d, nullptr, nullptr)) {
    c.why_not = "eglInitialize failed (" + egl_error_name(eglGetError()) + "; is libgl1-mesa-dri installed?)";
  } else {
    c.display = d;
  }
  return c;
}

}  // namespace

EglPlatform parse_egl_platform(const std::string& name, const std::string& where) {
  if (name == "auto") return EglPlatform::Auto;
  if (name == "device") return EglPlatform::Device;
  if (name == "surfaceless") return EglPlatform::Surfaceless;
  throw Error(where + " must be one of \"auto\", \"device\", \"surfaceless\", got \"" + name + "\"");
}

const char* egl_platform_name(EglPlatform p) {
  switch (p) {
    case EglPlatform::Device: return "device";
    case EglPlatform::Surfaceless: return "surfaceless";
    default: return "auto";
  }
}

EglPlatform egl_platform_from_env() {
  const char* v = std::getenv("INCISE_EGL_PLATFORM");
  return (v && *v) ? parse_egl_platform(v, "INCISE_EGL_PLATFORM") : EglPlatform::Auto;
}

EglContext::EglContext(EglPlatform want) {
  const char* client_ext = eglQueryString(EGL_NO_DISPLAY, EGL_EXTENSIONS);
  auto get_display =
      reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
  if (!client_ext || !get_display || !has_extension(client_ext, "EGL_EXT_platform_base"))
    throw Error("EGL: no EGL display can be had: EGL_EXT_platform_base is missing (install libegl1 and libegl-mesa0)");

  std::string tried;
  EGLDisplay dpy = EGL_NO_DISPLAY;
  if (want != EglPlatform::Surfaceless) {
    Candidate c = try_device(get_display, client_ext);
    if (c.display != EGL_NO_DISPLAY) dpy = c.display, platform_ = EglPlatform::Device;
    else tried += "device platform: " + c.why_not + ". ";
  }
  if (dpy == EGL_NO_DISPLAY && want != EglPlatform::Device) {
    Candidate c = try_surfaceless(get_display, client_ext);
    if (c.display != EGL_NO_DISPLAY) dpy = c.display, platform_ = EglPlatform::Surfaceless;
    else tried += "surfaceless Mesa: " + c.why_not + ". ";
  }
  if (dpy == EGL_NO_DISPLAY)
    throw Error(std::string("EGL: no EGL display can be had (platform ") + egl_platform_name(want) + "): " + tried +
                "Set INCISE_EGL_PLATFORM=auto|device|surfaceless to choose.");
  display_ = dpy;

  if (!eglBindAPI(EGL_OPENGL_API)) {
    throw Error("EGL: eglBindAPI(EGL_OPENGL_API) failed: the driver offers no desktop OpenGL");
  }
  // No config needed when rendering only into FBOs; otherwise any pbuffer-capable GL config.
  const char* dpy_ext = eglQueryString(dpy, EGL_EXTENSIONS);
  EGLConfig config = EGL_NO_CONFIG_KHR;
  if (!has_extension(dpy_ext, "EGL_KHR_no_config_context")) {
    const EGLint want_cfg[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
    EGLint n = 0;
    if (!eglChooseConfig(dpy, want_cfg, &config, 1, &n) || n < 1) {
        throw Error("EGL: no OpenGL-renderable config on the " + std::string(egl_platform_name(platform_)) + " display");
    }
  }
  const EGLint ctx_attr[] = {EGL_CONTEXT_MAJOR_VERSION, 3, EGL_CONTEXT_MINOR_VERSION, 3,
                             EGL_CONTEXT_OPENGL_PROFILE_MASK, EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
  EGLContext ctx = eglCreateContext(dpy, config, EGL_NO_CONTEXT, ctx_attr);
  if (ctx == EGL_NO_CONTEXT) {
    const std::string e = egl_error_name(eglGetError());
    throw Error("EGL: cannot create an OpenGL 3.3 core context on the " + std::string(egl_platform_name(platform_)) +
                " display (" + e + ")");
  }
  context_ = ctx;
  make_current();
  auto str = [](GLenum name) {
    const GLubyte* s = glGetString(name);
    return s ? std::string(reinterpret_cast<const char*>(s)) : std::string("?");
  };
  vendor_ = str(GL_VENDOR);
  renderer_ = str(GL_RENDERER);
  version_ = str(GL_VERSION);
}

// Displays are never terminated: eglInitialize does not count, so one
// eglTerminate would end the display under every other context on it, and
// terminating unloads the driver (Mesa's, with its JIT code), after which
// LeakSanitizer reports the driver's exit-time allocations as unnamed leaks.
// A display is a per-process singleton anyway; a second renderer reuses it.
EglContext::~EglContext() {
  if (display_) {
    eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
    if (context_) eglDestroyContext(display_, context_);
    eglReleaseThread();
  }
}

void EglContext::make_current() {
  if (!eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, context_))
    throw Error("EGL: eglMakeCurrent without a surface failed (" + egl_error_name(eglGetError()) +
                "); the driver lacks EGL_KHR_surfaceless_context");
}

std::string EglContext::description() const {
  return std::string(egl_platform_name(platform_)) + " (" + vendor_ + ", " + renderer_ + ", " + version_ + ")";
}

}  // namespace incise
