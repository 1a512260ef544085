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
    : machine_(machine), index_(RotaryWordAxes(machine)) {
  for (std::size_t k = 0; k < 3; ++k) {
    if (program.uses_rotary[k] && index_[k] < 0) {
      throw Error("{}: the program moves rotary axis {} but machine '{}' has none", program.file,
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

GcodePlan BuildGcodePlan(const GcodeProgram& program, const Machine& machine,
                         const interp::VpopOptions& base, const GcodeOptions& options) {
  GcodePlan plan;
  if (program.moves.empty()) throw Error("{}: the program has no moves", program.file);
  const GcodeToolAxis axis_of(program, machine);
  double rapid = options.rapid_feed_mm_s;
  if (!(rapid > 0.0)) {
    double sum = 0.0;
    for (const Axis& a : machine.Axes()) {
      if (!a.rotary) sum += a.vmax * a.vmax;
    }
    rapid = std::sqrt(sum);
  }
  const auto where = [&program](const GcodeMove& m) {
    return fmt::format("{}:{}", program.file, m.line);
  };

  Vector3d tip = program.moves.front().to;
  Vector3d axis = axis_of(program.moves.front());
  std::vector<geometry::ChainMove> chain;
  Vector3d chain_tip = tip, chain_axis = axis;
  double chain_feed = 0.0;
  int chain_first_line = 0;
  bool chain_rapid = false;

  const auto flush = [&] {
    if (chain.empty()) return;
    if (chain_rapid && chain.size() == 1) {
      // A lone rapid: the straight move it is.
      interp::VpopOptions o = base;
      o.feed_mm_s = rapid;
      std::unique_ptr<PathSource> path =
          geometry::StraightMove(chain_tip, chain[0].tip, chain_axis, chain[0].axis);
      plan.segments.push_back(
          {path.get(), o, fmt::format("{}:{}: rapid", program.file, chain[0].line)});
      plan.rapid.push_back(true);
      plan.paths.push_back(std::move(path));
      chain.clear();
      return;
    }
    geometry::CornerOptions corners = options.corners;
    corners.feed_mm_s = chain_feed;
    std::unique_ptr<geometry::G1Path> path;
    try {
      path = std::make_unique<geometry::G1Path>(chain_tip, chain_axis, chain, machine, corners);
    } catch (const Error& e) {
      throw Error("{}: {}", program.file, e.what());
    }
    plan.corners += static_cast<int>(path->Corners().size());
    if (!chain_rapid) plan.length_mm += *path->Length();
    interp::VpopOptions o = base;
    o.feed_mm_s = chain_feed;
    plan.segments.push_back({path.get(), o,
                             fmt::format("{}: lines {}-{}{}", program.file, chain_first_line,
                                         chain.back().line, chain_rapid ? " (rapids)" : "")});
    plan.rapid.push_back(chain_rapid);
    plan.paths.push_back(std::move(path));
    if (!chain_rapid) ++plan.chains;
    chain.clear();
  };

  for (std::size_t k = 1; k < program.moves.size(); ++k) {
    const GcodeMove& m = program.moves[k];
    const Vector3d next_axis = axis_of(m);
    const bool moves_tip = (m.to - tip).norm() > 1e-9;
    const bool turns = (next_axis - axis).norm() > 1e-12;
    if (!moves_tip && m.kind != GcodeMove::Kind::kArcCw && m.kind != GcodeMove::Kind::kArcCcw) {
      if (turns) {
        throw Error(
            "{}: the block turns the tool without moving its tip (not supported: give the "
            "turn some tip motion)",
            where(m));
      }
      continue;  // a repeated point
    }
    {
      // Feed moves at one feed form a chain; with blend_rapids, so do consecutive rapids.
      const bool is_rapid = m.kind == GcodeMove::Kind::kRapid;
      const double feed = is_rapid ? rapid : std::min(m.feed_mm_min / 60.0, options.max_feed_mm_s);
      if (is_rapid) ++plan.rapids;
      geometry::ChainMove c;
      c.kind = m.kind == GcodeMove::Kind::kLinear || is_rapid ? geometry::ChainMove::Kind::kLine
                                                              : geometry::ChainMove::Kind::kArc;
      c.tip = m.to;
      c.axis = next_axis;
      c.center = m.center;
      c.clockwise = m.kind == GcodeMove::Kind::kArcCw;
      c.line = m.line;
      bool joins = !chain.empty() && feed == chain_feed && is_rapid == chain_rapid &&
                   (!is_rapid || options.blend_rapids);
      if (joins) {
        const geometry::ChainMove& prev = chain.back();
        const Vector3d prev_from = chain.size() > 1 ? chain[chain.size() - 2].tip : chain_tip;
        const Vector3d out = geometry::EndTangent(prev_from, prev);
        const Vector3d in = geometry::StartTangent(tip, c);
        const double angle = geometry::Angle(out, in);
        const bool arc = prev.kind == geometry::ChainMove::Kind::kArc ||
                         c.kind == geometry::ChainMove::Kind::kArc;
        if (arc ? angle > options.tangent_rad : angle > std::numbers::pi - 1e-6) joins = false;
      }
      if (!joins) {
        flush();
        chain_tip = tip;
        chain_axis = axis;
        chain_feed = feed;
        chain_first_line = m.line;
        chain_rapid = is_rapid;
      }
      chain.push_back(c);
    }
    tip = m.to;
    axis = next_axis;
  }
  flush();
  if (plan.segments.empty()) {
    throw Error("{}: the program never moves after its first positioning move", program.file);
  }
  return plan;
}

}  // namespace dtis::io
