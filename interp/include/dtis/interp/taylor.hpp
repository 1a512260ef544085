// The classic parametric interpolators of Cheng, Tsai, Cheng (IFAC 2002), as a baseline: the curve
// parameter advances by the first- (Eq. 8) or second-order (Eq. 9) Taylor expansion of du/dt under
// a feed profile V(t) planned in advance (trapezoid, exponential or bell acceleration), with no
// knowledge of the axis limits. What it reports is the feedrate fluctuation: the feed actually
// produced between setpoints against the commanded V(t).
#pragma once

#include <Eigen/Core>
#include <functional>
#include <string>
#include <vector>

namespace dtis::interp {

enum class FeedProfile { kTrapezoid, kExponential, kBell };
FeedProfile ParseFeedProfile(const std::string& name);  // throws dtis::Error listing the choices
const char* FeedProfileName(FeedProfile profile);

struct TaylorOptions {
  int order = 2;           // 1: Eq. 8, 2: Eq. 9
  double period_s = 1e-3;  // T
  double feed_mm_s = 0.0;  // F
  FeedProfile profile = FeedProfile::kTrapezoid;
  double accel_time_s = 0.5;  // time to go from 0 to F (and back)
  bool IsValid(std::string* why) const;
};

// The commanded feed V(t) and its derivative for a path of length L: the acceleration phase has
// shape f(t / Ta) (trapezoid: x; exponential: (1 - e^{-5x}) / (1 - e^{-5}); bell: (1 - cos pi x) /
// 2), then F, then the mirror image; shortened when L is too short to reach F.
class FeedCommand {
 public:
  FeedCommand(FeedProfile profile, double feed, double accel_time, double length);
  double Feed(double t) const;
  double Acceleration(double t) const;
  double Duration() const { return total_; }

 private:
  double Shape(double x) const;
  double ShapeSlope(double x) const;
  FeedProfile profile_;
  double feed_, ta_, cruise_, total_;
};

struct TaylorResult {
  std::vector<double> u;  // curve parameter per setpoint (rest rows included)
  std::vector<Eigen::Vector3d> points;
  double motion_time_s = 0.0;
  double end_error_mm = 0.0;     // distance between where it stopped and the curve's end
  double max_fluctuation = 0.0;  // max |produced - commanded| / F over the steps
  double rms_fluctuation = 0.0;
};

// `derivatives(u, order, d)` fills d[0..order]; [u0, u1] is the domain; `length` its arc length.
TaylorResult PlanTaylor(const std::function<void(double, int, Eigen::Vector3d*)>& derivatives,
                        double u0, double u1, double length, const TaylorOptions& options);

}  // namespace dtis::interp
