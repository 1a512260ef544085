#include "dtis/strategies/orientation.hpp"

#include <fmt/format.h>

#include <numbers>

namespace dtis::strategies {

std::string Orientation::Describe() const {
  if (kind == Kind::kFixed) {
    return fmt::format("fixed axis ({:.6g}, {:.6g}, {:.6g})", axis.x(), axis.y(), axis.z());
  }
  std::string out =
      fmt::format("tilt {:.6g} deg, yaw {:.6g} deg", tilt_rad * 180.0 / std::numbers::pi,
                  yaw_rad * 180.0 / std::numbers::pi);
  // The tolerance in force, also when it is the default 0.
  out += axis_tolerance_rad > 0.0 ? fmt::format(", axis smoothed within {:.6g} deg",
                                                axis_tolerance_rad * 180.0 / std::numbers::pi)
                                  : std::string(", the rule's exact axis");
  return out;
}

}  // namespace dtis::strategies
