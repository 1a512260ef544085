// The parts dtis generates for its samples and tests (samples/parts/PROVENANCE.md): faces CAD
// makes that the public STEP files lack, written by dtis_make_part.
#pragma once

#include <Geom_BSplineSurface.hxx>
#include <TopoDS_Face.hxx>
#include <TopoDS_Shape.hxx>
#include <string>

namespace dtis::parts {

// A bicubic B-spline face over 80 x 80 mm with simple knots every 10 mm both ways (C2, so its
// normal is only C1 across the knot lines): one wave of 3 mm along y and a slope along x,
// z = 3 sin(2 pi y / 80) + slope x at the poles' Greville abscissae. With slope 0 its crest (near
// y = 20) and its trough (near y = 60) are level lines along x. The sample part has slope 0.15.
Handle(Geom_BSplineSurface) CubicWaveSurface(double slope = 0.15);
TopoDS_Face CubicWaveFace(double slope = 0.15);

// Writes `shape` as STEP AP214 (OpenCASCADE's writer, its messages silenced). Throws
// std::runtime_error naming the path when it cannot.
void WriteStep(const TopoDS_Shape& shape, const std::string& path);

}  // namespace dtis::parts
