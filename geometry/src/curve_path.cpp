#include "dtis/geometry/curve_path.hpp"

#include <fmt/format.h>

#include "dtis/core/error.hpp"

namespace dtis::geometry {

std::vector<double> DistinctKnots(const BSplineCurve& curve) {
  std::vector<double> breaks;
  for (const double k : curve.Knots()) {
    if (k < curve.FirstParameter() || k > curve.LastParameter()) continue;
    if (breaks.empty() || k > breaks.back()) breaks.push_back(k);
  }
  return breaks;
}

namespace {
ArcLengthMap::Evaluator DerivativesOf(const BSplineCurve& curve) {
  return [&curve](double u, int order, Eigen::Vector3d* d, bool from_left) {
    curve.Derivatives(u, order, d, from_left);
  };
}
}  // namespace

ArcLengthMap ArcLengthOf(const BSplineCurve& curve, const ArcLengthOptions& options) {
  return ArcLengthMap(DerivativesOf(curve), DistinctKnots(curve), options);
}

double ArcLengthOfCurve(const BSplineCurve& curve) {
  return ArcLengthMap::MeasureLength(DerivativesOf(curve), DistinctKnots(curve));
}

namespace {
// The tool axis turns linearly in its top point, this far up the axis.
constexpr double kLeverMm = 100.0;
}  // namespace

Eigen::Vector3d StraightMoveAxis(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                                 const Eigen::Vector3d& from_axis, const Eigen::Vector3d& to_axis,
                                 double t) {
  const Eigen::Vector3d tip = (1.0 - t) * from + t * to;
  const Eigen::Vector3d top =
      (1.0 - t) * (from + kLeverMm * from_axis) + t * (to + kLeverMm * to_axis);
  return (top - tip).normalized();
}

std::unique_ptr<PathSource> StraightMove(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                                         const Eigen::Vector3d& from_axis,
                                         const Eigen::Vector3d& to_axis) {
  if ((to_axis - from_axis).norm() < 1e-12) return std::make_unique<LinePath>(from, to, from_axis);
  BSplineCurveData bottom{1, {0.0, 0.0, 1.0, 1.0}, {from, to}, {}};
  BSplineCurveData top{
      1, {0.0, 0.0, 1.0, 1.0}, {from + from_axis * kLeverMm, to + to_axis * kLeverMm}, {}};
  return std::make_unique<CurvePath>(BSplineCurve(std::move(bottom), "move"),
                                     BSplineCurve(std::move(top), "move"));
}

CurvePath::CurvePath(BSplineCurve curve, const Eigen::Vector3d& tool_axis,
                     const ArcLengthOptions& options)
    : bottom_(std::move(curve)),
      axis_(tool_axis.normalized()),
      map_(ArcLengthOf(bottom_, options)) {
  if (!(tool_axis.norm() > 0.0)) throw Error("tool axis must be a non-zero vector");
  if (!(map_.Length() > 0.0)) throw Error("curve has zero length");
  knot_s_ = KnotArcLengths();
}

std::vector<double> CurvePath::KnotArcLengths() const {
  const std::vector<double> knots = DistinctKnots(bottom_);
  std::vector<double> arc;
  double s = 0.0;
  for (std::size_t k = 1; k + 1 < knots.size(); ++k) {
    s += map_.Integrate(knots[k - 1], knots[k]);
    arc.push_back(s);
  }
  return arc;
}

CurvePath::CurvePath(BSplineCurve bottom, BSplineCurve top, const ArcLengthOptions& options)
    : bottom_(std::move(bottom)),
      top_(std::move(top)),
      axis_(Eigen::Vector3d::UnitZ()),
      map_(ArcLengthOf(bottom_, options)) {
  if (top_->Degree() != bottom_.Degree() || top_->Knots() != bottom_.Knots()) {
    throw Error("top curve must have the bottom curve's degree and knots (same parametrization)");
  }
  if (!(map_.Length() > 0.0)) throw Error("bottom curve has zero length");
  // The tool axis is top - bottom: check it never vanishes at a dense set of parameters.
  const int samples = 64 * static_cast<int>(bottom_.Poles().size());
  for (int i = 0; i <= samples; ++i) {
    const double u = bottom_.FirstParameter() +
                     (bottom_.LastParameter() - bottom_.FirstParameter()) * i / samples;
    if ((top_->Point(u) - bottom_.Point(u)).norm() < 1e-9) {
      throw Error("top and bottom curves meet at u = {}: the tool axis is undefined there", u);
    }
  }
  knot_s_ = KnotArcLengths();
}

PathState CurvePath::Start() const { return {0.0, bottom_.FirstParameter(), 0.0, 0}; }

std::vector<double> CurvePath::Breaks(double s0, double s1) const {
  std::vector<double> breaks;
  for (const double s : knot_s_) {
    if (s > s0 && s <= s1) breaks.push_back(s);
  }
  return breaks;
}

Pose CurvePath::PoseAt(double u) const {
  Pose pose;
  pose.tip = bottom_.Point(u);
  pose.axis = top_ ? Eigen::Vector3d((top_->Point(u) - pose.tip).normalized()) : axis_;
  return pose;
}

PathSample CurvePath::At(const PathState& from, double s) const {
  PathSample sample;
  const double length = map_.Length();
  if (s >= length) {
    sample.status = s > length ? PathStatus::kEnd : PathStatus::kOk;
    s = length;
  }
  int hint = from.piece;
  const double u = map_.Parameter(s, &hint);
  sample.state = {.s = s, .u = u, .piece = hint};
  sample.pose = PoseAt(u);
  return sample;
}

std::string CurvePath::Describe(const PathState& state) const {
  return fmt::format("arc length {} mm, u = {}", state.s, state.u);
}

LinePath::LinePath(const Eigen::Vector3d& from, const Eigen::Vector3d& to,
                   const Eigen::Vector3d& tool_axis)
    : from_(from), axis_(tool_axis.normalized()), length_((to - from).norm()) {
  if (!(length_ > 0.0)) throw Error("line from and to are the same point");
  if (!(tool_axis.norm() > 0.0)) throw Error("tool axis must be a non-zero vector");
  direction_ = (to - from) / length_;
}

PathSample LinePath::At(const PathState&, double s) const {
  PathSample sample;
  if (s >= length_) {
    sample.status = s > length_ ? PathStatus::kEnd : PathStatus::kOk;
    s = length_;
  }
  sample.state = {.s = s, .u = s / length_};
  sample.pose.tip = from_ + s * direction_;
  sample.pose.axis = axis_;
  return sample;
}

std::string LinePath::Describe(const PathState& state) const {
  return fmt::format("arc length {} mm on the line", state.s);
}

std::vector<Pose> LinkWaypoints(const Pose& from, const Pose& to, double safe_z, double clearance,
                                bool straight) {
  const Eigen::Vector3d out1 = from.tip + from.axis * clearance;
  const Eigen::Vector3d out2 = to.tip + to.axis * clearance;
  const Eigen::Vector3d up1(out1.x(), out1.y(), std::max(safe_z, out1.z()));
  const Eigen::Vector3d up2(out2.x(), out2.y(), std::max(safe_z, out2.z()));
  constexpr double kMinMm = 1e-9;
  std::vector<Pose> points{from};
  std::vector<Pose> way{Pose{out1, from.axis}, Pose{up1, from.axis}, Pose{up2, to.axis},
                        Pose{out2, to.axis}, Pose{to.tip, to.axis}};
  if (straight) way.erase(way.begin(), way.end() - 1);
  for (const Pose& p : way) {
    if ((p.tip - points.back().tip).norm() > kMinMm) {
      points.push_back(p);
    } else if ((p.axis - points.back().axis).norm() >= 1e-12) {
      throw Error(
          "link move: the tool axis must turn where the tool does not move; raise the clearance");
    }
  }
  return points;
}

}  // namespace dtis::geometry
