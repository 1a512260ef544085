// The fixed-period VPOp interpolator (Beudaert, Lavernhe, Tournier 2012, §2), on any PathSource and
// any Machine.
//
// At each period the next arc length s_{j+1} must satisfy every constraint. The backward
// differences of Eq. 6 and 14 are affine in the newest position, so each axis limit is an interval
// on q_i^{j+1} built from the three previous exact positions:
//   |q - q_j| <= V dt,  |q - (2 q_j - q_{j-1})| <= A dt^2,  |q - (3 q_j - 3 q_{j-1} + q_{j-2})| <=
//   J dt^3
// (Eq. 7-9 are these intervals with q expanded around s_{j+1}; here the exact positions are used
// and a local model of q(s) only proposes the step). Tangential feed, acceleration and jerk give an
// interval on s_{j+1} directly. The planner takes the largest s_{j+1} whose exact position lies in
// every axis interval, so the emitted setpoints respect 100 % of every limit, not the paper's 120
// %. When no s_{j+1} is feasible it backs off with the dichotomy of §2.3: it finds the latest step
// from which the brake law reaches rest, brakes one period there and goes on at s_max. Look-ahead
// (§2.5) for known stops: a feed cap is approached without overshoot and the end of the path is
// reached at rest by discrete jerk-limited laws (motion_law.hpp).
#pragma once

#include <array>
#include <cstdint>
#include <functional>
#include <limits>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "dtis/core/machine.hpp"
#include "dtis/core/path_source.hpp"
#include "dtis/interp/least_time.hpp"
#include "dtis/interp/viable_feeds.hpp"

namespace dtis::interp {

// How the exact step looks ahead.
enum class PlannerKind : std::uint8_t {
  // The paper's: the greedy step learns of a feed valley by failing in it, and the dichotomy of
  // §2.3 backs off to the latest step from which a brake gets through. Kept so that the papers'
  // figures stay reproducible.
  kVpop,
  // The exact step capped by a look-ahead of the viable feeds (viable_feeds.hpp); the paper's
  // back-off stays as the last resort. The default.
  kLookAhead,
  // The look-ahead's plan, then shortened window by window on the verifier's own discrete
  // problem (least_time.hpp): the least time where the continuous model is wrong (sharp tips,
  // corners turned within a few periods). Plans a path whole; it does not stream.
  kLeastTime,
};
const char* PlannerName(PlannerKind planner);
// The planner PlannerName gives `name` ("vpop", "lookahead" or "least-time"), if any.
std::optional<PlannerKind> PlannerFromName(std::string_view name);

// The longest motion one path may take, s (a day).
inline constexpr double kMaxMotionS = 24.0 * 3600.0;

struct VpopOptions {
  PlannerKind planner = PlannerKind::kLookAhead;
  LookAheadOptions look_ahead;  // planner = kLookAhead or kLeastTime
  LeastTimeOptions least_time;  // planner = kLeastTime
  double period_s = 1e-3;       // dt: setpoints are exactly this far apart, s
  double feed_mm_s = 0.0;       // programmed feed F, the upper bound of (s_{j+1} - s_j) / dt, mm/s
  // Tangential acceleration and jerk bounds (Eq. 6 on s), mm/s^2 and mm/s^3; infinity: none.
  double tangential_acceleration_mm_s2 = std::numeric_limits<double>::infinity();
  double tangential_jerk_mm_s3 = std::numeric_limits<double>::infinity();
  // Plan against this fraction of every axis limit (1 = 100 %). Rounding of the emitted numbers is
  // accounted for separately, so 1 is safe.
  double limit_fraction = 1.0;
  // The motion ends at rest within this distance of the end of the path, mm.
  double end_tolerance_mm = 1e-9;
  // Exact evaluations allowed in the search for one step before it counts as empty.
  int max_search_evaluations = 24;
  // Steps kept open to back-off before they are handed to the sink. Each handed-over step is one
  // from which a stop to rest within every limit is proven (docs/design.md: the commit horizon).
  std::size_t commit_horizon = std::numeric_limits<std::size_t>::max();
  // Largest absolute axis position expected, used to size the rounding guard (mm or rad; 0: from
  // the axis travel, 10 turns for continuous rotary axes).
  double position_scale = 0.0;
  // Axis positions the machine holds before this path: the first pose's solution branch and the
  // unwrapping of rotary axes continue from them (none: the machine's default branch).
  std::optional<AxisVector> previous_q;
  // Start at this feed with zero acceleration instead of at rest (the two periods before the start
  // lie on the path behind it, at arc lengths -2 F dt and -F dt). Used by the look-ahead's backward
  // plans; a path planned this way does not start at rest.
  double start_feed_mm_s = 0.0;
  // A back-off's brake tests continue the brake law's last run that got through where they start
  // on it (the law depends only on the three steps it starts from). Off: every test recomputes
  // the law, with more evaluations and the same setpoints where the source's poses depend only on
  // the state and arc length asked (curves, G-code; a surface pass's warm-start cache makes its
  // last bits depend on the order of the solves). For tests and measurements.
  bool reuse_brake_runs = true;
  // A path whose motion has not ended after this long is refused (dtis::Error naming where the
  // feed went): a feed that collapses somewhere the look-ahead did not foresee must not plan, and
  // fill memory, for ever; s.
  double max_motion_s = kMaxMotionS;
  // Called every 256 steps planned with the arc length (mm) and time (s) the plan has reached, for
  // a progress display (a back-off may still take some of it back). From the planning thread.
  std::function<void(double, double)> progress;

  bool IsValid(std::string* why) const;
};

// Rounding guard: writing positions (and degrees) and differencing them again moves a jerk by
// about 8 eps |q| / dt^3; the planner plans that much below each limit so the verifier never
// reads > 1. PositionScale: the |q| it is sized for (options.position_scale, else the axis'
// travel, 10 turns for a continuous rotary axis); RoundingGuard: the position error, 64 eps
// (|q| + 1).
double PositionScale(const Axis& axis, const VpopOptions& options);
double RoundingGuard(const Axis& axis, const VpopOptions& options);
// The shortest periods (s) at which the guard takes at most 0.1 % of the axis' velocity,
// acceleration and jerk limit, each times options.limit_fraction: the planner refuses a period
// shorter than the longest of the three (dtis::Error "period ... is too short for axis ...").
std::array<double, 3> ShortestPeriods(const Axis& axis, const VpopOptions& options);

// Which constraint decided a step.
enum class Limiter : std::uint8_t {
  kStart,
  kFeed,
  kTangentialAcceleration,
  kTangentialJerk,
  kFeedLookAhead,       // approaching a feed or axis-velocity cap without overshoot
  kEndLookAhead,        // stopping at the end of the path
  kSlowPointLookAhead,  // braking for a slow point of the path (a G1 corner)
  kPathEnd,
  kAxisVelocity,
  kAxisAcceleration,
  kAxisJerk,
  kBackOff,  // a brake step chosen by the dichotomy
  kRest,
  kProfileLookAhead,  // the largest step whose state stays viable (planner = kLookAhead)
  kLeastTimeWindow,   // a period of a window the least-time planner shortened
  kCount
};
const char* LimiterName(Limiter limiter);
// The limiter LimiterName gives `name`, if any.
std::optional<Limiter> LimiterFromName(std::string_view name);

struct LimiterId {
  Limiter kind = Limiter::kStart;
  std::int8_t axis = -1;  // for axis limiters
};

struct Setpoint {
  long index = 0;   // period number; t = index * dt
  double s = 0.0;   // arc length, mm
  AxisVector q;     // mm and rad
  PathState state;  // of the path source
  LimiterId limiter;
};

class SetpointSink {
 public:
  virtual ~SetpointSink() = default;
  // Called once per setpoint, in order. A setpoint handed over never changes.
  virtual void Accept(const Setpoint& setpoint) = 0;
  // True when the sink wants no more setpoints: planning stops after the next hand-over.
  virtual bool Done() const { return false; }
  // For sinks that feed a running machine (docs/design.md: the commit horizon). When WantsStops(),
  // after every hand-over the planner offers `stop`: the rows that would follow the last setpoint
  // handed over to bring the machine to rest within every limit along the path (the steps
  // planned up to the last one from which a stop is proven, then the brake law, then the rest held
  // for two periods; indices continue the sequence). Playing it instead of what comes next is
  // always safe, whatever happens to the planner afterwards.
  virtual bool WantsStops() const { return false; }
  virtual void AcceptStop(const std::vector<Setpoint>& /*stop*/) {}
};

struct VpopSummary {
  double motion_time_s = 0.0;  // time of the last period that moves
  long setpoints = 0;          // handed to the sink, rest rows included
  double end_s = 0.0;          // arc length where the motion stopped, mm
  long back_offs = 0;          // dichotomies run
  long brake_tests = 0;        // brake-to-rest sequences tried by the dichotomies
  long evaluations = 0;        // pose + inverse kinematics evaluations
  long path_iterations = 0;    // Newton iterations reported by the path source
  // planner = kLookAhead: grid points of the look-ahead sampled, and steps for which no arc
  // length within the exact constraints kept the state viable (the one closest to it was taken).
  long profile_grid_points = 0;
  long profile_refusals = 0;
  // planner = kLookAhead: dead ends met on a state the look-ahead held viable, each repaired by
  // planning that stretch more cautiously and stepping back to a viable state (back-offs count
  // the paper's dichotomy, the last resort).
  long profile_repairs = 0;
  // Under a commit horizon: stops to rest proven before a hand-over, and how many of them with
  // the paper's law planned blind (the look-ahead planner tries it first; vpop proves with it
  // only).
  long stop_proofs = 0;
  long blind_proofs = 0;
  // planner = kLeastTime: windows of the look-ahead's plan tried, the linear programs solved for
  // them, and the periods they took off the motion.
  long least_time_windows = 0;
  long least_time_programs = 0;
  long least_time_saved = 0;
  std::array<long, static_cast<int>(Limiter::kCount)> limited_by{};  // steps per limiter kind
};

// Plans the whole path and hands every setpoint to `sink`. Throws dtis::Error when the path cannot
// be followed (out of travel, a singularity the machine cannot pass, the path source failing), with
// the arc length and the source's description of where.
VpopSummary PlanVpop(const PathSource& path, const Machine& machine, const VpopOptions& options,
                     SetpointSink& sink);

}  // namespace dtis::interp
