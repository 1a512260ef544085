// The angle between two vectors, accurate at small angles (atan2 of |a x b| and a . b, where
// acos(a . b) loses half the digits near 0).
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <numbers>

namespace dtis::geometry {

inline double Angle(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

inline double AngleDeg(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return Angle(a, b) * 180.0 / std::numbers::pi;
}

}  // namespace dtis::geometry
