// PathSource: what the interpolator sees of any path (docs/design.md, "The two contracts").
//
// Given a saved state near arc length s and a trial arc length s', a PathSource returns the pose at
// s' and the state there. For a curve the state is its parameter; for a surface strategy it is the
// (u, v) of the contact point, and the pose comes from a Newton solve warm-started from the state.
// States are small values, so the interpolator can back off to any earlier step and recompute.
#pragma once

#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "dtis/core/pose.hpp"

namespace dtis {

struct PathState {
  double s = 0.0;          // arc length of the tool tip from the start of the path, mm
  double u = 0.0;          // curve parameter, or the surface u of the contact point
  double v = 0.0;          // surface v of the contact point (unused by curves)
  double w = 0.0;          // a third coordinate if the source needs one (leading_line: the guide's)
  std::int32_t piece = 0;  // a hint for the source: arc-length table interval, pass piece, ...
};

enum class PathStatus : std::uint8_t {
  kOk,             // pose at the trial arc length
  kEnd,            // the trial arc length is past the end; the pose and state are at the end
  kLeftDomain,     // the solve left the face or the strategy's region before the trial arc length
  kNoConvergence,  // the solve did not converge to its tolerance
};

// What a source that answered `status` (kLeftDomain or kNoConvergence) at trial arc length s
// failed to do, for an error message: "the path source did not converge at arc length 12.5 mm".
std::string DescribePathFailure(PathStatus status, double s);

struct PathSample {
  PathStatus status = PathStatus::kOk;
  PathState state;
  Pose pose;
  int iterations = 0;  // Newton iterations spent (0 for closed-form sources)
};

// A point the path must pass no faster than `feed_mm_s`, known before planning (the middle of a
// smoothed G1 corner). The interpolator's look-ahead brakes for it as it brakes for the end of the
// path (Beudaert 2012, §2.5): it reaches the point at that feed with zero acceleration.
struct SlowPoint {
  double s = 0.0;          // arc length, mm
  double feed_mm_s = 0.0;  // > 0
};

class PathSource {
 public:
  virtual ~PathSource() = default;

  // The state at arc length 0.
  virtual PathState Start() const = 0;

  // The total arc length when it is known in advance (curves); surface strategies may only find
  // out when a solve reaches the end (kEnd).
  virtual std::optional<double> Length() const = 0;

  // The pose at arc length `s`, warm-started from `from` (any earlier or later state of this path).
  virtual PathSample At(const PathState& from, double s) const = 0;

  // Slow points sorted by arc length (none by default: the interpolator then finds every slow
  // place by itself, through its exact axis checks and back-off). A source built as the
  // interpolator advances returns those it holds: every one before the arc length last given to
  // Reach, none before the one last given to Release.
  virtual std::span<const SlowPoint> SlowPoints() const { return {}; }

  // The interpolator is about to look ahead to arc length `s`: from now on SlowPoints() holds
  // every slow point before `s`, and Length() is known if the path ends before `s`. Sources known
  // whole from the start (curves, surface passes, short G-code chains) have nothing to do; a long
  // G-code chain builds its corners up to there (geometry/g1_path.hpp).
  virtual void Reach(double s) const { (void)s; }

  // Arc lengths in [s0, s1] where the path's derivatives may jump (the knots of a curve, the ends
  // of a G1 block or smoothed corner), sorted. The look-ahead planner samples the axis derivatives
  // on either side of each (where q_sss jumps, the axis jerk does too). None by default.
  virtual std::vector<double> Breaks(double s0, double s1) const {
    (void)s0;
    (void)s1;
    return {};
  }

  // The interpolator will not step back before arc length `s` again (it has handed those steps
  // over): a source built as the interpolator advances may drop what lies far enough behind.
  virtual void Release(double s) const { (void)s; }

  // Where a state is, for error messages: "pass 3, u=0.25, v=0.5".
  virtual std::string Describe(const PathState& state) const = 0;
};

}  // namespace dtis
