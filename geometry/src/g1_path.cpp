#include "dtis/geometry/g1_path.hpp"

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <map>
#include <mutex>
#include <numbers>
#include <span>

#include "dtis/core/error.hpp"
#include "dtis/geometry/angle.hpp"
#include "dtis/geometry/curve_path.hpp"

namespace dtis::geometry {
namespace {

using Eigen::Vector3d;

// The corner curve: five control points on the two blocks around `p2` (Eq. 1).
BSplineCurve CornerCurve(const Vector3d& p2, const Vector3d& d_in, const Vector3d& d_out,
                         double l1_in, double l2_in, double l1_out, double l2_out) {
  BSplineCurveData data{
      3,
      {0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.0, 1.0, 1.0},
      {p2 - l2_in * d_in, p2 - l1_in * d_in, p2, p2 + l1_out * d_out, p2 + l2_out * d_out},
      {}};
  return BSplineCurve(std::move(data), "corner");
}

// q_s, q_ss, q_sss of a curve's coordinates with respect to its arc length, from its
// u-derivatives d[1..3] (chain rule with u' = 1/|C'|).
void ArcDerivatives(const Vector3d* d, Vector3d* qs, Vector3d* qss, Vector3d* qsss) {
  const double g = d[1].norm();
  const double gp = d[1].dot(d[2]) / g;
  const double gpp = (d[2].squaredNorm() + d[1].dot(d[3]) - gp * gp) / g;
  const double u1 = 1.0 / g, u2 = -gp / (g * g * g);
  const double u3 = (-gpp / (g * g * g) + 3.0 * gp * gp / (g * g * g * g)) / g;
  *qs = d[1] * u1;
  *qss = d[2] * u1 * u1 + d[1] * u2;
  *qsss = d[3] * u1 * u1 * u1 + 3.0 * d[2] * u1 * u2 + d[1] * u3;
}

double Eq8(const Axis& axis, double qs, double qss, double qsss) {
  double f = INFINITY;
  if (std::abs(qs) > 1e-300) f = std::min(f, axis.vmax / std::abs(qs));
  if (std::abs(qss) > 1e-300) f = std::min(f, std::sqrt(axis.amax / std::abs(qss)));
  if (std::abs(qsss) > 1e-300) f = std::min(f, std::cbrt(axis.jmax / std::abs(qsss)));
  return f;
}

// Eq. 8 on a corner curve's Cartesian coordinates, which are the machine's linear axes (at most
// three) when the tool axis does not turn (an XYZ machine, or XYZAC at A = 0), at 25 samples.
//
// The curve is linear in its control lengths: with N_i the basis functions (which sum to one, so
// the corner point drops out of every derivative), C^(k)(u) = d_in (-l2 N_0^(k) - l1 N_1^(k)) +
// d_out (l1 N_3^(k) + l2 N_4^(k)). The basis derivatives at the samples are tabulated once, so the
// L2 search below evaluates no B-spline at all.
class CornerFeed {
 public:
  CornerFeed(const Vector3d& d_in, const Vector3d& d_out, std::span<const Axis> linear, double feed)
      : d_in_(d_in), d_out_(d_out), linear_(linear), feed_(feed) {}

  double operator()(double l1, double l2) const {
    const Table& n = Basis();
    // Eq. 8 is min over samples of min(V / |q_s|, sqrt(A / |q_ss|), cbrt(J / |q_sss|)): the
    // largest ratios first, one root each at the end.
    double v = 0.0, a = 0.0, j = 0.0;
    for (const auto& sample : n) {
      Vector3d d[4];
      for (int k = 1; k <= 3; ++k) {
        const auto& w = sample[static_cast<std::size_t>(k)];
        d[k] = d_in_ * (-l2 * w[0] - l1 * w[1]) + d_out_ * (l1 * w[3] + l2 * w[4]);
      }
      if (!(d[1].norm() > 1e-12)) continue;
      Vector3d qs, qss, qsss;
      ArcDerivatives(d, &qs, &qss, &qsss);
      for (std::size_t i = 0; i < linear_.size(); ++i) {
        const int c = static_cast<int>(i);
        v = std::max(v, std::abs(qs[c]) / linear_[i].vmax);
        a = std::max(a, std::abs(qss[c]) / linear_[i].amax);
        j = std::max(j, std::abs(qsss[c]) / linear_[i].jmax);
      }
    }
    double f = feed_;
    if (v > 0.0) f = std::min(f, 1.0 / v);
    if (a > 0.0) f = std::min(f, std::sqrt(1.0 / a));
    if (j > 0.0) f = std::min(f, std::cbrt(1.0 / j));
    return f;
  }

 private:
  static constexpr int kSamples = 24;
  // [sample][derivative order 0..3][control point 0..4]
  using Table = std::array<std::array<std::array<double, 5>, 4>, kSamples + 1>;
  static const Table& Basis() {
    static const Table table = [] {
      Table t{};
      for (std::size_t i = 0; i < 5; ++i) {
        BSplineCurveData data{3, {0.0, 0.0, 0.0, 0.0, 0.5, 1.0, 1.0, 1.0, 1.0}, {}, {}};
        data.poles.assign(5, Vector3d::Zero());
        data.poles[i].x() = 1.0;
        const BSplineCurve unit(std::move(data), "corner basis");
        for (std::size_t k = 0; k <= kSamples; ++k) {
          Vector3d d[4];
          unit.Derivatives(static_cast<double>(k) / kSamples, 3, d);
          for (std::size_t order = 0; order < 4; ++order) t[k][order][i] = d[order].x();
        }
      }
      return t;
    }();
    return table;
  }

  Vector3d d_in_, d_out_;
  std::span<const Axis> linear_;
  double feed_;
};

// The largest distance of a curve from the polyline a - p - b, sampled densely.
double DeviationFromCorner(const BSplineCurve& curve, const Vector3d& a, const Vector3d& p,
                           const Vector3d& b) {
  const auto to_segment = [](const Vector3d& x, const Vector3d& s0, const Vector3d& s1) {
    const Vector3d d = s1 - s0;
    const double len2 = d.squaredNorm();
    const double t = len2 > 0.0 ? std::clamp((x - s0).dot(d) / len2, 0.0, 1.0) : 0.0;
    return (x - (s0 + t * d)).norm();
  };
  double worst = 0.0;
  constexpr int kSamples = 256;
  for (int k = 0; k <= kSamples; ++k) {
    const Vector3d x = curve.Point(static_cast<double>(k) / kSamples);
    worst = std::max(worst, std::min(to_segment(x, a, p), to_segment(x, p, b)));
  }
  return worst;
}

// The signed angle an arc sweeps from radius r0 to radius r1 (XY), in (0, 2 pi] counterclockwise
// and [-2 pi, 0) clockwise: equal radii make a full circle.
double ArcSweep(const Vector3d& r0, const Vector3d& r1, bool clockwise) {
  double sweep = std::atan2(r0.x() * r1.y() - r0.y() * r1.x(), r0.x() * r1.x() + r0.y() * r1.y());
  if (clockwise && sweep >= 0.0) sweep -= 2.0 * std::numbers::pi;
  if (!clockwise && sweep <= 0.0) sweep += 2.0 * std::numbers::pi;
  return sweep;
}

}  // namespace

Vector3d StartTangent(const Vector3d& from, const ChainMove& move) {
  if (move.kind == ChainMove::Kind::kLine) return (move.tip - from).normalized();
  const Vector3d r = from - move.center;
  Vector3d t(-r.y(), r.x(), 0.0);
  if (move.clockwise) t = -t;
  // The helix rises along z over the sweep; its tangent leans by the rise per unit of arc.
  const double sweep = ArcSweep(r, move.tip - move.center, move.clockwise);
  t = t.normalized() * std::hypot(r.x(), r.y()) * std::abs(sweep);
  t.z() = move.tip.z() - from.z();
  return t.normalized();
}

Vector3d EndTangent(const Vector3d& from, const ChainMove& move) {
  if (move.kind == ChainMove::Kind::kLine) return (move.tip - from).normalized();
  ChainMove reversed = move;
  reversed.tip = from;
  reversed.clockwise = !move.clockwise;
  return -StartTangent(move.tip, reversed);
}

double ReachableFeed(const PathSource& path, const Machine& machine, double s0, double s1,
                     double h) {
  const double length = path.Length().value_or(s1);
  const int n = std::max(1, static_cast<int>(std::ceil((s1 - s0) / h)));
  h = (s1 - s0) / n;
  std::vector<AxisVector> q(static_cast<std::size_t>(n + 5));
  PathState state = path.Start();
  for (int k = -2; k <= n + 2; ++k) {
    const double s = std::clamp(s0 + k * h, 0.0, length);
    const PathSample sample = path.At(state, s);
    state = sample.state;
    const auto idx = static_cast<std::size_t>(k + 2);
    const InverseResult r = machine.Inverse(sample.pose, idx ? &q[idx - 1] : nullptr, &q[idx]);
    if (r.status != InverseStatus::kOk) {
      throw Error("arc length {} mm: {}", s, DescribeInverseFailure(machine, r));
    }
  }
  const auto axes = machine.Axes();
  double best = INFINITY;
  for (int k = 0; k <= n; ++k) {
    const auto i = static_cast<std::size_t>(k + 2);
    const AxisVector qs = (q[i + 1] - q[i - 1]) / (2.0 * h);
    const AxisVector qss = (q[i + 1] - 2.0 * q[i] + q[i - 1]) / (h * h);
    const AxisVector qsss =
        (q[i + 2] - 2.0 * q[i + 1] + 2.0 * q[i - 1] - q[i - 2]) / (2.0 * h * h * h);
    for (std::size_t a = 0; a < axes.size(); ++a) {
      const int c = static_cast<int>(a);
      best = std::min(best, Eq8(axes[a], qs[c], qss[c], qsss[c]));
    }
  }
  return best;
}

void G1Path::AddLine(const Vector3d& a, const Vector3d& b, const Vector3d& ta, const Vector3d& tb,
                     int line) {
  const double length = (b - a).norm();
  if (!(length > 1e-12)) return;
  Piece p;
  p.kind = Piece::Kind::kLine;
  p.s0 = length_;
  p.length = length;
  p.line = line;
  p.a = a;
  p.d = (b - a) / length;
  p.ta = ta;
  p.tb = tb;
  pieces_.push_back(p);
  length_ += length;
}

G1Path::G1Path(const Vector3d& start_tip, const Vector3d& start_axis,
               const std::vector<ChainMove>& moves, const Machine& machine,
               const CornerOptions& options)
    : h_(options.top_height_mm), top_param_(options.top), axis_(start_axis.normalized()) {
  if (moves.empty()) throw Error("a G1 chain needs at least one move");
  if (!(options.contour_tol_mm > 0.0) || !(options.orientation_tol_mm > 0.0) ||
      !(options.top_height_mm > 0.0)) {
    throw Error("corner tolerances and the top height must be > 0 mm");
  }
  const std::size_t n = moves.size();
  std::vector<Vector3d> p(n + 1), t(n + 1), axis(n + 1);
  p[0] = start_tip;
  axis[0] = axis_;
  for (std::size_t i = 0; i < n; ++i) {
    p[i + 1] = moves[i].tip;
    axis[i + 1] = moves[i].axis.normalized();
    if ((axis[i + 1] - axis_).norm() > 1e-12) five_axis_ = true;
  }
  for (std::size_t i = 0; i <= n; ++i) t[i] = p[i] + h_ * axis[i];
  for (std::size_t i = 0; i < n; ++i) {
    const ChainMove& m = moves[i];
    if ((p[i + 1] - p[i]).norm() <= 1e-9 && m.kind == ChainMove::Kind::kLine) {
      throw Error(
          "line {}: the block does not move the tool tip (blocks that only turn the tool are "
          "not supported inside a contour)",
          m.line);
    }
    if (m.kind == ChainMove::Kind::kArc && (axis[i + 1] - axis[i]).norm() > 1e-12) {
      throw Error("line {}: an arc cannot turn the tool axis", m.line);
    }
  }
  const auto linear = machine.Axes().subspan(0, std::min<std::size_t>(3, machine.Axes().size()));

  // Corners at interior vertices between two lines: their control lengths first (each may take
  // up to half of either block), then the pieces. Corners are independent of each other: they
  // are built in parallel (a CAM program's million corners in seconds), and the first one that
  // fails in program order is reported, whatever the threads did.
  struct Plan {
    bool corner = false;
    double l1 = 0.0, l2 = 0.0, feed = INFINITY, length = 0.0;
    std::shared_ptr<const BSplineCurve> bottom, top;
    double r_in = 0.0, r_out = 0.0;  // mm of top per mm of tip on either block (5-axis)
  };
  std::vector<Plan> plan(n + 1);
  std::mutex failure_mutex;
  std::size_t failed_at = n;
  std::exception_ptr failure;
  const auto plan_corner = [&](std::size_t k) {
    if (moves[k - 1].kind != ChainMove::Kind::kLine || moves[k].kind != ChainMove::Kind::kLine) {
      return;
    }
    const double len_in = (p[k] - p[k - 1]).norm(), len_out = (p[k + 1] - p[k]).norm();
    const Vector3d d_in = (p[k] - p[k - 1]) / len_in, d_out = (p[k + 1] - p[k]) / len_out;
    const Vector3d top_in = (t[k] - t[k - 1]) / len_in, top_out = (t[k + 1] - t[k]) / len_out;
    const double turn = Angle(d_in, d_out);
    const bool top_turns = five_axis_ && (top_out - top_in).norm() > options.straight_rad;
    if (turn <= options.straight_rad && !top_turns) return;
    if (turn > std::numbers::pi - 1e-9) {
      throw Error("line {}: the path turns back on itself (a 180 degree corner cannot be smoothed)",
                  moves[k].line);
    }
    Plan& c = plan[k];
    c.corner = true;
    const double l2_max = 0.5 * std::min(len_in, len_out);
    if (turn > options.straight_rad) {
      // Eq. 3 with the turning angle: eps = L1 cos(alpha / 2) / 2, alpha = pi - turn.
      c.l1 = std::min(2.0 * options.contour_tol_mm / std::sin(0.5 * turn), 0.5 * l2_max);
      // L2 by Eq. 8: a coarse scan on a log scale, then golden-section refinement.
      const CornerFeed corner_feed(d_in, d_out, linear, options.feed_mm_s);
      const auto feed = [&](double l2) { return corner_feed(c.l1, l2); };
      const double lo = c.l1 * (1.0 + 1e-3);
      double best = l2_max, best_feed = feed(l2_max);
      constexpr int kScan = 8;
      for (int i = 0; i < kScan; ++i) {
        const double l2 = lo * std::pow(l2_max / lo, static_cast<double>(i) / kScan);
        const double f = feed(l2);
        if (f > best_feed) best = l2, best_feed = f;
      }
      const double ratio = std::pow(l2_max / lo, 1.0 / kScan);
      double a = std::log(std::max(lo, best / ratio)), b = std::log(std::min(l2_max, best * ratio));
      const double g = (std::sqrt(5.0) - 1.0) / 2.0;
      double x1 = b - g * (b - a), x2 = a + g * (b - a);
      double f1 = feed(std::exp(x1)), f2 = feed(std::exp(x2));
      for (int i = 0; i < 12; ++i) {
        if (f1 >= f2) {
          b = x2, x2 = x1, f2 = f1, x1 = b - g * (b - a), f1 = feed(std::exp(x1));
        } else {
          a = x1, x1 = x2, f1 = f2, x2 = a + g * (b - a), f2 = feed(std::exp(x2));
        }
      }
      for (const auto& [x, f] : {std::pair{x1, f1}, std::pair{x2, f2}}) {
        if (f > best_feed) best = std::exp(x), best_feed = f;
      }
      c.l2 = best;
      c.feed = best_feed;
    } else {
      c.l2 = l2_max;  // the tip goes straight; only the tool axis turns here
      c.l1 = 0.5 * c.l2;
    }
    c.bottom = std::make_shared<const BSplineCurve>(
        CornerCurve(p[k], d_in, d_out, c.l1, c.l2, c.l1, c.l2));
    if (five_axis_) {
      // The top point's control lengths scale with its rate on either block (mm of top per mm
      // of tip), so that its line pieces keep the programmed correspondence; its inner length
      // is set by eps_top, measured densely.
      const double r_in = top_in.norm(), r_out = top_out.norm();
      c.r_in = r_in;
      c.r_out = r_out;
      const double bend = (top_out - top_in).norm();
      double l1 =
          bend > 0.0 ? std::min(4.0 * options.orientation_tol_mm / bend, 0.5 * c.l2) : 0.5 * c.l2;
      const Vector3d e_in = r_in > 0.0 ? Vector3d(top_in / r_in) : Vector3d::Zero();
      const Vector3d e_out = r_out > 0.0 ? Vector3d(top_out / r_out) : Vector3d::Zero();
      for (int i = 0;; ++i, l1 *= 0.8) {
        c.top = std::make_shared<const BSplineCurve>(
            CornerCurve(t[k], e_in, e_out, r_in * l1, r_in * c.l2, r_out * l1, r_out * c.l2));
        if (i == 40 ||
            DeviationFromCorner(*c.top, t[k] - r_in * c.l2 * e_in, t[k],
                                t[k] + r_out * c.l2 * e_out) <= options.orientation_tol_mm) {
          break;
        }
      }
    }
    c.length = ArcLengthOfCurve(*c.bottom);
  };
  tbb::parallel_for(tbb::blocked_range<std::size_t>(1, n, 256),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t k = range.begin(); k != range.end(); ++k) {
                        try {
                          plan_corner(k);
                        } catch (...) {
                          const std::lock_guard lock(failure_mutex);
                          if (k < failed_at) failed_at = k, failure = std::current_exception();
                        }
                      }
                    });
  if (failure) std::rethrow_exception(failure);

  // Pieces in order: for each move, the corner at its start (if any) was added with the previous
  // move; add the move itself trimmed by the corners at both ends, then the corner at its end.
  for (std::size_t i = 0; i < n; ++i) {
    const ChainMove& m = moves[i];
    const double l2_start = plan[i].corner ? plan[i].l2 : 0.0;
    const double l2_end = plan[i + 1].corner ? plan[i + 1].l2 : 0.0;
    if (m.kind == ChainMove::Kind::kLine) {
      const double len = (p[i + 1] - p[i]).norm();
      const Vector3d d = (p[i + 1] - p[i]) / len, top_rate = (t[i + 1] - t[i]) / len;
      AddLine(p[i] + l2_start * d, p[i + 1] - l2_end * d, t[i] + l2_start * top_rate,
              t[i + 1] - l2_end * top_rate, m.line);
    } else {
      Piece a;
      a.kind = Piece::Kind::kArc;
      a.line = m.line;
      a.s0 = length_;
      const Vector3d r0 = p[i] - m.center;
      const Vector3d r1 = p[i + 1] - m.center;
      a.a = Vector3d(m.center.x(), m.center.y(), p[i].z());
      a.radius = std::hypot(r0.x(), r0.y());
      a.sweep = ArcSweep(r0, r1, m.clockwise);
      a.d = Vector3d(r0.x(), r0.y(), 0.0);
      a.dz = p[i + 1].z() - p[i].z();
      a.length = std::hypot(a.radius * a.sweep, a.dz);
      if (!(a.radius > 1e-9)) throw Error("line {}: the arc has no radius", m.line);
      pieces_.push_back(a);
      length_ += a.length;
    }
    if (i + 1 < n && plan[i + 1].corner) {
      const Plan& c = plan[i + 1];
      Corner corner;
      corner.l1 = c.l1;
      corner.l2 = c.l2;
      corner.line = m.line;
      corner.bottom = c.bottom;
      corner.top = c.top;
      Piece piece;
      piece.kind = Piece::Kind::kCorner;
      piece.line = m.line;
      piece.s0 = length_;
      piece.corner = static_cast<int>(corners_.size());
      piece.length = c.length;
      if (five_axis_) {
        const double S = piece.length;
        // The top parameter's slope and curvature at both ends, in tip arc length, that make the
        // top point move as on the blocks: C_t'(w) w' = rate e, C_t''(w) w'^2 + C_t'(w) w'' = 0.
        const auto ends = [&](double w, double rate, double* slope, double* second) {
          Vector3d d[3];
          corner.top->Derivatives(w, 2, d);
          const double speed = d[1].norm();
          if (!(speed > 1e-12) || !(rate > 0.0)) {
            *slope = 1.0 / S;
            *second = 0.0;
            return;
          }
          *slope = rate / speed;
          *second = -d[2].dot(d[1] / speed) * (*slope) * (*slope) / speed;
        };
        double s0d, s0dd, s1d, s1dd;
        ends(0.0, c.r_in, &s0d, &s0dd);
        ends(1.0, c.r_out, &s1d, &s1dd);
        const double a1 = S * s0d, a2 = S * S * s0dd, b1 = S * s1d, b2 = S * S * s1dd;
        piece.w[0] = 0.0;
        piece.w[1] = a1;
        piece.w[2] = a2 / 2.0;
        piece.w[3] = -6.0 * a1 - 1.5 * a2 + 10.0 - 4.0 * b1 + 0.5 * b2;
        piece.w[4] = 8.0 * a1 + 1.5 * a2 - 15.0 + 7.0 * b1 - b2;
        piece.w[5] = -3.0 * a1 - 0.5 * a2 + 6.0 - 3.0 * b1 + 0.5 * b2;
        if (options.top == TopParametrization::kC2) {
          for (int j = 0; j <= 200; ++j) {
            const double x = j / 200.0;
            const double slope =
                piece.w[1] +
                x * (2.0 * piece.w[2] +
                     x * (3.0 * piece.w[3] + x * (4.0 * piece.w[4] + x * 5.0 * piece.w[5])));
            if (!(slope > 0.0)) {
              throw Error(
                  "line {}: the tool axis turns too unevenly around this corner for a monotone "
                  "C2 orientation; split the blocks more evenly",
                  m.line);
            }
          }
        }
      }
      corner.s0 = piece.s0;
      corner.s1 = piece.s0 + piece.length;
      corner.reachable_feed_mm_s = std::min(c.feed, options.feed_mm_s);
      corners_.push_back(std::move(corner));
      pieces_.push_back(std::move(piece));
      length_ += pieces_.back().length;
    }
  }
  if (!(length_ > 0.0)) throw Error("line {}: the contour has no length", moves.front().line);

  // Slow points in the middle of each corner, at the feed Eq. 8 allows there: on the linear axes
  // in 3-axis (exact for the corner curve), from finite differences of the machine's axis
  // positions in 5-axis, over the corner and a little of both blocks.
  for (Corner& c : corners_) {
    if (five_axis_) {
      const double span = c.s1 - c.s0;
      c.reachable_feed_mm_s = std::min(
          options.feed_mm_s, ReachableFeed(*this, machine, std::max(0.0, c.s0 - 0.1 * span),
                                           std::min(length_, c.s1 + 0.1 * span), span / 64.0));
    }
    if (c.reachable_feed_mm_s < options.feed_mm_s) {
      slow_.push_back({0.5 * (c.s0 + c.s1), c.reachable_feed_mm_s});
    }
  }
  // Where corners come closer than a braking distance from the feed (F sqrt(F / J) with the
  // lowest linear jerk), keep the slowest of them: the look-ahead plans one backward limit per
  // slow point, and between close corners the exact axis checks decide anyway. A program of
  // fine blocks (CAM output of a freeform) would otherwise plan one per block.
  double jerk = INFINITY;
  for (const Axis& a : linear) jerk = std::min(jerk, a.jmax);
  const double window = std::isfinite(options.feed_mm_s) && std::isfinite(jerk)
                            ? options.feed_mm_s * std::sqrt(options.feed_mm_s / jerk)
                            : 0.0;
  if (window > 0.0 && slow_.size() > 1) {
    std::vector<std::size_t> order(slow_.size());
    for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
    std::stable_sort(order.begin(), order.end(), [this](std::size_t a, std::size_t b) {
      return slow_[a].feed_mm_s < slow_[b].feed_mm_s;
    });
    std::map<double, double> kept;  // s -> feed
    for (const std::size_t k : order) {
      const double s = slow_[k].s;
      const auto next = kept.lower_bound(s);
      if (next != kept.end() && next->first - s < window) continue;
      if (next != kept.begin() && s - std::prev(next)->first < window) continue;
      kept.emplace(s, slow_[k].feed_mm_s);
    }
    slow_.clear();
    for (const auto& [s, feed] : kept) slow_.push_back({s, feed});
  }
}

const G1Path::CornerMaps& G1Path::Maps(int corner) const {
  if (maps_.empty()) maps_.resize(std::min(kCachedCorners, corners_.size()));
  CornerMaps& slot = maps_[static_cast<std::size_t>(corner) % maps_.size()];
  if (slot.corner != corner) {
    const Corner& c = corners_[static_cast<std::size_t>(corner)];
    slot.bottom = std::make_shared<const ArcLengthMap>(ArcLengthOf(*c.bottom));
    slot.top = five_axis_ && top_param_ == TopParametrization::kTopArcLength
                   ? std::make_shared<const ArcLengthMap>(ArcLengthOf(*c.top))
                   : nullptr;
    slot.corner = corner;
  }
  return slot;
}

int G1Path::Find(double s, int hint) const {
  const int last = static_cast<int>(pieces_.size()) - 1;
  int i = std::clamp(hint, 0, last);
  const auto& P = pieces_;
  if (s >= P[static_cast<std::size_t>(i)].s0 &&
      (i == last || s < P[static_cast<std::size_t>(i + 1)].s0)) {
    return i;
  }
  const auto it =
      std::upper_bound(P.begin(), P.end(), s, [](double x, const Piece& p) { return x < p.s0; });
  return std::clamp(static_cast<int>(it - P.begin()) - 1, 0, last);
}

Pose G1Path::PoseAt(double s, int* hint) const {
  const int i = Find(s, *hint);
  *hint = i;
  const Piece& p = pieces_[static_cast<std::size_t>(i)];
  const double local = std::clamp(s - p.s0, 0.0, p.length);
  Pose pose;
  switch (p.kind) {
    case Piece::Kind::kLine: {
      pose.tip = p.a + local * p.d;
      if (five_axis_) {
        const Vector3d top = p.ta + (local / p.length) * (p.tb - p.ta);
        pose.axis = (top - pose.tip).normalized();
      } else {
        pose.axis = axis_;
      }
      break;
    }
    case Piece::Kind::kArc: {
      const double angle = p.sweep * local / p.length;
      const double c = std::cos(angle), sn = std::sin(angle);
      pose.tip = p.a + Vector3d(c * p.d.x() - sn * p.d.y(), sn * p.d.x() + c * p.d.y(),
                                p.dz * local / p.length);
      pose.axis = axis_;
      break;
    }
    case Piece::Kind::kCorner: {
      const Corner& corner = corners_[static_cast<std::size_t>(p.corner)];
      const CornerMaps& maps = Maps(p.corner);
      int map_hint = 0;
      const double u = maps.bottom->Parameter(local, &map_hint);
      pose.tip = corner.bottom->Point(u);
      if (!five_axis_) {
        pose.axis = axis_;
        break;
      }
      const double x = local / p.length;
      double w = x;
      switch (top_param_) {
        case TopParametrization::kC2:
          w = p.w[0] + x * (p.w[1] + x * (p.w[2] + x * (p.w[3] + x * (p.w[4] + x * p.w[5]))));
          break;
        case TopParametrization::kBottomParameter:
          w = u;
          break;
        case TopParametrization::kUniform:
          break;
        case TopParametrization::kTopArcLength: {
          int top_hint = 0;
          w = maps.top->Parameter(x * maps.top->Length(), &top_hint);
          break;
        }
      }
      pose.axis = (corner.top->Point(std::clamp(w, 0.0, 1.0)) - pose.tip).normalized();
      break;
    }
  }
  return pose;
}

PathSample G1Path::At(const PathState& from, double s) const {
  PathSample sample;
  if (s >= length_) {
    sample.status = s > length_ ? PathStatus::kEnd : PathStatus::kOk;
    s = length_;
  }
  int hint = from.piece;
  sample.pose = PoseAt(s, &hint);
  sample.state = {.s = s, .piece = hint};
  return sample;
}

std::string G1Path::Describe(const PathState& state) const {
  const int i = Find(state.s, state.piece);
  const Piece& p = pieces_[static_cast<std::size_t>(i)];
  return fmt::format("arc length {} mm, {} of the block at line {}", state.s,
                     p.kind == Piece::Kind::kCorner ? "in the corner at the end"
                     : p.kind == Piece::Kind::kArc  ? "on the arc"
                                                    : "on the line",
                     p.line);
}

std::vector<std::unique_ptr<PathSource>> LinkMoves(const Pose& from, const Pose& to, double safe_z,
                                                   double clearance, const Machine& machine,
                                                   const CornerOptions& corners) {
  const std::vector<Pose> points = LinkWaypoints(from, to, safe_z, clearance);
  std::vector<std::unique_ptr<PathSource>> moves;
  std::size_t first = 0;  // the waypoint the current chain starts from
  const auto flush = [&](std::size_t last) {
    if (last == first + 1) {
      moves.push_back(
          StraightMove(points[first].tip, points[last].tip, points[first].axis, points[last].axis));
    } else if (last > first + 1) {
      std::vector<ChainMove> chain;
      for (std::size_t k = first + 1; k <= last; ++k) {
        ChainMove m;
        m.tip = points[k].tip;
        m.axis = points[k].axis;
        m.line = static_cast<int>(k);  // the waypoint, in messages
        chain.push_back(m);
      }
      moves.push_back(
          std::make_unique<G1Path>(points[first].tip, points[first].axis, chain, machine, corners));
    }
    first = last;
  };
  for (std::size_t k = 1; k + 1 < points.size(); ++k) {
    const Vector3d in = (points[k].tip - points[k - 1].tip).normalized();
    const Vector3d out = (points[k + 1].tip - points[k].tip).normalized();
    if (Angle(in, out) > std::numbers::pi - 1e-6) flush(k);  // turns back: stop there
  }
  flush(points.size() - 1);
  return moves;
}

}  // namespace dtis::geometry
