// Arc-length reparametrization u(s) of a curve: piecewise quintic Hermite interpolation of the
// exact inverse of s(u) = integral of |C'(u)| du, built adaptively until the arc length of the
// interpolated parameter is within `tolerance_mm` of s everywhere it is checked. Positions stay
// exactly on the curve (they are C(u(s))); only the feed measured along s carries that tolerance.
#pragma once

#include <Eigen/Core>
#include <functional>
#include <vector>

namespace dtis::geometry {

struct ArcLengthOptions {
  // |s(u(s)) - s| at the checked points of every interval, mm; never below what a double resolves
  // at that arc length (64 ulps of s), so that a long curve's map ends.
  double tolerance_mm = 1e-10;
  int max_depth = 40;  // bisections of one knot span
  // Pieces allowed per knot span, and in all (whichever is larger): a curve that needs more is
  // refused (dtis::Error) rather than reparametrized for hours.
  int pieces_per_span = 256;
  int min_piece_budget = 1 << 16;
};

class ArcLengthMap {
 public:
  // `derivatives(u, order, d, from_left)` fills d[0..order] with the curve point and its
  // u-derivatives (at a break, those of the piece on its left when `from_left`).
  using Evaluator = std::function<void(double, int, Eigen::Vector3d*, bool)>;

  // `breaks` are the parameters where the curve's derivatives may jump (its distinct knots),
  // first and last included. Throws dtis::Error when the curve's speed is not finite somewhere or
  // the map would need more pieces than the options allow.
  ArcLengthMap(const Evaluator& derivatives, const std::vector<double>& breaks,
               const ArcLengthOptions& options = {});

  double Length() const { return nodes_.back().s; }

  // The Length() a map built from these arguments has, to the last bit, without building it (a
  // fraction of the work: the integrals between breaks, not the interpolation).
  static double MeasureLength(const Evaluator& derivatives, const std::vector<double>& breaks);

  // u at arc length s (clamped to [0, Length()]). `hint` is an interval index returned earlier; it
  // is updated so that walking along the curve costs O(1).
  double Parameter(double s, int* hint) const;

  // The exact arc length between two parameters (adaptive Gauss-Legendre on each piece between
  // breaks, where the speed |C'| may jump). Throws dtis::Error where the speed is not finite.
  double Integrate(double u0, double u1) const;

  // The largest |s(u(s)) - s| seen while building, mm.
  double MaxErrorMm() const { return max_error_mm_; }
  int Intervals() const { return static_cast<int>(nodes_.size()) - 1; }

 private:
  struct Node {
    double s;        // arc length at the node
    double u;        // parameter at the node
    double du_ds;    // 1/|C'|
    double d2u_ds2;  // -(C'.C'')/|C'|^4
  };
  struct Piece {
    double s0, inv_h;
    double c[6];  // u = c0 + c1 t + ... + c5 t^5, t = (s - s0) * inv_h
  };
  ArcLengthMap() = default;  // for MeasureLength
  Node MakeNode(double u, double s, bool from_left) const;
  // Interpolates between a (right-sided) and b (left-sided), appending the pieces and b's
  // right-sided twin.
  void Build(const Node& a, const Node& b, int depth);
  double Speed(double u) const;

  double IntegrateSmooth(double u0, double u1) const;

  Evaluator derivatives_;
  ArcLengthOptions options_;
  std::vector<double> breaks_;
  std::vector<Node> nodes_;
  std::vector<Piece> pieces_;
  std::size_t piece_budget_ = 0;
  double max_error_mm_ = 0.0;
};

}  // namespace dtis::geometry
