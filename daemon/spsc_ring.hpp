#pragma once
// A bounded lock-free single-producer / single-consumer ring of *preallocated* slots, used in
// place: the producer fills a slot it was lent (beginWrite/endWrite), the consumer reads it where
// it lies (beginRead/endRead). Nothing is copied or allocated after construction, so it can carry
// whole FrameSets (9 images) between the acquisition and vision threads.
//
// motion::SpscQueue copies values in and out, which is right for small PLC commands but not for
// 2.7 MB of images; this ring lends the slot instead.
#include <array>
#include <atomic>
#include <cstddef>

namespace mfcd::daemon {

template <typename T, std::size_t Capacity>
class SpscRing {
  static_assert(Capacity >= 2 && (Capacity & (Capacity - 1)) == 0, "capacity must be a power of two");

public:
  // Producer thread only: the next free slot, or nullptr when every slot is full.
  T* beginWrite() noexcept {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_.load(std::memory_order_acquire) == Capacity) return nullptr;
    return &slots_[head & (Capacity - 1)];
  }
  // Producer: publishes the slot returned by the last beginWrite().
  void endWrite() noexcept { head_.store(head_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }

  // Consumer thread only: the oldest filled slot, or nullptr when empty.
  T* beginRead() noexcept {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    if (head_.load(std::memory_order_acquire) == tail) return nullptr;
    return &slots_[tail & (Capacity - 1)];
  }
  // Consumer: hands the slot returned by the last beginRead() back to the producer.
  void endRead() noexcept { tail_.store(tail_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }

  std::size_t sizeApprox() const noexcept {
    return head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire);
  }
  static constexpr std::size_t capacity() { return Capacity; }

  // Every slot, for one-time preparation (allocation) before the threads start.
  std::array<T, Capacity>& slots() noexcept { return slots_; }

private:
  alignas(64) std::atomic<std::size_t> head_{0};
  alignas(64) std::atomic<std::size_t> tail_{0};
  std::array<T, Capacity> slots_{};
};

}  // namespace mfcd::daemon
