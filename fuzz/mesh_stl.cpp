// vision/model load_mesh() on an STL (ASCII or binary), read by assimp's STL importer, then the
// loader's own checks (indices, coordinates, size, topology).

#include "fuzz/mesh_harness.hpp"

// Debian 12's assimp 5.2.5 leaks the partly built scene when an importer throws on a malformed
// file (outside this project; docs/fuzzing.md): LeakSanitizer leaves allocations made in
// libassimp out of its reports, everything else's leaks remain findings.
extern "C" const char* __lsan_default_suppressions() { return "leak:libassimp.so\n"; }

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return mfcd::fuzz::load_mesh_input(data, size, ".stl");
}
