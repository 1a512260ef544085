#include "dtis/interp/vpop.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <deque>
#include <map>
#include <numbers>
#include <optional>

#include "dtis/core/error.hpp"
#include "dtis/interp/motion_law.hpp"
#include "dtis/interp/program.hpp"
#include "vector_sink.hpp"

namespace dtis::interp {

const char* LimiterName(Limiter limiter) {
  switch (limiter) {
    case Limiter::kStart:
      return "start";
    case Limiter::kFeed:
      return "feed";
    case Limiter::kTangentialAcceleration:
      return "tangential_acceleration";
    case Limiter::kTangentialJerk:
      return "tangential_jerk";
    case Limiter::kFeedLookAhead:
      return "feed_look_ahead";
    case Limiter::kEndLookAhead:
      return "end_look_ahead";
    case Limiter::kSlowPointLookAhead:
      return "slow_point_look_ahead";
    case Limiter::kPathEnd:
      return "path_end";
    case Limiter::kAxisVelocity:
      return "axis_velocity";
    case Limiter::kAxisAcceleration:
      return "axis_acceleration";
    case Limiter::kAxisJerk:
      return "axis_jerk";
    case Limiter::kBackOff:
      return "back_off";
    case Limiter::kRest:
      return "rest";
    case Limiter::kProfileLookAhead:
      return "profile_look_ahead";
    case Limiter::kLeastTimeWindow:
      return "least_time_window";
    case Limiter::kCount:
      break;
  }
  return "?";
}

std::optional<Limiter> LimiterFromName(std::string_view name) {
  for (int k = 0; k < static_cast<int>(Limiter::kCount); ++k) {
    const auto limiter = static_cast<Limiter>(k);
    if (name == LimiterName(limiter)) return limiter;
  }
  return std::nullopt;
}

const char* PlannerName(PlannerKind planner) {
  switch (planner) {
    case PlannerKind::kVpop:
      return "vpop";
    case PlannerKind::kLookAhead:
      return "lookahead";
    case PlannerKind::kLeastTime:
      return "least-time";
  }
  return "?";
}

std::optional<PlannerKind> PlannerFromName(std::string_view name) {
  for (const PlannerKind planner :
       {PlannerKind::kVpop, PlannerKind::kLookAhead, PlannerKind::kLeastTime}) {
    if (name == PlannerName(planner)) return planner;
  }
  return std::nullopt;
}

double PositionScale(const Axis& axis, const VpopOptions& options) {
  double scale = options.position_scale;
  if (!(scale > 0.0)) {
    scale = axis.continuous ? 20.0 * std::numbers::pi
                            : std::max(std::abs(axis.travel_min), std::abs(axis.travel_max));
    if (!std::isfinite(scale)) scale = 1e4;
  }
  return scale;
}

double RoundingGuard(const Axis& axis, const VpopOptions& options) {
  constexpr double kEps = 2.220446049250313e-16;
  return 64.0 * kEps * (PositionScale(axis, options) + 1.0);
}

std::array<double, 3> ShortestPeriods(const Axis& axis, const VpopOptions& options) {
  const double guard = RoundingGuard(axis, options), f = options.limit_fraction;
  // The guard may take 0.1 % of each limit: guard / dt, 2 guard / dt^2 and 4 guard / dt^3.
  return {guard / (1e-3 * f * axis.vmax), std::sqrt(2.0 * guard / (1e-3 * f * axis.amax)),
          std::cbrt(4.0 * guard / (1e-3 * f * axis.jmax))};
}

bool VpopOptions::IsValid(std::string* why) const {
  const auto fail = [why](std::string message) {
    if (why) *why = std::move(message);
    return false;
  };
  if (!(period_s > 0.0) || !std::isfinite(period_s)) {
    return fail(fmt::format("period must be a finite time > 0 s, got {}", period_s));
  }
  if (!(feed_mm_s > 0.0) || !std::isfinite(feed_mm_s)) {
    return fail(fmt::format("feed must be a finite speed > 0, got {} mm/s", feed_mm_s));
  }
  if (!(tangential_acceleration_mm_s2 > 0.0)) {
    return fail(fmt::format("tangential acceleration must be > 0, got {} mm/s^2",
                            tangential_acceleration_mm_s2));
  }
  if (!(tangential_jerk_mm_s3 > 0.0)) {
    return fail(fmt::format("tangential jerk must be > 0, got {} mm/s^3", tangential_jerk_mm_s3));
  }
  if (!(limit_fraction > 0.0 && limit_fraction <= 1.0)) {
    return fail(fmt::format("limit fraction must be in (0, 1], got {}", limit_fraction));
  }
  if (!(end_tolerance_mm > 0.0)) {
    return fail(fmt::format("end tolerance must be > 0 mm, got {}", end_tolerance_mm));
  }
  if (max_search_evaluations < 4) {
    return fail(fmt::format("max_search_evaluations must be >= 4, got {}", max_search_evaluations));
  }
  if (commit_horizon < 8) return fail("commit horizon must be at least 8 periods");
  if (!(max_motion_s > 0.0)) return fail("the longest motion must be > 0 s");
  return true;
}

namespace {

struct Step {
  double s = 0.0;
  PathState state;
  AxisVector q;
  LimiterId limiter;
};

Setpoint ToSetpoint(const Step& step, long index) {
  return {.index = index, .s = step.s, .q = step.q, .state = step.state, .limiter = step.limiter};
}

// The three latest steps, newest last.
struct History {
  const Step* p2;
  const Step* p1;
  const Step* p0;
};

struct Interval {
  double lo, hi;
  LimiterId lo_by, hi_by;
};

struct Box {
  int n = 0;
  double lo[kMaxAxes], hi[kMaxAxes];
  Limiter lo_kind[kMaxAxes], hi_kind[kMaxAxes];
  double band[kMaxAxes];  // narrowest of the three half-widths, for the search tolerance
  double jerk_lo[kMaxAxes], jerk_hi[kMaxAxes];  // the jerk interval alone (Eq. 9), for the laws
};

struct Limits {
  double v, a, j;  // per-axis planning limits after the rounding guard
};

// The limits the exact step plans an axis with: the limit fraction applied, the rounding guard
// taken off.
Limits ExactStepLimits(const Axis& axis, const VpopOptions& o) {
  const double guard = RoundingGuard(axis, o), dt = o.period_s, f = o.limit_fraction;
  return {.v = f * axis.vmax - guard / dt,
          .a = f * axis.amax - 2.0 * guard / (dt * dt),
          .j = f * axis.jmax - 4.0 * guard / (dt * dt * dt)};
}

struct Effective {
  double feed, acceleration, jerk;  // along the path, from the axis limits and the tangential ones
};

// The look-ahead and brake laws aim this fraction of the effective limits, so that their targets
// fall strictly inside the axis intervals instead of on their faces (where rounding decides).
constexpr double kLawMargin = 1.0 - 1e-7;

// The look-ahead planner's stop proofs (Mode::kStop) plan the release of their deceleration at this
// fraction of the jerk, not at kReleaseJerkFraction. A release planned at the whole jerk has no
// room: where the exact step cannot follow it for a period (a smoothed corner of the fine-block
// wave takes part of an axis' jerk), it falls behind for good and the stop ends at a feed of
// 0.01 mm/s still braking at 20 mm/s^2, where no step is left. Streamed, 485 of the wave's 525
// proof attempts failed so, each failure a back-off or a search for an earlier step to prove
// (514 000 exact evaluations instead of 72 000). With 1 % of room the law catches up.
constexpr double kProofReleaseFraction = 0.99;

// The look-ahead's cap is searched among the path jerks the axes allow at the current state,
// widened by this fraction of that interval's width.
constexpr double kJerkGive = 0.05;

// The look-ahead planner's end law may brake up to this factor harder than its acceleration cap
// where that cap falls just short of landing the state (LookAhead, ArriveBy).
constexpr double kEndLawGive = 1.1;

// Repairs of the look-ahead at one place (within a few periods' travel of the first) before the
// planner backs off instead. Where two repairs (6 % off the limits there) do not get the exact
// step through, the continuous model is wrong there, not short of margin: more repairs only slow
// the profile around that place further (on the trident at 5 m/min, 8 repairs per place passed
// some draws' tips at rest; the median of 17 draws went 1.893 -> 1.849 s with 2).
constexpr int kMaxRepairsHere = 2;
// Repairs of the look-ahead on one path before every further dead end is backed off from.
constexpr long kMaxRepairs = 200;
inline double kRepairNeighbourhood(double v, double dt) { return std::max(20.0 * v * dt, 1e-3); }

// Times in a row the planner may come back to rest at the same arc length, its step from there
// halved each time (2^-30 of the first), before it reports that no step forward is possible.
constexpr int kMaxStuckRetries = 30;

// A path walked backwards from arc length `end` (its s is end - s of the path): the look-ahead
// plans away from a slow point on it with the same planner, so that braking for the point is the
// mirror image of accelerating away from it (Beudaert 2012, §2.5).
class ReversedPath final : public PathSource {
 public:
  ReversedPath(const PathSource& path, double end) : path_(path), end_(end) {}
  PathState Start() const override {
    PathState state = path_.At(path_.Start(), end_).state;
    state.s = 0.0;
    return state;
  }
  std::optional<double> Length() const override { return end_; }
  PathSample At(const PathState& from, double s) const override {
    PathState f = from;
    f.s = end_ - from.s;
    PathSample x = path_.At(f, std::max(end_ - s, 0.0));
    if (s > end_) x.status = PathStatus::kEnd;
    x.state.s = end_ - x.state.s;
    return x;
  }
  std::string Describe(const PathState& state) const override {
    PathState f = state;
    f.s = end_ - state.s;
    return path_.Describe(f);
  }

 private:
  const PathSource& path_;
  double end_;
};

// Collects the feed of a backward plan as (arc length of the forward path, feed of the forward
// period that ends there), until the feed stops rising.
class BackwardCurve final : public SetpointSink {
 public:
  BackwardCurve(double end, double feed, double cap, double dt)
      : end_(end), cap_(cap), dt_(dt), last_s_(0.0) {
    curve_.push_back({end, feed});
  }
  void Accept(const Setpoint& sp) override {
    if (done_) return;
    if (sp.index == 0) {
      last_s_ = sp.s;
      return;
    }
    const double feed = (sp.s - last_s_) / dt_;
    const double at = end_ - last_s_;
    last_s_ = sp.s;
    if (feed <= curve_.back().second) {
      done_ = true;  // the feed no longer rises: the plan turns to its own end
      return;
    }
    curve_.push_back({at, feed});
    if (feed >= cap_ * (1.0 - 1e-9)) done_ = true;
  }
  bool Done() const override { return done_; }
  // Ascending in arc length.
  std::vector<std::pair<double, double>> Take() {
    std::reverse(curve_.begin(), curve_.end());
    return std::move(curve_);
  }

 private:
  double end_, cap_, dt_, last_s_;
  bool done_ = false;
  std::vector<std::pair<double, double>> curve_;
};

class Planner {
 public:
  Planner(const PathSource& path, const Machine& machine, const VpopOptions& options,
          SetpointSink& sink)
      : path_(path), machine_(machine), o_(options), sink_(sink), dt_(options.period_s) {
    std::string why;
    if (!o_.IsValid(&why)) throw Error("interpolator options: {}", why);
    const auto axes = machine_.Axes();
    n_ = static_cast<int>(axes.size());
    for (int i = 0; i < n_; ++i) {
      const Axis& a = axes[static_cast<std::size_t>(i)];
      for (const double limit : {a.vmax, a.amax, a.jmax}) {
        if (!(limit > 0.0) || !std::isfinite(limit)) {
          throw Error("machine '{}': axis {} limits must be finite and > 0", machine_.Name(),
                      a.name);
        }
      }
      const double scale = PositionScale(a, o_);
      const Limits l = ExactStepLimits(a, o_);
      if (l.v < 0.999 * o_.limit_fraction * a.vmax || l.a < 0.999 * o_.limit_fraction * a.amax ||
          l.j < 0.999 * o_.limit_fraction * a.jmax) {
        throw Error(
            "period {} s is too short for axis {}: rounding of positions near {} would eat more "
            "than 0.1 % of its limits; use a longer period",
            dt_, a.name, scale);
      }
      limits_[i] = l;
    }
  }

  VpopSummary Run();

 private:
  // ---- evaluation
  bool Evaluate(const Step& from, double s, Step* out);
  [[noreturn]] void FailAt(const Step& where, const std::string& what) const;

  // ---- one step
  Interval Tangential(const History& h) const;
  bool MakeBox(const History& h, Box* box) const;
  Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxAxes, 1> Direction(const History& h);
  Effective Available(const History& h, const Box& box, const Interval& t);
  // `a_cap`: the caller takes the lesser of the laws' next acceleration and a_cap, so the end law
  // is searched only where a_cap does not land (one stop distance where it does).
  std::pair<double, LimiterId> LookAhead(const History& h, const Effective& e,
                                         double a_cap = INFINITY);
  // The backward limit of a slow point (nullptr when it could not be planned).
  const std::vector<std::pair<double, double>>* SlowCurve(const SlowPoint& point, const Step& near);
  double ArriveBy(const History& h, double a_hi, double jerk, double acceleration, double at,
                  double feed, double give = 1.0) const;
  bool Solve(const History& h, const Box& box, double lo, double hi, double target, Step* out,
             LimiterId* by);
  // kGreedy: the planner's step. kBrake: the stop law of §2.3, which the back-off runs. kStop: the
  // stop law, no faster than the greedy step's caps allow (the look-ahead planner's stop proofs).
  enum class Mode { kGreedy, kBrake, kStop };
  bool Produce(const History& h, Mode mode, Step* out);
  // Whether the step lands the motion at the path's end: the end law binds it (`binding`) over the
  // last LookAheadOptions::law_zone_mm, where the law is followed and not the profile.
  bool Landing(const History& h, Limiter binding) const {
    return binding == Limiter::kEndLookAhead && length_ &&
           *length_ - h.p0->s <= o_.look_ahead.law_zone_mm;
  }

  // ---- back-off
  // Runs the brake law from step m until rest, or (when `pass_s` is finite) until it has carried
  // the motion `margin` periods beyond arc length `pass_s` without an empty step. `record`, when
  // given, receives every step of the law. `law` is kBrake or kStop.
  bool Brake(long m, Step* first, double pass_s = INFINITY, long margin = 0,
             std::vector<Step>* record = nullptr, Mode law = Mode::kBrake);
  // The law the stops of the commit horizon are proven with: kBrake for the paper's planner;
  // kStop for the look-ahead planner, where the blind kBrake is tried first (Run).
  Mode ProofLaw() const { return profile_ ? Mode::kStop : Mode::kBrake; }
  void BackOff(long failed);
  void Commit(long upto);
  // For sinks that want it: the stop to rest from the last step handed over.
  void OfferStop();

  const Step& At(long g) const {
    return steps_[static_cast<std::size_t>(std::max(g, base_) - base_)];
  }
  long Last() const { return base_ + static_cast<long>(steps_.size()) - 1; }
  History HistoryAt(long g) const { return {&At(g - 2), &At(g - 1), &At(g)}; }
  static bool AtRest(const History& h) { return h.p0->s == h.p1->s && h.p1->s == h.p2->s; }
  bool Finished(const History& h) const {
    return AtRest(h) && length_ && h.p0->s >= *length_ - o_.end_tolerance_mm;
  }

  const PathSource& path_;
  const Machine& machine_;
  const VpopOptions& o_;
  SetpointSink& sink_;
  const double dt_;
  int n_ = 0;
  Limits limits_[kMaxAxes];
  std::optional<double> length_;
  std::deque<Step> steps_;
  long base_ = 0;       // global index of steps_.front()
  long committed_ = 0;  // steps with a global index below this were handed to the sink
  long safe_ = 0;       // latest step from which a stop to rest is proven
  long hint_ = 0;       // latest step whose brake law got past the last failure (>= safe_)
  // The stop law's steps from step stop_from_ (a proven-safe step), for OfferStop and for a
  // back-off that goes back to that step (the law it was proven with may not be kBrake).
  std::vector<Step> stop_, trial_stop_;
  long stop_from_ = -1;
  Mode safe_law_ = Mode::kBrake;  // the law the stop from safe_ was proven with
  long last_proof_ = -1;          // the latest step a stop proof of the commit horizon started from
  // The look-ahead's stop proofs: how many more skip the blind law, after how many blind
  // failures in a row.
  long skip_blind_ = 0, blind_misses_ = 0;
  VpopSummary summary_;
  // The brake law's steps from step `from` on (the law is a function of the three steps it
  // starts from): the last run that got through, and the one being tried.
  struct BrakeRun {
    long from = -1;
    Mode law = Mode::kBrake;
    Step start[3];                 // steps from - 2 .. from when the run was made
    std::optional<double> length;  // the path length known then (it bounds the law's steps)
    std::vector<Step> steps;       // steps from + 1, from + 2, ...
    bool failed = false;           // the law found no step after the last one
    void Start(const Planner& planner, long m, Mode with) {
      from = m;
      law = with;
      for (int k = 0; k < 3; ++k) start[k] = planner.At(m - 2 + k);
      length = planner.length_;
      steps.clear();
      failed = false;
    }
    // Whether the planner's steps up to m are this run's (so the law from m continues it).
    bool Continues(const Planner& planner, long m, Mode with) const {
      if (from < 0 || law != with || m < from || m - from > static_cast<long>(steps.size()) ||
          length != planner.length_) {
        return false;
      }
      for (long g = from - 2; g <= m; ++g) {
        const Step& was =
            g <= from ? start[g - from + 2] : steps[static_cast<std::size_t>(g - from - 1)];
        if (!Same(planner.At(g), was)) return false;
      }
      return true;
    }
  };
  static bool Same(const Step& a, const Step& b) {
    return a.s == b.s && a.q == b.q && a.state.u == b.state.u && a.state.v == b.state.v &&
           a.state.w == b.state.w && a.state.piece == b.state.piece;
  }
  BrakeRun last_run_, scratch_run_;
  // Where the planner last came back to rest with no step forward kept, and how many times in a
  // row: each time, the next greedy step from there is halved (Produce).
  double last_stuck_s_ = -1.0;
  // Per slow point planned so far, by its arc length: its backward limit (ascending (s, feed)),
  // empty when it could not be planned. Those behind the released steps are dropped (Commit).
  std::map<double, std::vector<std::pair<double, double>>> curves_;
  int stuck_count_ = 0;
  // planner = kLookAhead
  std::optional<ViableFeeds> profile_;
  bool Repair(long j);
  double last_repair_s_ = -INFINITY;
  int repairs_here_ = 0;
  // The largest arc length in [lo, target] whose state the look-ahead holds viable, or, when
  // none is, the one closest to viable (counted as a refusal).
  // `floored`, when given, receives `target` raised to the releasable floor; `refused`, whether
  // no state was viable.
  double ProfileCap(const History& h, double lo, double hi, double target,
                    double* floored = nullptr, bool* refused = nullptr);
};

[[noreturn]] void Planner::FailAt(const Step& where, const std::string& what) const {
  throw Error("cannot follow the path at {}: {}", path_.Describe(where.state), what);
}

bool Planner::Evaluate(const Step& from, double s, Step* out) {
  ++summary_.evaluations;
  const PathSample sample = path_.At(from.state, s);
  summary_.path_iterations += sample.iterations;
  switch (sample.status) {
    case PathStatus::kOk:
      break;
    case PathStatus::kEnd:
      if (!length_ || sample.state.s < *length_) length_ = sample.state.s;
      break;
    case PathStatus::kLeftDomain:
    case PathStatus::kNoConvergence:
      FailAt(from, DescribePathFailure(sample.status, s));
  }
  out->s = sample.state.s;
  out->state = sample.state;
  const InverseResult r = machine_.Inverse(sample.pose, &from.q, &out->q);
  if (r.status != InverseStatus::kOk) {
    Step where = *out;
    FailAt(where, DescribeInverseFailure(machine_, r));
  }
  return sample.status == PathStatus::kOk;
}

Interval Planner::Tangential(const History& h) const {
  const double s0 = h.p0->s, v0 = (s0 - h.p1->s) / dt_;
  const double v1 = (h.p1->s - h.p2->s) / dt_, a0 = (v0 - v1) / dt_;
  Interval r{s0, s0 + o_.feed_mm_s * dt_, {Limiter::kRest, -1}, {Limiter::kFeed, -1}};
  const auto lower = [&r](double v, Limiter by) {
    if (v > r.lo) r.lo = v, r.lo_by = {by, -1};
  };
  const auto upper = [&r](double v, Limiter by) {
    if (v < r.hi) r.hi = v, r.hi_by = {by, -1};
  };
  if (std::isfinite(o_.tangential_acceleration_mm_s2)) {
    const double base = s0 + v0 * dt_, w = o_.tangential_acceleration_mm_s2 * dt_ * dt_;
    lower(base - w, Limiter::kTangentialAcceleration);
    upper(base + w, Limiter::kTangentialAcceleration);
  }
  if (std::isfinite(o_.tangential_jerk_mm_s3)) {
    const double base = s0 + v0 * dt_ + a0 * dt_ * dt_,
                 w = o_.tangential_jerk_mm_s3 * dt_ * dt_ * dt_;
    lower(base - w, Limiter::kTangentialJerk);
    upper(base + w, Limiter::kTangentialJerk);
  }
  if (length_) upper(*length_, Limiter::kPathEnd);
  return r;
}

bool Planner::MakeBox(const History& h, Box* box) const {
  box->n = n_;
  for (int i = 0; i < n_; ++i) {
    const double q0 = h.p0->q[i], q1 = h.p1->q[i], q2 = h.p2->q[i];
    const Limits& l = limits_[i];
    const double wv = l.v * dt_, wa = l.a * dt_ * dt_, wj = l.j * dt_ * dt_ * dt_;
    double lo = q0 - wv, hi = q0 + wv;
    Limiter lo_kind = Limiter::kAxisVelocity, hi_kind = Limiter::kAxisVelocity;
    const double ca = 2.0 * q0 - q1;
    if (ca - wa > lo) lo = ca - wa, lo_kind = Limiter::kAxisAcceleration;
    if (ca + wa < hi) hi = ca + wa, hi_kind = Limiter::kAxisAcceleration;
    const double cj = 3.0 * q0 - 3.0 * q1 + q2;
    box->jerk_lo[i] = cj - wj;
    box->jerk_hi[i] = cj + wj;
    if (cj - wj > lo) lo = cj - wj, lo_kind = Limiter::kAxisJerk;
    if (cj + wj < hi) hi = cj + wj, hi_kind = Limiter::kAxisJerk;
    if (lo > hi) return false;
    box->lo[i] = lo;
    box->hi[i] = hi;
    box->lo_kind[i] = lo_kind;
    box->hi_kind[i] = hi_kind;
    box->band[i] = std::min({wv, wa, wj});
  }
  return true;
}

Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxAxes, 1> Planner::Direction(const History& h) {
  const double ds = h.p0->s - h.p1->s;
  if (ds > 1e-9) return (h.p0->q - h.p1->q) / ds;
  // At (or almost at) rest: probe the path a little ahead.
  const double probe = 1e-4;
  double s = h.p0->s + probe;
  if (length_ && s > *length_) s = std::max(*length_, h.p0->s);
  Step ahead;
  Evaluate(*h.p0, s, &ahead);
  if (ahead.s - h.p0->s > 1e-12) return (ahead.q - h.p0->q) / (ahead.s - h.p0->s);
  // At the very end: look back instead.
  Step behind;
  Evaluate(*h.p0, std::max(0.0, h.p0->s - probe), &behind);
  if (h.p0->s - behind.s > 1e-12) return (h.p0->q - behind.q) / (h.p0->s - behind.s);
  return Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxAxes, 1>::Zero(n_);
}

// The limits along the path that the look-ahead and brake laws may use from this step: the feed
// (programmed, and each axis velocity over |dq_i/ds|), the acceleration (each axis' limit less its
// centripetal part q_ss v^2), and the jerk that the axis jerk intervals (Eq. 9) of this very step
// leave around the zero-jerk position, which accounts for the curvature terms of Eq. 3 exactly
// here. Only the jerk intervals: where an axis runs at its acceleration (or velocity) bound, the
// whole box leaves almost no room on that side, and a law planned with that sliver as its jerk
// takes the next step for braked too hard, lets go, and brakes again the period after. On the
// 10-degree tilt sample (A at its acceleration limit while the stop holds) the jerk so estimated
// alternated 160 / 640 mm/s^3 period by period, the stop crossed its release curve and reached
// the end still braking; on a circle where the axis acceleration binds the feed dipped 4 % below
// the closed form. The acceleration bound is the law's `acceleration`.
Effective Planner::Available(const History& h, const Box& box, const Interval& t) {
  using V = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxAxes, 1>;
  const double s0 = h.p0->s, s1 = h.p1->s;
  const double v0 = (s0 - s1) / dt_, a0 = (v0 - (s1 - h.p2->s) / dt_) / dt_;
  const double natural = s0 + (v0 + a0 * dt_) * dt_;  // zero path jerk
  Effective e{o_.feed_mm_s, o_.tangential_acceleration_mm_s2, o_.tangential_jerk_mm_s3};
  double up = INFINITY, down = INFINITY;
  if (std::isfinite(o_.tangential_jerk_mm_s3)) up = down = o_.tangential_jerk_mm_s3;
  V g, curvature = V::Zero(n_);
  Step probe;
  const double tiny = 1e-12 * (1.0 + std::abs(s0));
  if (natural - s0 > tiny && natural <= t.hi) {
    Evaluate(*h.p0, natural, &probe);
    const V d0x = (probe.q - h.p0->q) / (probe.s - s0);
    if (s0 - s1 > tiny) {
      const V d10 = (h.p0->q - h.p1->q) / (s0 - s1);
      const V d10x = (d0x - d10) / (probe.s - s1);
      g = d10 + d10x * ((probe.s - s1) + (probe.s - s0));
      curvature = 2.0 * d10x;
    } else {
      g = d0x;
    }
  } else {
    g = Direction(h);
    probe = *h.p0;
    probe.s = s0;
  }
  const double d3 = dt_ * dt_ * dt_;
  for (int i = 0; i < n_; ++i) {
    const double k = std::abs(g[i]);
    if (k < 1e-9) continue;
    e.feed = std::min(e.feed, limits_[i].v / k);
    const double centripetal = std::abs(curvature[i]) * v0 * v0;
    e.acceleration = std::min(e.acceleration, std::max(limits_[i].a - centripetal, 0.0) / k);
    // The axis jerk interval as an interval of s around the probe, then as path jerk around
    // `natural`.
    double a = probe.s + (box.jerk_lo[i] - probe.q[i]) / g[i];
    double b = probe.s + (box.jerk_hi[i] - probe.q[i]) / g[i];
    if (a > b) std::swap(a, b);
    up = std::min(up, (b - natural) / d3);
    down = std::min(down, (natural - a) / d3);
  }
  // Symmetric, and never below a quarter of the nominal path jerk: where curvature alone nearly
  // saturates an axis one side of its interval is almost empty, and a law planned with that
  // sliver would crawl. The laws only propose; the exact search and the back-off enforce the
  // limits.
  // The nominal values include the tangential limits: a floor above them would plan laws that
  // the tangential interval cannot follow (they overshoot the feed cap, or brake so hard that the
  // release comes too late to stop), and the back-off would find no step to brake from.
  double nominal = o_.tangential_jerk_mm_s3,
         nominal_acceleration = o_.tangential_acceleration_mm_s2;
  for (int i = 0; i < n_; ++i) {
    if (std::abs(g[i]) < 1e-9) continue;
    nominal = std::min(nominal, limits_[i].j / std::abs(g[i]));
    nominal_acceleration = std::min(nominal_acceleration, limits_[i].a / std::abs(g[i]));
  }
  if (!std::isfinite(nominal)) nominal = 1e15;
  e.jerk = std::clamp(std::min(up, down), 0.25 * nominal, nominal);
  // The same floor for the acceleration, whose centripetal part can take a whole axis limit.
  if (std::isfinite(nominal_acceleration)) {
    e.acceleration = std::max(e.acceleration, 0.25 * nominal_acceleration);
  }
  if (!std::isfinite(e.acceleration)) e.acceleration = 1e12;
  return e;
}

// The largest next acceleration in [lo, a_hi] from which the stop law brings the feed down to
// `feed` (with zero acceleration) no later than arc length `at`: the end of the path (feed 0) or
// a slow point. The law for the feed's excess over `feed` is the stop law, so the distance is the
// stop distance of the excess plus `feed` times its periods. Returns a_hi when it already does, lo
// when even lo does not, unless the law arrives with an acceleration cap up to `give` times
// `acceleration`: then the largest a it arrives with under the least such cap.
double Planner::ArriveBy(const History& h, double a_hi, double jerk, double acceleration, double at,
                         double feed, double give) const {
  const double s0 = h.p0->s, v0 = (s0 - h.p1->s) / dt_;
  const double a0 = (v0 - (h.p1->s - h.p2->s) / dt_) / dt_;
  const double release_jerk = jerk * kReleaseJerkFraction;
  // Planned with the softer law, so that following it leaves headroom for rounding. Monotone in
  // a: more braking, less reach. A stop to the end of the path that the law cannot bring to rest
  // reaches where its velocity turns (StopReach): counted short of the end instead, it let the
  // motion arrive there still braking, and back-offs replaced the approach period by period.
  // (`cap`: the law's acceleration cap.)
  const auto reach = [&](double a, double cap) {
    const double v = v0 + a * dt_;
    return s0 + v * dt_ + StopReach(v, a, release_jerk, cap * kReleaseJerkFraction, dt_, feed);
  };
  double hi = a_hi, f_hi = reach(hi, acceleration) - at;
  if (!(f_hi > 0.0)) return a_hi;
  // The hardest braking the jerk allows without the feed turning back, then the cap.
  const double floor = std::max(a0 - jerk * dt_, -v0 / dt_);
  double lo = std::max(floor, -acceleration);
  double f_lo = reach(lo, acceleration) - at;
  if (f_lo > 0.0) {
    // Cannot arrive in time even braking hardest. Where a cap a little higher lands the state,
    // brake with the least such cap; else brake hardest.
    const auto arrives = [&](double cap) { return reach(std::max(floor, -cap), cap) <= at; };
    double fails = acceleration, lands = std::min(give * acceleration, -floor);
    if (!(lands > fails) || !arrives(lands)) return lo;
    for (int k = 0; k < 40 && lands - fails > 1e-9 * lands; ++k) {
      const double mid = 0.5 * (fails + lands);
      (arrives(mid) ? lands : fails) = mid;
    }
    return ArriveBy(h, a_hi, jerk, lands, at, feed);
  }
  // Braking to the point follows the stop law, so its next acceleration is nearly the answer:
  // bracket it tightly before the search (a few evaluations instead of dozens).
  const double guess = StopAcceleration(std::max(v0 - feed, 0.0), a0, release_jerk,
                                        acceleration * kReleaseJerkFraction, dt_);
  const double delta = 1e-7 * (std::abs(guess) + jerk * dt_);
  for (const double g : {guess, guess - delta, guess + delta}) {
    if (!(g > lo && g < hi)) continue;
    const double f_g = reach(g, acceleration) - at;
    if (f_g <= 0.0) {
      lo = g, f_lo = f_g;
    } else {
      hi = g, f_hi = f_g;
    }
  }
  // The largest a with reach(a) <= at: Illinois regula falsi, bisection where reach is -inf. There,
  // an acceleration known to 1e-9 of the law's jerk step moves positions by far less than their
  // rounding: stop there.
  int side = 0;
  const auto tight = [&] {
    return std::isfinite(f_lo) ? 1e-12 * (1.0 + std::abs(hi)) : 1e-9 * (std::abs(hi) + jerk * dt_);
  };
  for (int k = 0; k < 60 && hi - lo > tight(); ++k) {
    double mid = std::isfinite(f_lo) ? lo + (hi - lo) * (-f_lo) / (f_hi - f_lo) : 0.5 * (lo + hi);
    if (!(mid > lo && mid < hi)) mid = 0.5 * (lo + hi);
    const double f_mid = reach(mid, acceleration) - at;
    if (f_mid <= 0.0) {
      lo = mid, f_lo = f_mid;
      if (side == -1) f_hi *= 0.5;
      side = -1;
    } else {
      hi = mid, f_hi = f_mid;
      if (side == 1 && std::isfinite(f_lo)) f_lo *= 0.5;
      side = 1;
    }
    if (f_lo > -1e-12 && f_lo <= 0.0) break;
  }
  return lo;
}

const std::vector<std::pair<double, double>>* Planner::SlowCurve(const SlowPoint& point,
                                                                 const Step& near) {
  auto [it, added] = curves_.try_emplace(point.s);
  auto& curve = it->second;
  if (added) {
    VpopOptions o = o_;
    o.start_feed_mm_s = std::min(point.feed_mm_s, o_.feed_mm_s);
    o.commit_horizon = 64;
    o.previous_q = near.q;
    o.progress = nullptr;  // a backward plan is no progress of this one
    const ReversedPath reversed(path_, point.s);
    BackwardCurve sink(point.s, o.start_feed_mm_s, o_.feed_mm_s, dt_);
    try {
      Planner backward(reversed, machine_, o, sink);
      const VpopSummary done = backward.Run();
      summary_.evaluations += done.evaluations;
      curve = sink.Take();
    } catch (const Error&) {
      curve.clear();  // the law alone then brakes for this point
    }
  }
  return curve.empty() ? nullptr : &curve;
}

// The soft upper bound of the look-ahead laws: approach the feed cap without overshoot, pass the
// path's slow points no faster than their feed, and stop at the end of the path.
std::pair<double, LimiterId> Planner::LookAhead(const History& h, const Effective& e,
                                                double a_cap) {
  const double s0 = h.p0->s, v0 = (s0 - h.p1->s) / dt_;
  const double a0 = (v0 - (h.p1->s - h.p2->s) / dt_) / dt_;
  const double jerk = e.jerk * kLawMargin, acceleration = e.acceleration * kLawMargin;
  double a_hi =
      std::min(MaxAccelerationUnderCap(v0, e.feed, jerk * kReleaseJerkFraction, dt_), acceleration);
  LimiterId by{Limiter::kFeedLookAhead, -1};
  // Skip the stop laws for points farther than any stop from the fastest next state.
  const double a_pos = std::clamp(a_hi, 0.0, std::max(a0, 0.0) + jerk * dt_);
  const double v_top = v0 + a_pos * dt_ + ReleaseGain(a_pos, jerk, dt_);
  const double t_stop =
      v_top / acceleration + 2.0 * std::sqrt(v_top / jerk) + a_pos / jerk + 4.0 * dt_;
  const double horizon = s0 + v_top * (t_stop + dt_);
  // Slow points: the backward limit, the mirror image of accelerating away from the point, is
  // one more bound on the next step (the step may not be faster than the limit where it ends);
  // where it could not be planned, the stop law brakes for the point instead.
  double curve_target = INFINITY;
  const double reach = s0 + 2.0 * (horizon - s0) + o_.feed_mm_s * dt_;
  path_.Reach(reach);
  if (!length_) length_ = path_.Length();
  // The look-ahead planner's profile holds the slow points; the paper's planner plans their
  // backward limits here.
  const auto slow = profile_ ? std::span<const SlowPoint>() : path_.SlowPoints();
  for (auto it = std::upper_bound(slow.begin(), slow.end(), s0,
                                  [](double s, const SlowPoint&p) { return s < p.s; });
       it != slow.end() && it->s < reach; ++it) {
    if (length_ && it->s >= *length_) break;
    const auto* curve = SlowCurve(*it, *h.p0);
    if (!curve) {
      if (it->s >= horizon) continue;
      const double a = ArriveBy(h, a_hi, jerk, acceleration, it->s, it->feed_mm_s);
      if (a < a_hi) a_hi = a, by = {Limiter::kSlowPointLookAhead, -1};
      continue;
    }
    const auto limit = [curve](double s) {  // the feed allowed for a period ending at s
      if (s <= curve->front().first) return std::numeric_limits<double>::infinity();
      if (s >= curve->back().first) return curve->back().second;
      const auto hi = std::upper_bound(
          curve->begin(), curve->end(), s,
          [](double x, const std::pair<double, double>& p) { return x < p.first; });
      const auto lo = hi - 1;
      const double t = (s - lo->first) / (hi->first - lo->first);
      return lo->second + t * (hi->second - lo->second);
    };
    double lo = s0, hi = s0 + o_.feed_mm_s * dt_;
    if (hi - s0 <= limit(hi) * dt_) continue;
    for (int k = 0; k < 60 && hi - lo > 1e-13 * (1.0 + std::abs(hi)); ++k) {
      const double mid = 0.5 * (lo + hi);
      if (mid - s0 <= limit(mid) * dt_) {
        lo = mid;
      } else {
        hi = mid;
      }
    }
    curve_target = std::min(curve_target, lo);
  }
  if (length_ && horizon >= *length_) {
    double j_end = jerk, a_end = acceleration, give = 1.0;
    if (profile_) {
      // The stop law with the least capacity the axes give the path before its end (the law
      // lands exactly at rest; the capacity at this point alone can be more than the end has).
      j_end = std::min(j_end, profile_->MinJerkCap(s0, *length_) * kLawMargin);
      a_end = std::min(a_end, profile_->MinAccelerationCap(s0, *length_) * kLawMargin);
      // Those least caps, and the symmetric estimate of this point's, can fall short of a state
      // the profile handed over by a hair, while the axes give more: the profile braked the
      // head-table pass at -47 mm/s^2 into a law capped at -41.2. Braking only at the cap, the
      // motion arrived at the end still braking, where holding still needs a rotary axis' jerk
      // just over its limit, and the back-off replaced the landing period by period (96
      // back-offs, half that pass' planning). So the law may brake a little harder than its cap
      // where that lands it (the exact step holds the axes to their limits). Where the caps fall
      // far short, as where the least ahead is a singularity's, the profile, which knows the
      // capacity along the way, is the better guide.
      give = kEndLawGive;
    }
    const double top = std::min(a_hi, a_cap);
    const double a = ArriveBy(h, top, j_end, a_end, *length_, 0.0, give);
    if (a < top) a_hi = a, by = {Limiter::kEndLookAhead, -1};
  }
  const double target = s0 + (v0 + a_hi * dt_) * dt_;
  if (curve_target < target) return {curve_target, {Limiter::kSlowPointLookAhead, -1}};
  return {target, by};
}

// The feasible s in [lo, hi] nearest to `target`, found with exact evaluations: a linear model of
// q(s) through the last infeasible evaluation proposes a point a hair inside the model's feasible
// interval; once a feasible point is known, regula falsi on the violated constraint closes in.
bool Planner::Solve(const History& h, const Box& box, double lo, double hi, double target,
                    Step* out, LimiterId* by) {
  struct Miss {
    double worst = 0.0;  // in units of the axis band; <= 0: feasible
    int axis = -1;
    bool upper = false;
  };
  const auto miss = [&](const Step& x) {
    Miss m;
    for (int i = 0; i < n_; ++i) {
      const double over = (x.q[i] - box.hi[i]) / box.band[i];
      const double under = (box.lo[i] - x.q[i]) / box.band[i];
      if (over > m.worst) m = {over, i, true};
      if (under > m.worst) m = {under, i, false};
    }
    return m;
  };
  const auto signed_miss = [&](const Step& x, const Miss& m) {
    return m.upper ? x.q[m.axis] - box.hi[m.axis] : box.lo[m.axis] - x.q[m.axis];
  };
  // dq/ds at x: the tangent of the quadratic through the two latest steps and x (the chord alone
  // misplaces q by q_ss ds^2 / 2, as much as an axis jerk interval is wide).
  using V = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, kMaxAxes, 1>;
  std::optional<V> tangent;  // Direction(h) probes the path at rest: once per search
  const auto direction = [&]() -> const V& {
    if (!tangent) tangent = Direction(h);
    return *tangent;
  };
  const auto slope = [&](const Step& x) {
    const double s1 = h.p1->s, s0 = h.p0->s, sx = x.s;
    const double tiny = 1e-12 * (1.0 + std::abs(sx));
    if (sx - s0 <= tiny) return V(direction());
    const V d0x = (x.q - h.p0->q) / (sx - s0);
    // At rest: the quadratic through p0 with its tangent, and x.
    if (s0 - s1 <= tiny) return V(2.0 * d0x - direction());
    const V d10 = (h.p0->q - h.p1->q) / (s0 - s1);
    const V d10x = (d0x - d10) / (sx - s1);
    return V(d10 + d10x * ((sx - s1) + (sx - s0)));
  };
  // Where the linear model q(s) = at.q + g (s - at.s) lies in every axis' box, within [lo, hi],
  // and the narrowest axis band in s. False when an axis the model holds still is outside its box.
  struct ModelInterval {
    double lo = 0.0, hi = 0.0, band_s = 0.0;
  };
  const auto model = [&](const Step& at, const V& g, double lo_s, double hi_s, ModelInterval* m) {
    *m = {lo_s, hi_s, std::numeric_limits<double>::infinity()};
    for (int i = 0; i < n_; ++i) {
      if (std::abs(g[i]) < 1e-300) {
        if (at.q[i] > box.hi[i] || at.q[i] < box.lo[i]) return false;
        continue;
      }
      double a = at.s + (box.lo[i] - at.q[i]) / g[i];
      double b = at.s + (box.hi[i] - at.q[i]) / g[i];
      if (a > b) std::swap(a, b);
      m->lo = std::max(m->lo, a);
      m->hi = std::min(m->hi, b);
      m->band_s = std::min(m->band_s, box.band[i] / std::abs(g[i]));
    }
    return true;
  };
  // Which way s must move to repair the miss m at x: +1, -1 (0: it cannot).
  const auto repair = [&](const Step& x, const Miss& m) {
    const double g = slope(x)[m.axis];
    if (g == 0.0) return 0;
    return (m.upper ? -1 : 1) * (g > 0.0 ? 1 : -1);
  };

  Step x;
  Evaluate(*h.p0, target, &x);
  Miss mx = miss(x);
  if (mx.worst <= 0.0) {
    *out = x;
    return true;
  }
  Step bad = x;
  Miss bad_miss = mx;
  int bad_dir = repair(bad, bad_miss);
  if (bad_dir == 0) return false;
  std::optional<Step> good;
  double far = std::numeric_limits<double>::quiet_NaN();  // infeasible, beyond the feasible set
  int kept = 0;  // times `good` was kept by regula falsi in a row (Illinois)
  for (int k = 1; k < o_.max_search_evaluations; ++k) {
    double next;
    if (good) {
      const double mg = signed_miss(*good, bad_miss);
      const double mb = signed_miss(bad, bad_miss);
      if (-mg <= 1e-4 * box.band[bad_miss.axis]) break;
      if (std::abs(bad.s - good->s) <= 1e-14 * (1.0 + std::abs(bad.s))) break;
      const double w = kept >= 2 ? 0.5 : 1.0;
      next = good->s + (bad.s - good->s) * (-mg) / (w * mb - mg);
      const double a = std::min(good->s, bad.s), b = std::max(good->s, bad.s);
      if (!(next > a && next < b)) next = 0.5 * (a + b);
    } else if (!std::isnan(far)) {
      next = 0.5 * (bad.s + far);
    } else {
      ModelInterval m;
      if (!model(bad, slope(bad), lo, hi, &m)) return false;
      if (m.lo > m.hi && bad_dir < 0) {
        // The linear model through `bad` leaves no s for all axes at once: `bad` is too far from
        // the feasible set for it (a tight curve, where q(s) bends by more than an axis band
        // between them). Model from the last step instead, with the path's direction there, and
        // look no farther than `bad`.
        if (!model(*h.p0, direction(), lo, std::min(hi, bad.s), &m)) return false;
      }
      if (m.lo > m.hi) return false;
      const double mlo = m.lo, mhi = m.hi, band_s = m.band_s;
      next = std::clamp(target, mlo, mhi);
      const double inset = std::min(1e-6 * band_s, 0.5 * (mhi - mlo));
      if (next >= mhi) next = mhi - inset;
      if (next <= mlo) next = mlo + inset;
      if ((next - bad.s) * bad_dir <= 0.0) {
        // The model disagrees with the repair direction: take a cautious step that way.
        next = bad.s + bad_dir * std::max(std::abs(next - bad.s), 1e-3 * band_s);
      }
      next = std::clamp(next, lo, hi);
      if (next == bad.s) return false;
    }
    Evaluate(*h.p0, next, &x);
    mx = miss(x);
    if (mx.worst <= 0.0) {
      if (!good || std::abs(x.s - target) < std::abs(good->s - target)) good = x;
      kept = 0;
    } else if (good) {
      // Regula falsi: keep the bracket [good, bad] around the boundary.
      if ((x.s - good->s) * (bad.s - good->s) > 0.0) {
        bad = x;
        bad_miss = mx;
        ++kept;
      }
    } else {
      const int dir = repair(x, mx);
      if (dir == bad_dir && (x.s - bad.s) * bad_dir > 0.0) {
        bad = x;  // still on the target's side: walk on
        bad_miss = mx;
      } else if (dir == 0) {
        return false;
      } else {
        far = x.s;  // past the feasible set, if there is one between
      }
    }
  }
  if (!good) return false;
  *out = *good;
  *by = {bad_miss.upper ? box.hi_kind[bad_miss.axis] : box.lo_kind[bad_miss.axis],
         static_cast<std::int8_t>(bad_miss.axis)};
  return true;
}

double Planner::ProfileCap(const History& h, double lo, double hi, double target, double* floored,
                           bool* refused) {
  const double s0 = h.p0->s, v0 = (s0 - h.p1->s) / dt_;
  const double a0 = (v0 - (h.p1->s - h.p2->s) / dt_) / dt_;
  // The next step as a function of its path jerk j (backward differences), and the slack of the
  // continuous state it ends in: the cubic through the last four arc lengths has, at its end, feed
  // v + a dt / 2 + j dt^2 / 3 and acceleration a + j dt.
  const double dt3 = dt_ * dt_ * dt_;
  const auto step = [&](double j) { return s0 + (v0 + (a0 + j * dt_) * dt_) * dt_; };
  const auto slack = [&](double x) {
    const double v = (x - s0) / dt_, a = (v - v0) / dt_, j = (a - a0) / dt_;
    return profile_->Slack(x, v + a * dt_ / 2.0 + j * dt_ * dt_ / 3.0, a + j * dt_);
  };
  // The jerks the axes can give the path here (where the path turns fast, the tangential jerk
  // that holds the axes within their limits may be many times any axis limit).
  double jlo, jhi;
  profile_->JerkRange(s0, v0 + a0 * dt_ / 2.0, a0, &jlo, &jhi);
  // Only the jerks that keep the continuous state's acceleration, a0 + 2 j dt, within what the
  // axes allow: where the jerk limits are high against the acceleration's (J dt > A, as on
  // machines imported from LinuxCNC) the jerk range spans accelerations far outside the viable
  // set, the walk below stepped over every viable state in one stride and took the motion to
  // rest, period after period (a zigzag crawled at 0.35 mm/s: 319 s instead of 3.2 s).
  if (double alo, ahi;
      profile_->AccelerationRange(s0, v0, &alo, &ahi) && 2.0 * dt_ * (jhi - jlo) > ahi - alo) {
    const double lo_a = (alo - a0) / (2.0 * dt_), hi_a = (ahi - a0) / (2.0 * dt_);
    if (std::max(jlo, lo_a) <= std::min(jhi, hi_a)) {
      jlo = std::max(jlo, lo_a), jhi = std::min(jhi, hi_a);
    }
  }
  const double width = std::max(jhi - jlo, 1.0);
  // Never a state braked so hard that its deceleration cannot be released before the feed
  // reaches zero (the viable set's lower side, which the look-ahead's upper boundary does not
  // hold), whatever asks for it.
  const double release_jerk = profile_->JerkCap(s0) * kReleaseJerkFraction;
  const auto releasable = [&](double x) {
    const double v = (x - s0) / dt_, a = (v - v0) / dt_;
    return v >= ReleaseGain(-a, release_jerk, dt_);
  };
  // Only the jerks the axes allow (give or take the gap between the continuous model and the
  // sampled motion): the exact step would not take a step outside them.
  const double give = kJerkGive * width;
  const double top = std::min(hi, step(jhi + give)), bottom = std::max(lo, step(jlo - give));
  // The least releasable step between them (a longer step brakes less); none: the target stands.
  double least = bottom;
  if (!releasable(top)) {
    least = INFINITY;
  } else if (!releasable(bottom)) {
    double good = top, bad = bottom;
    for (int k = 0; k < 50 && good - bad > 1e-13 * (1.0 + std::abs(good)); ++k) {
      const double mid = 0.5 * (good + bad);
      if (releasable(mid)) {
        good = mid;
      } else {
        bad = mid;
      }
    }
    least = good;
  }
  if (floored && target < least && std::isfinite(least)) *floored = target = least;
  double x_bad = std::min(target, top);
  double f_bad = slack(x_bad);
  if (f_bad >= 0.0 || least >= x_bad) return x_bad;
  // Walk down in jerk until the state is viable, then close in on the boundary. The walk's steps
  // are a quarter of the jerks the axes allow, and where nothing is viable (a refusal; half of
  // the calls on the trident) the steps either side of the walk's best state are halved: steps of
  // an eighth all the way made the slacks a quarter of the trident's planning, for the same
  // motion times within their spread.
  const double floor = least;
  double x_good = x_bad, f_good = f_bad;
  const double j_bad = (x_bad - s0) / dt3 - (v0 / (dt_ * dt_) + a0 / dt_);
  const auto at = [&](double k) { return std::max(floor, step(j_bad - width * k / 4.0)); };
  std::array<double, 9> xs{x_bad}, fs{f_bad};  // the walk's states (k = 0 is the target's)
  int walked = 0, k_best = 0;
  bool found = false;
  for (int k = 1; k <= 8; ++k) {
    const double x = at(k);
    const double f = slack(x);
    if (f >= 0.0) {
      x_good = x, f_good = f;
      found = true;
      break;
    }
    xs[static_cast<std::size_t>(k)] = x, fs[static_cast<std::size_t>(k)] = f;
    walked = k;
    if (f > fs[static_cast<std::size_t>(k_best)]) k_best = k;
    x_bad = x, f_bad = f;
    if (x <= floor) break;
  }
  if (!found) {
    double best = xs[static_cast<std::size_t>(k_best)],
           f_best = fs[static_cast<std::size_t>(k_best)];
    // The half steps below the walked state before the best one and below the best one.
    for (const int above : {k_best - 1, k_best}) {
      if (above < 0 || above + 1 > walked) continue;
      const double x = at(above + 0.5);
      const double f = slack(x);
      if (f >= 0.0) {
        x_good = x, f_good = f;
        x_bad = xs[static_cast<std::size_t>(above)], f_bad = fs[static_cast<std::size_t>(above)];
        found = true;
        break;
      }
      if (f > f_best) f_best = f, best = x;
    }
    if (!found) {
      // Nothing viable: the state closest to the boundary (a refusal; the exact step still holds
      // every limit).
      if (refused) *refused = true;
      return best;
    }
  }
  int side = 0;
  for (int k = 0; k < 40 && x_bad - x_good > 1e-12 * (1.0 + std::abs(x_bad)); ++k) {
    double x = x_good + (x_bad - x_good) * f_good / (f_good - f_bad);
    if (!(x > x_good && x < x_bad)) x = 0.5 * (x_good + x_bad);
    const double f = slack(x);
    if (f >= 0.0) {
      x_good = x, f_good = f;
      if (side == -1) f_bad *= 0.5;
      side = -1;
    } else {
      x_bad = x, f_bad = f;
      if (side == 1) f_good *= 0.5;
      side = 1;
    }
    if (f_good < 1e-9 * (1.0 + std::abs(v0))) break;
  }
  return x_good;
}

bool Planner::Produce(const History& h, Mode mode, Step* out) {
  const Interval t = Tangential(h);
  if (t.lo > t.hi) return false;
  Box box;
  if (!MakeBox(h, &box)) return false;
  const Effective e = Available(h, box, t);
  double target;
  LimiterId by;
  if (mode == Mode::kGreedy) {
    const auto [soft, soft_by] = LookAhead(h, e);
    target = t.hi;
    by = t.hi_by;
    if (soft < target) {
      target = std::max(soft, t.lo);
      by = soft > t.lo ? soft_by : t.lo_by;
    }
    if (profile_ && !AtRest(h) && !Landing(h, by.kind)) {
      // (From rest, the first step is a jerk's worth: it can always be braked again. Over the
      // last stretch of the path, LookAheadOptions::law_zone_mm, the law lands: the profile's
      // boundary where that stretch begins holds the states the law lands from.)
      bool refused = false;
      const double cap = ProfileCap(h, t.lo, t.hi, target, &target, &refused);
      if (refused) ++summary_.profile_refusals;
      if (cap < target) {
        target = std::max(cap, t.lo);
        by = {Limiter::kProfileLookAhead, -1};
      }
    }
    if (length_ && h.p0->s >= *length_ - o_.end_tolerance_mm &&
        std::abs(target - h.p0->s) <= 1e-12 * (1.0 + std::abs(h.p0->s))) {
      // Arrived, give or take a rounding step: come to rest (else the end law creeps a last ulp
      // per period towards the end, for ever).
      target = h.p0->s;
    }
    if (AtRest(h) && h.p0->s == last_stuck_s_) {
      // Back at rest where the last step from rest could not be carried on: the look-ahead laws
      // overreach where one period is long against the path (a 10 ms period, 0.2 mm blocks and
      // a tight corner 0.8 mm ahead: the first step from rest, 0.5 mm at the jerk limit, takes
      // the motion into the corner too fast). Step by half as much each time, down to a step
      // from which the motion gets through.
      target = std::max(t.lo, h.p0->s + std::ldexp(target - h.p0->s, -(stuck_count_ + 1)));
      by = {Limiter::kBackOff, -1};
    }
  } else {
    const double s0 = h.p0->s, v0 = (s0 - h.p1->s) / dt_;
    const double a0 = (v0 - (h.p1->s - h.p2->s) / dt_) / dt_;
    const double a =
        StopAcceleration(v0, a0, e.jerk * kLawMargin, e.acceleration * kLawMargin, dt_,
                         mode == Mode::kStop ? kProofReleaseFraction : kReleaseJerkFraction);
    target = s0 + (v0 + a * dt_) * dt_;
    if (std::abs(target - s0) <= 1e-15 * (1.0 + std::abs(s0))) target = s0;
    target = std::clamp(target, t.lo, t.hi);
    by = {Limiter::kBackOff, -1};
    if (mode == Mode::kStop) {
      // Planned blind, the law brakes past what lies ahead: from full feed before a corner, or
      // before the end of a short path, it reaches the corner or the end still fast, and the
      // proof fails where the greedy step, which slows for them, gets through (on the tilted
      // head-table pass 830 of 834 proofs under a 256-period horizon failed at the path's end).
      // No faster than the greedy step's own caps, then: the end law, the viable feeds ahead.
      const auto [soft, soft_by] = LookAhead(h, e, a);
      target = std::max(std::min(target, soft), t.lo);
      const Limiter binding = soft <= target ? soft_by.kind : Limiter::kBackOff;
      if (profile_ && !AtRest(h) && !Landing(h, binding)) {
        target = std::max(std::min(target, ProfileCap(h, t.lo, t.hi, target)), t.lo);
      }
    }
  }
  LimiterId axis_by = by;
  if (!Solve(h, box, t.lo, t.hi, target, out, &axis_by)) return false;
  out->limiter = out->s == target ? by : axis_by;
  if (out->s == h.p0->s && AtRest(h)) out->limiter = {Limiter::kRest, -1};
  return true;
}

// The look-ahead held the state at step j viable, yet the exact step finds no step from it: the
// continuous model missed something there. Plan that stretch more cautiously and go back to the
// latest step the repaired look-ahead holds viable (one still open). False when the same place
// has been repaired too often or no step can be gone back to: the caller backs off instead.
bool Planner::Repair(long j) {
  if (summary_.profile_repairs >= kMaxRepairs) return false;
  const double s = At(j).s;
  const double v = (s - At(j - 1).s) / dt_;
  if (std::abs(s - last_repair_s_) <= kRepairNeighbourhood(v, dt_)) {
    if (++repairs_here_ > kMaxRepairsHere) return false;
  } else {
    last_repair_s_ = s;
    repairs_here_ = 1;
  }
  // Reach: the stretch a brake from this feed covers, at least a few periods of it.
  const double reach = std::max(50.0 * v * dt_, 0.05);
  profile_->Repair(s, reach);
  // Not below the last step whose stop to rest is proven: that proof runs through the steps
  // after it, which going back would discard.
  const long first = std::max({committed_, base_ + 3, safe_});
  for (long m = j - 1; m >= first; --m) {
    const Step& p0 = At(m);
    const double s1 = At(m - 1).s, s2 = At(m - 2).s, s3 = At(m - 3).s;
    const double v0 = (p0.s - s1) / dt_, v1 = (s1 - s2) / dt_, v2 = (s2 - s3) / dt_;
    const double a0 = (v0 - v1) / dt_, a1 = (v1 - v2) / dt_, jj = (a0 - a1) / dt_;
    if (profile_->Slack(p0.s, v0 + a0 * dt_ / 2.0 + jj * dt_ * dt_ / 3.0, a0 + jj * dt_) >= 0.0) {
      steps_.resize(static_cast<std::size_t>(m - base_ + 1));
      hint_ = std::min(hint_, m);
      ++summary_.profile_repairs;
      return true;
    }
  }
  return false;
}

// Runs the brake law from step m (steps after m ignored) until rest. On success, `first` is its
// first step.
bool Planner::Brake(long m, Step* first, double pass_s, long margin, std::vector<Step>* record,
                    Mode law) {
  ++summary_.brake_tests;
  if (record) record->clear();
  // Continue the last run that got through when it started at or before m and the steps since
  // are its own (the back-off keeps the first step of its run: the next test starts there).
  BrakeRun* run = &scratch_run_;
  long p = 0;  // position in run->steps of the step after m
  if (o_.reuse_brake_runs && last_run_.Continues(*this, m, law)) {
    run = &last_run_;
    p = m - last_run_.from;
  } else {
    scratch_run_.Start(*this, m, law);
  }
  const auto through = [&] {
    if (run == &scratch_run_) std::swap(last_run_, scratch_run_);
    return true;
  };
  Step ring[3] = {At(m - 2), At(m - 1), At(m)};
  int newest = 2;
  long beyond = 0;
  const long max_steps = 10000000;
  for (long k = 0; k < max_steps; ++k, ++p) {
    const History h{&ring[(newest + 1) % 3], &ring[(newest + 2) % 3], &ring[newest]};
    if (AtRest(h)) {
      if (k == 0) {  // already at rest: the brake holds still
        *first = *h.p0;
        first->limiter = {Limiter::kRest, -1};
      }
      return through();
    }
    if (h.p0->s > pass_s && ++beyond > margin) return through();
    Step next;
    if (p < static_cast<long>(run->steps.size())) {
      next = run->steps[static_cast<std::size_t>(p)];
    } else {
      if (run->failed || !Produce(h, law, &next)) {
        run->failed = true;
        return false;
      }
      next.limiter = {Limiter::kBackOff, -1};
      run->steps.push_back(next);
    }
    if (k == 0) *first = next;
    if (record) record->push_back(next);
    newest = (newest + 1) % 3;
    ring[newest] = next;
  }
  return false;
}

// The dichotomy of §2.3: the latest step m from which the brake law gets through, found by
// galloping back from the failure and bisecting. A brake test counts as through once it has
// carried the motion past the failed arc length with a margin (a hint that m is safe); only when
// no step after the last hint gets through are full stops to rest required, down to the last step
// from which a stop is proven.
void Planner::BackOff(long failed) {
  ++summary_.back_offs;
  const long hi = failed - 1;
  const double pass_s = At(hi).s;
  // The stop from stop_from_ is proven and kept (stop_). Proven with kStop, it is not run again:
  // that law reads the look-ahead, which may have changed since.
  const bool kept = safe_law_ == Mode::kStop;
  const auto brake = [&](long m, double pass, long margin, Step* first) {
    if (kept && m == stop_from_ && !std::isfinite(pass)) {
      if (stop_.empty()) {
        *first = At(m);
        first->limiter = {Limiter::kRest, -1};
      } else {
        *first = stop_.front();
      }
      return true;
    }
    return Brake(m, first, pass, margin);
  };
  const auto search = [&](long lo, double pass, long margin, long* good, Step* first) {
    long bad = -1;
    for (long stride = 1, m = hi;; stride *= 2) {
      if (m <= lo) m = lo;
      Step candidate;
      if (brake(m, pass, margin, &candidate)) {
        *good = m;
        *first = candidate;
        break;
      }
      bad = m;
      if (m == lo) return false;
      m = hi - stride;
    }
    while (bad > *good + 1) {
      const long mid = *good + (bad - *good) / 2;
      Step candidate;
      if (brake(mid, pass, margin, &candidate)) {
        *good = mid;
        *first = candidate;
      } else {
        bad = mid;
      }
    }
    return true;
  };
  long good = -1;
  Step first;
  const long margin = std::max<long>(32, 2 * (hi - hint_));
  if (!search(std::max(hint_, safe_), pass_s, margin, &good, &first)) {
    const long floor = std::max(safe_, committed_ - 1);
    if (!search(floor, INFINITY, 0, &good, &first)) {
      FailAt(At(floor),
             "no stop to rest within the limits exists from here (this should not "
             "happen: please report it with the job)");
    }
    if (kept && good == stop_from_) {
      // The rest of the kept stop is the stop from the next step.
      if (!stop_.empty()) stop_.erase(stop_.begin());
      stop_from_ = good + 1;
    } else {
      safe_law_ = Mode::kBrake;
    }
    safe_ = good + 1;
  }
  // Keep steps up to `good`, brake one period there, and go on at s_max.
  steps_.resize(static_cast<std::size_t>(good - base_ + 1));
  const History h = HistoryAt(good);
  if (AtRest(h) && first.s == h.p0->s) {
    // Stuck at rest: no step forward is feasible from here.
    if (h.p0->s == last_stuck_s_) {
      if (++stuck_count_ > kMaxStuckRetries) {
        Box box;
        const bool boxed = MakeBox(h, &box);
        const std::string left =
            length_ ? fmt::format(" ({} mm before the end)", *length_ - h.p0->s) : std::string();
        FailAt(*h.p0, (boxed ? "no step forward respects the axis limits even from rest (the "
                               "path needs an axis to jump: a singularity or a position "
                               "discontinuity)"
                             : "the axis limits leave no position for the next step") +
                          left);
      }
    } else {
      last_stuck_s_ = h.p0->s;
      stuck_count_ = 0;
    }
  }
  steps_.push_back(first);
  hint_ = good + 1;
}

void Planner::Commit(long upto) {
  upto = std::min(upto, Last());
  for (long g = committed_; g <= upto; ++g) {
    const Step& step = At(g);
    sink_.Accept(ToSetpoint(step, g));
    ++summary_.setpoints;
    ++summary_.limited_by[static_cast<int>(step.limiter.kind)];
  }
  committed_ = std::max(committed_, upto + 1);
  if (sink_.WantsStops()) OfferStop();
  // Keep the three latest committed steps: the history of the first open one.
  while (base_ < committed_ - 3) {
    steps_.pop_front();
    ++base_;
  }
  const double behind = steps_.front().s;
  path_.Release(behind);
  curves_.erase(curves_.begin(), curves_.lower_bound(behind));
}

// The stop from the last step handed over: the open steps up to the last proven-safe one (they
// respect every limit), then the brake law from there to rest, then the rest held for two periods.
// Past the last proven-safe step only the end of the path is handed over, already at rest.
void Planner::OfferStop() {
  std::vector<Setpoint> stop;
  const long last = committed_ - 1;
  if (last <= safe_) {
    for (long g = committed_; g <= safe_; ++g) stop.push_back(ToSetpoint(At(g), g));
    if (stop_from_ != safe_) {
      Step first;
      if (!Brake(safe_, &first, INFINITY, 0, &trial_stop_, safe_law_)) {
        FailAt(At(safe_),
               "the stop law failed from a step where it had been proven (this should not "
               "happen: please report it with the job)");
      }
      stop_.swap(trial_stop_);
      stop_from_ = safe_;
    }
    long index = safe_;
    for (const Step& step : stop_) stop.push_back(ToSetpoint(step, ++index));
  }
  Setpoint rest = stop.empty() ? ToSetpoint(At(last), last) : stop.back();
  rest.limiter = {Limiter::kRest, -1};
  for (int k = 0; k < 2; ++k) {
    ++rest.index;
    stop.push_back(rest);
  }
  sink_.AcceptStop(stop);
}

VpopSummary Planner::Run() {
  length_ = path_.Length();
  Step start;
  start.state = path_.Start();
  const PathSample s0 = path_.At(start.state, 0.0);
  start.state = s0.state;
  start.s = 0.0;
  const InverseResult r =
      machine_.Inverse(s0.pose, o_.previous_q ? &*o_.previous_q : nullptr, &start.q);
  if (r.status != InverseStatus::kOk) FailAt(start, DescribeInverseFailure(machine_, r));
  if (o_.previous_q && o_.previous_q->size() == start.q.size()) {
    // A path that starts within a hair of where the machine holds (the previous path ended at
    // rest within its end tolerance; the hair segments join within, TurnShift) starts from
    // there: a first step measured from positions the machine is not at would add that hair,
    // over dt^3, to its jerk.
    const std::optional<AxisVector> shift = TurnShift(machine_, *o_.previous_q, start.q);
    if (shift && shift->isZero()) start.q = *o_.previous_q;
  }
  start.limiter = {Limiter::kStart, -1};
  if (o_.start_feed_mm_s > 0.0) {
    // The two periods before the start, on the path behind it, at the start feed.
    for (const int k : {2, 1}) {
      Step behind;
      Evaluate(start, -k * o_.start_feed_mm_s * dt_, &behind);
      behind.s = -k * o_.start_feed_mm_s * dt_;
      behind.limiter = start.limiter;
      steps_.push_back(behind);
    }
    base_ = -2;
    committed_ = 0;
  }
  steps_.push_back(start);
  if (o_.planner == PlannerKind::kLookAhead) {
    LookAheadLimits pl;
    pl.feed = o_.feed_mm_s;
    pl.tangential_acceleration =
        std::isfinite(o_.tangential_acceleration_mm_s2) ? o_.tangential_acceleration_mm_s2 : 1e12;
    pl.tangential_jerk = std::isfinite(o_.tangential_jerk_mm_s3) ? o_.tangential_jerk_mm_s3 : 1e15;
    for (int i = 0; i < n_; ++i) {
      pl.v[i] = limits_[i].v;
      pl.a[i] = limits_[i].a;
      pl.j[i] = limits_[i].j;
    }
    profile_.emplace(path_, machine_, pl, o_.look_ahead);
  }
  const long check_every =
      static_cast<long>(std::min<std::size_t>(o_.commit_horizon / 4, 1L << 40));

  for (;;) {
    const long j = Last();
    const History h = HistoryAt(j);
    if (Finished(h)) break;
    if (static_cast<double>(j) * dt_ > o_.max_motion_s) {
      FailAt(*h.p0, fmt::format("the motion has not ended after {:g} s, the most a path may take "
                                "(the feed is {:.3g} mm/s here)",
                                o_.max_motion_s, (h.p0->s - h.p1->s) / dt_));
    }
    if (profile_) {
      profile_->Advance(h.p0->s, h.p0->state, h.p0->q, At(std::max(base_, committed_ - 3)).s);
      summary_.profile_grid_points = profile_->GridPoints();
    }
    if (o_.progress && (j & 255) == 0) o_.progress(h.p0->s, static_cast<double>(j) * dt_);
    Step next;
    if (Produce(h, Mode::kGreedy, &next)) {
      steps_.push_back(next);
    } else if (!profile_ || !Repair(j)) {
      BackOff(j + 1);
    }
    if (static_cast<std::size_t>(Last() - committed_) > o_.commit_horizon) {
      // Prove a stop from the newest step so that the old ones can be handed over. The paper's
      // planner backs off from a failed proof at once (and so does each of its slow points'
      // backward plans, which a horizon bounds: its figures depend on it). The look-ahead
      // planner does not: where the path turns, the stop law fails from most states the greedy
      // step passes through (it brakes into the turn), and braking one period after each failed
      // proof slowed every such stretch and cost a thousand brake runs a second. The greedy step
      // goes on, the proof is tried again `check_every` steps later, and only once twice the
      // horizon is open does the planner look back for an earlier step to prove, and, finding
      // none, back off.
      // The stop is kept where a sink wants it or a back-off may reuse it (proven with kStop,
      // BackOff); the paper's law is run again from its three steps where needed.
      const bool keep = sink_.WantsStops() || ProofLaw() == Mode::kStop;
      // The look-ahead planner tries the paper's stop law first: planned blind it needs no
      // look-ahead per step, and on open stretches it proves the stop (on the circle at
      // 300 mm/s the capped law's proofs were a third of the streamed planning). Where it brakes
      // into a turn or past the end and fails, the capped law proves; after k blind failures in
      // a row, the next 2^k - 1 proofs (at most 15) go to the capped law at once.
      const auto prove = [&](long m) {
        std::vector<Step>* record = keep ? &trial_stop_ : nullptr;
        const bool capped = ProofLaw() == Mode::kStop;
        Step first;
        Mode law = Mode::kBrake;
        bool proven = false;
        if (capped && skip_blind_ > 0) {
          --skip_blind_;
        } else {
          proven = Brake(m, &first, INFINITY, 0, record, law);
          if (capped) {
            blind_misses_ = proven ? 0 : blind_misses_ + 1;
            skip_blind_ = proven ? 0 : (1L << std::min(blind_misses_, 4L)) - 1;
          }
        }
        if (!proven && capped) {
          law = Mode::kStop;
          proven = Brake(m, &first, INFINITY, 0, record, law);
        }
        if (!proven) return false;
        ++summary_.stop_proofs;
        if (law == Mode::kBrake) ++summary_.blind_proofs;
        safe_ = hint_ = m;
        safe_law_ = law;
        if (keep) {
          stop_.swap(trial_stop_);
          stop_from_ = safe_;
        }
        return true;
      };
      if (Last() - safe_ >= check_every && (!profile_ || Last() - last_proof_ >= check_every)) {
        last_proof_ = Last();
        if (!prove(Last())) {
          if (!profile_) {
            BackOff(Last() + 1);
          } else if (Last() - committed_ > 2 * static_cast<long>(o_.commit_horizon)) {
            bool proven = false;
            for (long back = 8; !proven && Last() - back > safe_; back *= 2) {
              proven = prove(Last() - back);
            }
            if (!proven) BackOff(Last() + 1);
          }
        }
      }
      Commit(std::min(safe_, Last() - static_cast<long>(o_.commit_horizon) / 2));
      if (sink_.Done()) return summary_;
    }
  }
  // Two more periods at rest so that a reader sees zero velocity and acceleration at the end.
  for (int k = 0; k < 2; ++k) {
    Step rest = steps_.back();
    rest.limiter = {Limiter::kRest, -1};
    steps_.push_back(rest);
  }
  long last_move = 0;
  for (long g = Last(); g > base_; --g) {
    if (At(g).s != At(g - 1).s || At(g).q != At(g - 1).q) {
      last_move = g;
      break;
    }
  }
  summary_.end_s = steps_.back().s;
  Commit(Last());
  summary_.motion_time_s = static_cast<double>(last_move) * dt_;
  return summary_;
}

}  // namespace

namespace {

VpopSummary PlanLeastTime(const PathSource& path, const Machine& machine,
                          const VpopOptions& options, SetpointSink& sink) {
  if (sink.WantsStops() || options.commit_horizon != std::numeric_limits<std::size_t>::max()) {
    throw Error(
        "the least-time planner plans a path whole and cannot stream it; stream with the "
        "'lookahead' or 'vpop' planner");
  }
  // Where the path has slow points (smoothed G1 corners), the faster of the two planners' plans:
  // the look-ahead's continuous model is cautious where a corner turns within a few periods,
  // which `vpop`'s exact back-off is not, and the windows do not always recover that. On curves
  // the look-ahead's plan alone: there it is within 0.65 % of `vpop`'s or faster
  // (bench/machines.py), and `vpop` backs off at nearly every period where the feed is decided by
  // an axis (the circle at 300 mm/s: 0.12x real time).
  path.Reach(std::numeric_limits<double>::infinity());
  const bool corners = !path.SlowPoints().empty();
  VpopOptions o = options;
  o.planner = PlannerKind::kLookAhead;
  VectorSink whole;
  VpopSummary summary = Planner(path, machine, o, whole).Run();
  if (corners) {
    o.planner = PlannerKind::kVpop;
    VectorSink paper;
    const VpopSummary other = Planner(path, machine, o, paper).Run();
    if (other.motion_time_s < summary.motion_time_s) {
      whole = std::move(paper);
      summary = other;
    }
  }

  // The limits the exact step kept (Planner's constructor checked them).
  LeastTimeLimits limits;
  limits.period_s = options.period_s;
  limits.feed = options.feed_mm_s;
  limits.tangential_acceleration = options.tangential_acceleration_mm_s2;
  limits.tangential_jerk = options.tangential_jerk_mm_s3;
  const auto axes = machine.Axes();
  const double dt = options.period_s;
  for (std::size_t i = 0; i < axes.size(); ++i) {
    const Limits l = ExactStepLimits(axes[i], options);
    limits.v[i] = l.v, limits.a[i] = l.a, limits.j[i] = l.j;
  }
  std::vector<PlannedStep> plan;
  plan.reserve(whole.rows.size());
  for (const Setpoint& row : whole.rows) plan.push_back({row.s, row.state, row.q, false});
  const LeastTimeStats stats = ShortenPlan(path, machine, limits, options.least_time, &plan);
  summary.least_time_windows = stats.windows;
  summary.least_time_programs = stats.linear_programs;
  summary.least_time_saved = stats.periods_saved;
  summary.evaluations += stats.evaluations;

  // Hand the shortened plan over; a period the windows kept keeps its limiter.
  summary.limited_by = {};
  long last_move = 0;
  std::size_t kept = 0;  // the look-ahead's row the next kept period matches
  for (std::size_t k = 0; k < plan.size(); ++k) {
    const PlannedStep& p = plan[k];
    LimiterId by{Limiter::kLeastTimeWindow, -1};
    if (!p.refined) {
      while (kept + 1 < whole.rows.size() && whole.rows[kept].s < p.s) ++kept;
      by = whole.rows[kept].limiter;
    }
    sink.Accept(
        {.index = static_cast<long>(k), .s = p.s, .q = p.q, .state = p.state, .limiter = by});
    ++summary.limited_by[static_cast<std::size_t>(by.kind)];
    if (k > 0 && (p.s != plan[k - 1].s || p.q != plan[k - 1].q)) last_move = static_cast<long>(k);
  }
  summary.setpoints = static_cast<long>(plan.size());
  summary.motion_time_s = static_cast<double>(last_move) * dt;
  return summary;
}

}  // namespace

VpopSummary PlanVpop(const PathSource& path, const Machine& machine, const VpopOptions& options,
                     SetpointSink& sink) {
  if (options.planner == PlannerKind::kLeastTime) {
    return PlanLeastTime(path, machine, options, sink);
  }
  Planner planner(path, machine, options, sink);
  return planner.Run();
}

}  // namespace dtis::interp
