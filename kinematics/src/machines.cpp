#include "dtis/kinematics/machines.hpp"

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>

#include "dtis/core/error.hpp"

namespace dtis::kinematics {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr int kTilt = 3, kC = 4;  // indices of the tilting (or head) axis and C in q

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

Eigen::Matrix3d Rotation(bool about_y, double angle) {
  return Eigen::AngleAxisd(angle, about_y ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitX())
      .toRotationMatrix();
}

Eigen::Matrix3d Rz(double angle) {
  return Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()).toRotationMatrix();
}

// The two rotary solutions for a tool axis (tilting axis, C), in axis values.
struct Branch {
  double tilt, c;
};

// Of the two branches, the one within travel nearest to the previous positions, with C unwrapped
// to them; `tilt` is the angle between the tool axis and the C axis, where C is undefined near 0
// and pi and keeps its previous value.
InverseResult PickBranch(std::span<const Axis> axes, const KinematicsOptions& options, double tilt,
                         Branch primary, Branch secondary, const AxisVector* previous,
                         Branch* best) {
  const Axis& axis_t = axes[kTilt];
  const Axis& axis_c = axes[kC];
  const double c_previous = previous ? (*previous)[kC] : 0.0;
  const double t_previous = previous ? (*previous)[kTilt] : 0.0;
  if (tilt <= options.singular_angle_rad || kPi - tilt <= options.singular_angle_rad) {
    primary.c = c_previous;
    secondary.c = c_previous;
  }
  double best_cost = INFINITY;
  *best = {NAN, NAN};
  InverseResult failure{InverseStatus::kOutOfTravel, kTilt, primary.tilt};
  for (const Branch& k : {primary, secondary}) {
    if (!axis_t.continuous && (k.tilt < axis_t.travel_min || k.tilt > axis_t.travel_max)) continue;
    const double c = WithinTravel(axis_c, k.c, c_previous);
    if (std::isnan(c)) {
      failure = {InverseStatus::kOutOfTravel, kC, Nearest(k.c, c_previous)};
      continue;
    }
    const double cost = std::abs(k.tilt - t_previous) + std::abs(c - c_previous);
    if (cost < best_cost) {
      best_cost = cost;
      *best = {k.tilt, c};
    }
  }
  if (std::isnan(best->tilt)) return failure;
  if (previous) {
    const bool c_jumps = std::abs(best->c - c_previous) > options.branch_jump_rad;
    if (c_jumps || std::abs(best->tilt - t_previous) > options.branch_jump_rad) {
      return {InverseStatus::kBranchJump, c_jumps ? kC : kTilt, c_jumps ? best->c : best->tilt};
    }
  }
  return {};
}

double TiltFromC(const Eigen::Vector3d& n) { return std::atan2(std::hypot(n.x(), n.y()), n.z()); }

struct KinematicsInfo {
  const char* name;
  Kinematics kinematics;
  const char* axes;
  bool head_table;
  bool alias;  // an older name of the same kinematics
};
constexpr KinematicsInfo kKinematics[] = {
    {"xyz", Kinematics::kXyz, "XYZ", false, false},
    {"xyzac", Kinematics::kXyzacTrt, "XYZAC", false, true},
    {"xyzac-trt", Kinematics::kXyzacTrt, "XYZAC", false, false},
    {"xyzbc-trt", Kinematics::kXyzbcTrt, "XYZBC", false, false},
    {"xyzac-head-table", Kinematics::kXyzacHeadTable, "XYZAC", true, false},
    {"xyzbc-head-table", Kinematics::kXyzbcHeadTable, "XYZBC", true, false},
    {"serial-arm", Kinematics::kSerialArm, "", false, false},
};

const KinematicsInfo& Info(Kinematics k) {
  for (const KinematicsInfo& i : kKinematics) {
    if (i.kinematics == k && !i.alias) return i;
  }
  throw Error("unknown kinematics {}", static_cast<int>(k));
}

bool TiltsAboutY(Kinematics k) {
  return k == Kinematics::kXyzbcTrt || k == Kinematics::kXyzbcHeadTable;
}

}  // namespace

const char* KinematicsName(Kinematics k) { return Info(k).name; }

std::vector<std::string> KinematicsNames() {
  std::vector<std::string> names;
  for (const KinematicsInfo& i : kKinematics) names.emplace_back(i.name);
  return names;
}

std::optional<Kinematics> KinematicsNamed(std::string_view name) {
  for (const KinematicsInfo& i : kKinematics) {
    if (name == i.name) return i.kinematics;
  }
  return std::nullopt;
}

const char* AxisLetters(Kinematics k) { return Info(k).axes; }

bool IsHeadTable(Kinematics k) { return Info(k).head_table; }

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

FiveAxisMachine::FiveAxisMachine(const MachineDescription& d)
    : d_(d), tilts_about_y_(TiltsAboutY(d.kinematics)) {
  if (d.axes.size() != 5) {
    throw Error("machine '{}': {} needs 5 axes, has {}", d.name, KinematicsName(d.kinematics),
                d.axes.size());
  }
  if (std::abs(d.head_direction) != 1.0 || std::abs(d.c_direction) != 1.0) {
    throw Error("machine '{}': axis directions are +1 or -1", d.name);
  }
}

// R(T) Rz(C) n = z: Rz(C) n = R(T)^T z, which is (0, sin A, cos A) for A and (-sin B, 0, cos B)
// for B; the other branch tilts the other way with C half a turn on.
InverseResult TableTiltingMachine::Inverse(const Pose& pose, const AxisVector* previous,
                                           AxisVector* q) const {
  const Eigen::Vector3d n = pose.axis.normalized();
  const double tilt = TiltFromC(n);
  const double c = tilts_about_y_ ? std::atan2(n.y(), -n.x()) : std::atan2(n.x(), n.y());
  Branch best;
  const InverseResult r =
      PickBranch(d_.axes, d_.options, tilt, {tilt, c}, {-tilt, c + kPi}, previous, &best);
  if (r.status != InverseStatus::kOk) return r;
  const Eigen::Vector3d m =
      d_.tilt_pivot + Rotation(tilts_about_y_, best.tilt) *
                          (d_.c_pivot + Rz(best.c) * (pose.tip - d_.c_pivot) - d_.tilt_pivot);
  q->resize(5);
  *q << m.x(), m.y(), m.z(), best.tilt, best.c;
  return CheckTravel(d_.axes, *q, 0, 3);
}

Pose TableTiltingMachine::Forward(const AxisVector& q) const {
  const Eigen::Matrix3d rt = Rotation(tilts_about_y_, q[kTilt]);
  const Eigen::Matrix3d rz = Rz(q[kC]);
  const Eigen::Vector3d m(q[0], q[1], q[2]);
  Pose pose;
  pose.tip = d_.c_pivot +
             rz.transpose() * (rt.transpose() * (m - d_.tilt_pivot) + d_.tilt_pivot - d_.c_pivot);
  pose.axis = rz.transpose() * rt.transpose() * Eigen::Vector3d::UnitZ();
  return pose;
}

// Rz(γ) n = R(β) z with γ = C·c_direction, β = H·head_direction: R(β) z is (sin β, 0, cos β)
// about Y and (0, -sin β, cos β) about X.
InverseResult HeadTableMachine::Inverse(const Pose& pose, const AxisVector* previous,
                                        AxisVector* q) const {
  const Eigen::Vector3d n = pose.axis.normalized();
  const double tilt = TiltFromC(n);
  const double gamma = tilts_about_y_ ? std::atan2(-n.y(), n.x()) : std::atan2(n.x(), n.y());
  const double beta = tilts_about_y_ ? tilt : -tilt;
  const double sh = d_.head_direction, sc = d_.c_direction;
  Branch best;
  const InverseResult r = PickBranch(d_.axes, d_.options, tilt, {sh * beta, sc * gamma},
                                     {-sh * beta, sc * (gamma + kPi)}, previous, &best);
  if (r.status != InverseStatus::kOk) return r;
  const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d w = Rotation(tilts_about_y_, sh * best.tilt) * z;
  const Eigen::Vector3d m = d_.c_pivot + Rz(sc * best.c) * (pose.tip - d_.c_pivot);
  const Eigen::Vector3d axes = m + d_.head_length_mm * (w - z);
  q->resize(5);
  *q << axes.x(), axes.y(), axes.z(), best.tilt, best.c;
  return CheckTravel(d_.axes, *q, 0, 3);
}

Pose HeadTableMachine::Forward(const AxisVector& q) const {
  const Eigen::Vector3d z = Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d w = Rotation(tilts_about_y_, d_.head_direction * q[kTilt]) * z;
  const Eigen::Matrix3d rz = Rz(d_.c_direction * q[kC]);
  const Eigen::Vector3d m = Eigen::Vector3d(q[0], q[1], q[2]) - d_.head_length_mm * (w - z);
  return {d_.c_pivot + rz.transpose() * (m - d_.c_pivot), rz.transpose() * w};
}

std::unique_ptr<Machine> BuildMachine(const MachineDescription& d) {
  switch (d.kinematics) {
    case Kinematics::kXyz:
      return std::make_unique<XyzMachine>(d.name, d.axes, d.options);
    case Kinematics::kXyzacTrt:
    case Kinematics::kXyzbcTrt:
      return std::make_unique<TableTiltingMachine>(d);
    case Kinematics::kXyzacHeadTable:
    case Kinematics::kXyzbcHeadTable:
      return std::make_unique<HeadTableMachine>(d);
    case Kinematics::kSerialArm:
      return std::make_unique<SerialArmMachine>(d);
  }
  throw Error("machine '{}': unknown kinematics", d.name);
}

}  // namespace dtis::kinematics
