#include "dtis/interp/verifier.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "dtis/core/error.hpp"

namespace dtis::interp {

VerifyReport Verify(const SetpointTable& table, const Machine& machine) {
  const auto axes = machine.Axes();
  if (table.axes.size() != axes.size()) {
    throw Error("the setpoints have {} axes but machine '{}' has {}", table.axes.size(),
                machine.Name(), axes.size());
  }
  for (std::size_t i = 0; i < axes.size(); ++i) {
    if (table.axes[i] != axes[i].name) {
      throw Error("setpoint column {} is axis '{}' but machine '{}' has '{}' there", i + 2,
                  table.axes[i], machine.Name(), axes[i].name);
    }
  }
  const long n = static_cast<long>(table.Rows());
  if (n < 2) throw Error("a setpoint sequence needs at least 2 rows, got {}", n);

  VerifyReport r;
  r.rows = n;
  r.period_s = (table.t[static_cast<std::size_t>(n - 1)] - table.t[0]) / static_cast<double>(n - 1);
  const double dt = r.period_s;
  if (!(dt > 0.0)) throw Error("setpoint times do not increase (period {} s)", dt);
  for (long k = 0; k < n; ++k) {
    const double expected = table.t[0] + static_cast<double>(k) * dt;
    if (std::abs(table.t[static_cast<std::size_t>(k)] - expected) >
            1e-9 * std::max(1.0, expected) ||
        (k > 0 &&
         !(table.t[static_cast<std::size_t>(k)] > table.t[static_cast<std::size_t>(k - 1)]))) {
      r.uniform_period = false;
      r.bad_period_row = k;
      break;
    }
  }

  long first_move = -1, last_move = -1;
  for (std::size_t i = 0; i < axes.size(); ++i) {
    const Axis& axis = axes[i];
    const double k = axis.rotary ? 180.0 / std::numbers::pi : 1.0;  // limits to file units
    const double vmax = axis.vmax * k, amax = axis.amax * k, jmax = axis.jmax * k;
    const auto& x = table.columns[i];
    AxisCheck c;
    c.name = axis.name;
    // Rows before the first are the first row held; two rows after the last are the last held.
    const auto at = [&](long row) {
      return x[static_cast<std::size_t>(std::clamp(row, 0L, n - 1))];
    };
    for (long row = 0; row < n + 2; ++row) {
      const double x0 = at(row), x1 = at(row - 1), x2 = at(row - 2), x3 = at(row - 3);
      const double v = (x0 - x1) / dt;
      const double a = (x0 - 2.0 * x1 + x2) / (dt * dt);
      const double j = (x0 - 3.0 * x1 + 3.0 * x2 - x3) / (dt * dt * dt);
      if (std::abs(v) > c.v) c.v = std::abs(v), c.v_row = row;
      if (std::abs(a) > c.a) c.a = std::abs(a), c.a_row = row;
      if (std::abs(j) > c.j) c.j = std::abs(j), c.j_row = row;
      if (row > 0 && row < n && x0 != x1) {
        if (first_move < 0 || row - 1 < first_move) first_move = row - 1;
        last_move = std::max(last_move, row);
      }
      if (row <= 2 && (std::abs(v) > vmax || std::abs(a) > amax || std::abs(j) > jmax)) {
        r.starts_at_rest = false;
      }
    }
    c.v_ratio = c.v / vmax;
    c.a_ratio = c.a / amax;
    c.j_ratio = c.j / jmax;
    const std::pair<double, std::string> worst[] = {
        {c.v_ratio, fmt::format("{} velocity at t = {} s", c.name,
                                static_cast<double>(c.v_row) * dt + table.t[0])},
        {c.a_ratio, fmt::format("{} acceleration at t = {} s", c.name,
                                static_cast<double>(c.a_row) * dt + table.t[0])},
        {c.j_ratio, fmt::format("{} jerk at t = {} s", c.name,
                                static_cast<double>(c.j_row) * dt + table.t[0])}};
    for (const auto& [ratio, what] : worst) {
      if (ratio > r.worst_ratio || r.worst.empty()) r.worst_ratio = ratio, r.worst = what;
    }
    if (n < 3 || x[static_cast<std::size_t>(n - 1)] != x[static_cast<std::size_t>(n - 2)] ||
        x[static_cast<std::size_t>(n - 2)] != x[static_cast<std::size_t>(n - 3)]) {
      r.ends_at_rest = false;
    }
    r.axes.push_back(c);
  }
  r.motion_time_s = first_move < 0 ? 0.0 : static_cast<double>(last_move - first_move) * dt;
  return r;
}

std::string FormatReport(const VerifyReport& r) {
  std::string out = fmt::format("{} setpoints, period {:.6g} ms, motion time {:.6f} s\n", r.rows,
                                r.period_s * 1e3, r.motion_time_s);
  out += fmt::format("{:<5} {:>10} {:>10} {:>10}   (ratio of |v|, |a|, |j| to the limit)\n", "axis",
                     "velocity", "accel", "jerk");
  for (const auto& c : r.axes) {
    out += fmt::format("{:<5} {:>10.6f} {:>10.6f} {:>10.6f}\n", c.name, c.v_ratio, c.a_ratio,
                       c.j_ratio);
  }
  out += fmt::format("worst ratio {:.9f} ({})\n", r.worst_ratio, r.worst);
  out += fmt::format("uniform period: {}{}\n", r.uniform_period ? "yes" : "no",
                     r.uniform_period ? "" : fmt::format(" (row {})", r.bad_period_row + 1));
  out += fmt::format("starts at rest: {}\nends at rest: {}\n", r.starts_at_rest ? "yes" : "no",
                     r.ends_at_rest ? "yes" : "no");
  out += fmt::format("result: {}\n", r.Passed() ? "PASS" : "FAIL");
  return out;
}

}  // namespace dtis::interp
