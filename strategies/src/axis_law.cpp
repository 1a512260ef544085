#include "dtis/strategies/axis_law.hpp"

#include <Eigen/Dense>
#include <cmath>
#include <stdexcept>
#include <utility>

#include "dtis/geometry/bspline_curve.hpp"

namespace dtis::strategies {
namespace {

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
  // Beyond the knots the end spans' polynomials go on.
  const int k = geometry::KnotSpan(knots_, kDegree, x);
  geometry::BasisTable n;
  geometry::BasisDerivativesInSpan(knots_, k, x, kDegree, d_ds != nullptr ? 1 : 0, n);
  Eigen::Vector3d c = Eigen::Vector3d::Zero(), dc = Eigen::Vector3d::Zero();
  for (int j = 0; j <= kDegree; ++j) {
    const Eigen::Vector3d& p = poles_[static_cast<std::size_t>(k - kDegree + j)];
    c += n[0][static_cast<std::size_t>(j)] * p;
    if (d_ds != nullptr) dc += n[1][static_cast<std::size_t>(j)] * p;
  }
  const double norm = c.norm();
  const Eigen::Vector3d a = c / norm;
  if (d_ds != nullptr) *d_ds = (dc - a * a.dot(dc)) / norm;
  return a;
}

AxisLaw FitAxisLaw(const std::vector<double>& s, const std::vector<Eigen::Vector3d>& axes,
                   const std::vector<double>& breaks, double smoothing) {
  if (breaks.size() < 2 || s.size() != axes.size()) {
    throw std::invalid_argument("FitAxisLaw: expected two knots or more, a sample per axis");
  }
  constexpr int p = AxisLaw::kDegree;
  const std::vector<double> knots = KnotVector(breaks);
  const int n = static_cast<int>(knots.size()) - p - 1;
  if (static_cast<int>(s.size()) < 2 * n) {
    throw std::invalid_argument("FitAxisLaw: fewer samples than twice the poles");
  }
  // The normal equations (N^T W N + smoothing R) x = N^T W b, each sample and each span touching
  // p + 1 consecutive poles.
  Eigen::MatrixXd lhs = Eigen::MatrixXd::Zero(n, n);
  Eigen::MatrixXd rhs = Eigen::MatrixXd::Zero(n, 3);
  for (std::size_t i = 0; i < s.size(); ++i) {
    const double w = 0.5 * ((i + 1 < s.size() ? s[i + 1] : s[i]) - (i > 0 ? s[i - 1] : s[i]));
    double basis[p + 1];
    const int first = geometry::NonZeroBasis(knots, p, s[i], basis);
    for (int j = 0; j <= p; ++j) {
      rhs.row(first + j) += w * basis[j] * axes[i].transpose();
      for (int k = 0; k <= p; ++k) lhs(first + j, first + k) += w * basis[j] * basis[k];
    }
  }
  if (smoothing > 0.0) {
    // The third derivatives of quintic basis functions are quadratics in a span: their products
    // are quartics, which three Gauss-Legendre points integrate exactly.
    static constexpr double kNode[3] = {-0.7745966692414834, 0.0, 0.7745966692414834};
    static constexpr double kWeight[3] = {5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0};
    for (std::size_t b = 0; b + 1 < breaks.size(); ++b) {
      const double half = 0.5 * (breaks[b + 1] - breaks[b]), mid = breaks[b] + half;
      for (int g = 0; g < 3; ++g) {
        const double x = mid + half * kNode[g];
        const int span = geometry::KnotSpan(knots, p, x);
        geometry::BasisTable d;
        geometry::BasisDerivativesInSpan(knots, span, x, p, 3, d);
        const double w = smoothing * half * kWeight[g];
        for (int j = 0; j <= p; ++j) {
          for (int k = 0; k <= p; ++k) lhs(span - p + j, span - p + k) += w * d[3][j] * d[3][k];
        }
      }
    }
  }
  const Eigen::MatrixXd x = lhs.ldlt().solve(rhs);
  std::vector<Eigen::Vector3d> poles(static_cast<std::size_t>(n));
  for (int j = 0; j < n; ++j) poles[static_cast<std::size_t>(j)] = x.row(j).transpose();
  return AxisLaw(knots, std::move(poles));
}

}  // namespace dtis::strategies
