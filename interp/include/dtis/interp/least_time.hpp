// The least-time planner's refinement: a plan that keeps every limit, shortened window by window
// on the verifier's own discrete problem.
//
// The variables are the arc lengths s_k of the periods; the constraints are the backward
// differences of the exact axis positions q(s_k) (Beudaert et al. 2012, Eq. 6 and 14), each within
// its limit, and the feed, tangential acceleration and jerk on s itself. A window of m periods of
// the plan, from period a, is replaced by m - d periods that cover the same arc length: the
// periods before it are kept, and those after it are the plan's own, d periods earlier. Whether
// m - d periods can do it is a feasibility problem, solved by sequential linear programs (the
// axis positions linearised through dq/ds around the iterate, a trust region on the steps of s)
// that minimise the largest excess of a limit; the exact positions judge every iterate, and only
// an iterate whose exact positions keep every limit replaces the window. So the plan is feasible
// after every window, and a refinement cut short leaves a plan as safe as the one it started from.
//
// A continuous-time jerk bound implies the discrete one (the third difference of positions is
// q''' averaged by a non-negative kernel over three periods), but where the path turns within a
// few periods' travel (the tips of a sharp curve, a G1 corner smoothed within a hundredth of a
// millimetre) the continuous bound is far more cautious than the discrete one: there the
// look-ahead's plan is slower than the least time, and a window of the discrete problem is what
// recovers it (docs/planner.md).
#pragma once

#include <vector>

#include "dtis/core/machine.hpp"
#include "dtis/core/path_source.hpp"

namespace dtis::interp {

struct LeastTimeOptions {
  // Periods in a window. The time a tip loses builds up over hundreds of periods before it at
  // high feeds, so a window must span them.
  int window_periods = 400;
  // Windows start this many periods apart (half a window: every stretch lies inside two).
  int window_stride = 200;
  // Linear programs allowed for one attempt (one window, one number of periods).
  int max_lps = 30;
  // Keep no shortened window whose axes' jerk flips sign between the extremes (beyond half the
  // limit, from one period to the next) more often than the plan it replaced: chatter no worse
  // than the look-ahead's or `vpop`'s, for less of the time (docs/planner.md measures both).
  bool no_added_chatter = false;
  // Sweeps over the plan; the next runs only where the last saved a period.
  int sweeps = 2;
};

// The limits the refinement keeps: per axis (mm or rad, s) as the exact step plans them (the
// limit fraction applied and the rounding guard taken off), and along the path (mm, s; infinity:
// none).
struct LeastTimeLimits {
  double period_s = 1e-3;
  double feed = 0.0, tangential_acceleration = 0.0, tangential_jerk = 0.0;
  double v[kMaxAxes] = {}, a[kMaxAxes] = {}, j[kMaxAxes] = {};
};

// One period of a plan.
struct PlannedStep {
  double s = 0.0;
  PathState state;
  AxisVector q;
  bool refined = false;  // set by ShortenPlan where a window replaced it
};

struct LeastTimeStats {
  long windows = 0;   // windows tried
  long attempts = 0;  // (window, periods removed) feasibility problems posed
  long linear_programs = 0;
  long evaluations = 0;  // exact poses
  // Attempts given up because the path could not be followed at an arc length they asked for.
  long failed_evaluations = 0;
  long periods_saved = 0;
  long smoothed = 0;  // windows whose path jerk was smoothed after they were shortened
  long reverted = 0;  // shortened windows given back because their axes' jerk flipped more
};

// Shortens `plan` (at rest at both ends, every period within `limits`) in place. Where the path
// cannot be followed at an arc length an attempt asks for, that attempt is given up: the plan
// stays as it was there.
LeastTimeStats ShortenPlan(const PathSource& path, const Machine& machine,
                           const LeastTimeLimits& limits, const LeastTimeOptions& options,
                           std::vector<PlannedStep>* plan);

}  // namespace dtis::interp
