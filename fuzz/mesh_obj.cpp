// vision/model load_mesh() on a Wavefront OBJ, read by read_obj, then the loader's own checks
// (indices, coordinates, size, topology).

#include "fuzz/mesh_harness.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return mfcd::fuzz::load_mesh_input(data, size, ".obj");
}
