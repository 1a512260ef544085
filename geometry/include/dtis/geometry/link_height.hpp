// How high the links between passes traverse: above the faces where the tool passes, by the
// clearance, instead of above their highest point everywhere.
//
// A link (LinkWaypoints) backs off along the tool axis by the clearance, rises, traverses in a
// straight line at one height, comes down above the next pass and approaches it. With the tool
// axis vertical at both ends, the tool's body lies within its radius R of its axis and above its
// tip, so the traverse clears the faces by the clearance when its tip is that far above their
// highest point within R (in X, Y) of the traverse: between neighbouring passes of a wavy face
// that is the crest between them, not the face's top. Where either axis is tilted the body
// reaches sideways by a length the job does not give (the holder's), and the traverse stays above
// the faces' highest point.
//
// The heights come from OpenCASCADE's triangulation of the faces: every point of a triangle lies
// within the mesh's deflection of its face, so the highest vertex of the triangles within R of the
// traverse, plus that deflection, bounds the faces there from above.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "dtis/core/pose.hpp"
#include "dtis/geometry/face_mesh.hpp"

namespace dtis::geometry {

class LinkHeights {
 public:
  // The faces as placed in the workpiece frame; the tool's radius and the links' clearance, mm.
  // Nothing is computed before the first link asks.
  LinkHeights(std::vector<NamedFace> faces, double tool_radius_mm, double clearance_mm);
  ~LinkHeights();

  // The height (Z, mm) the link from `from` to `to` traverses at: the clearance above the face
  // where the tool passes (both axes vertical), or above the face's highest point. Never below
  // the points the link backs off to. Thread-safe.
  double TraverseZ(const Pose& from, const Pose& to) const;

  double ClearanceMm() const { return clearance_mm_; }
  // The faces' highest point (their optimal bounding boxes' top), mm. Thread-safe.
  double TopZ() const;

 private:
  struct Data;
  const Data& Get() const;

  std::vector<NamedFace> faces_;
  double tool_radius_mm_, clearance_mm_;
  mutable std::once_flag once_;
  mutable std::unique_ptr<Data> data_;
};

}  // namespace dtis::geometry
