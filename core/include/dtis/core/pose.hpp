// A tool pose in the workpiece frame: tool tip point (mm) and unit tool axis (tip towards spindle).
#pragma once

#include <Eigen/Core>

namespace dtis {

struct Pose {
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();
};

}  // namespace dtis
