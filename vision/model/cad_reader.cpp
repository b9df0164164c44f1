#include "vision/model/cad_reader.hpp"

#include <BRepMesh_IncrementalMesh.hxx>
#include <BRep_Tool.hxx>
#include <IFSelect_ReturnStatus.hxx>
#include <IGESControl_Reader.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <Message_Printer.hxx>
#include <Poly_Triangulation.hxx>
#include <STEPControl_Reader.hxx>
#include <Standard_Failure.hxx>
#include <TopExp_Explorer.hxx>
#include <TopLoc_Location.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Face.hxx>
#include <TopoDS_Shape.hxx>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <mutex>
#include <stdexcept>
#include <string>

namespace mfcd::vision {

namespace {

std::string lower_extension(const std::filesystem::path& file) {
  std::string ext = file.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext;
}

// OCCT reports through one global messenger, to stdout by default. While a file is read its
// printers are set aside and the warnings and failures collected, for the error message.
class Collector : public Message_Printer {
 public:
  mutable std::string text;

 protected:
  void send(const TCollection_AsciiString& s, const Message_Gravity gravity) const override {
    if (gravity < Message_Warning || text.size() > 1000) return;
    std::string line = s.ToCString();
    while (!line.empty() && (line.back() == '\n' || line.back() == ' ')) line.pop_back();
    if (!line.empty()) text += (text.empty() ? "" : "; ") + line;
  }
};

class CaptureMessages {
 public:
  CaptureMessages() : collector_(new Collector) {
    const Handle(Message_Messenger)& m = Message::DefaultMessenger();
    saved_ = m->Printers();
    m->ChangePrinters().Clear();
    m->AddPrinter(collector_);
  }
  ~CaptureMessages() { Message::DefaultMessenger()->ChangePrinters() = saved_; }
  CaptureMessages(const CaptureMessages&) = delete;
  CaptureMessages& operator=(const CaptureMessages&) = delete;
  // ": what OCCT said", or nothing.
  std::string said() const { return collector_->text.empty() ? "" : " (OCCT: " + collector_->text + ")"; }

 private:
  Handle(Collector) collector_;
  Message_SequenceOfPrinters saved_;
};

const char* status_text(IFSelect_ReturnStatus s) {
  switch (s) {
    case IFSelect_RetVoid:
      return "nothing in it";
    case IFSelect_RetDone:
      return "read";
    case IFSelect_RetError:
      return "not a file of this format, or its header is malformed";
    case IFSelect_RetFail:
      return "the reader failed on its content";
    case IFSelect_RetStop:
      return "the reader stopped";
  }
  return "unknown reader status";
}

// Every shape of the file as one, in OCCT's session unit (millimetres: the readers convert the
// file's own length unit).
template <typename Reader>
TopoDS_Shape read_shape(const std::filesystem::path& file, const char* format, const CaptureMessages& messages) {
  Reader reader;
  const IFSelect_ReturnStatus status = reader.ReadFile(file.c_str());
  if (status != IFSelect_RetDone)
    throw std::runtime_error(file.string() + ": cannot read as " + format + ": " + status_text(status) +
                             messages.said());
  if (reader.TransferRoots() == 0)
    throw std::runtime_error(file.string() + ": the " + std::string(format) +
                             " file holds no shape that can be transferred");
  TopoDS_Shape shape = reader.OneShape();
  if (shape.IsNull()) throw std::runtime_error(file.string() + ": the " + std::string(format) + " file holds no shape");
  return shape;
}

// The triangles of every face, placed by the face's location; reversed faces turned so every
// triangle is counter-clockwise seen from outside the solid.
void append_faces(const TopoDS_Shape& shape, Mesh& out) {
  for (TopExp_Explorer e(shape, TopAbs_FACE); e.More(); e.Next()) {
    const TopoDS_Face& face = TopoDS::Face(e.Current());
    TopLoc_Location where;
    const Handle(Poly_Triangulation) tri = BRep_Tool::Triangulation(face, where);
    if (tri.IsNull()) continue;
    const gp_Trsf placement = where.Transformation();
    if (out.vertices.size() + static_cast<std::size_t>(tri->NbNodes()) > std::numeric_limits<uint32_t>::max())
      throw std::runtime_error("more than 2^32 vertices");
    const auto base = static_cast<uint32_t>(out.vertices.size());
    for (int i = 1; i <= tri->NbNodes(); ++i) {
      const gp_Pnt p = tri->Node(i).Transformed(placement);
      out.vertices.emplace_back(static_cast<float>(p.X()), static_cast<float>(p.Y()), static_cast<float>(p.Z()));
    }
    const bool reversed = face.Orientation() == TopAbs_REVERSED;
    for (int i = 1; i <= tri->NbTriangles(); ++i) {
      int a = 0, b = 0, c = 0;
      tri->Triangle(i).Get(a, b, c);
      if (reversed) std::swap(b, c);
      out.triangles.push_back({base + static_cast<uint32_t>(a - 1), base + static_cast<uint32_t>(b - 1),
                               base + static_cast<uint32_t>(c - 1)});
    }
  }
}

}  // namespace

bool is_cad_file(const std::filesystem::path& file) {
  const std::string ext = lower_extension(file);
  return ext == ".step" || ext == ".stp" || ext == ".iges" || ext == ".igs";
}

Mesh read_cad(const std::filesystem::path& file, const CadTessellation& t) {
  if (!(t.chordal_tolerance_mm > 0) || !std::isfinite(t.chordal_tolerance_mm) || !(t.angular_tolerance_deg > 0) ||
      !(t.angular_tolerance_deg <= 90))
    throw std::runtime_error(file.string() +
                             ": the chordal tolerance must be > 0 mm and the angular one in (0, 90] degrees");
  const std::string ext = lower_extension(file);
  Mesh mesh;
  mesh.name = file.stem().string();
  static std::mutex one_at_a_time;  // the messenger is global
  const std::lock_guard lock(one_at_a_time);
  const CaptureMessages messages;
  try {
    const TopoDS_Shape shape = ext == ".step" || ext == ".stp" ? read_shape<STEPControl_Reader>(file, "STEP", messages)
                                                               : read_shape<IGESControl_Reader>(file, "IGES", messages);
    // Absolute chordal deflection in mm; the angular one in radians.
    BRepMesh_IncrementalMesh mesher(shape, t.chordal_tolerance_mm, false, t.angular_tolerance_deg * M_PI / 180.0,
                                    false);
    if (!mesher.IsDone()) throw std::runtime_error(file.string() + ": OCCT could not tessellate the shape");
    append_faces(shape, mesh);
  } catch (const Standard_Failure& f) {
    throw std::runtime_error(file.string() + ": OCCT: " + (f.GetMessageString() ? f.GetMessageString() : "failure"));
  }
  if (mesh.triangles.empty())
    throw std::runtime_error(file.string() + ": the file's shapes have no faces to tessellate (wires or points only?)");
  return mesh;
}

Mesh load_part(const std::filesystem::path& file, const MeshLoadOptions& options, MeshReport* report) {
  if (!is_cad_file(file)) return load_mesh(file, options, report);
  const std::string src = file.string();
  if (!std::filesystem::exists(file)) throw std::runtime_error(src + ": no such file");
  // A CAD exchange file states its length unit; OCCT converts to millimetres.
  if (options.unit_mm != 1.0)
    throw std::runtime_error(src + ": a STEP or IGES file carries its own length unit; give no other unit for it");
  return finish_loading(read_cad(file, options.tessellation), options, report, src);
}

}  // namespace mfcd::vision
