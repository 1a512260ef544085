#include "dtis/geometry/tool.hpp"

#include <fmt/format.h>

#include "dtis/core/error.hpp"

namespace dtis::geometry {

void Tool::Validate() const {
  if (!(radius > 0.0) || !std::isfinite(radius)) {
    throw Error("tool radius: expected a positive number of mm, got {}", radius);
  }
  switch (kind) {
    case Kind::kBallEnd:
      if (corner_radius != radius) throw Error("a ball end's corner radius is its radius");
      break;
    case Kind::kFlatEnd:
      if (corner_radius != 0.0) throw Error("a flat end has no corner radius");
      break;
    case Kind::kBullNose:
      if (!(corner_radius > 0.0) || !(corner_radius < radius)) {
        throw Error(
            "bull nose corner radius: expected a number in (0, {}) mm (the tool radius), "
            "got {}",
            radius, corner_radius);
      }
      break;
  }
}

std::string Tool::Describe() const {
  switch (kind) {
    case Kind::kBallEnd:
      return fmt::format("ball end R{}", radius);
    case Kind::kFlatEnd:
      return fmt::format("flat end R{}", radius);
    case Kind::kBullNose:
      return fmt::format("bull nose R{} r{}", radius, corner_radius);
  }
  return "tool";
}

}  // namespace dtis::geometry
