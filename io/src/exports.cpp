#include "dtis/io/exports.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iterator>
#include <numbers>

#include "dtis/core/error.hpp"
#include "dtis/geometry/curve_path.hpp"
#include "dtis/io/gcode_program.hpp"

namespace dtis::io {
namespace {

std::string Number(double x) { return fmt::format("{:.6f}", x); }

// The double the text of x reads back as.
double Rounded(double x) { return std::strtod(Number(x).c_str(), nullptr); }

// Comment lines; in ( ) comments, which do not nest, parentheses become brackets.
void Comments(const std::vector<std::string>& header, const char* open, const char* close,
              std::string* out) {
  for (std::string line : header) {
    if (*close) {
      std::replace(line.begin(), line.end(), '(', '[');
      std::replace(line.begin(), line.end(), ')', ']');
    }
    *out += fmt::format("{}{}{}\n", open, line, close);
  }
}

// G0 blocks from `from` (null: nowhere yet, the program's first block) to `to`, the start of pass
// p, through the links' waypoints (geometry::LinkWaypoints, as the exact run links its passes):
// `block(pose)` writes one.
template <class Block>
void LinkBlocks(const Pose* from, const Pose& to, std::size_t p, const LinkSpec& links,
                Block block) {
  if (!from) {
    block(to);
    return;
  }
  const double z = links.heights ? links.heights->TraverseZ(*from, to) : links.traverse_z_mm;
  const std::vector<Pose> way =
      geometry::LinkWaypoints(*from, to, z, links.clearance_mm, links.Straight(p));
  for (std::size_t w = 1; w < way.size(); ++w) block(way[w]);
}

}  // namespace

GcodeExport ExportG1(const std::vector<std::vector<Pose>>& passes, const Machine& machine,
                     double feed_mm_min, const LinkSpec& links,
                     const std::vector<std::string>& header, const std::string& file_name) {
  GcodeExport out;
  out.program.file = file_name;
  Comments(header, "(", ")", &out.text);
  out.text += "G21 G90 G94 G17\n";
  const std::array<int, 3> rotary = RotaryWordAxes(machine);
  for (int k = 0; k < 3; ++k) out.program.uses_rotary[static_cast<std::size_t>(k)] = rotary[k] >= 0;
  AxisVector q, previous;
  bool have_previous = false;
  const auto emit = [&](GcodeMove::Kind kind, const Pose& pose, bool with_feed,
                        const std::string& where) {
    const InverseResult ir = machine.Inverse(pose, have_previous ? &previous : nullptr, &q);
    if (ir.status != InverseStatus::kOk) {
      throw Error("{}: {}: {}", file_name, where, DescribeInverseFailure(machine, ir));
    }
    previous = q;
    have_previous = true;
    GcodeMove move;
    move.kind = kind;
    move.to = Eigen::Vector3d(Rounded(pose.tip.x()), Rounded(pose.tip.y()), Rounded(pose.tip.z()));
    std::string text = fmt::format("{} X{} Y{} Z{}", kind == GcodeMove::Kind::kRapid ? "G0" : "G1",
                                   Number(move.to.x()), Number(move.to.y()), Number(move.to.z()));
    for (int r = 0; r < 3; ++r) {
      if (rotary[static_cast<std::size_t>(r)] < 0) continue;
      const double deg = Rounded(q[rotary[static_cast<std::size_t>(r)]] * 180.0 / std::numbers::pi);
      move.rotary[static_cast<std::size_t>(r)] = deg;
      text += fmt::format(" {}{}", static_cast<char>('A' + r), Number(deg));
    }
    if (kind != GcodeMove::Kind::kRapid) {
      move.feed_mm_min = Rounded(feed_mm_min);
      if (with_feed) text += fmt::format(" F{}", Number(move.feed_mm_min));
    }
    // 1-based: the header's comment lines, the G21 line, then one line per move.
    move.line = static_cast<int>(header.size() + out.program.moves.size()) + 2;
    out.text += text + "\n";
    out.program.moves.push_back(move);
  };
  for (std::size_t p = 0; p < passes.size(); ++p) {
    const auto& poses = passes[p];
    if (poses.size() < 2) throw Error("{}: pass {} has fewer than 2 poses", file_name, p + 1);
    const std::string where =
        p == 0 ? "pass 1 start" : fmt::format("link from pass {} to pass {}", p, p + 1);
    LinkBlocks(p == 0 ? nullptr : &passes[p - 1].back(), poses.front(), p, links,
               [&](const Pose& pose) { emit(GcodeMove::Kind::kRapid, pose, false, where); });
    for (std::size_t v = 1; v < poses.size(); ++v) {
      emit(GcodeMove::Kind::kLinear, poses[v], v == 1, fmt::format("pass {}, block {}", p + 1, v));
    }
  }
  out.text += "M2\n";
  return out;
}

namespace {

std::string NumberList(const std::vector<double>& values) {
  std::string out = "[";
  for (std::size_t i = 0; i < values.size(); ++i)
    out += fmt::format("{}{}", i ? ", " : "", values[i]);
  return out + "]";
}

std::string PoleList(const std::vector<Eigen::Vector3d>& poles) {
  std::string out = "[";
  for (std::size_t i = 0; i < poles.size(); ++i) {
    out +=
        fmt::format("{}\n  [{}, {}, {}]", i ? "," : "", poles[i].x(), poles[i].y(), poles[i].z());
  }
  return out + "]";
}

// The pose at the start or end of a fitted pass.
Pose EndPose(const SplinePass& pass, bool end) {
  const auto& b = *pass.bottom;
  const double u = end ? b.LastParameter() : b.FirstParameter();
  Pose pose{b.Point(u), pass.axis};
  if (pass.top) pose.axis = (pass.top->Point(u) - pose.tip).normalized();
  return pose;
}

// G0 blocks from the end of pass p - 1 to the start of pass p (p = 0: to the start of pass 0).
template <class Block>
void LinkBlocks(const std::vector<SplinePass>& passes, std::size_t p, const LinkSpec& links,
                Block block) {
  const Pose end = p == 0 ? Pose{} : EndPose(passes[p - 1], true);
  LinkBlocks(p == 0 ? nullptr : &end, EndPose(passes[p], false), p, links, block);
}

}  // namespace

std::string FormatCurveFile(const SplinePass& pass, const std::vector<std::string>& header) {
  std::string out;
  Comments(header, "# ", "", &out);
  const auto& b = *pass.bottom;
  out += fmt::format("units = \"mm\"\ndegree = {}\nknots = {}\npoles = {}\n", b.Degree(),
                     NumberList(b.Knots()), PoleList(b.Poles()));
  if (b.Rational()) out += fmt::format("weights = {}\n", NumberList(b.Weights()));
  if (pass.top) {
    out += fmt::format("\n[top]\npoles = {}\n", PoleList(pass.top->Poles()));
    if (pass.top->Rational()) out += fmt::format("weights = {}\n", NumberList(pass.top->Weights()));
  }
  return out;
}

std::string FormatSiemensBspline(const std::vector<SplinePass>& passes, double feed_mm_min,
                                 const LinkSpec& links, const std::vector<std::string>& header) {
  std::string out;
  Comments(header, "; ", "", &out);
  const bool five = !passes.empty() && passes.front().top;
  out += "G71 G90 G64\n";
  if (five) out += "TRAORI\nORIWKS\nORICURVE\n";
  for (std::size_t p = 0; p < passes.size(); ++p) {
    LinkBlocks(passes, p, links, [&](const Pose& pose) {
      out += fmt::format("G0 X{} Y{} Z{}", Number(pose.tip.x()), Number(pose.tip.y()),
                         Number(pose.tip.z()));
      if (five) {
        out += fmt::format(" A3={} B3={} C3={}", Number(pose.axis.x()), Number(pose.axis.y()),
                           Number(pose.axis.z()));
      }
      out += "\n";
    });
    const auto& b = *passes[p].bottom;
    const auto& knots = b.Knots();
    const auto& poles = b.Poles();
    const int deg = b.Degree();
    out += fmt::format("; pass {}: {} poles\nBSPLINE SD={} F{}\n", p + 1, poles.size(), deg,
                       Number(feed_mm_min));
    // The first pole is where the tool is; each block carries the next pole, and the knot interval
    // it opens (the last `deg` blocks close the clamped end and carry none).
    for (std::size_t i = 1; i < poles.size(); ++i) {
      out += fmt::format("X{} Y{} Z{}", Number(poles[i].x()), Number(poles[i].y()),
                         Number(poles[i].z()));
      if (five) {
        const auto& t = passes[p].top->Poles()[i];
        out += fmt::format(" XH={} YH={} ZH={}", Number(t.x()), Number(t.y()), Number(t.z()));
      }
      const std::size_t k = i + static_cast<std::size_t>(deg);
      if (k < knots.size() - static_cast<std::size_t>(deg)) {
        out += fmt::format(" PL={}", Number(knots[k] - knots[k - 1]));
      }
      out += "\n";
    }
    out += "G1\n";
  }
  out += "M30\n";
  return out;
}

bool PlanarXY(const std::vector<SplinePass>& passes, double tol_mm) {
  for (const auto& pass : passes) {
    if (pass.top || (pass.axis - Eigen::Vector3d::UnitZ()).norm() > 1e-12) return false;
    const auto& poles = pass.bottom->Poles();
    for (const auto& p : poles) {
      if (std::abs(p.z() - poles.front().z()) > tol_mm) return false;
    }
  }
  return !passes.empty();
}

std::string FormatLinuxcncNurbs(const std::vector<SplinePass>& passes, double feed_mm_min,
                                const LinkSpec& links, const std::vector<std::string>& header) {
  for (std::size_t p = 0; p < passes.size(); ++p) {
    const auto& b = *passes[p].bottom;
    if (!PlanarXY({passes[p]}, 1e-9)) {
      throw Error(
          "pass {}: LinuxCNC's G5.2 is XY only: the pass must lie in a plane z = const "
          "with a vertical tool axis",
          p + 1);
    }
    const auto& U = b.Knots();
    const std::size_t d = static_cast<std::size_t>(b.Degree());
    const double first = U[d + 1] - U[d];
    for (std::size_t k = d; k + d + 1 < U.size(); ++k) {
      if (std::abs((U[k + 1] - U[k]) - first) > 1e-9 * (U.back() - U.front())) {
        throw Error("pass {}: G5.2 assumes uniform knots: fit with uniform_knots", p + 1);
      }
    }
  }
  std::string out;
  Comments(header, "(", ")", &out);
  out += "G21 G90 G94 G17\n";
  for (std::size_t p = 0; p < passes.size(); ++p) {
    LinkBlocks(passes, p, links, [&](const Pose& pose) {
      out += fmt::format("G0 X{} Y{} Z{}\n", Number(pose.tip.x()), Number(pose.tip.y()),
                         Number(pose.tip.z()));
    });
    const auto& b = *passes[p].bottom;
    const auto& poles = b.Poles();
    // The first control point is the current position; L is the order.
    out += fmt::format("F{}\n", Number(feed_mm_min));
    for (std::size_t i = 1; i < poles.size(); ++i) {
      const double w = b.Rational() ? b.Weights()[i] : 1.0;
      out += fmt::format("{}X{} Y{} P{}{}\n", i == 1 ? "G5.2 " : "", Number(poles[i].x()),
                         Number(poles[i].y()), Number(w),
                         i == 1 ? fmt::format(" L{}", b.Degree() + 1) : "");
    }
    out += "G5.3\n";
  }
  out += "M2\n";
  return out;
}

}  // namespace dtis::io
