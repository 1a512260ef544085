// Machine: pose -> axis positions, with the solution branch kept continuous with the previous
// positions, and the per-axis limits (docs/design.md, "The two contracts"). Units inside: mm, s,
// rad.
#pragma once

#include <Eigen/Core>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "dtis/core/pose.hpp"

namespace dtis {

inline constexpr int kMaxAxes = 6;

// Axis positions: X, Y, Z in mm then rotary axes in rad. Fixed capacity, no allocation.
using AxisVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxAxes, 1>;

struct Axis {
  std::string name;         // "X", "A", ...
  bool rotary = false;      // rad instead of mm
  double travel_min = 0.0;  // mm or rad
  double travel_max = 0.0;  // mm or rad
  bool continuous = false;  // rotary axis without travel limits (unwrapped freely)
  double vmax = 0.0;        // mm/s or rad/s
  double amax = 0.0;        // mm/s^2 or rad/s^2
  double jmax = 0.0;        // mm/s^3 or rad/s^3
};

enum class InverseStatus : std::uint8_t {
  kOk,
  kOutOfTravel,  // the pose needs an axis beyond its travel on every branch
  kUnreachable,  // the machine cannot hold this tool axis at all (e.g. tilted axis on XYZ)
  kBranchJump,   // the only branch within travel is far from the previous positions
  kSingular,     // a serial arm at (or through) a singularity: `detail` says which
};

struct InverseResult {
  InverseStatus status = InverseStatus::kOk;
  int axis = -1;                 // the axis concerned, for kOutOfTravel / kBranchJump
  double value = 0.0;            // its required value (mm or rad)
  const char* detail = nullptr;  // kSingular: which singularity, static text
};

class Machine {
 public:
  virtual ~Machine() = default;

  virtual const std::string& Name() const = 0;
  virtual std::span<const Axis> Axes() const = 0;
  int AxisCount() const { return static_cast<int>(Axes().size()); }

  // Axis positions for `pose`. `previous` (may be null for the first pose) selects the branch and
  // the unwrapping of rotary axes so that positions stay continuous.
  virtual InverseResult Inverse(const Pose& pose, const AxisVector* previous,
                                AxisVector* q) const = 0;

  // The pose the machine holds at axis positions q.
  virtual Pose Forward(const AxisVector& q) const = 0;
};

// "A must be in [-100, 120] deg" and the like, for error messages, in the units users read.
std::string DescribeInverseFailure(const Machine& machine, const InverseResult& result);

}  // namespace dtis
