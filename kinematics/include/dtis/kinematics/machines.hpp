// Machine models: Cartesian XYZ, and the table-tilting XYZAC of the Mikron UCP 710 (Beudaert 2012):
// A tilts the cradle about an axis parallel to X, C turns the table about its own axis (parallel to
// Z when A = 0), the spindle is along +Z.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include "dtis/core/machine.hpp"

namespace dtis::kinematics {

struct KinematicsOptions {
  // A tool axis closer than this to the C axis is treated as on it: C is undefined there and keeps
  // its previous value (rad, angle between the tool axis and the C axis).
  double singular_angle_rad = 1e-12;
  // The largest change of a rotary axis between two consecutive poses that still counts as
  // continuous; beyond it the branch is said to jump (rad).
  double branch_jump_rad = 1.5707963267948966;
  // On XYZ, the largest angle between the tool axis and +Z still taken as vertical (rad).
  double axis_tolerance_rad = 1e-9;
};

class XyzMachine final : public Machine {
 public:
  XyzMachine(std::string name, std::vector<Axis> axes, const KinematicsOptions& options = {});
  const std::string& Name() const override { return name_; }
  std::span<const Axis> Axes() const override { return axes_; }
  InverseResult Inverse(const Pose& pose, const AxisVector* previous, AxisVector* q) const override;
  Pose Forward(const AxisVector& q) const override;

 private:
  std::string name_;
  std::vector<Axis> axes_;
  KinematicsOptions options_;
};

class XyzacMachine final : public Machine {
 public:
  // `a_pivot`: a point on the A axis, `c_pivot`: a point on the C axis, both in the workpiece frame
  // at A = C = 0 (mm).
  XyzacMachine(std::string name, std::vector<Axis> axes, const Eigen::Vector3d& a_pivot,
               const Eigen::Vector3d& c_pivot, const KinematicsOptions& options = {});
  const std::string& Name() const override { return name_; }
  std::span<const Axis> Axes() const override { return axes_; }
  InverseResult Inverse(const Pose& pose, const AxisVector* previous, AxisVector* q) const override;
  Pose Forward(const AxisVector& q) const override;

 private:
  std::string name_;
  std::vector<Axis> axes_;
  Eigen::Vector3d a_pivot_, c_pivot_;
  KinematicsOptions options_;
};

// Reads a machine file (TOML, units stated in the file; see samples/machines/). Throws dtis::Error
// naming the file, line and key.
std::unique_ptr<Machine> LoadMachineFile(const std::string& path);
std::unique_ptr<Machine> ParseMachine(std::string_view text, const std::string& source_name);

}  // namespace dtis::kinematics
