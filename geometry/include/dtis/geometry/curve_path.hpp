// Curves as PathSources: a B-spline/NURBS tool-tip curve with a fixed tool axis (3-axis), the
// 5-axis B-spline pair of Beudaert 2012 (bottom curve = tool tip, top curve = a point on the tool
// axis, same parameter), and straight lines. The state is the curve parameter; s is the arc length
// of the tool tip.
#pragma once

#include <memory>
#include <optional>
#include <vector>

#include "dtis/core/path_source.hpp"
#include "dtis/geometry/arc_length.hpp"
#include "dtis/geometry/bspline_curve.hpp"

namespace dtis::geometry {

class CurvePath final : public PathSource {
 public:
  // 3-axis: the tool axis is constant.
  CurvePath(BSplineCurve curve, const Eigen::Vector3d& tool_axis,
            const ArcLengthOptions& options = {});
  // 5-axis pair: `top` must have the bottom's degree and knots. Throws dtis::Error otherwise, or if
  // the two curves meet (the tool axis would be undefined).
  CurvePath(BSplineCurve bottom, BSplineCurve top, const ArcLengthOptions& options = {});

  PathState Start() const override;
  std::optional<double> Length() const override { return map_.Length(); }
  PathSample At(const PathState& from, double s) const override;
  std::string Describe(const PathState& state) const override;
  // The arc lengths of the curve's inner distinct knots.
  std::vector<double> Breaks(double s0, double s1) const override;

  const BSplineCurve& Bottom() const { return bottom_; }
  const std::optional<BSplineCurve>& Top() const { return top_; }
  const ArcLengthMap& Map() const { return map_; }
  // The pose at curve parameter u.
  Pose PoseAt(double u) const;

 private:
  BSplineCurve bottom_;
  std::optional<BSplineCurve> top_;
  Eigen::Vector3d axis_;
  ArcLengthMap map_;
  std::vector<double> knot_s_;  // arc lengths of the inner distinct knots
  std::vector<double> KnotArcLengths() const;
};

class LinePath final : public PathSource {
 public:
  // Throws dtis::Error if the two points coincide.
  LinePath(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
           const Eigen::Vector3d& tool_axis);

  PathState Start() const override { return {}; }
  std::optional<double> Length() const override { return length_; }
  PathSample At(const PathState& from, double s) const override;
  std::string Describe(const PathState& state) const override;

 private:
  Eigen::Vector3d from_, direction_, axis_;
  double length_;
};

// The poses that link two poses: back off along the first tool axis by `clearance`, rise to z =
// safe_z, traverse (the tool axis turning with a 5-axis line pair when the two axes differ), come
// down above the second pose and approach it along its axis; `from` and `to` included, without
// repeats. LinkMoves (g1_path.hpp) makes paths of them; a G-code export writes one rapid to each
// after the first. `straight`: from one straight to the other (the tool rides over what lies
// between, strategies::SurfacePass::RidesOverFromPrevious).
std::vector<Pose> LinkWaypoints(const Pose& from, const Pose& to, double safe_z, double clearance,
                                bool straight = false);

// The distinct knots of a curve inside its domain, ends included.
std::vector<double> DistinctKnots(const BSplineCurve& curve);

// The arc-length map of a curve, broken at its distinct knots. The curve must outlive the map.
ArcLengthMap ArcLengthOf(const BSplineCurve& curve, const ArcLengthOptions& options = {});
// ArcLengthOf(curve).Length(), to the last bit, without building the map.
double ArcLengthOfCurve(const BSplineCurve& curve);

// A straight move of the tool tip: a line with a fixed tool axis, or, when the axis turns, the
// 5-axis line pair whose top point (100 mm up the axis) moves linearly too. The tip must move.
std::unique_ptr<PathSource> StraightMove(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                                         const Eigen::Vector3d& from_axis,
                                         const Eigen::Vector3d& to_axis);
// The tool axis of that move where the tip has gone the fraction t of the way.
Eigen::Vector3d StraightMoveAxis(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                                 const Eigen::Vector3d& from_axis, const Eigen::Vector3d& to_axis,
                                 double t);

}  // namespace dtis::geometry
