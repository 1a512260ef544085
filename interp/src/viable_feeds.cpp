#include "dtis/interp/viable_feeds.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "dtis/core/error.hpp"
#include "dtis/interp/motion_law.hpp"

namespace dtis::interp {
namespace {

// 0.6^k, the feeds Clip probes below a state that is not admissible, computed once (std::pow per
// probe was 1.5 % of a streamed 5-axis plan).
const std::array<double, 13> kShrink = [] {
  std::array<double, 13> p{};
  for (int k = 0; k < 13; ++k) p[static_cast<std::size_t>(k)] = std::pow(0.6, k);
  return p;
}();

// The period the stop law is reckoned in (the grid's time is continuous; the law's stops are
// sums over periods of this length).
constexpr double kLawPeriod = 1e-3;

// A repair plans the grid points near a dead end with this fraction of their limits (again at
// each repair there), down to kMinRepairMargin.
constexpr double kRepairFactor = 0.97;
constexpr double kMinRepairMargin = 0.5;

// A chord between two boundary points may read the boundary this much low (relative), no more.
constexpr double kChordTolerance = 2e-4;

// The grid is extended, once the planner is within half a window of its end, to this many
// windows ahead: each extension also recomputes the stretch before the old end that rest there
// held back, so longer extensions recompute less of the grid twice.
constexpr double kExtendWindows = 2.0;

// A slow point (the middle of a smoothed G1 corner) caps the feed of its grid point where the
// axis limits at that grid point, at zero acceleration, allow more than this many times the slow
// point's feed. The slow point's feed is the least over the corner of each axis' bound at a
// constant feed (Eq. 8); the grid point's own is the axes' joint one there, with the path's
// acceleration and jerk free. Where the two are close the grid sees what slows the corner, and
// the slow point's feed only held the motion below what the axes allow: on the 5-axis G1 sample
// its points are 1.1 to 2.1 times slower than their grid points, and without the cap the motion
// passes the first at 28.2 mm/s instead of its 25.0 (the paper's planner, which brakes for slow
// points without holding them, passes it at 28.0). A corner of a 3-axis link within a few
// hundredths of a millimetre turns within a few periods: its grid point sees 5.9 times the slow
// point's feed, and without the cap the exact step is refused there thousands of times.
constexpr double kUnseenCorner = 3.0;

// Past the ends of a boundary, Bisect looks for a viable feed down to this many steps of 0.6 below
// the top (1.7 % of it; 16 steps elsewhere). These looks mostly find none, and each step that
// finds none is a slack evaluation: 17 518 of 18 226 looks failed on the fine-block wave, 716 of
// 718 on the line. With 8 steps every sample plans the same setpoints (6 changed one) and the
// trident streams with 4 % fewer instructions, the fine-block wave 2.5 %, the 5-axis G1 program
// 2 %; a point below 1.7 % of the top would only have widened the boundary's acceleration range.
constexpr int kEndDescent = 8;

// Grid points a release of the deceleration is followed over; past them it is taken to go on at
// the jerk the axes give at the last (no more than its cap). A release longer than a few dozen
// grid points is one along fine blocks or at low feed, where that jerk changes little: followed
// over 64 grid points, the walks were a third of the fine-block wave's planning and a sixth of
// the trident's, for motion times within their spread (bench/spread.py medians over 17 draws,
// 64 against 16: the trident 2.359 against 2.342 s, the other samples within 0.15 %; cut at 8
// or 12 grid points, the trident was slower).
constexpr int kMaxReleaseNodes = 16;

// A release's walk (ReleaseFeed) goes on past a grid point whose own jerk cannot release the
// deceleration: where the axes' curvature terms take that jerk for a few grid points, those
// further on may. On a 5-axis G1 export's smoothed corners the tangential jerk the axes allow
// swings between -12 000 and +10 000 mm/s^3 along 0.05 mm of path, and a walk that stopped at
// the first such grid point held the feed 25 % below what `vpop` follows there. It goes on only
// where the deceleration is shallow, its release costing at most kShallowRelease of the feed at
// the grid point's jerk cap: braking hard into a turn (the trident's tips), the walk counted on
// jerk the exact step did not find, and planned the trident 2 % slower in the median (2.382
// against 2.331 s; with 0.5, 2.348 s; with 0.2, 2.331 s). Nor within kReleaseTailMm of the
// path's end, whose landing the end law plans: measured without the shallow rule, walks going on
// there handed the law states it landed only after backing off (the head-table pass 61 times
// instead of 2, plane_cl 2 002 instead of 299; alike from 0.3 to 3 mm).
constexpr double kShallowRelease = 0.2;
constexpr double kReleaseTailMm = 1.0;

// Away from a break of the path's derivatives (where a G1 block meets its smoothed corner, a
// B-spline's knot), past one such grid point only; within kBreakReachMm of one, past as many as
// it takes. At a break the axes' third derivatives jump, and with them the jerk the axes allow,
// which is what going on is for. Away from breaks a run of such grid points is the path bending
// ever faster into a turn (the trident's tips), where the walk counted on jerk the exact step
// did not find. Measured against going on everywhere: the G1 exports of `dtis compare` keep
// their motion times; the trident's medians over 17 lowered limits (bench/spread.py) are alike
// or shorter (2.328 -> 2.331 s at 2 m/min, 2.139 -> 2.134 at 2.4, 1.983 -> 1.982 at 3, 1.803 ->
// 1.777 at 5, 1.789 -> 1.776 at 8) and the 5-axis G1 program's over nine 14.890 -> 14.846 s;
// streamed over five lowered limits (callgrind) the trident takes 17 % fewer instructions, the
// 5-axis program 7 %. Not going on at all away from breaks made the trident's medians at 2.4, 3
// and 8 m/min 1.5 to 2 % longer, and with it, within 0.2 mm of a break instead of 1, the 10 um
// exports took 6 % (5-axis) and 3.5 % (3-axis) longer; within 0.2 mm and past one grid point
// away, the 5-axis one 3.6 % (3.115 against 3.006 s, which tests/lookahead_test.cpp catches).
constexpr int kAwayFromBreaks = 1;
// How near a break a grid point counts as at it.
constexpr double kBreakReachMm = 1.0;

// Grid points per JerkBlock: a release's bound that follows dozens of grid points (a release at
// a high feed covers millimetres) reads one bound per block where none of its points lowers the
// least jerk, and the same least jerk comes out.
constexpr long kJerkBlock = 8;

// The time t > 0 in which a motion starting with feed v, acceleration a and constant jerk j
// covers the distance h (v t + a t^2 / 2 + j t^3 / 6 = h, the first root), or NaN when it comes to
// rest first. Newton from the root's series in h, or from the least time any one term alone needs.
double TimeToCover(double v, double a, double j, double h) {
  const auto covered = [&](double x) { return x * (v + x * (a / 2.0 + x * j / 6.0)); };
  const auto feed = [&](double x) { return v + x * (a + x * j / 2.0); };
  // Where the feed dominates, the series of the root in x = h / v (the reversion of
  // h = v t + a t^2 / 2 + j t^3 / 6) to third order: over a grid stretch it is within a few parts
  // in 1e6, and Newton needs one or two steps.
  double t = INFINITY;
  const double x = v > 1e-9 ? h / v : INFINITY;
  if (std::isfinite(x)) {
    const double c2 = -a / (2.0 * v), c3 = a * a / (2.0 * v * v) - j / (6.0 * v);
    if (std::abs(c2 * x) < 0.25 && std::abs(c3 * x * x) < 0.25) t = x * (1.0 + x * (c2 + x * c3));
  }
  if (!std::isfinite(t)) {
    // Braking: the first time the feed v + a t + j t^2 / 2 reaches zero. Short of h by then, the
    // motion comes to rest first. (From the series' start Newton finds a root past that rest if
    // any, where the feed has turned negative on the way: the checks after it tell.)
    double rest = INFINITY;
    if (a < 0.0 || j < 0.0) {
      const double c = j / 2.0, disc = a * a - 4.0 * c * v;
      if (std::abs(c) * v <= 1e-12 * a * a) {
        if (a < 0.0) rest = -v / a;
      } else if (disc >= 0.0) {
        // The roots q / c and v / q (q from the sign of a, without cancellation).
        const double q = -0.5 * (a + std::copysign(std::sqrt(disc), a));
        for (const double r : {q / c, q != 0.0 ? v / q : INFINITY}) {
          if (r >= 0.0) rest = std::min(rest, r);
        }
      }
      if (covered(rest) < h) return NAN;
    }
    // The least of the times the feed, the acceleration or the jerk alone would take (an upper
    // bound of the root where all three push forward, and Newton then closes in from above).
    t = x;
    if (a > 0.0) t = std::min(t, std::sqrt(2.0 * h / a));
    if (j > 0.0) t = std::min(t, std::cbrt(6.0 * h / j));
    if (!std::isfinite(t)) t = std::cbrt(6.0 * h / std::max(std::abs(j), 1e-9));
    t = std::min(t, rest);
  }
  for (int it = 0; it < 40; ++it) {
    const double f = covered(t) - h;
    const double df = feed(t);
    if (df <= 1e-12) {
      t *= 0.5;
      continue;
    }
    const double step = f / df;
    double next = t - step;
    if (next <= 0.0) next = 0.5 * t;
    // Newton's next error is about step^2 f'' / (2 f'): below 1e-13 t, this step is the last.
    const bool done =
        std::abs(step) <= 1e-13 * t ||
        (std::abs(step) <= 1e-4 * t && step * step * std::abs(a + j * next) <= 2e-13 * next * df);
    t = next;
    if (done) break;
  }
  if (std::abs(covered(t) - h) > 1e-9 * h) return NAN;
  // The feed must not turn negative on the way (its minimum is at t = -a / j): the check above
  // took j as zero where it is negligible, and a series start may lie past the rest.
  if (feed(t) < 0.0) return NAN;
  if (j != 0.0) {
    const double tm = -a / j;
    if (tm > 0.0 && tm < t && feed(tm) < 0.0) return NAN;
  }
  return t;
}

// A constant jerk j held from (v, a) over the distance h: the state where it ends. False when the
// motion comes to rest (or would turn back) before covering h.
bool Forward(double v, double a, double j, double h, double* v2, double* a2) {
  const double t = TimeToCover(v, a, j, h);
  if (std::isnan(t)) return false;
  *v2 = v + t * (a + t * j / 2.0);
  *a2 = a + j * t;
  return true;
}

// The state a constant jerk j held over the distance h came from, ending at (v2, a2): the same
// motion run backwards in time (feed v2, acceleration -a2, jerk j).
bool Backward(double v2, double a2, double j, double h, double* v, double* a) {
  const double t = TimeToCover(v2, -a2, j, h);
  if (std::isnan(t)) return false;
  *v = v2 + t * (-a2 + t * j / 2.0);
  *a = a2 - j * t;
  return true;
}

// The largest x in [good, bad) where slack(x) >= 0 (within 1e-9 of bad), from slack(good) =
// f_good >= 0 and slack(bad) = f_bad < 0: regula falsi with the Illinois rule (the end kept twice
// has its slack halved). A step is at least a fraction of the tolerance from either end, so that
// once an estimate lands within it of the root, the next one closes the bracket; a bisection
// follows whenever two steps have not halved the bracket (the slacks it is used on are only
// piecewise smooth).
template <class Slack>
double LargestWithin(double good, double f_good, double bad, double f_bad, const Slack& slack) {
  int kept = 0;  // > 0: `good` kept that many times in a row, < 0: `bad`
  double before = INFINITY, last = INFINITY;  // the bracket's width two steps back, one step back
  for (int it = 0; it < 48 && bad - good > 1e-9 * bad; ++it) {
    const double width = bad - good;
    const bool bisect = width > 0.5 * before || !(f_good - f_bad > 0.0);
    double x = bisect ? 0.5 * (good + bad) : good + width * f_good / (f_good - f_bad);
    const double edge = 0.4e-9 * bad;
    x = std::clamp(x, good + edge, bad - edge);
    const double f = slack(x);
    if (f >= 0.0) {
      good = x, f_good = f;
      kept = std::min(kept, 0) - 1;
      if (kept <= -2) f_bad *= 0.5;
    } else {
      bad = x, f_bad = f;
      kept = std::max(kept, 0) + 1;
      if (kept >= 2) f_good *= 0.5;
    }
    before = last;
    last = width;
  }
  return good;
}

}  // namespace

ViableFeeds::ViableFeeds(const PathSource& path, const Machine& machine,
                         const LookAheadLimits& limits, const LookAheadOptions& options)
    : path_(path), machine_(machine), limits_(limits), full_(limits), options_(options) {
  n_axes_ = machine.AxisCount();
  for (int i = 0; i < n_axes_; ++i) {
    limits_.v[i] *= options_.velocity_fraction;
    limits_.a[i] *= options_.acceleration_fraction;
    limits_.j[i] *= options_.jerk_fraction;
  }
  // The look-ahead must see further than the longest stop: from the feed, with the weakest axis'
  // acceleration and jerk (a path along an axis, the worst case for linear axes; rotary-dominated
  // stretches lengthen the window as they are met, Extend).
  double amin = INFINITY, jmin = INFINITY;
  for (int i = 0; i < n_axes_; ++i) {
    if (machine.Axes()[static_cast<std::size_t>(i)].rotary) continue;
    amin = std::min(amin, limits_.a[i]);
    jmin = std::min(jmin, limits_.j[i]);
  }
  amin = std::min(amin, limits_.tangential_acceleration);
  jmin = std::min(jmin, limits_.tangential_jerk);
  const double f = limits_.feed;
  const double stop =
      std::isfinite(amin) && std::isfinite(jmin)
          ? f * std::max(std::sqrt(f / jmin), f / (2.0 * amin) + amin / (2.0 * jmin))
          : 10.0;
  window_ = std::max(6.0 * stop, 20.0);
}

void ViableFeeds::Append(Node node) {
  node.id = nodes_.empty() ? 0 : nodes_.back().id + 1;
  if (node.id % kJerkBlock == 0) {
    blocks_.push_back(
        {node.id, 0, node.margin, node.d1.cwiseAbs(), node.d2.cwiseAbs(), node.d3.cwiseAbs()});
  }
  node.near_break = node.s - last_break_s_ <= kBreakReachMm;
  if (node.break_after) {
    // The nodes appended within reach before it are near it too, back to the first already
    // marked (those before it are marked, or beyond reach of this break too).
    last_break_s_ = node.s;
    node.near_break = true;
    for (auto q = nodes_.rbegin();
         q != nodes_.rend() && !q->near_break && q->s >= node.s - kBreakReachMm; ++q) {
      q->near_break = true;
    }
  }
  JerkBlock& b = blocks_.back();
  ++b.count;
  b.margin = std::min(b.margin, node.margin);
  b.d1 = b.d1.cwiseMax(node.d1.cwiseAbs());
  b.d2 = b.d2.cwiseMax(node.d2.cwiseAbs());
  b.d3 = b.d3.cwiseMax(node.d3.cwiseAbs());
  nodes_.push_back(std::move(node));
}

double ViableFeeds::End() const { return nodes_.empty() ? 0.0 : nodes_.back().s; }

bool ViableFeeds::Admissible(const Node& n, double v, double a, double* lo, double* hi) const {
  return Admissible(n, n.margin, v, a, lo, hi);
}

bool ViableFeeds::Admissible(const Node& n, double m, double v, double a, double* lo,
                             double* hi) const {
  if (!(v >= 0.0) || v > n.feed_cap * m || std::abs(a) > limits_.tangential_acceleration * m) {
    return false;
  }
  for (int i = 0; i < n_axes_; ++i) {
    const double g = n.d1[i];
    if (std::abs(g) * v > limits_.v[i] * m) return false;
    if (std::abs(n.d2[i] * v * v + g * a) > limits_.a[i] * m) return false;
  }
  return JerkInterval(n, limits_, m, v, a, lo, hi);
}

bool ViableFeeds::JerkInterval(const Node& n, const LookAheadLimits& l, double m, double v,
                               double a, double* lo, double* hi) const {
  *lo = -l.tangential_jerk * m;
  *hi = l.tangential_jerk * m;
  for (int i = 0; i < n_axes_; ++i) {
    const double g = n.d1[i];
    const double c = v * (n.d3[i] * v * v + 3.0 * n.d2[i] * a);
    const double J = l.j[i] * m;
    if (std::abs(g) < 1e-12) {
      if (std::abs(c) > J) return false;
      continue;
    }
    double jl = (-J - c) / g, jh = (J - c) / g;
    if (g < 0.0) std::swap(jl, jh);
    *lo = std::max(*lo, jl);
    *hi = std::min(*hi, jh);
  }
  return *lo <= *hi;
}

double ViableFeeds::Excess(const Node& n, double v, double a) const {
  const double m = n.margin;
  double worst = -INFINITY;
  double lo = -limits_.tangential_jerk * m, hi = limits_.tangential_jerk * m;
  for (int i = 0; i < n_axes_; ++i) {
    const double g = n.d1[i];
    const double A = limits_.a[i] * m, J = limits_.j[i] * m;
    worst = std::max(worst, (std::abs(n.d2[i] * v * v + g * a) - A) / A);
    const double c = v * (n.d3[i] * v * v + 3.0 * n.d2[i] * a);
    if (std::abs(g) < 1e-12) {
      worst = std::max(worst, (std::abs(c) - J) / J);
      continue;
    }
    double jl = (-J - c) / g, jh = (J - c) / g;
    if (g < 0.0) std::swap(jl, jh);
    lo = std::max(lo, jl);
    hi = std::min(hi, jh);
  }
  // The jerk intervals' overlap, against the largest tangential jerk the axes give here.
  const double scale = n.jerk_cap > 0.0 ? n.jerk_cap : limits_.tangential_jerk;
  return std::max(worst, (lo - hi) / (scale * m));
}

double ViableFeeds::Clip(const Node& n, double a, double v) const {
  double lo, hi;
  // The velocity caps are closed forms.
  v = std::min(v, n.feed_cap * n.margin);
  for (int i = 0; i < n_axes_; ++i) {
    const double g = std::abs(n.d1[i]);
    if (g > 0.0) v = std::min(v, limits_.v[i] * n.margin / g);
  }
  if (Admissible(n, v, a, &lo, &hi)) return v;
  if (std::abs(a) > limits_.tangential_acceleration * n.margin) return -1.0;
  if (!(v > 0.0)) return Admissible(n, 0.0, a, &lo, &hi) ? 0.0 : -1.0;
  // Between 0 and v (within the velocity caps, a within its own) the excess says what
  // Admissible would: <= 0 where admissible.
  const auto slack = [&](double x) { return -Excess(n, x, a); };
  double good = -1.0, bad = v, f_good = 0.0, f_bad = -1.0;
  for (int k = 1; k <= 12; ++k) {
    const double x = v * kShrink[static_cast<std::size_t>(k)];
    const double f = slack(x);
    if (f >= 0.0) {
      good = x, f_good = f;
      break;
    }
    bad = x, f_bad = f;
  }
  if (good < 0.0) return slack(0.0) >= 0.0 ? 0.0 : -1.0;
  // The excess is smooth between the limits it switches among: where one limit binds, regula
  // falsi lands within 1e-9 in a few steps where bisection took 24.
  if (bad == v) f_bad = slack(v);  // the first step down was admissible
  return LargestWithin(good, f_good, bad, f_bad, slack);
}

double ViableFeeds::Boundary(const std::vector<Point>& b, double a) {
  if (b.empty() || a < b.front().a || a > b.back().a) return -1.0;
  const auto it =
      std::upper_bound(b.begin(), b.end(), a, [](double x, const Point& p) { return x < p.a; });
  if (it == b.end()) return b.back().v;
  if (it == b.begin()) return b.front().v;
  const Point& r = *it;
  const Point& l = *(it - 1);
  return l.v + (a - l.a) / (r.a - l.a) * (r.v - l.v);
}

double ViableFeeds::Curved(const std::vector<Point>& b, std::size_t i, double a) {
  // Monotone cubic (Fritsch and Carlson) between points i and i + 1.
  const Point& l = b[i];
  const Point& r = b[i + 1];
  const double h = r.a - l.a;
  const double d = (r.v - l.v) / h;
  const auto slope = [&](std::size_t k) {
    if (k == 0 || k + 1 >= b.size()) return d;
    const double d0 = (b[k].v - b[k - 1].v) / (b[k].a - b[k - 1].a);
    const double d1 = (b[k + 1].v - b[k].v) / (b[k + 1].a - b[k].a);
    if (d0 * d1 <= 0.0) return 0.0;
    const double h0 = b[k].a - b[k - 1].a, h1 = b[k + 1].a - b[k].a;
    const double w0 = 2.0 * h1 + h0, w1 = h1 + 2.0 * h0;
    return (w0 + w1) / (w0 / d0 + w1 / d1);
  };
  const double m0 = slope(i) * h, m1 = slope(i + 1) * h;
  const double t = (a - l.a) / h, t2 = t * t, t3 = t2 * t;
  return (2.0 * t3 - 3.0 * t2 + 1.0) * l.v + (t3 - 2.0 * t2 + t) * m0 +
         (-2.0 * t3 + 3.0 * t2) * r.v + (t3 - t2) * m1;
}

template <typename Points>
double ViableFeeds::LeastJerk(const Points& n, double v, double deceleration) const {
  // On a JerkBlock the values are already each node's worst (|.| changes nothing) and rounding is
  // monotone, so the block's least jerk is at most each node's in floating point too.
  const double m = n.margin;
  double least = limits_.tangential_jerk * m;
  for (int i = 0; i < n_axes_; ++i) {
    const double curvature =
        v * (std::abs(n.d3[i]) * v * v + 3.0 * std::abs(n.d2[i]) * deceleration);
    const double room = limits_.j[i] * m - curvature;
    const double g = std::abs(n.d1[i]);
    if (room < 0.0) return 0.0;
    if (g > 1e-12) least = std::min(least, room / g);
  }
  return least;
}

ViableFeeds::JerkBlock& ViableFeeds::BlockOf(long id) {
  return blocks_[static_cast<std::size_t>((id - blocks_.front().first) / kJerkBlock)];
}

const ViableFeeds::JerkBlock& ViableFeeds::BlockOf(long id) const {
  return blocks_[static_cast<std::size_t>((id - blocks_.front().first) / kJerkBlock)];
}

double ViableFeeds::ReleaseFeed(const Node& n, double s, double v, double a) const {
  // Walk the grid from n with the largest jerk the axes allow at each grid point (where the path
  // turns, its curvature terms give the axes more room than their jerk limits alone).
  auto it = nodes_.begin() + (n.id - nodes_.front().id);
  if (v > 0.0) {
    // First a bound that needs no walk: the release loses at most a^2 / (2 j) of the feed when
    // the jerk stays at least j, and the axes give at least LeastJerk over the states the release
    // passes through (feed at most v, deceleration at most -a). At that jerk the release is over
    // within -a / j, at most v (-a / j) along the path.
    const double need = a * a / (2.0 * v);
    double least = INFINITY;
    auto q = it;
    while (q != nodes_.end()) {
      if (q->id % kJerkBlock == 0) {
        // A whole block none of whose points can lower `least`: the walk would only look for
        // the end of the release in it.
        const JerkBlock& b = BlockOf(q->id);
        if (b.count == kJerkBlock && LeastJerk(b, v, -a) >= least) {
          if ((q + (kJerkBlock - 1))->s >= s + v * -a / least) break;
          q += kJerkBlock;
          continue;
        }
      }
      least = std::min(least, LeastJerk(*q, v, -a));
      if (least < need) break;
      if (q->s >= s + v * -a / least) break;
      ++q;
    }
    if (least >= need) return v - a * a / (2.0 * least);
  }
  // The largest jerk the axes allow at a grid point in the state the walk has reached there. It
  // is negative where the curvature terms q_sss v^3 + 3 q_ss v a leave an axis no room to release
  // with: there the deceleration grows, until a grid point further on lets it shrink.
  const auto jerk = [&](const Node& here) {
    double lo, hi;
    return Admissible(here, v, a, &lo, &hi) ? hi : here.jerk_cap;
  };
  // The feed left if the release went on at jerk j from here; where j <= 0 it never ends, and a
  // jerk of a thousandth of the cap stands in (how far from viable the state is, a guide only).
  const auto left = [&](const Node& here, double j) {
    return v - a * a / (2.0 * std::max(j, 1e-3 * here.jerk_cap));
  };
  const double tail = length_ ? *length_ - kReleaseTailMm : INFINITY;
  int away = 0;  // grid points gone on past away from breaks
  for (int k = 0; k < kMaxReleaseNodes; ++k) {
    const Node& here = *it;
    const double j = jerk(here);
    const double released = left(here, j);
    ++it;
    // A grid point that cannot release the state with its own jerk ends the walk where the state
    // brakes hard (its release would take more than kShallowRelease of the feed even at the
    // grid point's jerk cap), near the path's end, or at a second such grid point away from
    // the path's breaks.
    if (it == nodes_.end() ||
        (released < 0.0 && (s >= tail || (!here.near_break && ++away > kAwayFromBreaks) ||
                            a * a / (2.0 * here.jerk_cap) > kShallowRelease * v))) {
      return released;
    }
    const double h = it->s - s;
    if (h > 0.0) {
      if (j > 0.0) {
        const double t = -a / j;
        if (released >= 0.0 && t * (v + t * (a / 2.0 + t * j / 6.0)) <= h) return released;
      }
      double v2, a2;
      if (!Forward(v, a, j, h, &v2, &a2)) return released;
      v = v2, a = a2;
      if (a >= 0.0) return v;
    }
    s = it->s;
  }
  return left(*it, std::min(jerk(*it), it->jerk_cap));
}

double ViableFeeds::SlackTowards(const Node& n, double s, const Node& next, double v,
                                 double a) const {
  const auto& b = next.boundary;
  if (b.empty()) return -v - 1.0;
  // Outside the boundary's acceleration range: how far, as a feed (a guide for the search of the
  // least violation, not a measure).
  const auto outside = [&](double a2, double v2) {
    if (a2 < b.front().a) return b.front().v - v2 - 1e-2 * (b.front().a - a2);
    return b.back().v - v2 - 1e-2 * (a2 - b.back().a);
  };
  double lo, hi;
  if (!Admissible(n, v, a, &lo, &hi)) {
    const double c = Clip(n, a, v);
    return c >= 0.0 ? c - v : -v - 1.0;
  }
  // Braked so hard that the feed runs out before the deceleration is released: not viable
  // whatever lies ahead (the viable set's lower side).
  if (a < 0.0) {
    const double left = ReleaseFeed(n, s, v, a);
    if (left < 0.0) return left;
  }
  const double h = next.s - s;
  if (h <= 0.0) {
    const double cap = Boundary(b, a);
    return cap >= 0.0 ? cap - v : outside(a, v);
  }
  // The peak of the next boundary: aim the acceleration there.
  const double peak_a = b[next.peak].a;
  const double t = h / std::max(v, 1e-9);
  double best = -INFINITY;
  // The jerk that aims at the peak, then the extreme ones (each once: the aim is often one of
  // them).
  const double aim = std::clamp((peak_a - a) / t, lo, hi);
  const double jerks[3] = {aim, lo, hi};
  for (int k = 0; k < 3; ++k) {
    const double j = jerks[k];
    if ((k > 0 && j == aim) || (k == 2 && j == lo)) continue;
    double v2, a2;
    if (!Forward(v, a, j, h, &v2, &a2)) {
      // Comes to rest before the next grid point: viable if the stop law gets there at rest.
      const StopDistance d = StopDistanceFrom(v, a, n.jerk_cap, n.acceleration_cap, 1e-4);
      if (!d.reverses && d.distance <= h) return 0.0;
      continue;
    }
    const double cap = Boundary(b, a2);
    best = std::max(best, cap >= 0.0 ? cap - v2 : outside(a2, v2));
  }
  return best;
}

double ViableFeeds::Slack(double s, double v, double a) const {
  if (nodes_.size() < 2) return -v - 1.0;
  auto it = After(s);
  if (it == nodes_.begin()) ++it;
  if (it == nodes_.end()) {
    const Node& last = nodes_.back();
    const double cap = Boundary(last.boundary, a);
    return cap >= 0.0 ? cap - v : -v - 1.0;
  }
  const Node& next = *it;
  const Node& here = *(it - 1);
  return SlackTowards(here, s, next, v, a);
}

double ViableFeeds::Bisect(const Node& n, const Node& next, double a, int descent) const {
  const double top = Clip(n, a, n.feed_cap);
  if (top < 0.0) return -1.0;
  // A braking state must keep the feed its release takes away: if even the top cannot, none can
  // (below it, the slack says which can).
  if (a < 0.0 && ReleaseFeed(n, n.s, top, a) < 0.0) return -1.0;
  const auto slack = [&](double v) { return SlackTowards(n, n.s, next, v, a); };
  double bad = top, f_bad = slack(top);
  if (f_bad >= 0.0) return top;
  // A bracket: first where the slack, close to linear in v with slope -1, puts the boundary, then
  // geometrically down.
  double good = -1.0, f_good = 0.0;
  const double guess = top + f_bad;
  if (guess > 0.0 && guess < top) {
    const double f = slack(guess);
    if (f >= 0.0) {
      good = guess, f_good = f;
    } else {
      bad = guess, f_bad = f;
    }
  }
  for (int k = 1; k <= descent && good < 0.0 && bad > 0.0; ++k) {
    const double x = bad * 0.6;
    const double f = slack(x);
    if (f >= 0.0) {
      good = x, f_good = f;
    } else {
      bad = x, f_bad = f;
    }
  }
  if (good < 0.0) return -1.0;
  return LargestWithin(good, f_good, bad, f_bad, slack);
}

void ViableFeeds::Propagate(Node* n, const Node& next) const {
  Flow(n, next);
  n->peak = PeakOf(n->boundary);
}

std::size_t ViableFeeds::PeakOf(const std::vector<Point>& b) {
  std::size_t peak = 0;
  for (std::size_t i = 1; i < b.size(); ++i) {
    if (b[i].v > b[peak].v) peak = i;
  }
  return peak;
}

void ViableFeeds::Flow(Node* n, const Node& next) const {
  const double h = next.s - n->s;
  const auto& b = next.boundary;
  if (b.empty()) {
    n->boundary.clear();  // nothing viable ahead: nothing here either
    return;
  }
  std::vector<Point> out;
  out.reserve(b.size() + 8);
  if (h <= 0.0) {
    // Either side of a break: the same states, admissible on both sides.
    for (const Point& p : b) {
      const double c = Clip(*n, p.a, p.v);
      if (c >= 0.0) out.push_back({p.a, c});
    }
    n->boundary = std::move(out);
    return;
  }
  if (n->law_entry) {
    // Past this point the law brings the motion to rest wherever it binds: the states it lands
    // from, within what the axes allow here (what lies past them is the law's to get through).
    for (const Point& p : LawBoundary(*n)) {
      const double c = Clip(*n, p.a, p.v);
      if (c >= 0.0) out.push_back({p.a, c});
    }
    n->boundary = std::move(out);
    return;
  }
  // The peak: the points at the boundary's largest feed (a plateau at the feed cap has many).
  const std::size_t peak = next.peak;
  const double top = b[peak].v;
  std::size_t peak_left = peak, peak_right = peak;
  while (peak_left > 0 && b[peak_left - 1].v >= top - 1e-9 * (1.0 + top)) --peak_left;
  while (peak_right + 1 < b.size() && b[peak_right + 1].v >= top - 1e-9 * (1.0 + top)) ++peak_right;
  const double a_range = n->acceleration_cap;
  // Flow a boundary point of `next` back to `n` along the extreme jerk that keeps it viable:
  // braking as hard as allowed right of the peak, accelerating left of it. The jerk is held over
  // the whole stretch, so it must be one the axes allow at both of its ends: in the state it
  // comes from (a fixed point, found in a few rounds) and in the one it reaches. With the bound of
  // the first alone, a boundary where the axes' jerk interval narrows along the stretch promised
  // states that only a jerk outside it could hold; the exact step rode the boundary out of the
  // viable set and, refused everything, braked as hard as it could (five_axis_g1: 11 010 of its
  // 15 000 steps).
  // `hold`: the jerk that keeps the acceleration (inside a plateau, where any successor on it
  // will do).
  const auto flow = [&](const Point& e, bool brake, bool hold = false) {
    double lo, hi;
    if (!Admissible(next, e.v, e.a, &lo, &hi)) return;
    if (hold && (lo > 0.0 || hi < 0.0)) return;
    double j = hold ? 0.0 : brake ? lo : hi;
    double v = e.v, a = e.a;
    for (int round = 0; round < 4; ++round) {
      if (!Backward(e.v, e.a, j, h, &v, &a)) return;
      if (std::abs(a) > 2.0 * a_range) return;
      if (a < 0.0 && ReleaseFeed(*n, n->s, v, a) < 0.0) return;
      double lo0, hi0;
      if (!Admissible(*n, v, a, &lo0, &hi0)) {
        const double c = Clip(*n, a, v);
        if (c >= 0.0) out.push_back({a, c});
        return;
      }
      if (hold) {
        if (lo0 > 0.0 || hi0 < 0.0) return;
        break;
      }
      const double j0 = brake ? std::max(lo0, lo) : std::min(hi0, hi);
      if (std::abs(j0 - j) <= 1e-9 * (std::abs(j) + 1.0)) break;
      j = j0;
    }
    out.push_back({a, v});
  };
  for (std::size_t i = 0; i < b.size(); ++i) {
    if (i >= peak_right) flow(b[i], true);
    if (i <= peak_left) flow(b[i], false);
    if (i >= peak_left && i <= peak_right) flow(b[i], false, true);
  }
  if (out.empty()) {
    const double v = Bisect(*n, next, 0.0);
    if (v >= 0.0) out.push_back({0.0, v});
  }
  std::sort(out.begin(), out.end(), [](const Point& x, const Point& y) { return x.a < y.a; });
  // Merge points closer than the resolution allows (keep the higher: both are viable), and fill
  // gaps wider than it by flowing back an interpolated point of `next`.
  const double resolution = options_.boundary_resolution * a_range;
  const double merge = 0.05 * resolution;
  const double t = h / std::max(b[peak].v, 1.0);
  const double peak_a = b[peak].a;
  std::vector<Point> merged;
  merged.reserve(out.size() + 8);
  for (const Point& p : out) {
    if (!merged.empty() && p.a - merged.back().a < merge) {
      merged.back().v = std::max(merged.back().v, p.v);
      continue;
    }
    if (!merged.empty() && p.a - merged.back().a > resolution) {
      const Point l = merged.back();
      const int extra = std::min(16, static_cast<int>(std::ceil((p.a - l.a) / resolution)) - 1);
      for (int e = 1; e <= extra; ++e) {
        const double f = static_cast<double>(e) / (extra + 1);
        const Point spawned =
            Spawn(*n, next, l.a + f * (p.a - l.a), l.v + f * (p.v - l.v), peak_a, t);
        if (spawned.v >= 0.0 && spawned.a > merged.back().a + merge && spawned.a < p.a - merge) {
          merged.push_back(spawned);
        }
      }
    }
    merged.push_back(p);
  }
  // Where the flows move inward (the jerk interval lies all on one side), look past the ends.
  for (const int side : {-1, 1}) {
    for (int k = 0; k < 4 && !merged.empty(); ++k) {
      const Point& end = side > 0 ? merged.back() : merged.front();
      const double a = end.a + side * resolution;
      if (std::abs(a) > a_range) break;
      const double v = Bisect(*n, next, a, kEndDescent);
      if (v < 0.0) break;
      if (side > 0) {
        merged.push_back({a, v});
      } else {
        merged.insert(merged.begin(), Point{a, v});
      }
    }
  }
  // Where a chord reads the boundary low (it bends between two points), add the point between.
  for (int pass = 0; pass < 2; ++pass) {
    std::vector<Point> refined;
    refined.reserve(2 * merged.size());
    for (std::size_t i = 0; i + 1 < merged.size(); ++i) {
      refined.push_back(merged[i]);
      const double mid = 0.5 * (merged[i].a + merged[i + 1].a);
      if (merged[i + 1].a - merged[i].a < 2.0 * merge) continue;
      const double chord = 0.5 * (merged[i].v + merged[i + 1].v);
      const double curve = Curved(merged, i, mid);
      if (curve - chord <= kChordTolerance * (1.0 + chord)) continue;
      const Point spawned = Spawn(*n, next, mid, curve, peak_a, t);
      if (spawned.v >= 0.0 && spawned.a > merged[i].a + merge &&
          spawned.a < merged[i + 1].a - merge) {
        refined.push_back(spawned);
      }
    }
    if (!merged.empty()) refined.push_back(merged.back());
    if (refined.size() == merged.size()) break;
    merged = std::move(refined);
  }
  // Drop points the straight line between their neighbours carries (a plateau at the feed).
  std::vector<Point> simple;
  simple.reserve(merged.size());
  for (std::size_t i = 0; i < merged.size(); ++i) {
    if (i > 0 && i + 1 < merged.size() && !simple.empty()) {
      const Point& l = simple.back();
      const Point& r = merged[i + 1];
      const double line = l.v + (merged[i].a - l.a) / (r.a - l.a) * (r.v - l.v);
      if (std::abs(line - merged[i].v) <= 1e-9 * (1.0 + merged[i].v)) continue;
    }
    simple.push_back(merged[i]);
  }
  n->boundary = std::move(simple);
}

std::vector<ViableFeeds::Point> ViableFeeds::LawBoundary(const Node& n) const {
  // The law's capacity over its stretch, as the exact step plans it (vpop.cpp, LookAhead: the
  // least jerk and acceleration caps of the grid points before the end).
  const double jerk = MinJerkCap(n.s, End()), acceleration = MinAccelerationCap(n.s, End());
  const double zone = options_.law_zone_mm;
  // The law from (v, a), with the jerk the exact step's end law plans with there: the axes' jerk
  // interval around the state, symmetric and at least a quarter of the cap (vpop.cpp, Available),
  // which is less than the cap where the path bends, as the terms q_sss v^3 + 3 q_ss v a take
  // part of an axis' jerk. Planned with the cap alone, the boundary handed the leading-line
  // passes states at the stretch's entry that the law, braking at the jerk actually left, could
  // not land: it reached the end still braking, and the back-off replaced the approach period by
  // period (125 of that job's 167 back-offs).
  const auto run = [&](double v, double a) -> StopDistance {
    double lo, hi;
    if (!JerkInterval(n, full_, n.margin, std::max(v, 0.0), a, &lo, &hi)) return {0.0, 0, true};
    const double j = std::min(jerk, std::max(std::min(-lo, hi), 0.25 * n.jerk_cap));
    return StopDistanceFrom(v, a, j, acceleration, kLawPeriod);
  };
  const auto lands = [&](double v, double a) {
    const StopDistance d = run(v, a);
    return !d.reverses && d.distance <= zone;
  };
  std::vector<Point> out;
  // A stop within the stretch d from (v, a) needs |a| of the order of (J^2 d)^(1/3): far less than
  // the acceleration cap where the stretch is short.
  const double reach = std::min(acceleration, 4.0 * std::cbrt(jerk * jerk * zone));
  const int k = 2 * static_cast<int>(std::ceil(1.0 / options_.boundary_resolution));
  for (int i = -k; i <= k; ++i) {
    const double a = reach * i / k;
    // The least feed that releases the deceleration before it runs out, then the largest that
    // still stops within the stretch.
    double good = a < 0.0 ? ReleaseGain(-a, jerk, kLawPeriod) * (1.0 + 1e-6) + 1e-9 : 0.0;
    double bad = n.feed_cap;
    if (a < 0.0 && run(good, a).reverses) {
      // Where the axes leave less jerk than the cap, the release needs a higher feed (dropping
      // the point instead cut the deepest decelerations off every plane_cl pass' boundary).
      double low = good, high = bad;
      if (run(high, a).reverses) continue;
      for (int it = 0; it < 60 && high - low > 1e-9 * high; ++it) {
        const double mid = 0.5 * (low + high);
        (run(mid, a).reverses ? low : high) = mid;
      }
      good = high;
    }
    if (!lands(good, a)) continue;
    if (lands(bad, a)) {
      out.push_back({a, bad});
      continue;
    }
    for (int it = 0; it < 60 && bad - good > 1e-9 * bad; ++it) {
      const double mid = 0.5 * (good + bad);
      if (lands(mid, a)) {
        good = mid;
      } else {
        bad = mid;
      }
    }
    out.push_back({a, good});
  }
  return out;
}

ViableFeeds::Point ViableFeeds::Spawn(const Node& n, const Node& next, double a, double v_guess,
                                      double peak_a, double t) const {
  // The boundary point of n near acceleration a: the point of `next` that the extreme jerk (the
  // one of the state guessed at a) carries there, flowed back; a bisection where that fails.
  double lo, hi;
  if (Admissible(n, v_guess, a, &lo, &hi)) {
    const double j = a > peak_a ? lo : hi;
    const double a2 = a + j * t;
    const double v2 = Boundary(next.boundary, a2);
    double pv, pa;
    if (v2 >= 0.0 && Backward(v2, a2, j, next.s - n.s, &pv, &pa) &&
        !(pa < 0.0 && ReleaseFeed(n, n.s, pv, pa) < 0.0)) {
      const double c = Clip(n, pa, pv);
      if (c >= 0.0) return {pa, c};
    }
  }
  return {a, Bisect(n, next, a)};
}

ViableFeeds::Node ViableFeeds::Sample(double s, const PathState& hint, const AxisVector& q_hint,
                                      int side) const {
  ++const_cast<ViableFeeds*>(this)->grid_points_;
  Node n;
  n.s = s;
  const double length = length_.value_or(INFINITY);
  const auto pose_at = [&](double x, PathState* st, AxisVector* q, const AxisVector& near) {
    const PathSample p = path_.At(*st, x);
    // In the exact step's words (vpop.cpp), so that a path fails alike with either planner.
    if (p.status == PathStatus::kLeftDomain || p.status == PathStatus::kNoConvergence) {
      throw Error("cannot follow the path at {}: {}", path_.Describe(*st),
                  DescribePathFailure(p.status, x));
    }
    *st = p.state;
    const InverseResult r = machine_.Inverse(p.pose, &near, q);
    if (r.status != InverseStatus::kOk) {
      throw Error("cannot follow the path at {}: {}", path_.Describe(p.state),
                  DescribeInverseFailure(machine_, r));
    }
  };
  PathState st = hint;
  pose_at(s, &st, &n.q, q_hint);
  n.state = st;
  // Central differences of exact positions, one-sided at the path's ends and breaks.
  const double d = 2e-3;
  AxisVector f[5];
  const bool left = side < 0 || (side == 0 && s + 2.0 * d > length);
  const bool right = !left && (side > 0 || s - 2.0 * d < 0.0);
  if (left || right) {
    const double sign = left ? -1.0 : 1.0;
    f[0] = n.q;
    PathState w = st;
    for (int k = 1; k < 5; ++k) pose_at(s + sign * k * d, &w, &f[k], n.q);
    n.d1 =
        sign * (-25.0 * f[0] + 48.0 * f[1] - 36.0 * f[2] + 16.0 * f[3] - 3.0 * f[4]) / (12.0 * d);
    n.d2 = (35.0 * f[0] - 104.0 * f[1] + 114.0 * f[2] - 56.0 * f[3] + 11.0 * f[4]) / (12.0 * d * d);
    n.d3 = sign * (-5.0 * f[0] + 18.0 * f[1] - 24.0 * f[2] + 14.0 * f[3] - 3.0 * f[4]) /
           (2.0 * d * d * d);
  } else {
    PathState w = st;
    pose_at(s - 2.0 * d, &w, &f[0], n.q);
    pose_at(s - d, &w, &f[1], n.q);
    f[2] = n.q;
    pose_at(s + d, &w, &f[3], n.q);
    pose_at(s + 2.0 * d, &w, &f[4], n.q);
    n.d1 = (f[0] - 8.0 * f[1] + 8.0 * f[3] - f[4]) / (12.0 * d);
    n.d2 = (-f[0] + 16.0 * f[1] - 30.0 * f[2] + 16.0 * f[3] - f[4]) / (12.0 * d * d);
    n.d3 = (-f[0] + 2.0 * f[1] - 2.0 * f[3] + f[4]) / (2.0 * d * d * d);
  }
  n.feed_cap = limits_.feed;
  // A slow point's feed (Eq. 8 over its corner: each axis alone, at constant feed) caps the node
  // only where the node does not see the corner itself, allowing at zero acceleration more than
  // kUnseenCorner times that feed (see there).
  std::optional<double> own;  // computed at the first slow point here, before any cap
  for (const SlowPoint& p : path_.SlowPoints()) {
    if (!(std::abs(p.s - s) <= 1e-9 * (1.0 + s))) continue;
    if (!own) own = Clip(n, 0.0, n.feed_cap);
    if (*own > kUnseenCorner * p.feed_mm_s) n.feed_cap = std::min(n.feed_cap, p.feed_mm_s);
  }
  double cap = limits_.tangential_acceleration, jerk = limits_.tangential_jerk;
  for (int i = 0; i < n_axes_; ++i) {
    const double g = std::abs(n.d1[i]);
    if (g > 1e-9) cap = std::min(cap, limits_.a[i] / g), jerk = std::min(jerk, limits_.j[i] / g);
  }
  n.acceleration_cap = std::isfinite(cap) ? cap : 1e6;
  n.jerk_cap = std::isfinite(jerk) ? jerk : 1e9;
  return n;
}

double ViableFeeds::Spacing(const Node& n, double end) const {
  // The feed to expect: the admissible feed at zero acceleration, and near the end of the grid
  // (where the motion comes to rest) the feed of a stop there, (J d^2)^(1/3).
  const double d = std::max(end - n.s, 0.0);
  const double v =
      std::max(std::min(Clip(n, 0.0, n.feed_cap), std::cbrt(n.jerk_cap * d * d)), 0.05);
  const double swing = n.acceleration_cap / n.jerk_cap;  // LookAheadOptions::swing_spacing_mm
  double h = std::min({options_.max_spacing_mm, options_.node_time_s * v,
                       std::max(options_.swing_spacing_mm, swing * v)});
  // Where the axes' directions change: q_ss and q_sss relative to q_s, each axis scaled by its
  // velocity limit so that linear and rotary axes weigh alike.
  double d1 = 0.0, d2 = 0.0, d3 = 0.0;
  for (int i = 0; i < n_axes_; ++i) {
    const double w = 1.0 / limits_.v[i];
    d1 += (n.d1[i] * w) * (n.d1[i] * w);
    d2 += (n.d2[i] * w) * (n.d2[i] * w);
    d3 += (n.d3[i] * w) * (n.d3[i] * w);
  }
  d1 = std::sqrt(d1), d2 = std::sqrt(d2), d3 = std::sqrt(d3);
  if (d2 > 0.0) h = std::min(h, 0.05 * d1 / d2);
  if (d3 > 0.0) h = std::min(h, 0.075 * std::sqrt(d1 / d3));
  // Where an axis turns while others set the tangential jerk (LookAheadOptions::axis_turn).
  for (int i = 0; i < n_axes_; ++i) {
    const double turn = std::abs(n.d2[i]) * n.jerk_cap;
    if (turn > 0.0) h = std::min(h, options_.axis_turn * limits_.j[i] / turn);
  }
  return std::max(h, options_.min_spacing_mm);
}

void ViableFeeds::Extend(double to) {
  // Forward: sample from the last node to `to`, on either side of every break and at every slow
  // point (where the node's feed cap holds the slow point's feed).
  const double old_end = nodes_.back().s;
  path_.Reach(to);
  if (!length_) length_ = path_.Length();
  if (length_) to = std::min(to, *length_);
  struct Mark {
    double s;
    bool is_break;
    bool law_entry = false;
  };
  std::vector<Mark> marks;
  for (const double b : path_.Breaks(old_end, to)) marks.push_back({b, true});
  for (const SlowPoint& p : path_.SlowPoints()) {
    if (p.s > old_end && p.s <= to) marks.push_back({p.s, false});
  }
  if (length_) {
    const double entry = *length_ - options_.law_zone_mm;
    if (entry > old_end && entry < to && entry > 0.0) marks.push_back({entry, false, true});
  }
  std::stable_sort(marks.begin(), marks.end(),
                   [](const Mark& x, const Mark& y) { return x.s < y.s; });
  auto next_mark = marks.begin();
  while (nodes_.back().s < to) {
    const Node& last = nodes_.back();
    while (next_mark != marks.end() && next_mark->s <= last.s + 1e-9) ++next_mark;
    const double limit = next_mark != marks.end() ? std::min(next_mark->s, to) : to;
    double step = Spacing(last, to);
    for (;;) {
      double s = last.s + step;
      if (s > limit - 0.3 * step) s = limit;
      const bool at_mark = next_mark != marks.end() && s == next_mark->s;
      const bool at_break = at_mark && next_mark->is_break;
      Node n = Sample(s, last.state, last.q, at_break ? -1 : 0);
      n.law_entry = at_mark && next_mark->law_entry;
      const double need = Spacing(n, to);
      if (need < 0.7 * (s - last.s) && step > options_.min_spacing_mm) {
        step = std::max(options_.min_spacing_mm, need);
        continue;
      }
      if (at_break) {
        // The piece after the break: same point, right-sided derivatives.
        Node right = Sample(s, n.state, n.q, 1);
        n.break_after = true;
        Append(std::move(n));
        Append(std::move(right));
      } else {
        Append(std::move(n));
      }
      break;
    }
  }
  // Backward: rest at the end of the window, then every boundary from the next one, back to a
  // quarter of a window before the old end (one and a half stops at the feed: what rest at the old
  // end held back lies nearer to it; a boundary left as it was is only the smaller set). Near the
  // end, every state from which the planner's own discrete stop law (motion_law.hpp) comes to rest
  // there with the least capacity the axes leave before it belongs to the viable set too: the
  // continuous boundary alone would brake a little earlier than that law lands.
  nodes_.back().boundary = TerminalBoundary(nodes_.back());
  nodes_.back().peak = PeakOf(nodes_.back().boundary);
  Recompute(nodes_.size() - 1, old_end, old_end - 0.25 * window_);
}

void ViableFeeds::Recompute(std::size_t from, double unchanged, double until) {
  // Node k's boundary depends only on its own limits and node k + 1's boundary: once a node
  // before `unchanged` comes out as it was, so do all before it. Before `until`, what changed
  // ahead reaches no further (or only as the slightly smaller viable set planned there before:
  // rest at an earlier end, a wider margin).
  const auto same = [](const std::vector<Point>& x, const std::vector<Point>& y) {
    if (x.size() != y.size()) return false;
    for (std::size_t i = 0; i < x.size(); ++i) {
      if (std::abs(x[i].a - y[i].a) > 1e-12 * (1.0 + std::abs(x[i].a)) ||
          std::abs(x[i].v - y[i].v) > 1e-12 * (1.0 + x[i].v)) {
        return false;
      }
    }
    return true;
  };
  std::vector<Point> before;
  for (std::size_t k = from; k-- > 0;) {
    before.swap(nodes_[k].boundary);
    Propagate(&nodes_[k], nodes_[k + 1]);
    if (nodes_[k].s < until) break;
    if (nodes_[k].s < unchanged && !before.empty() && same(before, nodes_[k].boundary)) break;
  }
}

std::vector<ViableFeeds::Point> ViableFeeds::TerminalBoundary(const Node& n) const {
  // Rest at the end of the grid, give or take the landing (LookAheadOptions::landing_mm): the
  // states that stop within it, the pure release (a = -J t, v = J t^2 / 2 over J t^3 / 6) and the
  // stop from zero acceleration (v = (J d^2)^(1/3)).
  const double j = n.jerk_cap, d = options_.landing_mm;
  const double t = std::cbrt(6.0 * d / j);
  return {{-j * t, 0.5 * j * t * t}, {0.0, std::cbrt(j * d * d)}};
}

void ViableFeeds::Repair(double s, double reach) {
  if (nodes_.size() < 2) return;
  std::size_t last = 0;
  bool any = false;
  for (std::size_t k = 0; k < nodes_.size(); ++k) {
    Node& n = nodes_[k];
    if (std::abs(n.s - s) > reach) continue;
    n.margin = std::max(kMinRepairMargin, n.margin * kRepairFactor);
    JerkBlock& b = BlockOf(n.id);
    b.margin = std::min(b.margin, n.margin);
    n.jerk_cap = std::min(n.jerk_cap, n.jerk_cap * kRepairFactor);
    n.acceleration_cap = std::min(n.acceleration_cap, n.acceleration_cap * kRepairFactor);
    last = k;
    any = true;
  }
  if (!any) return;
  // Recompute back over the stretch a stop from here can reach (the lowered boundary reaches no
  // further back).
  Recompute(std::min(last + 1, nodes_.size() - 1), s - reach, s - 4.0 * reach);
}

double ViableFeeds::JerkCap(double s) const {
  if (nodes_.empty()) return limits_.tangential_jerk;
  return NodeAt(s).jerk_cap;
}

bool ViableFeeds::AccelerationRange(double s, double v, double* lo, double* hi) const {
  if (nodes_.empty()) return false;
  const Node& n = NodeAt(s);
  const double m = n.margin;
  *lo = -limits_.tangential_acceleration * m;
  *hi = limits_.tangential_acceleration * m;
  for (int i = 0; i < n_axes_; ++i) {
    const double g = n.d1[i];
    if (std::abs(g) < 1e-12) continue;
    const double A = limits_.a[i] * m, c = n.d2[i] * v * v;
    double al = (-A - c) / g, ah = (A - c) / g;
    if (g < 0.0) std::swap(al, ah);
    *lo = std::max(*lo, al);
    *hi = std::min(*hi, ah);
  }
  return *lo <= *hi;
}

double ViableFeeds::MinJerkCap(double s0, double s1) const {
  double cap = std::min(limits_.tangential_jerk, JerkCap(s0));
  for (auto it = FirstAtOrAfter(s0); it != nodes_.end() && it->s <= s1; ++it) {
    cap = std::min(cap, it->jerk_cap);
  }
  return cap;
}

double ViableFeeds::MinAccelerationCap(double s0, double s1) const {
  double cap = limits_.tangential_acceleration;
  for (auto it = FirstAtOrAfter(s0); it != nodes_.end() && it->s <= s1; ++it) {
    cap = std::min(cap, it->acceleration_cap);
  }
  return cap;
}

std::deque<ViableFeeds::Node>::const_iterator ViableFeeds::After(double s) const {
  // The planner asks about arc lengths that mostly move forward by less than a grid stretch:
  // look at the node it asked about last and the next one before searching the whole grid (a
  // binary search over a deque was 6 % of the circle's planning).
  const std::size_t size = nodes_.size();
  for (std::size_t k = cursor_; k < size && k <= cursor_ + 1; ++k) {
    if (nodes_[k].s > s && (k == 0 || nodes_[k - 1].s <= s)) {
      cursor_ = k;
      return nodes_.begin() + static_cast<std::ptrdiff_t>(k);
    }
  }
  const auto it = std::upper_bound(nodes_.begin(), nodes_.end(), s,
                                   [](double x, const Node& n) { return x < n.s; });
  cursor_ = static_cast<std::size_t>(it - nodes_.begin());
  return it;
}

const ViableFeeds::Node& ViableFeeds::NodeAt(double s) const {
  const auto it = After(s);
  return it == nodes_.begin() ? *it : *(it - 1);
}

std::deque<ViableFeeds::Node>::const_iterator ViableFeeds::FirstAtOrAfter(double s) const {
  return std::lower_bound(nodes_.begin(), nodes_.end(), s,
                          [](const Node& n, double x) { return n.s < x; });
}

bool ViableFeeds::Admissible(double s, double v, double a) const {
  if (nodes_.empty()) return false;
  double lo, hi;
  return Admissible(NodeAt(s), v, a, &lo, &hi);
}

void ViableFeeds::JerkRange(double s, double v, double a, double* lo, double* hi) const {
  if (nodes_.empty()) {
    *lo = -limits_.tangential_jerk, *hi = limits_.tangential_jerk;
    return;
  }
  const Node& n = NodeAt(s);
  if (!JerkInterval(n, full_, n.margin, std::max(v, 0.0), a, lo, hi)) {
    *lo = -10.0 * n.jerk_cap;
    *hi = 10.0 * n.jerk_cap;
  }
}

void ViableFeeds::Advance(double s, const PathState& state, const AxisVector& q, double keep) {
  if (nodes_.empty()) {
    path_.Reach(s + window_);
    length_ = path_.Length();
    Node first = Sample(s, state, q, 1);
    Append(std::move(first));
    Extend(s + window_);
    return;
  }
  // Drop the grid behind where the planner may still step back to.
  while (nodes_.size() > 2 && nodes_[1].s <= keep) nodes_.pop_front(), cursor_ = 0;
  while (blocks_.front().first + kJerkBlock <= nodes_.front().id) blocks_.pop_front();
  const bool at_end = length_ && nodes_.back().s >= *length_;
  if (!at_end && nodes_.back().s < s + 0.5 * window_) Extend(s + kExtendWindows * window_);
}

}  // namespace dtis::interp
