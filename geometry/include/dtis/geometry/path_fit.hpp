// What CAM software makes of an exact tool path, and how far that is from it (Beudaert et al. 2014,
// Tab. 1): the path sampled finely, a polyline within a chordal tolerance (the G1 export), a cubic
// B-spline or 5-axis B-spline pair fitted by least squares within a tolerance (the B-spline
// export), and distances from any point to the exact path.
//
// Everything works on a PathSource (a surface pass, a curve), so the exports are made from the
// very poses the interpolator plans on the exact surface. In 5-axis the tool axis is carried as
// the top point, tip + top_height * axis, as the 2012 paper's bottom/top curves carry it.
#pragma once

#include <Eigen/Core>
#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "dtis/core/path_source.hpp"
#include "dtis/geometry/bspline_curve.hpp"

namespace dtis::geometry {

// Poses of a path at increasing tip arc length, both ends included.
struct PathSamples {
  std::vector<double> s;  // tip arc length, mm
  std::vector<PathState> state;
  std::vector<Eigen::Vector3d> tip;
  std::vector<Eigen::Vector3d> axis;  // unit
  bool turning_axis = false;          // the tool axis changes along the path (5-axis)
  std::size_t Size() const { return s.size(); }
};

// The path every `step_mm` of arc length (the last step shorter). Throws dtis::Error, prefixed
// with `what` ("pass 3"), naming the arc length where a pose cannot be computed.
PathSamples SamplePath(const PathSource& path, double step_mm, const std::string& what);

struct ExportTolerance {
  double tip_mm = 0.01;  // the tool tip's distance to the exact path
  // 5-axis: the angle between the export's tool axis where it passes a sample's tip and the
  // sample's exact axis (ignored when the axis is fixed).
  double axis_deg = 0.1;
  // The export carries the axis as the top point, this far up it: G1 blocks interpolate tip and
  // top linearly, B-spline pairs share their parameter.
  double top_height_mm = 100.0;
};

// The samples a CAM system's chordal discretization keeps: every sample between two kept ones lies
// within tolerance of their chord, and in 5-axis its axis within tolerance of the axis the tip and
// top chords give at its foot. The first and last are always kept. Greedy: each chord as long as
// the tolerance allows.
std::vector<std::size_t> ChordalVertices(const PathSamples& samples,
                                         const ExportTolerance& tolerance);

struct BSplineFitOptions {
  ExportTolerance tolerance;
  // Equally spaced knots (LinuxCNC's G5.2 takes no knot vector: it assumes them uniform); else
  // knots are inserted where the fit is out of tolerance.
  bool uniform_knots = false;
  int max_rounds = 60;
};

struct BSplineFit {
  BSplineCurve bottom;              // the tip, parametrized by the exact path's arc length
  std::optional<BSplineCurve> top;  // the top point, same knots (when the axis turns)
  int rounds = 0;                   // least-squares solves
  double max_tip_mm = 0.0;          // largest distance of a sample to the bottom curve
  double max_axis_deg = 0.0;        // largest angle of the pair's axis there to the sample's
};

// Cubic B-spline (pair) through the first and last samples, least squares (Ceres) at the samples'
// arc lengths, knots added until every sample is within tolerance of the curve. Throws
// dtis::Error, prefixed with `what`, if the tolerance cannot be met with the samples given.
BSplineFit FitCubicBSpline(const PathSamples& samples, const BSplineFitOptions& options,
                           const std::string& what);

// The point of a curve closest to x, by Newton from parameter u (kept in the domain): returns the
// parameter.
double ClosestOnCurve(const BSplineCurve& curve, const Eigen::Vector3d& x, double u);

// Distances to the exact path: the nearest sample chord first, then Newton along the path with
// the path's own poses, so the foot lies on the exact path, not on the samples' polyline.
class PathProjector {
 public:
  // `samples` from SamplePath(path, ...); both must outlive the projector. Not thread safe (the
  // path is not).
  PathProjector(const PathSource& path, const PathSamples& samples);

  struct Foot {
    double s = 0.0;
    Pose pose;              // exact pose at s
    double distance = 0.0;  // |x - pose.tip|
  };
  // `hint`: a sample index near the answer, updated to the foot's; points that move along the
  // path in order find their feet in constant time.
  Foot Project(const Eigen::Vector3d& x, std::size_t* hint) const;

 private:
  const PathSource& path_;
  const PathSamples& samples_;
};

// Distance from x to the segment [a, b], and the segment parameter of the nearest point.
double DistanceToSegment(const Eigen::Vector3d& x, const Eigen::Vector3d& a,
                         const Eigen::Vector3d& b, double* t = nullptr);

}  // namespace dtis::geometry
