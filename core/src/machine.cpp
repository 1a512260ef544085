#include "dtis/core/machine.hpp"

#include <fmt/format.h>

#include <cmath>
#include <cstdlib>
#include <numbers>
#include <string>

namespace dtis {

std::string DescribeInverseFailure(const Machine& machine, const InverseResult& result) {
  const auto axes = machine.Axes();
  if (result.axis < 0 || result.axis >= static_cast<int>(axes.size())) {
    if (result.detail) {
      return fmt::format("machine '{}' cannot hold this pose: {}", machine.Name(), result.detail);
    }
    return result.status == InverseStatus::kUnreachable
               ? fmt::format("machine '{}' cannot hold this tool axis", machine.Name())
               : fmt::format("machine '{}' has no solution for this pose", machine.Name());
  }
  const Axis& a = axes[static_cast<std::size_t>(result.axis)];
  const double k = a.rotary ? 180.0 / std::numbers::pi : 1.0;
  const char* unit = a.rotary ? "deg" : "mm";
  switch (result.status) {
    case InverseStatus::kOutOfTravel: {
      const double v = result.value * k, lo = a.travel_min * k, hi = a.travel_max * k;
      // As many digits as it takes for the value printed to be outside the printed travel.
      std::string shown;
      for (int digits = 6; digits <= 17; ++digits) {
        shown = fmt::format("{:.{}g}", v, digits);
        const double back = std::strtod(shown.c_str(), nullptr);
        if (back < lo || back > hi || !std::isfinite(v)) break;
      }
      return fmt::format(
          "axis {} would have to reach {} {}, {:.3g} {} outside its travel [{:.6g}, {:.6g}] {}",
          a.name, shown, unit, v < lo ? lo - v : v - hi, unit, lo, hi, unit);
    }
    case InverseStatus::kBranchJump:
      return fmt::format(
          "axis {} would have to jump to {:.6g} {} (the tool axis passes a singularity that the "
          "travel of the other axes does not let the machine go around)",
          a.name, result.value * k, unit);
    case InverseStatus::kUnreachable:
      return fmt::format("machine '{}' cannot hold this tool axis", machine.Name());
    case InverseStatus::kSingular:
      return fmt::format(
          "the arm would pass its {} here ({} at {:.6g} {}): its configuration would flip or a "
          "joint turn without bound; move the part or the path away from it",
          result.detail ? result.detail : "singularity", a.name, result.value * k, unit);
    case InverseStatus::kOk:
      break;
  }
  return "ok";
}

}  // namespace dtis
