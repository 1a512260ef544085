#include "dtis/kinematics/machines.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>

namespace dtis::kinematics {
namespace {

constexpr double kPi = std::numbers::pi;

InverseResult CheckTravel(std::span<const Axis> axes, const AxisVector& q, int first, int last) {
  for (int i = first; i < last; ++i) {
    const Axis& a = axes[static_cast<std::size_t>(i)];
    if (a.continuous) continue;
    if (q[i] < a.travel_min || q[i] > a.travel_max) {
      return {InverseStatus::kOutOfTravel, i, q[i]};
    }
  }
  return {};
}

// The angle equal to `angle` modulo 2 pi that is nearest to `target`.
double Nearest(double angle, double target) {
  return angle + 2.0 * kPi * std::round((target - angle) / (2.0 * kPi));
}

// The angle equal to `angle` modulo 2 pi within the axis travel and nearest to `target`, or NaN.
double WithinTravel(const Axis& axis, double angle, double target) {
  if (axis.continuous) return Nearest(angle, target);
  double best = NAN;
  for (double c = Nearest(angle, axis.travel_min) - 2.0 * kPi; c <= axis.travel_max + 2.0 * kPi;
       c += 2.0 * kPi) {
    if (c < axis.travel_min || c > axis.travel_max) continue;
    if (std::isnan(best) || std::abs(c - target) < std::abs(best - target)) best = c;
  }
  return best;
}

}  // namespace

XyzMachine::XyzMachine(std::string name, std::vector<Axis> axes, const KinematicsOptions& options)
    : name_(std::move(name)), axes_(std::move(axes)), options_(options) {}

InverseResult XyzMachine::Inverse(const Pose& pose, const AxisVector*, AxisVector* q) const {
  q->resize(3);
  *q = pose.tip;
  const double angle = std::atan2(pose.axis.head<2>().norm(), pose.axis.z());
  if (angle > options_.axis_tolerance_rad) return {InverseStatus::kUnreachable, -1, angle};
  return CheckTravel(axes_, *q, 0, 3);
}

Pose XyzMachine::Forward(const AxisVector& q) const {
  return {Eigen::Vector3d(q[0], q[1], q[2]), Eigen::Vector3d::UnitZ()};
}

XyzacMachine::XyzacMachine(std::string name, std::vector<Axis> axes, const Eigen::Vector3d& a_pivot,
                           const Eigen::Vector3d& c_pivot, const KinematicsOptions& options)
    : name_(std::move(name)),
      axes_(std::move(axes)),
      a_pivot_(a_pivot),
      c_pivot_(c_pivot),
      options_(options) {}

// The table rotations bring the tool axis n (workpiece frame) onto the spindle +Z:
//   Rx(A) Rz(C) n = z  =>  C = atan2(nx, ny), A = atan2(hypot(nx, ny), nz)
// or the other branch (-A, C + pi). A workpiece point p is then at
//   m = a + Rx(A) (c + Rz(C) (p - c) - a)
// in the machine frame, which is where the linear axes put the tool tip.
InverseResult XyzacMachine::Inverse(const Pose& pose, const AxisVector* previous,
                                    AxisVector* q) const {
  const Eigen::Vector3d n = pose.axis.normalized();
  const double r = std::hypot(n.x(), n.y());
  const double tilt = std::atan2(r, n.z());
  const Axis& axis_a = axes_[3];
  const Axis& axis_c = axes_[4];
  const double c_previous = previous ? (*previous)[4] : 0.0;
  const double a_previous = previous ? (*previous)[3] : 0.0;

  struct Candidate {
    double a, c;
  };
  Candidate candidates[2];
  if (tilt <= options_.singular_angle_rad || kPi - tilt <= options_.singular_angle_rad) {
    // On the C axis: C is free, keep it.
    candidates[0] = {tilt, c_previous};
    candidates[1] = {-tilt, c_previous};
  } else {
    const double c = std::atan2(n.x(), n.y());
    candidates[0] = {tilt, c};
    candidates[1] = {-tilt, c + kPi};
  }
  double best_cost = INFINITY;
  Candidate best{NAN, NAN};
  InverseResult failure{InverseStatus::kOutOfTravel, 3, candidates[0].a};
  for (const Candidate& k : candidates) {
    if (!axis_a.continuous && (k.a < axis_a.travel_min || k.a > axis_a.travel_max)) continue;
    const double c = WithinTravel(axis_c, k.c, c_previous);
    if (std::isnan(c)) {
      failure = {InverseStatus::kOutOfTravel, 4, Nearest(k.c, c_previous)};
      continue;
    }
    const double cost = std::abs(k.a - a_previous) + std::abs(c - c_previous);
    if (cost < best_cost) {
      best_cost = cost;
      best = {k.a, c};
    }
  }
  if (std::isnan(best.a)) return failure;
  if (previous && (std::abs(best.c - c_previous) > options_.branch_jump_rad ||
                   std::abs(best.a - a_previous) > options_.branch_jump_rad)) {
    const bool c_jumps = std::abs(best.c - c_previous) > options_.branch_jump_rad;
    return {InverseStatus::kBranchJump, c_jumps ? 4 : 3, c_jumps ? best.c : best.a};
  }
  const Eigen::Matrix3d rx = Eigen::AngleAxisd(best.a, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::Matrix3d rz = Eigen::AngleAxisd(best.c, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Vector3d m = a_pivot_ + rx * (c_pivot_ + rz * (pose.tip - c_pivot_) - a_pivot_);
  q->resize(5);
  *q << m.x(), m.y(), m.z(), best.a, best.c;
  return CheckTravel(axes_, *q, 0, 3);
}

Pose XyzacMachine::Forward(const AxisVector& q) const {
  const Eigen::Matrix3d rx = Eigen::AngleAxisd(q[3], Eigen::Vector3d::UnitX()).toRotationMatrix();
  const Eigen::Matrix3d rz = Eigen::AngleAxisd(q[4], Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const Eigen::Vector3d m(q[0], q[1], q[2]);
  Pose pose;
  pose.tip = c_pivot_ + rz.transpose() * (rx.transpose() * (m - a_pivot_) + a_pivot_ - c_pivot_);
  pose.axis = rz.transpose() * rx.transpose() * Eigen::Vector3d::UnitZ();
  return pose;
}

}  // namespace dtis::kinematics
