#pragma once
// The project's own reader of Wavefront OBJ meshes: the geometry a part needs, nothing of the
// materials, textures or curves the format also carries.

#include "vision/model/mesh.hpp"

#include <filesystem>

namespace mfcd::vision {

// Reads `v x y z` (further numbers, a weight or a colour, are read past) scaled by `scale`, and
// `f` faces of three or more corners (`i`, `i/t`, `i//n`, `i/t/n`; negative indices count back
// from the last vertex so far), fan-triangulated; every other statement (vt, vn, g, o, s, usemtl,
// mtllib, l, p, ...) and `#` comments are read past. Throws std::runtime_error naming the file and
// the line on a malformed number or index, a face of fewer than three corners or an index 0 or
// before the first vertex. Indices past the last vertex are load_mesh's to refuse (a face may
// name a vertex defined after it).
Mesh read_obj(const std::filesystem::path& file, float scale = 1.0f);

}  // namespace mfcd::vision
