#pragma once
// An OpenGL 3.3 core context on EGL's surfaceless display (Mesa's llvmpipe when there is no
// GPU), for offscreen rendering into framebuffer objects.

#include <mutex>

namespace mfcd::vision {

// Held around every use of OpenGL in the process (one renderer's render, its making and its
// destruction): llvmpipe, the renderer of machines without a GPU, is not safe with two contexts
// working at once in one process: mapping a resource (a readback, an upload) looks into every
// context of the process while their threads may be drawing. Rendering in one context at a time still uses every core
// (llvmpipe rasterizes on threads of its own); the callers' work between renders overlaps.
[[nodiscard]] std::unique_lock<std::mutex> lock_gl();

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
