// Six-joint serial arms (kinematics "serial-arm"): the forward kinematics along the chain of joint
// frames, and the inverse for a rotating tool, whose rotation about its own axis is free: one joint
// is locked and Newton's method finds the five others from the previous joints (docs/robots.md).
#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <numbers>

#include "dtis/core/error.hpp"
#include "dtis/kinematics/machines.hpp"

namespace dtis::kinematics {
namespace {

constexpr int kJoints = 6;
using Eigen::Vector3d;
using Matrix5d = Eigen::Matrix<double, 5, 5>;
using Vector5d = Eigen::Matrix<double, 5, 1>;

Eigen::Matrix3d Rpy(const Vector3d& rpy) {
  return (Eigen::AngleAxisd(rpy.z(), Vector3d::UnitZ()) *
          Eigen::AngleAxisd(rpy.y(), Vector3d::UnitY()) *
          Eigen::AngleAxisd(rpy.x(), Vector3d::UnitX()))
      .toRotationMatrix();
}

// The three singularities of a 6R arm with a spherical wrist, the joint each is named by in
// messages (the one whose value says where the arm is), and what happens there.
constexpr const char* kSingularity[3] = {
    "shoulder singularity (the wrist centre on the J1 axis)",
    "elbow singularity (the arm stretched or folded: the wrist centre in the plane of the J2 and "
    "J3 axes)",
    "wrist singularity (the J4 and J6 axes in line)"};
constexpr int kNamedJoint[3] = {0, 2, 4};

// Newton: the largest step of a joint per iteration (rad), the iterations, and the step below which
// the joints have converged (rad; the last digits of a double).
constexpr double kMaxStep = 0.2;
constexpr int kMaxIterations = 60;
constexpr double kConverged = 1e-14;
// A pose reached: the tip within this of the target (mm) and the tool axis within this angle (rad).
constexpr double kTipTolerance = 1e-9, kAxisTolerance = 1e-11;
// The first pose of a path is reached from the home posture in this many blended steps.
constexpr int kHomotopySteps = 64;

}  // namespace

bool ToolOnLastAxis(const ArmDescription& arm) {
  const Vector3d j6 = arm.form == ArmDescription::Form::kDh ? Vector3d::UnitZ()
                                                            : Vector3d(arm.axis[5].normalized());
  return arm.tool_tip.cross(j6).norm() <= 1e-9 &&
         arm.tool_axis.normalized().cross(j6).norm() <= 1e-12;
}

struct SerialArmMachine::Chain {
  std::array<Vector3d, kJoints> origin, axis;  // each joint's point and axis, base frame
  Eigen::Isometry3d flange;
};

SerialArmMachine::SerialArmMachine(const MachineDescription& d)
    : name_(d.name), axes_(d.axes), arm_(d.arm), options_(d.options) {
  if (axes_.size() != kJoints) {
    throw Error("machine '{}': serial-arm needs 6 joints, has {}", name_, axes_.size());
  }
  for (const Axis& a : axes_) {
    if (!a.rotary) throw Error("machine '{}': joint {} is not rotary", name_, a.name);
  }
  if (arm_.locked_joint < 0 || arm_.locked_joint >= kJoints) {
    throw Error("machine '{}': the locked joint is J1 to J6, got J{}", name_,
                arm_.locked_joint + 1);
  }
  if (!(arm_.tool_axis.norm() > 0.0)) throw Error("machine '{}': the tool axis is zero", name_);
  if (arm_.locked_joint != kJoints - 1 && ToolOnLastAxis(arm_)) {
    throw Error(
        "machine '{}': the tool lies on J6's axis, so J6 only turns it about its own axis: "
        "lock J6, not J{}",
        name_, arm_.locked_joint + 1);
  }
  arm_.tool_axis.normalize();
  reach_mm_ = arm_.tool_tip.norm();
  for (int i = 0; i < kJoints; ++i) {
    const auto k = static_cast<std::size_t>(i);
    if (arm_.form == ArmDescription::Form::kDh) {
      fixed_[k] = Eigen::Isometry3d::Identity();
      fixed_[k].rotate(Eigen::AngleAxisd(arm_.alpha[k], Vector3d::UnitX()));
      fixed_[k].translate(Vector3d(arm_.a[k], 0.0, 0.0));
      fixed_[k].rotate(Eigen::AngleAxisd(arm_.theta[k], Vector3d::UnitZ()));
      fixed_[k].translate(Vector3d(0.0, 0.0, arm_.d[k]));
      axis_[k] = Vector3d::UnitZ();
      reach_mm_ += std::abs(arm_.a[k]) + std::abs(arm_.d[k]);
    } else {
      if (!(arm_.axis[k].norm() > 0.0)) {
        throw Error("machine '{}': the axis of joint J{} is zero", name_, i + 1);
      }
      fixed_[k] = Eigen::Isometry3d::Identity();
      fixed_[k].translate(arm_.origin[k]);
      fixed_[k].rotate(Rpy(arm_.rpy[k]));
      axis_[k] = arm_.axis[k].normalized();
      reach_mm_ += arm_.origin[k].norm();
    }
  }
  reach_mm_ = std::max(reach_mm_, 1.0);
  part_ = Eigen::Isometry3d::Identity();
  part_.translate(arm_.part_origin);
  part_.rotate(Rpy(arm_.part_rpy));
  const Axis& locked = axes_[static_cast<std::size_t>(arm_.locked_joint)];
  if (!locked.continuous &&
      (arm_.locked_at < locked.travel_min || arm_.locked_at > locked.travel_max)) {
    throw Error("machine '{}': the locked joint {} is locked outside its travel", name_,
                locked.name);
  }
  for (int i = 0; i < kJoints; ++i) {
    const Axis& a = axes_[static_cast<std::size_t>(i)];
    const double h = arm_.home[static_cast<std::size_t>(i)];
    if (!a.continuous && (h < a.travel_min || h > a.travel_max)) {
      throw Error("machine '{}': the home posture puts joint {} outside its travel", name_, a.name);
    }
  }
}

SerialArmMachine::Chain SerialArmMachine::Evaluate(const AxisVector& q) const {
  Chain c;
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  for (int i = 0; i < kJoints; ++i) {
    const auto k = static_cast<std::size_t>(i);
    t = t * fixed_[k];
    c.origin[k] = t.translation();
    c.axis[k] = t.linear() * axis_[k];
    t.rotate(Eigen::AngleAxisd(q[i], axis_[k]));
  }
  c.flange = t;
  return c;
}

Eigen::Isometry3d SerialArmMachine::Flange(const AxisVector& q) const { return Evaluate(q).flange; }

Pose SerialArmMachine::Forward(const AxisVector& q) const {
  const Eigen::Isometry3d f = Flange(q);
  const Eigen::Isometry3d to_part = part_.inverse();
  return {to_part * (f * arm_.tool_tip), to_part.linear() * (f.linear() * arm_.tool_axis)};
}

Eigen::Vector3d SerialArmMachine::Configuration(const AxisVector& q) const {
  const Chain c = Evaluate(q);
  const Vector3d& w = c.origin[4];  // the wrist centre: J5's point, on J4 and J6 too
  // Shoulder: the wrist centre's distance from J1's axis across the arm's plane.
  const Vector3d across = c.axis[0].cross(c.axis[1]);
  const double shoulder =
      across.norm() > 0.0 ? (w - c.origin[0]).dot(across.normalized()) / reach_mm_ : 0.0;
  // Elbow: the sine of the angle between the upper arm and the forearm, about J2's axis.
  const Vector3d z = c.axis[1];
  const Vector3d u = c.origin[2] - c.origin[1], v = w - c.origin[2];
  const Vector3d up = u - u.dot(z) * z, vp = v - v.dot(z) * z;
  const double elbow =
      up.norm() > 0.0 && vp.norm() > 0.0 ? up.cross(vp).dot(z) / (up.norm() * vp.norm()) : 0.0;
  // Wrist: the sine of the angle between J4's and J6's axes, signed about J5's.
  const double wrist = c.axis[3].cross(c.axis[5]).dot(c.axis[4]);
  return {shoulder, elbow, wrist};
}

bool SerialArmMachine::Solve(const Vector3d& tip, const Vector3d& axis, AxisVector* q) const {
  int free[5];
  for (int i = 0, n = 0; i < kJoints; ++i) {
    if (i != arm_.locked_joint) free[n++] = i;
  }
  const Vector3d e1 = axis.unitOrthogonal(), e2 = axis.cross(e1);
  Vector5d r;
  for (int iteration = 0; iteration < kMaxIterations; ++iteration) {
    const Chain c = Evaluate(*q);
    const Vector3d p = c.flange * arm_.tool_tip;
    const Vector3d a = c.flange.linear() * arm_.tool_axis;
    r << p - tip, e1.dot(a), e2.dot(a);
    Matrix5d j;
    for (int k = 0; k < 5; ++k) {
      const auto i = static_cast<std::size_t>(free[k]);
      const Vector3d dp = c.axis[i].cross(p - c.origin[i]);
      const Vector3d da = c.axis[i].cross(a);
      j.col(k) << dp, e1.dot(da), e2.dot(da);
    }
    const Eigen::FullPivLU<Matrix5d> lu(j);
    if (!lu.isInvertible()) return false;
    Vector5d step = lu.solve(-r);
    if (!step.allFinite()) return false;
    const double largest = step.cwiseAbs().maxCoeff();
    if (largest > kMaxStep) step *= kMaxStep / largest;
    for (int k = 0; k < 5; ++k) (*q)[free[k]] += step[k];
    if (largest < kConverged) break;
  }
  const Chain c = Evaluate(*q);
  const Vector3d p = c.flange * arm_.tool_tip;
  const Vector3d a = c.flange.linear() * arm_.tool_axis;
  return (p - tip).norm() <= kTipTolerance && a.dot(axis) > 0.0 &&
         a.cross(axis).norm() <= kAxisTolerance;
}

InverseResult SerialArmMachine::Check(const AxisVector& q, const AxisVector* previous) const {
  for (int i = 0; i < kJoints; ++i) {
    const Axis& a = axes_[static_cast<std::size_t>(i)];
    if (!a.continuous && (q[i] < a.travel_min || q[i] > a.travel_max)) {
      return {InverseStatus::kOutOfTravel, i, q[i]};
    }
  }
  const Vector3d conf = Configuration(q);
  const Vector3d before = previous ? Configuration(*previous) : conf;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(conf[k]) < arm_.singular_sine || conf[k] * before[k] < 0.0) {
      return {InverseStatus::kSingular, kNamedJoint[k], q[kNamedJoint[k]], kSingularity[k]};
    }
  }
  if (previous) {
    for (int i = 0; i < kJoints; ++i) {
      if (std::abs(q[i] - (*previous)[i]) > options_.branch_jump_rad) {
        return {InverseStatus::kBranchJump, i, q[i]};
      }
    }
  }
  return {};
}

InverseResult SerialArmMachine::Inverse(const Pose& pose, const AxisVector* previous,
                                        AxisVector* q) const {
  const Vector3d tip = part_ * pose.tip;
  const Vector3d axis = (part_.linear() * pose.axis).normalized();
  const bool near = previous && previous->size() == kJoints;
  AxisVector start(kJoints);
  if (near) {
    start = *previous;
  } else {
    for (int i = 0; i < kJoints; ++i) start[i] = arm_.home[static_cast<std::size_t>(i)];
  }
  start[arm_.locked_joint] = arm_.locked_at;
  *q = start;
  if (near && Solve(tip, axis, q)) return Check(*q, previous);
  // From home (or from the previous joints when Newton did not get there in one go): follow a
  // straight blend from the pose the arm holds there, so that the configuration stays the start's.
  *q = start;
  const Eigen::Isometry3d f = Flange(start);
  const Vector3d tip0 = f * arm_.tool_tip, axis0 = f.linear() * arm_.tool_axis;
  const Eigen::Quaterniond turn = Eigen::Quaterniond::FromTwoVectors(axis0, axis);
  for (int k = 1; k <= kHomotopySteps; ++k) {
    const double t = static_cast<double>(k) / kHomotopySteps;
    const Vector3d tip_t = k == kHomotopySteps ? tip : Vector3d(tip0 + t * (tip - tip0));
    const Vector3d axis_t = k == kHomotopySteps
                                ? axis
                                : Vector3d(Eigen::Quaterniond::Identity().slerp(t, turn) * axis0);
    if (!Solve(tip_t, axis_t, q)) {
      // Newton fails where the Jacobian is singular on the way, or the pose is out of reach.
      const Vector3d conf = Configuration(*q);
      int k_min = 0;
      conf.cwiseAbs().minCoeff(&k_min);
      if (std::abs(conf[k_min]) < 1e3 * arm_.singular_sine) {
        return {InverseStatus::kSingular, kNamedJoint[k_min], (*q)[kNamedJoint[k_min]],
                kSingularity[k_min]};
      }
      return {InverseStatus::kUnreachable, -1, 0.0,
              "the arm cannot reach it from its home posture without a singularity (out of "
              "reach, or in another configuration)"};
    }
  }
  return Check(*q, near ? previous : nullptr);
}

}  // namespace dtis::kinematics
