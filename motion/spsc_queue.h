// Bounded lock-free single-producer / single-consumer ring. The Modbus server thread pushes
// PLC commands, the daemon pops them; neither side blocks or allocates.
#pragma once

#include <array>
#include <atomic>
#include <cstddef>
#include <optional>

namespace mfcd::motion {

template <typename T, std::size_t Capacity>
class SpscQueue
{
	static_assert(Capacity >= 2 && (Capacity & (Capacity - 1)) == 0, "capacity must be a power of two");

public:
	// Producer thread only. False when full: the caller decides what "full" means.
	bool push(const T &value) noexcept
	{
		const std::size_t head = head_.load(std::memory_order_relaxed);
		if (head - tail_.load(std::memory_order_acquire) == Capacity)
			return false;
		slots_[head & (Capacity - 1)] = value;
		head_.store(head + 1, std::memory_order_release);
		return true;
	}

	// Consumer thread only.
	std::optional<T> pop() noexcept
	{
		const std::size_t tail = tail_.load(std::memory_order_relaxed);
		if (head_.load(std::memory_order_acquire) == tail)
			return std::nullopt;
		T value = slots_[tail & (Capacity - 1)];
		tail_.store(tail + 1, std::memory_order_release);
		return value;
	}

	std::size_t size_approx() const noexcept
	{
		return head_.load(std::memory_order_acquire) - tail_.load(std::memory_order_acquire);
	}

private:
	alignas(64) std::atomic<std::size_t> head_{0};
	alignas(64) std::atomic<std::size_t> tail_{0};
	std::array<T, Capacity> slots_{};
};

} // namespace mfcd::motion
