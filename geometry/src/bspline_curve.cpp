#include "dtis/geometry/bspline_curve.hpp"

#include <algorithm>
#include <cmath>

#include "dtis/core/error.hpp"

namespace dtis::geometry {
namespace {

// Non-vanishing basis functions at u in span (A2.2). kDegree >= 0 fixes the degree at compile
// time, so that the loops unroll (the same operations in the same order: the same bits).
template <int kDegree>
void BasisFunctionsOfDegree(const std::vector<double>& U, int span, double u, int degree,
                            double* N) {
  const int p = kDegree >= 0 ? kDegree : degree;
  std::array<double, kMaxCurveDegree + 1> left, right;
  N[0] = 1.0;
  for (int j = 1; j <= p; ++j) {
    left[j] = u - U[static_cast<std::size_t>(span + 1 - j)];
    right[j] = U[static_cast<std::size_t>(span + j)] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      const double temp = N[r] / (right[r + 1] + left[j - r]);
      N[r] = saved + right[r + 1] * temp;
      saved = left[j - r] * temp;
    }
    N[j] = saved;
  }
}

void BasisFunctions(const std::vector<double>& U, int span, double u, int p, double* N) {
  switch (p) {
    case 2:
      return BasisFunctionsOfDegree<2>(U, span, u, p, N);
    case 3:
      return BasisFunctionsOfDegree<3>(U, span, u, p, N);
    default:
      return BasisFunctionsOfDegree<-1>(U, span, u, p, N);
  }
}

// Basis functions and their derivatives up to n at u in span (A2.3): ders[k][j].
//
// Only the entries [0..p][0..p] of ndu and [0..n][0..p] of ders are written and read, so neither
// table is cleared: zeroing their 2 x 2 KB cost more than the recurrences themselves at degree 3.
template <int kDegree>
void BasisDerivativesOfDegree(const std::vector<double>& U, int span, double u, int degree, int n,
                              BasisTable& ders) {
  const int p = kDegree >= 0 ? kDegree : degree;
  BasisTable ndu;
  std::array<double, kMaxCurveDegree + 1> left, right;
  ndu[0][0] = 1.0;
  for (int j = 1; j <= p; ++j) {
    left[j] = u - U[static_cast<std::size_t>(span + 1 - j)];
    right[j] = U[static_cast<std::size_t>(span + j)] - u;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      ndu[j][r] = right[r + 1] + left[j - r];
      const double temp = ndu[r][j - 1] / ndu[j][r];
      ndu[r][j] = saved + right[r + 1] * temp;
      saved = left[j - r] * temp;
    }
    ndu[j][j] = saved;
  }
  for (int j = 0; j <= p; ++j) ders[0][j] = ndu[j][p];
  std::array<std::array<double, kMaxCurveDegree + 1>, 2> a;
  for (int r = 0; r <= p; ++r) {
    int s1 = 0, s2 = 1;
    a[0][0] = 1.0;
    for (int k = 1; k <= n; ++k) {
      double d = 0.0;
      const int rk = r - k, pk = p - k;
      if (r >= k) {
        a[s2][0] = a[s1][0] / ndu[pk + 1][rk];
        d = a[s2][0] * ndu[rk][pk];
      }
      const int j1 = rk >= -1 ? 1 : -rk;
      const int j2 = r - 1 <= pk ? k - 1 : p - r;
      for (int j = j1; j <= j2; ++j) {
        a[s2][j] = (a[s1][j] - a[s1][j - 1]) / ndu[pk + 1][rk + j];
        d += a[s2][j] * ndu[rk + j][pk];
      }
      if (r <= pk) {
        a[s2][k] = -a[s1][k - 1] / ndu[pk + 1][r];
        d += a[s2][k] * ndu[r][pk];
      }
      ders[k][r] = d;
      std::swap(s1, s2);
    }
  }
  double factor = p;
  for (int k = 1; k <= n; ++k) {
    for (int j = 0; j <= p; ++j) ders[k][j] *= factor;
    factor *= p - k;
  }
}

}  // namespace

void BasisDerivativesInSpan(const std::vector<double>& U, int span, double u, int p, int n,
                            BasisTable& ders) {
  switch (p) {
    case 2:
      return BasisDerivativesOfDegree<2>(U, span, u, p, n, ders);
    case 3:
      return BasisDerivativesOfDegree<3>(U, span, u, p, n, ders);
    default:
      return BasisDerivativesOfDegree<-1>(U, span, u, p, n, ders);
  }
}

BSplineCurve::BSplineCurve(BSplineCurveData data, const std::string& what)
    : degree_(data.degree),
      knots_(std::move(data.knots)),
      poles_(std::move(data.poles)),
      weights_(std::move(data.weights)) {
  const int p = degree_;
  if (p < 1 || p > kMaxCurveDegree) {
    throw Error("{}: degree {} is not supported; expected 1..{}", what, p, kMaxCurveDegree);
  }
  const std::size_t n = poles_.size();
  if (n < static_cast<std::size_t>(p) + 1) {
    throw Error("{}: {} poles for degree {}; expected at least degree + 1 = {}", what, n, p, p + 1);
  }
  if (knots_.size() != n + static_cast<std::size_t>(p) + 1) {
    throw Error("{}: {} knots for {} poles of degree {}; expected poles + degree + 1 = {}", what,
                knots_.size(), n, p, n + static_cast<std::size_t>(p) + 1);
  }
  for (std::size_t i = 0; i < knots_.size(); ++i) {
    if (!std::isfinite(knots_[i])) throw Error("{}: knot {} is not a finite number", what, i);
    if (i > 0 && knots_[i] < knots_[i - 1]) {
      throw Error("{}: knots must not decrease, but knot {} ({}) < knot {} ({})", what, i,
                  knots_[i], i - 1, knots_[i - 1]);
    }
  }
  if (!(FirstParameter() < LastParameter())) {
    throw Error("{}: the parameter domain [knot {}, knot {}] = [{}, {}] is empty", what, p, n,
                FirstParameter(), LastParameter());
  }
  // A knot inside the domain repeated more than `degree` times breaks the curve; at the ends more
  // than degree + 1 copies leave poles that nothing uses.
  for (std::size_t i = 0; i < knots_.size();) {
    std::size_t j = i;
    while (j + 1 < knots_.size() && knots_[j + 1] == knots_[i]) ++j;
    const std::size_t m = j - i + 1;
    const bool inside = knots_[i] > FirstParameter() && knots_[i] < LastParameter();
    const std::size_t allowed = static_cast<std::size_t>(inside ? p : p + 1);
    if (m > allowed) {
      throw Error("{}: knot value {} (knots {}..{}) has multiplicity {}; at most {} is allowed {}",
                  what, knots_[i], i, j, m, allowed, inside ? "inside the domain" : "at an end");
    }
    i = j + 1;
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!poles_[i].allFinite()) throw Error("{}: pole {} is not finite", what, i);
    if (poles_[i].cwiseAbs().maxCoeff() > kMaxPoleCoordinateMm) {
      throw Error(
          "{}: pole {} ({}, {}, {}) is more than {:g} mm from the origin on an axis; "
          "no machine's travel reaches there (check the units)",
          what, i, poles_[i].x(), poles_[i].y(), poles_[i].z(), kMaxPoleCoordinateMm);
    }
  }
  if (!weights_.empty()) {
    if (weights_.size() != n) {
      throw Error("{}: {} weights for {} poles; expected one weight per pole", what,
                  weights_.size(), n);
    }
    bool all_one = true;
    for (std::size_t i = 0; i < n; ++i) {
      if (!(weights_[i] > 0.0) || !std::isfinite(weights_[i])) {
        throw Error("{}: weight {} is {}; weights must be finite and > 0", what, i, weights_[i]);
      }
      all_one = all_one && weights_[i] == 1.0;
    }
    if (all_one) weights_.clear();
    weighted_.reserve(n);
    for (std::size_t i = 0; i < weights_.size(); ++i) {
      weighted_.emplace_back(poles_[i].x() * weights_[i], poles_[i].y() * weights_[i],
                             poles_[i].z() * weights_[i], weights_[i]);
    }
  }
}

int BSplineCurve::FindSpan(double u, bool from_left) const {
  const int n = static_cast<int>(poles_.size()) - 1;
  const int p = degree_;
  if (from_left && u > knots_[static_cast<std::size_t>(p)]) {
    // The span whose half-open interval (knots[span], knots[span + 1]] holds u.
    const auto first = knots_.begin() + p;
    const auto last = knots_.begin() + n + 2;
    const int span = static_cast<int>(std::lower_bound(first, last, u) - knots_.begin()) - 1;
    return std::clamp(span, p, n);
  }
  if (u >= knots_[static_cast<std::size_t>(n + 1)]) {
    int span = n;
    while (span > p &&
           knots_[static_cast<std::size_t>(span)] == knots_[static_cast<std::size_t>(span + 1)]) {
      --span;
    }
    return span;
  }
  if (u <= knots_[static_cast<std::size_t>(p)]) {
    int span = p;
    while (span < n && knots_[static_cast<std::size_t>(span + 1)] <= u) ++span;
    return span;
  }
  const auto first = knots_.begin() + p;
  const auto last = knots_.begin() + n + 2;
  return static_cast<int>(std::upper_bound(first, last, u) - knots_.begin()) - 1;
}

int KnotSpan(const std::vector<double>& knots, int degree, double u) {
  const int p = degree;
  const int n = static_cast<int>(knots.size()) - p - 2;  // last pole index
  const auto first = knots.begin() + p;
  const auto last = knots.begin() + n + 1;  // the last span is closed on the right
  return std::clamp(static_cast<int>(std::upper_bound(first, last, u) - knots.begin()) - 1, p, n);
}

int NonZeroBasis(const std::vector<double>& knots, int degree, double u, double* N) {
  const int p = degree;
  const int n = static_cast<int>(knots.size()) - p - 2;  // last pole index
  u = std::clamp(u, knots[static_cast<std::size_t>(p)], knots[static_cast<std::size_t>(n + 1)]);
  const int span = KnotSpan(knots, p, u);
  BasisFunctions(knots, span, u, p, N);
  return span - p;
}

Eigen::Vector3d BSplineCurve::Point(double u) const {
  u = std::clamp(u, FirstParameter(), LastParameter());
  const int span = FindSpan(u);
  std::array<double, kMaxCurveDegree + 1> N;
  BasisFunctions(knots_, span, u, degree_, N.data());
  const std::size_t first = static_cast<std::size_t>(span - degree_);
  if (weights_.empty()) {
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (int j = 0; j <= degree_; ++j) c += N[j] * poles_[first + j];
    return c;
  }
  Eigen::Vector4d cw = Eigen::Vector4d::Zero();
  for (int j = 0; j <= degree_; ++j) cw += N[j] * weighted_[first + j];
  return cw.head<3>() / cw.w();
}

void BSplineCurve::Derivatives(double u, int order, Eigen::Vector3d* d, bool from_left) const {
  order = std::clamp(order, 0, 3);
  u = std::clamp(u, FirstParameter(), LastParameter());
  const int span = FindSpan(u, from_left);
  const int n = std::min(order, degree_);
  BasisTable ders;
  BasisDerivativesInSpan(knots_, span, u, degree_, n, ders);
  const std::size_t first = static_cast<std::size_t>(span - degree_);
  if (weights_.empty()) {
    for (int k = 0; k <= order; ++k) {
      d[k].setZero();
      if (k > n) continue;
      for (int j = 0; j <= degree_; ++j) d[k] += ders[k][j] * poles_[first + j];
    }
    return;
  }
  // Rational: derivatives of the homogeneous curve, then A4.2.
  std::array<Eigen::Vector4d, 4> aw;
  for (int k = 0; k <= order; ++k) {
    aw[k].setZero();
    if (k > n) continue;
    for (int j = 0; j <= degree_; ++j) aw[k] += ders[k][j] * weighted_[first + j];
  }
  static constexpr int kBinomial[4][4] = {{1, 0, 0, 0}, {1, 1, 0, 0}, {1, 2, 1, 0}, {1, 3, 3, 1}};
  for (int k = 0; k <= order; ++k) {
    Eigen::Vector3d v = aw[k].head<3>();
    for (int i = 1; i <= k; ++i) v -= kBinomial[k][i] * aw[i].w() * d[k - i];
    d[k] = v / aw[0].w();
  }
}

}  // namespace dtis::geometry
