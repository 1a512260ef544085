// Curve files (TOML): a B-spline/NURBS tool-tip curve, and optionally the top curve of a 5-axis
// pair. Example (samples/curves/trident.toml):
//   units = "mm"                     # optional: mm | m | in
//   degree = 3
//   knots = [0, 0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1, 1]
//   poles = [[10, 0], [20, 27], ...]  # [x, y] or [x, y, z]
//   weights = [1, 1, ...]            # optional: rational curve
//   [top]                            # optional: the 5-axis top curve, same degree and knots
//   poles = [...]
//   weights = [...]
#pragma once

#include <optional>
#include <string>

#include "dtis/geometry/bspline_curve.hpp"

namespace dtis::io {

struct CurveFile {
  std::string file;
  geometry::BSplineCurve bottom;
  std::optional<geometry::BSplineCurve> top;
};

// Throws dtis::Error naming the file, line and key (or knot / pole / weight index).
CurveFile LoadCurveFile(const std::string& path);
CurveFile ParseCurveFile(std::string_view text, const std::string& source_name);

}  // namespace dtis::io
