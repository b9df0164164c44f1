// vision/model load_mesh() on an STL (ASCII or binary), read by read_stl, then the loader's own
// checks (indices, coordinates, size, topology).

#include "fuzz/mesh_harness.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  return mfcd::fuzz::load_mesh_input(data, size, ".stl");
}
