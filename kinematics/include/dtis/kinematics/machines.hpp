// Machine models, named after the LinuxCNC kinematics modules that describe the same machines:
//   xyz          Cartesian (trivkins); the spindle is along +Z.
//   xyzac-trt    table-tilting: A tilts the cradle about an axis parallel to X, C turns the table
//                about its own axis (parallel to Z when A = 0); xyzac-trt-kins. The 5-axis Mikron
//                UCP 710 of Beudaert 2012 is one.
//   xyzbc-trt    the same with the cradle tilting about an axis parallel to Y (B); xyzbc-trt-kins.
//   xyzac-head-table, xyzbc-head-table
//                the spindle head tilts (A about X or B about Y, about a pivot head_length above
//                the tool tip), C turns the table; LinuxCNC's maxkins is an xyzbc-head-table.
//   serial-arm   a six-joint serial arm (genserkins, pumakins): joints J1..J6, each a rotation
//   about
//                its axis after a fixed transform from the previous joint's frame (a chain of joint
//                frames, or Craig's modified Denavit-Hartenberg parameters); one joint is locked,
//                since the rotation about a rotating tool's axis is free (docs/robots.md).
// Every rotary angle is right-handed about its axis unless a direction of -1 reverses it.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
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

enum class Kinematics : std::uint8_t {
  kXyz,
  kXyzacTrt,
  kXyzbcTrt,
  kXyzacHeadTable,
  kXyzbcHeadTable,
  kSerialArm,
};

// The name machine files use ("xyzbc-trt").
const char* KinematicsName(Kinematics k);
// Every name machine files accept, for messages: the names above and "xyzac", the name of
// xyzac-trt before the other 5-axis machines existed.
std::vector<std::string> KinematicsNames();
// The kinematics a machine file names, if it is one of KinematicsNames().
std::optional<Kinematics> KinematicsNamed(std::string_view name);
// The machine's axes in order: "XYZ", "XYZAC" or "XYZBC" (the tilting axis, then C); "" for an
// arm, whose joints are J1..J6.
const char* AxisLetters(Kinematics k);
bool IsHeadTable(Kinematics k);

// A six-joint serial arm. Joint i turns by q[i] about `axis[i]` after the fixed transform
// `fixed[i]` from joint i-1's frame (the base frame for J1); the flange is J6's frame. Lengths mm,
// angles rad.
struct ArmDescription {
  // How the file gave the chain, to write it back the same way.
  enum class Form : std::uint8_t { kFrames, kDh };
  Form form = Form::kFrames;
  // kFrames: joint i's origin and roll-pitch-yaw (URDF's: R = Rz(yaw) Ry(pitch) Rx(roll)) in the
  // previous joint's frame, and its axis there.
  std::array<Eigen::Vector3d, 6> origin{}, rpy{}, axis{};
  // kDh: Craig's modified parameters, as LinuxCNC's genserkins reads them: joint i's frame is
  // RotX(alpha[i]) TransX(a[i]) RotZ(theta[i] + q[i]) TransZ(d[i]) from the previous one.
  std::array<double, 6> a{}, alpha{}, d{}, theta{};
  // The tool tip in the flange frame and the tool axis there (from the tip towards the spindle).
  Eigen::Vector3d tool_tip = Eigen::Vector3d::Zero();
  Eigen::Vector3d tool_axis = -Eigen::Vector3d::UnitZ();
  // The part frame (the frame of the poses) in the arm's base frame: origin and roll-pitch-yaw.
  Eigen::Vector3d part_origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d part_rpy = Eigen::Vector3d::Zero();
  int locked_joint = 5;  // 0-based: J6
  double locked_at = 0.0;
  // The posture the first pose of a path is reached from; it picks the configuration (shoulder,
  // elbow, wrist) every later pose keeps.
  std::array<double, 6> home{};
  // A pose nearer a singularity than this (the sine of the angle that vanishes there) is refused.
  double singular_sine = 1e-4;
};

// Everything a machine is built from: what machine files and LinuxCNC INI files are read into, and
// what `dtis machine import` writes back out. Units: mm, s, rad.
struct MachineDescription {
  std::string name;
  Kinematics kinematics = Kinematics::kXyz;
  std::vector<Axis> axes;  // X, Y, Z, then the tilting axis (A or B) and C for 5-axis machines
  // trt: a point on the tilting axis and one on the C axis, in the workpiece frame with every
  // axis at 0 (LinuxCNC: C point = (x, y, z)-rot-point, tilting point = rot-point + offsets).
  Eigen::Vector3d tilt_pivot = Eigen::Vector3d::Zero();
  Eigen::Vector3d c_pivot = Eigen::Vector3d::Zero();  // head-table: a point on the C axis too
  // head-table: from the head's pivot to the tool tip along the tool axis at head angle 0.
  double head_length_mm = 0.0;
  // head-table: +1 right-handed, -1 reversed (LinuxCNC maxkins: head = conventional-directions
  // ? +1 : -1, C = -1).
  double head_direction = 1.0;
  double c_direction = 1.0;
  ArmDescription arm;  // serial-arm
  KinematicsOptions options;
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

// What the 5-axis machines share: their description, the two rotary axes at q[3] (A or B) and
// q[4] (C), and the branch choice between the two rotary solutions of a tool axis.
class FiveAxisMachine : public Machine {
 public:
  explicit FiveAxisMachine(const MachineDescription& d);
  const std::string& Name() const override { return d_.name; }
  std::span<const Axis> Axes() const override { return d_.axes; }

 protected:
  MachineDescription d_;
  bool tilts_about_y_;  // B rather than A
};

// A rotary table C on a cradle tilting about X (A) or Y (B). A workpiece point p is at
//   m = t + R(T) (c + Rz(C) (p - c) - t)
// in the machine frame (t, c: the pivots), which is where the linear axes put the tool tip, and
// R(T) Rz(C) maps the tool axis onto the spindle's +Z.
class TableTiltingMachine final : public FiveAxisMachine {
 public:
  using FiveAxisMachine::FiveAxisMachine;
  InverseResult Inverse(const Pose& pose, const AxisVector* previous, AxisVector* q) const override;
  Pose Forward(const AxisVector& q) const override;
};

// A spindle head tilting about X (A) or Y (B) over a rotary table C. The table carries the
// workpiece point p to m = c + Rz(C) (p - c); the head turns the tool axis from +Z to w = R(H) +Z,
// and the linear axes read the tool tip's position at H = 0: q = m + L (w - z).
class HeadTableMachine final : public FiveAxisMachine {
 public:
  using FiveAxisMachine::FiveAxisMachine;
  InverseResult Inverse(const Pose& pose, const AxisVector* previous, AxisVector* q) const override;
  Pose Forward(const AxisVector& q) const override;
};

// True when the tool lies on J6's axis (its tip on it, its axis along it): J6 then only turns the
// tool about its own axis, the rotation a rotating tool leaves free, and J6 is the joint to lock.
bool ToolOnLastAxis(const ArmDescription& arm);

// A six-joint serial arm with one joint locked: poses (tool tip and axis, 5 numbers) to the five
// free joints by Newton's method from the previous joints (from the home posture, followed along a
// straight blend of poses, for the first), so that the configuration never flips between
// setpoints; a pose at a shoulder, elbow or wrist singularity, or one whose joints would change
// configuration from the previous ones, is refused naming which.
class SerialArmMachine final : public Machine {
 public:
  explicit SerialArmMachine(const MachineDescription& d);
  const std::string& Name() const override { return name_; }
  std::span<const Axis> Axes() const override { return axes_; }
  InverseResult Inverse(const Pose& pose, const AxisVector* previous, AxisVector* q) const override;
  Pose Forward(const AxisVector& q) const override;

  // The flange's pose in the arm's base frame at joints q.
  Eigen::Isometry3d Flange(const AxisVector& q) const;
  // The signed shoulder, elbow and wrist measures at q (sines: 0 at the singularity, the sign is
  // the configuration).
  Eigen::Vector3d Configuration(const AxisVector& q) const;

 private:
  struct Chain;  // positions and axes of every joint at some q
  Chain Evaluate(const AxisVector& q) const;
  // Newton on the free joints from *q towards the tip and axis (base frame); false when it does
  // not converge.
  bool Solve(const Eigen::Vector3d& tip, const Eigen::Vector3d& axis, AxisVector* q) const;
  InverseResult Check(const AxisVector& q, const AxisVector* previous) const;

  std::string name_;
  std::vector<Axis> axes_;
  ArmDescription arm_;
  std::array<Eigen::Isometry3d, 6> fixed_;
  std::array<Eigen::Vector3d, 6> axis_;
  Eigen::Isometry3d part_;  // part frame -> base frame
  double reach_mm_ = 1.0;   // the sum of the link lengths, to make the shoulder measure a sine
  KinematicsOptions options_;
};

std::unique_ptr<Machine> BuildMachine(const MachineDescription& description);

// Reads a machine: a TOML machine file (units stated in the file; see samples/machines/) or, for a
// path ending in .ini, a LinuxCNC INI file (docs/machines.md). Throws dtis::Error naming the file,
// line and key.
struct MachineLoadOptions {
  // For INI files whose axes have no MAX_JERK: jerk = MAX_ACCELERATION / jerk_time_s (s), from
  // kMinJerkTimeS to kMaxJerkTimeS (anything else, NaN included, is an error naming the file).
  std::optional<double> jerk_time_s;
  // 0.1 ms: a jerk ten thousand times the acceleration; 10 s: a ramp longer than any drive's.
  static constexpr double kMinJerkTimeS = 1e-4, kMaxJerkTimeS = 10.0;
};
// A path LoadMachineFile reads as a LinuxCNC INI file (it ends in .ini or .INI).
bool IsLinuxcncIni(const std::string& path);
std::unique_ptr<Machine> LoadMachineFile(const std::string& path,
                                         const MachineLoadOptions& options = {});
MachineDescription ReadMachineDescription(const std::string& path,
                                          const MachineLoadOptions& options = {});
std::unique_ptr<Machine> ParseMachine(std::string_view text, const std::string& source_name);
MachineDescription ParseMachineDescription(std::string_view text, const std::string& source_name);

// LinuxCNC INI: [KINS] KINEMATICS, [TRAJ] COORDINATES / LINEAR_UNITS / ANGULAR_UNITS, [JOINT_n]
// and [AXIS_L] limits, and the kinematics' pivot pins set in the INI's HALCMD lines and its HAL
// files.
MachineDescription ParseLinuxcncIni(std::string_view text, const std::string& source_name,
                                    const MachineLoadOptions& options = {});

// The description as a machine file, in mm, s and deg, that reads back to the same machine.
std::string FormatMachineFile(const MachineDescription& description);

}  // namespace dtis::kinematics
