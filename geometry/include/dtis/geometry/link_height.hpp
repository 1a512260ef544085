// How high the links between passes traverse: above the face where the tool passes, by the
// clearance, instead of above the face's highest point everywhere.
//
// A link (LinkWaypoints) backs off along the tool axis by the clearance, rises, traverses in a
// straight line at one height, comes down above the next pass and approaches it. With the tool
// axis vertical at both ends, the tool's body lies within its radius R of its axis and above its
// tip, so the traverse clears the face by the clearance when its tip is that far above the face's
// highest point within R (in X, Y) of the traverse: between neighbouring passes of a wavy face
// that is the crest between them, not the face's top. Where either axis is tilted the body
// reaches sideways by a length the job does not give (the holder's), and the traverse stays above
// the face's highest point, as before.
//
// The face's heights come from OpenCASCADE's triangulation of it: every point of a triangle lies
// within the mesh's deflection of the face, so the highest vertex of the triangles within R of the
// traverse, plus that deflection, bounds the face there from above.
#pragma once

#include <Eigen/Core>
#include <TopoDS_Face.hxx>
#include <memory>
#include <mutex>
#include <string>

#include "dtis/core/pose.hpp"
#include "dtis/geometry/face_mesh.hpp"

namespace dtis::geometry {

class LinkHeights {
 public:
  // `face` as placed in the workpiece frame, named `where` in errors; the tool's radius and the
  // links' clearance, mm. Nothing is computed before the first link asks.
  LinkHeights(const TopoDS_Face& face, std::string where, double tool_radius_mm,
              double clearance_mm);
  ~LinkHeights();

  // The height (Z, mm) the link from `from` to `to` traverses at: the clearance above the face
  // where the tool passes (both axes vertical), or above the face's highest point. Never below
  // the points the link backs off to. Thread-safe.
  double TraverseZ(const Pose& from, const Pose& to) const;

  double ClearanceMm() const { return clearance_mm_; }
  // The face's highest point (its optimal bounding box's top), mm. Thread-safe.
  double TopZ() const;

 private:
  struct Data;
  const Data& Get() const;

  TopoDS_Face face_;
  std::string where_;
  double tool_radius_mm_, clearance_mm_;
  mutable std::once_flag once_;
  mutable std::unique_ptr<Data> data_;
};

}  // namespace dtis::geometry
