// Evaluation of one face of a STEP part: points and derivatives up to order 2 (B-spline and
// rational faces with dtis' own kernel, BSplineSurfaceSpans; periodic ones and analytic faces
// through OpenCASCADE's generic surface evaluation), and whether a (u, v) lies in the face's
// trimmed domain.
//
// A FaceSurface caches evaluation spans (its own, or OpenCASCADE's adaptor cache), so it is not
// thread-safe: copy one per thread (a copy builds its own cache).
#pragma once

#include <BRepTopAdaptor_FClass2d.hxx>
#include <Eigen/Core>
#include <GeomAdaptor_Surface.hxx>
#include <TopoDS_Face.hxx>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "dtis/geometry/bspline_surface.hpp"

namespace dtis::geometry {

// The face set up on the machine: rotated about the workpiece origin's X, then Y, then Z axis by
// `rotate_deg`, then moved by `translate_mm`.
TopoDS_Face PlaceFace(const TopoDS_Face& face, const Eigen::Vector3d& rotate_deg,
                      const Eigen::Vector3d& translate_mm);
// The face has one wire, each edge an iso-line (u or v constant, checked at intervals_per_edge + 1
// points) on a side of [u0, u1] x [v0, v1], to tol_fraction of the box's size.
bool BoundedByBox(const TopoDS_Face& face, double u0, double u1, double v0, double v1,
                  double tol_fraction, int intervals_per_edge);
// Axis-aligned bounding box of a face (mm): min then max corner.
std::pair<Eigen::Vector3d, Eigen::Vector3d> FaceBox(const TopoDS_Face& face);

class FaceSurface {
 public:
  // `where` names the face in messages ("part.stp face 3"). Throws dtis::Error if the face has no
  // surface.
  FaceSurface(const TopoDS_Face& face, std::string where);
  FaceSurface(const FaceSurface& other);
  FaceSurface& operator=(const FaceSurface&) = delete;
  ~FaceSurface();

  void D2(double u, double v, SurfaceDerivatives* d) const;
  Eigen::Vector3d Point(double u, double v) const;

  // The face's UV bounds (the box of its trimmed domain).
  double U0() const { return u0_; }
  double U1() const { return u1_; }
  double V0() const { return v0_; }
  double V1() const { return v1_; }
  bool Trimmed() const { return trimmed_; }
  // The parameters of the knot lines inside the UV box across which the surface's third
  // derivatives may jump (a B-spline's interior knots of multiplicity above degree - 3: every knot
  // of a cubic), sorted; none for other surfaces. A pass crossing one is a break of its path.
  const std::vector<double>& UKnotLines() const { return u_knots_; }
  const std::vector<double>& VKnotLines() const { return v_knots_; }
  // Evaluated by dtis' own B-spline kernel (BSplineSurfaceSpans), not OpenCASCADE's adaptor.
  bool OwnKernel() const { return spans_.has_value(); }
  // (u, v) lies in the face's domain: its UV box, and inside its trimming loops for a trimmed face.
  // Away from the trimming loops the answer comes from a grid over the UV box (TrimGrid below);
  // near them, from OpenCASCADE's classifier, as InsideByClassifier.
  bool Inside(double u, double v) const;
  // (u, v) lies in the face's UV box (to 1e-12 of its size), whatever the trimming loops say.
  bool InBox(double u, double v) const;
  // Inside, always asking OpenCASCADE's classifier (BRepTopAdaptor_FClass2d) of a trimmed face.
  bool InsideByClassifier(double u, double v) const;
  // Off the face without asking the classifier: off the UV box, or in a cell of the trim grid
  // wholly outside the trimming loops. False on the face and in the cells the loops cross (and,
  // for a trimmed face without a grid, wherever the classifier says it is on the face).
  bool SurelyOutside(double u, double v) const;
  // The share of the UV box the grid answers for without the classifier (1 untrimmed, 0 without
  // a grid).
  double GridCoverage() const;
  // How far (u, v) is off the face, mm: 0 inside; beyond the UV box, the distance to the point at
  // the nearest box edge; inside the box but outside a trim, infinity (not measured).
  double DistanceOutside(double u, double v) const;

  // Points along the face's boundary in UV, one list per wire, `per_edge` intervals per edge, in
  // wire order. For an untrimmed face this is its parameter rectangle.
  std::vector<std::vector<Eigen::Vector2d>> Boundary(int per_edge) const;

  const std::string& Where() const { return where_; }
  const TopoDS_Face& Face() const { return face_; }

 private:
  TopoDS_Face face_;
  std::string where_;
  GeomAdaptor_Surface surface_;
  mutable std::optional<BSplineSurfaceSpans> spans_;  // B-spline faces it takes; else surface_
  double u0_ = 0, u1_ = 0, v0_ = 0, v1_ = 0;
  bool trimmed_ = false;
  std::vector<double> u_knots_, v_knots_;
  std::unique_ptr<BRepTopAdaptor_FClass2d> classifier_;

  // Which cells of an n x n grid over the UV box the trimming loops do not come near, and on
  // which side of them each such cell lies. Built once per face from polylines of the loops'
  // pcurves (sampled until a chord strays less than a tenth of a cell from its curve) with each
  // segment's box widened by twice that stray: a cell no widened box touches holds no point of
  // the boundary, so all of it is on one side, and so is every cell connected to it through such
  // cells (one classifier call per connected region).
  struct TrimGrid {
    enum Cell : std::uint8_t { kBoundary, kIn, kOut, kUnvisited };  // kUnvisited: building
    int n = 0;
    std::vector<Cell> cells;  // row-major, v by u
  };
  TrimGrid grid_;
  void BuildTrimGrid();
  // The grid's cell holding (u, v), a point of the UV box (the grid built).
  TrimGrid::Cell GridCell(double u, double v) const;
};

}  // namespace dtis::geometry
