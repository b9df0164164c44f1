// vision/model load_mesh() on a PLY (ASCII or binary), read by vision/model/ply_reader, then the
// loader's own checks (indices, coordinates, size, topology).

#include "fuzz/fuzz_support.hpp"
#include "vision/model/mesh.hpp"

#include <stdexcept>

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const auto input = mfcd::fuzz::scratch_dir() / "input.ply";
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
