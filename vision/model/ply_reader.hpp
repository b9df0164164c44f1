#pragma once
// The project's own reader of PLY meshes (http://paulbourke.net/dataformats/ply/): ASCII,
// binary little- and big-endian. BOP datasets ship their models as binary PLY.

#include "vision/model/mesh.hpp"

#include <filesystem>

namespace mfcd::vision {

// Reads the `vertex` element's x, y, z (any scalar type, scaled by `scale`) and the `face`
// element's `vertex_indices` (or `vertex_index`) lists, fan-triangulating polygons; every other
// property and element is read past. Throws std::runtime_error naming the file and what is wrong
// (not a PLY, unknown format or type, a count the file cannot hold, a truncated body, a face index
// outside the vertices, a non-number in an ASCII body) before it allocates or indexes anything
// from an unchecked count.
Mesh read_ply(const std::filesystem::path& file, float scale = 1.0f);

}  // namespace mfcd::vision
