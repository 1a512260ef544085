#include "dtis/io/curve_file.hpp"

#include <fmt/format.h>

#include <algorithm>

#include "dtis/core/error.hpp"
#include "dtis/core/toml_reader.hpp"

namespace dtis::io {
namespace {

geometry::BSplineCurve ReadCurve(TomlTable& t, int degree, const std::vector<double>& knots,
                                 double scale, int knots_line) {
  geometry::BSplineCurveData data;
  data.degree = degree;
  data.knots = knots;
  data.poles = t.Points("poles");
  for (auto& p : data.poles) p *= scale;
  const int poles_line = t.Line("poles");
  if (t.Has("weights")) data.weights = t.Numbers("weights");
  const int weights_line = t.Line("weights");
  // A curve that stays on one point is no path (as a line of zero length is none).
  if (!data.poles.empty() && std::all_of(data.poles.begin(), data.poles.end(), [&](const auto& p) {
        return (p - data.poles.front()).norm() <= 1e-9;
      })) {
    t.Fail("poles", fmt::format("all {} poles coincide at ({:g}, {:g}, {:g}): the curve has zero "
                                "length; expected poles that move",
                                data.poles.size(), data.poles.front().x(), data.poles.front().y(),
                                data.poles.front().z()));
  }
  try {
    return geometry::BSplineCurve(std::move(data), "curve");
  } catch (const Error& e) {
    // Point at the key the message is about.
    const std::string what = e.what();
    const int line = what.find("weight") != std::string::npos ? weights_line
                     : what.find("knot") != std::string::npos ? knots_line
                     : what.find("pole") != std::string::npos ? poles_line
                                                              : knots_line;
    throw Error("{}:{}: {}", t.File(), line, what);
  }
}

CurveFile ReadCurveFile(TomlTable& root) {
  const auto units = root.OptionalChoice("units", {"mm", "m", "in"});
  const double scale = !units || *units == "mm" ? 1.0 : *units == "m" ? 1000.0 : 25.4;
  const auto degree = root.Integer("degree");
  if (degree < 1 || degree > geometry::kMaxCurveDegree) {
    root.Fail("degree", fmt::format("expected 1..{}, got {}", geometry::kMaxCurveDegree, degree));
  }
  const auto knots = root.Numbers("knots");
  const int knots_line = root.Line("knots");
  CurveFile file{root.File(), ReadCurve(root, static_cast<int>(degree), knots, scale, knots_line),
                 std::nullopt};
  if (auto top = root.OptionalTable("top")) {
    file.top = ReadCurve(*top, static_cast<int>(degree), knots, scale, knots_line);
    top->RejectUnknown();
  }
  root.RejectUnknown();
  return file;
}

}  // namespace

CurveFile ParseCurveFile(std::string_view text, const std::string& source_name) {
  TomlTable root = TomlTable::ParseString(text, source_name);
  return ReadCurveFile(root);
}

CurveFile LoadCurveFile(const std::string& path) {
  TomlTable root = TomlTable::ParseFile(path);
  return ReadCurveFile(root);
}

}  // namespace dtis::io
