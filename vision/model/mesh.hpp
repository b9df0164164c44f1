#pragma once
// Triangle meshes of parts, in millimetres: loaded from CAD exports (STL, OBJ, PLY, STEP, IGES) or
// generated in code for tests (cube, sphere, cylinder, plane).

#include <opencv2/core.hpp>

#include <array>
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace mfcd::vision {

struct Mesh {
  std::vector<cv::Vec3f> vertices;                 // mm, in the part's own frame
  std::vector<std::array<uint32_t, 3>> triangles;  // indices into vertices, counter-clockwise seen from outside
  std::string name;

  cv::Vec3f bbox_min() const;
  cv::Vec3f bbox_max() const;
};

// How a STEP or IGES file's surfaces become triangles (cad_reader.hpp).
struct CadTessellation {
  // The largest distance between a triangle and the surface it stands for: 0.05 mm is 0.2 px at
  // the cell's 0.27 mm/px, so the templates' edges do not show the facets.
  double chordal_tolerance_mm = 0.05;
  // The largest turn between neighbouring triangles' normals on a curved face: bounds the facets
  // of small radii, which the chordal tolerance alone leaves coarse in angle.
  double angular_tolerance_deg = 10;
};

struct MeshLoadOptions {
  // Millimetres per file unit: 1 for files in mm, 25.4 for inches, 1000 for metres.
  double unit_mm = 1.0;
  // Sizes outside [min_size_mm, max_size_mm] (largest bounding-box side) are rejected:
  // they almost always mean a wrong unit.
  double min_size_mm = 1.0;
  double max_size_mm = 2000.0;
  // STEP and IGES (load_part, cad_reader.hpp): how their surfaces become triangles. Their length
  // unit comes from the file; unit_mm must stay 1 for them.
  CadTessellation tessellation;
};

// Parses a unit name for --unit options: "mm", "cm", "m", "in"/"inch", or a number (mm per unit).
double parse_unit_mm(const std::string& unit);

// What validation found that is worth telling but does not stop loading.
struct MeshReport {
  size_t open_edges = 0;          // edges used by one triangle only (holes)
  size_t non_manifold_edges = 0;  // edges used by more than two triangles
  size_t degenerate_triangles = 0;
  std::vector<std::string> warnings;
};

// Loads an STL (ASCII or binary, read_stl), OBJ (read_obj) or PLY (ASCII or binary, read_ply;
// vision/model/*_reader.hpp), merges all its meshes into one, scales to mm, welds identical
// vertices and validates. The extension (.stl, .obj, .ply, any case) picks the reader; any other is
// refused (STEP and IGES with a pointer to load_part, vision/model/cad_reader.hpp: OCCT is a
// library of its own, linked only by what reads a user's CAD). Throws std::runtime_error naming the file on an
// unsupported extension, an unreadable, empty or absurdly sized mesh, a face index outside the vertices or a non-finite
// vertex; non-manifold geometry only adds warnings to *report (and to syslog when report is null).
Mesh load_mesh(const std::filesystem::path& file, const MeshLoadOptions& options = {}, MeshReport* report = nullptr);

// What every loader ends with: checks indices and coordinates, welds identical vertices and
// validates (validate_mesh; its warnings to *report, or to syslog when report is null). Throws as
// load_mesh does, naming `source`.
Mesh finish_loading(Mesh mesh, const MeshLoadOptions& options, MeshReport* report, const std::string& source);

// Checks topology and size. Throws on an empty mesh, bad indices, non-finite vertices or
// a size outside the options' range; returns the topology findings.
MeshReport validate_mesh(const Mesh& mesh, const MeshLoadOptions& options = {}, const std::string& source = "mesh");

// Closed, outward-oriented meshes centred on the origin.
Mesh make_box(double sx, double sy, double sz);
Mesh make_uv_sphere(double radius, int slices = 64, int stacks = 32);
Mesh make_cylinder(double radius, double height, int slices = 64);  // axis z, from -h/2 to h/2
// A square in the z = 0 plane, normal -z (facing a camera looking along +z), side `size`.
Mesh make_plane(double size);

}  // namespace mfcd::vision
