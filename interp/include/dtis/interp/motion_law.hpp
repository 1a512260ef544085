// Discrete jerk-limited laws along the path, in the backward differences of Eq. 6 (Beudaert 2012):
//   v_k = (s_k - s_{k-1}) / dt,  a_k = (v_k - v_{k-1}) / dt,  j_k = (a_k - a_{k-1}) / dt.
// They serve the interpolator as look-ahead (reach a feed cap without overshoot, stop at the end of
// the path) and as the brake policy of the back-off (the paper's "s_min sequence", made to end at
// rest with zero acceleration).
#pragma once

namespace dtis::interp {

// The release of an acceleration is planned at this fraction of the jerk the law may use. In exact
// arithmetic a release that just fits is a neutral equilibrium: the slack v - ReleaseGain never
// changes, so rounding of the positions would random-walk it and a negative slack makes the last
// period need more than the jerk limit. Planning the release slightly softer than the jerk cap lets
// every period re-aim at zero slack with headroom to absorb that noise (cost: 1e-4 of a release).
inline constexpr double kReleaseJerkFraction = 1.0 - 1e-4;

// Velocity gained while an acceleration a > 0 is brought back to 0 at jerk -jerk, one period at a
// time (the last period partial). Zero for a <= 0. By symmetry, ReleaseGain(-a) is the velocity
// lost while a negative acceleration is brought back to 0.
double ReleaseGain(double a, double jerk, double dt);

// The largest next acceleration a such that v + a dt + ReleaseGain(a) <= cap: accelerating with it
// still lets the feed settle at or below `cap`. May be negative when v is above the cap.
double MaxAccelerationUnderCap(double v, double cap, double jerk, double dt);

// The next acceleration of the fastest stop to rest from (v >= 0, a): brake at -jerk down to
// -acceleration, and release (planned at `release_fraction` of jerk) so that v and a reach zero
// together. A period may still change a by the whole jerk: a law that fell behind its release
// (the exact step could not follow it for a period) catches up by the difference.
double StopAcceleration(double v, double a, double jerk, double acceleration, double dt,
                        double release_fraction = kReleaseJerkFraction);

// Distance travelled by StopAcceleration from (v, a) until rest, and the number of periods.
// `reverses` is set when the state is braked too hard to come to rest without moving backwards
// (the acceleration cannot be released before v turns negative); the distance is then the one
// travelled until v reaches zero.
struct StopDistance {
  double distance;
  int periods;
  bool reverses = false;
};
StopDistance StopDistanceFrom(double v, double a, double jerk, double acceleration, double dt);
// The same by stepping StopAcceleration period by period: the reference StopDistanceFrom is
// tested against (StopDistanceFrom sums the long phases in closed form).
StopDistance StopDistanceBySimulation(double v, double a, double jerk, double acceleration,
                                      double dt);

// How far a motion with feed v and acceleration a (one period old) runs before the stop law, run
// on its excess over `feed`, has brought it down to `feed` with zero acceleration: the stop
// distance of the excess plus `feed` for each of its periods. Minus infinity when the motion is
// not above the feed at all (nothing to brake for). A state braked so hard that the excess would
// turn negative (StopDistance::reverses) passes a point of feed > 0 below that feed, which is
// allowed: minus infinity too. At feed 0 it is a stop the law cannot bring to rest, and it runs
// as far as the law takes it before the velocity turns.
double StopReach(double v, double a, double jerk, double acceleration, double dt, double feed);

}  // namespace dtis::interp
