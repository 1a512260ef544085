#include "dtis/interp/program.hpp"

#include <oneapi/tbb/global_control.h>
#include <oneapi/tbb/parallel_for.h>

#include <atomic>
#include <cmath>
#include <exception>
#include <limits>
#include <memory>
#include <numbers>

#include "dtis/core/error.hpp"
#include "vector_sink.hpp"

namespace dtis::interp {
namespace {

using Planned = PlannedSegment;

void PlanOne(const ProgramSegment& seg, const Machine& machine, const VpopOptions& options,
             Planned* out, std::function<void(double, double)> advance = {}) {
  try {
    VectorSink sink;
    VpopOptions o = options;
    if (advance) o.progress = advance;
    out->summary = PlanVpop(*seg.path, machine, o, sink);
    // Its whole time, the periods at rest that hand over to the next segment included.
    if (advance) {
      advance(out->summary.end_s,
              static_cast<double>(out->summary.setpoints - 1) * options.period_s);
    }
    out->rows = std::move(sink.rows);
    out->error = nullptr;
  } catch (const Error& e) {
    out->error = std::make_exception_ptr(Error("{}: {}", seg.name, e.what()));
  } catch (...) {
    out->error = std::current_exception();
  }
}

// Shifts continuous rotary axes of `rows` by whole turns so that they start at `previous`.
// Returns false if they then do not start where it holds (StartsWhereHeld): another branch, or a
// hair away.
bool Align(const Machine& machine, const AxisVector& previous, std::vector<Setpoint>* rows) {
  const std::optional<AxisVector> shift = TurnShift(machine, previous, rows->front().q);
  if (!shift) return false;
  if (!shift->isZero()) {
    for (Setpoint& sp : *rows) sp.q += *shift;
  }
  return StartsWhereHeld(previous, rows->front().q);
}

}  // namespace

bool StartsWhereHeld(const AxisVector& previous, const AxisVector& first) {
  constexpr double kUlps = 8.0 * std::numeric_limits<double>::epsilon();
  if (previous.size() != first.size()) return false;
  for (Eigen::Index i = 0; i < previous.size(); ++i) {
    if (std::abs(first[i] - previous[i]) > kUlps * (1.0 + std::abs(previous[i]))) return false;
  }
  return true;
}

std::optional<AxisVector> TurnShift(const Machine& machine, const AxisVector& previous,
                                    const AxisVector& first) {
  const auto axes = machine.Axes();
  AxisVector shift = AxisVector::Zero(machine.AxisCount());
  for (int i = 0; i < machine.AxisCount(); ++i) {
    const double d = previous[i] - first[i];
    const double scale = 1e-9 * (1.0 + std::abs(previous[i]));
    if (std::abs(d) <= scale) continue;
    if (!axes[static_cast<std::size_t>(i)].continuous) return std::nullopt;
    const double turns = std::round(d / (2.0 * std::numbers::pi));
    if (turns == 0.0 || std::abs(d - turns * 2.0 * std::numbers::pi) > 1e-9) return std::nullopt;
    shift[i] = turns * 2.0 * std::numbers::pi;
  }
  return shift;
}

std::vector<PlannedSegment> PlanSegments(const std::vector<ProgramSegment>& segments,
                                         const Machine& machine, const ProgramOptions& options) {
  const int n = static_cast<int>(segments.size());
  std::vector<Planned> planned(segments.size());
  std::atomic<int> done{0};
  std::unique_ptr<oneapi::tbb::global_control> limit;
  if (options.threads > 0) {
    limit = std::make_unique<oneapi::tbb::global_control>(
        oneapi::tbb::global_control::max_allowed_parallelism,
        static_cast<std::size_t>(options.threads));
  }
  oneapi::tbb::parallel_for(0, n, [&](int k) {
    const auto i = static_cast<std::size_t>(k);
    std::function<void(double, double)> advance;
    if (options.advance) {
      advance = [&options, k](double s, double t) { options.advance(k, s, t); };
    }
    PlanOne(segments[i], machine, segments[i].options, &planned[i], std::move(advance));
    const int d = ++done;
    if (options.progress) options.progress(d, n);
  });
  return planned;
}

ProgramResult PlanProgram(const std::vector<ProgramSegment>& segments, const Machine& machine,
                          const ProgramOptions& options) {
  return Stitch(segments, PlanSegments(segments, machine, options), machine);
}

long DwellRows(double seconds, double period_s) {
  if (!(seconds > 0.0) || !(period_s > 0.0)) return 0;
  return std::llround(seconds / period_s);
}

ProgramResult Stitch(const std::vector<ProgramSegment>& segments,
                     std::vector<PlannedSegment> planned, const Machine& machine) {
  const int n = static_cast<int>(segments.size());
  ProgramResult result;
  for (int k = 0; k < n; ++k) {
    const auto i = static_cast<std::size_t>(k);
    if (planned[i].error) std::rethrow_exception(planned[i].error);
    if (k > 0) {
      const AxisVector& previous = result.setpoints.back().q;
      if (!Align(machine, previous, &planned[i].rows)) {
        // Another branch than where the previous segment ended, or a hair away from it (the
        // previous segment stopped within its end tolerance): plan again from there.
        VpopOptions o = segments[i].options;
        o.previous_q = previous;
        PlanOne(segments[i], machine, o, &planned[i]);
        if (planned[i].error) std::rethrow_exception(planned[i].error);
        if (!Align(machine, previous, &planned[i].rows)) {
          const AxisVector gap = planned[i].rows.front().q - previous;
          Eigen::Index axis = 0;
          gap.cwiseAbs().maxCoeff(&axis);
          throw Error(
              "{}: starts at other axis positions than where the previous segment ended (axis {} "
              "differs by {:.3g}): the path is not continuous there",
              segments[i].name, machine.Axes()[static_cast<std::size_t>(axis)].name, gap[axis]);
        }
      }
    }
    const Planned& p = planned[i];
    result.first_row.push_back(static_cast<long>(result.setpoints.size()));
    const auto append = [&](Setpoint sp) {
      sp.index = static_cast<long>(result.setpoints.size());
      result.setpoints.push_back(sp);
    };
    // Each segment starts with the row the previous one ended on: keep one of them.
    if (k == 0) append(p.rows.front());
    // A dwell: that row, held exactly where the machine is.
    Setpoint held = p.rows.front();
    held.q = result.setpoints.back().q;
    const long hold = DwellRows(segments[i].dwell_before_s, segments[i].options.period_s);
    for (long r = 0; r < hold; ++r) append(held);
    for (std::size_t r = 1; r < p.rows.size(); ++r) append(p.rows[r]);
    result.segments.push_back(p.summary);
    VpopSummary& t = result.total;
    t.setpoints = static_cast<long>(result.setpoints.size());
    t.back_offs += p.summary.back_offs;
    t.brake_tests += p.summary.brake_tests;
    t.evaluations += p.summary.evaluations;
    t.path_iterations += p.summary.path_iterations;
    t.profile_grid_points += p.summary.profile_grid_points;
    t.profile_refusals += p.summary.profile_refusals;
    t.profile_repairs += p.summary.profile_repairs;
    t.stop_proofs += p.summary.stop_proofs;
    t.blind_proofs += p.summary.blind_proofs;
    t.least_time_windows += p.summary.least_time_windows;
    t.least_time_programs += p.summary.least_time_programs;
    t.least_time_saved += p.summary.least_time_saved;
    t.end_s += p.summary.end_s;
    for (std::size_t l = 0; l < t.limited_by.size(); ++l)
      t.limited_by[l] += p.summary.limited_by[l];
  }
  // The motion ends at the last row that moves.
  long last_move = 0;
  for (long r = static_cast<long>(result.setpoints.size()) - 1; r > 0; --r) {
    if (result.setpoints[static_cast<std::size_t>(r)].q !=
        result.setpoints[static_cast<std::size_t>(r - 1)].q) {
      last_move = r;
      break;
    }
  }
  if (!result.setpoints.empty() && n > 0) {
    result.total.motion_time_s = static_cast<double>(last_move) * segments[0].options.period_s;
  }
  return result;
}

}  // namespace dtis::interp
