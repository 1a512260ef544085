#include "face_with_holes.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <BRepBuilderAPI_MakeEdge.hxx>
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepBuilderAPI_MakeWire.hxx>
#include <BRepLib.hxx>
#include <Geom2d_Circle.hxx>
#include <GeomAPI_PointsToBSpline.hxx>
#include <Geom_BSplineCurve.hxx>
#include <Geom_BSplineSurface.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <STEPControl_Writer.hxx>
#include <TColStd_Array1OfInteger.hxx>
#include <TColStd_Array1OfReal.hxx>
#include <TColgp_Array1OfPnt.hxx>
#include <TColgp_Array2OfPnt.hxx>
#include <TopoDS_Face.hxx>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <gp_Circ2d.hxx>
#include <numbers>
#include <stdexcept>

namespace dtis::bench {
namespace {

// The ruled surface between two waves along y at x = 0 and x = 60, a third of a period apart.
Handle(Geom_BSplineSurface) WavySurface() {
  Handle(Geom_BSplineCurve) wave[2];
  for (int k = 0; k < 2; ++k) {
    constexpr int kPoints = 41;
    TColgp_Array1OfPnt points(1, kPoints);
    for (int i = 1; i <= kPoints; ++i) {
      const double y = 60.0 * (i - 1) / (kPoints - 1);
      points(i) =
          gp_Pnt(60.0 * k, y,
                 3.0 * std::sin(2.0 * std::numbers::pi * y / 30.0 + k * std::numbers::pi / 3));
    }
    wave[k] = GeomAPI_PointsToBSpline(points, 3, 3, GeomAbs_C2, 1e-4).Curve();
  }
  const int n = wave[0]->NbPoles();
  TColgp_Array2OfPnt poles(1, 2, 1, n);
  for (int k = 0; k < 2; ++k) {
    for (int i = 1; i <= n; ++i) poles(k + 1, i) = wave[k]->Pole(i);
  }
  TColStd_Array1OfReal u_knots(1, 2), v_knots(1, wave[0]->NbKnots());
  TColStd_Array1OfInteger u_mults(1, 2), v_mults(1, wave[0]->NbKnots());
  u_knots(1) = 0.0, u_knots(2) = 1.0, u_mults(1) = u_mults(2) = 2;
  wave[0]->Knots(v_knots);
  wave[0]->Multiplicities(v_mults);
  return new Geom_BSplineSurface(poles, u_knots, v_knots, u_mults, v_mults, 1, 3);
}

std::filesystem::path& Folder() {
  static std::filesystem::path folder;
  return folder;
}

void RemoveFolder() {
  std::error_code ignored;
  std::filesystem::remove_all(Folder(), ignored);
}

}  // namespace

std::string WriteFaceWithHolesJob() {
  const Handle(Geom_BSplineSurface) surface = WavySurface();
  BRepBuilderAPI_MakeFace face(surface, 1e-7);
  // Each hole a circle in (u, v) (u across 60 mm, v along about 60 mm), clockwise: inside the
  // face's outer loop.
  for (const double u : {0.3, 0.7}) {
    const gp_Circ2d circle(gp_Ax2d(gp_Pnt2d(u, 0.5), gp_Dir2d(1, 0)), 0.1, Standard_False);
    TopoDS_Edge edge = BRepBuilderAPI_MakeEdge(new Geom2d_Circle(circle), surface).Edge();
    BRepLib::BuildCurves3d(edge);
    face.Add(BRepBuilderAPI_MakeWire(edge).Wire());
  }
  if (!face.IsDone()) throw std::runtime_error("the face with holes could not be made");
  Folder() = std::filesystem::temp_directory_path() / fmt::format("dtis_bench_{}", getpid());
  std::filesystem::create_directories(Folder());
  std::atexit(RemoveFolder);
  const std::string step = (Folder() / "wavy_with_holes.stp").string();
  const Handle(Message_Messenger) messenger = Message::DefaultMessenger();
  const Message_SequenceOfPrinters printers = messenger->Printers();
  messenger->ChangePrinters().Clear();  // the writer's statistics
  STEPControl_Writer writer;
  const bool written = writer.Transfer(face.Face(), STEPControl_AsIs) == IFSelect_RetDone &&
                       writer.Write(step.c_str()) == IFSelect_RetDone;
  messenger->ChangePrinters() = printers;
  if (!written) throw std::runtime_error("could not write " + step);
  const std::string job = (Folder() / "wavy_with_holes.toml").string();
  std::ofstream(job) << fmt::format(R"(name = "wavy_with_holes"
machine = "{}/samples/machines/mikron_ucp710_xyz.toml"
period_ms = 1.0
feed_mm_min = 3000

[surface]
file = "wavy_with_holes.stp"

[tool]
kind = "ball_end"
radius_mm = 1

[strategy]
kind = "plane_cl"
plane_normal = [1, 0, 0]
direction = [0, 1, 0]
stepover_mm = 3
)",
                                    DTIS_SOURCE_DIR);
  return job;
}

}  // namespace dtis::bench
