#include "dtis/io/gcode_program.hpp"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>

#include "dtis/core/error.hpp"
#include "dtis/geometry/angle.hpp"
#include "dtis/geometry/curve_path.hpp"

namespace dtis::io {
namespace {

using Eigen::Vector3d;

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
      rapid_feed_(options.rapid_feed_mm_s) {
  if (!(rapid_feed_ > 0.0)) {
    double sum = 0.0;
    for (const Axis& a : machine.Axes()) {
      if (!a.rotary) sum += a.vmax * a.vmax;
    }
    rapid_feed_ = std::sqrt(sum);
  }
}

GcodeSegment GcodeSegments::Flush() {
  GcodeSegment segment;
  segment.rapid = chain_rapid_;
  segment.options = base_;
  segment.options.feed_mm_s = chain_feed_;
  if (chain_rapid_ && chain_.size() == 1) {
    // A lone rapid: the straight move it is.
    segment.path = geometry::StraightMove(chain_tip_, chain_[0].tip, chain_axis_, chain_[0].axis);
    segment.name = fmt::format("{}:{}: rapid", file_, chain_[0].line);
  } else {
    geometry::CornerOptions corners = options_.corners;
    corners.feed_mm_s = chain_feed_;
    std::unique_ptr<geometry::G1Path> path;
    try {
      path = std::make_unique<geometry::G1Path>(chain_tip_, chain_axis_, chain_, machine_, corners);
    } catch (const Error& e) {
      throw Error("{}: {}", file_, e.what());
    }
    segment.corners = static_cast<int>(path->Corners().size());
    segment.name = fmt::format("{}: lines {}-{}{}", file_, chain_first_line_, chain_.back().line,
                               chain_rapid_ ? " (rapids)" : "");
    segment.path = std::move(path);
  }
  chain_.clear();
  return segment;
}

std::optional<GcodeSegment> GcodeSegments::Next() {
  const auto where = [this](const GcodeMove& m) { return fmt::format("{}:{}", file_, m.line); };
  if (!started_) {
    const std::optional<GcodeMove> first = next_();
    if (!first) throw Error("{}: the program has no moves", file_);
    tip_ = first->to;
    axis_ = axis_of_(*first);
    started_ = true;
  }
  while (!ended_) {
    const std::optional<GcodeMove> read = next_();
    if (!read) {
      ended_ = true;
      break;
    }
    const GcodeMove& m = *read;
    const Vector3d next_axis = axis_of_(m);
    const bool moves_tip = (m.to - tip_).norm() > 1e-9;
    const bool turns = (next_axis - axis_).norm() > 1e-12;
    if (!moves_tip && m.kind != GcodeMove::Kind::kArcCw && m.kind != GcodeMove::Kind::kArcCcw) {
      if (turns) {
        throw Error(
            "{}: the block turns the tool without moving its tip (not supported: give the "
            "turn some tip motion)",
            where(m));
      }
      continue;  // a repeated point
    }
    // Feed moves at one feed form a chain; with blend_rapids, so do consecutive rapids.
    const bool is_rapid = m.kind == GcodeMove::Kind::kRapid;
    const double feed =
        is_rapid ? rapid_feed_ : std::min(m.feed_mm_min / 60.0, options_.max_feed_mm_s);
    if (is_rapid) ++rapids_;
    geometry::ChainMove c;
    c.kind = m.kind == GcodeMove::Kind::kLinear || is_rapid ? geometry::ChainMove::Kind::kLine
                                                            : geometry::ChainMove::Kind::kArc;
    c.tip = m.to;
    c.axis = next_axis;
    c.center = m.center;
    c.clockwise = m.kind == GcodeMove::Kind::kArcCw;
    c.line = m.line;
    bool joins = !chain_.empty() && feed == chain_feed_ && is_rapid == chain_rapid_ &&
                 (!is_rapid || options_.blend_rapids);
    if (joins) {
      const geometry::ChainMove& prev = chain_.back();
      const Vector3d prev_from = chain_.size() > 1 ? chain_[chain_.size() - 2].tip : chain_tip_;
      const Vector3d out = geometry::EndTangent(prev_from, prev);
      const Vector3d in = geometry::StartTangent(tip_, c);
      const double angle = geometry::Angle(out, in);
      const bool arc =
          prev.kind == geometry::ChainMove::Kind::kArc || c.kind == geometry::ChainMove::Kind::kArc;
      if (arc ? angle > options_.tangent_rad : angle > std::numbers::pi - 1e-6) joins = false;
    }
    std::optional<GcodeSegment> done;
    if (!joins) {
      if (!chain_.empty()) done = Flush();
      chain_tip_ = tip_;
      chain_axis_ = axis_;
      chain_feed_ = feed;
      chain_first_line_ = m.line;
      chain_rapid_ = is_rapid;
    }
    chain_.push_back(c);
    tip_ = m.to;
    axis_ = next_axis;
    if (done) {
      ++segments_;
      return done;
    }
  }
  if (!chain_.empty()) {
    ++segments_;
    return Flush();
  }
  if (segments_ == 0) {
    throw Error("{}: the program never moves after its first positioning move", file_);
  }
  return std::nullopt;
}

GcodePlan BuildGcodePlan(const GcodeProgram& program, const Machine& machine,
                         const interp::VpopOptions& base, const GcodeOptions& options) {
  GcodePlan plan;
  std::size_t k = 0;
  GcodeSegments segments(
      [&]() -> std::optional<GcodeMove> {
        if (k == program.moves.size()) return std::nullopt;
        return program.moves[k++];
      },
      program.file, program.uses_rotary, machine, base, options);
  while (std::optional<GcodeSegment> s = segments.Next()) {
    plan.corners += s->corners;
    if (!s->rapid) {
      plan.length_mm += *s->path->Length();
      ++plan.chains;
    }
    plan.segments.push_back({s->path.get(), s->options, std::move(s->name)});
    plan.rapid.push_back(s->rapid);
    plan.paths.push_back(std::move(s->path));
  }
  plan.rapids = segments.Rapids();
  return plan;
}

}  // namespace dtis::io
