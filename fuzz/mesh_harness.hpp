#pragma once
// The body of the mesh_stl, mesh_obj and mesh_ply harnesses: vision/model load_mesh() on the input
// written as a file of the given extension (which picks the reader), then the loader's own checks
// (indices, coordinates, size, topology). Besides the sanitizers: every triangle of a loaded mesh
// names one of its vertices.

#include "fuzz/fuzz_support.hpp"
#include "vision/model/mesh.hpp"

#include <stdexcept>

namespace mfcd::fuzz {

inline int load_mesh_input(const uint8_t* data, size_t size, const char* extension) {
  const auto input = scratch_dir() / (std::string("input") + extension);
  write_file(input, data, size);
  try {
    vision::MeshReport report;  // non-null: warnings go here, not to syslog
    const vision::Mesh mesh = vision::load_mesh(input, {}, &report);
    for (const auto& t : mesh.triangles)
      for (uint32_t i : t)
        if (i >= mesh.vertices.size()) finding("a loaded triangle names a missing vertex");
  } catch (const std::runtime_error&) {
    // documented: the file and the reason named
  }
  return 0;
}

}  // namespace mfcd::fuzz
