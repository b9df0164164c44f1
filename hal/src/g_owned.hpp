#pragma once
// GOwned: owns one GLib/GObject pointer and gives it back exactly once with `Release`
// (g_object_unref for ArvCamera / ArvStream / ArvBuffer, g_error_free for a GError, g_free for
// the arrays Aravis's dup_* functions return). Move-only. Private to hal/src: the public headers
// carry no GLib types.
#include <utility>

namespace mfcd::hal {

template <typename T, auto Release>
class GOwned {
 public:
  GOwned() = default;
  explicit GOwned(T* p) noexcept : p_(p) {}
  ~GOwned() { reset(); }
  GOwned(GOwned&& other) noexcept : p_(std::exchange(other.p_, nullptr)) {}
  GOwned& operator=(GOwned&& other) noexcept {
    if (this != &other) reset(std::exchange(other.p_, nullptr));
    return *this;
  }
  GOwned(const GOwned&) = delete;
  GOwned& operator=(const GOwned&) = delete;

  T* get() const noexcept { return p_; }
  T* operator->() const noexcept { return p_; }
  explicit operator bool() const noexcept { return p_ != nullptr; }
  // For C out-parameters (GError**): releases what is held, then lets the callee fill it.
  T** out() noexcept {
    reset();
    return &p_;
  }
  void reset(T* p = nullptr) noexcept {
    if (p_) Release(p_);
    p_ = p;
  }

 private:
  T* p_ = nullptr;
};

}  // namespace mfcd::hal
