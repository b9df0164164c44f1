#pragma once
// CAD exchange files (STEP, IGES) as triangle meshes, through Open CASCADE (Debian's OCCT 7.6):
// the file's solids and faces are read with their units (converted to millimetres by OCCT's
// reader), tessellated with a stated chordal tolerance (the largest distance between a triangle
// and the surface it stands for) and angular tolerance, and merged into one mesh, assemblies
// with their placements applied. load_mesh (mesh.hpp) calls it for .step/.stp/.iges/.igs.
#include <filesystem>

#include "vision/model/mesh.hpp"

namespace mfcd::vision {

// True for the extensions read_cad takes (any case).
bool is_cad_file(const std::filesystem::path& file);

// Reads and tessellates the file; the mesh is in mm and not yet welded or validated. Throws
// std::runtime_error naming the file and OCCT's reason when it cannot be read, holds no shape or
// yields no triangles.
Mesh read_cad(const std::filesystem::path& file, const CadTessellation& tessellation = {});

}  // namespace mfcd::vision
