#include "dtis/interp/motion_law.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace dtis::interp {

double ReleaseGain(double a, double jerk, double dt) {
  if (!(a > 0.0)) return 0.0;
  const double step = jerk * dt;
  const double n = std::ceil(a / step - 1e-12);
  return dt * ((n - 1.0) * a - step * n * (n - 1.0) / 2.0);
}

namespace {

// MaxAccelerationUnderCap for room = cap - v > 0 and unit = jerk dt^2. On the piece
// a in ((n-1) J dt, n J dt]: v + n dt a - J dt^2 n (n-1) / 2 = cap, and the piece boundaries are at
// room = J dt^2 n (n -+ 1) / 2. The square root only seeds n, the loops settle it exactly (the
// least n >= 1 with unit n (n + 1) / 2 >= room, whatever the seed), so `eight_over_unit` = 8 / unit
// may come precomputed: the stop law's release asks this with one unit a dozen times per stop.
double AccelerationInRoom(double room, double unit, double eight_over_unit, double dt) {
  double n = std::ceil((-1.0 + std::sqrt(1.0 + eight_over_unit * room)) / 2.0);
  n = std::max(n, 1.0);
  while (n > 1.0 && unit * (n - 1.0) * n / 2.0 >= room) n -= 1.0;
  while (unit * n * (n + 1.0) / 2.0 < room) n += 1.0;
  return (room + unit * n * (n - 1.0) / 2.0) / (n * dt);
}

}  // namespace

double MaxAccelerationUnderCap(double v, double cap, double jerk, double dt) {
  const double room = cap - v;
  if (room <= 0.0) return room / dt;
  const double unit = jerk * dt * dt;
  return AccelerationInRoom(room, unit, 8.0 / unit, dt);
}

namespace {

// The hardest braking a release at `release_jerk` still brings back to zero acceleration as v
// reaches zero: v + a' dt - ReleaseGain(-a') >= 0, i.e. b = -a' with b dt + gain(b) <= v. That is
// -MaxAccelerationUnderCap(0, v, release_jerk, dt), with the jerk's unit kept for repeated use.
class Release {
 public:
  Release(double release_jerk, double dt)
      : unit_(release_jerk * dt * dt), eight_over_unit_(8.0 / unit_), dt_(dt) {}
  double operator()(double v) const {
    const double room = std::max(v, 0.0);
    if (room <= 0.0) return -(room / dt_);
    return -AccelerationInRoom(room, unit_, eight_over_unit_, dt_);
  }

 private:
  double unit_, eight_over_unit_, dt_;
};

// The stop law's next acceleration, given the release's: brake harder by the jerk step down to
// -acceleration, but no harder than the release allows, and never change a by more than a step.
double StopChoice(double a, double step, double acceleration, double released) {
  return std::min(std::max({a - step, -acceleration, released}), a + step);
}

}  // namespace

double StopAcceleration(double v, double a, double jerk, double acceleration, double dt,
                        double release_fraction) {
  return StopChoice(a, jerk * dt, acceleration, Release(jerk * release_fraction, dt)(v));
}

namespace {

// Stops that take longer than this many periods count as never ending.
constexpr int kMaxStopPeriods = 200000;

// One period of a stop with acceleration `next`: a velocity within `tiny` of zero is settled to
// exactly zero (with the acceleration that does it). Returns false when the velocity would turn
// negative (the stop reverses); v, a and distance are then left as they were.
bool StopPeriod(double next, double tiny, double dt, double* v, double* a, double* distance) {
  double v_next = *v + next * dt;
  if (v_next < -tiny) return false;
  if (std::abs(v_next) <= tiny) {
    v_next = 0.0;
    next = -*v / dt;
  }
  *distance += v_next * dt;
  *v = v_next;
  *a = next;
  return true;
}

}  // namespace

StopDistance StopDistanceBySimulation(double v, double a, double jerk, double acceleration,
                                      double dt) {
  double distance = 0.0;
  int periods = 0;
  const double tiny = 1e-12 * (1.0 + std::abs(v));
  while (v != 0.0 || a != 0.0) {
    const double next = StopAcceleration(v, a, jerk, acceleration, dt);
    if (!StopPeriod(next, tiny, dt, &v, &a, &distance)) return {distance, periods, true};
    if (++periods > kMaxStopPeriods) return {std::numeric_limits<double>::infinity(), periods};
  }
  return {distance, periods};
}

namespace {

// The largest k in [1, hi] for which holds(k), given holds(1) and that holds is true then false:
// galloping from `guess` (two probes when the guess is the answer, one when it is hi), then
// bisecting the bracket the gallop found.
template <typename Holds>
long LastTrue(long hi, long guess, const Holds& holds) {
  long lo = 1, up = hi + 1;  // holds(lo); up > hi or !holds(up)
  guess = std::clamp(guess, lo, hi);
  if (guess > lo && !holds(guess)) {
    up = guess;
    for (long d = 1; up - d > lo; d *= 2) {
      if (holds(up - d)) {
        lo = up - d;
        break;
      }
      up -= d;
    }
  } else {
    lo = guess;
    for (long d = 1; lo + d < up; d *= 2) {
      if (!holds(lo + d)) {
        up = lo + d;
        break;
      }
      lo += d;
    }
  }
  while (up - lo > 1) {
    const long mid = lo + (up - lo) / 2;
    if (holds(mid)) {
      lo = mid;
    } else {
      up = mid;
    }
  }
  return lo;
}

// Below this many periods a phase is stepped, not summed.
constexpr long kMinJump = 8;

}  // namespace

// StopDistanceBySimulation, with the long phases summed in closed form instead of stepped: the
// ramp (a falls by jerk dt per period), the rise (a state braked harder than its release needs
// lets go by jerk dt per period), the hold at -acceleration, and the release, which follows
// its own plan (accelerations -b, -b + j dt, ... as MaxAccelerationUnderCap planned them) because
// that plan re-aims to itself period after period. Each phase's length is found by a search on the
// law's own choice (from a closed-form guess), so the result is the simulation's up to rounding.
StopDistance StopDistanceFrom(double v, double a, double jerk, double acceleration, double dt) {
  double distance = 0.0;
  int periods = 0;
  const double tiny = 1e-12 * (1.0 + std::abs(v));
  const double step = jerk * dt;
  const double release_jerk = jerk * kReleaseJerkFraction;
  const Release release(release_jerk, dt);
  // The ramp and the rise: a changes by da = -step or +step each period, a_m = a + m da,
  // v_m = v + dt (m a + da m (m + 1) / 2). `jump` sums the periods 1..k of such a phase in closed
  // form, k the last one for which `goes` holds, when that is at least kMinJump of them.
  const auto a_with = [&](double da, long m) { return a + static_cast<double>(m) * da; };
  const auto v_with = [&](double da, long m) {
    const double mm = static_cast<double>(m);
    return v + dt * (mm * a + da * mm * (mm + 1.0) / 2.0);
  };
  // The guess for such a phase's length: where it meets the release plan, a_m = -b with b the
  // release's deceleration for v_{m-1}, b^2 / 2j + b dt / 2 = v_{m-1} (MaxAccelerationUnderCap's
  // cap, exact when b is a whole number of jerk steps), or where v_m reaches zero, whichever comes
  // first: quadratics in m, their first roots >= 1 (`most` when there is none).
  const auto phase_guess = [&](double da, long most) {
    double first = static_cast<double>(most);
    const auto roots = [&first](double q2, double q1, double q0, const auto& valid) {
      const double disc = q1 * q1 - 4.0 * q2 * q0;
      if (disc < 0.0) return;
      const double q = -0.5 * (q1 + std::copysign(std::sqrt(disc), q1));
      for (const double m : {q2 != 0.0 ? q / q2 : INFINITY, q != 0.0 ? q0 / q : INFINITY}) {
        if (m >= 1.0 && m < first && valid(m)) first = m;
      }
    };
    roots(da * da / (2.0 * release_jerk) - dt * da / 2.0, a * (da / release_jerk - dt),
          a * a / (2.0 * release_jerk) + a * dt / 2.0 - v,
          [&](double m) { return a + da * m <= 0.0; });
    roots(da / 2.0, a + da / 2.0, v / dt, [](double) { return true; });
    return static_cast<long>(first);
  };
  const auto jump = [&](double da, long most, const auto& goes) {
    if (most < kMinJump || !goes(kMinJump)) return false;
    const long k = LastTrue(most, phase_guess(da, most), goes);
    const double kk = static_cast<double>(k);
    distance +=
        dt * (kk * v + dt * (a * kk * (kk + 1.0) / 2.0 + da * kk * (kk + 1.0) * (kk + 2.0) / 6.0));
    v = v_with(da, k);
    a = a_with(da, k);
    periods += static_cast<int>(k);
    return true;
  };
  while (v != 0.0 || a != 0.0) {
    // StopAcceleration, with the release's own choice kept for the release branch below.
    const double released = release(v);
    const double next = StopChoice(a, step, acceleration, released);
    if (next == a - step && next > -acceleration) {
      // Ramp: the law brakes harder at the full jerk.
      const auto ramps = [&](long m) {  // period m chooses a_{m-1} - step
        const double choice = a_with(-step, m);
        return choice > -acceleration && choice > release(v_with(-step, m - 1)) &&
               v_with(-step, m) > tiny;
      };
      if (jump(-step, static_cast<long>((a + acceleration) / step), ramps)) continue;
    } else if (next == a + step && a + step < 0.0) {
      // Rise: braked harder than the release plan needs, the law lets go at the full jerk until
      // it meets the plan (or v reaches zero first: the state reverses).
      const auto rises = [&](long m) {  // period m chooses a_{m-1} + step
        return std::max(-acceleration, release(v_with(step, m - 1))) >= a_with(step, m) &&
               v_with(step, m) > tiny;
      };
      if (jump(step, static_cast<long>(-a / step), rises)) continue;
    } else if (a == -acceleration && next == -acceleration) {
      // Hold: v_m = v - m A dt.
      const auto v_at = [&](long m) { return v - static_cast<double>(m) * acceleration * dt; };
      const auto holds = [&](long m) {
        return -acceleration >= release(v_at(m - 1)) && v_at(m) > tiny;
      };
      const long most = static_cast<long>(v / (acceleration * dt)) + 1;
      if (most >= kMinJump && holds(kMinJump)) {
        // The hold lasts while the release from -acceleration still fits in v: v >= hold_end.
        const double hold_end = acceleration * dt + ReleaseGain(acceleration, release_jerk, dt);
        const long k =
            LastTrue(most, 1 + static_cast<long>((v - hold_end) / (acceleration * dt)), holds);
        const double kk = static_cast<double>(k);
        distance += dt * (kk * v - acceleration * dt * kk * (kk + 1.0) / 2.0);
        v = v_at(k);
        periods += static_cast<int>(k);
        continue;
      }
    } else if (next == released && next > a - step && next < a + step) {
      // Release: a_i = -b + i j dt (i = 0, 1, ...), v_i = v - dt (i b - j dt i (i - 1) / 2).
      const double b = -next, rstep = release_jerk * dt;
      const auto v_at = [&](long i) {
        const double ii = static_cast<double>(i);
        return v - dt * (ii * b - rstep * ii * (ii - 1.0) / 2.0);
      };
      const auto a_at = [&](long i) { return -b + static_cast<double>(i - 1) * rstep; };
      const auto releases = [&](long i) {  // period i chooses a_i, re-aimed from v_{i-1}
        const double planned = a_at(i);
        return std::abs(release(v_at(i - 1)) - planned) <= 1e-9 * (b + rstep) && v_at(i) > tiny;
      };
      const long most = static_cast<long>(b / rstep) + 1;
      if (most >= kMinJump && releases(kMinJump)) {
        // Leave the last periods to the loop: it settles v and a to exactly zero.
        const long k = LastTrue(most, most, releases) - 2;
        if (k >= kMinJump) {
          const double kk = static_cast<double>(k);
          distance += dt * (kk * v - dt * (b * kk * (kk + 1.0) / 2.0 -
                                           rstep * (kk + 1.0) * kk * (kk - 1.0) / 6.0));
          v = v_at(k);
          a = a_at(k);
          periods += static_cast<int>(k);
          continue;
        }
      }
    }
    // One period, as the simulation steps it.
    if (!StopPeriod(next, tiny, dt, &v, &a, &distance)) return {distance, periods, true};
    if (++periods > kMaxStopPeriods) return {std::numeric_limits<double>::infinity(), periods};
  }
  return {distance, periods};
}

double StopReach(double v, double a, double jerk, double acceleration, double dt, double feed) {
  const double excess = v - feed;
  if (v < 0.0 || excess + ReleaseGain(a, jerk, dt) <= 0.0) {
    return -std::numeric_limits<double>::infinity();
  }
  const StopDistance stop = StopDistanceFrom(std::max(excess, 0.0), a, jerk, acceleration, dt);
  if (stop.reverses && feed > 0.0) return -std::numeric_limits<double>::infinity();
  return stop.distance + feed * stop.periods * dt;
}

}  // namespace dtis::interp
