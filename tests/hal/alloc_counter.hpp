#pragma once
// Counting allocator for the test and benchmark binaries: alloc_counter.cpp replaces the global
// operator new/delete, so every heap allocation in the process (std::vector, std::string, ...) bumps
// allocation_count(). Steady-state checks read it before and after a loop; the difference must be 0.
#include <cstdint>

namespace mfcd::hal::test {
std::uint64_t allocation_count() noexcept;
// From now on (nullptr: off), also count the allocations of threads whose name does not start with
// `prefix` (a string literal), for a steady-state check while other threads (a web server) allocate.
// Reads the thread's name at every allocation while on: slow, for tests only.
void exclude_threads_named(const char* prefix) noexcept;
std::uint64_t allocation_count_outside_excluded() noexcept;
}  // namespace mfcd::hal::test
