// G1 tool paths smoothed at every corner (Beudaert, Lavernhe, Tournier 2012, "Kinematical analysis
// of 5-axis corner smoothing"), as one PathSource.
//
// A chain of tool poses (tip + unit axis) joined by straight blocks. Each corner is replaced by a
// cubic B-spline with five control points on the two blocks (knots 0 0 0 0 1/2 1 1 1 1): P2 at the
// corner, P1 and P3 at L1 from it, P0 and P4 at L2. Its deviation from the corner is exactly
// eps = L1 cos(alpha / 2) / 2 (Eq. 3), at its middle; it meets the blocks with zero curvature, so
// the path is C2. L2 (never beyond half of either block) is chosen to maximise the corner's
// reachable feed by Eq. 8 on the machine's linear axes. Collinear blocks pass straight through.
//
// 5-axis: the top point (tip + h axis) follows its own polyline; each corner of it is smoothed
// within eps_top with control points scaled by the rate at which the top point moves per mm of
// tip on either block, so that on the straight parts the pose is exactly the programmed linear
// interpolation of tip and top. Inside a corner the top curve's parameter is a quintic in the tip's
// arc length that matches the top point's velocity and acceleration on both blocks: the tool
// orientation is C2 at both connections, which none of the paper's three parametrizations gives.
// Those three are kept as options for comparison.
//
// G2/G3 arcs join the chain where they meet their neighbours tangentially; the interpolator's exact
// axis checks handle the curvature jump there.
#pragma once

#include <Eigen/Core>
#include <memory>
#include <optional>
#include <vector>

#include "dtis/core/machine.hpp"
#include "dtis/core/path_source.hpp"
#include "dtis/geometry/arc_length.hpp"
#include "dtis/geometry/bspline_curve.hpp"

namespace dtis::geometry {

// How the top curve of a 5-axis corner is walked as the tip advances.
enum class TopParametrization {
  kC2,               // quintic in the tip's arc length, matched to both blocks (dtis)
  kBottomParameter,  // paper's parametrization 1: u_top = u_bottom
  kUniform,          // paper's parametrization 2: u_top linear in the tip's arc length
  kTopArcLength,     // paper's parametrization 3: top arc length linear in the tip's arc length
};

struct CornerOptions {
  double contour_tol_mm = 0.02;      // eps: deviation of the tip from the programmed corner
  double orientation_tol_mm = 0.05;  // eps_top: deviation of the top point from its corner
  double top_height_mm = 100.0;      // h: where the top point sits on the tool axis
  // Corners whose blocks turn by less than this pass straight through (rad).
  double straight_rad = 1e-9;
  TopParametrization top = TopParametrization::kC2;
  // Programmed feed: Eq. 8 never asks for more (mm/s).
  double feed_mm_s = 1e300;
};

// One element of a chain, as programmed.
struct ChainMove {
  enum class Kind { kLine, kArc } kind = Kind::kLine;
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();     // end point, mm
  Eigen::Vector3d axis = Eigen::Vector3d::UnitZ();   // tool axis at the end point (unit)
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  // arcs: centre, z of the start
  bool clockwise = false;                            // arcs: G2
  int line = 0;                                      // source line, for messages
};

// Eq. 8 of the paper on a stretch of path: the largest feed at which no axis exceeds its
// velocity, acceleration or jerk limit, with q_s, q_ss, q_sss from finite differences of exact
// axis positions (spacing h, mm). The least value over [s0, s1] is returned.
double ReachableFeed(const PathSource& path, const Machine& machine, double s0, double s1,
                     double h);

// The unit tangent of a move from `from` at its start and at its end.
Eigen::Vector3d StartTangent(const Eigen::Vector3d& from, const ChainMove& move);
Eigen::Vector3d EndTangent(const Eigen::Vector3d& from, const ChainMove& move);

class G1Path final : public PathSource {
 public:
  // `start`: the pose before the first move. Throws dtis::Error naming the source line when a
  // block has no length, the tip stands still while the axis turns, or a corner cannot be smoothed.
  G1Path(const Eigen::Vector3d& start_tip, const Eigen::Vector3d& start_axis,
         const std::vector<ChainMove>& moves, const Machine& machine,
         const CornerOptions& options = {});

  PathState Start() const override { return {}; }
  std::optional<double> Length() const override { return length_; }
  PathSample At(const PathState& from, double s) const override;
  std::span<const SlowPoint> SlowPoints() const override { return slow_; }
  std::string Describe(const PathState& state) const override;

  Pose PoseAt(double s, int* hint) const;

  // The corners as built, for tests and reports.
  struct Corner {
    double s0 = 0.0, s1 = 0.0;  // arc length of the tip where the corner starts and ends
    double l1 = 0.0, l2 = 0.0;  // bottom control lengths (mm)
    double reachable_feed_mm_s = 0.0;
    int line = 0;  // line of the block that ends at the corner
    std::shared_ptr<const BSplineCurve> bottom, top;
  };
  const std::vector<Corner>& Corners() const { return corners_; }
  bool FiveAxis() const { return five_axis_; }

 private:
  struct Piece {
    enum class Kind { kLine, kArc, kCorner } kind = Kind::kLine;
    double s0 = 0.0, length = 0.0;
    int line = 0;
    Eigen::Vector3d a, d;    // line: start and unit direction; arc: centre and start radius
    Eigen::Vector3d ta, tb;  // line (5-axis): top point at the start and the end
    double radius = 0.0, sweep = 0.0, dz = 0.0;  // arc: signed sweep (rad), rise (mm)
    int corner = -1;
    double w[6] = {};  // corner (kC2): top parameter = sum w_k t^k, t = tip arc length / length
  };
  // A corner's arc-length maps: the tip's, and the top point's (parametrization 3 only).
  struct CornerMaps {
    int corner = -1;
    std::shared_ptr<const ArcLengthMap> bottom, top;
  };
  // Built when the corner is first evaluated; the latest kCachedCorners stay (a program of a
  // million corners would otherwise hold a million maps). A map depends on its corner only, so
  // one built again is the same map. The reference lasts until the next call.
  const CornerMaps& Maps(int corner) const;
  void AddLine(const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& ta,
               const Eigen::Vector3d& tb, int line);
  int Find(double s, int hint) const;

  std::vector<Piece> pieces_;
  std::vector<Corner> corners_;
  // Like every PathSource of a program, a G1Path is evaluated by one thread at a time
  // (interp/program.hpp): its map cache takes no lock.
  static constexpr std::size_t kCachedCorners = 256;
  mutable std::vector<CornerMaps> maps_;  // slot: corner index modulo kCachedCorners
  std::vector<SlowPoint> slow_;
  double length_ = 0.0;
  bool five_axis_ = false;
  double h_ = 100.0;
  TopParametrization top_param_ = TopParametrization::kC2;
  Eigen::Vector3d axis_ = Eigen::Vector3d::UnitZ();  // 3-axis: the constant tool axis
};

// The moves that link two poses through LinkWaypoints (curve_path.hpp), as few paths as it takes:
// one chain of straight moves whose corners are smoothed within `corners` (so the machine does not
// stop at the waypoints), split only where the link turns back on itself. `corners.feed_mm_s` is
// the link feed.
std::vector<std::unique_ptr<PathSource>> LinkMoves(const Pose& from, const Pose& to, double safe_z,
                                                   double clearance, const Machine& machine,
                                                   const CornerOptions& corners);

}  // namespace dtis::geometry
