// The ISO 14649-11 freeform strategies: from a face, a tool, an orientation rule and a stepover to
// the list of passes, each a SurfacePass (a PathSource solved by Newton on the exact surface).
//
// plane_cl: the tool tip in parallel planes (the offset surface cut by planes); plane_cc: the
// contact point in parallel planes; uv: iso-parametric lines, forward along u (iso-v lines) or v.
// A line of the strategy may cross the face several times: each crossing is a pass, running from
// where it enters the face's (trimmed) domain to where it leaves it. Passes are found by scanning
// the face's boundary for the lines' roots and tracing each once (length, gouge check).
// leading_line: contact points whose XY lies on a guide curve offset in XY by whole stepovers.
#pragma once

#include <array>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "dtis/geometry/check_faces.hpp"
#include "dtis/geometry/face_surface.hpp"
#include "dtis/geometry/tool.hpp"
#include "dtis/strategies/orientation.hpp"
#include "dtis/strategies/surface_pass.hpp"

namespace dtis::strategies {

struct StrategySpec {
  enum class Kind { kPlaneCl, kPlaneCc, kUv, kLeadingLine };
  enum class PathMode { kForward, kZigzag };
  enum class Side { kAuto, kFace, kReversed };
  // Where the tool would go into the face (a concave region tighter than the tool, a flat bottom
  // across a valley) or touch it with its upper side: kSkip cuts the pass there and goes on where
  // the tool fits again (PassList::unreachable says what was left); kStop refuses the job.
  enum class OnGouge { kSkip, kStop };

  Kind kind = Kind::kPlaneCl;
  // Plane strategies: the planes' normal, and the direction of travel (the feed direction is the
  // tangent plane cut by the strategy plane, oriented along this vector).
  Eigen::Vector3d plane_normal = Eigen::Vector3d::UnitX();
  Eigen::Vector3d direction = Eigen::Vector3d::UnitY();
  // leading_line: the guide curve (its XY counts: it is projected along Z onto the face); passes
  // follow it, offset by whole stepovers to its left (+) and right (-) in XY, travelling the
  // guide's way.
  std::shared_ptr<const geometry::BSplineCurve> guide;
  // uv: passes along u (iso-v lines) or along v; travel towards increasing parameter.
  bool along_u = true;
  PathMode mode = PathMode::kForward;
  // Distance between neighbouring lines, mm; 0: from scallop_mm.
  double stepover_mm = 0.0;
  double scallop_mm = 0.0;
  // Lines inside [first, last] only: plane offsets in mm along the normal, or parameter values for
  // uv. Without it the lines cover the face, half a stepover in from its extremes.
  std::optional<std::array<double, 2>> range;
  int max_passes = 0;  // 0: all
  // Where stepover_mm (or scallop_mm) and range were given, for the message that refuses more than
  // kMaxLines lines (e.g. "job.toml:12: key 'strategy.stepover_mm'"); "" : "stepover_mm", "range".
  std::string stepover_key, range_key;
  // The most strategy lines one face is traced with (0.01 mm across 100 mm; tracing one takes some
  // 10 ms): more (a stepover of 1 um, a range of 1e300 mm) is
  // an error naming stepover_key or range_key, before any line is traced.
  static constexpr long kMaxLines = 10'000;
  // The box (mm, in the workpiece frame) the tool tip stays in: passes end where the tip reaches
  // a side of it (a part larger than the machine's travel, finished in parts). Unbounded when
  // unset; a side may be infinite.
  struct Bounds {
    Eigen::Vector3d min, max;
    bool Contain(const Eigen::Vector3d& p) const {
      return (p.array() >= min.array()).all() && (p.array() <= max.array()).all();
    }
  };
  std::optional<Bounds> bounds;
  // kAuto: the outside of a face that bounds a solid (`bounds_solid`: its outward normal, from
  // its orientation in the solid), else the side whose normal points up (+Z) over most of it.
  Side side = Side::kAuto;
  bool bounds_solid = false;
  OnGouge on_gouge = OnGouge::kSkip;
  // Faces the tool must not go into besides the one it finishes (the part's others): where it
  // would, the tool does not fit, as where it gouges its own face. None when null.
  std::shared_ptr<const geometry::CheckFaces> check;
  NewtonOptions newton;

  static const char* KindName(Kind kind);
};

// A stretch of a strategy line the tool cannot finish without going into the face, left out of
// the passes (StrategySpec::OnGouge::kSkip).
struct Unreachable {
  int line = 0;                                    // the strategy line, 1-based
  Eigen::Vector3d from = Eigen::Vector3d::Zero();  // contact point where the tool last fits
  Eigen::Vector3d to = Eigen::Vector3d::Zero();    // where it fits again, or where the trace stops
  double length_mm = 0.0;  // of the line on the face (the contact point's path) left out
  bool resumes = false;    // false: the line is not finished past it
  bool ridden_over =
      false;         // the tool moves straight across it (SurfacePass::RidesOverFromPrevious)
  std::string why;   // the first reason met on it
  std::string face;  // which face, when a job finishes several ("" otherwise)
};

struct PassList {
  std::vector<std::unique_ptr<SurfacePass>> passes;
  std::vector<Unreachable> unreachable;
  double stepover_mm = 0.0;  // used between lines (mm; for uv the nominal distance)
  int side = 1;              // +1: the side of S_u x S_v was machined
  std::string Summary() const;
  // The stretches left out, a line each (at most `most`, then how many more), or "".
  std::string UnreachableText(std::size_t most) const;
};

// Throws dtis::Error naming the face, line, arc length and (u, v) on a degenerate normal, a
// gouge or undercut (OnGouge::kStop), an undefined feed direction, a range that misses the face,
// a pass that never ends.
PassList BuildPasses(const geometry::FaceSurface& face, const geometry::Tool& tool,
                     const Orientation& orientation, const StrategySpec& spec);

// The stepover leaving a scallop of height h between passes on a flat surface: 2 sqrt(h (2 R - h))
// with the tool's effective radius across the feed: the ball radius; r + R / sin(tilt) for a
// torus leaning by `tilt` along the feed; the corner radius r for a fixed axis (its worst case).
double StepoverFromScallop(const geometry::Tool& tool, const Orientation& orientation, double h);

}  // namespace dtis::strategies
