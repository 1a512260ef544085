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

double MaxAccelerationUnderCap(double v, double cap, double jerk, double dt) {
  const double room = cap - v;
  if (room <= 0.0) return room / dt;
  // On the piece a in ((n-1) J dt, n J dt]: v + n dt a - J dt^2 n (n-1) / 2 = cap, and the piece
  // boundaries are at room = J dt^2 n (n -+ 1) / 2.
  const double unit = jerk * dt * dt;
  double n = std::ceil((-1.0 + std::sqrt(1.0 + 8.0 * room / unit)) / 2.0);
  n = std::max(n, 1.0);
  while (n > 1.0 && unit * (n - 1.0) * n / 2.0 >= room) n -= 1.0;
  while (unit * n * (n + 1.0) / 2.0 < room) n += 1.0;
  return (room + unit * n * (n - 1.0) / 2.0) / (n * dt);
}

double StopAcceleration(double v, double a, double jerk, double acceleration, double dt) {
  // Release condition: v + a' dt - ReleaseGain(-a') >= 0, i.e. b = -a' with b dt + gain(b) <= v.
  const double release =
      -MaxAccelerationUnderCap(0.0, std::max(v, 0.0), jerk * kReleaseJerkFraction, dt);
  double next = std::max({a - jerk * dt, -acceleration, release});
  return std::min(next, a + jerk * dt);
}

StopDistance StopDistanceFrom(double v, double a, double jerk, double acceleration, double dt) {
  double distance = 0.0;
  int periods = 0;
  const double tiny = 1e-12 * (1.0 + std::abs(v));
  while (v != 0.0 || a != 0.0) {
    double next = StopAcceleration(v, a, jerk, acceleration, dt);
    double v_next = v + next * dt;
    if (v_next < -tiny) return {distance, periods, true};
    if (std::abs(v_next) <= tiny) {
      v_next = 0.0;
      next = -v / dt;
    }
    distance += v_next * dt;
    v = v_next;
    a = next;
    if (++periods > 200000) return {std::numeric_limits<double>::infinity(), periods};
  }
  return {distance, periods};
}

}  // namespace dtis::interp
