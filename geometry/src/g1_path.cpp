#include "dtis/geometry/g1_path.hpp"

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <exception>
#include <mutex>
#include <numbers>
#include <span>

#include "dtis/core/error.hpp"
#include "dtis/core/golden_section.hpp"
#include "dtis/geometry/angle.hpp"
#include "dtis/geometry/curve_path.hpp"

namespace dtis::geometry {
namespace {

using Eigen::Vector3d;

// v.normalized(), the same operations, inlined into the pose evaluation (GCC stopped inlining
// Eigen's on its own: 2 % of the 5-axis G-code sample's planning time).
inline Vector3d Unit(const Vector3d& v) {
  const double z = v.squaredNorm();
  return z > 0.0 ? Vector3d(v / std::sqrt(z)) : v;
}

// Erases the first n elements of v when they are more than 64 and more than half of it (a windowed
// chain drops what lies behind in batches, so that its storage stays contiguous for Find).
// Returns how many went.
template <typename T>
std::size_t DropFront(std::vector<T>& v, std::size_t n) {
  if (n <= 64 || 2 * n <= v.size()) return 0;
  v.erase(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(n));
  return n;
}

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

// The length of a vector, as std::hypot of its components: exactly the planar hypot for a vector
// in the XY plane.
double Norm(const Vector3d& v) { return std::hypot(std::hypot(v.x(), v.y()), v.z()); }

// The component of v across the unit axis n (exactly v's x and y for n = +Z).
Vector3d Across(const Vector3d& v, const Vector3d& n) {
  if (n == Vector3d::UnitZ()) return Vector3d(v.x(), v.y(), 0.0);
  return v - v.dot(n) * n;
}

// The signed angle an arc about the axis n sweeps from radius r0 to radius r1, counterclockwise
// about n positive: in (0, 2 pi] counterclockwise and [-2 pi, 0) clockwise (equal radii make a
// full circle), and a whole turn more for each turn begun after the first.
double ArcSweep(const Vector3d& r0, const Vector3d& r1, const ChainMove& m) {
  double sweep = 0.0;
  if (m.normal == Vector3d::UnitZ()) {
    sweep = std::atan2(r0.x() * r1.y() - r0.y() * r1.x(), r0.x() * r1.x() + r0.y() * r1.y());
  } else {
    const Vector3d a = Across(r0, m.normal), b = Across(r1, m.normal);
    sweep = std::atan2(m.normal.dot(a.cross(b)), a.dot(b));
  }
  if (m.clockwise && sweep >= 0.0) sweep -= 2.0 * std::numbers::pi;
  if (!m.clockwise && sweep <= 0.0) sweep += 2.0 * std::numbers::pi;
  const double extra = 2.0 * std::numbers::pi * std::max(m.turns - 1, 0);
  return sweep + (m.clockwise ? -extra : extra);
}

}  // namespace

Vector3d StartTangent(const Vector3d& from, const ChainMove& move) {
  if (move.kind == ChainMove::Kind::kLine) return (move.tip - from).normalized();
  const Vector3d r = Across(from - move.center, move.normal);
  Vector3d t = move.normal.cross(r);
  if (move.clockwise) t = -t;
  // The helix rises along its axis over the sweep; its tangent leans by the rise per unit of arc.
  const double sweep = ArcSweep(from - move.center, move.tip - move.center, move);
  t = t.normalized() * Norm(r) * std::abs(sweep);
  t += move.normal * move.normal.dot(move.tip - from);
  return t.normalized();
}

Vector3d EndTangent(const Vector3d& from, const ChainMove& move) {
  if (move.kind == ChainMove::Kind::kLine) return (move.tip - from).normalized();
  ChainMove reversed = move;
  reversed.tip = from;
  reversed.clockwise = !move.clockwise;
  return -StartTangent(move.tip, reversed);
}

namespace {

// ReachableFeed on a path whose samples are clamped to [0, length].
double ReachableFeedWithin(const PathSource& path, const Machine& machine, double s0, double s1,
                           double h, double length) {
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

}  // namespace

double ReachableFeed(const PathSource& path, const Machine& machine, double s0, double s1,
                     double h) {
  return ReachableFeedWithin(path, machine, s0, s1, h, path.Length().value_or(s1));
}

// ---- building
//
// A chain is built move by move: the pieces of move i (vertex i to vertex i + 1) need the corners
// at both of its ends, so move i + 1 must have been read. A chain given whole plans all its
// corners first, in parallel; a windowed one plans each when its move is built. Either way a
// corner depends on its vertex and the two around it only, so both build the same pieces.

G1Path::G1Path(const Vector3d& start_tip, const Vector3d& start_axis,
               const std::vector<ChainMove>& moves, const Machine& machine,
               const CornerOptions& options) {
  if (moves.empty()) throw Error("a G1 chain needs at least one move");
  Init(start_tip, start_axis, machine, options);
  const std::size_t n = moves.size();
  for (const ChainMove& m : moves) {
    if ((m.axis.normalized() - axis_).norm() > 1e-12) five_axis_ = true;
  }
  for (const ChainMove& m : moves) AddVertex(m);
  read_all_ = true;

  // Corners are independent of each other: they are planned in parallel (a CAM program's million
  // corners in seconds), and the first one that fails in program order is reported, whatever the
  // threads did.
  std::vector<CornerPlan> plan(n + 1);
  std::mutex failure_mutex;
  std::size_t failed_at = n;
  std::exception_ptr failure;
  tbb::parallel_for(tbb::blocked_range<std::size_t>(1, n, 256),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t k = range.begin(); k != range.end(); ++k) {
                        try {
                          plan[k] = PlanCorner(k);
                        } catch (...) {
                          const std::lock_guard lock(failure_mutex);
                          if (k < failed_at) failed_at = k, failure = std::current_exception();
                        }
                      }
                    });
  if (failure) std::rethrow_exception(failure);
  plans_.assign(std::make_move_iterator(plan.begin()), std::make_move_iterator(plan.end()));
  plan.clear();
  while (Advance()) {
  }
  Settle();
}

G1Path::G1Path(const Vector3d& start_tip, const Vector3d& start_axis, Window window,
               const Machine& machine, const CornerOptions& options) {
  Init(start_tip, start_axis, machine, options);
  windowed_ = true;
  five_axis_ = window.five_axis;
  if (window.keep_behind_mm > 0.0) keep_behind_ = window.keep_behind_mm;
  context_ = std::move(window.context);
  behind_remedy_ = std::move(window.behind_remedy);
  first_ = std::move(window.first);
  more_ = std::move(window.more);
  plans_.emplace_back();  // vertex 0: no corner
  if (!Pull()) throw Error("a G1 chain needs at least one move");
}

void G1Path::Init(const Vector3d& start_tip, const Vector3d& start_axis, const Machine& machine,
                  const CornerOptions& options) {
  if (!(options.contour_tol_mm > 0.0) || !(options.orientation_tol_mm > 0.0) ||
      !(options.top_height_mm > 0.0)) {
    throw Error("corner tolerances and the top height must be > 0 mm");
  }
  machine_ = &machine;
  options_ = options;
  h_ = options.top_height_mm;
  top_param_ = options.top;
  axis_ = start_axis.normalized();
  vertices_.push_back({start_tip, start_tip + h_ * axis_, axis_, {}});
  // Where corners come closer than a braking distance from the feed (F sqrt(F / J) with the
  // lowest linear jerk), only the slowest of them is a slow point (Thin).
  double acceleration = INFINITY, jerk = INFINITY;
  const auto axes = machine.Axes();
  for (std::size_t i = 0; i < std::min<std::size_t>(3, axes.size()); ++i) {
    acceleration = std::min(acceleration, axes[i].amax);
    jerk = std::min(jerk, axes[i].jmax);
  }
  const double f = options.feed_mm_s;
  window_ = std::isfinite(f) && std::isfinite(jerk) ? f * std::sqrt(f / jerk) : 0.0;
  // Behind the planner a windowed chain keeps what its backward look-ahead may walk again: many
  // times the distance to reach the feed from rest on the slowest linear axis, and a second of
  // feed, at least 200 mm.
  keep_behind_ = std::max(200.0, 8.0 * f * (f / acceleration + std::sqrt(f / jerk)) + 2.0 * f);
}

bool G1Path::Pull() const {
  if (read_all_) return false;
  std::optional<ChainMove> m;
  if (first_next_ < first_.size()) {
    m = first_[first_next_++];
    if (first_next_ == first_.size()) std::vector<ChainMove>().swap(first_);
  } else if (more_) {
    m = more_();
  }
  if (!m) {
    read_all_ = true;
    more_ = nullptr;
    return false;
  }
  InContext([&] { AddVertex(*m); });
  return true;
}

void G1Path::AddVertex(const ChainMove& m) const {
  const Vertex& prev = vertices_.back();
  Vertex v{m.tip, Vector3d::Zero(), m.axis.normalized(), m};
  v.t = v.p + h_ * v.axis;
  if ((v.p - prev.p).norm() <= 1e-9 && m.kind == ChainMove::Kind::kLine) {
    throw Error(
        "line {}: the block does not move the tool tip (blocks that only turn the tool are "
        "not supported inside a contour)",
        m.line);
  }
  if (m.kind == ChainMove::Kind::kArc && (v.axis - prev.axis).norm() > 1e-12) {
    throw Error("line {}: an arc cannot turn the tool axis", m.line);
  }
  if (moves_read_ == 0) first_line_ = m.line;
  vertices_.push_back(std::move(v));
  ++moves_read_;
}

// The corner at vertex k, between move k - 1 (into it) and move k (out of it).
G1Path::CornerPlan G1Path::PlanCorner(std::size_t k) const {
  CornerPlan c;
  if (k == 0 || k >= moves_read_) return c;
  const Vertex &v0 = V(k - 1), &v1 = V(k), &v2 = V(k + 1);
  if (v1.move.kind != ChainMove::Kind::kLine || v2.move.kind != ChainMove::Kind::kLine) return c;
  const auto linear =
      machine_->Axes().subspan(0, std::min<std::size_t>(3, machine_->Axes().size()));
  const double len_in = (v1.p - v0.p).norm(), len_out = (v2.p - v1.p).norm();
  const Vector3d d_in = (v1.p - v0.p) / len_in, d_out = (v2.p - v1.p) / len_out;
  const Vector3d top_in = (v1.t - v0.t) / len_in, top_out = (v2.t - v1.t) / len_out;
  const double turn = Angle(d_in, d_out);
  const bool top_turns = five_axis_ && (top_out - top_in).norm() > options_.straight_rad;
  if (turn <= options_.straight_rad && !top_turns) return c;
  if (turn > std::numbers::pi - 1e-9) {
    throw Error("line {}: the path turns back on itself (a 180 degree corner cannot be smoothed)",
                v2.move.line);
  }
  c.corner = true;
  const double l2_max = 0.5 * std::min(len_in, len_out);
  if (turn > options_.straight_rad) {
    // Eq. 3 with the turning angle: eps = L1 cos(alpha / 2) / 2, alpha = pi - turn.
    c.l1 = std::min(2.0 * options_.contour_tol_mm / std::sin(0.5 * turn), 0.5 * l2_max);
    // L2 by Eq. 8: a coarse scan on a log scale, then golden-section refinement.
    const CornerFeed corner_feed(d_in, d_out, linear, options_.feed_mm_s);
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
    const auto [x, f] = GoldenSectionMax([&](double y) { return feed(std::exp(y)); },
                                         std::log(std::max(lo, best / ratio)),
                                         std::log(std::min(l2_max, best * ratio)), 12);
    if (f > best_feed) best = std::exp(x), best_feed = f;
    c.l2 = best;
    c.feed = best_feed;
  } else {
    c.l2 = l2_max;  // the tip goes straight; only the tool axis turns here
    c.l1 = 0.5 * c.l2;
  }
  c.bottom =
      std::make_shared<const BSplineCurve>(CornerCurve(v1.p, d_in, d_out, c.l1, c.l2, c.l1, c.l2));
  if (five_axis_) {
    // The top point's control lengths scale with its rate on either block (mm of top per mm of
    // tip), so that its line pieces keep the programmed correspondence; its inner length is set
    // by eps_top, measured densely.
    const double r_in = top_in.norm(), r_out = top_out.norm();
    c.r_in = r_in;
    c.r_out = r_out;
    const double bend = (top_out - top_in).norm();
    double l1 =
        bend > 0.0 ? std::min(4.0 * options_.orientation_tol_mm / bend, 0.5 * c.l2) : 0.5 * c.l2;
    const Vector3d e_in = r_in > 0.0 ? Vector3d(top_in / r_in) : Vector3d::Zero();
    const Vector3d e_out = r_out > 0.0 ? Vector3d(top_out / r_out) : Vector3d::Zero();
    for (int i = 0;; ++i, l1 *= 0.8) {
      c.top = std::make_shared<const BSplineCurve>(
          CornerCurve(v1.t, e_in, e_out, r_in * l1, r_in * c.l2, r_out * l1, r_out * c.l2));
      if (i == 40 ||
          DeviationFromCorner(*c.top, v1.t - r_in * c.l2 * e_in, v1.t,
                              v1.t + r_out * c.l2 * e_out) <= options_.orientation_tol_mm) {
        break;
      }
    }
  }
  c.length = ArcLengthOfCurve(*c.bottom);
  return c;
}

void G1Path::AddLine(const Vector3d& a, const Vector3d& b, const Vector3d& ta, const Vector3d& tb,
                     int line) const {
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

template <typename F>
auto G1Path::InContext(F&& f) const -> decltype(f()) {
  if (context_.empty()) return f();
  try {
    return f();
  } catch (const Error& e) {
    throw Error("{}: {}", context_, e.what());
  }
}

bool G1Path::Advance() const {
  if (built_all_) return false;
  while (moves_read_ < next_move_ + 2 && Pull()) {
  }
  return InContext([this] { return AdvanceRead(); });
}

bool G1Path::AdvanceRead() const {
  const std::size_t i = next_move_;
  if (i >= moves_read_) {
    built_all_ = true;
    if (!(length_ > 0.0)) throw Error("line {}: the contour has no length", first_line_);
    return false;
  }
  // The corner at the end of move i (none after the last move).
  if (plan_base_ + plans_.size() == i + 1) plans_.push_back(PlanCorner(i + 1));
  const CornerPlan& start = plans_[i - plan_base_];
  const CornerPlan& end = plans_[i + 1 - plan_base_];
  const Vertex &v0 = V(i), &v1 = V(i + 1);
  const ChainMove& m = v1.move;
  // The move trimmed by the corners at both ends, then the corner at its end.
  const double l2_start = start.corner ? start.l2 : 0.0;
  const double l2_end = end.corner ? end.l2 : 0.0;
  if (m.kind == ChainMove::Kind::kLine) {
    const double len = (v1.p - v0.p).norm();
    const Vector3d d = (v1.p - v0.p) / len, top_rate = (v1.t - v0.t) / len;
    AddLine(v0.p + l2_start * d, v1.p - l2_end * d, v0.t + l2_start * top_rate,
            v1.t - l2_end * top_rate, m.line);
  } else {
    Piece a;
    a.kind = Piece::Kind::kArc;
    a.line = m.line;
    a.s0 = length_;
    const Vector3d r0 = v0.p - m.center;
    const Vector3d r1 = v1.p - m.center;
    a.n = m.normal;
    a.d = Across(r0, m.normal);
    a.a = v0.p - a.d;  // the axis at the start's height
    if (m.normal == Vector3d::UnitZ()) a.a = Vector3d(m.center.x(), m.center.y(), v0.p.z());
    a.radius = Norm(a.d);
    a.sweep = ArcSweep(r0, r1, m);
    a.dz = m.normal.dot(v1.p - v0.p);
    a.length = std::hypot(a.radius * a.sweep, a.dz);
    if (!(a.radius > 1e-9)) throw Error("line {}: the arc has no radius", m.line);
    pieces_.push_back(a);
    length_ += a.length;
  }
  if (end.corner) {
    const CornerPlan& c = end;
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
    piece.corner = static_cast<long>(CornersBuilt());
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
      if (options_.top == TopParametrization::kC2) {
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
    corner.reachable_feed_mm_s = std::min(c.feed, options_.feed_mm_s);
    corners_.push_back(std::move(corner));
    pieces_.push_back(std::move(piece));
    length_ += pieces_.back().length;
  }
  ++next_move_;
  // Move i + 1 needs vertices i + 1 and on, and the corner plans from i + 1.
  while (vertex_base_ < next_move_) vertices_.pop_front(), ++vertex_base_;
  while (plan_base_ < next_move_) plans_.pop_front(), ++plan_base_;
  return true;
}

// Slow points in the middle of each corner, at the feed Eq. 8 allows there: on the linear axes in
// 3-axis (exact for the corner curve, found when it was planned), from finite differences of the
// machine's axis positions in 5-axis, over the corner and a little of both blocks (which must be
// built by then).
void G1Path::Settle() const {
  while (settled_ < CornersBuilt()) {
    Corner& c = corners_[settled_ - corner_base_];
    const double span = c.s1 - c.s0;
    if (five_axis_) {
      if (!built_all_ && !(length_ > c.s1 + 0.2 * span)) break;
      const double length = built_all_ ? length_ : INFINITY;
      const double feed = InContext([&] {
        return ReachableFeedWithin(*this, *machine_, std::max(0.0, c.s0 - 0.1 * span),
                                   std::min(length, c.s1 + 0.1 * span), span / 64.0, length);
      });
      c.reachable_feed_mm_s = std::min(options_.feed_mm_s, feed);
    }
    if (c.reachable_feed_mm_s < options_.feed_mm_s) {
      candidates_.push_back(
          {0.5 * (c.s0 + c.s1), c.reachable_feed_mm_s, static_cast<long>(settled_)});
    }
    ++settled_;
  }
  // Every slow point still to come lies beyond the next corner's start (or the built length).
  const double frontier = settled_ < CornersBuilt() ? corners_[settled_ - corner_base_].s0
                          : built_all_              ? INFINITY
                                                    : length_;
  Thin(frontier);
}

// Where corners come closer than `window_` to each other, keep the slowest: the look-ahead plans
// one backward limit per slow point, and between close corners the exact axis checks decide
// anyway. A program of fine blocks (CAM output of a freeform) would otherwise plan one per block.
//
// Taken in order of feed (the earlier corner first at equal feed), a point is kept unless a kept
// point lies closer than the window. A point is decided once every slower point near it is, and
// no point still to come (beyond `frontier`) can be near it; so a chain built bit by bit thins as
// the whole chain does.
void G1Path::Thin(double frontier) const {
  using State = Candidate::State;
  const auto slower = [](const Candidate& a, const Candidate& b) {
    return a.feed < b.feed || (a.feed == b.feed && a.order < b.order);
  };
  std::vector<std::size_t> open;
  for (std::size_t k = emitted_; k < candidates_.size(); ++k) {
    if (candidates_[k].state == State::kOpen && frontier - candidates_[k].s >= window_) {
      open.push_back(k);
    }
  }
  std::sort(open.begin(), open.end(),
            [&](std::size_t a, std::size_t b) { return slower(candidates_[a], candidates_[b]); });
  for (const std::size_t k : open) {
    Candidate& p = candidates_[k];
    bool undecided = false, blocked = false;
    const auto look = [&](std::size_t j) {
      const Candidate& q = candidates_[j];
      if (!slower(q, p)) return;
      if (q.state == State::kOpen) undecided = true;
      if (q.state == State::kKept) blocked = true;
    };
    for (std::size_t j = k; j-- > 0 && p.s - candidates_[j].s < window_;) look(j);
    for (std::size_t j = k + 1; j < candidates_.size() && candidates_[j].s - p.s < window_; ++j) {
      look(j);
    }
    if (blocked) {
      p.state = State::kDropped;
    } else if (!undecided) {
      p.state = State::kKept;
    }
  }
  // Hand over the decided ones in order, and forget those no open point can need.
  while (emitted_ < candidates_.size() && candidates_[emitted_].state != State::kOpen) {
    const Candidate& c = candidates_[emitted_++];
    if (c.state == State::kKept) slow_.push_back({c.s, c.feed});
  }
  const double first_open = emitted_ < candidates_.size() ? candidates_[emitted_].s : INFINITY;
  decided_to_ = std::min(first_open, frontier);
  while (emitted_ > 0 && candidates_.front().s + window_ <= decided_to_) {
    candidates_.pop_front();
    --emitted_;
  }
}

void G1Path::BuildTo(double s) const {
  while (!(decided_to_ > s && (length_ > s || built_all_))) {
    const double target = std::max(s, length_) + 2.0 * window_ + 1.0;
    while (length_ <= target && Advance()) {
    }
    Settle();
  }
}

std::optional<double> G1Path::Length() const {
  if (!built_all_) return std::nullopt;
  return length_;
}

std::span<const SlowPoint> G1Path::SlowPoints() const {
  return std::span<const SlowPoint>(slow_).subspan(slow_dead_);
}

void G1Path::Reach(double s) const {
  if (windowed_) BuildTo(s);
}

void G1Path::Release(double s) const {
  if (!windowed_ || !(s > released_)) return;
  released_ = s;
  const double keep_from = s - keep_behind_;
  // What lies wholly behind keep_from goes, in batches (DropFront).
  const auto pieces_behind = static_cast<std::size_t>(
      std::partition_point(pieces_.begin(), pieces_.end() - 1,
                           [&](const Piece& p) { return p.s0 + p.length < keep_from; }) -
      pieces_.begin());
  piece_base_ += static_cast<long>(DropFront(pieces_, pieces_behind));
  const auto corners_behind = static_cast<std::size_t>(
      std::partition_point(corners_.begin(),
                           corners_.begin() + static_cast<std::ptrdiff_t>(settled_ - corner_base_),
                           [&](const Corner& c) { return c.s1 < keep_from; }) -
      corners_.begin());
  corner_base_ += DropFront(corners_, corners_behind);
  while (slow_dead_ < slow_.size() && slow_[slow_dead_].s < keep_from) ++slow_dead_;
  if (DropFront(slow_, slow_dead_) > 0) slow_dead_ = 0;
}

void G1Path::Check() const {
  while (!built_all_) {
    BuildTo(length_ + 2.0 * window_ + 1.0);
    Release(length_);
  }
  BuildTo(length_);
}

const G1Path::CornerMaps& G1Path::Maps(long corner) const {
  if (maps_.empty())
    maps_.resize(windowed_ ? kCachedCorners : std::min(kCachedCorners, corners_.size()));
  CornerMaps& slot = maps_[static_cast<std::size_t>(corner) % maps_.size()];
  if (slot.corner != corner) {
    const Corner& c = CornerAt(corner);
    slot.bottom = std::make_shared<const ArcLengthMap>(ArcLengthOf(*c.bottom));
    slot.top = five_axis_ && top_param_ == TopParametrization::kTopArcLength
                   ? std::make_shared<const ArcLengthMap>(ArcLengthOf(*c.top))
                   : nullptr;
    slot.corner = corner;
  }
  return slot;
}

void G1Path::BuildPiecesTo(double s) const {
  while (!(length_ > s) && Advance()) {
  }
}

void G1Path::FailBehind(double s) const {
  throw Error(
      "arc length {} mm lies behind the part of the chain still held (from {} mm): the planner "
      "stepped back further than the chain keeps{}{}",
      s, pieces_.front().s0, behind_remedy_.empty() ? "" : "; ", behind_remedy_);
}

std::vector<double> G1Path::Breaks(double s0, double s1) const {
  if (!built_all_ && !(length_ > s1)) BuildPiecesTo(s1);
  std::vector<double> breaks;
  const auto first = std::upper_bound(pieces_.begin(), pieces_.end(), s0,
                                      [](double x, const Piece& p) { return x < p.s0; });
  for (auto it = first; it != pieces_.end() && it->s0 <= s1; ++it) breaks.push_back(it->s0);
  return breaks;
}

long G1Path::Find(double s, long hint) const {
  if (!built_all_ && !(length_ > s)) [[unlikely]] {
    BuildPiecesTo(s);
  }
  const long first = piece_base_;
  const long last = piece_base_ + static_cast<long>(pieces_.size()) - 1;
  if (first > 0 && s < pieces_.front().s0) [[unlikely]] {
    FailBehind(s);
  }
  long i = std::clamp(hint, first, last);
  if (s >= PieceAt(i).s0 && (i == last || s < PieceAt(i + 1).s0)) return i;
  const auto it = std::upper_bound(pieces_.begin(), pieces_.end(), s,
                                   [](double x, const Piece& p) { return x < p.s0; });
  return std::clamp(first + static_cast<long>(it - pieces_.begin()) - 1, first, last);
}

Pose G1Path::PoseAt(double s, int* hint) const {
  const long i = Find(s, *hint);
  *hint = static_cast<int>(i);
  const Piece& p = PieceAt(i);
  const double local = std::clamp(s - p.s0, 0.0, p.length);
  Pose pose;
  switch (p.kind) {
    case Piece::Kind::kLine: {
      pose.tip = p.a + local * p.d;
      if (five_axis_) {
        const Vector3d top = p.ta + (local / p.length) * (p.tb - p.ta);
        pose.axis = Unit(top - pose.tip);
      } else {
        pose.axis = axis_;
      }
      break;
    }
    case Piece::Kind::kArc: {
      const double angle = p.sweep * local / p.length;
      const double c = std::cos(angle), sn = std::sin(angle);
      if (p.n == Vector3d::UnitZ()) {
        pose.tip = p.a + Vector3d(c * p.d.x() - sn * p.d.y(), sn * p.d.x() + c * p.d.y(),
                                  p.dz * local / p.length);
      } else {
        pose.tip = p.a + c * p.d + sn * p.n.cross(p.d) + (p.dz * local / p.length) * p.n;
      }
      pose.axis = axis_;
      break;
    }
    case Piece::Kind::kCorner: {
      const Corner& corner = CornerAt(p.corner);
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
      pose.axis = Unit(corner.top->Point(std::clamp(w, 0.0, 1.0)) - pose.tip);
      break;
    }
  }
  return pose;
}

PathSample G1Path::At(const PathState& from, double s) const {
  PathSample sample;
  if (!built_all_ && !(length_ > s)) [[unlikely]] {
    BuildPiecesTo(s);
  }
  if (built_all_ && s >= length_) {
    sample.status = s > length_ ? PathStatus::kEnd : PathStatus::kOk;
    s = length_;
  }
  int hint = from.piece;
  sample.pose = PoseAt(s, &hint);
  sample.state = {.s = s, .piece = hint};
  return sample;
}

std::string G1Path::Describe(const PathState& state) const {
  if (piece_base_ > 0 && state.s < pieces_.front().s0) {
    return fmt::format("arc length {} mm", state.s);
  }
  const Piece& p = PieceAt(Find(state.s, state.piece));
  return fmt::format("arc length {} mm, {} of the block at line {}", state.s,
                     p.kind == Piece::Kind::kCorner ? "in the corner at the end"
                     : p.kind == Piece::Kind::kArc  ? "on the arc"
                                                    : "on the line",
                     p.line);
}

std::vector<std::unique_ptr<PathSource>> LinkMoves(const Pose& from, const Pose& to, double safe_z,
                                                   double clearance, const Machine& machine,
                                                   const CornerOptions& corners, bool straight) {
  const std::vector<Pose> points = LinkWaypoints(from, to, safe_z, clearance, straight);
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
