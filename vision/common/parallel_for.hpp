#pragma once
// OpenMP loops whose exceptions reach the caller. An exception that leaves an OpenMP structured
// block calls std::terminate, so a std::bad_alloc or cv::Exception thrown inside a parallel fit
// would kill the daemon instead of reaching the cycle's catch. Inside the region, every iteration
// runs in a try block; the first exception is kept, the remaining iterations are skipped, and it
// is rethrown on the calling thread once the region has ended.
//
// Steady state costs one relaxed atomic load per iteration: no lock, no allocation (the
// exception_ptr is written only on the error path).

#include <omp.h>

#include <atomic>
#include <exception>

namespace mfcd::vision {

// The first exception thrown by any thread of a region. capture() is called from a catch block.
class FirstException {
 public:
  bool failed() const { return claimed_.load(std::memory_order_acquire) == 2; }
  // Skip further work once any thread has failed (the flag is set before the pointer is
  // published; a thread that reads it a little late does one more iteration, no harm).
  bool stopping() const { return claimed_.load(std::memory_order_relaxed) != 0; }
  void capture() noexcept {
    int expected = 0;
    if (claimed_.compare_exchange_strong(expected, 1, std::memory_order_acq_rel)) {
      error_ = std::current_exception();
      claimed_.store(2, std::memory_order_release);
    }
  }
  // After the region (its implicit barrier orders every capture before this).
  void rethrow_if_any() const {
    if (claimed_.load(std::memory_order_acquire) != 0 && error_) std::rethrow_exception(error_);
  }

 private:
  std::atomic<int> claimed_{0};  // 0 none, 1 being stored, 2 stored
  std::exception_ptr error_;
};

// body(i) for every i in [begin, end) on `threads` threads (<= 0: OpenMP's default), dynamic
// schedule in chunks of `chunk`. Rethrows the first exception a body threw; the iterations not
// yet started when it was thrown are skipped.
template <class Body>
void parallel_for(int begin, int end, int threads, int chunk, Body&& body) {
  FirstException first;
  const int n = threads > 0 ? threads : omp_get_max_threads();
#pragma omp parallel for schedule(dynamic, chunk) num_threads(n)
  for (int i = begin; i < end; ++i) {
    if (first.stopping()) continue;
    try {
      body(i);
    } catch (...) {
      first.capture();
    }
  }
  first.rethrow_if_any();
}

}  // namespace mfcd::vision
