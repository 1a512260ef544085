// The tool axis smoothed within a tolerance ([orientation] axis_tolerance_deg): on a cubic
// B-spline face the rule's axis is only C1 across the knot lines; the smoothed one stays within
// the tolerance of it, the tool still touches the exact face, and the pass plans faster.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepBuilderAPI_Transform.hxx>
#include <BRep_Tool.hxx>
#include <GeomAPI_ProjectPointOnSurf.hxx>
#include <Geom_BSplineSurface.hxx>
#include <Geom_Surface.hxx>
#include <TopoDS.hxx>
#include <chrono>
#include <cmath>
#include <fstream>
#include <gp.hxx>
#include <gp_Trsf.hxx>
#include <iostream>
#include <numbers>

#include "dtis/core/error.hpp"
#include "dtis/geometry/angle.hpp"
#include "dtis/geometry/face_surface.hpp"
#include "dtis/interp/vpop.hpp"
#include "dtis/io/job.hpp"
#include "dtis/kinematics/machines.hpp"
#include "dtis/strategies/axis_law.hpp"
#include "dtis/strategies/strategy.hpp"
#include "fixture_shapes.hpp"
#include "parts.hpp"
#include "test_support.hpp"

namespace dtis {
namespace {

using geometry::FaceSurface;
using geometry::Tool;
using strategies::Orientation;
using strategies::StrategySpec;

constexpr double kDeg = std::numbers::pi / 180.0;
// The tool touches the face: its corner's centre is the corner radius from it (OpenCASCADE).
constexpr double kContactMm = 1e-6;

// The face set up 60 deg about X, as a user keeps a tilted pass away from the XYZAC's pole (see
// docs/limits.md): its axis stays far from vertical.
TopoDS_Face CubicWaveFace() {
  const TopoDS_Face flat =
      BRepBuilderAPI_MakeFace(Handle(Geom_Surface)(parts::CubicWaveSurface()), 1e-7).Face();
  gp_Trsf set_up;
  set_up.SetRotation(gp::OX(), 60.0 * kDeg);
  return TopoDS::Face(BRepBuilderAPI_Transform(flat, set_up, Standard_True).Shape());
}

Tool Ball(double r) {
  Tool t;
  t.kind = Tool::Kind::kBallEnd;
  t.radius = t.corner_radius = r;
  return t;
}

Tool BullNose(double radius, double corner) {
  Tool t;
  t.kind = Tool::Kind::kBullNose;
  t.radius = radius;
  t.corner_radius = corner;
  return t;
}

Orientation Tilted10(double tolerance_deg) {
  Orientation o;
  o.kind = Orientation::Kind::kTiltYaw;
  o.tilt_rad = 10.0 * kDeg;
  o.axis_tolerance_rad = tolerance_deg * kDeg;
  return o;
}

// One plane_cl pass along y, in the plane x = 40 across the middle of the face.
StrategySpec MiddlePass() {
  StrategySpec spec;
  spec.kind = StrategySpec::Kind::kPlaneCl;
  spec.plane_normal = Eigen::Vector3d::UnitX();
  spec.direction = Eigen::Vector3d::UnitY();
  spec.stepover_mm = 10.0;
  spec.range = std::array<double, 2>{40.0, 40.0};
  return spec;
}

// The same line as an iso-u line of the face (u = 40, v along y).
StrategySpec MiddleUvLine() {
  StrategySpec spec;
  spec.kind = StrategySpec::Kind::kUv;
  spec.along_u = false;
  spec.stepover_mm = 10.0;
  spec.range = std::array<double, 2>{40.0, 40.0};
  return spec;
}

Eigen::Vector3d ToEigen(const gp_XYZ& p) { return {p.X(), p.Y(), p.Z()}; }

// What OpenCASCADE says of the tool at `pose` touching the face near (u, v) (the pass's state):
// the rule's axis there, from its own normal, and how far the centre of the tool's corner (where
// its circle is nearest the face's point at (u, v)) is from the face less the corner radius.
struct Independent {
  double axis_off_rad = 0.0;  // the pose's axis from the rule's
  double contact_mm = 0.0;    // |distance of the corner's centre to the face - r|
};
Independent Check(const Handle(Geom_Surface) & surface, const Tool& tool, const Orientation& o,
                  int side, int feed_sign, const Pose& pose, double u, double v) {
  gp_Pnt p;
  gp_Vec su, sv;
  surface->D1(u, v, p, su, sv);
  const Eigen::Vector3d n = ToEigen(su.Crossed(sv).XYZ()).normalized() * static_cast<double>(side);
  const Eigen::Vector3d feed =
      n.cross(Eigen::Vector3d::UnitX()).normalized() * static_cast<double>(feed_sign);
  const Eigen::Vector3d rule =
      std::cos(o.tilt_rad) * n +
      std::sin(o.tilt_rad) * (std::cos(o.yaw_rad) * feed + std::sin(o.yaw_rad) * n.cross(feed));
  Independent out;
  out.axis_off_rad = geometry::Angle(rule, pose.axis);
  // The corner's circle: centre tip + r a, radius R across the axis.
  const Eigen::Vector3d& a = pose.axis;
  const Eigen::Vector3d c0 = pose.tip + tool.corner_radius * a;
  Eigen::Vector3d w = ToEigen(p.XYZ()) - c0;
  w -= a * w.dot(a);
  const Eigen::Vector3d centre =
      c0 + (tool.TorusRadius() > 0.0 ? Eigen::Vector3d(w.normalized() * tool.TorusRadius())
                                     : Eigen::Vector3d::Zero());
  GeomAPI_ProjectPointOnSurf proj(gp_Pnt(centre.x(), centre.y(), centre.z()), surface);
  EXPECT_GT(proj.NbPoints(), 0);
  out.contact_mm = std::abs(proj.LowerDistance() - tool.corner_radius);
  return out;
}

struct Case {
  const char* name;
  Tool tool;
};

// With axis_tolerance_deg = 0.09 the axis of a tilted pass (plane_cl, and uv along the same line)
// on the cubic wave stays within the
// tolerance of the rule's at points the law was not fitted from (OpenCASCADE's normal), the tool
// touches the face within 1e-6 mm (OpenCASCADE's projection of its corner's centre), every setpoint
// passes the verifier, and the pass plans faster than with the rule's axis, whose rotary
// accelerations step at each knot line.
TEST(AxisTolerance, ASmoothedAxisStaysWithinItsToleranceTouchesTheFaceAndPlansFaster) {
  const TopoDS_Face face = CubicWaveFace();
  const Handle(Geom_Surface) surface = BRep_Tool::Surface(face);
  const FaceSurface fs(face, "cubic wave, set up 60 deg about X");
  const auto xyzac =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyzac.toml"));
  constexpr double kTolDeg = 0.09;
  for (const auto& [strategy, line] :
       {std::pair{"plane_cl", MiddlePass()}, std::pair{"uv", MiddleUvLine()}}) {
    for (const Case& c :
         {Case{"ball R3", Ball(3.0)}, Case{"bull nose R5 r1", BullNose(5.0, 1.0)}}) {
      SCOPED_TRACE(fmt::format("{}, {}", strategy, c.name));
      const Orientation exact_axis = Tilted10(0.0), smooth_axis = Tilted10(kTolDeg);
      const auto exact = strategies::BuildPasses(fs, c.tool, exact_axis, line);
      const auto smooth = strategies::BuildPasses(fs, c.tool, smooth_axis, line);
      ASSERT_EQ(exact.passes.size(), 1u);
      ASSERT_EQ(smooth.passes.size(), 1u);
      const strategies::SurfacePass& pass = *smooth.passes[0];
      const double length = pass.Length().value();
      // The same stretch of the face: the ends move by what the axis moves the tip.
      EXPECT_NEAR(length, exact.passes[0]->Length().value(), 0.01);
      EXPECT_GT(length, 70.0);
      // It reports the knot lines it crosses as breaks, as the rule's pass does (the tip is a few
      // micrometres elsewhere, so the arc lengths move by as much).
      ASSERT_EQ(pass.KnotLines().size(), exact.passes[0]->KnotLines().size());
      EXPECT_GE(pass.KnotLines().size(), 7u);
      for (std::size_t k = 0; k < pass.KnotLines().size(); ++k) {
        EXPECT_NEAR(pass.KnotLines()[k], exact.passes[0]->KnotLines()[k], 0.01) << k;
      }
      // At points unlike the law's samples (every 0.0137 mm, marching from the start).
      double worst_axis = 0.0, worst_contact = 0.0;
      PathState st = pass.Start();
      int checked = 0;
      for (double s = 0.0; s <= length; s += 0.0137) {
        const PathSample smp = pass.At(st, s);
        ASSERT_EQ(smp.status, PathStatus::kOk) << s;
        st = smp.state;
        const Independent ind =
            Check(surface, c.tool, smooth_axis, pass.Evaluator().Side(),
                  pass.Evaluator().Constraint().feed_sign, smp.pose, smp.state.u, smp.state.v);
        worst_axis = std::max(worst_axis, ind.axis_off_rad);
        worst_contact = std::max(worst_contact, ind.contact_mm);
        ++checked;
      }
      EXPECT_GT(checked, 5000);
      EXPECT_LE(worst_axis, kTolDeg * kDeg) << worst_axis / kDeg << " deg";
      // It is smoothed: the law leaves the rule's axis by a good part of the tolerance.
      EXPECT_GT(worst_axis, 0.2 * kTolDeg * kDeg) << worst_axis / kDeg << " deg";
      EXPECT_LE(worst_contact, kContactMm);
      test::ExpectRoundingStepsHold(pass, c.name);
      // The rule's own pass touches as closely, and follows the rule to rounding.
      {
        PathState e = exact.passes[0]->Start();
        double rule_off = 0.0;
        for (double s = 0.0; s <= exact.passes[0]->Length().value(); s += 0.137) {
          const PathSample smp = exact.passes[0]->At(e, s);
          ASSERT_EQ(smp.status, PathStatus::kOk);
          e = smp.state;
          const Independent ind =
              Check(surface, c.tool, exact_axis, pass.Evaluator().Side(),
                    pass.Evaluator().Constraint().feed_sign, smp.pose, smp.state.u, smp.state.v);
          rule_off = std::max(rule_off, ind.axis_off_rad);
          EXPECT_LE(ind.contact_mm, kContactMm);
        }
        EXPECT_LT(rule_off, 1e-9);
      }
      interp::VpopOptions opt;
      opt.feed_mm_s = 50.0;
      const test::Planned rule = test::PlanAndVerify(*exact.passes[0], *xyzac, opt);
      const test::Planned smoothed = test::PlanAndVerify(pass, *xyzac, opt);
      EXPECT_TRUE(rule.report.Passed()) << interp::FormatReport(rule.report);
      EXPECT_TRUE(smoothed.report.Passed()) << interp::FormatReport(smoothed.report);
      EXPECT_LE(smoothed.report.worst_ratio, 1.0) << smoothed.report.worst;
      EXPECT_NEAR(smoothed.points.back().s, length, 1e-6);
      // Every setpoint's tool touches the face (its forward kinematics).
      for (std::size_t i = 0; i < smoothed.points.size(); i += 25) {
        const interp::Setpoint& sp = smoothed.points[i];
        const Pose pose = xyzac->Forward(sp.q);
        const Independent ind =
            Check(surface, c.tool, smooth_axis, pass.Evaluator().Side(),
                  pass.Evaluator().Constraint().feed_sign, pose, sp.state.u, sp.state.v);
        EXPECT_LE(ind.contact_mm, kContactMm) << sp.s;
        EXPECT_LE(ind.axis_off_rad, kTolDeg * kDeg + 1e-9) << sp.s;
      }
      const double t_rule = rule.summary.motion_time_s, t_smooth = smoothed.summary.motion_time_s;
      std::cout << fmt::format(
          "[ measured ] {}, {}: {:.3f} mm, rule's axis {:.3f} s, smoothed within {} deg {:.3f} s "
          "(axis at most {:.4f} deg from the rule's)\n",
          strategy, c.name, length, t_rule, kTolDeg, t_smooth, worst_axis / kDeg);
      EXPECT_LT(t_smooth, t_rule);
    }
  }
}

// With a tolerance of 0 a job plans exactly today's setpoints: the key is the rule's axis.
TEST(AxisTolerance, ZeroIsTheRulesAxisByteForByte) {
  std::ifstream in(test::Source("samples/jobs/surface_tilt10_xyzac.toml"));
  std::stringstream text;
  text << in.rdbuf();
  const std::string original = text.str();
  const std::size_t at = original.find("[orientation]");
  ASSERT_NE(at, std::string::npos);
  std::string zero = original;
  const std::size_t line_end = zero.find('\n', at);
  zero.insert(line_end + 1, "axis_tolerance_deg = 0\n");
  const std::string source = test::Source("samples/jobs/surface_tilt10_xyzac.toml");
  const io::RunResult a = io::RunJob(io::ParseJob(original, source));
  const io::RunResult b = io::RunJob(io::ParseJob(zero, source));
  ASSERT_EQ(a.table.Rows(), b.table.Rows());
  EXPECT_EQ(a.table.t, b.table.t);
  EXPECT_EQ(a.table.columns, b.table.columns);
  EXPECT_TRUE(a.verify.Passed());
}

// The key: named in the run summary, refused out of range and on a fixed axis.
TEST(AxisTolerance, TheKeyIsNamedInTheSummaryAndCheckedWhereItIsRead) {
  const std::string step = test::Scratch("cubic_wave.stp");
  test::WriteStep(CubicWaveFace(), step);
  const auto job = [&](const std::string& orientation) {
    return io::ParseJob(
        fmt::format(R"(machine = "{}"
feed_mm_min = 3000
[surface]
file = "{}"
[tool]
kind = "ball_end"
radius_mm = 3
[orientation]
{}
[strategy]
kind = "plane_cl"
plane_normal = [1, 0, 0]
direction = [0, 1, 0]
stepover_mm = 10
range = [40, 40]
)",
                    test::Source("samples/machines/mikron_ucp710_xyzac.toml"), step, orientation),
        test::Scratch("axis_tolerance.toml"));
  };
  const io::Job smoothed = job("kind = \"tilt_yaw\"\ntilt_deg = 10\naxis_tolerance_deg = 0.09");
  const io::RunResult r = io::RunJob(smoothed);
  EXPECT_TRUE(r.verify.Passed());
  EXPECT_NE(io::FormatRunSummary(smoothed, r).find("axis smoothed within 0.09 deg"),
            std::string::npos)
      << io::FormatRunSummary(smoothed, r);
  const io::Job exact = job("kind = \"tilt_yaw\"\ntilt_deg = 10");
  const std::string exact_summary = io::FormatRunSummary(exact, io::RunJob(exact));
  EXPECT_EQ(exact_summary.find("smoothed"), std::string::npos);
  EXPECT_NE(exact_summary.find("the rule's exact axis"), std::string::npos) << exact_summary;
  test::ExpectError([&] { job("kind = \"tilt_yaw\"\ntilt_deg = 10\naxis_tolerance_deg = -1"); },
                    {"axis_tolerance_deg", "[0, 5]"});
  test::ExpectError([&] { job("kind = \"fixed\"\naxis_tolerance_deg = 0.1"); },
                    {"axis_tolerance_deg", "tilt_yaw"});
}

// A tolerance the law cannot hold without knots closer than 0.5 mm (the rule's axis is only C1
// at the knot lines) refuses the job, naming the face, the pass, where, and how far off it stays.
TEST(AxisTolerance, ATolerancesTooTightToHoldIsRefusedWithWhere) {
  const TopoDS_Face face = CubicWaveFace();
  const FaceSurface fs(face, "cubic wave");
  test::ExpectError([&] { strategies::BuildPasses(fs, Ball(3.0), Tilted10(1e-5), MiddlePass()); },
                    {"cubic wave", "pass 1", "arc length", "axis_tolerance_deg = 1e-05",
                     "too abruptly", "deg from it"});
}

// The law itself: a quintic fitted to a smooth axis reproduces it, its derivative is the
// derivative of its value, and it goes on past its ends smoothly.
TEST(AxisLaw, FitsASmoothAxisAndDifferentiatesIt) {
  std::vector<double> s;
  std::vector<Eigen::Vector3d> axes;
  const auto axis = [](double x) {
    return Eigen::Vector3d(0.3 * std::sin(x / 15.0), 0.2 * std::cos(x / 12.0), 1.0).normalized();
  };
  for (int i = 0; i <= 400; ++i) {
    s.push_back(40.0 * i / 400);
    axes.push_back(axis(s.back()));
  }
  const strategies::AxisLaw law = strategies::FitAxisLaw(s, axes, {0.0, 10.0, 20.0, 30.0, 40.0});
  EXPECT_EQ(law.Spans(), 4);
  for (double x = 0.013; x < 40.0; x += 0.37) {
    Eigen::Vector3d d;
    const Eigen::Vector3d a = law.At(x, &d);
    EXPECT_NEAR(a.norm(), 1.0, 1e-14);
    EXPECT_LT(geometry::Angle(a, axis(x)), 5e-5) << x;
    const double h = 1e-5;
    const Eigen::Vector3d fd = (law.At(x + h) - law.At(x - h)) / (2.0 * h);
    EXPECT_LT((fd - d).norm(), 1e-8) << x;
  }
  EXPECT_LT(geometry::Angle(law.At(40.001), axis(40.001)), 1e-4);
  EXPECT_LT(geometry::Angle(law.At(-0.001), axis(-0.001)), 1e-4);
}

}  // namespace
}  // namespace dtis
