#include "dtis/geometry/face_surface.hpp"

#include <BRepBndLib.hxx>
#include <BRepTools.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <Geom2d_Curve.hxx>
#include <Geom_BSplineSurface.hxx>
#include <Geom_Surface.hxx>
#include <TColStd_Array1OfInteger.hxx>
#include <TColStd_Array1OfReal.hxx>
#include <TopExp_Explorer.hxx>
#include <TopLoc_Location.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Edge.hxx>
#include <TopoDS_Wire.hxx>
#include <algorithm>
#include <cmath>
#include <gp.hxx>
#include <gp_Ax1.hxx>
#include <gp_Pnt2d.hxx>
#include <gp_Trsf.hxx>

#include "dtis/core/error.hpp"

namespace dtis::geometry {
namespace {

Eigen::Vector3d V(const gp_Pnt& p) { return {p.X(), p.Y(), p.Z()}; }
Eigen::Vector3d V(const gp_Vec& p) { return {p.X(), p.Y(), p.Z()}; }

}  // namespace

bool BoundedByBox(const TopoDS_Face& face, double u0, double u1, double v0, double v1,
                  double tol_fraction, int intervals_per_edge) {
  int wires = 0;
  for (TopExp_Explorer w(face, TopAbs_WIRE); w.More(); w.Next()) ++wires;
  if (wires != 1) return false;
  const double tol = tol_fraction * std::max({1.0, u1 - u0, v1 - v0});
  const auto at = [tol](double x, double a, double b) {
    return std::abs(x - a) < tol || std::abs(x - b) < tol;
  };
  for (TopExp_Explorer e(face, TopAbs_EDGE); e.More(); e.Next()) {
    double f = 0, l = 0;
    const Handle(Geom2d_Curve) pc =
        BRep_Tool::CurveOnSurface(TopoDS::Edge(e.Current()), face, f, l);
    if (pc.IsNull()) return false;
    const gp_Pnt2d first = pc->Value(f);
    bool on_u = true, on_v = true;
    for (int k = 1; k <= intervals_per_edge; ++k) {
      const gp_Pnt2d p = pc->Value(f + (l - f) * k / intervals_per_edge);
      on_u = on_u && std::abs(p.X() - first.X()) < tol;
      on_v = on_v && std::abs(p.Y() - first.Y()) < tol;
    }
    if (!(on_u && at(first.X(), u0, u1)) && !(on_v && at(first.Y(), v0, v1))) return false;
  }
  return true;
}

TopoDS_Face PlaceFace(const TopoDS_Face& face, const Eigen::Vector3d& rotate_deg,
                      const Eigen::Vector3d& translate_mm) {
  gp_Trsf trsf;
  const gp_Ax1 axes[3] = {gp::OX(), gp::OY(), gp::OZ()};
  for (int i = 0; i < 3; ++i) {
    if (rotate_deg[i] == 0.0) continue;
    gp_Trsf r;
    r.SetRotation(axes[i], rotate_deg[i] * M_PI / 180.0);
    trsf = r * trsf;
  }
  gp_Trsf t;
  t.SetTranslation(gp_Vec(translate_mm.x(), translate_mm.y(), translate_mm.z()));
  trsf = t * trsf;
  return TopoDS::Face(face.Moved(TopLoc_Location(trsf)));
}

std::pair<Eigen::Vector3d, Eigen::Vector3d> FaceBox(const TopoDS_Face& face) {
  Bnd_Box box;
  BRepBndLib::AddOptimal(face, box, Standard_False, Standard_False);
  if (box.IsVoid()) return {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  double x0, y0, z0, x1, y1, z1;
  box.Get(x0, y0, z0, x1, y1, z1);
  return {{x0, y0, z0}, {x1, y1, z1}};
}

FaceSurface::FaceSurface(const TopoDS_Face& face, std::string where)
    : face_(face), where_(std::move(where)) {
  const Handle(Geom_Surface) s = BRep_Tool::Surface(face_);
  if (s.IsNull()) throw Error("{}: the face has no surface", where_);
  surface_.Load(s);
  if (surface_.GetType() == GeomAbs_BSplineSurface) {
    spans_ = BSplineSurfaceSpans::From(*surface_.BSpline());
  }
  BRepTools::UVBounds(face_, u0_, u1_, v0_, v1_);
  if (surface_.GetType() == GeomAbs_BSplineSurface) {
    const Handle(Geom_BSplineSurface) b = surface_.BSpline();
    // Interior knots where the continuity is below C3 (degree - multiplicity < 3).
    const auto lines = [](const TColStd_Array1OfReal& knots, const TColStd_Array1OfInteger& mults,
                          int degree, double lo, double hi) {
      std::vector<double> out;
      const double eps = 1e-12 * std::max(1.0, hi - lo);
      for (int i = knots.Lower(); i <= knots.Upper(); ++i) {
        if (knots(i) > lo + eps && knots(i) < hi - eps && degree - mults(i) < 3) {
          out.push_back(knots(i));
        }
      }
      return out;
    };
    u_knots_ = lines(b->UKnots(), b->UMultiplicities(), b->UDegree(), u0_, u1_);
    v_knots_ = lines(b->VKnots(), b->VMultiplicities(), b->VDegree(), v0_, v1_);
  }
  // The domain is the UV box unless the face's boundary is not that box's four sides.
  trimmed_ = !BoundedByBox(face_, u0_, u1_, v0_, v1_, 1e-9, 2);
  if (trimmed_) {
    const double tol = 1e-9 * std::max({1.0, u1_ - u0_, v1_ - v0_});
    classifier_ = std::make_unique<BRepTopAdaptor_FClass2d>(face_, tol);
    BuildTrimGrid();
  }
}

void FaceSurface::BuildTrimGrid() {
  constexpr int kCells = 256;
  const double du = u1_ - u0_, dv = v1_ - v0_;
  if (!(du > 0.0) || !(dv > 0.0)) return;
  // In cell units: x = (u - u0) / du * n.
  const auto cell_xy = [&](const gp_Pnt2d& p) {
    return Eigen::Vector2d((p.X() - u0_) / du * kCells, (p.Y() - v0_) / dv * kCells);
  };
  // Every cell starts unvisited; the loops' cells become kBoundary, the rest kIn or kOut.
  std::vector<TrimGrid::Cell> cells(kCells * kCells, TrimGrid::kUnvisited);
  const auto at = [&](int k) -> TrimGrid::Cell& { return cells[static_cast<std::size_t>(k)]; };
  const auto mark = [&](Eigen::Vector2d a, Eigen::Vector2d b, double widen) {
    const int x0 = std::max(0, static_cast<int>(std::floor(std::min(a.x(), b.x()) - widen)));
    const int x1 =
        std::min(kCells - 1, static_cast<int>(std::floor(std::max(a.x(), b.x()) + widen)));
    const int y0 = std::max(0, static_cast<int>(std::floor(std::min(a.y(), b.y()) - widen)));
    const int y1 =
        std::min(kCells - 1, static_cast<int>(std::floor(std::max(a.y(), b.y()) + widen)));
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) at(y * kCells + x) = TrimGrid::kBoundary;
    }
  };
  for (TopExp_Explorer e(face_, TopAbs_EDGE); e.More(); e.Next()) {
    double f = 0, l = 0;
    const Handle(Geom2d_Curve) pc =
        BRep_Tool::CurveOnSurface(TopoDS::Edge(e.Current()), face_, f, l);
    if (pc.IsNull() || !std::isfinite(f) || !std::isfinite(l)) return;  // no grid: classify all
    // Halve the chords until every chord's midpoint lies within a tenth of a cell of the curve's.
    double stray = 0.0;
    std::vector<Eigen::Vector2d> points;
    for (int segments = 16;; segments *= 2) {
      points.clear();
      stray = 0.0;
      for (int k = 0; k <= segments; ++k)
        points.push_back(cell_xy(pc->Value(f + (l - f) * k / segments)));
      for (int k = 0; k < segments; ++k) {
        const Eigen::Vector2d mid = cell_xy(pc->Value(f + (l - f) * (k + 0.5) / segments));
        stray = std::max(stray, (mid - 0.5 * (points[k] + points[k + 1])).norm());
      }
      if (!std::isfinite(stray)) return;
      if (stray < 0.1 || segments >= 4096) break;
    }
    if (stray >= 0.1) return;  // a curve the sampling cannot follow: no grid
    for (std::size_t k = 0; k + 1 < points.size(); ++k)
      mark(points[k], points[k + 1], 2.0 * stray + 1e-6);
  }
  // One side per connected region of cells the boundary does not come near.
  std::vector<int> stack;
  for (int start = 0; start < kCells * kCells; ++start) {
    if (at(start) != TrimGrid::kUnvisited) continue;
    const int sx = start % kCells, sy = start / kCells;
    const TrimGrid::Cell side =
        InsideByClassifier(u0_ + du * (sx + 0.5) / kCells, v0_ + dv * (sy + 0.5) / kCells)
            ? TrimGrid::kIn
            : TrimGrid::kOut;
    stack.assign(1, start);
    at(start) = side;
    while (!stack.empty()) {
      const int x = stack.back() % kCells, y = stack.back() / kCells;
      stack.pop_back();
      const int next[4][2] = {{x - 1, y}, {x + 1, y}, {x, y - 1}, {x, y + 1}};
      for (const auto& [nx, ny] : next) {
        if (nx < 0 || ny < 0 || nx >= kCells || ny >= kCells) continue;
        const int k = ny * kCells + nx;
        if (at(k) != TrimGrid::kUnvisited) continue;
        at(k) = side;
        stack.push_back(k);
      }
    }
  }
  grid_.n = kCells;
  grid_.cells = std::move(cells);
}

double FaceSurface::GridCoverage() const {
  if (!classifier_) return 1.0;
  if (grid_.n == 0) return 0.0;
  const auto certain = std::count_if(grid_.cells.begin(), grid_.cells.end(),
                                     [](TrimGrid::Cell c) { return c != TrimGrid::kBoundary; });
  return static_cast<double>(certain) / static_cast<double>(grid_.cells.size());
}

FaceSurface::FaceSurface(const FaceSurface& other) : FaceSurface(other.face_, other.where_) {}

FaceSurface::~FaceSurface() = default;

void FaceSurface::D2(double u, double v, SurfaceDerivatives* d) const {
  if (spans_) return spans_->D2(u, v, d);
  gp_Pnt p;
  gp_Vec su, sv, suu, svv, suv;
  surface_.D2(u, v, p, su, sv, suu, svv, suv);
  d->p = V(p);
  d->su = V(su);
  d->sv = V(sv);
  d->suu = V(suu);
  d->suv = V(suv);
  d->svv = V(svv);
}

Eigen::Vector3d FaceSurface::Point(double u, double v) const {
  if (spans_) return spans_->Point(u, v);
  return V(surface_.Value(u, v));
}

bool FaceSurface::InBox(double u, double v) const {
  const double tol = 1e-12 * std::max({1.0, u1_ - u0_, v1_ - v0_});
  return u >= u0_ - tol && u <= u1_ + tol && v >= v0_ - tol && v <= v1_ + tol;
}

FaceSurface::TrimGrid::Cell FaceSurface::GridCell(double u, double v) const {
  const int n = grid_.n;
  const int x = std::clamp(static_cast<int>((u - u0_) / (u1_ - u0_) * n), 0, n - 1);
  const int y = std::clamp(static_cast<int>((v - v0_) / (v1_ - v0_) * n), 0, n - 1);
  return grid_.cells[static_cast<std::size_t>(y * n + x)];
}

bool FaceSurface::Inside(double u, double v) const {
  if (!InBox(u, v)) return false;
  if (!classifier_) return true;
  if (grid_.n > 0) {
    const TrimGrid::Cell cell = GridCell(u, v);
    if (cell != TrimGrid::kBoundary) return cell == TrimGrid::kIn;
  }
  return InsideByClassifier(u, v);
}

bool FaceSurface::SurelyOutside(double u, double v) const {
  if (!InBox(u, v)) return true;
  if (!classifier_) return false;
  if (grid_.n == 0) return !InsideByClassifier(u, v);
  return GridCell(u, v) == TrimGrid::kOut;
}

bool FaceSurface::InsideByClassifier(double u, double v) const {
  if (!InBox(u, v)) return false;
  if (!classifier_) return true;
  const TopAbs_State state = classifier_->Perform(gp_Pnt2d(u, v), Standard_False);
  return state == TopAbs_IN || state == TopAbs_ON;
}

double FaceSurface::DistanceOutside(double u, double v) const {
  if (Inside(u, v)) return 0.0;
  const double cu = std::clamp(u, u0_, u1_), cv = std::clamp(v, v0_, v1_);
  if (cu == u && cv == v) return INFINITY;
  // The distance to the nearest violated side of the UV box, along that side (Newton on the
  // side's free parameter): clamping alone misjudges it on a skewed parametrization.
  const Eigen::Vector3d p = Point(u, v);
  double best = INFINITY;
  SurfaceDerivatives d;
  const auto along_side = [&](bool fixed_u, double fixed, double t, double lo, double hi) {
    for (int it = 0; it < 20; ++it) {
      const double su = fixed_u ? fixed : t, sv = fixed_u ? t : fixed;
      D2(su, sv, &d);
      const Eigen::Vector3d r = d.p - p, dt = fixed_u ? d.sv : d.su, dtt = fixed_u ? d.svv : d.suu;
      const double f = r.dot(dt), fp = dt.squaredNorm() + r.dot(dtt);
      if (!(fp > 0.0)) break;
      const double next = std::clamp(t - f / fp, lo, hi);
      if (std::abs(next - t) <= 1e-14 * (1.0 + std::abs(t))) break;
      t = next;
    }
    const double su = fixed_u ? fixed : t, sv = fixed_u ? t : fixed;
    best = std::min(best, (Point(su, sv) - p).norm());
  };
  if (u != cu) along_side(true, cu, cv, v0_, v1_);
  if (v != cv) along_side(false, cv, cu, u0_, u1_);
  return best;
}

std::vector<std::vector<Eigen::Vector2d>> FaceSurface::Boundary(int per_edge) const {
  std::vector<std::vector<Eigen::Vector2d>> loops;
  if (!trimmed_) {
    std::vector<Eigen::Vector2d> loop;
    const Eigen::Vector2d corner[5] = {{u0_, v0_}, {u1_, v0_}, {u1_, v1_}, {u0_, v1_}, {u0_, v0_}};
    for (int side = 0; side < 4; ++side) {
      for (int k = 0; k < per_edge; ++k) {
        loop.push_back(corner[side] + (corner[side + 1] - corner[side]) * k / per_edge);
      }
    }
    loop.push_back(corner[0]);
    loops.push_back(std::move(loop));
    return loops;
  }
  for (TopExp_Explorer w(face_, TopAbs_WIRE); w.More(); w.Next()) {
    std::vector<Eigen::Vector2d> loop;
    for (TopExp_Explorer e(w.Current(), TopAbs_EDGE); e.More(); e.Next()) {
      const TopoDS_Edge& edge = TopoDS::Edge(e.Current());
      double f = 0, l = 0;
      const Handle(Geom2d_Curve) pc = BRep_Tool::CurveOnSurface(edge, face_, f, l);
      if (pc.IsNull()) continue;
      const bool reversed = edge.Orientation() == TopAbs_REVERSED;
      for (int k = 0; k <= per_edge; ++k) {
        const double t = reversed ? l - (l - f) * k / per_edge : f + (l - f) * k / per_edge;
        const gp_Pnt2d p = pc->Value(t);
        loop.emplace_back(p.X(), p.Y());
      }
    }
    if (!loop.empty()) loops.push_back(std::move(loop));
  }
  return loops;
}

}  // namespace dtis::geometry
