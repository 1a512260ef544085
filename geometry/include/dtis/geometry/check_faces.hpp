// Whether the tool goes into faces it does not finish: the part's other faces (a wall beside the
// pass, a fillet and floor next to the face), which a pass planned against its own face alone
// would cut into.
//
// The tool is the solid of revolution of geometry/tool.hpp (a flat bottom of radius R, a corner
// of radius r, a cylinder of radius R + r above it) reaching `length_mm` up its axis from the tip
// (its holder included; unlimited by default). In the half-plane through the axis, with rho the
// distance from the axis and z the height above the tip, it is the union of the bottom's segment
// (0..R at z = r) widened by r and the rectangle rho <= R + r, r <= z <= length: the distance of a
// point to the tool's surface is a distance in that plane, in closed form.
//
// A face goes into the tool where one of its points lies inside the tool by more than the
// tolerance. Each face is sampled once, on a grid in (u, v) a quarter of the tool radius apart in
// space (at most 1 mm; wider on a face that would need more than a million samples), when a tool
// first comes near it. A face point inside the tool lies within the grid's covering radius c of
// a sample, and the distance to the tool changes by at most the distance moved, so every face
// that goes into the tool has a sample less than c outside it: from each such sample (the closest
// of each block of 16 x 16) the distance is minimised on the exact face (descent in (u, v),
// projected onto the face's UV box), and what is found inside is a hit. A descent stops at a
// trimming loop, so a trimmed face's loops are sampled too, a sixteenth of the grid's spacing
// apart. The faces' boxes, each face's blocks and its loops' blocks are held in hierarchies of
// boxes (built once per job, a face's when it is sampled): a check visits only those within
// reach of the tool.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "dtis/geometry/face_mesh.hpp"
#include "dtis/geometry/tool.hpp"

namespace dtis::geometry {

// Signed distance (mm) from the point at distance rho from the tool's axis and height z above its
// tip to the tool's surface: negative inside. `length` is the tool's reach up its axis.
double ToolSignedDistance(const Tool& tool, double length, double rho, double z);

class CheckFaces {
 public:
  struct Hit {
    double depth_mm = 0.0;  // how far the face point lies inside the tool
    Eigen::Vector3d at = Eigen::Vector3d::Zero();
    Eigen::Vector2d uv = Eigen::Vector2d::Zero();
    std::string where;  // the face ("part.stp face 4")
  };

  // The faces as placed in the workpiece frame, the tool, its reach up its axis (mm, infinite by
  // default) and how far a face may lie inside the tool before it counts (mm: STEP files join
  // faces within their edges' tolerance, so a neighbour sharing an edge with the finished face
  // may overlap it by that much). Nothing is sampled before a tool comes near a face.
  CheckFaces(std::vector<NamedFace> faces, const Tool& tool, double length_mm, double tolerance_mm);
  ~CheckFaces();

  // The same faces less the one at `except` (its place in the list given), sharing their samples:
  // a job of several faces checks each against the others without sampling any twice.
  CheckFaces Without(std::size_t except) const;

  // The deepest point found of a face inside the tool with tip `tip` and unit axis `axis`, if
  // deeper than the tolerance. Thread-safe.
  std::optional<Hit> Into(const Eigen::Vector3d& tip, const Eigen::Vector3d& axis) const;

  // Into, and how far the tool is from the faces: no face lies nearer the tool than
  // `clearance_mm` (at most `reach_mm`; the deepest depth found, negated, where one goes into it).
  // The faces, their samples' blocks and a trimmed face's loops are looked at only where their
  // bounding volumes (a hierarchy of boxes, built once per face) come within `reach_mm` of the
  // tool: Around(tip, axis, 0) costs what Into does.
  struct Near {
    std::optional<Hit> hit;
    double clearance_mm = 0.0;
  };
  Near Around(const Eigen::Vector3d& tip, const Eigen::Vector3d& axis, double reach_mm) const;

  // The most any point of the tool that can come within a millimetre of a face moves from the
  // pose (tip_a, axis_a) to (tip_b, axis_b) (mm): the tip's move, plus the turn of the axis (the
  // chord between the unit axes) times the distance from the tip of the farthest such point (at
  // a height where the axis is inside the faces' bounding box widened by the tool's radius and a
  // millimetre, at either pose). A face `clearance_mm` (< 1 mm) from the tool at one pose is at
  // least clearance_mm less this from it at the other.
  double Displacement(const Eigen::Vector3d& tip_a, const Eigen::Vector3d& axis_a,
                      const Eigen::Vector3d& tip_b, const Eigen::Vector3d& axis_b) const;

  double ToleranceMm() const { return tolerance_mm_; }

 private:
  struct Sampled;
  struct Face;
  const Sampled& Samples(const Face& face) const;
  void BuildTree();

  struct Tree;
  std::vector<std::shared_ptr<const Face>> faces_;
  std::shared_ptr<const Tree> tree_;  // the faces' boxes, built once per list of faces
  Eigen::Vector3d lo_, hi_;           // the box of all faces
  Tool tool_;
  double length_mm_, tolerance_mm_;
  double spacing_mm_;  // the samples' spacing asked for
};

}  // namespace dtis::geometry
