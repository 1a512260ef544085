#include "dtis/geometry/occt_convert.hpp"

#include <TColStd_Array1OfInteger.hxx>
#include <TColStd_Array1OfReal.hxx>
#include <TColgp_Array1OfPnt.hxx>

namespace dtis::geometry {

Handle(Geom_BSplineCurve) ToOcct(const BSplineCurve& curve) {
  const auto& poles = curve.Poles();
  TColgp_Array1OfPnt p(1, static_cast<int>(poles.size()));
  for (std::size_t i = 0; i < poles.size(); ++i) {
    p.SetValue(static_cast<int>(i) + 1, gp_Pnt(poles[i].x(), poles[i].y(), poles[i].z()));
  }
  std::vector<double> values;
  std::vector<int> multiplicities;
  for (const double k : curve.Knots()) {
    if (!values.empty() && values.back() == k) {
      ++multiplicities.back();
    } else {
      values.push_back(k);
      multiplicities.push_back(1);
    }
  }
  TColStd_Array1OfReal knots(1, static_cast<int>(values.size()));
  TColStd_Array1OfInteger mults(1, static_cast<int>(values.size()));
  for (std::size_t i = 0; i < values.size(); ++i) {
    knots.SetValue(static_cast<int>(i) + 1, values[i]);
    mults.SetValue(static_cast<int>(i) + 1, multiplicities[i]);
  }
  if (!curve.Rational()) return new Geom_BSplineCurve(p, knots, mults, curve.Degree());
  TColStd_Array1OfReal w(1, static_cast<int>(poles.size()));
  for (std::size_t i = 0; i < poles.size(); ++i) {
    w.SetValue(static_cast<int>(i) + 1, curve.Weights()[i]);
  }
  return new Geom_BSplineCurve(p, w, knots, mults, curve.Degree());
}

}  // namespace dtis::geometry
