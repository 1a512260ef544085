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
    double basis[AxisLaw::kDegree + 1];
    const int first = geometry::NonZeroBasis(knots, AxisLaw::kDegree, s[i], basis);
    for (int j = 0; j <= AxisLaw::kDegree; ++j)
      a(static_cast<Eigen::Index>(i), first + j) = basis[j];
    b.row(static_cast<Eigen::Index>(i)) = axes[i].transpose();
  }
  const Eigen::MatrixXd x = a.colPivHouseholderQr().solve(b);
  std::vector<Eigen::Vector3d> poles(static_cast<std::size_t>(n));
  for (int j = 0; j < n; ++j) poles[static_cast<std::size_t>(j)] = x.row(j).transpose();
  return AxisLaw(knots, std::move(poles));
}

}  // namespace dtis::strategies
