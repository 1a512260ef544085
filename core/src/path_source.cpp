#include "dtis/core/path_source.hpp"

#include <fmt/format.h>

#include <string>

namespace dtis {

std::string DescribePathFailure(PathStatus status, double s) {
  if (status == PathStatus::kLeftDomain) {
    return fmt::format("the path source left its domain before arc length {} mm", s);
  }
  return fmt::format("the path source did not converge at arc length {} mm", s);
}

}  // namespace dtis
