// The Taylor baseline of Cheng, Tsai, Cheng (2002) on their NURBS circle.
#include "dtis/interp/taylor.hpp"

#include <gtest/gtest.h>

#include <numbers>

#include "dtis/geometry/curve_path.hpp"

namespace dtis::interp {
namespace {

TEST(Taylor, CircleDurationAndSecondOrderBeatsFirst) {
  geometry::BSplineCurveData d;
  d.degree = 2;
  d.knots = {0, 0, 0, 0.25, 0.5, 0.5, 0.75, 1, 1, 1};
  d.poles = {{0, 0, 0},     {0, 50, 0},  {100, 50, 0}, {100, 0, 0},
             {100, -50, 0}, {0, -50, 0}, {0, 0, 0}};
  d.weights = {1.0, 0.5, 0.5, 1.0, 0.5, 0.5, 1.0};
  const geometry::BSplineCurve c(d);
  const auto eval = [&c](double u, int order, Eigen::Vector3d* out) {
    c.Derivatives(u, order, out);
  };
  const double length = 2.0 * std::numbers::pi * 50.0;
  // The paper: 314.1593 mm at 100 mm/s with 0.5 s acceleration takes about 3.6416 s.
  EXPECT_NEAR(FeedCommand(FeedProfile::kTrapezoid, 100.0, 0.5, length).Duration(), 3.6416, 1e-4);
  for (const FeedProfile p :
       {FeedProfile::kTrapezoid, FeedProfile::kExponential, FeedProfile::kBell}) {
    TaylorOptions o;
    o.feed_mm_s = 100.0;
    o.profile = p;
    o.order = 1;
    const TaylorResult first = PlanTaylor(eval, 0.0, 1.0, length, o);
    o.order = 2;
    const TaylorResult second = PlanTaylor(eval, 0.0, 1.0, length, o);
    EXPECT_LT(second.rms_fluctuation, first.rms_fluctuation) << FeedProfileName(p);
    EXPECT_LT(second.max_fluctuation, 1e-3) << FeedProfileName(p);
    EXPECT_LT(second.end_error_mm, 0.01) << FeedProfileName(p);
    // It stops when u reaches the end or, as the feed fades, ceil(D / T) + 2 periods at most.
    EXPECT_NEAR(second.motion_time_s, FeedCommand(p, 100.0, 0.5, length).Duration(), 3e-3);
  }
}

}  // namespace
}  // namespace dtis::interp
