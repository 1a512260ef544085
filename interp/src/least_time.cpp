#include "dtis/interp/least_time.hpp"

#include <algorithm>
#include <cmath>
#include <coin/ClpSimplex.hpp>
#include <coin/CoinPackedMatrix.hpp>
#include <limits>

#include "dtis/core/error.hpp"

namespace dtis::interp {
namespace {

constexpr double kNever = std::numeric_limits<double>::infinity();

// The backward differences of orders 1 to 3: the order-p difference at period k is
// sum_j kDifference[p][j] x_{k - j}.
constexpr double kDifference[4][4] = {{1, 0, 0, 0}, {1, -1, 0, 0}, {1, -2, 1, 0}, {1, -3, 3, -1}};

// The linear programs keep the linearised limits with this much room (relative): the exact
// positions, not the model, decide whether an iterate holds, and a little room spares an
// iterate that the model put exactly on a limit.
constexpr double kRoom = 1e-6;

// A row whose exact value, plus what the trust region lets the iterate move it, stays below this
// share of its limit cannot bind: it is left out of the linear program.
constexpr double kRowReach = 0.5;

// dq/ds by central differences of exact positions this far apart (mm).
constexpr double kGradientStep = 1e-5;

// The excess the linear programs may aim below the limits (relative, so the iterate moves into
// the feasible set rather than onto its boundary).
constexpr double kInterior = 0.01;

// Linear programs allowed for smoothing a window: one smooths, the others restore the limits.
constexpr int kSmoothingPrograms = 12;
// Smoothings of one window, each from the last one kept.
constexpr int kSmoothingRounds = 3;
// The smoothing LP's trust region, as a share of the attempt's: a full one missed the exact rows
// by up to 1 % and the restoration seldom brought them back (one window of the trident's eleven
// shortened ones smoothed, its axes' jerk flips 88 against 74); a share of 0.02 smoothed two, the
// windows that held the flips (12 flips; 0.05: 30, 0.01: 11).
constexpr double kSmoothingStep = 0.02;

// The fourth difference: the change of the third (the path's jerk) from one period to the next.
constexpr double kFourth[5] = {1, -4, 6, -4, 1};

// The smootherstep 6x^5 - 15x^4 + 10x^3: a warp of the period index that is flat (to second
// order) at both ends of a window, so the periods that join the kept ones keep their rates.
double Smootherstep(double x) { return x * x * x * (x * (6.0 * x - 15.0) + 10.0); }

class Shortener {
 public:
  Shortener(const PathSource& path, const Machine& machine, const LeastTimeLimits& limits,
            const LeastTimeOptions& options, std::vector<PlannedStep>* plan)
      : path_(path),
        machine_(machine),
        o_(options),
        plan_(*plan),
        n_axes_(static_cast<int>(machine.Axes().size())) {
    const double dt = limits.period_s;
    for (int i = 0; i < n_axes_; ++i) {
      width_[1][i] = limits.v[i] * dt;
      width_[2][i] = limits.a[i] * dt * dt;
      width_[3][i] = limits.j[i] * dt * dt * dt;
    }
    tangential_[1] = limits.feed * dt;
    tangential_[2] = limits.tangential_acceleration * dt * dt;
    tangential_[3] = limits.tangential_jerk * dt * dt * dt;
  }

  LeastTimeStats Run() {
    // Each sweep after the first starts its windows half a stride later, so that a stretch that
    // straddled two windows lies inside one.
    for (int sweep = 0; sweep < o_.sweeps; ++sweep) {
      const long saved = stats_.periods_saved;
      Sweep(sweep % 2 == 0 ? 3 : 3 + o_.window_stride / 2);
      if (stats_.periods_saved == saved) break;
    }
    return stats_;
  }

 private:
  void Sweep(long first) {
    const long m = o_.window_periods;
    bool last = false;
    for (long a = first; !last; a += o_.window_stride) {
      // The window must leave the motion's last three rows (rest) after it; the rows at rest
      // after them are no window's to take.
      const long size = Moving();
      if (a + m + 3 >= size) {
        a = size - m - 3;  // the last window ends where the rest begins
        last = true;
        if (a < 3) break;
      }
      ++stats_.windows;
      // Periods to take off: doubled after each success until one fails, then halved.
      long d = 1;
      bool failed = false;
      bool smooth = false;  // the window was shortened: smooth it once done
      const std::vector<PlannedStep> before =
          o_.no_added_chatter ? plan_ : std::vector<PlannedStep>();
      const long saved = stats_.periods_saved;
      for (;;) {
        // The last window moves back as it shortens the plan, to keep the rest after it.
        a = std::min(a, Moving() - m - 3);
        bool shorter = false;
        try {
          shorter = Attempt(a, m, d);
        } catch (const Error&) {
          // The path could not be followed at an arc length between two of the plan's (a
          // surface's solve that did not converge there): this window keeps its periods.
          ++stats_.failed_evaluations;
        }
        if (shorter) {
          stats_.periods_saved += d;
          smooth = true;
          if (!failed) d = std::min<long>(2L * d, m / 4);
        } else if (d == 1) {
          break;
        } else {
          failed = true;
          d /= 2;
        }
      }
      if (smooth) {
        // The LPs' solutions lie on vertices: the path's jerk may take the extreme an axis allows
        // one period and the other extreme the next (chatter, docs/planner.md). One more
        // question, at the window's final length: the least change of the path's jerk that keeps
        // every limit.
        a = std::min(a, Moving() - m - 3);
        try {
          for (int round = 0; round < kSmoothingRounds && Attempt(a, m, 0, Goal::kSmoother);
               ++round) {
            ++stats_.smoothed;
          }
        } catch (const Error&) {
          ++stats_.failed_evaluations;
        }
      }
      // With no_added_chatter, a shorter window that still shakes an axis more than the plan did
      // (its jerk flipping between the extremes from one period to the next, docs/planner.md) is
      // not kept.
      if (o_.no_added_chatter && Flips(plan_) > Flips(before)) {
        plan_ = before;
        stats_.periods_saved = saved;
        ++stats_.reverted;
      }
    }
  }

  // The periods of `plan` whose jerk, on some axis, has the other sign than the period before's,
  // both beyond half the limit (as `dtis verify` counts jerk flips).
  int Flips(const std::vector<PlannedStep>& plan) const {
    int flips = 0;
    for (int i = 0; i < n_axes_; ++i) {
      double last = 0.0;
      for (std::size_t k = 3; k < plan.size(); ++k) {
        const double j =
            plan[k].q[i] - 3.0 * plan[k - 1].q[i] + 3.0 * plan[k - 2].q[i] - plan[k - 3].q[i];
        if (std::abs(j) > 0.5 * width_[3][i] && std::abs(last) > 0.5 * width_[3][i] &&
            (j > 0.0) != (last > 0.0)) {
          ++flips;
        }
        last = j;
      }
    }
    return flips;
  }

  // The rows up to three after the last that moves (the plan's rows at rest after those are
  // left as they are).
  long Moving() const {
    long last = static_cast<long>(plan_.size()) - 1;
    while (last > 0 &&
           plan_[static_cast<std::size_t>(last)].s == plan_[static_cast<std::size_t>(last - 1)].s &&
           plan_[static_cast<std::size_t>(last)].q == plan_[static_cast<std::size_t>(last - 1)].q) {
      --last;
    }
    return std::min(static_cast<long>(plan_.size()), last + 4);
  }

  // The exact pose at arc length s, starting the path's solve from `near`.
  PlannedStep Evaluate(double s, const PlannedStep& near) {
    ++stats_.evaluations;
    const PathSample sample = path_.At(near.state, s);
    if (sample.status == PathStatus::kLeftDomain || sample.status == PathStatus::kNoConvergence) {
      throw Error("cannot follow the path at {}: {}", path_.Describe(near.state),
                  DescribePathFailure(sample.status, s));
    }
    PlannedStep out;
    out.s = sample.state.s;
    out.state = sample.state;
    const InverseResult r = machine_.Inverse(sample.pose, &near.q, &out.q);
    if (r.status != InverseStatus::kOk) {
      throw Error("cannot follow the path at {}: {}", path_.Describe(sample.state),
                  DescribeInverseFailure(machine_, r));
    }
    out.refined = true;
    return out;
  }

  // dq/ds at the step x (central differences of exact positions, one-sided at the path's ends),
  // and how far from x that slope may be followed: no farther than the step delta whose
  // second-order term |q_ss| delta^2 is an axis' jerk width (J dt^3). Where the path turns within
  // a few periods (a G1 corner smoothed within 0.01 mm) the slope holds only for tiny steps, and a
  // trust region of one radius for the whole window shrank to them everywhere: the zigzag sample
  // saved 52 periods, with this reach 132. A reach of a sixteenth of that lost the trident 20 of
  // its 51 (2.282 s against 2.261 s).
  struct Slope {
    AxisVector g;
    double reach = 0.0;
  };
  Slope SlopeAt(const PlannedStep& x) {
    const double lo = std::max(0.0, x.s - kGradientStep);
    const double hi = std::min(end_s_, x.s + kGradientStep);
    Slope slope{AxisVector::Zero(n_axes_), kNever};
    if (!(hi > lo)) return slope;
    const PlannedStep a = Evaluate(lo, x), b = Evaluate(hi, x);
    slope.g = (b.q - a.q) / (b.s - a.s);
    if (a.s < x.s && x.s < b.s) {
      for (int i = 0; i < n_axes_; ++i) {
        const double h =
            2.0 * ((b.q[i] - x.q[i]) / (b.s - x.s) - (x.q[i] - a.q[i]) / (x.s - a.s)) / (b.s - a.s);
        if (h != 0.0) slope.reach = std::min(slope.reach, std::sqrt(width_[3][i] / std::abs(h)));
      }
    }
    return slope;
  }

  // What an attempt asks of the window: fewer periods, or (at the same number) a path jerk that
  // changes less from one period to the next.
  enum class Goal { kShorter, kSmoother };

  // Replaces the plan's periods [a, a + m) by m - d periods covering the same arc length (or, for
  // kSmoother with d = 0, by as many whose path jerk changes less), if the sequential linear
  // programs find such periods that keep every limit. Returns whether it did.
  bool Attempt(long a, long m, long d, Goal goal = Goal::kShorter) {
    ++stats_.attempts;
    end_s_ = plan_.back().s;
    const long n = m - d;
    // The window's new periods, first from a warp of the plan's: period k of the new plan takes
    // the arc length the plan had at the fractional period k + d w((k - a + 1) / (n + 1)).
    std::vector<PlannedStep> x(static_cast<std::size_t>(n));
    for (long k = 0; k < n; ++k) {
      const double o = static_cast<double>(a + k) +
                       static_cast<double>(d) *
                           Smootherstep(static_cast<double>(k + 1) / static_cast<double>(n + 1));
      const auto i = static_cast<long>(std::floor(o));
      const double f = o - static_cast<double>(i);
      const auto s_at = [&](long j) {
        return plan_[static_cast<std::size_t>(
                         std::clamp(j, 0L, static_cast<long>(plan_.size()) - 1))]
            .s;
      };
      // Catmull-Rom through the plan's arc lengths, held between the two it lies between.
      const double p0 = s_at(i - 1), p1 = s_at(i), p2 = s_at(i + 1), p3 = s_at(i + 2);
      double s =
          p1 + 0.5 * f *
                   (p2 - p0 +
                    f * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3 + f * (3.0 * (p1 - p2) + p3 - p0)));
      s = std::clamp(s, p1, p2);
      if (k > 0) s = std::max(s, x[static_cast<std::size_t>(k - 1)].s);
      x[static_cast<std::size_t>(k)] = Evaluate(s, plan_[static_cast<std::size_t>(i)]);
    }
    // The period at new index k: the plan's before the window, x in it, the plan's d later after.
    const auto at = [&](long k) -> const PlannedStep& {
      if (k < a) return plan_[static_cast<std::size_t>(std::max(k, 0L))];
      if (k < a + n) return x[static_cast<std::size_t>(k - a)];
      return plan_[static_cast<std::size_t>(k + d)];
    };
    const long rows_end = a + n + 3;  // rows [a, a + n + 3) hold a window period
    // The largest excess over a limit of the rows [a, rows_end), relative: <= 0 where all hold.
    const auto excess = [&]() {
      double worst = -kNever;
      for (long k = a; k < rows_end; ++k) {
        for (int p = 1; p <= 3; ++p) {
          double ds = 0.0;
          for (int j = 0; j <= p; ++j) ds += kDifference[p][j] * at(k - j).s;
          if (p == 1 && ds < 0.0) return kNever;  // the motion goes back
          if (std::isfinite(tangential_[p]))
            worst = std::max(worst, std::abs(ds) / tangential_[p] - 1.0);
          for (int i = 0; i < n_axes_; ++i) {
            double dq = 0.0;
            for (int j = 0; j <= p; ++j) dq += kDifference[p][j] * at(k - j).q[i];
            worst = std::max(worst, std::abs(dq) / width_[p][i] - 1.0);
          }
        }
      }
      return worst;
    };
    // The path's jerk changes: the sum of |fourth differences| of s over the rows that hold a
    // window period.
    const auto roughness = [&]() {
      double sum = 0.0;
      for (long k = a; k < a + n + 4; ++k) {
        double e = 0.0;
        for (int j = 0; j <= 4; ++j) e += kFourth[j] * at(k - j).s;
        sum += std::abs(e);
      }
      return sum;
    };
    const bool smoother = goal == Goal::kSmoother;
    double current = excess();
    if (current <= 0.0 && !smoother) return Accept(a, m, std::move(x));
    if (current > 0.0 && smoother) return false;
    const double rough = smoother ? roughness() : 0.0;
    // Smoother: the first LP smooths; where its step misses an exact row, the next ones bring the
    // smoothed window back within the limits (least excess, as for a shorter window), and it is
    // kept only if it is still smoother.
    bool smoothing = smoother;

    double radius = 0.0;
    for (long k = a; k < a + n; ++k) radius = std::max(radius, at(k).s - at(k - 1).s);
    // No step of s moves farther than two periods' travel: beyond that the iterate would ask the
    // path for poses far from where its solves were started (a surface pass's Newton from the
    // plan's neighbouring state).
    const double widest = std::max(2.0 * radius, 1e-6);
    radius = std::max(0.25 * radius, 1e-6);
    std::vector<Slope> g(static_cast<std::size_t>(n));
    bool fresh = false;  // g holds the gradients at x
    // The last LP's basis (its columns' and rows' status, each row by its key), to start the next
    // from: the rows change little from one LP of an attempt to the next.
    std::vector<unsigned char> basis;
    std::vector<long> basis_keys;
    const int max_lps = smoother ? kSmoothingPrograms : o_.max_lps;
    for (int lp = 0; lp < max_lps; ++lp) {
      if (!fresh) {
        for (long k = 0; k < n; ++k)
          g[static_cast<std::size_t>(k)] = SlopeAt(x[static_cast<std::size_t>(k)]);
        fresh = true;
      }
      // min t over (delta_0 .. delta_{n-1}, t): every row's linearised excess <= t, |delta| <=
      // radius, the arc lengths in order and within the path.
      std::vector<int> row_index, column_index;
      std::vector<double> value, row_lo, row_hi;
      std::vector<long> keys;  // increasing: (period, order, axis or kind, side)
      int rows = 0;
      const auto key = [&](long k, int p, int slot, int side) {
        return (((k - a) * 4 + p) * (kMaxAxes + 2) + slot) * 2 + side;
      };
      const auto add_row = [&](long row_key, const double* coefficient, const long* period,
                               int count, double t_coefficient, double lo, double hi) {
        keys.push_back(row_key);
        for (int c = 0; c < count; ++c) {
          if (coefficient[c] == 0.0) continue;
          row_index.push_back(rows);
          column_index.push_back(static_cast<int>(period[c] - a));
          value.push_back(coefficient[c]);
        }
        if (t_coefficient != 0.0) {
          row_index.push_back(rows);
          column_index.push_back(static_cast<int>(n));
          value.push_back(t_coefficient);
        }
        row_lo.push_back(lo);
        row_hi.push_back(hi);
        ++rows;
      };
      for (long k = a; k < rows_end; ++k) {
        for (int p = 1; p <= 3; ++p) {
          long period[4];
          int count = 0;
          double ds = 0.0;
          double ds_coefficient[4];
          for (int j = 0; j <= p; ++j) {
            ds += kDifference[p][j] * at(k - j).s;
            if (k - j >= a && k - j < a + n) {
              period[count] = k - j;
              ds_coefficient[count++] = kDifference[p][j];
            }
          }
          if (count == 0) continue;
          if (p == 1) {
            // In order: s_k - s_{k-1} >= 0, exactly (linear in s).
            add_row(key(k, p, 0, 0), ds_coefficient, period, count, 0.0, -ds, INFINITY);
          }
          if (std::isfinite(tangential_[p])) {
            const double w = tangential_[p];
            double c[4];
            for (int q = 0; q < count; ++q) c[q] = ds_coefficient[q] / w;
            add_row(key(k, p, 1, 0), c, period, count, -1.0, -INFINITY, 1.0 - kRoom - ds / w);
            add_row(key(k, p, 1, 1), c, period, count, 1.0, -1.0 + kRoom - ds / w, INFINITY);
          }
          for (int i = 0; i < n_axes_; ++i) {
            const double w = width_[p][i];
            double dq = 0.0, reach = 0.0;
            double c[4];
            for (int j = 0; j <= p; ++j) dq += kDifference[p][j] * at(k - j).q[i];
            for (int q = 0; q < count; ++q) {
              const Slope& slope = g[static_cast<std::size_t>(period[q] - a)];
              c[q] = ds_coefficient[q] * slope.g[i] / w;
              reach += std::abs(c[q]) * std::min(radius, slope.reach);
            }
            if (std::abs(dq) / w + reach < kRowReach) continue;
            add_row(key(k, p, 2 + i, 0), c, period, count, -1.0, -INFINITY, 1.0 - kRoom - dq / w);
            add_row(key(k, p, 2 + i, 1), c, period, count, 1.0, -1.0 + kRoom - dq / w, INFINITY);
          }
        }
      }
      // Smoother: one column u_k >= |fourth difference of s at k| per row k, their sum the
      // objective, and every row kept within its limit (t <= 0).
      long columns = n + 1;
      if (smoothing) {
        for (long k = a; k < a + n + 4; ++k, ++columns) {
          double e = 0.0, c[5];
          long period[5];
          int count = 0;
          for (int j = 0; j <= 4; ++j) {
            e += kFourth[j] * at(k - j).s;
            if (k - j >= a && k - j < a + n) period[count] = k - j, c[count++] = kFourth[j];
          }
          for (int side = 0; side < 2; ++side) {
            for (int q = 0; q < count; ++q) {
              row_index.push_back(rows);
              column_index.push_back(static_cast<int>(period[q] - a));
              value.push_back(side == 0 ? -c[q] : c[q]);
            }
            row_index.push_back(rows);
            column_index.push_back(static_cast<int>(columns));
            value.push_back(1.0);
            row_lo.push_back(side == 0 ? e : -e);
            row_hi.push_back(INFINITY);
            ++rows;
          }
        }
        basis.clear();  // the columns differ from the last LP's
      }
      std::vector<double> col_lo(static_cast<std::size_t>(columns), 0.0),
          col_hi(col_lo.size(), INFINITY), objective(col_lo.size(), smoothing ? 1.0 : 0.0);
      for (long k = 0; k < n; ++k) {
        const double s = x[static_cast<std::size_t>(k)].s;
        const double r = std::min(radius, g[static_cast<std::size_t>(k)].reach) *
                         (smoothing ? kSmoothingStep : 1.0);
        col_lo[static_cast<std::size_t>(k)] = std::max(-r, -s);
        col_hi[static_cast<std::size_t>(k)] = std::min(r, end_s_ - s);
      }
      col_lo[static_cast<std::size_t>(n)] = -kInterior;
      col_hi[static_cast<std::size_t>(n)] = smoothing ? 0.0 : INFINITY;
      objective[static_cast<std::size_t>(n)] = smoothing ? 0.0 : 1.0;
      const CoinPackedMatrix matrix(true, row_index.data(), column_index.data(), value.data(),
                                    static_cast<CoinBigIndex>(value.size()));
      ClpSimplex model;
      model.setLogLevel(0);
      model.loadProblem(matrix, col_lo.data(), col_hi.data(), objective.data(), row_lo.data(),
                        row_hi.data());
      if (!basis.empty()) {
        // The last basis for the columns and the rows both LPs hold; a new row's slack basic.
        std::vector<unsigned char> status(static_cast<std::size_t>(n + 1) + keys.size(),
                                          ClpSimplex::basic);
        std::copy_n(basis.begin(), n + 1, status.begin());
        std::size_t j = 0;
        for (std::size_t r = 0; r < keys.size(); ++r) {
          while (j < basis_keys.size() && basis_keys[j] < keys[r]) ++j;
          if (j < basis_keys.size() && basis_keys[j] == keys[r]) {
            status[static_cast<std::size_t>(n + 1) + r] =
                basis[static_cast<std::size_t>(n + 1) + j];
          }
        }
        model.copyinStatus(status.data());
      }
      model.dual();
      ++stats_.linear_programs;
      if (model.status() != 0) return false;
      if (!smoothing) {
        const unsigned char* status = model.statusArray();
        basis.assign(status, status + n + 1 + rows);
        basis_keys = keys;
      }
      const double* solution = model.primalColumnSolution();
      const double predicted = solution[n];
      if (!smoothing && predicted >= current - 1e-9) return false;  // the model sees no way down
      std::vector<PlannedStep> y(x.size());
      double moved = 0.0;  // the largest step, relative to the radius
      for (long k = 0; k < n; ++k) {
        const auto u = static_cast<std::size_t>(k);
        double s = std::clamp(x[u].s + solution[k], 0.0, end_s_);
        if (k > 0) s = std::max(s, y[u - 1].s);
        moved = std::max(moved, std::abs(s - x[u].s) / std::min(radius, g[u].reach));
        y[u] = Evaluate(s, x[u]);
      }
      std::swap(x, y);
      const double trial = excess();
      if (smoothing) {
        smoothing = false;
        if (trial <= 0.0) return roughness() < rough && Accept(a, m, std::move(x));
        current = trial;  // restore the limits from here
        fresh = false;
        continue;
      }
      if (trial < current) {
        if (trial <= 0.0) return (!smoother || roughness() < rough) && Accept(a, m, std::move(x));
        const double ratio = (current - trial) / (current - predicted);
        if (ratio > 0.5 && moved > 0.9) radius = std::min(2.0 * radius, widest);
        if (ratio < 0.1) radius *= 0.5 * std::min(moved, 1.0);
        current = trial;
        fresh = false;
      } else {
        std::swap(x, y);  // back to the iterate before
        radius *= 0.25 * std::min(moved, 1.0);
        if (radius < 1e-9) return false;
      }
    }
    return false;
  }

  bool Accept(long a, long m, std::vector<PlannedStep> x) {
    const auto first = plan_.begin() + a;
    plan_.erase(first, first + m);
    plan_.insert(plan_.begin() + a, std::make_move_iterator(x.begin()),
                 std::make_move_iterator(x.end()));
    return true;
  }

  const PathSource& path_;
  const Machine& machine_;
  LeastTimeOptions o_;
  std::vector<PlannedStep>& plan_;
  int n_axes_;
  double width_[4][kMaxAxes] = {};  // limit times dt^p, per order and axis
  double tangential_[4] = {};       // along the path, per order
  double end_s_ = 0.0;
  LeastTimeStats stats_;
};

}  // namespace

LeastTimeStats ShortenPlan(const PathSource& path, const Machine& machine,
                           const LeastTimeLimits& limits, const LeastTimeOptions& options,
                           std::vector<PlannedStep>* plan) {
  if (plan->size() < 16) return {};
  LeastTimeOptions o = options;
  o.window_periods =
      static_cast<int>(std::min<long>(o.window_periods, static_cast<long>(plan->size()) - 6));
  o.window_stride = std::max(1, std::min(o.window_stride, o.window_periods / 2));
  Shortener shortener(path, machine, limits, o, plan);
  return shortener.Run();
}

}  // namespace dtis::interp
