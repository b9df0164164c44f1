#pragma once
// An OpenGL 3.3 core context on EGL's surfaceless display (Mesa's llvmpipe when there is no
// GPU), for offscreen rendering into framebuffer objects.

namespace mfcd::vision {

class EglContext {
 public:
  // Throws std::runtime_error naming what is missing (EGL, the surfaceless platform, a 3.3
  // core context) and the packages that provide it.
  EglContext();
  // Destroys the context. The display is shared by every context of the process and is never
  // terminated: that would invalidate the others' contexts.
  ~EglContext();
  EglContext(const EglContext&) = delete;
  EglContext& operator=(const EglContext&) = delete;

  // Makes the context current on the calling thread; throws std::runtime_error if EGL refuses.
  void make_current() const;

 private:
  void* display_ = nullptr;  // EGLDisplay
  void* context_ = nullptr;  // EGLContext
};

}  // namespace mfcd::vision
