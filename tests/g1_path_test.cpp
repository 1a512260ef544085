// G1 corner smoothing (3- and 5-axis) and G-code programs planned by VPOp: tolerances measured
// densely, C2 connections, the C2 orientation against the paper's three parametrizations,
// collinear blocks against the straight line, and a symmetric feed around a symmetric corner.
#include "dtis/geometry/g1_path.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <numbers>
#include <random>

#include "dtis/core/error.hpp"
#include "dtis/geometry/curve_path.hpp"
#include "dtis/geometry/path_fit.hpp"
#include "dtis/interp/verifier.hpp"
#include "dtis/interp/vpop.hpp"
#include "dtis/io/curve_file.hpp"
#include "dtis/io/gcode_program.hpp"
#include "dtis/io/job.hpp"
#include "dtis/io/setpoint_file.hpp"
#include "dtis/kinematics/machines.hpp"
#include "test_support.hpp"

namespace dtis {
namespace {

using test::Cartesian;

using Eigen::Vector3d;

// The largest distance of the smoothed tip from the programmed tip polyline, and of the tool
// axis (the line through the tip, near height h) from the programmed top polyline, sampled every
// `step` mm of the path.
std::pair<double, double> Deviation(const geometry::G1Path& path, const std::vector<Vector3d>& tips,
                                    const std::vector<Vector3d>& tops, double h, double step) {
  const auto to_polyline = [](const Vector3d& x, const std::vector<Vector3d>& line) {
    double d = INFINITY;
    for (std::size_t k = 0; k + 1 < line.size(); ++k) {
      d = std::min(d, geometry::DistanceToSegment(x, line[k], line[k + 1]));
    }
    return d;
  };
  double worst_tip = 0.0, worst_top = 0.0;
  int hint = 0;
  for (double s = 0.0; s <= *path.Length(); s += step) {
    const Pose pose = path.PoseAt(s, &hint);
    worst_tip = std::max(worst_tip, to_polyline(pose.tip, tips));
    if (h > 0.0) {
      // Golden-section search along the axis for the point nearest the top polyline.
      double a = 0.5 * h, b = 1.5 * h;
      const auto f = [&](double t) { return to_polyline(pose.tip + t * pose.axis, tops); };
      const double g = (std::sqrt(5.0) - 1.0) / 2.0;
      for (int k = 0; k < 80; ++k) {
        const double x1 = b - g * (b - a), x2 = a + g * (b - a);
        if (f(x1) <= f(x2)) {
          b = x2;
        } else {
          a = x1;
        }
      }
      worst_top = std::max(worst_top, f(0.5 * (a + b)));
    }
  }
  return {worst_tip, worst_top};
}

// The lock's contour, which starts after its plunge: the blocks after the first G1 at Z0, as moves
// from `start`.
struct LockContour {
  Vector3d start;
  std::vector<geometry::ChainMove> moves;
};
LockContour ReadLockContour() {
  const io::GcodeProgram program = io::ReadGcode(test::Source("samples/gcode/lock.ngc"));
  LockContour contour{program.moves[1].to, {}};
  for (std::size_t k = 2; k + 1 < program.moves.size(); ++k) {
    geometry::ChainMove m;
    m.tip = program.moves[k].to;
    m.line = program.moves[k].line;
    contour.moves.push_back(m);
  }
  return contour;
}

TEST(G1Path, LockCornersStayWithinTheContourToleranceAndUseIt) {
  const auto machine =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  const auto [start, moves] = ReadLockContour();
  std::vector<Vector3d> tips{start};
  for (const auto& m : moves) tips.push_back(m.tip);
  geometry::CornerOptions o;
  o.contour_tol_mm = 0.02;
  o.feed_mm_s = 50.0;
  const geometry::G1Path path(tips.front(), Vector3d::UnitZ(), moves, *machine, o);
  EXPECT_GT(path.Corners().size(), 50u);
  const auto [tip, top] = Deviation(path, tips, tips, 0.0, 1e-3);
  EXPECT_LE(tip, 0.02 * (1.0 + 1e-9));
  // Where the blocks are long enough, Eq. 3 uses the whole tolerance: the middle of the corner
  // curve is exactly eps from the corner point.
  int full = 0;
  for (const auto& c : path.Corners()) {
    int hint = 0;
    const Vector3d mid = path.PoseAt(0.5 * (c.s0 + c.s1), &hint).tip;
    double d = INFINITY;  // from the programmed corner point (Eq. 3 measures it so)
    for (const Vector3d& p : tips) d = std::min(d, (mid - p).norm());
    EXPECT_LE(d, 0.02 * (1.0 + 1e-9));
    EXPECT_LT(c.l1, c.l2);
    if (std::abs(d - 0.02) < 1e-9) ++full;
  }
  EXPECT_GT(full, 5);
}

// A G1 chain's breaks are where one piece meets the next: both ends of every smoothed corner.
TEST(G1Path, BreaksAreTheEndsOfTheBlocksAndCorners) {
  const auto machine =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  const auto [start, moves] = ReadLockContour();
  geometry::CornerOptions o;
  o.contour_tol_mm = 0.02;
  o.feed_mm_s = 50.0;
  const geometry::G1Path path(start, Vector3d::UnitZ(), moves, *machine, o);
  const std::vector<double> breaks = path.Breaks(0.0, path.Length().value());
  ASSERT_TRUE(std::is_sorted(breaks.begin(), breaks.end()));
  for (const auto& c : path.Corners()) {
    for (const double end : {c.s0, c.s1}) {
      if (end <= 0.0 || end >= path.Length().value()) continue;
      EXPECT_TRUE(std::binary_search(breaks.begin(), breaks.end(), end)) << end;
    }
  }
  // Between two breaks the pose is smooth: no break lies inside a corner.
  for (const auto& c : path.Corners()) {
    EXPECT_TRUE(path.Breaks(c.s0, c.s1 - 1e-9 * (1.0 + c.s1)).empty());
  }
}

// One-sided second differences of f at s, from the left and from the right.
template <typename F>
std::pair<Vector3d, Vector3d> SecondDerivatives(const F& f, double s, double h) {
  const Vector3d left = (f(s) - 2.0 * f(s - h) + f(s - 2.0 * h)) / (h * h);
  const Vector3d right = (f(s + 2.0 * h) - 2.0 * f(s + h) + f(s)) / (h * h);
  return {left, right};
}

TEST(G1Path, TipIsCurvatureContinuousAtEveryConnection) {
  const auto machine = Cartesian(500, 2500, 5000);
  std::vector<geometry::ChainMove> moves(3);
  moves[0].tip = {10, 0, 0};
  moves[1].tip = {12, 6, 0};
  moves[2].tip = {0, 9, 1};
  const geometry::G1Path path({0, 0, 0}, Vector3d::UnitZ(), moves, *machine);
  ASSERT_EQ(path.Corners().size(), 2u);
  const auto tip = [&path](double s) {
    int hint = 0;
    return path.PoseAt(s, &hint).tip;
  };
  for (const auto& c : path.Corners()) {
    double peak = 0.0;
    for (int k = 1; k < 100; ++k) {
      const double s = c.s0 + (c.s1 - c.s0) * k / 100.0;
      peak = std::max(peak, SecondDerivatives(tip, s, 1e-4).second.norm());
    }
    for (const double s : {c.s0, c.s1}) {
      const auto [left, right] = SecondDerivatives(tip, s, 1e-4 * (c.s1 - c.s0));
      // Zero curvature on both sides (the jump a tangent-continuous join would show is the peak).
      EXPECT_LT((left - right).norm(), 2e-3 * peak) << "at s = " << s;
    }
  }
}

// A 5-axis corner: the tool leans 15 degrees and the lean turns with the path.
struct FiveAxisCorner {
  std::unique_ptr<Machine> machine =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyzac.toml"));
  std::vector<geometry::ChainMove> moves;
  Vector3d start_axis;
  FiveAxisCorner() {
    const auto axis = [this](double a_deg, double c_deg) {
      AxisVector q = AxisVector::Zero(5);
      q[3] = a_deg * std::numbers::pi / 180.0;
      q[4] = c_deg * std::numbers::pi / 180.0;
      return machine->Forward(q).axis;
    };
    start_axis = axis(15, 0);
    moves.resize(2);
    moves[0].tip = {20, 0, 0};
    moves[0].axis = axis(20, 10);
    moves[1].tip = {25, 15, -2};
    moves[1].axis = axis(12, 60);
  }
  geometry::G1Path Path(geometry::TopParametrization top) const {
    geometry::CornerOptions o;
    o.top = top;
    o.feed_mm_s = 100.0;
    return geometry::G1Path({0, 0, 0}, start_axis, moves, *machine, o);
  }
};

TEST(G1Path, FiveAxisCornerKeepsBothTolerancesAndTheOrientationC2) {
  const FiveAxisCorner corner;
  const geometry::G1Path path = corner.Path(geometry::TopParametrization::kC2);
  ASSERT_EQ(path.Corners().size(), 1u);
  const geometry::CornerOptions o;
  const std::vector<Vector3d> tips{{0, 0, 0}, corner.moves[0].tip, corner.moves[1].tip};
  const std::vector<Vector3d> tops{tips[0] + o.top_height_mm * corner.start_axis,
                                   tips[1] + o.top_height_mm * corner.moves[0].axis,
                                   tips[2] + o.top_height_mm * corner.moves[1].axis};
  const auto [tip, top] = Deviation(path, tips, tops, o.top_height_mm, 1e-3);
  EXPECT_LE(tip, o.contour_tol_mm * (1.0 + 1e-9));
  EXPECT_LE(top, o.orientation_tol_mm * (1.0 + 1e-9));
  // On the straight parts the pose is the programmed linear interpolation of tip and top.
  int hint = 0;
  const Pose quarter = path.PoseAt(5.0, &hint);
  const Vector3d programmed_top = tops[0] + 0.25 * (tops[1] - tops[0]);
  EXPECT_LT((quarter.tip - (tips[0] + 0.25 * (tips[1] - tips[0]))).norm(), 1e-12);
  EXPECT_LT((quarter.axis - (programmed_top - quarter.tip).normalized()).norm(), 1e-12);
}

TEST(G1Path, C2OrientationHasNoJumpAndBeatsThePapersParametrizations) {
  const FiveAxisCorner corner;
  using T = geometry::TopParametrization;
  double feed_c2 = 0.0;
  for (const T top : {T::kC2, T::kBottomParameter, T::kUniform, T::kTopArcLength}) {
    const geometry::G1Path path = corner.Path(top);
    const auto& c = path.Corners().front();
    const auto axis = [&path](double s) {
      int hint = 0;
      return path.PoseAt(s, &hint).axis;
    };
    // One-sided second differences on either side of each connection: where the second
    // derivative is continuous their difference shrinks with the step (it is only the
    // differences' own O(h) error); where it jumps it stays.
    const auto jump = [&](double h) {
      double worst = 0.0;
      for (const double s : {c.s0, c.s1}) {
        const auto [left, right] = SecondDerivatives(axis, s, h);
        worst = std::max(worst, (left - right).norm());
      }
      return worst;
    };
    const double coarse = jump(1e-3), fine = jump(1e-4);
    const double span = c.s1 - c.s0;
    const double feed = geometry::ReachableFeed(path, *corner.machine, c.s0 - 0.2 * span,
                                                c.s1 + 0.2 * span, span / 400.0);
    if (top == T::kC2) {
      EXPECT_LT(fine, 0.2 * coarse);
      feed_c2 = feed;
    } else {
      EXPECT_GE(feed_c2, feed) << "parametrization " << static_cast<int>(top);
    }
    // The paper's parametrizations 1 and 2 leave a jump in the orientation's second derivative.
    if (top == T::kBottomParameter || top == T::kUniform) {
      EXPECT_GT(fine, 0.5 * coarse);
      EXPECT_GT(fine, 1e-2);
    }
  }
}

TEST(G1Path, CollinearBlocksPlanLikeTheStraightLine) {
  const auto machine = Cartesian(500, 2500, 5e6);  // a large jerk limit
  std::vector<geometry::ChainMove> moves;
  for (int k = 1; k <= 10; ++k) {
    geometry::ChainMove m;
    m.tip = {7.0 * k, 3.0 * k, 0.0};
    moves.push_back(m);
  }
  const geometry::G1Path chain({0, 0, 0}, Vector3d::UnitZ(), moves, *machine);
  EXPECT_TRUE(chain.Corners().empty());
  const geometry::LinePath line({0, 0, 0}, moves.back().tip, Vector3d::UnitZ());
  interp::VpopOptions o;
  o.feed_mm_s = 100.0;
  test::Collect a, b;
  const auto ta = interp::PlanVpop(chain, *machine, o, a).motion_time_s;
  const auto tb = interp::PlanVpop(line, *machine, o, b).motion_time_s;
  EXPECT_LE(std::abs(ta - tb), 2.0 * o.period_s);
}

// A wavy zigzag of `blocks` short G1 blocks: a corner at every vertex.
std::vector<geometry::ChainMove> Zigzag(int blocks) {
  std::vector<geometry::ChainMove> moves;
  for (int k = 1; k <= blocks; ++k) {
    geometry::ChainMove m;
    m.tip = {0.5 * k, 0.3 * (k % 2), 0.01 * std::sin(k)};
    m.line = k + 1;
    moves.push_back(m);
  }
  return moves;
}

// Corner arc-length maps are built when a corner is first evaluated and only the latest 256 are
// kept: on a path with many more corners, walking forwards, backwards and at random gives the
// same poses to the last bit, and every corner is as long as its map says.
TEST(G1Path, CornerMapsBuiltOnDemandGiveTheSamePosesInAnyOrder) {
  const auto machine = Cartesian(500, 2500, 5e4);
  const geometry::G1Path path({0, 0, 0}, Vector3d::UnitZ(), Zigzag(700), *machine);
  ASSERT_GT(path.Corners().size(), 600u);
  for (const auto& c : path.Corners()) {
    const double length = geometry::ArcLengthOf(*c.bottom).Length();
    EXPECT_EQ(geometry::ArcLengthOfCurve(*c.bottom), length);
    EXPECT_NEAR(c.s1 - c.s0, length, 1e-12);
  }
  std::vector<double> at;
  for (int k = 0; k <= 4000; ++k) at.push_back(*path.Length() * k / 4000.0);
  const auto poses = [&](const std::vector<double>& where) {
    std::map<double, Vector3d> tips;
    int hint = 0;
    for (const double s : where) tips[s] = path.PoseAt(s, &hint).tip;
    return tips;
  };
  const auto forward = poses(at);
  std::vector<double> order(at.rbegin(), at.rend());
  EXPECT_EQ(poses(order), forward);
  std::shuffle(order.begin(), order.end(), std::mt19937(7));
  EXPECT_EQ(poses(order), forward);
}

// A random walk of `blocks` G1 blocks, from 0.05 to 3 mm long, turning by up to 150 degrees: fine
// stretches where the slow points crowd (and are thinned), long ones where they stand alone.
std::vector<geometry::ChainMove> RandomWalk(int blocks, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<geometry::ChainMove> moves;
  Vector3d at(0, 0, 0);
  double heading = 0.0;
  for (int k = 0; k < blocks; ++k) {
    const bool fine = (k / 200) % 2 == 0;
    const double length = fine ? 0.05 + 0.3 * unit(rng) : 0.5 + 2.5 * unit(rng);
    heading += (unit(rng) - 0.5) * (fine ? 0.3 : 5.2);
    at += length * Vector3d(std::cos(heading), std::sin(heading), 0.02 * (unit(rng) - 0.5));
    geometry::ChainMove m;
    m.tip = at;
    m.line = k + 2;
    moves.push_back(m);
  }
  return moves;
}

// The same chain built whole and through a window: `first` moves given, the rest read one by one.
geometry::G1Path WindowedChain(const Vector3d& start_tip, const Vector3d& start_axis,
                               const std::vector<geometry::ChainMove>& moves,
                               const Machine& machine, const geometry::CornerOptions& o,
                               std::size_t first, bool five_axis, double keep_behind_mm = 200.0,
                               std::string behind_remedy = {}) {
  geometry::G1Path::Window w;
  w.behind_remedy = std::move(behind_remedy);
  w.first.assign(moves.begin(), moves.begin() + static_cast<std::ptrdiff_t>(first));
  w.more = [&moves, next = first]() mutable -> std::optional<geometry::ChainMove> {
    if (next == moves.size()) return std::nullopt;
    return moves[next++];
  };
  w.five_axis = five_axis;
  w.keep_behind_mm = keep_behind_mm;
  return geometry::G1Path(start_tip, start_axis, std::move(w), machine, o);
}

// Walks a windowed chain as a planner does (reach ahead, release behind) and compares every pose
// and every slow point with the chain built whole, bit for bit; then plans both with a short
// commit horizon (so that the planner releases as it goes) and compares the setpoints.
void ExpectWindowedIsWhole(const geometry::G1Path& whole, const geometry::G1Path& windowed) {
  ASSERT_FALSE(windowed.Length());  // not known before the chain is built to its end
  const double length = *whole.Length();
  std::vector<SlowPoint> slow;
  int hint_a = 0, hint_b = 0;
  std::size_t compared = 0;
  for (double s = 0.0; s < length + 1.0; s += 0.013) {
    windowed.Reach(s + 25.0);
    for (const SlowPoint& p : windowed.SlowPoints()) {
      if (p.s < s + 25.0 && (slow.empty() || p.s > slow.back().s)) slow.push_back(p);
    }
    const PathSample a = whole.At({.piece = hint_a}, s);
    const PathSample b = windowed.At({.piece = hint_b}, s);
    hint_a = a.state.piece, hint_b = b.state.piece;
    ASSERT_EQ(a.status, b.status) << "s = " << s;
    ASSERT_EQ(a.pose.tip, b.pose.tip) << "s = " << s;
    ASSERT_EQ(a.pose.axis, b.pose.axis) << "s = " << s;
    ++compared;
    windowed.Release(s - 5.0);
  }
  EXPECT_GT(compared, 1000u);
  ASSERT_TRUE(windowed.Length());
  EXPECT_EQ(*windowed.Length(), length);
  EXPECT_EQ(windowed.CornersBuilt(), whole.Corners().size());
  EXPECT_LT(windowed.Corners().size(), whole.Corners().size());  // it was dropped behind
  const auto all = whole.SlowPoints();
  ASSERT_EQ(slow.size(), all.size());
  for (std::size_t k = 0; k < slow.size(); ++k) {
    EXPECT_EQ(slow[k].s, all[k].s);
    EXPECT_EQ(slow[k].feed_mm_s, all[k].feed_mm_s);
  }
}

// `dropped`: the chain is long enough against its keep_behind_mm for the planner's releases to
// drop some of it (it drops in batches of more than 64 corners).
void ExpectSamePlan(const geometry::G1Path& whole, const geometry::G1Path& windowed,
                    const Machine& machine, double feed_mm_s, bool dropped) {
  interp::VpopOptions o;
  o.feed_mm_s = feed_mm_s;
  o.commit_horizon = 128;
  test::Collect a, b;
  const auto ra = interp::PlanVpop(whole, machine, o, a);
  const auto rb = interp::PlanVpop(windowed, machine, o, b);
  EXPECT_EQ(ra.motion_time_s, rb.motion_time_s);
  ASSERT_EQ(a.points.size(), b.points.size());
  for (std::size_t k = 0; k < a.points.size(); ++k) {
    ASSERT_EQ(a.points[k].q, b.points[k].q) << "setpoint " << k;
  }
  if (dropped) {
    EXPECT_LT(windowed.Corners().size(), windowed.CornersBuilt());
  }
}

TEST(G1Path, WindowedChainIsTheWholeChainBitForBit) {
  const auto machine = Cartesian(500, 2500, 5000);
  const auto moves = RandomWalk(1500, 11);
  geometry::CornerOptions o;
  o.feed_mm_s = 100.0;
  const geometry::G1Path whole({0, 0, 0}, Vector3d::UnitZ(), moves, *machine, o);
  ASSERT_GT(whole.Corners().size(), 1000u);
  // The thinning, against the rule computed here from the corners: taken slowest first (the
  // earlier corner at equal feed), a slow point stays unless a kept one is nearer than the
  // braking distance F sqrt(F / J).
  const double window = o.feed_mm_s * std::sqrt(o.feed_mm_s / 5000.0);
  std::vector<std::pair<double, double>> candidates;  // feed, s
  for (const auto& c : whole.Corners()) {
    if (c.reachable_feed_mm_s < o.feed_mm_s) {
      candidates.push_back({c.reachable_feed_mm_s, 0.5 * (c.s0 + c.s1)});
    }
  }
  std::stable_sort(candidates.begin(), candidates.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  std::map<double, double> kept;
  for (const auto& [feed, s] : candidates) {
    bool near = false;
    for (const auto& [t, f] : kept) near = near || std::abs(t - s) < window;
    if (!near) kept.emplace(s, feed);
  }
  ASSERT_EQ(whole.SlowPoints().size(), kept.size());
  EXPECT_LT(kept.size(), candidates.size() / 4);  // the fine stretches crowd
  std::size_t k = 0;
  for (const auto& [s, feed] : kept) {
    EXPECT_EQ(whole.SlowPoints()[k].s, s);
    EXPECT_EQ(whole.SlowPoints()[k].feed_mm_s, feed);
    ++k;
  }
  for (const std::size_t first : {std::size_t{1}, std::size_t{40}}) {
    SCOPED_TRACE(fmt::format("{} moves given first", first));
    const auto windowed =
        WindowedChain({0, 0, 0}, Vector3d::UnitZ(), moves, *machine, o, first, false);
    ExpectWindowedIsWhole(whole, windowed);
  }
  // Planned: a shorter chain, kept 30 mm behind the planner (more than its backward look-ahead
  // walks: some 18 mm to accelerate to F from rest, and the horizon).
  const auto some = RandomWalk(250, 12);
  const geometry::G1Path short_whole({0, 0, 0}, Vector3d::UnitZ(), some, *machine, o);
  const auto planned =
      WindowedChain({0, 0, 0}, Vector3d::UnitZ(), some, *machine, o, 10, false, 30.0);
  ExpectSamePlan(short_whole, planned, *machine, o.feed_mm_s, true);
}

TEST(G1Path, WindowedFiveAxisChainIsTheWholeChainBitForBit) {
  const FiveAxisCorner corner;
  const Machine& machine = *corner.machine;
  std::vector<geometry::ChainMove> moves;
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  double a = 15.0, c = 0.0, heading = 0.0;
  Vector3d at(0, 0, 0);
  for (int k = 0; k < 400; ++k) {
    heading += (unit(rng) - 0.5) * 1.2;
    at += (0.5 + 2.0 * unit(rng)) * Vector3d(std::cos(heading), std::sin(heading), 0.0);
    a = std::clamp(a + (unit(rng) - 0.5) * 1.0, 5.0, 25.0);
    c += (unit(rng) - 0.3) * 3.0;
    AxisVector q = AxisVector::Zero(5);
    q[3] = a * std::numbers::pi / 180.0;
    q[4] = c * std::numbers::pi / 180.0;
    geometry::ChainMove m;
    m.tip = at;
    m.axis = machine.Forward(q).axis;
    m.line = k + 2;
    moves.push_back(m);
  }
  geometry::CornerOptions o;
  o.feed_mm_s = 50.0;
  const geometry::G1Path whole({0, 0, 0}, corner.start_axis, moves, machine, o);
  ASSERT_TRUE(whole.FiveAxis());
  ASSERT_GT(whole.SlowPoints().size(), 10u);
  const auto windowed =
      WindowedChain({0, 0, 0}, corner.start_axis, moves, machine, o, 3, true, 20.0);
  ExpectWindowedIsWhole(whole, windowed);
  const std::vector<geometry::ChainMove> some(moves.begin(), moves.begin() + 40);
  const geometry::G1Path short_whole({0, 0, 0}, corner.start_axis, some, machine, o);
  const auto planned = WindowedChain({0, 0, 0}, corner.start_axis, some, machine, o, 3, true, 30.0);
  ExpectSamePlan(short_whole, planned, machine, o.feed_mm_s, false);
}

// A windowed chain drops what lies behind the planner; asking for it again is an error, not a
// wrong pose. Errors in the moves come when the chain is built that far, Check builds it all.
TEST(G1Path, WindowedChainSaysWhatItNoLongerHoldsAndChecksItsMoves) {
  const auto machine = Cartesian(500, 2500, 5000);
  const auto moves = RandomWalk(600, 3);
  geometry::CornerOptions o;
  o.feed_mm_s = 100.0;
  const auto windowed =
      WindowedChain({0, 0, 0}, Vector3d::UnitZ(), moves, *machine, o, 1, false, 10.0, "do this");
  windowed.Reach(200.0);
  windowed.Release(150.0);
  EXPECT_NO_THROW(windowed.At({}, 141.0));
  test::ExpectError([&] { windowed.At({}, 20.0); },
                    "arc length 20 mm lies behind the part of the chain still held");
  test::ExpectError([&] { windowed.At({}, 20.0); }, "than the chain keeps; do this");
  auto bad = moves;
  bad[450].tip = bad[448].tip;  // turns back at 449
  const auto checked =
      WindowedChain({0, 0, 0}, Vector3d::UnitZ(), bad, *machine, o, 1, false, 10.0);
  windowed.Check();
  EXPECT_EQ(*windowed.Length(),
            *geometry::G1Path({0, 0, 0}, Vector3d::UnitZ(), moves, *machine, o).Length());
  test::ExpectError([&] { checked.Check(); },
                    fmt::format("line {}: the path turns back on itself", bad[450].line));
}

// Corners are built in parallel; the error is the first bad corner in program order.
TEST(G1Path, FirstBadCornerInProgramOrderIsReported) {
  const auto machine = Cartesian(500, 2500, 5e4);
  auto moves = Zigzag(3000);
  for (const int k : {2900, 1200}) moves[k].tip = moves[k - 2].tip;  // turn back at k - 1
  test::ExpectError(
      [&] {
        geometry::G1Path({0, 0, 0}, Vector3d::UnitZ(), moves, *machine);
      },
      fmt::format("line {}: the path turns back on itself", moves[1200].line));
}

TEST(G1Path, FeedIsSymmetricAroundASymmetricCorner) {
  const auto machine =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  std::vector<geometry::ChainMove> moves(2);
  moves[0].tip = {30, 0, 0};
  moves[1].tip = {30, 30, 0};
  geometry::CornerOptions co;
  co.feed_mm_s = 50.0;
  const geometry::G1Path path({0, 0, 0}, Vector3d::UnitZ(), moves, *machine, co);
  ASSERT_EQ(path.SlowPoints().size(), 1u);
  interp::VpopOptions o;
  o.planner = interp::PlannerKind::kVpop;  // the paper's slow-point law (Eq. 8)
  o.feed_mm_s = 50.0;
  test::Collect sink;
  const auto summary = interp::PlanVpop(path, *machine, o, sink);
  io::TableSink table(*machine, o.period_s);
  for (const auto& s : sink.points) table.Accept(s);
  EXPECT_LE(interp::Verify(table.Table(), *machine).worst_ratio, 1.0);
  // Feed against arc length (each period's feed at the middle of its step), compared at equal
  // distances before and after the middle of the corner.
  std::vector<std::pair<double, double>> feed;
  for (std::size_t k = 1; k < sink.points.size(); ++k) {
    const double a = sink.points[k - 1].s, b = sink.points[k].s;
    if (b > a) feed.push_back({0.5 * (a + b), (b - a) / o.period_s});
  }
  const auto feed_at = [&feed](double s) {
    const auto hi = std::upper_bound(feed.begin(), feed.end(), s,
                                     [](double x, const auto& p) { return x < p.first; });
    const auto lo = hi - 1;
    return lo->second + (s - lo->first) / (hi->first - lo->first) * (hi->second - lo->second);
  };
  const SlowPoint slow = path.SlowPoints()[0];
  EXPECT_NEAR(feed_at(slow.s), slow.feed_mm_s, 0.05 * slow.feed_mm_s);
  double worst = 0.0;
  for (double d = 0.0; d < 20.0; d += 0.01) {
    worst = std::max(worst, std::abs(feed_at(slow.s - d) - feed_at(slow.s + d)));
  }
  EXPECT_LT(worst, 0.01 * o.feed_mm_s) << "back-offs " << summary.back_offs;
}

TEST(GcodeProgram, SamplesPlanWithinEveryLimit) {
  for (const char* name : {"samples/jobs/lock.toml", "samples/jobs/five_axis_g1.toml"}) {
    const io::Job job = io::LoadJob(test::Source(name));
    const io::RunResult r = io::RunJob(job);
    EXPECT_LE(r.verify.worst_ratio, 1.0) << name;
    EXPECT_GT(r.corners, 20) << name;
    EXPECT_GT(r.verify.motion_time_s, 0.0) << name;
  }
}

// A link of a plane_cl G1 export (retract, traverse, plunge through a 0.44 mm block) at a feed
// above any single axis' velocity: the planner used to stop at rest in the corner before the
// plunge and find no step forward (its linear model of q(s), taken 2 um ahead in a corner of
// 0.03 mm radius, left no s for X and Y at once), and failed with "no step forward respects the
// axis limits even from rest".
TEST(GcodeProgram, TightCornerAboveAxisVelocityDoesNotGetStuck) {
  const auto machine =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  const io::GcodeProgram p = io::ParseGcode(
      "G21 G90\nG0 X-10.099248 Y-5.288789 Z5.726022\n"
      "G1 Z10.726022 F40000\nG1 Z11.546276\nG1 X-8.148618 Y-8.669506\nG1 Z11.107334\n"
      "G1 Z6.107334\n",
      "link.ngc");
  interp::VpopOptions o;
  io::GcodeOptions go;
  go.from = {-10.099248, -5.288789, 5.726022};  // the machine is where the G0 goes
  const io::GcodePlan plan = io::BuildGcodePlan(p, *machine, o, go);
  const interp::ProgramResult r = interp::PlanProgram(plan.segments, *machine, {});
  io::TableSink sink(*machine, o.period_s);
  for (const auto& sp : r.setpoints) sink.Accept(sp);
  const auto report = interp::Verify(sink.Table(), *machine);
  EXPECT_TRUE(report.Passed()) << report.worst;
  EXPECT_NEAR(r.setpoints.back().s, *plan.paths.front()->Length(), 1e-9);
}

// Segments join when the next starts within a hair (1e-9 relative) of where the previous one
// stopped, as a path that ends at rest within its end tolerance does. The next segment's first
// step from rest is a whole jerk limit's worth; measured from its own start instead of where the
// machine stopped, it carried the hair too, over dt^3 (here 200 mm/s^3 on 5 000 mm/s^3).
TEST(GcodeProgram, ASegmentStartingAHairAwayKeepsEveryLimit) {
  const auto machine = Cartesian(500, 2500, 5000);
  const Eigen::Vector3d z(0, 0, 1);
  const double hair = 2e-7;  // below 1e-9 (1 + 310 mm)
  const geometry::LinePath first({300, 0, 0}, {310, 0, 0}, z);
  const geometry::LinePath second({310 + hair, 0, 0}, {320, 0, 0}, z);
  interp::VpopOptions o;
  o.feed_mm_s = 50.0;
  for (const auto planner : {interp::PlannerKind::kVpop, interp::PlannerKind::kLookAhead}) {
    o.planner = planner;
    const interp::ProgramResult r =
        interp::PlanProgram({{&first, o, "first"}, {&second, o, "second"}}, *machine);
    io::TableSink sink(*machine, o.period_s);
    for (const auto& sp : r.setpoints) sink.Accept(sp);
    const auto report = interp::Verify(sink.Table(), *machine);
    EXPECT_TRUE(report.Passed()) << interp::PlannerName(planner) << ": " << report.worst;
    EXPECT_NEAR(r.setpoints.back().q[0], 320.0, 1e-9);
  }
}

// Blended (the default), a retract-traverse-plunge link is one chain: the machine does not stop at
// the G0 vertices, and the smoothed corners stay within the contour tolerance. With blend_rapids
// off, three straight moves, each from rest to rest.
// A 10 ms period on 0.2 mm blocks: the first step from rest at the jerk limit is 0.5 mm, and a
// tight corner lay 0.8 mm ahead; that step could not be carried on through the corner and the
// planner came back to the same rest again and again ("no step forward ... even from rest").
// The step from a rest it came back to is halved until the motion gets through.
TEST(GcodeProgram, LongPeriodBeforeATightCornerDoesNotGetStuck) {
  const auto machine = Cartesian(1000, 20000, 5e5);
  std::string text = "G21 G90\nG0 X0 Y0 Z0\nG1 X0.2 F6000\n";
  for (int k = 2; k <= 40; ++k) {
    const int row = k / 10, i = k % 10;
    text += fmt::format("G1 X{:.1f} Y{:.1f}\n", (row % 2 == 0 ? i : 10 - i) * 0.2, row * 0.5);
  }
  const io::GcodeProgram p = io::ParseGcode(text, "raster.ngc");
  interp::VpopOptions o;
  o.period_s = 0.01;
  const io::GcodePlan plan = io::BuildGcodePlan(p, *machine, o, {});
  ASSERT_EQ(plan.segments.size(), 1u);
  test::Collect sink;
  interp::VpopOptions po = plan.segments[0].options;
  const auto r = interp::PlanVpop(*plan.paths[0], *machine, po, sink);
  io::TableSink table(*machine, o.period_s);
  for (const auto& sp : sink.points) table.Accept(sp);
  const auto report = interp::Verify(table.Table(), *machine);
  EXPECT_TRUE(report.Passed()) << report.worst;
  EXPECT_NEAR(r.end_s, *plan.paths[0]->Length(), 1e-9);
}

TEST(GcodeProgram, BlendedRapidsDoNotStopAtTheirVertices) {
  const auto machine = Cartesian(500, 5000, 5e6);
  const io::GcodeProgram p =
      io::ParseGcode("G0 X0 Y0 Z0\nG0 Z10\nG0 X40 Y30\nG0 Z0\nG1 X50 F3000\n", "link.ngc");
  interp::VpopOptions o;
  io::GcodeOptions go;
  go.blend_rapids = false;
  const io::GcodePlan stops = io::BuildGcodePlan(p, *machine, o, go);
  EXPECT_EQ(stops.segments.size(), 4u);
  EXPECT_EQ(stops.rapids, 3);
  go.blend_rapids = true;
  const io::GcodePlan blended = io::BuildGcodePlan(p, *machine, o, go);
  ASSERT_EQ(blended.segments.size(), 2u);
  EXPECT_EQ(blended.rapids, 3);
  EXPECT_EQ(blended.rapid, (std::vector<bool>{true, false}));
  EXPECT_EQ(blended.chains, 1);
  const auto& chain = dynamic_cast<const geometry::G1Path&>(*blended.paths[0]);
  ASSERT_EQ(chain.Corners().size(), 2u);
  const auto [tip_dev, top_dev] =
      Deviation(chain, {{0, 0, 0}, {0, 0, 10}, {40, 30, 10}, {40, 30, 0}}, {}, 0.0, 1e-3);
  EXPECT_LE(tip_dev, go.corners.contour_tol_mm * (1 + 1e-9));
  (void)top_dev;
  const interp::ProgramResult r = interp::PlanProgram(blended.segments, *machine, {});
  io::TableSink sink(*machine, o.period_s);
  for (const auto& sp : r.setpoints) sink.Accept(sp);
  EXPECT_TRUE(interp::Verify(sink.Table(), *machine).Passed());
  // The feed in the rapid chain (the first segment), a millimetre away from its ends.
  double slowest = INFINITY;
  const double length = *chain.Length();
  for (long k = 1; k < r.first_row[1]; ++k) {
    const auto& a = r.setpoints[static_cast<std::size_t>(k - 1)];
    const auto& b = r.setpoints[static_cast<std::size_t>(k)];
    if (a.s > 1.0 && b.s < length - 1.0) slowest = std::min(slowest, (b.s - a.s) / o.period_s);
  }
  EXPECT_GT(slowest, 1.0) << "mm/s: the machine stopped at a G0 vertex";
  const interp::ProgramResult stopping = interp::PlanProgram(stops.segments, *machine, {});
  EXPECT_LT(r.total.motion_time_s, stopping.total.motion_time_s);
}

// A surface job's link is one path through its waypoints, within the contour tolerance of them, and
// is planned without a stop at them; a link that turns back (the next pass right below) is split
// there.
TEST(LinkMoves, OnePathThroughTheWaypointsSplitWhereItTurnsBack) {
  const auto machine = Cartesian(500, 5000, 5e6);
  geometry::CornerOptions corners;
  corners.feed_mm_s = 500;
  const Pose from{{0, 0, 0}, Vector3d::UnitZ()}, to{{30, 20, -2}, Vector3d::UnitZ()};
  const auto moves = geometry::LinkMoves(from, to, 10.0, 5.0, *machine, corners);
  ASSERT_EQ(moves.size(), 1u);
  const auto& link = dynamic_cast<const geometry::G1Path&>(*moves[0]);
  std::vector<Vector3d> waypoints;
  for (const Pose& p : geometry::LinkWaypoints(from, to, 10.0, 5.0)) waypoints.push_back(p.tip);
  EXPECT_EQ(waypoints.size(), 6u);
  EXPECT_EQ(link.Corners().size(), 2u);  // retract and rise, descent and approach: collinear
  EXPECT_LE(Deviation(link, waypoints, {}, 0.0, 1e-3).first, corners.contour_tol_mm * (1 + 1e-9));
  interp::VpopOptions o;
  o.feed_mm_s = 500;
  test::Collect sink;
  interp::PlanVpop(link, *machine, o, sink);
  for (std::size_t k = 1; k + 1 < sink.points.size(); ++k) {
    if (sink.points[k].s > 1.0 && sink.points[k].s < *link.Length() - 1.0) {
      ASSERT_GT(sink.points[k + 1].s - sink.points[k].s, 1e-3 * o.period_s)
          << "stopped at s " << sink.points[k].s;
    }
  }
  // Straight down onto the next pass: up, then down the same line.
  const auto back =
      geometry::LinkMoves(from, {{0, 0, -1}, Vector3d::UnitZ()}, 10.0, 5.0, *machine, corners);
  EXPECT_EQ(back.size(), 2u);
}

TEST(GcodeProgram, BadProgramsNameTheLine) {
  const auto machine = Cartesian(500, 2500, 5000);
  interp::VpopOptions o;
  o.feed_mm_s = 1.0;
  const auto error = [&machine, &o](const std::string& text) {
    try {
      const io::GcodeProgram p = io::ParseGcode(text, "p.ngc");
      io::BuildGcodePlan(p, *machine, o, {});
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_EQ(error("G0 X0 Y0\nG1 X10 F600 A5\n"),
            "p.ngc: the program moves rotary axis A but machine 'test' has none");
  EXPECT_EQ(error("G0 X0 Y0\n"),
            "p.ngc: the program never moves from where it starts (0, 0, 0 mm)");
}

// A program starts where the machine is and its first move is planned, as LinuxCNC runs it: the
// zigzag sample's first block cuts 5.2 mm from the origin (its [path] from), then 13 strokes of
// 5 x 5 mm follow: 97.12 mm of polyline, a little less with the corners smoothed within 0.01 mm.
// Taken as the start instead, the first cut was lost (91.92 mm).
TEST(GcodeProgram, TheZigzagKeepsItsFirstCut) {
  const io::Job job = io::LoadJob(test::Source("samples/jobs/zigzag.toml"));
  const io::RunResult r = io::RunJob(job);
  const double polyline = 5.2 + 13.0 * std::sqrt(50.0);
  EXPECT_LT(r.path_length_mm, polyline);
  EXPECT_GT(r.path_length_mm, polyline - 0.2);
  EXPECT_TRUE(r.verify.Passed()) << r.verify.worst;
  for (std::size_t i = 0; i < r.table.axes.size(); ++i) {
    EXPECT_EQ(r.table.columns[i].front(), 0.0) << r.table.axes[i];  // at the origin
  }
  EXPECT_NEAR(r.table.columns[0].back(), 5.2 + 13 * 5.0, 1e-3);
  // From elsewhere, the same cut is planned from there.
  io::Job moved = job;
  moved.path.gcode.from = {-10, 0, 0};
  EXPECT_NEAR(io::RunJob(moved).path_length_mm, r.path_length_mm + 10.0, 1e-6);
}

TEST(GcodeProgram, SegmentsAreBuiltOneChainAtATime) {
  // Three chains (the feed changes twice) read by GcodeSegments: each segment is built from the
  // moves up to the one that ends its chain, no further, and the segments are BuildGcodePlan's.
  const auto machine = Cartesian(500, 2500, 5000);
  interp::VpopOptions o;
  o.feed_mm_s = 1.0;
  const io::GcodeProgram p = io::ParseGcode(
      "G0 X0 Y0\nG1 X10 F600\nY10\nX0\nG1 Y20 F300\nX10\nG1 Y30 F600\nX20\nM2\n", "p.ngc");
  std::size_t read = 0;
  io::GcodeSegments segments(
      [&]() -> std::optional<io::GcodeMove> {
        if (read == p.moves.size()) return std::nullopt;
        return p.moves[read++];
      },
      p.file, p.uses_rotary, *machine, o, {});
  const io::GcodePlan plan = io::BuildGcodePlan(p, *machine, o, {});
  ASSERT_EQ(plan.segments.size(), 3u);
  const std::size_t moves_read_by_then[] = {5, 7, 8};  // the first move of the next chain, or all
  for (std::size_t k = 0; k < 3; ++k) {
    const std::optional<io::GcodeSegment> s = segments.Next();
    ASSERT_TRUE(s);
    EXPECT_EQ(read, moves_read_by_then[k]);
    EXPECT_EQ(s->name, plan.segments[k].name);
    EXPECT_EQ(s->options.feed_mm_s, plan.segments[k].options.feed_mm_s);
    EXPECT_EQ(*s->path->Length(), *plan.segments[k].path->Length());
  }
  EXPECT_FALSE(segments.Next());
}

// With window_blocks, a long chain comes out as soon as it is longer than that, and reads the rest
// of its moves as it is built; the segments after it are BuildGcodePlan's. The lock sample: its
// contour is one chain of 54 blocks.
TEST(GcodeProgram, LongChainsAreReadAsTheyAreBuilt) {
  const auto machine =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  const io::GcodeProgram p = io::ReadGcode(test::Source("samples/gcode/lock.ngc"));
  interp::VpopOptions o;
  o.feed_mm_s = 1.0;
  io::GcodeOptions go;
  go.window_blocks = 8;
  const io::GcodePlan plan = io::BuildGcodePlan(p, *machine, o, go);
  std::size_t read = 0;
  const auto source = [&]() -> std::optional<io::GcodeMove> {
    if (read == p.moves.size()) return std::nullopt;
    return p.moves[read++];
  };
  io::GcodeSegments scan(source, p.file, p.uses_rotary, *machine, o, go);
  scan.ScanOnly();
  std::vector<bool> five_axis;
  std::size_t windowed = 0;
  while (const auto s = scan.Next()) {
    EXPECT_FALSE(s->path);
    if (s->windowed) five_axis.push_back(s->five_axis);
  }
  ASSERT_GE(five_axis.size(), 1u);
  read = 0;
  io::GcodeSegments segments(source, p.file, p.uses_rotary, *machine, o, go);
  segments.SetWindowedFiveAxis(five_axis);
  for (std::size_t k = 0; k < plan.segments.size(); ++k) {
    SCOPED_TRACE(plan.segments[k].name);
    const std::size_t before = read;
    const std::optional<io::GcodeSegment> s = segments.Next();
    ASSERT_TRUE(s);
    const auto& whole = *plan.segments[k].path;
    if (!s->windowed) {
      EXPECT_EQ(s->name, plan.segments[k].name);
      EXPECT_EQ(*s->path->Length(), *whole.Length());
      continue;
    }
    ++windowed;
    EXPECT_LE(read - before, 10u);  // the window's 9 moves (and a repeated point or so)
    EXPECT_FALSE(s->path->Length());
    // Walked as a planner does, it is the whole chain.
    int hint_a = 0, hint_b = 0;
    for (double at = 0.0; at < *whole.Length(); at += 0.05) {
      s->path->Reach(at + 10.0);
      const PathSample a = whole.At({.piece = hint_a}, at), b = s->path->At({.piece = hint_b}, at);
      hint_a = a.state.piece, hint_b = b.state.piece;
      ASSERT_EQ(a.pose.tip, b.pose.tip) << at;
    }
    s->path->Reach(*whole.Length() + 1.0);
    EXPECT_EQ(*s->path->Length(), *whole.Length());
  }
  EXPECT_EQ(windowed, five_axis.size());
  EXPECT_FALSE(segments.Next());
}

// The PathSource contract on every curve-like source (test::ExpectRoundingStepsHold).
TEST(PathSource, AnArcLengthARoundingErrorFromAKnownStateIsThatState) {
  const io::CurveFile trident = io::LoadCurveFile(test::Source("samples/curves/trident.toml"));
  test::ExpectRoundingStepsHold(geometry::CurvePath(trident.bottom, Vector3d::UnitZ()), "trident");
  const io::CurveFile pocket = io::LoadCurveFile(test::Source("samples/curves/open_pocket.toml"));
  ASSERT_TRUE(pocket.top);
  test::ExpectRoundingStepsHold(geometry::CurvePath(pocket.bottom, *pocket.top),
                                "open pocket pair");
  test::ExpectRoundingStepsHold(geometry::LinePath({0, 0, 0}, {100, 20, -3}, Vector3d::UnitZ()),
                                "line");
  const auto machine =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  const auto [start, moves] = ReadLockContour();
  test::ExpectRoundingStepsHold(geometry::G1Path(start, Vector3d::UnitZ(), moves, *machine),
                                "lock G1 chain");
}

// A program's least time (each move's chord at its F, rapids at the rapid feed, dwells) is summed
// as it is read, and the block at which it passes a day is an error naming it and what it takes.
TEST(GcodePlan, TheLeastTimeOfAProgramIsBoundedNamingTheBlock) {
  const auto machine =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  interp::VpopOptions base;
  base.feed_mm_s = 1.0;
  io::GcodeOptions options;
  const io::GcodeProgram ok = io::ParseGcode("G0 X0 Y0\nG1 X10 F600\nG0 X20\nM2\n", "p.ngc");
  const io::GcodePlan plan = io::BuildGcodePlan(ok, *machine, base, options);
  // 10 mm at 10 mm/s, then 10 mm at the machine's rapid feed (sqrt(3) x 500 mm/s).
  EXPECT_NEAR(plan.least_time_s, 1.0 + 10.0 / (std::sqrt(3.0) * 500.0), 1e-12);
  test::ExpectError(
      [&] {
        io::BuildGcodePlan(io::ParseGcode("G0 X0 Y0\nG1 X10 F600\nG1 X15 F0.0001\nM2\n", "p.ngc"),
                           *machine, base, options);
      },
      "p.ngc:3: the program takes at least 833 h up to this block, more than the 24 h a job may "
      "take; this block alone takes 833 h: its move of 5 mm at F0.0001 mm/min");
  io::GcodeOptions crawl = options;
  crawl.rapid_feed_mm_s = 1e-9 / 60.0;
  test::ExpectError([&] { io::BuildGcodePlan(ok, *machine, base, crawl); },
                    "p.ngc:3: the program takes at least 1.67e+08 h");
}

}  // namespace
}  // namespace dtis
