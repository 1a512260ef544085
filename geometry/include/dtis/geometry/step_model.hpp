// STEP import (OpenCASCADE's STEPControl_Reader): the faces of a part file, in file order, with
// what a CAM engineer needs to choose one. Lengths are converted to mm on reading.
#pragma once

#include <Eigen/Core>
#include <TopoDS_Face.hxx>
#include <TopoDS_Shape.hxx>
#include <string>
#include <vector>

namespace dtis::geometry {

struct FaceInfo {
  int index = 0;     // 1-based, in the order OpenCASCADE explores the shape
  std::string name;  // the name the file gives the face (its ADVANCED_FACE's), often ""
  std::string type;  // "bspline", "plane", "cylinder", "cone", "sphere", "torus", ...
  int u_degree = 0;  // B-spline and Bezier faces only (0 otherwise)
  int v_degree = 0;
  int u_poles = 0;
  int v_poles = 0;
  bool rational = false;
  bool trimmed = false;  // the face's boundary is not the surface's natural parameter rectangle
  double u0 = 0, u1 = 0, v0 = 0, v1 = 0;              // the face's UV bounds
  Eigen::Vector3d box_min = Eigen::Vector3d::Zero();  // axis-aligned bounding box, mm
  Eigen::Vector3d box_max = Eigen::Vector3d::Zero();
  double area_mm2 = 0.0;  // of the trimmed face
  int holes = 0;          // inner boundary loops
};

class StepModel {
 public:
  // Reads a STEP part file (AP203, AP214 or AP242 geometry). Throws dtis::Error naming the file
  // when it is missing, not STEP, a STEP-NC program without part geometry, or holds no face.
  static StepModel Load(const std::string& path);

  const std::string& File() const { return file_; }
  int FaceCount() const { return static_cast<int>(faces_.size()); }
  // 1-based; throws dtis::Error listing the valid range.
  const TopoDS_Face& Face(int index) const;
  // The name the file gives face `index` ("" when none).
  const std::string& FaceName(int index) const;
  // Whether face `index` bounds a solid (or a closed shell): its orientation there says which
  // side of it the material is on, and its outside is the side of its outward normal.
  bool BoundsSolid(int index) const;
  // The faces the file gives this name, in file order (CAD systems may give a name to several).
  std::vector<int> FacesNamed(const std::string& name) const;
  // What `dtis faces` lists, worked out when asked (the bounding box is an optimisation over the
  // surface, a millisecond or more per face: a job that plans one face does not pay it for all).
  FaceInfo Info(int index) const;
  std::vector<FaceInfo> Infos() const;

 private:
  std::string file_;
  TopoDS_Shape shape_;
  std::vector<TopoDS_Face> faces_;
  std::vector<std::string> names_;
  std::vector<bool> bounds_solid_;
};

// The table `dtis faces` prints.
std::string FormatFaceTable(const StepModel& model);

}  // namespace dtis::geometry
