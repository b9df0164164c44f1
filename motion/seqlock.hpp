// A single-writer, many-reader snapshot (seqlock). The writer never blocks and never
// allocates, so the vision thread can publish a result without taking a lock; readers retry
// while a write is in progress.
//
// The payload is stored as atomic 32-bit words rather than as a plain T: a torn read is then
// a detected retry instead of a C++ data race, and ThreadSanitizer sees only atomics (it
// does not understand the classic seqlock's racy memcpy, nor standalone fences, which GCC
// refuses under -fsanitize=thread). Ordering without fences (Boehm, "Can seqlocks get along
// with programming language memory models?"): the writer's word stores are release, so a
// reader that sees any new word also sees the odd sequence number stored before it; the
// reader's word loads are acquire, so its second sequence load cannot move above them.
// On x86 these are plain moves.
#pragma once

#include <array>
#include <atomic>
#include <bit>
#include <cstdint>
#include <cstring>
#include <type_traits>

namespace mfcd::motion {

template <typename T>
class SeqlockSnapshot {
  static_assert(std::is_trivially_copyable_v<T>, "snapshot payload must be trivially copyable");
  static constexpr std::size_t kWords = (sizeof(T) + 3) / 4;

 public:
  SeqlockSnapshot() { store_words(T{}); }

  // Writer side. Only one thread may call publish().
  void publish(const T& value) noexcept {
    const std::uint32_t seq = seq_.load(std::memory_order_relaxed);
    seq_.store(seq + 1, std::memory_order_relaxed);  // odd: write in progress
    store_words(value);
    seq_.store(seq + 2, std::memory_order_release);
  }

  // Reader side, any number of threads. Returns a value some publish() wrote in full.
  T read() const noexcept {
    for (;;) {
      const std::uint32_t before = seq_.load(std::memory_order_acquire);
      if (before & 1u) continue;
      std::array<std::uint32_t, kWords> words;
      for (std::size_t i = 0; i < kWords; ++i) words[i] = words_[i].load(std::memory_order_acquire);
      if (seq_.load(std::memory_order_relaxed) == before) {
        T out;
        std::memcpy(static_cast<void*>(&out), words.data(), sizeof(T));
        return out;
      }
    }
  }

  // Number of completed publishes; lets readers notice a change cheaply.
  std::uint32_t version() const noexcept { return seq_.load(std::memory_order_acquire) / 2; }

 private:
  void store_words(const T& value) noexcept {
    std::array<std::uint32_t, kWords> words{};
    std::memcpy(words.data(), &value, sizeof(T));
    for (std::size_t i = 0; i < kWords; ++i) words_[i].store(words[i], std::memory_order_release);
  }

  std::atomic<std::uint32_t> seq_{0};
  std::array<std::atomic<std::uint32_t>, kWords> words_{};
};

}  // namespace mfcd::motion
