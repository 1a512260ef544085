#include "dtis/io/gcode_program.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <numbers>
#include <utility>

#include "dtis/core/error.hpp"
#include "dtis/geometry/angle.hpp"
#include "dtis/geometry/curve_path.hpp"
#include "dtis/io/setpoint_file.hpp"
#include "dtis/io/tool_table.hpp"

namespace dtis::io {
namespace {

using Eigen::Vector3d;

// LinuxCNC's G5.2 curve: `order` - 1 the degree, knots clamped and uniform (k zeros, then 1, 2, …,
// then k times the last), rational unless every weight is 1.
std::shared_ptr<const geometry::BSplineCurve> NurbsCurve(const GcodeMove::Nurbs& n,
                                                         const std::string& file, int line) {
  geometry::BSplineCurveData data;
  data.degree = n.order - 1;
  const int count = static_cast<int>(n.poles.size());
  for (int i = 0; i < count + n.order; ++i) {
    data.knots.push_back(i < n.order ? 0.0 : i < count ? i - n.order + 1 : count - n.order + 1);
  }
  data.poles = n.poles;
  for (const double w : n.weights) {
    if (w != 1.0) data.weights = n.weights;
  }
  return std::make_shared<const geometry::BSplineCurve>(std::move(data),
                                                        fmt::format("{}:{}: G5.2", file, line));
}

}  // namespace

std::array<int, 3> RotaryWordAxes(const Machine& machine) {
  std::array<int, 3> index{-1, -1, -1};
  const auto axes = machine.Axes();
  for (int k = 0; k < 3; ++k) {
    for (std::size_t i = 0; i < axes.size(); ++i) {
      if (axes[i].rotary && axes[i].name == std::string(1, static_cast<char>('A' + k))) {
        index[static_cast<std::size_t>(k)] = static_cast<int>(i);
      }
    }
  }
  return index;
}

GcodeStart GcodeStartOf(const GcodeOptions& options, const Machine& machine) {
  GcodeStart start;
  start.parameters = options.parameters;
  const int axes = machine.AxisCount();
  if (options.from.empty()) return start;
  const int given = static_cast<int>(options.from.size());
  if (given != 3 && given != axes) {
    throw Error("from: {} values; machine '{}' has {} axes: give X, Y, Z{} (mm{})", given,
                machine.Name(), axes, axes > 3 ? " or every axis" : "",
                axes > 3 ? ", degrees" : "");
  }
  std::vector<double> values = options.from;
  values.resize(static_cast<std::size_t>(axes), 0.0);
  start.tip = Vector3d(values[0], values[1], values[2]);
  const std::array<int, 3> rotary = RotaryWordAxes(machine);
  for (std::size_t k = 0; k < 3; ++k) {
    if (rotary[k] >= 0) start.rotary[k] = values[static_cast<std::size_t>(rotary[k])];
  }
  return start;
}

std::vector<double> GcodeFrom(const AxisVector& q, const Machine& machine) {
  std::vector<double> values(static_cast<std::size_t>(machine.AxisCount()));
  FileUnits(machine).FromPlanner(q, values.data());
  const Vector3d tip = machine.Forward(q).tip;
  for (int k = 0; k < 3; ++k) values[static_cast<std::size_t>(k)] = tip[k];
  return values;
}

GcodeToolAxis::GcodeToolAxis(const GcodeProgram& program, const Machine& machine)
    : GcodeToolAxis(program.file, program.uses_rotary, machine) {}

GcodeToolAxis::GcodeToolAxis(const std::string& file, const std::array<bool, 3>& uses_rotary,
                             const Machine& machine)
    : machine_(machine), index_(RotaryWordAxes(machine)) {
  for (std::size_t k = 0; k < 3; ++k) {
    if (uses_rotary[k] && index_[k] < 0) {
      throw Error("{}: the program moves rotary axis {} but machine '{}' has none", file,
                  static_cast<char>('A' + k), machine.Name());
    }
  }
}

Vector3d GcodeToolAxis::operator()(const GcodeMove& m) const {
  AxisVector q = AxisVector::Zero(machine_.AxisCount());
  for (std::size_t k = 0; k < 3; ++k) {
    if (index_[k] >= 0) q[index_[k]] = m.rotary[k] * std::numbers::pi / 180.0;
  }
  return machine_.Forward(q).axis;
}

GcodeSegments::GcodeSegments(MoveSource next, std::string file,
                             const std::array<bool, 3>& uses_rotary, const Machine& machine,
                             const interp::VpopOptions& base, const GcodeOptions& options)
    : next_(std::move(next)),
      file_(std::move(file)),
      machine_(machine),
      axis_of_(file_, uses_rotary, machine),
      base_(base),
      options_(options),
      rapid_feed_(RapidFeed(options, machine)),
      least_(file_, base.max_motion_s) {
  // The program starts where the machine is.
  const GcodeStart start = GcodeStartOf(options, machine);
  tip_ = start_tip_ = start.tip;
  GcodeMove at;
  at.rotary = start.rotary;
  axis_ = axis_of_(at);
  if (options.tool_table) {
    const std::array<int, 3> rotary = RotaryWordAxes(machine);
    if (std::any_of(rotary.begin(), rotary.end(), [](int axis) { return axis >= 0; })) {
      throw Error(
          "{}: the tool table {} gives tool length offsets, which dtis applies as LinuxCNC "
          "does on an XYZ machine (a translation of the programmed tip); machine '{}' turns the "
          "tool or the table, where the tool length belongs to its kinematics: leave tool_table "
          "out and program the tip (TCP)",
          file_, options.tool_table->file, machine.Name());
    }
  }
}

GcodeReadOptions JobReadOptions(const GcodeOptions& options, const std::string& job_file) {
  GcodeReadOptions read;
  read.max_blocks = options.max_blocks;
  read.remedy = fmt::format(
      "max_blocks in the [path] of {} raises it (each block held costs about 1 KB; dtis stream "
      "reads a longer program in constant memory)",
      job_file);
  return read;
}

double RapidFeed(const GcodeOptions& options, const Machine& machine) {
  if (options.rapid_feed_mm_s > 0.0) return options.rapid_feed_mm_s;
  double sum = 0.0;
  for (const Axis& a : machine.Axes()) {
    if (!a.rotary) sum += a.vmax * a.vmax;
  }
  return std::sqrt(sum);
}

GcodeSegment GcodeSegments::ChainSegment() const {
  GcodeSegment segment;
  segment.rapid = chain_rapid_;
  segment.options = base_;
  segment.options.feed_mm_s = chain_feed_;
  segment.dwell_before_s = chain_dwell_;
  return segment;
}

// The chain smoothed from `moves` (all of them, or a Window), its errors naming the file.
template <typename Moves>
std::unique_ptr<geometry::G1Path> GcodeSegments::Smooth(Moves&& moves) const {
  geometry::CornerOptions corners = options_.corners;
  corners.feed_mm_s = chain_feed_;
  if (chain_tolerance_ > 0.0) corners.contour_tol_mm = chain_tolerance_;
  try {
    return std::make_unique<geometry::G1Path>(chain_tip_, chain_axis_, std::forward<Moves>(moves),
                                              machine_, corners);
  } catch (const Error& e) {
    throw Error("{}: {}", file_, e.what());
  }
}

GcodeSegment GcodeSegments::Flush() {
  GcodeSegment segment = ChainSegment();
  segment.five_axis = chain_five_axis_;
  if (chain_nurbs_) {
    // A G5.2 curve: the exact NURBS, the tool axis held.
    if (!scan_only_) {
      try {
        segment.path = std::make_unique<geometry::CurvePath>(*chain_nurbs_, chain_axis_);
      } catch (const Error& e) {
        throw Error("{}:{}: {}", file_, last_.line, e.what());
      }
    }
    segment.name = fmt::format("{}:{}: NURBS (G5.2)", file_, last_.line);
  } else if (chain_rapid_ && chain_moves_ == 1) {
    // A lone rapid: the straight move it is.
    if (!scan_only_) {
      segment.path = geometry::StraightMove(chain_tip_, chain_[0].tip, chain_axis_, chain_[0].axis);
    }
    segment.name = fmt::format("{}:{}: rapid", file_, last_.line);
  } else {
    segment.windowed = options_.window_blocks > 0 && chain_moves_ > options_.window_blocks;
    if (!scan_only_) {
      std::unique_ptr<geometry::G1Path> path = Smooth(chain_);
      segment.corners = static_cast<int>(path->Corners().size());
      segment.path = std::move(path);
    }
    segment.name = fmt::format("{}: lines {}-{}{}", file_, chain_first_line_, last_.line,
                               chain_rapid_ ? " (rapids)" : "");
  }
  chain_.clear();
  chain_moves_ = 0;
  return segment;
}

// A chain of more than window_blocks moves: the path takes the moves read so far and reads the
// rest from here (PullJoined) as the planner reaches them.
GcodeSegment GcodeSegments::FlushWindowed() {
  if (windowed_ >= windowed_five_axis_.size()) {
    throw Error("{}: internal: a chain longer than {} blocks was not scanned before", file_,
                options_.window_blocks);
  }
  GcodeSegment segment = ChainSegment();
  segment.windowed = true;
  segment.five_axis = windowed_five_axis_[windowed_++];
  segment.name =
      fmt::format("{}: lines {}-{}", file_, chain_first_line_, chain_rapid_ ? " (rapids)" : "");
  geometry::G1Path::Window window;
  window.first = std::move(chain_);
  window.more = [this] { return PullJoined(); };
  window.five_axis = segment.five_axis;
  window.context = file_;
  window.behind_remedy = fmt::format(
      "hold chains whole with window_blocks = 0 in the job's [path] (this chain has more than {} "
      "blocks), and please report it with the program",
      options_.window_blocks);
  chain_.clear();
  chain_moves_ = 0;
  windowed_open_ = true;
  segment.path = Smooth(std::move(window));
  return segment;
}

std::optional<GcodeSegments::Read> GcodeSegments::ReadMove() {
  for (;;) {
    const std::optional<GcodeMove> read = next_();
    if (!read) return std::nullopt;
    const GcodeMove& m = *read;
    const Vector3d next_axis = axis_of_(m);
    const bool moves_tip = (m.to - tip_).norm() > 1e-9;
    const bool turns = (next_axis - axis_).norm() > 1e-12;
    if (!moves_tip && m.kind != GcodeMove::Kind::kArcCw && m.kind != GcodeMove::Kind::kArcCcw &&
        m.kind != GcodeMove::Kind::kNurbs) {
      if (turns) {
        throw Error(
            "{}:{}: the block turns the tool without moving its tip (not supported: give the "
            "turn some tip motion)",
            file_, m.line);
      }
      skipped_rest_ = skipped_rest_ || m.rest_before;
      skipped_dwell_ += m.dwell_s;
      continue;  // a repeated point
    }
    Read r;
    r.rapid = m.kind == GcodeMove::Kind::kRapid;
    r.feed = MoveFeed(m, options_, rapid_feed_);
    if (r.rapid) ++rapids_;
    geometry::ChainMove& c = r.move;
    c.kind = m.kind == GcodeMove::Kind::kLinear || r.rapid ? geometry::ChainMove::Kind::kLine
                                                           : geometry::ChainMove::Kind::kArc;
    c.tip = m.to;
    c.axis = next_axis;
    c.center = m.center;
    c.normal = m.normal;
    c.clockwise = m.kind == GcodeMove::Kind::kArcCw;
    c.turns = m.turns;
    c.line = m.line;
    r.tolerance_mm = m.tolerance_mm;
    r.stop = m.stop;
    r.rest_before = m.rest_before || std::exchange(skipped_rest_, false);
    r.dwell_s = m.dwell_s + std::exchange(skipped_dwell_, 0.0);
    if (m.kind == GcodeMove::Kind::kNurbs) r.nurbs = NurbsCurve(*m.nurbs, file_, m.line);
    least_.Add(m, tip_, r.feed, r.dwell_s);
    return r;
  }
}

double MoveFeed(const GcodeMove& m, const GcodeOptions& options, double rapid_feed_mm_s) {
  return m.kind == GcodeMove::Kind::kRapid ? rapid_feed_mm_s
                                           : std::min(m.feed_mm_min / 60.0, options.max_feed_mm_s);
}

namespace {

// An arc's radius times its sweep in its plane (the helix' rise left out), from `from`: no more
// than its length.
double ArcSweepLength(const GcodeMove& m, const Vector3d& from) {
  const Vector3d n = m.normal.normalized();
  const auto in_plane = [&](const Vector3d& v) { return v - n * n.dot(v); };
  const Vector3d u = in_plane(from - m.center), v = in_plane(m.to - m.center);
  const double r = u.norm();
  if (!(r > 0.0) || !n.allFinite()) return 0.0;
  double sweep = std::atan2(n.dot(u.cross(v)), u.dot(v));  // counterclockwise about n
  if (m.kind == GcodeMove::Kind::kArcCw) sweep = -sweep;
  if (sweep <= 1e-12) sweep += 2.0 * std::numbers::pi;  // the same point again: a whole turn
  return r * (sweep + 2.0 * std::numbers::pi * std::max(0, m.turns - 1));
}

}  // namespace

void ProgramLeastTime::Add(const GcodeMove& m, const Vector3d& from, double feed_mm_s,
                           double dwell_s) {
  // A move is no shorter than its chord, an arc than its sweep.
  double length = (m.to - from).norm();
  if (m.kind == GcodeMove::Kind::kArcCw || m.kind == GcodeMove::Kind::kArcCcw) {
    const double sweep = ArcSweepLength(m, from);
    if (std::isfinite(sweep)) length = std::max(length, sweep);
  }
  const double move_s = length / feed_mm_s, block_s = move_s + dwell_s;
  seconds_ += block_s;
  if (seconds_ <= max_s_) return;
  std::string what;
  if (dwell_s >= move_s) {
    what = fmt::format("a dwell (G4) of {:.6g} s before it", dwell_s);
  } else if (m.kind == GcodeMove::Kind::kRapid) {
    what = fmt::format(
        "its rapid of {:.6g} mm at {:.6g} mm/min ([path] rapid_feed_mm_min, or the "
        "machine's velocities)",
        length, feed_mm_s * 60.0);
  } else {
    what = fmt::format("its move of {:.6g} mm at F{:.6g} mm/min", length, feed_mm_s * 60.0);
  }
  throw Error(
      "{}:{}: the program takes at least {:.3g} h up to this block, more than the {:g} h a job may "
      "take; this block alone takes {:.3g} h: {}{}",
      file_, m.line, seconds_ / 3600.0, max_s_ / 3600.0, block_s / 3600.0, what,
      block_s < 0.01 * seconds_ ? " (does a loop repeat more often than meant?)" : "");
}

// Feed moves at one feed form a chain; with blend_rapids, so do consecutive rapids. A chain ends
// where an arc meets its neighbour at an angle, or the path turns back on itself.
bool GcodeSegments::Joins(const Read& r) const {
  if (r.feed != chain_feed_ || r.rapid != chain_rapid_ || (r.rapid && !options_.blend_rapids)) {
    return false;
  }
  if (last_stop_ || r.rest_before || r.tolerance_mm != chain_tolerance_) return false;
  if (r.nurbs || chain_nurbs_) return false;  // a G5.2 curve is planned alone, rest to rest
  const Vector3d out = geometry::EndTangent(last_from_, last_);
  const Vector3d in = geometry::StartTangent(tip_, r.move);
  const double angle = geometry::Angle(out, in);
  const bool arc = last_.kind == geometry::ChainMove::Kind::kArc ||
                   r.move.kind == geometry::ChainMove::Kind::kArc;
  return !(arc ? angle > options_.tangent_rad : angle > std::numbers::pi - 1e-6);
}

void GcodeSegments::Open(const Read& r) {
  chain_tip_ = tip_;
  chain_axis_ = axis_;
  chain_feed_ = r.feed;
  chain_tolerance_ = r.tolerance_mm;
  chain_dwell_ = r.dwell_s;
  chain_nurbs_ = r.nurbs;
  chain_first_line_ = r.move.line;
  chain_rapid_ = r.rapid;
  chain_five_axis_ = false;
  chain_.clear();
  chain_moves_ = 0;
  Append(r);
}

void GcodeSegments::Append(const Read& r) {
  if (!windowed_open_) {
    if (!scan_only_) chain_.push_back(r.move);
    ++chain_moves_;
  }
  // As G1Path decides it for the chain: some move's axis away from the start's.
  if ((r.move.axis.normalized() - chain_axis_.normalized()).norm() > 1e-12) {
    chain_five_axis_ = true;
  }
  last_from_ = tip_;
  last_ = r.move;
  last_stop_ = r.stop;
  tip_ = r.move.tip;
  axis_ = r.move.axis;
}

std::optional<geometry::ChainMove> GcodeSegments::PullJoined() {
  if (!windowed_open_) return std::nullopt;
  std::optional<Read> r = ReadMove();
  if (!r) {
    ended_ = true;
    windowed_open_ = false;
    return std::nullopt;
  }
  if (!Joins(*r)) {
    windowed_open_ = false;
    Open(*r);  // the next chain's first move
    return std::nullopt;
  }
  Append(*r);
  return r->move;
}

std::optional<GcodeSegment> GcodeSegments::Next() {
  if (!started_ && options_.start_at_first_move) {
    const std::optional<GcodeMove> first = next_();
    if (!first) throw Error("{}: the program has no moves", file_);
    tip_ = start_tip_ = first->to;
    axis_ = axis_of_(*first);
  }
  started_ = true;
  while (windowed_open_) PullJoined();  // what a windowed chain was not asked to read
  while (!ended_) {
    std::optional<Read> r = ReadMove();
    if (!r) {
      ended_ = true;
      break;
    }
    std::optional<GcodeSegment> done;
    if (chain_moves_ > 0 && Joins(*r)) {
      Append(*r);
    } else {
      if (chain_moves_ > 0) done = Flush();
      Open(*r);
    }
    if (done) {
      ++segments_;
      return done;
    }
    if (!scan_only_ && options_.window_blocks > 0 && chain_moves_ > options_.window_blocks) {
      ++segments_;
      return FlushWindowed();
    }
  }
  if (chain_moves_ > 0) {
    ++segments_;
    return Flush();
  }
  if (segments_ == 0) {
    throw Error("{}: the program never moves from where it starts ({:g}, {:g}, {:g} mm)", file_,
                start_tip_.x(), start_tip_.y(), start_tip_.z());
  }
  return std::nullopt;
}

GcodePlan BuildGcodePlan(const GcodeProgram& program, const Machine& machine,
                         const interp::VpopOptions& base, const GcodeOptions& options) {
  GcodePlan plan;
  std::size_t k = 0;
  GcodeOptions whole = options;
  whole.window_blocks = 0;
  GcodeSegments segments(
      [&]() -> std::optional<GcodeMove> {
        if (k == program.moves.size()) return std::nullopt;
        return program.moves[k++];
      },
      program.file, program.uses_rotary, machine, base, whole);
  while (std::optional<GcodeSegment> s = segments.Next()) {
    plan.corners += s->corners;
    if (!s->rapid) {
      plan.length_mm += *s->path->Length();
      ++plan.chains;
    }
    plan.segments.push_back({s->path.get(), s->options, std::move(s->name), s->dwell_before_s});
    plan.rapid.push_back(s->rapid);
    plan.paths.push_back(std::move(s->path));
  }
  plan.rapids = segments.Rapids();
  plan.least_time_s = segments.LeastTime();
  return plan;
}

}  // namespace dtis::io
