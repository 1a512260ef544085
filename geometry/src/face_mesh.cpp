#include "dtis/geometry/face_mesh.hpp"

#include <BRepBuilderAPI_Copy.hxx>
#include <BRepMesh_IncrementalMesh.hxx>
#include <BRep_Tool.hxx>
#include <Poly_Triangulation.hxx>
#include <TopLoc_Location.hxx>
#include <TopoDS.hxx>
#include <algorithm>
#include <cmath>

#include "dtis/core/error.hpp"
#include "dtis/geometry/face_surface.hpp"

namespace dtis::geometry {

FaceMesh MeshFace(const TopoDS_Face& face, const std::string& where,
                  const FaceMeshOptions& options) {
  const auto [lo, hi] = FaceBox(face);
  const double diagonal = (hi - lo).norm();
  double deflection = std::max(1e-6, options.relative_deflection * diagonal);
  for (;;) {
    // A copy of the geometry without its triangulation: meshing writes into the shape it meshes.
    const TopoDS_Face copy = TopoDS::Face(BRepBuilderAPI_Copy(face, true, false).Shape());
    const BRepMesh_IncrementalMesh mesher(copy, deflection, false, options.angle_deg * M_PI / 180.0,
                                          false);
    TopLoc_Location location;
    const Handle(Poly_Triangulation)& tri = BRep_Tool::Triangulation(copy, location);
    if (tri.IsNull() || tri->NbTriangles() == 0) {
      throw Error("{}: OpenCASCADE made no triangles of the face (deflection {:g} mm)", where,
                  deflection);
    }
    if (tri->NbTriangles() > options.max_triangles && deflection < diagonal) {
      deflection *= 2.0;
      continue;
    }
    FaceMesh mesh;
    mesh.deflection_mm = deflection;
    const gp_Trsf& trsf = location.Transformation();
    mesh.vertices.reserve(static_cast<std::size_t>(tri->NbNodes()));
    for (int i = 1; i <= tri->NbNodes(); ++i) {
      const gp_Pnt p = tri->Node(i).Transformed(trsf);
      mesh.vertices.emplace_back(p.X(), p.Y(), p.Z());
    }
    mesh.triangles.reserve(static_cast<std::size_t>(tri->NbTriangles()));
    for (int i = 1; i <= tri->NbTriangles(); ++i) {
      int a = 0, b = 0, c = 0;
      tri->Triangle(i).Get(a, b, c);
      mesh.triangles.push_back({a - 1, b - 1, c - 1});
    }
    return mesh;
  }
}

FaceMesh MeshFaces(const std::vector<NamedFace>& faces, const FaceMeshOptions& options) {
  FaceMesh all;
  for (const NamedFace& f : faces) {
    const FaceMesh one = MeshFace(f.face, f.where, options);
    const int base = static_cast<int>(all.vertices.size());
    all.vertices.insert(all.vertices.end(), one.vertices.begin(), one.vertices.end());
    for (const auto& t : one.triangles)
      all.triangles.push_back({t[0] + base, t[1] + base, t[2] + base});
    all.deflection_mm = std::max(all.deflection_mm, one.deflection_mm);
  }
  return all;
}

}  // namespace dtis::geometry
