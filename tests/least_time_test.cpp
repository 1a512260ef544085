// The least-time planner (planner = kLeastTime): the faster of the two planners' plans, shortened
// window by window on the verifier's own discrete problem. Measured against the minimum-time
// references (docs/references.md: a nonlinear program solved independently of dtis, and
// dtis_min_time), the other planners and the verifier.
#include <gtest/gtest.h>

#include <algorithm>
#include <string>
#include <vector>

#include "dtis/core/error.hpp"
#include "dtis/geometry/curve_path.hpp"
#include "dtis/geometry/g1_path.hpp"
#include "dtis/interp/verifier.hpp"
#include "dtis/interp/vpop.hpp"
#include "dtis/io/job.hpp"
#include "dtis/kinematics/machines.hpp"
#include "test_support.hpp"

namespace dtis {
namespace {

using interp::PlannerKind;
using test::Planned;
using test::PlanWith;

struct Sample {
  io::Job job;
  std::unique_ptr<Machine> machine;
  std::shared_ptr<const PathSource> path;
};
Sample Load(const std::string& name, double feed_mm_min = 0.0) {
  Sample s{io::LoadJob(test::Source("samples/jobs/" + name + ".toml")), nullptr, nullptr};
  if (feed_mm_min > 0.0) s.job.vpop.feed_mm_s = feed_mm_min / 60.0;
  s.machine = kinematics::LoadMachineFile(s.job.machine_file);
  s.path = io::BuildPath(s.job);
  return s;
}

// The trident's tips turn within a few periods' travel, where the look-ahead's continuous model
// is cautious and its motion a draw among nearby limits (docs/planner.md). The least-time planner
// comes within 2 % of the minimum at F 2 and 5 m/min (2.260 and 1.6668 s, a nonlinear program
// solved independently of dtis), never slower than the look-ahead, and its motion moves by less
// than 1 % when the limits are lowered to 99.9 and 99.6 %.
TEST(LeastTime, TridentIsWithinTwoPercentOfItsMinimumAtAnyLimits) {
  for (const auto& [feed, minimum] : {std::pair{2000.0, 2.260}, std::pair{5000.0, 1.6668}}) {
    SCOPED_TRACE(feed);
    const Sample s = Load("trident", feed);
    std::vector<double> times;
    for (const double fraction : {1.0, 0.999, 0.996}) {
      if (feed != 2000.0 && fraction != 1.0) continue;
      SCOPED_TRACE(fraction);
      interp::VpopOptions o = s.job.vpop;
      o.limit_fraction = fraction;
      const Planned least = PlanWith(*s.path, *s.machine, o, PlannerKind::kLeastTime);
      EXPECT_TRUE(least.report.Passed()) << interp::FormatReport(least.report);
      const Planned ahead = PlanWith(*s.path, *s.machine, o, PlannerKind::kLookAhead);
      EXPECT_LE(least.summary.motion_time_s, ahead.summary.motion_time_s);
      EXPECT_GT(least.summary.least_time_saved, 0);
      times.push_back(least.summary.motion_time_s);
    }
    EXPECT_LE(times.front(), 1.02 * minimum);
    const auto [lo, hi] = std::minmax_element(times.begin(), times.end());
    EXPECT_LE(*hi, 1.01 * *lo);
  }
}

// Where the continuous model is nearly right, the least time is within 1 % of the minimum: the
// NURBS circle at F 300 mm/s (1.857 s) and the open pocket's bottom curve at F 5 m/min (1.539 s),
// both from dtis_min_time.
TEST(LeastTime, SmoothCurvesAreWithinOnePercentOfTheirMinimum) {
  for (const auto& [name, minimum] :
       {std::pair{"circle_300", 1.857}, std::pair{"open_pocket_bottom", 1.539}}) {
    SCOPED_TRACE(name);
    const Sample s = Load(name);
    const Planned least = PlanWith(*s.path, *s.machine, s.job.vpop, PlannerKind::kLeastTime);
    EXPECT_TRUE(least.report.Passed()) << interp::FormatReport(least.report);
    EXPECT_LE(least.summary.motion_time_s, 1.01 * minimum);
    EXPECT_GE(least.summary.motion_time_s, minimum - 0.005);  // not below the least time
  }
}

// A zigzag of 90-degree turns smoothed within 0.01 mm on a LinuxCNC-like machine (100 mm/s,
// 1000 mm/s^2 per axis), from a low jerk to a jerk at which any axis may swing its whole
// acceleration range within a period: the look-ahead brakes harder into the corners than `vpop`
// passes them; the least-time planner is faster than both.
TEST(LeastTime, CornersOfAnAccelerationLimitedMachineAreNoSlowerThanEitherPlanner) {
  for (const double jerk : {5e4, 5e6}) {
    SCOPED_TRACE(jerk);
    const auto machine = test::Cartesian(100.0, 1000.0, jerk);
    const auto zigzag = test::Zigzag(*machine);
    const geometry::G1Path& path = *zigzag;
    interp::VpopOptions o;
    o.feed_mm_s = 50.0;
    const Planned paper = PlanWith(path, *machine, o, PlannerKind::kVpop);
    const Planned ahead = PlanWith(path, *machine, o, PlannerKind::kLookAhead);
    const Planned least = PlanWith(path, *machine, o, PlannerKind::kLeastTime);
    EXPECT_TRUE(least.report.Passed()) << interp::FormatReport(least.report);
    EXPECT_LE(least.summary.motion_time_s,
              std::min(paper.summary.motion_time_s, ahead.summary.motion_time_s));
  }
}

long Flips(const interp::VerifyReport& report) {
  long flips = 0;
  for (const auto& axis : report.axes) flips += axis.jerk_flips;
  return flips;
}

// The linear programs' vertices may flip an axis' jerk between its extremes from one period to
// the next. With no_added_chatter a shortened window that flips more than the plan it replaced is
// given back: the trident's axes flip no more often than the look-ahead's (18 times), and the
// motion is still no longer than the look-ahead's.
TEST(LeastTime, NoAddedChatterFlipsTheAxesNoMoreThanThePlanItStartsFrom) {
  const Sample s = Load("trident");
  interp::VpopOptions o = s.job.vpop;
  o.least_time.no_added_chatter = true;
  const Planned least = PlanWith(*s.path, *s.machine, o, PlannerKind::kLeastTime);
  const Planned ahead = PlanWith(*s.path, *s.machine, o, PlannerKind::kLookAhead);
  EXPECT_TRUE(least.report.Passed()) << interp::FormatReport(least.report);
  EXPECT_LE(Flips(least.report), Flips(ahead.report));
  EXPECT_LE(least.summary.motion_time_s, ahead.summary.motion_time_s);
}

// It plans a path whole: a commit horizon (a stream to a machine) is refused with a message that
// names the planners that stream.
TEST(LeastTime, RefusesToStream) {
  const auto machine = test::Cartesian(500.0, 2500.0, 5000.0);
  const geometry::LinePath line({0, 0, 0}, {10, 0, 0}, Eigen::Vector3d::UnitZ());
  interp::VpopOptions o;
  o.feed_mm_s = 50.0;
  o.planner = PlannerKind::kLeastTime;
  o.commit_horizon = 200;
  test::Collect sink;
  try {
    interp::PlanVpop(line, *machine, o, sink);
    FAIL() << "planned under a commit horizon";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("lookahead"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(sink.points.empty());
}

}  // namespace
}  // namespace dtis
