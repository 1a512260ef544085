#include "face_with_holes.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <BRepBuilderAPI_MakeEdge.hxx>
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepBuilderAPI_MakeWire.hxx>
#include <BRepLib.hxx>
#include <Geom2d_Circle.hxx>
#include <Geom_BSplineSurface.hxx>
#include <TopoDS_Face.hxx>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <gp_Circ2d.hxx>
#include <stdexcept>

#include "fixture_shapes.hpp"

namespace dtis::bench {
namespace {

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
  const Handle(Geom_BSplineSurface) surface = test::WavyRuledSurface();
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
  test::WriteStep(face.Face(), step);
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
