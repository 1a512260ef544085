#include "face_with_holes.hpp"

#include <fmt/format.h>
#include <unistd.h>

#include <BRepBuilderAPI_MakeEdge.hxx>
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepBuilderAPI_MakePolygon.hxx>
#include <BRepBuilderAPI_MakeWire.hxx>
#include <BRepLib.hxx>
#include <Geom2d_Circle.hxx>
#include <Geom_BSplineSurface.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Face.hxx>
#include <TopoDS_Wire.hxx>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <gp_Circ2d.hxx>
#include <gp_Cylinder.hxx>
#include <gp_Pln.hxx>
#include <stdexcept>
#include <utility>
#include <vector>

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

// The wavy ruled face with its two holes.
TopoDS_Face FaceWithHoles() {
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
  return face.Face();
}

// This process's folder for the files (removed at exit).
std::filesystem::path MakeFolder() {
  if (Folder().empty()) {
    Folder() = std::filesystem::temp_directory_path() / fmt::format("dtis_bench_{}", getpid());
    std::filesystem::create_directories(Folder());
    std::atexit(RemoveFolder);
  }
  return Folder();
}

// The job on `step` (face `face`, "" for the only one): plane_cl, 1 mm ball, stepover 3 mm.
std::string WriteJob(const std::string& name, const std::string& step, const std::string& face) {
  const std::string job = (MakeFolder() / (name + ".toml")).string();
  std::ofstream(job) << fmt::format(R"(name = "{}"
machine = "{}/samples/machines/mikron_ucp710_xyz.toml"
period_ms = 1.0
feed_mm_min = 3000

[surface]
file = "{}"
{}

[tool]
kind = "ball_end"
radius_mm = 1

[strategy]
kind = "plane_cl"
plane_normal = [1, 0, 0]
direction = [0, 1, 0]
stepover_mm = 3
)",
                                    name, DTIS_SOURCE_DIR, step, face);
  return job;
}

}  // namespace

std::string WriteFaceWithHolesJob() {
  const std::string step = (MakeFolder() / "wavy_with_holes.stp").string();
  test::WriteStep(FaceWithHoles(), step);
  return WriteJob("wavy_with_holes", "wavy_with_holes.stp", "");
}

std::string WriteFaceWithHolesAmongOthersJob() {
  // The face with holes first, named for the job; the others unnamed.
  std::vector<std::pair<TopoDS_Face, std::string>> faces = {{FaceWithHoles(), "with_holes"}};
  const auto add = [&](const TopoDS_Face& face) { faces.emplace_back(face, ""); };
  // A pin in each hole: hole centres at x = 18 and 42, y = 30 (u = 0.3, 0.7; v = 0.5).
  for (const double x : {18.0, 42.0}) {
    const gp_Cylinder pin(gp_Ax3(gp_Pnt(x, 30.0, -10.0), gp_Dir(0, 0, 1)), 4.0);
    add(BRepBuilderAPI_MakeFace(pin, 0.0, 2.0 * M_PI, 0.0, 20.0).Face());
  }
  // Walls standing at the sides, from z = -5 to 10, just outside the face.
  const auto wall = [&](double x0, double y0, double x1, double y1) {
    BRepBuilderAPI_MakePolygon outline(gp_Pnt(x0, y0, -5), gp_Pnt(x1, y1, -5), gp_Pnt(x1, y1, 10),
                                       gp_Pnt(x0, y0, 10), Standard_True);
    add(BRepBuilderAPI_MakeFace(outline.Wire(), Standard_True).Face());
  };
  wall(-1, -0.01, 61, -0.01);
  wall(-1, 60.01, 61, 60.01);
  wall(-0.01, -1, -0.01, 61);
  wall(60.01, -1, 60.01, 61);
  // The part's top at z = 10, 220 x 140 mm, the pocket's opening cut out of it.
  const auto rectangle = [](double x0, double y0, double x1, double y1) {
    return BRepBuilderAPI_MakePolygon(gp_Pnt(x0, y0, 10), gp_Pnt(x1, y0, 10), gp_Pnt(x1, y1, 10),
                                      gp_Pnt(x0, y1, 10), Standard_True)
        .Wire();
  };
  BRepBuilderAPI_MakeFace top(rectangle(-70, -40, 150, 100), Standard_True);
  top.Add(TopoDS::Wire(rectangle(-0.01, -0.01, 60.01, 60.01).Reversed()));
  add(top.Face());
  // The boss grid on the top: 6 x 4 bosses of 3 mm radius, 10 mm apart, each a side and a top.
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 4; ++j) {
      const gp_Pnt base(80.0 + 10.0 * i, 15.0 + 10.0 * j, 10.0);
      const gp_Ax3 ax(base, gp_Dir(0, 0, 1));
      add(BRepBuilderAPI_MakeFace(gp_Cylinder(ax, 3.0), 0.0, 2.0 * M_PI, 0.0, 8.0).Face());
      const gp_Pln boss_top(gp_Ax3(gp_Pnt(base.X(), base.Y(), 18.0), gp_Dir(0, 0, 1)));
      add(BRepBuilderAPI_MakeFace(boss_top, -3.0, 3.0, -3.0, 3.0).Face());
    }
  }
  test::WriteNamedFaces(faces, (MakeFolder() / "among_others.stp").string());
  return WriteJob("wavy_with_holes_among_others", "among_others.stp", "face = \"with_holes\"");
}

}  // namespace dtis::bench
