// Tool orientation rules (ISO 14649-11): a fixed axis (3-axis, or a fixed tilted axis on a 5-axis
// machine), and five_axes_const_tilt_yaw: the axis leans from the surface normal n by the tilt
// angle, in the direction of the feed f turned about n by the yaw angle:
//     a = cos(tilt) n + sin(tilt) (cos(yaw) f + sin(yaw) n x f).
// A positive tilt leans the tool's top forward along the feed (the tip trails: a lead angle).
// The feed direction f is the strategy's (see surface_pass.hpp): a unit tangent of the surface
// along the pass.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <string>

namespace dtis::strategies {

struct Orientation {
  enum class Kind { kFixed, kTiltYaw };
  Kind kind = Kind::kFixed;
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();  // kFixed: the unit tool axis
  double tilt_rad = 0.0;                            // kTiltYaw
  double yaw_rad = 0.0;
  // kTiltYaw: 0 follows the rule exactly. Above 0, along each pass the axis follows a quintic law
  // in the pass's arc length (AxisLaw) that stays within this angle of the rule everywhere: on a
  // cubic B-spline face the normal, and the rule's axis with it, is only C1 across knot lines,
  // and the rotary axes' accelerations would step there.
  double axis_tolerance_rad = 0.0;

  std::string Describe() const;
};

// The unit tool axis for unit normal n and unit feed direction f (orthogonal to n). T is double or
// a ceres::Jet, so that the strategies get the axis' derivatives along the surface exactly.
template <typename T>
Eigen::Matrix<T, 3, 1> ToolAxis(const Orientation& o, const Eigen::Matrix<T, 3, 1>& n,
                                const Eigen::Matrix<T, 3, 1>& f) {
  if (o.kind == Orientation::Kind::kFixed) return o.axis.cast<T>();
  const Eigen::Matrix<T, 3, 1> side = n.cross(f);
  return n * T(std::cos(o.tilt_rad)) +
         (f * T(std::cos(o.yaw_rad)) + side * T(std::sin(o.yaw_rad))) * T(std::sin(o.tilt_rad));
}

}  // namespace dtis::strategies
