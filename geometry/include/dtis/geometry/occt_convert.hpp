// Conversions between dtis' curve kernel and OpenCASCADE's, used as an independent reference.
#pragma once

#include <Geom_BSplineCurve.hxx>
#include <Standard_Handle.hxx>

#include "dtis/geometry/bspline_curve.hpp"

namespace dtis::geometry {

Handle(Geom_BSplineCurve) ToOcct(const BSplineCurve& curve);

}  // namespace dtis::geometry
