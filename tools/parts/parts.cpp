#include "parts.hpp"

#include <BRepBuilderAPI_MakeFace.hxx>
#include <Geom_Surface.hxx>
#include <IFSelect_ReturnStatus.hxx>
#include <Message.hxx>
#include <Message_Messenger.hxx>
#include <STEPControl_Writer.hxx>
#include <TColStd_Array1OfInteger.hxx>
#include <TColStd_Array1OfReal.hxx>
#include <TColgp_Array2OfPnt.hxx>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <vector>

namespace dtis::parts {

Handle(Geom_BSplineSurface) CubicWaveSurface(double slope) {
  constexpr int kSpans = 8, kPoles = kSpans + 3;
  constexpr double kSpan = 10.0;
  TColStd_Array1OfReal knots(1, kSpans + 1);
  TColStd_Array1OfInteger mults(1, kSpans + 1);
  for (int i = 1; i <= kSpans + 1; ++i) {
    knots(i) = kSpan * (i - 1);
    mults(i) = i == 1 || i == kSpans + 1 ? 4 : 1;
  }
  // The Greville abscissae of the clamped cubic knot vector: the poles there make x and y linear.
  std::vector<double> flat(3, 0.0);
  for (int i = 0; i <= kSpans; ++i) flat.push_back(kSpan * i);
  for (int i = 0; i < 3; ++i) flat.push_back(kSpan * kSpans);
  std::vector<double> greville;
  for (int i = 0; i < kPoles; ++i)
    greville.push_back((flat[i + 1] + flat[i + 2] + flat[i + 3]) / 3);
  TColgp_Array2OfPnt poles(1, kPoles, 1, kPoles);
  for (int i = 1; i <= kPoles; ++i) {
    for (int j = 1; j <= kPoles; ++j) {
      const double x = greville[i - 1], y = greville[j - 1];
      poles(i, j) = gp_Pnt(x, y, 3.0 * std::sin(2.0 * std::numbers::pi * y / 80.0) + slope * x);
    }
  }
  return new Geom_BSplineSurface(poles, knots, knots, mults, mults, 3, 3);
}

TopoDS_Face CubicWaveFace(double slope) {
  return BRepBuilderAPI_MakeFace(Handle(Geom_Surface)(CubicWaveSurface(slope)), 1e-7).Face();
}

void WriteStep(const TopoDS_Shape& shape, const std::string& path) {
  const Handle(Message_Messenger) messenger = Message::DefaultMessenger();
  const Message_SequenceOfPrinters printers = messenger->Printers();
  messenger->ChangePrinters().Clear();
  STEPControl_Writer writer;
  const bool written = writer.Transfer(shape, STEPControl_AsIs) == IFSelect_RetDone &&
                       writer.Write(path.c_str()) == IFSelect_RetDone;
  messenger->ChangePrinters() = printers;
  if (!written) throw std::runtime_error("could not write " + path);
}

}  // namespace dtis::parts
