#pragma once
// CAD exchange files (STEP, IGES) as triangle meshes, through Open CASCADE (Debian's OCCT 7.6):
// the file's solids and faces are read with their units (converted to millimetres by OCCT's
// reader), tessellated with a stated chordal tolerance (the largest distance between a triangle
// and the surface it stands for) and angular tolerance, and merged into one mesh, assemblies
// with their placements applied. load_part reads a part's model in any format: STEP and IGES here,
// the others through load_mesh (mesh.hpp). A library of its own (mfcd_vision_cad), linked only by
// the programs that read a user's CAD (mfc-teach).
#include <filesystem>

#include "vision/model/mesh.hpp"

namespace mfcd::vision {

// True for the extensions read_cad takes (any case).
bool is_cad_file(const std::filesystem::path& file);

// Reads and tessellates the file; the mesh is in mm and not yet welded or validated. Throws
// std::runtime_error naming the file and OCCT's reason when it cannot be read, holds no shape or
// yields no triangles.
Mesh read_cad(const std::filesystem::path& file, const CadTessellation& tessellation = {});

// A part's model: STEP/IGES through read_cad (options.unit_mm must be 1: the file carries its
// unit; options.tessellation applies), anything else through load_mesh; then welded and
// validated. Throws std::runtime_error naming the file.
Mesh load_part(const std::filesystem::path& file, const MeshLoadOptions& options = {}, MeshReport* report = nullptr);

}  // namespace mfcd::vision
