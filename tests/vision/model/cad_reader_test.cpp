// STEP and IGES parts read through OCCT: files the test writes itself with OCCT (a box, a cylinder
// with a hole through it, an assembly of two placed solids, a box in inches), read back by
// load_mesh and checked against the analytic shapes: size, volume, closed and outward, the
// chordal tolerance kept; and malformed files refused with the reason.
//
// OCCT keeps one-time allocations in its libraries' static state (readers' and writers' editors
// and controllers) and never frees them: LeakSanitizer is told to leave allocations whose stack
// passes through OCCT alone; a leak of ours still shows.
#include "vision/model/cad_reader.hpp"
#include "vision/model/mesh.hpp"

#include <gtest/gtest.h>

#include <BRepAlgoAPI_Cut.hxx>
#include <BRepBuilderAPI_Transform.hxx>
#include <BRepPrimAPI_MakeBox.hxx>
#include <BRepPrimAPI_MakeCylinder.hxx>
#include <BRep_Builder.hxx>
#include <IGESControl_Controller.hxx>
#include <IGESControl_Writer.hxx>
#include <Interface_Static.hxx>
#include <STEPControl_Controller.hxx>
#include <STEPControl_Writer.hxx>
#include <TopoDS_Compound.hxx>
#include <gp_Ax2.hxx>
#include <gp_Trsf.hxx>

#include <unistd.h>

#include <cmath>
#include <fstream>
#include <sstream>

using namespace mfcd::vision;
namespace fs = std::filesystem;

extern "C" const char* __lsan_default_suppressions() {
  return "leak:libTKernel.so\nleak:libTKXSBase.so\nleak:libTKSTEP\nleak:libTKIGES.so\nleak:libTKXSBase\n"
         "leak:libTKBRep.so\nleak:libTKMesh.so\nleak:libTKG3d.so\nleak:libTKGeomBase.so\nleak:libTKPrim.so\n"
         "leak:libTKBO.so\nleak:libTKTopAlgo.so\nleak:libTKShHealing.so\nleak:libTKMath.so\nleak:libTKG2d.so\n";
}

namespace {

struct TempDir {
  fs::path path = fs::temp_directory_path() / ("mfcd-cad-" + std::to_string(::getpid()));
  TempDir() { fs::create_directories(path); }
  ~TempDir() { fs::remove_all(path); }
};

void write_step(const TopoDS_Shape& shape, const fs::path& file, const char* unit = "MM") {
  // The STEP parameters exist once the controller is initialised; the unit must be set before the
  // writer is made (it takes its model's unit then).
  STEPControl_Controller::Init();
  ASSERT_TRUE(Interface_Static::SetCVal("write.step.unit", unit));
  STEPControl_Writer writer;
  ASSERT_EQ(writer.Transfer(shape, STEPControl_AsIs), IFSelect_RetDone);
  ASSERT_EQ(writer.Write(file.c_str()), IFSelect_RetDone);
  Interface_Static::SetCVal("write.step.unit", "MM");
}

// Volume enclosed by the mesh (divergence theorem): positive when the triangles face outwards.
double volume(const Mesh& m) {
  double v = 0;
  for (const auto& t : m.triangles) {
    const cv::Vec3d a = m.vertices[t[0]], b = m.vertices[t[1]], c = m.vertices[t[2]];
    v += a.dot(b.cross(c)) / 6.0;
  }
  return v;
}

TopoDS_Shape cylinder_with_hole(double R, double r, double h) {
  const TopoDS_Shape outer = BRepPrimAPI_MakeCylinder(R, h).Shape();
  const TopoDS_Shape hole = BRepPrimAPI_MakeCylinder(gp_Ax2(gp_Pnt(0, 0, -1), gp_Dir(0, 0, 1)), r, h + 2).Shape();
  BRepAlgoAPI_Cut cut(outer, hole);
  cut.Build();
  return cut.Shape();
}

}  // namespace

TEST(CadReader, StepBoxIsClosedOutwardAndExact) {
  TempDir tmp;
  write_step(BRepPrimAPI_MakeBox(30, 20, 10).Shape(), tmp.path / "box.step");
  MeshReport report;
  const Mesh m = load_part(tmp.path / "box.step", {}, &report);
  EXPECT_EQ(report.open_edges, 0u) << "faces share their edges' vertices: watertight after welding";
  EXPECT_EQ(report.non_manifold_edges, 0u);
  EXPECT_EQ(m.vertices.size(), 8u);
  EXPECT_EQ(m.triangles.size(), 12u);
  EXPECT_EQ(m.bbox_min(), cv::Vec3f(0, 0, 0));
  EXPECT_EQ(m.bbox_max(), cv::Vec3f(30, 20, 10));
  EXPECT_NEAR(volume(m), 6000.0, 1e-3) << "outward triangles (reversed faces turned)";
}

TEST(CadReader, CylinderWithAHoleKeepsTheChordalTolerance) {
  TempDir tmp;
  const double R = 10, r = 4, h = 20;
  write_step(cylinder_with_hole(R, r, h), tmp.path / "bushing.STP");  // any case of the extension
  for (const double tol : {0.05, 0.5}) {
    MeshLoadOptions o;
    o.tessellation.chordal_tolerance_mm = tol;
    o.tessellation.angular_tolerance_deg = 90;  // the chordal tolerance alone decides
    MeshReport report;
    const Mesh m = load_part(tmp.path / "bushing.STP", o, &report);
    EXPECT_EQ(report.open_edges, 0u) << "tolerance " << tol;
    const double exact = M_PI * (R * R - r * r) * h;
    // Chords lie inside the outer wall and outside the hole's: the mesh's volume is smaller, by at
    // most the tolerance times the walls' area.
    const double bound = tol * 2 * M_PI * (R + r) * h + 1e-3;
    EXPECT_LT(volume(m), exact) << "tolerance " << tol;
    EXPECT_GT(volume(m), exact - bound) << "tolerance " << tol;
    // Every outer-wall triangle's centroid within the tolerance of the surface it stands for.
    double worst = 0;
    for (const auto& t : m.triangles) {
      bool outer = true;
      for (int k = 0; k < 3; ++k)
        outer = outer && std::abs(std::hypot(m.vertices[t[k]][0], m.vertices[t[k]][1]) - R) < 1e-3;
      if (!outer) continue;
      const cv::Vec3d c =
          (cv::Vec3d(m.vertices[t[0]]) + cv::Vec3d(m.vertices[t[1]]) + cv::Vec3d(m.vertices[t[2]])) / 3.0;
      worst = std::max(worst, R - std::hypot(c[0], c[1]));
    }
    EXPECT_LE(worst, tol + 1e-4) << "tolerance " << tol;
    std::printf(
        "[ figures  ] chordal tolerance %.2f mm: %zu triangles, volume %.1f of %.1f mm^3, worst centroid %.4f mm\n",
        tol, m.triangles.size(), volume(m), exact, worst);
  }
}

TEST(CadReader, AnAssemblyOfTwoSolidsKeepsTheirPlacements) {
  TempDir tmp;
  gp_Trsf moved;
  moved.SetTranslation(gp_Vec(50, 0, 5));
  TopoDS_Compound both;
  BRep_Builder b;
  b.MakeCompound(both);
  b.Add(both, BRepPrimAPI_MakeBox(10, 10, 10).Shape());
  b.Add(both, BRepBuilderAPI_Transform(cylinder_with_hole(6, 2, 8), moved).Shape());
  write_step(both, tmp.path / "assembly.step");
  MeshReport report;
  const Mesh m = load_part(tmp.path / "assembly.step", {}, &report);
  EXPECT_EQ(report.open_edges, 0u);
  EXPECT_NEAR(m.bbox_min()[0], 0, 1e-4);
  EXPECT_NEAR(m.bbox_max()[0], 56, 1e-4) << "the second solid at x = 50, radius 6";
  EXPECT_NEAR(m.bbox_max()[2], 13, 1e-4);
  EXPECT_NEAR(volume(m), 1000 + M_PI * (36 - 4) * 8, 0.02 * M_PI * (36 - 4) * 8);
}

TEST(CadReader, UnitsComeFromTheFile) {
  TempDir tmp;
  write_step(BRepPrimAPI_MakeBox(25.4, 50.8, 12.7).Shape(), tmp.path / "inch.step", "INCH");
  std::ifstream in(tmp.path / "inch.step");
  std::stringstream text;
  text << in.rdbuf();
  ASSERT_NE(text.str().find("INCH"), std::string::npos) << "the file is written in inches";
  const Mesh m = load_part(tmp.path / "inch.step");
  EXPECT_NEAR(m.bbox_max()[0], 25.4, 1e-3);
  EXPECT_NEAR(m.bbox_max()[1], 50.8, 1e-3);
  EXPECT_NEAR(m.bbox_max()[2], 12.7, 1e-3);
  MeshLoadOptions o;
  o.unit_mm = 25.4;
  try {
    load_part(tmp.path / "inch.step", o);
    ADD_FAILURE() << "a unit given for a STEP file was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("carries its own length unit"), std::string::npos) << e.what();
  }
}

TEST(CadReader, LoadMeshPointsToLoadPart) {
  TempDir tmp;
  write_step(BRepPrimAPI_MakeBox(5, 5, 5).Shape(), tmp.path / "box.step");
  try {
    load_mesh(tmp.path / "box.step");
    ADD_FAILURE() << "load_mesh read a STEP file";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("load_part"), std::string::npos) << e.what();
  }
}

TEST(CadReader, IgesToo) {
  TempDir tmp;
  IGESControl_Controller::Init();
  IGESControl_Writer writer("MM", 1);
  writer.AddShape(BRepPrimAPI_MakeBox(12, 8, 4).Shape());
  writer.ComputeModel();
  ASSERT_TRUE(writer.Write((tmp.path / "box.igs").c_str()));
  const Mesh m = load_part(tmp.path / "box.igs");
  EXPECT_NEAR(m.bbox_max()[0], 12, 1e-4);
  EXPECT_NEAR(std::abs(volume(m)), 12 * 8 * 4, 1e-2);
}

TEST(CadReader, MalformedFilesAreRefusedWithTheReason) {
  TempDir tmp;
  const auto refused = [&](const std::string& name, const std::string& content, const std::string& why) {
    std::ofstream(tmp.path / name) << content;
    try {
      load_part(tmp.path / name);
      ADD_FAILURE() << name << " was read";
    } catch (const std::runtime_error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find((tmp.path / name).string()), std::string::npos) << what;
      EXPECT_NE(what.find(why), std::string::npos) << what;
    }
  };
  refused("text.step", "solid cube\nfacet normal 0 0 1\nendsolid\n", "cannot read as STEP");
  refused("truncated.step", "ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION(('x'),'2;1');\n", "cannot read as STEP");
  refused("empty.stp", "", "cannot read as STEP");
  // A well-formed file with no geometry: header and an empty data section.
  refused("nothing.step",
          "ISO-10303-21;\nHEADER;\nFILE_DESCRIPTION((''),'2;1');\nFILE_NAME('n','',(''),(''),'','','');\n"
          "FILE_SCHEMA(('AUTOMOTIVE_DESIGN'));\nENDSEC;\nDATA;\nENDSEC;\nEND-ISO-10303-21;\n",
          "no shape");
  refused("garbage.igs", std::string(400, 'x'), "IGES");
}
