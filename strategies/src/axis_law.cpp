#include "dtis/strategies/axis_law.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace dtis::strategies {
namespace {

// The knot span [knots[k], knots[k + 1]) holding x, clamped to the first and last non-empty spans
// (outside the range their polynomials go on).
int SpanOf(const std::vector<double>& knots, int degree, double x) {
  const int n = static_cast<int>(knots.size()) - degree - 1;  // basis functions
  if (x >= knots[static_cast<std::size_t>(n)]) return n - 1;
  if (x <= knots[static_cast<std::size_t>(degree)]) return degree;
  const auto it = std::upper_bound(knots.begin() + degree, knots.begin() + n + 1, x);
  return static_cast<int>(it - knots.begin()) - 1;
}

// The degree + 1 non-zero basis functions of degree `degree` on span k at x (Piegl and Tiller,
// The NURBS Book, A2.2); x may lie outside the span (its polynomial continued).
void Basis(const std::vector<double>& knots, int k, int degree, double x, double* out) {
  double left[AxisLaw::kDegree + 1], right[AxisLaw::kDegree + 1];
  out[0] = 1.0;
  for (int j = 1; j <= degree; ++j) {
    left[j] = x - knots[static_cast<std::size_t>(k + 1 - j)];
    right[j] = knots[static_cast<std::size_t>(k + j)] - x;
    double saved = 0.0;
    for (int r = 0; r < j; ++r) {
      const double temp = out[r] / (right[r + 1] + left[j - r]);
      out[r] = saved + right[r + 1] * temp;
      saved = left[j - r] * temp;
    }
    out[j] = saved;
  }
}

std::vector<double> KnotVector(const std::vector<double>& breaks) {
  std::vector<double> knots(AxisLaw::kDegree, breaks.front());
  knots.insert(knots.end(), breaks.begin(), breaks.end());
  knots.insert(knots.end(), AxisLaw::kDegree, breaks.back());
  return knots;
}

}  // namespace

AxisLaw::AxisLaw(std::vector<double> knots, std::vector<Eigen::Vector3d> poles)
    : knots_(std::move(knots)), poles_(std::move(poles)) {
  for (std::size_t i = kDegree; i + kDegree < knots_.size(); ++i) {
    if (breaks_.empty() || knots_[i] > breaks_.back()) breaks_.push_back(knots_[i]);
  }
}

Eigen::Vector3d AxisLaw::At(double s, Eigen::Vector3d* d_ds) const {
  const double x = s + shift_;
  const int k = SpanOf(knots_, kDegree, x);
  double n[kDegree + 1];
  Basis(knots_, k, kDegree, x, n);
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (int j = 0; j <= kDegree; ++j) c += n[j] * poles_[static_cast<std::size_t>(k - kDegree + j)];
  const double norm = c.norm();
  const Eigen::Vector3d a = c / norm;
  if (d_ds != nullptr) {
    // c' = sum of the degree-4 basis times p (P_i+1 - P_i) / (t_i+p+1 - t_i+1).
    double m[kDegree];
    Basis(knots_, k, kDegree - 1, x, m);
    Eigen::Vector3d dc = Eigen::Vector3d::Zero();
    for (int j = 0; j < kDegree; ++j) {
      const int i = k - kDegree + 1 + j;  // the derivative's pole i - 1 -> i
      const double span =
          knots_[static_cast<std::size_t>(i + kDegree)] - knots_[static_cast<std::size_t>(i)];
      dc += m[j] * (kDegree / span) *
            (poles_[static_cast<std::size_t>(i)] - poles_[static_cast<std::size_t>(i - 1)]);
    }
    *d_ds = (dc - a * a.dot(dc)) / norm;
  }
  return a;
}

AxisLaw FitAxisLaw(const std::vector<double>& s, const std::vector<Eigen::Vector3d>& axes,
                   const std::vector<double>& breaks) {
  if (breaks.size() < 2 || s.size() != axes.size()) {
    throw std::invalid_argument("FitAxisLaw: expected two knots or more, a sample per axis");
  }
  const std::vector<double> knots = KnotVector(breaks);
  const int n = static_cast<int>(knots.size()) - AxisLaw::kDegree - 1;
  if (static_cast<int>(s.size()) < 2 * n) {
    throw std::invalid_argument("FitAxisLaw: fewer samples than twice the poles");
  }
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(static_cast<Eigen::Index>(s.size()), n);
  Eigen::MatrixXd b(static_cast<Eigen::Index>(s.size()), 3);
  for (std::size_t i = 0; i < s.size(); ++i) {
    const int k = SpanOf(knots, AxisLaw::kDegree, s[i]);
    double basis[AxisLaw::kDegree + 1];
    Basis(knots, k, AxisLaw::kDegree, s[i], basis);
    for (int j = 0; j <= AxisLaw::kDegree; ++j) {
      a(static_cast<Eigen::Index>(i), k - AxisLaw::kDegree + j) = basis[j];
    }
    b.row(static_cast<Eigen::Index>(i)) = axes[i].transpose();
  }
  const Eigen::MatrixXd x = a.colPivHouseholderQr().solve(b);
  std::vector<Eigen::Vector3d> poles(static_cast<std::size_t>(n));
  for (int j = 0; j < n; ++j) poles[static_cast<std::size_t>(j)] = x.row(j).transpose();
  return AxisLaw(knots, std::move(poles));
}

}  // namespace dtis::strategies
