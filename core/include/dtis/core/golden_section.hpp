// Golden-section search for the largest value of a function on an interval.
#pragma once

#include <cmath>
#include <utility>

namespace dtis {

// The better of the two last probes of a golden-section search for the maximum of f on
// [lo, hi]: `steps` times the bracket shrinks to 0.618 of itself around the better probe.
// Returns (x, f(x)); on a tie the lower probe. f is asked steps + 2 times.
template <typename F>
std::pair<double, double> GoldenSectionMax(F&& f, double lo, double hi, int steps) {
  const double g = (std::sqrt(5.0) - 1.0) / 2.0;
  double x1 = hi - g * (hi - lo), x2 = lo + g * (hi - lo);
  double f1 = f(x1), f2 = f(x2);
  for (int i = 0; i < steps; ++i) {
    if (f1 >= f2) {
      hi = x2, x2 = x1, f2 = f1, x1 = hi - g * (hi - lo), f1 = f(x1);
    } else {
      lo = x1, x1 = x2, f1 = f2, x2 = lo + g * (hi - lo), f2 = f(x2);
    }
  }
  return f1 >= f2 ? std::pair{x1, f1} : std::pair{x2, f2};
}

}  // namespace dtis
