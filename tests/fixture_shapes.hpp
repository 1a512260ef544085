// Shapes the surface tests and the benchmarks make in code (no bundled part has them), and how
// they write them as STEP files.
#pragma once

#include <Geom_BSplineSurface.hxx>
#include <TopoDS_Face.hxx>
#include <TopoDS_Shape.hxx>
#include <string>

namespace dtis::test {

// Ruled between z = 3 sin(2 pi y / 30) along x = 0 and the same wave a sixth of a period on along
// x = 60 (valleys of radius 7.6 mm), y in [0, 60]; u across (x = 60 u), v along.
Handle(Geom_BSplineSurface) WavyRuledSurface();
// The same as a face over its whole domain.
TopoDS_Face WavyRuledFace();

// A bicubic face over 80 x 80 mm with knot lines every 10 mm both ways: one wave of 3 mm along y
// (z = 3 sin(2 pi y / 80) + slope x at the poles' Greville abscissae), so the normal is C1 across
// the knot lines y = 10, 20, ... that a pass along y crosses. With slope 0 its crest (near y = 20)
// and its trough (near y = 60) are level lines along x.
Handle(Geom_BSplineSurface) CubicWaveSurface(double slope);

// Writes `shape` as a STEP file at `path`, quietly (OpenCASCADE's writer prints its statistics
// through the messenger). Throws std::runtime_error if it cannot.
void WriteStep(const TopoDS_Shape& shape, const std::string& path);

}  // namespace dtis::test
