// Shared helpers for the tests: the random-suite knobs, sample paths, and an in-memory sink.
#pragma once

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <initializer_list>
#include <memory>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "dtis/core/error.hpp"
#include "dtis/geometry/g1_path.hpp"
#include "dtis/interp/verifier.hpp"
#include "dtis/interp/vpop.hpp"
#include "dtis/io/job.hpp"
#include "dtis/io/setpoint_file.hpp"
#include "dtis/kinematics/machines.hpp"

namespace dtis::test {

extern long g_count;          // cases per randomized property test
extern unsigned long g_seed;  // base seed

// A path for `name` in this run's own scratch folder (removed when the run ends).
std::string Scratch(const std::string& name);

inline std::string Source(const std::string& relative) {
  return std::string(DTIS_SOURCE_DIR) + "/" + relative;
}

// A 3-axis plane_cl job with `tool` (its [tool] keys) on the STEP file `step`: `surface` gives the
// face (and more of [surface]), `planes` the strategy's plane_normal, direction and stepover (and
// more of [strategy]); read as if from `source`.
inline io::Job PlaneClJob(const std::string& step, const std::string& surface,
                          const std::string& tool, const std::string& planes,
                          const std::string& source) {
  return io::ParseJob(fmt::format(R"(machine = "{}"
feed_mm_min = 3000
[surface]
file = "{}"
{}
[tool]
{}
[strategy]
kind = "plane_cl"
{}
)",
                                  test::Source("samples/machines/mikron_ucp710_xyz.toml"), step,
                                  surface, tool, planes),
                      source);
}

// `f` throws dtis::Error with every one of `fragments` in its message.
template <typename F>
void ExpectError(F&& f, std::initializer_list<std::string> fragments) {
  try {
    f();
    FAIL() << "expected an error containing '" << *fragments.begin() << "'";
  } catch (const Error& e) {
    for (const std::string& fragment : fragments) {
      EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
    }
  }
}
template <typename F>
void ExpectError(F&& f, const std::string& fragment) {
  ExpectError(std::forward<F>(f), {fragment});
}

// The PathSource contract: asked for an arc length a few ulps from a state it handed out, a source
// returns that state's pose. A surface pass's Newton once failed on such a 1e-16 mm step; nothing
// in the contract keeps a search from asking for one. Probes about 40 states along the path.
inline void ExpectRoundingStepsHold(const PathSource& path, const std::string& what) {
  SCOPED_TRACE(what);
  path.Reach(INFINITY);
  const double length = path.Length().value();
  PathState st = path.Start();
  int probed = 0;
  for (double s = 0.05; s < length - 0.05; s += length / 41.0) {
    const PathSample here = path.At(st, s);
    ASSERT_EQ(here.status, PathStatus::kOk) << s;
    st = here.state;
    for (const double ulps : {1.0, 4.0, -1.0, -4.0}) {
      const double at = st.s + ulps * (std::nextafter(st.s, INFINITY) - st.s);
      const PathSample near = path.At(st, at);
      ASSERT_EQ(near.status, PathStatus::kOk) << "from " << st.s << " to " << at;
      EXPECT_LT((near.pose.tip - here.pose.tip).norm(), 1e-12) << at;
      EXPECT_LT((near.pose.axis - here.pose.axis).norm(), 1e-12) << at;
      ++probed;
    }
  }
  EXPECT_GT(probed, 150);
}

struct Collect final : interp::SetpointSink {
  std::vector<interp::Setpoint> points;
  void Accept(const interp::Setpoint& s) override { points.push_back(s); }
};

// A path planned and its setpoints checked by the independent verifier.
struct Planned {
  interp::VpopSummary summary;
  interp::VerifyReport report;
  std::vector<interp::Setpoint> points;
};
inline Planned PlanAndVerify(const PathSource& path, const Machine& machine,
                             const interp::VpopOptions& o) {
  Collect sink;
  Planned p;
  p.summary = interp::PlanVpop(path, machine, o, sink);
  io::TableSink table(machine, o.period_s);
  for (const auto& s : sink.points) table.Accept(s);
  p.report = interp::Verify(table.Table(), machine);
  p.points = std::move(sink.points);
  return p;
}

// PlanAndVerify with `planner`.
inline Planned PlanWith(const PathSource& path, const Machine& machine, interp::VpopOptions o,
                        interp::PlannerKind planner) {
  o.planner = planner;
  return PlanAndVerify(path, machine, o);
}

// A zigzag of ten G1 blocks of 14.1 mm with 90-degree turns, corners smoothed within 0.01 mm for
// F 50 mm/s, from the origin.
inline std::unique_ptr<geometry::G1Path> Zigzag(const Machine& machine) {
  std::vector<geometry::ChainMove> moves;
  for (int k = 1; k <= 10; ++k) {
    geometry::ChainMove m;
    m.tip = {10.0 * k, 10.0 * (k % 2), 0.0};
    m.line = k;
    moves.push_back(m);
  }
  geometry::CornerOptions corners;
  corners.contour_tol_mm = 0.01;
  corners.feed_mm_s = 50.0;
  return std::make_unique<geometry::G1Path>(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d::UnitZ(),
                                            moves, machine, corners);
}

// An XYZ machine with the same limits on every axis (mm, s).
inline std::unique_ptr<Machine> Cartesian(double v, double a, double j) {
  std::vector<Axis> axes;
  for (const char* n : {"X", "Y", "Z"}) {
    Axis x;
    x.name = n;
    x.travel_min = -1000;
    x.travel_max = 1000;
    x.vmax = v;
    x.amax = a;
    x.jmax = j;
    axes.push_back(x);
  }
  return std::make_unique<kinematics::XyzMachine>("test", axes);
}

}  // namespace dtis::test
