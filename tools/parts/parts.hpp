// The parts dtis generates for its samples and tests (samples/parts/PROVENANCE.md): faces CAD
// makes that the public STEP files lack, written by dtis_make_part.
#pragma once

#include <Geom_BSplineSurface.hxx>
#include <TopoDS_Face.hxx>
#include <TopoDS_Shape.hxx>
#include <string>

namespace dtis::parts {

// A bicubic B-spline face over 80 x 80 mm with simple knots every 10 mm both ways (C2, so its
// normal is only C1 across the knot lines): one wave of 3 mm along y and a slope of 0.15 along x,
// z = 3 sin(2 pi y / 80) + 0.15 x at the poles' Greville abscissae.
Handle(Geom_BSplineSurface) CubicWaveSurface();
TopoDS_Face CubicWaveFace();

// Writes `shape` as STEP AP214 (OpenCASCADE's writer, its messages silenced). Throws
// std::runtime_error naming the path when it cannot.
void WriteStep(const TopoDS_Shape& shape, const std::string& path);

}  // namespace dtis::parts
