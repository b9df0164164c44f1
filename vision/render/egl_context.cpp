#include "vision/render/egl_context.hpp"

#include <EGL/egl.h>
#include <EGL/eglext.h>

#include <stdexcept>
#include <string>

namespace mfcd::vision {

namespace {

[[noreturn]] void egl_fail(const std::string& what) { throw std::runtime_error("renderer: " + what); }

const char* egl_error_name(EGLint e) {
  switch (e) {
    case EGL_SUCCESS:
      return "EGL_SUCCESS";
    case EGL_NOT_INITIALIZED:
      return "EGL_NOT_INITIALIZED";
    case EGL_BAD_ACCESS:
      return "EGL_BAD_ACCESS";
    case EGL_BAD_ALLOC:
      return "EGL_BAD_ALLOC";
    case EGL_BAD_ATTRIBUTE:
      return "EGL_BAD_ATTRIBUTE";
    case EGL_BAD_CONFIG:
      return "EGL_BAD_CONFIG";
    case EGL_BAD_CONTEXT:
      return "EGL_BAD_CONTEXT";
    case EGL_BAD_DISPLAY:
      return "EGL_BAD_DISPLAY";
    case EGL_BAD_MATCH:
      return "EGL_BAD_MATCH";
    case EGL_BAD_PARAMETER:
      return "EGL_BAD_PARAMETER";
    default:
      return "EGL error";
  }
}

}  // namespace

std::unique_lock<std::mutex> lock_gl() {
  static std::mutex gl_mutex;
  return std::unique_lock<std::mutex>(gl_mutex);
}

EglContext::EglContext() {
  auto get_platform_display =
      reinterpret_cast<PFNEGLGETPLATFORMDISPLAYEXTPROC>(eglGetProcAddress("eglGetPlatformDisplayEXT"));
  if (!get_platform_display)
    egl_fail("EGL lacks eglGetPlatformDisplayEXT; install Mesa's EGL (libegl-mesa0, libgl1-mesa-dri)");
  EGLDisplay display = get_platform_display(EGL_PLATFORM_SURFACELESS_MESA, EGL_DEFAULT_DISPLAY, nullptr);
  EGLint major = 0, minor = 0;
  if (display == EGL_NO_DISPLAY || !eglInitialize(display, &major, &minor))
    egl_fail(std::string("cannot initialise an EGL surfaceless display (") + egl_error_name(eglGetError()) +
             "); install Mesa's EGL and DRI drivers (libegl-mesa0, libgl1-mesa-dri)");
  if (!eglBindAPI(EGL_OPENGL_API)) egl_fail("EGL cannot bind the desktop OpenGL API");
  const EGLint config_attribs[] = {EGL_SURFACE_TYPE, EGL_PBUFFER_BIT, EGL_RENDERABLE_TYPE, EGL_OPENGL_BIT, EGL_NONE};
  EGLConfig config = nullptr;
  EGLint n = 0;
  if (!eglChooseConfig(display, config_attribs, &config, 1, &n) || n < 1) config = nullptr;
  const EGLint context_attribs[] = {
      EGL_CONTEXT_MAJOR_VERSION,           3,       EGL_CONTEXT_MINOR_VERSION, 3, EGL_CONTEXT_OPENGL_PROFILE_MASK,
      EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT, EGL_NONE};
  EGLContext context = eglCreateContext(display, config, EGL_NO_CONTEXT, context_attribs);
  if (context == EGL_NO_CONTEXT)
    egl_fail(std::string("cannot create an OpenGL 3.3 core context (") + egl_error_name(eglGetError()) + ")");
  display_ = display;
  context_ = context;
}

EglContext::~EglContext() {
  if (!context_) return;
  eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, EGL_NO_CONTEXT);
  eglDestroyContext(display_, context_);
}

void EglContext::make_current() const {
  if (!eglMakeCurrent(display_, EGL_NO_SURFACE, EGL_NO_SURFACE, context_))
    egl_fail(std::string("eglMakeCurrent failed: ") + egl_error_name(eglGetError()));
}

}  // namespace mfcd::vision
