// One pass of a surface strategy as a PathSource (DTIS, Beudaert et al. 2014, §2.3).
//
// A pass is the set of contact points (u, v) on the face where the strategy's constraint g(u, v) is
// zero: the tool tip in a plane (plane_cl), the contact point in a plane (plane_cc), or an
// iso-parametric line (uv). Its arc length s is that of the tool tip. For a trial arc length the
// pose comes from a Newton solve on the exact surface, warm-started from the given state:
//     g(u, v) = 0  and  arc(tip(state), tip(u, v)) = s' - s,
// where the chord c is such that the arc between the two states (from the chord and the angle of
// their tangents) is the requested step, to 1e-10 mm, so that the arc length of a pose does not
// depend on the steps that reached it. The Jacobian is exact: the normal, feed direction, tool
// axis and tip are computed with forward-mode derivatives (ceres::Jet) from the surface's second
// derivatives. Nothing is tabulated: a pass holds its start, its end and its length, found by the
// builder when it traced the pass once.
//
// A SurfacePass evaluates its face through its own FaceSurface (an OpenCASCADE cache): use one pass
// from one thread at a time.
#pragma once

#include <Eigen/Core>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "dtis/core/path_source.hpp"
#include "dtis/geometry/bspline_curve.hpp"
#include "dtis/geometry/face_surface.hpp"
#include "dtis/geometry/tool.hpp"
#include "dtis/strategies/axis_law.hpp"
#include "dtis/strategies/orientation.hpp"

namespace dtis::strategies {

// What g(u, v) = 0 means for one pass.
struct PassConstraint {
  enum class Kind { kPlaneCl, kPlaneCc, kIsoV, kIsoU, kGuide };
  Kind kind = Kind::kPlaneCl;
  Eigen::Vector3d normal = Eigen::Vector3d::UnitX();  // plane strategies: unit plane normal
  // plane: normal . x = value (mm); iso lines: the fixed parameter; guide: the offset from the
  // guide curve (mm, positive to its left in XY).
  double value = 0.0;
  double iso_scale = 1.0;  // iso lines: mm per parameter unit, so that g is in mm
  // leading_line: the guide curve; a pass is where the contact point, seen from above (XY), is
  // `value` mm to the left of it.
  std::shared_ptr<const geometry::BSplineCurve> guide;
  // The feed direction f is sign * unit(n x normal) for planes (the tangent plane cut by the
  // strategy plane), sign * unit(S_u) for iso-v lines and sign * unit(S_v) for iso-u lines, and
  // sign * unit(n x N) for a guide, N the guide's horizontal normal at the closest point.
  int feed_sign = 1;

  std::string Describe() const;
};

struct NewtonOptions {
  double tolerance_mm = 1e-6;  // |g| and the chord residual, mm (the paper's 0.001 um)
  int max_iterations = 12;
  // Longer moves are split into steps of at most this length: the builder traces passes with the
  // same step, so that a march follows the trace's branch where a pass nears another one.
  double max_step_mm = 0.1;
  // Each step's arc length, and the strategy's constraint when Newton gets there cheaply, are met
  // to this: arc lengths summed over steps of any size then agree, so the pose at an arc length
  // does not depend on the state it was reached from, and poses do not jitter across the line.
  double arc_tolerance_mm = 1e-10;
};

enum class EvalStatus {
  kOk,
  kDegenerateNormal,
  kFeedUndefined,
  kFlatContact,
  kGuideFold,
  kStalled
};
const char* EvalStatusText(EvalStatus status);

// Everything known at one contact point.
struct ContactPoint {
  Eigen::Vector2d uv = Eigen::Vector2d::Zero();
  Eigen::Vector3d p, n, feed, axis, tip;  // contact point, unit normal, feed, tool axis, tool tip
  Eigen::Matrix<double, 3, 2> dp, dtip;   // d/d(u, v)
  double g = 0.0;                         // strategy residual, mm
  Eigen::Vector2d dg = Eigen::Vector2d::Zero();
  Eigen::Vector2d duv = Eigen::Vector2d::Zero();  // d(u, v)/ds along the travel
  Eigen::Vector3d tangent;                        // unit tip tangent along the travel
  double concave_curvature = 0.0;  // largest principal curvature bending towards the tool, 1/mm
  // leading_line: parameter of the closest guide point, the warm start of the next evaluation
  // (the distance to a bending guide has several local minima: a pass follows its own).
  double guide_t = std::numeric_limits<double>::quiet_NaN();
  // leading_line: the contact point's offset from the guide times the guide's curvature there
  // (signed, both positive to the left); 1 where the offset line folds over itself.
  double guide_fold = 0.0;
  // With an axis law (PassEvaluator::SetAxisLaw): the pass's arc length whose axis the law gave
  // (NaN: the orientation rule's axis), and the rule's axis here, which the law's stays near.
  double s = std::numeric_limits<double>::quiet_NaN();
  Eigen::Vector3d rule_axis = Eigen::Vector3d::Zero();
};

// Surface + tool + orientation + constraint: the geometry of one pass.
class PassEvaluator {
 public:
  // side: +1 machines the side of S_u x S_v, -1 the other.
  PassEvaluator(const geometry::FaceSurface& face, const geometry::Tool& tool,
                const Orientation& orientation, int side, const PassConstraint& constraint);
  PassEvaluator(const PassEvaluator&) = default;

  // guide_hint: leading_line's closest guide parameter near this point (NaN: search the guide).
  // The tool axis is the orientation rule's. kFlatContact on a line that holds the contact point
  // (not plane_cl) still fills `out`, with the tip on the contact point (one of the places a flat
  // bottom sitting on a top may stand).
  EvalStatus Evaluate(const Eigen::Vector2d& uv, ContactPoint* out,
                      double guide_hint = std::numeric_limits<double>::quiet_NaN()) const {
    return EvaluateAt(uv, std::numeric_limits<double>::quiet_NaN(), out, guide_hint);
  }
  // With an axis law and a finite s, the tool axis is the law's at arc length s (fixed: the
  // derivatives in (u, v) hold the axis, and the travel direction and tangent include the axis'
  // turning along s); otherwise the rule's.
  EvalStatus EvaluateAt(const Eigen::Vector2d& uv, double s, ContactPoint* out,
                        double guide_hint = std::numeric_limits<double>::quiet_NaN()) const;
  // The pass's axis follows `law` in its arc length instead of the rule (null: the rule). The
  // solves below then carry the arc length: from a point at s, a step of delta reaches s + delta.
  void SetAxisLaw(std::shared_ptr<const AxisLaw> law) { law_ = std::move(law); }
  const AxisLaw* Law() const { return law_.get(); }
  // Newton: the point with g = 0 whose tip is `chord` mm from `anchor`, from `uv`. Returns the
  // iterations (updates) spent, or -1 if it did not converge; `status` says why it stopped.
  // With an axis law, the point's axis is the law's at arc length `s`.
  int SolveChord(const Eigen::Vector3d& anchor, double chord, Eigen::Vector2d uv,
                 const NewtonOptions& options, ContactPoint* out, EvalStatus* status,
                 double anchor_guide_t = std::numeric_limits<double>::quiet_NaN(),
                 double s = std::numeric_limits<double>::quiet_NaN()) const;
  // Newton: the point with g = 0 whose tip is |delta| mm of arc from `from`'s (arc from the chord
  // and the tangents, ArcFromChord), from `uv`. Iterations spent, or -1.
  int SolveArc(const ContactPoint& from, double delta, Eigen::Vector2d uv,
               const NewtonOptions& options, ContactPoint* out, EvalStatus* status) const;
  // One step of `delta` mm of tip arc length along the pass (backwards if negative) from `from`,
  // from the tangent predictor. Returns false (with `status`, kOk meaning no convergence).
  bool Step(const ContactPoint& from, double delta, const NewtonOptions& options, ContactPoint* to,
            EvalStatus* status, int* iterations) const;
  bool Inside(const Eigen::Vector2d& uv) const { return face_.Inside(uv.x(), uv.y()); }
  bool SurelyOutside(const Eigen::Vector2d& uv) const {
    return face_.SurelyOutside(uv.x(), uv.y());
  }
  double DistanceOutside(const Eigen::Vector2d& uv) const {
    return face_.DistanceOutside(uv.x(), uv.y());
  }
  // The last point of the face's domain on the way from `inside` (sign +1: along the travel)
  // towards the point `chord_out` mm away, known to be outside; bisection on the chord to 1e-10 mm.
  ContactPoint LastInside(const ContactPoint& inside, double sign, double chord_out,
                          const NewtonOptions& options) const;

  const geometry::FaceSurface& Face() const { return face_; }
  const geometry::Tool& Tool() const { return tool_; }
  const PassConstraint& Constraint() const { return constraint_; }
  PassConstraint& MutableConstraint() { return constraint_; }
  int Side() const { return side_; }

 private:
  geometry::FaceSurface face_;
  geometry::Tool tool_;
  Orientation orientation_;
  int side_;
  PassConstraint constraint_;
  std::shared_ptr<const AxisLaw> law_;

  // The Newton loop of SolveChord and SolveArc: g = 0 and the chord (anchor_tangent null) or the
  // arc from the anchor equal to target.
  int Solve(const Eigen::Vector3d& anchor, const Eigen::Vector3d* anchor_tangent, double target,
            double anchor_guide_t, Eigen::Vector2d uv, const NewtonOptions& options,
            ContactPoint* out, EvalStatus* status, double s) const;
};

// The parameter of the point of `guide` closest to (x, y) in XY, by Newton from `hint` (NaN: from
// a coarse scan of the curve). With `at`, also the guide's point and first two derivatives there.
double ClosestOnGuide(const geometry::BSplineCurve& guide, double x, double y, double hint,
                      Eigen::Vector3d at[3] = nullptr);

// The arc length between two points with unit tangents ta, tb, `chord` apart: exact for a circular
// arc (c (theta/2) / sin(theta/2), theta the angle of the tangents), fifth order otherwise.
double ArcFromChord(double chord, const Eigen::Vector3d& ta, const Eigen::Vector3d& tb);

// The surface's largest principal curvature at d, with unit normal n: positive where it bends
// towards n's side, 1/mm.
double CurvatureTowards(const geometry::SurfaceDerivatives& d, const Eigen::Vector3d& n);

// A stretch of a pass that is not followed by contact point, bridged by a straight tip motion
// from `entry` (the last contact point traced before it, at s_start) to `exit` (the first one
// after it, at s_exit):
// - Over a top. Where a flat end or bull nose on a fixed axis passes over a top of the face (the
//   normal is the tool axis and the face bends away from the tool all round), its flat bottom
//   sits on the top while the tip slides across: the contact point stays put and does not fix
//   the cutter location. The tip runs straight at the top's height along the strategy's plane,
//   over the chord (s_in, s_out) of the disc of radius R around the top, and the contact point
//   leaves the top on the other side.
// - Across a pole. Where the contact point crosses a collapsed edge of the (u, v) parametrization
//   (a sphere's pole), (u, v) jumps while the contact point does not; the trace stops within
//   1e-4 mm of it, and the bridge is the straight chord to the first point past it (s_in =
//   s_start, s_out = s_exit; `top` is the pole).
struct Bridge {
  double s_start = 0.0, s_in = 0.0, s_out = 0.0, s_exit = 0.0;
  Eigen::Vector3d tip_in = Eigen::Vector3d::Zero();
  Eigen::Vector3d direction = Eigen::Vector3d::Zero();  // unit, along the travel
  ContactPoint entry, exit;
  Eigen::Vector2d top_uv = Eigen::Vector2d::Zero();
  Eigen::Vector3d top = Eigen::Vector3d::Zero();

  // The tip at arc length s in [s_start, s_exit]: the straight chord, and straight joins to the
  // traced contact points on either side (they lie within 1e-3 mm of it, along its direction).
  Eigen::Vector3d Tip(double s) const;
};

class SurfacePass final : public PathSource {
 public:
  // `start` and `end` lie on the face's boundary, `length` is the tip arc length between them.
  // `bridges`: where the pass is not followed by contact point, sorted by arc length.
  // `knot_lines`: the arc lengths where it crosses a knot line of the face (FaceSurface::
  // UKnotLines), sorted.
  SurfacePass(const PassEvaluator& evaluator, int index, const ContactPoint& start,
              const ContactPoint& end, double length, const NewtonOptions& options,
              std::vector<Bridge> bridges = {}, std::vector<double> knot_lines = {});

  PathState Start() const override;
  std::optional<double> Length() const override { return length_; }
  PathSample At(const PathState& from, double s) const override;
  // The ends of the flat pieces' chords (where the tip path's curvature jumps) and the knot lines
  // the pass crosses (where the face's third derivatives, and so the axes' jerk, may jump).
  std::vector<double> Breaks(double s0, double s1) const override;
  std::string Describe(const PathState& state) const override;

  int Index() const { return index_; }  // 1-based
  // Whether the previous pass ends on the same strategy line just before a stretch where the tool
  // does not fit, and the tool moved straight from there to this pass's start (as a link's
  // straight move turns it, geometry::StraightMove) stays out of the face: it rides over the
  // stretch (a valley narrower than the tool, where it rests on both sides) instead of lifting.
  bool RidesOverFromPrevious() const { return rides_over_; }
  void SetRidesOverFromPrevious(bool rides) { rides_over_ = rides; }
  Pose StartPose() const;
  Pose EndPose() const;
  const PassEvaluator& Evaluator() const { return eval_; }
  const std::vector<double>& KnotLines() const { return knot_lines_; }
  bool HasBridges() const { return !bridges_.empty(); }
  // The contact point of a state of this pass, for tests and reports.
  EvalStatus Evaluate(const PathState& state, ContactPoint* out) const;

 private:
  const ContactPoint& From(const PathState& state, int* slot) const;
  // The arc length an axis law is evaluated at for a state at s (NaN without a law: the rule).
  double LawS(double s) const { return eval_.Law() ? s : std::numeric_limits<double>::quiet_NaN(); }
  // The flat piece whose [s_start, s_exit] holds s (nullptr if none).
  const Bridge* BridgeAt(double s) const;
  PathSample OnBridge(const Bridge& flat, double s) const;

  PassEvaluator eval_;
  int index_;
  ContactPoint start_, end_;
  double length_;
  NewtonOptions options_;
  std::vector<Bridge> bridges_;
  std::vector<double> knot_lines_;
  bool rides_over_ = false;
  // The last state stepped from and the last result: the planner asks several trial arc lengths
  // from the same state, then steps from one of the results.
  mutable ContactPoint cache_[2];
  mutable bool cache_valid_[2] = {false, false};
};

}  // namespace dtis::strategies
