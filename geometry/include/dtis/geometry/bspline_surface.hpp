// Non-periodic B-spline and NURBS surfaces evaluated with dtis' own kernel, for the surface passes'
// Newton solves: per knot span, the Taylor coefficients of the span's (homogeneous) polynomial at
// its centre, computed when a point first falls in the span (The NURBS Book, A2.3), then Horner
// with derivatives along u and along v. OpenCASCADE's adaptor evaluates the same kind of cache
// through generic loops; bench/ (SurfaceD2/) measures both, the tests compare them.
#pragma once

#include <Eigen/Core>
#include <Geom_BSplineSurface.hxx>
#include <optional>
#include <vector>

namespace dtis::geometry {

struct SurfaceDerivatives {
  Eigen::Vector3d p, su, sv, suu, suv, svv;
};

class BSplineSurfaceSpans {
 public:
  // Nothing for a surface this kernel does not take: periodic in u or v (OpenCASCADE wraps the
  // parameter), or of a degree above kMaxCurveDegree.
  static std::optional<BSplineSurfaceSpans> From(const Geom_BSplineSurface& surface);

  // The point and its derivatives up to order 2 at (u, v). Beyond the knot range the end spans'
  // polynomials continue (as OpenCASCADE's evaluation does). Not thread-safe: the span cache
  // changes.
  void D2(double u, double v, SurfaceDerivatives* d);
  Eigen::Vector3d Point(double u, double v);

 private:
  BSplineSurfaceSpans() = default;
  void Cover(double u, double v);  // loads the span of (u, v) unless it is the cached one
  void Load(double u, double v);

  int p_ = 0, q_ = 0, nu_ = 0, nv_ = 0;  // degrees, pole counts
  bool rational_ = false;
  std::vector<double> uknots_, vknots_;  // flat
  std::vector<Eigen::Vector4d> poles_;   // (w P, w), index i nv + j
  // The cached span: its (u, v) box (infinite at the ends of the knot range), its centre and the
  // Taylor coefficients there, coef_[k (q + 1) + l] = d^k/du^k d^l/dv^l (w P, w) / (k! l!).
  double ulo_ = 1.0, uhi_ = 0.0, vlo_ = 1.0, vhi_ = 0.0, uc_ = 0.0, vc_ = 0.0;
  std::vector<Eigen::Vector4d> coef_;
  std::vector<Eigen::Vector4d> scratch_;  // Load's products along u
};

}  // namespace dtis::geometry
