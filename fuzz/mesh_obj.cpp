// vision/model load_mesh() on a Wavefront OBJ, read by assimp's OBJ importer, then the
// loader's own checks (indices, coordinates, size, topology).

#include "fuzz/fuzz_support.hpp"
#include "vision/model/mesh.hpp"

#include <stdexcept>

// Debian 12's assimp 5.2.5 leaks the partly built scene when an importer throws on a malformed
// file (outside this project; docs/fuzzing.md): LeakSanitizer leaves allocations made in
// libassimp out of its reports, everything else's leaks remain findings.
extern "C" const char* __lsan_default_suppressions() { return "leak:libassimp.so\n"; }

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto input = mfcd::fuzz::scratch_dir() / "input.obj";
  mfcd::fuzz::write_file(input, data, size);
  try {
    mfcd::vision::MeshReport report;  // non-null: warnings go here, not to syslog
    const mfcd::vision::Mesh mesh = mfcd::vision::load_mesh(input, {}, &report);
    for (const auto& t : mesh.triangles)
      for (uint32_t i : t)
        if (i >= mesh.vertices.size()) mfcd::fuzz::finding("a loaded triangle names a missing vertex");
  } catch (const std::runtime_error&) {
    // documented: the file and the reason named
  }
  return 0;
}
