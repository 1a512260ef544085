#include "fixture_shapes.hpp"

#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRep_Builder.hxx>
#include <GeomAPI_PointsToBSpline.hxx>
#include <Geom_BSplineCurve.hxx>
#include <TColStd_Array1OfInteger.hxx>
#include <TColStd_Array1OfReal.hxx>
#include <TColgp_Array1OfPnt.hxx>
#include <TColgp_Array2OfPnt.hxx>
#include <TopoDS_Compound.hxx>
#include <cmath>
#include <fstream>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "parts.hpp"

namespace dtis::test {

Handle(Geom_BSplineSurface) WavyRuledSurface() {
  Handle(Geom_BSplineCurve) wave[2];
  for (int k = 0; k < 2; ++k) {
    constexpr int kPoints = 41;
    TColgp_Array1OfPnt points(1, kPoints);
    for (int i = 1; i <= kPoints; ++i) {
      const double y = 60.0 * (i - 1) / (kPoints - 1);
      points(i) =
          gp_Pnt(60.0 * k, y,
                 3.0 * std::sin(2.0 * std::numbers::pi * y / 30.0 + k * std::numbers::pi / 3));
    }
    wave[k] = GeomAPI_PointsToBSpline(points, 3, 3, GeomAbs_C2, 1e-4).Curve();
  }
  const int n = wave[0]->NbPoles();
  if (wave[1]->NbPoles() != n) throw std::logic_error("the two waves have different poles");
  TColgp_Array2OfPnt poles(1, 2, 1, n);
  for (int k = 0; k < 2; ++k) {
    for (int i = 1; i <= n; ++i) poles(k + 1, i) = wave[k]->Pole(i);
  }
  TColStd_Array1OfReal u_knots(1, 2), v_knots(1, wave[0]->NbKnots());
  TColStd_Array1OfInteger u_mults(1, 2), v_mults(1, wave[0]->NbKnots());
  u_knots(1) = 0.0, u_knots(2) = 1.0, u_mults(1) = u_mults(2) = 2;
  wave[0]->Knots(v_knots);
  wave[0]->Multiplicities(v_mults);
  return new Geom_BSplineSurface(poles, u_knots, v_knots, u_mults, v_mults, 1, 3);
}

TopoDS_Face WavyRuledFace() {
  return BRepBuilderAPI_MakeFace(Handle(Geom_Surface)(WavyRuledSurface()), 1e-7).Face();
}

void WriteStep(const TopoDS_Shape& shape, const std::string& path) {
  parts::WriteStep(shape, path);
}

std::string WriteNamedFaces(const std::vector<std::pair<TopoDS_Face, std::string>>& faces,
                            const std::string& path) {
  TopoDS_Compound all;
  BRep_Builder builder;
  builder.MakeCompound(all);
  for (const auto& f : faces) builder.Add(all, f.first);
  const std::string unnamed = path + ".unnamed.stp";
  WriteStep(all, unnamed);
  std::ostringstream text;
  text << std::ifstream(unnamed).rdbuf();
  std::string step = text.str();
  std::size_t at = 0;
  for (const auto& f : faces) {
    at = step.find("ADVANCED_FACE('',", at);
    if (at == std::string::npos) {
      throw std::runtime_error(unnamed + " has fewer unnamed faces than were written");
    }
    if (!f.second.empty()) step.replace(at, 16, "ADVANCED_FACE('" + f.second + "'");
    ++at;
  }
  std::ofstream out(path);
  out << step;
  if (!out) throw std::runtime_error("cannot write " + path);
  return path;
}

}  // namespace dtis::test
