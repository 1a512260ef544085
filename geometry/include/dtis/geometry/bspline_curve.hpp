// Non-rational and rational B-spline (NURBS) curves in 2D/3D, evaluated with dtis' own kernel
// (The NURBS Book, A2.1-A2.3 and A4.2). OpenCASCADE's Geom_BSplineCurve is the reference the tests
// compare against; bench/bench_curve.cpp measures both.
#pragma once

#include <Eigen/Core>
#include <array>
#include <string>
#include <vector>

namespace dtis::geometry {

inline constexpr int kMaxCurveDegree = 15;

// No pole lies farther than this from the origin on any axis: 1 km is beyond every machine tool's
// travel, and a double there resolves about 1e-10 mm, the arc-length map's tolerance. Farther
// poles (a typo, a unit error, a corrupt file) are refused instead of planned for hours.
inline constexpr double kMaxPoleCoordinateMm = 1e6;

// The poles, knots and weights that define a curve, as read from a file. Validated by BSplineCurve.
struct BSplineCurveData {
  int degree = 3;
  std::vector<double> knots;           // size = poles + degree + 1, non-decreasing
  std::vector<Eigen::Vector3d> poles;  // 2D curves have z = 0
  std::vector<double> weights;         // empty: non-rational; else one per pole, > 0
};

class BSplineCurve {
 public:
  // Throws dtis::Error naming the first offending item (knot index, pole index, weight index).
  // `what` prefixes the messages ("curves/trident.toml: curve").
  explicit BSplineCurve(BSplineCurveData data, const std::string& what = "curve");

  int Degree() const { return degree_; }
  bool Rational() const { return !weights_.empty(); }
  double FirstParameter() const { return knots_[static_cast<std::size_t>(degree_)]; }
  double LastParameter() const { return knots_[poles_.size()]; }
  const std::vector<double>& Knots() const { return knots_; }
  const std::vector<Eigen::Vector3d>& Poles() const { return poles_; }
  const std::vector<double>& Weights() const { return weights_; }

  // The point at u (u is clamped to the domain).
  Eigen::Vector3d Point(double u) const;

  // The point and its derivatives with respect to u up to `order` (<= 3): d[0] .. d[order]. At a
  // knot the derivatives are those of the span on its right, or on its left when `from_left`.
  void Derivatives(double u, int order, Eigen::Vector3d* d, bool from_left = false) const;

  // Index of the knot span containing u: knots[span] <= u < knots[span + 1] (last span closed);
  // with `from_left`, knots[span] < u <= knots[span + 1] (first span closed).
  int FindSpan(double u, bool from_left = false) const;

 private:
  int degree_;
  std::vector<double> knots_;
  std::vector<Eigen::Vector3d> poles_;
  std::vector<double> weights_;
  std::vector<Eigen::Vector4d> weighted_;  // (w*P, w) for rational curves
};

// The degree + 1 basis functions of a knot vector that do not vanish at u (clamped to the domain),
// written to N[0..degree]; returns the index of the pole N[0] weights. For fitting, where the
// poles are the unknowns. `knots` must be valid for some number of poles (size >= 2 degree + 2).
int NonZeroBasis(const std::vector<double>& knots, int degree, double u, double* N);

// The knot span of u for poles counted from the knots' size: knots[span] <= u < knots[span + 1],
// the first span below the knot range, the last one at or above it.
int KnotSpan(const std::vector<double>& knots, int degree, double u);

// The degree + 1 basis functions that do not vanish in knot span `span` (knots[span] <= u <
// knots[span + 1], or u beyond it: the span's polynomials continued) and their derivatives up to
// order n <= degree <= kMaxCurveDegree at u: ders[k][j] is the k-th derivative of the function of
// pole span - degree + j (The NURBS Book, A2.3).
using BasisTable = std::array<std::array<double, kMaxCurveDegree + 1>, kMaxCurveDegree + 1>;
void BasisDerivativesInSpan(const std::vector<double>& knots, int span, double u, int degree, int n,
                            BasisTable& ders);

}  // namespace dtis::geometry
