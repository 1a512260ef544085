// A smoothed tool axis along one pass: a(s) = c(s) / |c(s)|, c a quintic B-spline of the three
// axis components in the pass's tip arc length s (simple interior knots: C4, so the axis is C4
// wherever c does not vanish), fitted by least squares to the orientation rule's axis sampled along
// the pass. Controllers and CAM systems smooth the tool axis within a tolerance in the same way
// (Siemens ORISON / OTOL); here the smoothing follows the exact surface: the cutter location is
// still solved by Newton on the face for the smoothed axis (surface_pass.hpp).
#pragma once

#include <Eigen/Core>
#include <vector>

namespace dtis::strategies {

class AxisLaw {
 public:
  static constexpr int kDegree = 5;

  // knots: the full knot vector (ends repeated kDegree + 1 times), poles: one per basis function.
  AxisLaw(std::vector<double> knots, std::vector<Eigen::Vector3d> poles);

  // The unit axis at arc length s of the pass (s + Shift() on the spline), and its derivative
  // d a / d s. Outside the knots' range the end spans' polynomials go on (the pass's ends may lie
  // a few nanometres past the arc length the law was fitted over).
  Eigen::Vector3d At(double s, Eigen::Vector3d* d_ds = nullptr) const;

  // The pass starts `shift` mm into the spline (its start was moved along it).
  double Shift() const { return shift_; }
  void SetShift(double shift) { shift_ = shift; }
  int Spans() const { return static_cast<int>(breaks_.size()) - 1; }
  // The distinct knots, from the first to the last.
  const std::vector<double>& Breaks() const { return breaks_; }

 private:
  std::vector<double> knots_;
  std::vector<Eigen::Vector3d> poles_;
  std::vector<double> breaks_;
  double shift_ = 0.0;
};

// Penalized least squares: the quintic c with the distinct knots `breaks` (first and last the
// range's ends, increasing) that minimizes
//   sum_i w_i |c(s_i) - axes_i|^2 + smoothing * integral |c'''(s)|^2 ds,
// w_i the arc length each sample stands for (both terms are integrals over the pass; smoothing in
// mm^6). smoothing = 0 is the plain least-squares fit; the larger it is, the smaller the axis'
// third derivative (what the rotary axes' jerk grows with) and the further from the samples.
// Each span must hold samples enough (the caller refines knots only where they are); throws
// std::invalid_argument otherwise.
AxisLaw FitAxisLaw(const std::vector<double>& s, const std::vector<Eigen::Vector3d>& axes,
                   const std::vector<double>& breaks, double smoothing = 0.0);

}  // namespace dtis::strategies
