#pragma once
// The project's own reader of STL meshes, binary and ASCII. STL is a list of triangles, each
// with its three corners written out (shared corners are joined later, by load_mesh's weld).

#include "vision/model/mesh.hpp"

#include <filesystem>

namespace mfcd::vision {

// Binary when the file is exactly 84 + 50 x (its triangle count) bytes long (an ASCII file's
// length cannot say so by chance of its first 84 bytes, while a binary file's 80-byte header
// often begins "solid"); ASCII otherwise: `solid`, then `facet [normal x y z]`, `outer loop`,
// three `vertex x y z`, `endloop`, `endfacet`, any number of times, then `endsolid` (several
// solids may follow one another). Corners are scaled by `scale`; normals are not read (the
// winding is the triangle's orientation). Throws std::runtime_error naming the file, and for
// ASCII the line, on anything else, before allocating from an unchecked count.
Mesh read_stl(const std::filesystem::path& file, float scale = 1.0f);

}  // namespace mfcd::vision
