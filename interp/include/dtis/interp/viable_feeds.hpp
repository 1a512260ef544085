// The look-ahead of the look-ahead planner: the feeds from which the path ahead can still be
// followed within every limit, computed on an arc-length grid ahead of the exact step.
//
// Ahead of the planner, exact poses on an arc-length grid are mapped through the machine, and each
// grid point keeps the axis derivatives q_s, q_ss, q_sss (central differences of exact axis
// positions; one-sided on either side of a point where the path's derivatives jump). Along the
// path, with tangential feed v, acceleration a and jerk j, axis i moves with
//   velocity q_s v,  acceleration q_ss v^2 + q_s a,  jerk q_sss v^3 + 3 q_ss v a + q_s j,
// so a state (v, a) at arc length s is admissible when every axis velocity and acceleration is
// within its limit and the jerk intervals of the axes (each an interval of j) intersect.
//
// A single feed v(s) cannot say whether a state can still be brought through what lies ahead:
// that depends on the acceleration too (at 80 mm/s, braking at 600 mm/s^2 reaches a corner in
// time where accelerating at 200 mm/s^2 does not). The profile is therefore the viable set itself,
// the states (v, a) at each grid point from which a motion within every limit exists to rest at
// the end of the window, stored as its upper boundary v_max(a). It is computed by a backward pass
// (reachability, as in TOPP-RA, one order higher): between two grid points the tangential jerk is
// held constant, so a boundary point of the next grid point flows back along the extreme jerk
// that keeps it viable (the characteristics of the boundary), points that would leave the
// admissible set are clipped to it, and a point between two others is found by flowing back an
// interpolated point. Points are moved, not resampled, so the boundary does not diffuse along the
// hundreds of grid points of a stretch.
//
// The exact step (vpop.hpp) then takes the largest next arc length whose exact axis positions lie
// in every constraint interval and whose state stays inside this boundary. The boundary is a
// continuous-time model planned at a fraction of every limit; the exact step holds the limits.
#pragma once

#include <cstdint>
#include <deque>
#include <optional>
#include <vector>

#include "dtis/core/machine.hpp"
#include "dtis/core/path_source.hpp"

namespace dtis::interp {

struct LookAheadOptions {
  // The look-ahead plans against these fractions of the axes' velocity, acceleration and jerk
  // limits, so that the exact step, at 100 %, has room for the difference between the continuous
  // model and the sampled motion. The room each order needs was measured, not derived: a
  // velocity is a first difference of the sampled positions and follows the model closely, and
  // where an axis velocity decides the feed for long stretches (the rotary axes of the
  // table-tilting pass) each 0.1 % of room costs 0.1 % of motion time. With 0.5 % of acceleration
  // room the exact step refuses the profile thousands of times on open_pocket_xyzac and backs
  // off hundreds (2.756 s instead of 2.676); 0.5 % of jerk room instead of 1 % takes the circle
  // at 300 mm/s from 1.872 to 1.868 s (the paper's planner: 1.862).
  double velocity_fraction = 0.999;
  double acceleration_fraction = 0.99;
  double jerk_fraction = 0.995;
  // Grid spacing in time at the feed the boundary allows: a constant jerk is held this long.
  double node_time_s = 4e-3;
  // Grid spacing bounds, mm. Where the path bends, the spacing also shrinks so that q_ss and
  // q_sss change little between two grid points.
  double max_spacing_mm = 5.0;
  // A stretch between grid points holds one tangential jerk, so it must be short against the
  // time the axes take to swing their acceleration (the acceleration cap over the jerk cap): where
  // that is shorter than node_time_s (a jerk limit far above the acceleration's, as on rapids
  // with stiff axes), the spacing is what the swing covers, but at least this. It used to cap
  // the spacing everywhere, and above 125 mm/s it spaced the grid closer than node_time_s: the
  // NURBS circle at 300 mm/s had a grid point every 1.7 ms of motion and planned with 44 % more
  // instructions (705 grid points instead of 380) for a motion 2 ms shorter (1.868 s, now
  // 1.870 s).
  double swing_spacing_mm = 0.5;
  double min_spacing_mm = 1e-3;
  // A grid point checks each axis' jerk with that axis' q_s there, and a tangential jerk up to
  // the largest the axes allow there (its jerk cap, which the axis the path moves most sets).
  // Over a stretch h the axis' q_s moves by |q_ss| h, and its jerk with it by up to |q_ss| h
  // times that cap: the spacing keeps this within this fraction of the axis' own jerk limit. It
  // binds where an axis turns while another sets the tangential jerk: an axis reversing, or X and
  // Y curving on a path mostly along Z, whose jerk limit is ten times theirs on the Mikron. There,
  // grid points 0.2 mm apart held states the exact step then refused period after period.
  // Measured against no such bound (bench/spread.py, medians over 8 draws): the leading-line job
  // -0.30 %, plane_cl -0.16 %, five_axis_g1 -0.07 %, fine_wave +0.07 % (within its spread), the
  // other samples byte-identical; 0.1 gained less.
  double axis_turn = 0.2;
  // Acceleration resolution of the boundary, as a fraction of the largest tangential acceleration
  // the axes allow at the grid point.
  double boundary_resolution = 0.1;
  // The look-ahead ends with the states that come to rest within this distance past the end of
  // its grid, mm: there the exact step's own stop law (motion_law.hpp) lands the motion at rest,
  // and a continuous boundary ending exactly at rest would disagree with it by a hair and stop the
  // motion short of the end.
  double landing_mm = 0.01;
  // Over the last this many mm of the path the exact step follows its discrete stop law
  // (motion_law.hpp) to rest wherever the law binds, not the profile. The grid has a point where
  // that stretch begins, and its boundary keeps only the states from which the law lands: where
  // the path turns, the profile may count on jerk the curvature terms give the axes, which the
  // law, planned with the axes' jerk limits over |q_s|, does not have.
  double law_zone_mm = 0.05;
};

// Limits along the path (mm, s) and of each axis (mm or rad, s), as the exact step plans them.
struct LookAheadLimits {
  double feed = 0.0, tangential_acceleration = 0.0, tangential_jerk = 0.0;
  double v[kMaxAxes] = {}, a[kMaxAxes] = {}, j[kMaxAxes] = {};
};

class ViableFeeds {
 public:
  ViableFeeds(const PathSource& path, const Machine& machine, const LookAheadLimits& limits,
              const LookAheadOptions& options);

  // The planner is at arc length `s` (state `state`, axis positions `q`): the grid covers the
  // path from there to at least a window ahead, or to the end of the path. Throws dtis::Error
  // when the path cannot be followed there (the path source fails, an axis leaves its travel).
  // The grid behind `keep` is dropped (the planner will not step back before it).
  void Advance(double s, const PathState& state, const AxisVector& q, double keep);

  // How far the state (v, a) at arc length s lies inside the viable set, as a feed (mm/s):
  // >= 0 inside. v and a are the continuous-time feed and acceleration at s.
  double Slack(double s, double v, double a) const;

  // Whether the state (v, a) at arc length s is admissible: every axis velocity and acceleration
  // within its limit and the axes' jerk intervals intersecting (the grid point at or before s).
  bool Admissible(double s, double v, double a) const;

  // The tangential jerks the axes allow at arc length s in the state (v, a), at their full jerk
  // limits (the exact step's), or wide when their intervals do not meet.
  void JerkRange(double s, double v, double a, double* lo, double* hi) const;

  // The largest tangential jerk the axes allow at arc length s (their limits over |q_s|), and the
  // least of it, and of the tangential acceleration they allow, over [s0, s1] on the grid.
  double JerkCap(double s) const;
  double MinJerkCap(double s0, double s1) const;
  // The tangential accelerations [lo, hi] the axes allow at feed v at the grid point whose
  // stretch holds s (as planned: the look-ahead's fractions and any repair's margin there); false
  // where there are none.
  bool AccelerationRange(double s, double v, double* lo, double* hi) const;
  double MinAccelerationCap(double s0, double s1) const;

  // The exact step found no step from a state this profile held viable near arc length s (its
  // continuous model missed something there): plan more cautiously around s, by tightening the
  // limits of the grid points within `reach` mm of it, and recompute the boundaries behind.
  void Repair(double s, double reach);

  // Where the grid ends (rest is planned there), mm.
  double End() const;
  long GridPoints() const { return grid_points_; }  // sampled so far

 private:
  struct Point {
    double a, v;
  };
  struct Node {
    double s = 0.0;
    AxisVector d1, d2, d3;  // dq/ds, d2q/ds2, d3q/ds3 on the side towards the next node
    AxisVector q;           // exact axis positions
    PathState state;
    double feed_cap = 0.0;          // the tangential feed and the slow points at this arc length
    double acceleration_cap = 0.0;  // largest tangential acceleration the axes allow (a guide)
    double jerk_cap = 0.0;          // largest tangential jerk the axes allow (a guide)
    bool break_after = false;       // the path's derivatives jump between this node and the next
    bool near_break = false;        // within kBreakReachMm of such a jump
    bool law_entry = false;         // where the stop law's last stretch begins (law_zone_mm)
    double margin = 1.0;            // fraction of the limits planned with here (repairs lower it)
    std::vector<Point> boundary;    // v_max(a), sorted by a
    std::size_t peak = 0;           // its first point of largest feed
    long id = 0;                    // position in the grid since the first node
  };
  // What LeastJerk reads of kJerkBlock consecutive nodes, each taken at its worst: their least
  // margin and each axis' largest |q_s|, |q_ss|, |q_sss|. LeastJerk of it is at most that of any
  // of its nodes, so a release's bound skips the block where that is no less than the least jerk
  // it has found.
  struct JerkBlock {
    long first = 0;  // id of its first node
    int count = 0;   // nodes appended to it so far
    double margin = 1.0;
    AxisVector d1, d2, d3;
  };
  // Adds a node at the end of the grid.
  void Append(Node node);
  // The block of the node with this id.
  JerkBlock& BlockOf(long id);
  const JerkBlock& BlockOf(long id) const;

  // Admissible at node `n`: the jerk interval [lo, hi] of the state (v, a), or false; planned
  // with the fraction m of the limits instead of the node's margin.
  bool Admissible(const Node& n, double v, double a, double* lo, double* hi) const;
  bool Admissible(const Node& n, double m, double v, double a, double* lo, double* hi) const;
  // The tangential jerks [lo, hi] that keep every axis' jerk within the limits `l` times m at
  // node n in the state (v, a) (the jerk part of Admissible), or false when they do not meet.
  bool JerkInterval(const Node& n, const LookAheadLimits& l, double m, double v, double a,
                    double* lo, double* hi) const;
  // How far the state (v, a) at node n is beyond the axes' acceleration and jerk limits: the
  // largest excess of one over its limit, relative to it. Below the velocity caps (and with a
  // within its own), (v, a) is admissible exactly where this is <= 0.
  double Excess(const Node& n, double v, double a) const;
  // The largest v' <= v with (v', a) admissible at `n`; -1 if none.
  double Clip(const Node& n, double a, double v) const;
  // v_max(a) of a boundary, -1 outside it: the chords between its points (they read a concave
  // boundary low, never high).
  static double Boundary(const std::vector<Point>& b, double a);
  // The monotone cubic between points i and i + 1 of b at a (to tell where a chord reads low).
  static double Curved(const std::vector<Point>& b, std::size_t i, double a);
  // A new boundary point of n near acceleration a (v_guess: the feed there, roughly).
  Point Spawn(const Node& n, const Node& next, double a, double v_guess, double peak_a,
              double t) const;
  // The feed left once the deceleration -a > 0 of the state (v, a) at arc length s on node n's
  // stretch is released with the largest jerk the axes allow along the grid (< 0: the feed runs
  // out first, the state is not viable whatever lies ahead).
  double ReleaseFeed(const Node& n, double s, double v, double a) const;
  // The least tangential jerk the axes allow at n to any state with feed at most v and
  // deceleration at most `deceleration` (>= 0): the jerk a release there can count on. `n` is a
  // Node, or a JerkBlock (at most that of each of its nodes).
  template <typename Points>
  double LeastJerk(const Points& n, double v, double deceleration) const;
  // The slack of (v, a) at arc length s on node n's stretch, towards node `next`.
  double SlackTowards(const Node& n, double s, const Node& next, double v, double a) const;
  // The boundary at the end of the grid (rest there).
  std::vector<Point> TerminalBoundary(const Node& n) const;
  // The states at the law's entry node n from which the discrete stop law, with the least
  // capacity the grid points from n to the end give, comes to rest within the law's stretch.
  std::vector<Point> LawBoundary(const Node& n) const;
  // The boundary of `n` from that of `next` (Flow), and its peak.
  void Propagate(Node* n, const Node& next) const;
  void Flow(Node* n, const Node& next) const;
  // The first point of largest feed of a boundary (0 if it is empty).
  static std::size_t PeakOf(const std::vector<Point>& b);
  // The largest v with (v, a) viable at `n`, by bisection (where no point flows to a), its bracket
  // looked for `descent` steps of 0.6 down from the largest admissible feed.
  double Bisect(const Node& n, const Node& next, double a, int descent = 16) const;

  // The first node at or after arc length s; the first node past it.
  std::deque<Node>::const_iterator FirstAtOrAfter(double s) const;
  std::deque<Node>::const_iterator After(double s) const;
  // The grid point whose stretch holds s (the first one, for s before the grid; not empty).
  const Node& NodeAt(double s) const;
  // The node at s; `side` < 0: derivatives of the piece before s, > 0: after it, 0: central.
  Node Sample(double s, const PathState& hint, const AxisVector& q_hint, int side) const;
  // The grid spacing at n, the grid ending at `end` (rest).
  double Spacing(const Node& n, double end) const;
  // Samples the path from the last node to `to` and recomputes the boundaries backward.
  void Extend(double to);
  // Recomputes the boundaries backward from node `from` - 1 to arc length `until`, or to the
  // first node before `unchanged` (where the limits did not change) that comes out as it was.
  void Recompute(std::size_t from, double unchanged, double until);

  const PathSource& path_;
  const Machine& machine_;
  LookAheadLimits limits_;  // the axis limits planned with (LookAheadOptions' fractions)
  LookAheadLimits full_;    // the axis limits as given
  LookAheadOptions options_;
  int n_axes_ = 0;
  double window_ = 0.0;  // mm ahead of the planner
  std::optional<double> length_;
  std::deque<Node> nodes_;
  std::deque<JerkBlock> blocks_;     // over nodes_, from the block of its first node on
  double last_break_s_ = -INFINITY;  // the latest node appended with break_after
  long grid_points_ = 0;
  mutable std::size_t cursor_ = 0;  // the index After() returned last
};

}  // namespace dtis::interp
