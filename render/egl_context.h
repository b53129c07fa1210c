#pragma once
// An offscreen OpenGL 3.3 core context with no window system: the EGL device
// platform when a GPU is present, Mesa's surfaceless platform (llvmpipe on
// the CPU) otherwise. Rendering goes into a framebuffer object; no EGL
// surface is ever created (EGL_KHR_surfaceless_context).
#include <string>

namespace incise {

enum class EglPlatform { Auto, Device, Surfaceless };

// "auto", "device" or "surfaceless"; throws incise::Error naming the allowed values.
EglPlatform parse_egl_platform(const std::string& name, const std::string& where);
const char* egl_platform_name(EglPlatform p);
// INCISE_EGL_PLATFORM when set (auto|device|surfaceless), else Auto.
EglPlatform egl_platform_from_env();

class EglContext {
 public:
  // Auto tries a hardware EGL device first (skipping Mesa's software device),
  // then surfaceless Mesa. Throws incise::Error listing what each platform
  // tried and why it failed when no context can be had.
  explicit EglContext(EglPlatform platform = egl_platform_from_env());
  ~EglContext();
  EglContext(const EglContext&) = delete;
  EglContext& operator=(const EglContext&) = delete;

  void make_current();
  EglPlatform platform() const { return platform_; }
  // e.g. "surfaceless (Mesa, llvmpipe (LLVM 15.0.6, 256 bits), 4.5 (Core Profile) Mesa 22.3.6)"
  std::string description() const;
  const std::string& gl_renderer() const { return renderer_; }

 private:
  void* display_ = nullptr;  // EGLDisplay
  void* context_ = nullptr;  // EGLContext
  EglPlatform platform_ = EglPlatform::Auto;
  std::string vendor_, renderer_, version_;
};

}  // namespace incise
