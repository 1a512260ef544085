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
  const std::size_t n = table.Rows();
  if (n < 2) throw Error("a setpoint sequence needs at least 2 rows, got {}", n);
  const double dt = (table.t[n - 1] - table.t[0]) / static_cast<double>(n - 1);
  if (!(dt > 0.0)) throw Error("setpoint times do not increase (period {} s)", dt);
  StreamVerifier verifier(machine, dt);
  std::vector<double> row(axes.size());
  for (std::size_t k = 0; k < n; ++k) {
    for (std::size_t i = 0; i < axes.size(); ++i) row[i] = table.columns[i][k];
    verifier.Add(table.t[k], row.data());
  }
  return verifier.Report();
}

StreamVerifier::StreamVerifier(const Machine& machine, double period_s) : dt_(period_s) {
  if (!(period_s > 0.0)) throw Error("setpoint period must be > 0, got {} s", period_s);
  for (const Axis& axis : machine.Axes()) {
    const double k = axis.rotary ? 180.0 / std::numbers::pi : 1.0;  // limits to file units
    AxisState a{axis.vmax * k, axis.amax * k, axis.jmax * k, {}, 0.0, {}};
    a.check.name = axis.name;
    axes_.push_back(a);
  }
}

// The backward differences at `row` (Eq. 6 and 14), from the four newest values, into the axis'
// maxima. True when one of them exceeds its limit.
bool StreamVerifier::Differences(long row, AxisState* a) const {
  const double* x = a->x;
  const double v = (x[0] - x[1]) / dt_;
  const double acc = (x[0] - 2.0 * x[1] + x[2]) / (dt_ * dt_);
  const double j = (x[0] - 3.0 * x[1] + 3.0 * x[2] - x[3]) / (dt_ * dt_ * dt_);
  AxisCheck& c = a->check;
  if (std::abs(v) > c.v) c.v = std::abs(v), c.v_row = row;
  if (std::abs(acc) > c.a) c.a = std::abs(acc), c.a_row = row;
  if (std::abs(j) > c.j) c.j = std::abs(j), c.j_row = row;
  const double half = 0.5 * a->jmax;
  if (std::abs(j) > half && std::abs(a->last_jerk) > half && (j > 0.0) != (a->last_jerk > 0.0)) {
    ++c.jerk_flips;
  }
  a->last_jerk = j;
  return std::abs(v) > a->vmax || std::abs(acc) > a->amax || std::abs(j) > a->jmax;
}

void StreamVerifier::Add(double t, const double* row) {
  const long k = rows_++;
  if (k == 0) t0_ = t;
  const double expected = t0_ + static_cast<double>(k) * dt_;
  if (uniform_ &&
      (std::abs(t - expected) > 1e-9 * std::max(1.0, expected) || (k > 0 && !(t > last_t_)))) {
    uniform_ = false;
    bad_period_row_ = k;
  }
  last_t_ = t;
  for (std::size_t i = 0; i < axes_.size(); ++i) {
    AxisState& a = axes_[i];
    if (k == 0) {
      std::fill(std::begin(a.x), std::end(a.x), row[i]);  // the first row held before the file
    } else {
      std::copy_backward(a.x, a.x + 3, a.x + 4);
      a.x[0] = row[i];
    }
    // Holding the first row before the file must respect every limit.
    if (Differences(k, &a) && k <= 2) starts_at_rest_ = false;
    if (k > 0 && a.x[0] != a.x[1]) {
      if (first_move_ < 0) first_move_ = k - 1;
      last_move_ = k;
    }
  }
}

VerifyReport StreamVerifier::Report() const {
  if (rows_ < 2) throw Error("a setpoint sequence needs at least 2 rows, got {}", rows_);
  VerifyReport r;
  r.rows = rows_;
  r.period_s = dt_;
  r.uniform_period = uniform_;
  r.bad_period_row = bad_period_row_;
  r.starts_at_rest = starts_at_rest_;
  for (AxisState a : axes_) {
    const bool rest = rows_ >= 3 && a.x[0] == a.x[1] && a.x[1] == a.x[2];
    if (!rest) r.ends_at_rest = false;
    // Two rows after the last are the last held.
    for (long row = rows_; row < rows_ + 2; ++row) {
      std::copy_backward(a.x, a.x + 3, a.x + 4);
      if (Differences(row, &a) && row <= 2) r.starts_at_rest = false;
    }
    AxisCheck c = a.check;
    c.v_ratio = c.v / a.vmax;
    c.a_ratio = c.a / a.amax;
    c.j_ratio = c.j / a.jmax;
    // Row times to 12 digits: row * dt carries the period's binary rounding (0.41100000000000003).
    const auto at = [&](const char* what, long row) {
      return fmt::format("{} {} at t = {:.12g} s", c.name, what,
                         static_cast<double>(row) * dt_ + t0_);
    };
    const std::pair<double, std::string> worst[] = {{c.v_ratio, at("velocity", c.v_row)},
                                                    {c.a_ratio, at("acceleration", c.a_row)},
                                                    {c.j_ratio, at("jerk", c.j_row)}};
    for (const auto& [ratio, what] : worst) {
      if (ratio > r.worst_ratio || r.worst.empty()) r.worst_ratio = ratio, r.worst = what;
    }
    r.axes.push_back(c);
  }
  r.motion_time_s = first_move_ < 0 ? 0.0 : static_cast<double>(last_move_ - first_move_) * dt_;
  return r;
}

std::string FormatReport(const VerifyReport& r) {
  std::string out = fmt::format("{} setpoints, period {:.6g} ms, motion time {:.6f} s\n", r.rows,
                                r.period_s * 1e3, r.motion_time_s);
  out += fmt::format(
      "{:<5} {:>10} {:>10} {:>10} {:>11}   (ratio of |v|, |a|, |j| to the limit; periods whose "
      "jerk flips sign beyond half the limit)\n",
      "axis", "velocity", "accel", "jerk", "jerk flips");
  for (const auto& c : r.axes) {
    out += fmt::format("{:<5} {:>10.6f} {:>10.6f} {:>10.6f} {:>11}\n", c.name, c.v_ratio, c.a_ratio,
                       c.j_ratio, c.jerk_flips);
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
