#include "dtis/geometry/step_model.hpp"

#include <fmt/format.h>

#include <BRepAdaptor_Surface.hxx>
#include <BRepGProp.hxx>
#include <BRepTools.hxx>
#include <BRep_Tool.hxx>
#include <GProp_GProps.hxx>
#include <IFSelect_ReturnStatus.hxx>
#include <Interface_InterfaceModel.hxx>
#include <Interface_Static.hxx>
#include <STEPControl_Reader.hxx>
#include <Standard_Failure.hxx>
#include <StepShape_Face.hxx>
#include <TCollection_HAsciiString.hxx>
#include <TopExp_Explorer.hxx>
#include <TopTools_IndexedMapOfShape.hxx>
#include <TopoDS.hxx>
#include <TransferBRep.hxx>
#include <XSControl_TransferReader.hxx>
#include <XSControl_WorkSession.hxx>
#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <tuple>

#include "dtis/core/error.hpp"
#include "dtis/core/file_text.hpp"
#include "dtis/geometry/face_surface.hpp"

namespace dtis::geometry {
namespace {

// OpenCASCADE's STEP reader crashes on some STEP-NC (ISO 14649) files, whose schemas hold no part
// geometry it knows: check the header first, and name the schema in the error.
void CheckHeader(const std::string& path) {
  RequireRegularFile(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) throw Error("{}: cannot open the file", path);
  std::string head(65536, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  if (head.find("ISO-10303-21") == std::string::npos) {
    throw Error("{}: not a STEP file (no 'ISO-10303-21;' header); expected a STEP part file", path);
  }
  const auto at = head.find("FILE_SCHEMA");
  if (at == std::string::npos) throw Error("{}: the STEP header has no FILE_SCHEMA", path);
  const auto open = head.find('\'', at), close = head.find('\'', open + 1);
  std::string schema = open == std::string::npos || close == std::string::npos
                           ? std::string()
                           : head.substr(open + 1, close - open - 1);
  std::string upper = schema;
  std::transform(upper.begin(), upper.end(), upper.begin(),
                 [](unsigned char c) { return static_cast<char>(std::toupper(c)); });
  for (const char* known : {"AUTOMOTIVE_DESIGN", "CONFIG_CONTROL_DESIGN", "AP203", "AP214", "AP242",
                            "AP209", "STRUCTURAL_ANALYSIS_DESIGN"}) {
    if (upper.find(known) != std::string::npos) return;
  }
  throw Error(
      "{}: STEP schema '{}' holds no part geometry dtis reads; expected an AP203, AP214 or AP242 "
      "part file (a STEP-NC program such as ISO 14649 describes operations, not the surface)",
      path, schema);
}

const char* SurfaceTypeName(GeomAbs_SurfaceType type) {
  switch (type) {
    case GeomAbs_Plane:
      return "plane";
    case GeomAbs_Cylinder:
      return "cylinder";
    case GeomAbs_Cone:
      return "cone";
    case GeomAbs_Sphere:
      return "sphere";
    case GeomAbs_Torus:
      return "torus";
    case GeomAbs_BezierSurface:
      return "bezier";
    case GeomAbs_BSplineSurface:
      return "bspline";
    case GeomAbs_SurfaceOfRevolution:
      return "revolution";
    case GeomAbs_SurfaceOfExtrusion:
      return "extrusion";
    case GeomAbs_OffsetSurface:
      return "offset";
    default:
      return "other";
  }
}

// A face is untrimmed when its only wire runs along the surface's natural parameter rectangle:
// every edge's pcurve is an iso-line at a bound of the surface.
bool IsTrimmed(const TopoDS_Face& face, const BRepAdaptor_Surface& s) {
  const double su0 = s.FirstUParameter(), su1 = s.LastUParameter();
  const double sv0 = s.FirstVParameter(), sv1 = s.LastVParameter();
  if (!std::isfinite(su0) || !std::isfinite(su1) || std::abs(su0) > 1e50 || std::abs(su1) > 1e50 ||
      std::abs(sv0) > 1e50 || std::abs(sv1) > 1e50) {
    return true;  // an infinite analytic surface is always bounded by a trim
  }
  return !BoundedByBox(face, su0, su1, sv0, sv1, 1e-7, 8);
}

FaceInfo Describe(int index, const TopoDS_Face& face) {
  FaceInfo info;
  info.index = index;
  BRepAdaptor_Surface s(face, Standard_False);
  info.type = SurfaceTypeName(s.GetType());
  if (s.GetType() == GeomAbs_BSplineSurface || s.GetType() == GeomAbs_BezierSurface) {
    info.u_degree = s.UDegree();
    info.v_degree = s.VDegree();
    info.u_poles = s.NbUPoles();
    info.v_poles = s.NbVPoles();
    info.rational = s.IsURational() || s.IsVRational();
  }
  BRepTools::UVBounds(face, info.u0, info.u1, info.v0, info.v1);
  info.trimmed = IsTrimmed(face, s);
  std::tie(info.box_min, info.box_max) = FaceBox(face);
  GProp_GProps props;
  BRepGProp::SurfaceProperties(face, props);
  info.area_mm2 = props.Mass();
  for (TopExp_Explorer w(face, TopAbs_WIRE); w.More(); w.Next()) ++info.holes;
  info.holes = std::max(0, info.holes - 1);
  return info;
}

// Where a face lies on its surface: its (u, v) bounds and the point at their middle.
struct FacePlace {
  std::array<double, 4> uv{};
  gp_Pnt middle;
};

FacePlace PlaceOf(const TopoDS_Face& face) {
  FacePlace p;
  BRepTools::UVBounds(face, p.uv[0], p.uv[1], p.uv[2], p.uv[3]);
  p.middle = BRepAdaptor_Surface(face).Value(0.5 * (p.uv[0] + p.uv[1]), 0.5 * (p.uv[2] + p.uv[3]));
  return p;
}

bool SamePlace(const FacePlace& a, const FacePlace& b) {
  for (std::size_t k = 0; k < 4; ++k) {
    if (std::abs(a.uv[k] - b.uv[k]) > 1e-9 * (1.0 + std::abs(a.uv[k]))) return false;
  }
  return a.middle.Distance(b.middle) < 1e-7;
}

// Each face's name: that of the STEP face entity it was read from (ADVANCED_FACE('name', ...)),
// or empty. The reader records which shape each entity became; where its shape healing then
// rebuilt a face (as it does to the faces of a surface model), the face that has the entity's
// (u, v) bounds and the same point at their middle carries its name.
std::vector<std::string> FaceNames(const STEPControl_Reader& reader,
                                   const std::vector<TopoDS_Face>& faces) {
  std::vector<std::string> names(faces.size());
  const Handle(XSControl_TransferReader) transfer = reader.WS()->TransferReader();
  const Handle(Interface_InterfaceModel) entities = reader.WS()->Model();
  if (transfer.IsNull() || entities.IsNull()) return names;
  std::vector<std::pair<TopoDS_Face, std::string>> named;
  for (int i = 1; i <= entities->NbEntities(); ++i) {
    const auto entity = Handle(StepShape_Face)::DownCast(entities->Value(i));
    if (entity.IsNull() || entity->Name().IsNull() || entity->Name()->Length() == 0) continue;
    const TopoDS_Shape shape = TransferBRep::ShapeResult(transfer->TransientProcess(), entity);
    if (shape.IsNull() || shape.ShapeType() != TopAbs_FACE) continue;
    named.emplace_back(TopoDS::Face(shape), entity->Name()->ToCString());
  }
  if (named.empty()) return names;
  std::vector<std::size_t> unmatched;
  for (std::size_t k = 0; k < faces.size(); ++k) {
    const auto same = std::find_if(named.begin(), named.end(),
                                   [&](const auto& n) { return n.first.IsSame(faces[k]); });
    if (same != named.end()) {
      names[k] = same->second;
    } else {
      unmatched.push_back(k);
    }
  }
  if (unmatched.empty()) return names;
  std::vector<FacePlace> places;
  for (const auto& n : named) places.push_back(PlaceOf(n.first));
  for (const std::size_t k : unmatched) {
    const FacePlace here = PlaceOf(faces[k]);
    for (std::size_t n = 0; n < named.size(); ++n) {
      if (SamePlace(here, places[n])) {
        names[k] = named[n].second;
        break;
      }
    }
  }
  return names;
}

// STEPControl_Reader's static parameters are process-wide.
std::mutex& ReaderMutex() {
  static std::mutex m;
  return m;
}

}  // namespace

StepModel StepModel::Load(const std::string& path) {
  RequireRegularFile(path);  // a folder, a FIFO, a device, a loop of links: said what it is
  std::error_code ec;
  if (!std::filesystem::exists(path, ec)) throw Error("{}: no such file", path);
  CheckHeader(path);
  StepModel model;
  model.file_ = path;
  try {
    std::lock_guard lock(ReaderMutex());
    Interface_Static::SetCVal("xstep.cascade.unit", "MM");
    STEPControl_Reader reader;
    if (reader.ReadFile(path.c_str()) != IFSelect_RetDone) {
      throw Error("{}: OpenCASCADE could not parse this STEP file", path);
    }
    if (reader.TransferRoots() == 0) throw Error("{}: no shape could be read from the file", path);
    model.shape_ = reader.OneShape();
    for (TopExp_Explorer e(model.shape_, TopAbs_FACE); e.More(); e.Next()) {
      model.faces_.push_back(TopoDS::Face(e.Current()));
    }
    // The faces that bound a solid or a closed shell: their orientation there says where the
    // material is.
    TopTools_IndexedMapOfShape bounding;
    for (TopExp_Explorer e(model.shape_, TopAbs_SHELL); e.More(); e.Next()) {
      bool closed = BRep_Tool::IsClosed(e.Current());
      for (TopExp_Explorer s(model.shape_, TopAbs_SOLID); s.More() && !closed; s.Next()) {
        for (TopExp_Explorer in(s.Current(), TopAbs_SHELL); in.More() && !closed; in.Next()) {
          closed = in.Current().IsSame(e.Current());
        }
      }
      if (!closed) continue;
      for (TopExp_Explorer f(e.Current(), TopAbs_FACE); f.More(); f.Next())
        bounding.Add(f.Current());
    }
    for (const TopoDS_Face& f : model.faces_) model.bounds_solid_.push_back(bounding.Contains(f));
    model.names_ = FaceNames(reader, model.faces_);
  } catch (const Standard_Failure& e) {
    throw Error("{}: OpenCASCADE failed reading the file: {}", path, e.GetMessageString());
  }
  if (model.faces_.empty()) throw Error("{}: the file holds no face", path);
  return model;
}

const TopoDS_Face& StepModel::Face(int index) const {
  if (index < 1 || index > FaceCount()) {
    throw Error(
        "{}: face {} does not exist; the file has faces 1 to {} (list them with `dtis faces "
        "{}`)",
        file_, index, FaceCount(), file_);
  }
  return faces_[static_cast<std::size_t>(index - 1)];
}

const std::string& StepModel::FaceName(int index) const {
  Face(index);  // the range check
  return names_[static_cast<std::size_t>(index - 1)];
}

bool StepModel::BoundsSolid(int index) const {
  Face(index);  // the range check
  return bounds_solid_[static_cast<std::size_t>(index - 1)];
}

std::vector<int> StepModel::FacesNamed(const std::string& name) const {
  std::vector<int> found;
  for (std::size_t k = 0; k < names_.size(); ++k) {
    if (names_[k] == name) found.push_back(static_cast<int>(k) + 1);
  }
  return found;
}

FaceInfo StepModel::Info(int index) const {
  FaceInfo info = Describe(index, Face(index));
  info.name = FaceName(index);
  return info;
}

std::vector<FaceInfo> StepModel::Infos() const {
  std::vector<FaceInfo> infos;
  for (int k = 1; k <= FaceCount(); ++k) infos.push_back(Info(k));
  return infos;
}

std::string FormatFaceTable(const StepModel& model) {
  std::string out = fmt::format("{}: {} face{}\n", model.File(), model.FaceCount(),
                                model.FaceCount() == 1 ? "" : "s");
  out += fmt::format(
      "{:>5}  {:<10} {:>7} {:>7}  {:<8} {:<7} {:>5}  {:>10}  {:<40}  {:<26}  {:<26}  {}\n", "face",
      "type", "degree", "poles", "rational", "trimmed", "holes", "area mm2", "uv bounds",
      "from mm (x y z)", "size mm (x y z)", "name");
  for (const FaceInfo& f : model.Infos()) {
    const std::string degree = f.u_degree ? fmt::format("{}x{}", f.u_degree, f.v_degree) : "-";
    const std::string poles = f.u_poles ? fmt::format("{}x{}", f.u_poles, f.v_poles) : "-";
    const std::string uv =
        fmt::format("[{:.6g}, {:.6g}] x [{:.6g}, {:.6g}]", f.u0, f.u1, f.v0, f.v1);
    const Eigen::Vector3d size = f.box_max - f.box_min;
    const std::string from =
        fmt::format("{:.6g} {:.6g} {:.6g}", f.box_min.x(), f.box_min.y(), f.box_min.z());
    const std::string extent = fmt::format("{:.4g} {:.4g} {:.4g}", size.x(), size.y(), size.z());
    out += fmt::format(
        "{:>5}  {:<10} {:>7} {:>7}  {:<8} {:<7} {:>5}  {:>10.6g}  {:<40}  {:<26}  {:<26}  {}\n",
        f.index, f.type, degree, poles, f.rational ? "yes" : "no", f.trimmed ? "yes" : "no",
        f.holes, f.area_mm2, uv, from, extent, f.name.empty() ? "-" : "'" + f.name + "'");
  }
  return out;
}

}  // namespace dtis::geometry
