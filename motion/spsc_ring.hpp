// The one lock-free single-producer / single-consumer ring of mfcd: a bounded array of slots
// allocated once, used either in place (the producer fills a slot it was lent with
// begin_write/end_write, the consumer reads it where it lies with begin_read/end_read: how whole
// frame sets of 9 images travel without a copy) or by value (push/pop: how small PLC commands and
// cycle requests travel). Neither side blocks, locks or allocates.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <optional>

namespace mfcd::motion {

template <typename T, std::size_t Capacity>
class SpscRing {
  static_assert(Capacity >= 2 && (Capacity & (Capacity - 1)) == 0, "capacity must be a power of two");

 public:
  // Producer thread only: the next free slot, or nullptr when every slot is full.
  T* begin_write() noexcept {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_.load(std::memory_order_acquire) == Capacity) return nullptr;
    return &slots_[head & (Capacity - 1)];
  }
  // Producer: publishes the slot returned by the last begin_write().
  void end_write() noexcept { head_.store(head_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }

  // Consumer thread only: the oldest filled slot, or nullptr when empty.
  T* begin_read() noexcept {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    if (head_.load(std::memory_order_acquire) == tail) return nullptr;
    return &slots_[tail & (Capacity - 1)];
  }
  // Consumer: hands the slot returned by the last begin_read() back to the producer.
  void end_read() noexcept { tail_.store(tail_.load(std::memory_order_relaxed) + 1, std::memory_order_release); }

  // Producer: copies `value` into the next slot. False when full: the caller decides what
  // "full" means.
  bool push(const T& value) noexcept {
    T* slot = begin_write();
    if (!slot) return false;
    *slot = value;
    end_write();
    return true;
  }
  // Consumer: the oldest value, copied out, or nullopt when empty.
  std::optional<T> pop() noexcept {
    T* slot = begin_read();
    if (!slot) return std::nullopt;
    std::optional<T> value(*slot);
    end_read();
    return value;
  }

  std::size_t size_approx() const noexcept {
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

}  // namespace mfcd::motion
