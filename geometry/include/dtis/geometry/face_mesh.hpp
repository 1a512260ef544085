// A face as triangles, for display: OpenCASCADE's own triangulation of it (BRepMesh), in the
// workpiece frame of the face as placed (PlaceFace), trimmed as the face is.
#pragma once

#include <Eigen/Core>
#include <TopoDS_Face.hxx>
#include <array>
#include <string>
#include <vector>

namespace dtis::geometry {

struct FaceMesh {
  std::vector<Eigen::Vector3d> vertices;      // mm
  std::vector<std::array<int, 3>> triangles;  // indices into `vertices`
  double deflection_mm = 0.0;                 // the chord deflection it was meshed with
};

struct FaceMeshOptions {
  // Largest distance from a triangle to the face, as a fraction of the face's bounding-box
  // diagonal.
  double relative_deflection = 2.5e-4;
  // Largest angle between the normals of neighbouring triangles (BRepMesh's angular deflection).
  double angle_deg = 5.0;
  // The mesh is made coarser (deflection doubled) until it has at most this many triangles.
  int max_triangles = 200000;
};

// Meshes a copy of `face`'s shape (the face given keeps no triangulation). Throws dtis::Error,
// naming `where` ("part.stp face 3"), when OpenCASCADE makes no triangles of it.
FaceMesh MeshFace(const TopoDS_Face& face, const std::string& where,
                  const FaceMeshOptions& options = {});

// A face as a job places it, and what errors call it ("part.stp face 3").
struct NamedFace {
  TopoDS_Face face;
  std::string where;
};

// The faces meshed one by one (MeshFace) into one mesh, whose deflection is the largest of theirs.
FaceMesh MeshFaces(const std::vector<NamedFace>& faces, const FaceMeshOptions& options = {});

}  // namespace dtis::geometry
