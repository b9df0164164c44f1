#pragma once
// Counting allocator for the test and benchmark binaries: alloc_counter.cpp replaces the global
// operator new/delete, so every heap allocation in the process (std::vector, std::string, ...) bumps
// allocationCount(). Steady-state checks read it before and after a loop; the difference must be 0.
#include <cstdint>

namespace mfcd::hal::test {
std::uint64_t allocationCount() noexcept;
}
