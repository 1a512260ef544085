#include "dtis/geometry/arc_length.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include "dtis/core/error.hpp"

namespace dtis::geometry {
namespace {

// 8-point Gauss-Legendre nodes and weights on [-1, 1].
constexpr std::array<double, 8> kX = {-0.9602898564975363, -0.7966664774136267, -0.5255324099163290,
                                      -0.1834346424956498, 0.1834346424956498,  0.5255324099163290,
                                      0.7966664774136267,  0.9602898564975363};
constexpr std::array<double, 8> kW = {0.1012285362903763, 0.2223810344533745, 0.3137066458778873,
                                      0.3626837833783620, 0.3626837833783620, 0.3137066458778873,
                                      0.2223810344533745, 0.1012285362903763};

Eigen::Array<double, 6, 1> HermiteCoefficients(double u0, double d0, double c0, double u1,
                                               double d1, double c1, double h) {
  // u(t) = h00 u0 + h10 h d0 + h20 h^2 c0 + h21 h^2 c1 + h11 h d1 + h01 u1, in monomials of t.
  const double a = h * d0, b = h * h * c0, e = h * h * c1, f = h * d1;
  Eigen::Array<double, 6, 1> c;
  c[0] = u0;
  c[1] = a;
  c[2] = 0.5 * b;
  c[3] = -10 * u0 - 6 * a - 1.5 * b + 0.5 * e - 4 * f + 10 * u1;
  c[4] = 15 * u0 + 8 * a + 1.5 * b - e + 7 * f - 15 * u1;
  c[5] = -6 * u0 - 3 * a - 0.5 * b + 0.5 * e - 3 * f + 6 * u1;
  return c;
}

double Horner(const double* c, double t) {
  return c[0] + t * (c[1] + t * (c[2] + t * (c[3] + t * (c[4] + t * c[5]))));
}

}  // namespace

ArcLengthMap::ArcLengthMap(const Evaluator& derivatives, const std::vector<double>& breaks,
                           const ArcLengthOptions& options)
    : derivatives_(derivatives), options_(options), breaks_(breaks) {
  piece_budget_ = std::max<std::size_t>(
      static_cast<std::size_t>(options.min_piece_budget),
      static_cast<std::size_t>(options.pieces_per_span) * (breaks.size() - 1));
  nodes_.push_back(MakeNode(breaks.front(), 0.0, false));
  for (std::size_t i = 1; i < breaks.size(); ++i) {
    const Node a = nodes_.back();
    Build(a, MakeNode(breaks[i], a.s + Integrate(a.u, breaks[i]), true), 0);
  }
}

double ArcLengthMap::MeasureLength(const Evaluator& derivatives,
                                   const std::vector<double>& breaks) {
  ArcLengthMap map;
  map.derivatives_ = derivatives;
  map.breaks_ = breaks;
  // As the constructor sums them: the integral from each break to the next.
  double s = 0.0;
  for (std::size_t i = 1; i < breaks.size(); ++i) s = s + map.Integrate(breaks[i - 1], breaks[i]);
  return s;
}

double ArcLengthMap::Speed(double u) const {
  Eigen::Vector3d d[2];
  derivatives_(u, 1, d, false);
  return d[1].norm();
}

ArcLengthMap::Node ArcLengthMap::MakeNode(double u, double s, bool from_left) const {
  Eigen::Vector3d d[3];
  derivatives_(u, 2, d, from_left);
  const double speed = d[1].norm();
  if (speed <= 0.0) return {s, u, 0.0, 0.0};  // a stationary point: the Hermite check will split
  const double du_ds = 1.0 / speed;
  return {s, u, du_ds, -d[1].dot(d[2]) * du_ds * du_ds * du_ds * du_ds};
}

double ArcLengthMap::Integrate(double u0, double u1) const {
  if (u1 < u0) return -Integrate(u1, u0);
  double total = 0.0, from = u0;
  for (const double b : breaks_) {
    if (b <= from) continue;
    if (b >= u1) break;
    total += IntegrateSmooth(from, b);
    from = b;
  }
  return total + IntegrateSmooth(from, u1);
}

double ArcLengthMap::IntegrateSmooth(double u0, double u1) const {
  // Adaptive 8-point Gauss-Legendre: accept when both halves agree with the whole.
  const auto gauss = [this](double a, double b) {
    const double m = 0.5 * (a + b), r = 0.5 * (b - a);
    double sum = 0.0;
    for (std::size_t i = 0; i < kX.size(); ++i) sum += kW[i] * Speed(m + r * kX[i]);
    return sum * r;
  };
  struct Frame {
    double a, b, whole;
    int depth;
  };
  double total = 0.0;
  std::array<Frame, 64> stack;
  int top = 0;
  stack[top++] = {u0, u1, gauss(u0, u1), 0};
  while (top > 0) {
    const Frame f = stack[--top];
    const double m = 0.5 * (f.a + f.b);
    const double left = gauss(f.a, m), right = gauss(m, f.b);
    if (!std::isfinite(left + right)) {
      throw Error(
          "the curve's speed |C'(u)| is not finite for u in [{}, {}] (poles or weights "
          "too far apart in size)",
          f.a, f.b);
    }
    if (std::abs(left + right - f.whole) <= 1e-14 * std::max(1.0, std::abs(f.whole)) ||
        f.depth >= 30 || top + 2 > static_cast<int>(stack.size())) {
      total += left + right;
    } else {
      stack[top++] = {m, f.b, right, f.depth + 1};
      stack[top++] = {f.a, m, left, f.depth + 1};
    }
  }
  return total;
}

void ArcLengthMap::Build(const Node& a, const Node& b, int depth) {
  const double h = b.s - a.s;
  const Node b_right = MakeNode(b.u, b.s, false);
  // u linear in s across the piece.
  const Piece line{a.s, 1.0 / h, {a.u, b.u - a.u, 0, 0, 0, 0}};
  if (h <= options_.tolerance_mm) {
    // A zero-length piece (repeated poles) holds u constant. One shorter than the tolerance (poles
    // that all but coincide, where |C'| is rounding noise) is exact to within h with any
    // increasing u(s): a line in s.
    pieces_.push_back(h > 0.0 ? line : Piece{a.s, 0.0, {a.u, 0, 0, 0, 0, 0}});
    nodes_.push_back(b_right);
    return;
  }
  if (pieces_.size() >= piece_budget_) {
    throw Error(
        "the curve needs more than {} pieces to map its arc length to {} mm (near u = {}); "
        "it is too long or too irregular to plan",
        piece_budget_, options_.tolerance_mm, a.u);
  }
  const auto coeff = HermiteCoefficients(a.u, a.du_ds, a.d2u_ds2, b.u, b.du_ds, b.d2u_ds2, h);
  // What a double resolves at this arc length bounds the tolerance from below.
  const double tolerance = std::max(
      options_.tolerance_mm, 64.0 * std::numeric_limits<double>::epsilon() * (std::abs(a.s) + h));
  double worst = 0.0;
  for (const double t : {0.25, 0.5, 0.75}) {
    const double u = Horner(coeff.data(), t);
    if (!(u > a.u && u < b.u)) {
      worst = INFINITY;
      break;
    }
    worst = std::max(worst, std::abs(a.s + Integrate(a.u, u) - (a.s + t * h)));
  }
  if (worst > tolerance && depth < options_.max_depth && b.u - a.u > 1e-15) {
    const double um = 0.5 * (a.u + b.u);
    const double sm = a.s + Integrate(a.u, um);
    Build(a, MakeNode(um, sm, true), depth + 1);
    Build(nodes_.back(), b, depth + 1);
    return;
  }
  if (!std::isfinite(worst)) {
    // Could not split further (a stationary point): interpolate linearly in this tiny piece.
    pieces_.push_back(line);
  } else {
    Piece piece{a.s, 1.0 / h, {}};
    std::copy(coeff.data(), coeff.data() + 6, piece.c);
    pieces_.push_back(piece);
    max_error_mm_ = std::max(max_error_mm_, worst);
  }
  nodes_.push_back(b_right);
}

double ArcLengthMap::Parameter(double s, int* hint) const {
  const int count = static_cast<int>(pieces_.size());
  int i = hint ? std::clamp(*hint, 0, count - 1) : 0;
  s = std::clamp(s, 0.0, Length());
  const auto lo = [&](int k) { return nodes_[static_cast<std::size_t>(k)].s; };
  if (s < lo(i) || s > lo(i + 1)) {
    // Walk a few pieces, then fall back to a binary search.
    int steps = 0;
    while (steps < 4 && s < lo(i) && i > 0) --i, ++steps;
    while (steps < 4 && s > lo(i + 1) && i + 1 < count) ++i, ++steps;
    if (s < lo(i) || s > lo(i + 1)) {
      const auto it = std::upper_bound(nodes_.begin(), nodes_.end(), s,
                                       [](double value, const Node& n) { return value < n.s; });
      i = std::clamp(static_cast<int>(it - nodes_.begin()) - 1, 0, count - 1);
    }
  }
  if (hint) *hint = i;
  const Piece& piece = pieces_[static_cast<std::size_t>(i)];
  const double t = std::clamp((s - piece.s0) * piece.inv_h, 0.0, 1.0);
  const Node& a = nodes_[static_cast<std::size_t>(i)];
  const Node& b = nodes_[static_cast<std::size_t>(i + 1)];
  return std::clamp(Horner(piece.c, t), a.u, b.u);
}

}  // namespace dtis::geometry
