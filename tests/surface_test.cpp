// Surface strategies (DTIS): STEP import, passes solved by Newton on the exact face, every planned
// setpoint on the cutter-location surface and on its strategy plane, and the error paths.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <BRepBuilderAPI_MakeEdge.hxx>
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepBuilderAPI_MakePolygon.hxx>
#include <BRepBuilderAPI_MakeVertex.hxx>
#include <BRepBuilderAPI_MakeWire.hxx>
#include <BRepBuilderAPI_Transform.hxx>
#include <BRepExtrema_DistShapeShape.hxx>
#include <BRepPrimAPI_MakeRevol.hxx>
#include <BRepPrimAPI_MakeSphere.hxx>
#include <BRep_Builder.hxx>
#include <BRep_Tool.hxx>
#include <GCPnts_AbscissaPoint.hxx>
#include <GC_MakeArcOfCircle.hxx>
#include <Geom2d_BSplineCurve.hxx>
#include <GeomAPI_PointsToBSpline.hxx>
#include <GeomAPI_ProjectPointOnCurve.hxx>
#include <GeomAPI_ProjectPointOnSurf.hxx>
#include <GeomAdaptor_Curve.hxx>
#include <GeomAdaptor_Surface.hxx>
#include <GeomConvert.hxx>
#include <Geom_BSplineCurve.hxx>
#include <Geom_BSplineSurface.hxx>
#include <Geom_BezierSurface.hxx>
#include <Geom_CylindricalSurface.hxx>
#include <Geom_RectangularTrimmedSurface.hxx>
#include <Geom_SphericalSurface.hxx>
#include <Geom_Surface.hxx>
#include <TColStd_Array1OfInteger.hxx>
#include <TColStd_Array1OfReal.hxx>
#include <TColgp_Array1OfPnt.hxx>
#include <TColgp_Array1OfPnt2d.hxx>
#include <TColgp_Array2OfPnt.hxx>
#include <TopoDS.hxx>
#include <TopoDS_Compound.hxx>
#include <TopoDS_Wire.hxx>
#include <cmath>
#include <fstream>
#include <gp.hxx>
#include <gp_Ax3.hxx>
#include <gp_Circ.hxx>
#include <gp_Pln.hxx>
#include <gp_Trsf.hxx>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <numbers>
#include <random>
#include <set>
#include <sstream>
#include <tuple>

#include "dtis/core/error.hpp"
#include "dtis/geometry/angle.hpp"
#include "dtis/geometry/curve_path.hpp"
#include "dtis/geometry/face_surface.hpp"
#include "dtis/geometry/occt_convert.hpp"
#include "dtis/geometry/step_model.hpp"
#include "dtis/interp/vpop.hpp"
#include "dtis/io/job.hpp"
#include "dtis/io/report.hpp"
#include "dtis/io/stream.hpp"
#include "dtis/kinematics/machines.hpp"
#include "dtis/strategies/strategy.hpp"
#include "fixture_shapes.hpp"
#include "parts.hpp"
#include "test_support.hpp"

namespace dtis {
namespace {

using geometry::FaceSurface;
using geometry::StepModel;
using geometry::Tool;
using strategies::Orientation;
using strategies::StrategySpec;

const std::string kTrj8 = "samples/parts/occt_trj8_c2-db-214_single_bspline_face.stp";
const std::string kStrip = "samples/parts/occt_OCC26308-Face_single_bspline_face.stp";

Tool Ball(double r) {
  Tool t;
  t.kind = Tool::Kind::kBallEnd;
  t.radius = t.corner_radius = r;
  return t;
}

// Distance from a point to the exact face surface, by OpenCASCADE's projection (independent of
// the strategies' Newton solves).
double DistanceToSurface(const TopoDS_Face& face, const Eigen::Vector3d& p) {
  const Handle(Geom_Surface) s = BRep_Tool::Surface(face);
  GeomAPI_ProjectPointOnSurf proj(gp_Pnt(p.x(), p.y(), p.z()), s);
  EXPECT_GT(proj.NbPoints(), 0);
  return proj.LowerDistance();
}

TEST(StepModel, ListsTheFacesOfRealFiles) {
  const StepModel trj8 = StepModel::Load(test::Source(kTrj8));
  ASSERT_EQ(trj8.FaceCount(), 1);
  const auto& f = trj8.Info(1);
  EXPECT_EQ(f.type, "bspline");
  EXPECT_EQ(f.u_degree, 5);
  EXPECT_EQ(f.v_degree, 3);
  EXPECT_EQ(f.u_poles, 21);
  EXPECT_EQ(f.v_poles, 4);
  EXPECT_FALSE(f.rational);
  EXPECT_FALSE(f.trimmed);
  EXPECT_NEAR((f.box_max - f.box_min).z(), 76.07, 0.05);  // PROVENANCE: 19 x 97 x 76 mm box
  const StepModel rational =
      StepModel::Load(test::Source("samples/parts/occt_bug29478_single_rational_face_worknc.stp"));
  EXPECT_TRUE(rational.Info(1).rational);
  const StepModel fuselage =
      StepModel::Load(test::Source("samples/parts/occt_bug28366_fuselage_8faces.stp"));
  EXPECT_EQ(fuselage.FaceCount(), 8);
  // A plane with a hole: its area against the share of a 400 x 400 grid over its (u, v) box (in
  // mm on a plane) that the trim classifier puts inside.
  const StepModel turbine =
      StepModel::Load(test::Source("samples/parts/occt_ec_turbine-A_53faces_rational.stp"));
  const auto& plate = turbine.Info(2);
  EXPECT_EQ(plate.type, "plane");
  EXPECT_EQ(plate.holes, 1);
  EXPECT_EQ(trj8.Info(1).holes, 0);
  const FaceSurface surface(turbine.Face(2), "plate");
  constexpr int kGrid = 400;
  int inside = 0;
  for (int i = 0; i < kGrid; ++i) {
    for (int j = 0; j < kGrid; ++j) {
      inside += surface.Inside(plate.u0 + (plate.u1 - plate.u0) * (i + 0.5) / kGrid,
                               plate.v0 + (plate.v1 - plate.v0) * (j + 0.5) / kGrid);
    }
  }
  const double sampled =
      (plate.u1 - plate.u0) * (plate.v1 - plate.v0) * inside / (double(kGrid) * kGrid);
  EXPECT_NEAR(plate.area_mm2, sampled, 0.01 * sampled);
  EXPECT_LT(plate.area_mm2, 0.99 * (plate.u1 - plate.u0) * (plate.v1 - plate.v0));
}

TEST(StepModel, BadFilesGetOneClearMessage) {
  const auto message = [](const std::string& path) {
    try {
      StepModel::Load(path);
    } catch (const Error& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(message("/nonexistent.stp").find("no such file"), std::string::npos);
  EXPECT_NE(message(test::Source("README.md")).find("not a STEP file"), std::string::npos);
  const std::string nist =
      message(test::Source("samples/parts/nist_iso14649_ex1E_freeform_operation.stp"));
  EXPECT_NE(nist.find("MACHINING_SCHEMA"), std::string::npos) << nist;
  const StepModel trj8 = StepModel::Load(test::Source(kTrj8));
  try {
    trj8.Face(2);
    FAIL() << "face 2 should not exist";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("faces 1 to 1"), std::string::npos) << e.what();
  }
}

// dtis' own B-spline kernel against OpenCASCADE's evaluation of the same surface, on every face of
// the bundled parts: inside the domain, on its knots (a span's two sides meet there) and up to 5 %
// beyond it (where both continue the end spans' polynomials).
TEST(FaceSurface, OwnKernelAgreesWithOpenCascadeOnEveryBundledFace) {
  std::mt19937_64 rng(20261122);
  int own = 0;
  for (const char* file :
       {"occt_trj8_c2-db-214_single_bspline_face.stp", "occt_OCC26308-Face_single_bspline_face.stp",
        "occt_bug29478_single_rational_face_worknc.stp",
        "occt_bug29715_single_bspline_face_22x22.stp", "occt_bug28366_fuselage_8faces.stp"}) {
    const StepModel m = StepModel::Load(test::Source(std::string("samples/parts/") + file));
    for (int f = 1; f <= m.FaceCount(); ++f) {
      const FaceSurface surface(m.Face(f), "face");
      own += surface.OwnKernel();
      const GeomAdaptor_Surface occt(BRep_Tool::Surface(m.Face(f)));
      const double du = surface.U1() - surface.U0(), dv = surface.V1() - surface.V0();
      std::uniform_real_distribution<double> u(surface.U0() - 0.05 * du, surface.U1() + 0.05 * du),
          v(surface.V0() - 0.05 * dv, surface.V1() + 0.05 * dv);
      std::vector<std::pair<double, double>> at;
      for (int k = 0; k < 300; ++k) at.emplace_back(u(rng), v(rng));
      if (occt.GetType() == GeomAbs_BSplineSurface) {
        const auto b = occt.BSpline();
        for (int i = 1; i <= b->NbUKnots(); ++i) at.emplace_back(b->UKnot(i), v(rng));
        for (int j = 1; j <= b->NbVKnots(); ++j) at.emplace_back(u(rng), b->VKnot(j));
      }
      for (const auto& [uu, vv] : at) {
        geometry::SurfaceDerivatives d;
        surface.D2(uu, vv, &d);
        gp_Pnt p;
        gp_Vec su, sv, suu, svv, suv;
        occt.D2(uu, vv, p, su, sv, suu, svv, suv);
        const auto near = [&](const Eigen::Vector3d& mine, const gp_XYZ& theirs, const char* what) {
          const Eigen::Vector3d t(theirs.X(), theirs.Y(), theirs.Z());
          EXPECT_LE((mine - t).norm(), 1e-9 * (1.0 + t.norm()))
              << file << " face " << f << " " << what << " at (" << uu << ", " << vv << ")";
        };
        near(d.p, p.XYZ(), "point");
        near(surface.Point(uu, vv), p.XYZ(), "Point()");
        near(d.su, su.XYZ(), "S_u");
        near(d.sv, sv.XYZ(), "S_v");
        near(d.suu, suu.XYZ(), "S_uu");
        near(d.suv, suv.XYZ(), "S_uv");
        near(d.svv, svv.XYZ(), "S_vv");
      }
    }
  }
  EXPECT_GE(own, 5);  // trj8, the strip, the rational face, the 22 x 22 face and the fuselage's
}

// A periodic B-spline surface (a cylinder) stays with OpenCASCADE, which wraps its parameter.
TEST(FaceSurface, PeriodicSurfacesAreLeftToOpenCascade) {
  const Handle(Geom_Surface) cylinder = new Geom_CylindricalSurface(gp::XOY(), 10.0);
  const Handle(Geom_BSplineSurface) b = GeomConvert::SurfaceToBSplineSurface(
      new Geom_RectangularTrimmedSurface(cylinder, 0.0, 2.0 * M_PI, 0.0, 5.0));
  b->SetUPeriodic();
  ASSERT_TRUE(b->IsUPeriodic());
  const TopoDS_Face face = BRepBuilderAPI_MakeFace(b, 1e-7).Face();
  const FaceSurface surface(face, "cylinder");
  EXPECT_FALSE(surface.OwnKernel());
  geometry::SurfaceDerivatives d;
  surface.D2(0.3 + 2.0 * M_PI, 1.0, &d);  // a period on: the same point
  const gp_Pnt at = b->Value(0.3, 1.0);
  EXPECT_NEAR(std::hypot(d.p.x(), d.p.y()), 10.0, 1e-6);
  EXPECT_LE((d.p - Eigen::Vector3d(at.X(), at.Y(), at.Z())).norm(), 1e-9);
}

struct PlannedPass {
  std::vector<Pose> poses;  // forward kinematics of every setpoint
  strategies::PassConstraint constraint;
};

// Plans the first pass of `spec` on an XYZ machine and maps every setpoint back to a pose.
PlannedPass PlanFirstPass(const TopoDS_Face& face, const Tool& tool, const StrategySpec& spec) {
  const FaceSurface surface(face, "test face");
  const auto passes = strategies::BuildPasses(surface, tool, Orientation{}, spec);
  EXPECT_FALSE(passes.passes.empty());
  const auto machine =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  interp::VpopOptions o;
  o.feed_mm_s = 50.0;
  test::Collect sink;
  interp::PlanVpop(*passes.passes[0], *machine, o, sink);
  PlannedPass out;
  out.constraint = passes.passes[0]->Evaluator().Constraint();
  for (const auto& sp : sink.points) out.poses.push_back(machine->Forward(sp.q));
  return out;
}

// Every setpoint of a planned plane_cl pass: the ball centre is one radius from the exact surface
// (the tip is on the cutter-location surface) and the tip is on the pass's plane.
void ExpectOnSurfaceAndPlane(const TopoDS_Face& face, const StrategySpec& spec, double radius) {
  SCOPED_TRACE(spec.plane_normal.transpose());
  const PlannedPass pass = PlanFirstPass(face, Ball(radius), spec);
  ASSERT_GT(pass.poses.size(), 100u);
  double worst_surface = 0.0, worst_plane = 0.0;
  for (const Pose& p : pass.poses) {
    const Eigen::Vector3d centre = p.tip + p.axis * radius;
    worst_surface = std::max(worst_surface, std::abs(DistanceToSurface(face, centre) - radius));
    worst_plane =
        std::max(worst_plane, std::abs(p.tip.dot(pass.constraint.normal) - pass.constraint.value));
  }
  EXPECT_LT(worst_surface, 1e-6);
  EXPECT_LT(worst_plane, 1e-6);
}

TEST(SurfacePass, EverySetpointLiesOnTheCutterLocationSurfaceAndItsPlane_Trj8) {
  const StepModel m = StepModel::Load(test::Source(kTrj8));
  const TopoDS_Face face = geometry::PlaceFace(m.Face(1), {0, 90, 0}, {0, 0, 0});
  StrategySpec spec;
  spec.plane_normal = Eigen::Vector3d::UnitX();
  spec.direction = Eigen::Vector3d::UnitY();
  spec.stepover_mm = 4.0;
  ExpectOnSurfaceAndPlane(face, spec, 3.0);
}

TEST(SurfacePass, EverySetpointLiesOnTheCutterLocationSurfaceAndItsPlane_Strip) {
  const StepModel m = StepModel::Load(test::Source(kStrip));
  // The strip lies near (1966, -230, 43) mm: set it up within the machine's travel.
  const TopoDS_Face face = geometry::PlaceFace(m.Face(1), {0, 0, 0}, {-1966, 230, -43});
  StrategySpec spec;
  spec.plane_normal = Eigen::Vector3d(1, 0.2, 0).normalized();
  spec.direction = Eigen::Vector3d::UnitY();
  spec.stepover_mm = 0.5;
  ExpectOnSurfaceAndPlane(face, spec, 2.0);
}

TEST(SurfacePass, PlaneCcPutsTheContactPointOnThePlane) {
  const StepModel m = StepModel::Load(test::Source(kStrip));
  const FaceSurface surface(m.Face(1), "strip");
  StrategySpec spec;
  spec.kind = StrategySpec::Kind::kPlaneCc;
  spec.plane_normal = Eigen::Vector3d::UnitX();
  spec.direction = Eigen::Vector3d::UnitY();
  spec.stepover_mm = 1.0;
  const auto passes = strategies::BuildPasses(surface, Ball(2.0), Orientation{}, spec);
  ASSERT_FALSE(passes.passes.empty());
  const auto& pass = *passes.passes[0];
  PathState st = pass.Start();
  for (double s = 0.0; s < *pass.Length(); s += 0.37) {
    const PathSample smp = pass.At(st, s);
    ASSERT_EQ(smp.status, PathStatus::kOk);
    strategies::ContactPoint c;
    ASSERT_EQ(pass.Evaluate(smp.state, &c), strategies::EvalStatus::kOk);
    EXPECT_NEAR(c.p.x(), pass.Evaluator().Constraint().value, 1e-6);
    // The contact point is on the exact surface and the tip is one ball radius off it.
    EXPECT_NEAR(DistanceToSurface(m.Face(1), c.p), 0.0, 1e-7);
    EXPECT_NEAR(DistanceToSurface(m.Face(1), smp.pose.tip + smp.pose.axis * 2.0), 2.0, 1e-6);
    st = smp.state;
  }
}

// The planner may ask for an arc length a rounding error away from a state it holds (a look-ahead
// search converging on it). The march used to try a step of 1e-16 mm there, which its Newton
// cannot resolve: it halved the step ten times and reported "did not converge" on the plane_cl
// sample's first pass, which runs along the face's edge v = 0.
TEST(SurfacePass, AnArcLengthARoundingErrorFromAKnownStateIsThatState) {
  const StepModel m = StepModel::Load(test::Source(kTrj8));
  const FaceSurface surface(geometry::PlaceFace(m.Face(1), {0, 90, 0}, {0, 0, 0}), "trj8");
  StrategySpec spec;
  spec.plane_normal = Eigen::Vector3d::UnitX();
  spec.direction = Eigen::Vector3d::UnitY();
  spec.stepover_mm = 2.0;
  const auto passes = strategies::BuildPasses(surface, Ball(3.0), Orientation{}, spec);
  ASSERT_FALSE(passes.passes.empty());
  test::ExpectRoundingStepsHold(*passes.passes[0], "trj8 pass 1");
}

TEST(SurfacePass, IsoLinesKeepTheirParameterAndArcLengthIsTheTipPath) {
  const StepModel m = StepModel::Load(test::Source(kStrip));
  const FaceSurface surface(m.Face(1), "strip");
  StrategySpec spec;
  spec.kind = StrategySpec::Kind::kUv;
  spec.along_u = false;
  spec.stepover_mm = 1.0;
  const auto passes = strategies::BuildPasses(surface, Ball(2.0), Orientation{}, spec);
  ASSERT_FALSE(passes.passes.empty());
  const auto& pass = *passes.passes[0];
  const double u = pass.Evaluator().Constraint().value;
  // March in small steps and sum the chords: the pass length is the tip's arc length.
  PathState st = pass.Start();
  Eigen::Vector3d last = pass.StartPose().tip;
  double chords = 0.0;
  const double length = *pass.Length();
  for (int k = 1; k <= 4000; ++k) {
    const PathSample smp = pass.At(st, length * k / 4000.0);
    ASSERT_EQ(smp.status, PathStatus::kOk);
    EXPECT_NEAR(smp.state.u, u, 1e-9);
    chords += (smp.pose.tip - last).norm();
    last = smp.pose.tip;
    st = smp.state;
  }
  EXPECT_NEAR(chords, length, 1e-4 * length);
  // The march and the builder's trace sum their arcs over different steps: they end together to
  // the arc model's error (fifth order in the 0.1 mm trace step), well below 1e-6 mm.
  EXPECT_LT((last - pass.EndPose().tip).norm(), 1e-6);
}

Tool Torus(Tool::Kind kind, double radius, double corner) {
  Tool t;
  t.kind = kind;
  t.radius = radius;
  t.corner_radius = corner;
  return t;
}

// OCCT's trj8 stood up (rotated 90 deg about Y), finished along Y in planes x = const by a bull
// nose R5 r1 leaning 10 deg along the feed.
struct TiltedTrj8 {
  TopoDS_Face face;
  Tool bull = Torus(Tool::Kind::kBullNose, 5.0, 1.0);
  Orientation o;
  strategies::PassList passes;

  TiltedTrj8() {
    const StepModel m = StepModel::Load(test::Source(kTrj8));
    face = geometry::PlaceFace(m.Face(1), {0, 90, 0}, {0, 0, 0});
    o.kind = Orientation::Kind::kTiltYaw;
    o.tilt_rad = 10.0 * std::numbers::pi / 180.0;
    StrategySpec spec;
    spec.plane_normal = Eigen::Vector3d::UnitX();
    spec.direction = Eigen::Vector3d::UnitY();
    spec.stepover_mm = 6.0;
    passes = strategies::BuildPasses(FaceSurface(face, "trj8"), bull, o, spec);
  }
};

TEST(SurfacePass, FiveAxisTiltLeansTheAxisFromTheNormalAlongTheFeed) {
  const TiltedTrj8 trj8;
  const TopoDS_Face& face = trj8.face;
  const Tool& bull = trj8.bull;
  const Orientation& o = trj8.o;
  const auto& passes = trj8.passes;
  ASSERT_FALSE(passes.passes.empty());
  const auto machine =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyzac.toml"));
  for (const auto& pass : passes.passes) {
    PathState st = pass->Start();
    AxisVector q, prev;
    bool first = true;
    for (double s = 0.0; s <= *pass->Length(); s += 0.25) {
      const PathSample smp = pass->At(st, s);
      ASSERT_EQ(smp.status, PathStatus::kOk);
      strategies::ContactPoint c;
      ASSERT_EQ(pass->Evaluate(smp.state, &c), strategies::EvalStatus::kOk);
      EXPECT_NEAR(std::acos(std::clamp(c.axis.dot(c.n), -1.0, 1.0)), o.tilt_rad, 1e-9);
      EXPECT_GT(c.feed.dot(c.tangent), 0.0);  // the feed goes along the travel
      EXPECT_NEAR(c.axis.dot(c.feed), std::sin(o.tilt_rad), 1e-9);  // leaning forward along it
      EXPECT_NEAR(smp.pose.tip.x(), pass->Evaluator().Constraint().value, 1e-6);
      // The torus touches the surface: its corner centre is r from the contact point along n.
      const Eigen::Vector3d corner = c.p + c.n * bull.corner_radius;
      EXPECT_NEAR(DistanceToSurface(face, corner), bull.corner_radius, 1e-6);
      // Inverse then forward kinematics on the XYZAC machine return the pose.
      ASSERT_EQ(machine->Inverse(smp.pose, first ? nullptr : &prev, &q).status, InverseStatus::kOk);
      const Pose back = machine->Forward(q);
      EXPECT_LT((back.tip - smp.pose.tip).norm(), 1e-9);
      EXPECT_LT((back.axis - smp.pose.axis).norm(), 1e-12);
      prev = q;
      first = false;
      st = smp.state;
    }
  }
}

// How far the tool (a torus of corner radius r around a circle of radius R, closed by its flat
// bottom) stands above the plane through `on` with unit normal n, the tool's axis a: the support
// function of the torus, min over the tool of n . x = n . (tip + r a) - R |n - (n.a) a| - r.
double ClearanceAbovePlane(const Tool& tool, const Pose& pose, const Eigen::Vector3d& n,
                           const Eigen::Vector3d& on) {
  const double r = tool.corner_radius, big_r = tool.TorusRadius();
  const Eigen::Vector3d& a = pose.axis;
  return n.dot(pose.tip + r * a - on) - big_r * (n - n.dot(a) * a).norm() - r;
}

TEST(Tool, EveryToolTouchesAPlaneWithoutGoingIntoIt) {
  // The tip from a contact point on a plane, for random normals and axes: the tool's lowest point
  // along the normal is the contact point (support function, independent of TipFromContact).
  std::mt19937_64 rng(20261125);
  std::normal_distribution<double> gauss(0.0, 1.0);
  const auto random_unit = [&] {
    return Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
  };
  const Tool tools[] = {Ball(3.0), Torus(Tool::Kind::kBullNose, 5.0, 1.0),
                        Torus(Tool::Kind::kFlatEnd, 4.0, 0.0)};
  for (const Tool& tool : tools) {
    SCOPED_TRACE(tool.Describe());
    for (int k = 0; k < 1000; ++k) {
      const Eigen::Vector3d n = random_unit(), p = 10.0 * random_unit();
      Eigen::Vector3d a = random_unit();
      if (a.dot(n) < 0.05) a = (a - (a.dot(n) - 0.05) * n).normalized();
      Eigen::Vector3d tip;
      ASSERT_TRUE(geometry::TipFromContact(tool, p, n, a, &tip));
      EXPECT_NEAR(ClearanceAbovePlane(tool, {tip, a}, n, p), 0.0, 1e-12);
    }
  }
}

TEST(SurfacePass, TorusToolsFinishASlopeWithoutGoingIntoIt) {
  // The plane z = -x tan(30 deg), finished along Y by plane_cl with a fixed vertical axis and
  // leaning 10 deg along the feed: every setpoint's tool touches the plane and stays above it.
  const double slope = 30.0 * std::numbers::pi / 180.0;
  const Eigen::Vector3d n(std::sin(slope), 0.0, std::cos(slope));
  const gp_Pln plane(gp_Pnt(0, 0, 0), gp_Dir(n.x(), n.y(), n.z()));
  const TopoDS_Face face = BRepBuilderAPI_MakeFace(plane, -20, 20, -20, 20).Face();
  const FaceSurface surface(face, "slope");
  const auto xyzac =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyzac.toml"));
  Orientation tilted;
  tilted.kind = Orientation::Kind::kTiltYaw;
  tilted.tilt_rad = 10.0 * std::numbers::pi / 180.0;
  for (const Tool& tool :
       {Torus(Tool::Kind::kBullNose, 5.0, 1.0), Torus(Tool::Kind::kFlatEnd, 4.0, 0.0), Ball(3.0)}) {
    for (const Orientation& o : {Orientation{}, tilted}) {
      SCOPED_TRACE(tool.Describe() + ", " + o.Describe());
      StrategySpec spec;
      spec.plane_normal = Eigen::Vector3d::UnitX();
      spec.direction = Eigen::Vector3d::UnitY();
      spec.stepover_mm = 8.0;
      const auto passes = strategies::BuildPasses(surface, tool, o, spec);
      ASSERT_GE(passes.passes.size(), 3u);
      interp::VpopOptions opt;
      opt.feed_mm_s = 50.0;
      test::Collect sink;
      interp::PlanVpop(*passes.passes[1], *xyzac, opt, sink);
      ASSERT_GT(sink.points.size(), 100u);
      double lo = INFINITY, hi = -INFINITY;
      for (const auto& sp : sink.points) {
        const double c =
            ClearanceAbovePlane(tool, xyzac->Forward(sp.q), n, Eigen::Vector3d::Zero());
        lo = std::min(lo, c), hi = std::max(hi, c);
      }
      EXPECT_GT(lo, -1e-6);
      EXPECT_LT(hi, 1e-6);
    }
  }
}

// Calls visit(pass, sample, contact) at arc lengths (from + k step) times each pass's length,
// below its end, marching from one to the next.
template <typename Visit>
void ForPosesAlong(const strategies::PassList& passes, double from, double step, Visit&& visit) {
  for (const auto& pass : passes.passes) {
    PathState st = pass->Start();
    const double length = *pass->Length();
    for (double f = from; f < 1.0; f += step) {
      const PathSample smp = pass->At(st, f * length);
      ASSERT_EQ(smp.status, PathStatus::kOk);
      strategies::ContactPoint c;
      ASSERT_EQ(pass->Evaluate(smp.state, &c), strategies::EvalStatus::kOk);
      visit(*pass, smp, c);
      st = smp.state;
    }
  }
}

// How far the tool at `pose` stands above `face` (from the side `toward` points to at the
// contact (u, v)), sampled: points of its flat bottom and of the lower outer quarter of its
// corner, each projected onto the face by OpenCASCADE; samples with no orthogonal projection (off
// the face's edge, or projected onto it) are skipped. The least signed distance.
double SampledClearance(const TopoDS_Face& face, const Tool& tool, const Pose& pose,
                        const Eigen::Vector2d& uv, const Eigen::Vector3d& toward) {
  const Handle(Geom_Surface) s = BRep_Tool::Surface(face);
  gp_Pnt p0;
  gp_Vec su, sv;
  s->D1(uv.x(), uv.y(), p0, su, sv);
  const double side =
      Eigen::Vector3d(su.Crossed(sv).X(), su.Crossed(sv).Y(), su.Crossed(sv).Z()).dot(toward) > 0.0
          ? 1.0
          : -1.0;
  const Eigen::Vector3d& a = pose.axis;
  const Eigen::Vector3d e1 = a.unitOrthogonal(), e2 = a.cross(e1);
  const double r = tool.corner_radius, big_r = tool.TorusRadius();
  std::vector<Eigen::Vector3d> points;
  constexpr int kAround = 72;
  for (int i = 0; i < kAround; ++i) {
    const double phi = 2.0 * std::numbers::pi * i / kAround;
    const Eigen::Vector3d e = std::cos(phi) * e1 + std::sin(phi) * e2;
    for (int k = 1; k <= 3; ++k) points.push_back(pose.tip + e * (big_r * k / 3.0));
    for (int k = 0; k <= 6; ++k) {
      const double psi = 0.5 * std::numbers::pi * k / 6.0;
      points.push_back(pose.tip + r * a + big_r * e + r * (std::sin(psi) * e - std::cos(psi) * a));
    }
  }
  double least = INFINITY;
  GeomAPI_ProjectPointOnSurf proj;
  double u0, u1, v0, v1;
  s->Bounds(u0, u1, v0, v1);
  proj.Init(s, u0, u1, v0, v1, 1e-9);
  for (const Eigen::Vector3d& x : points) {
    proj.Perform(gp_Pnt(x.x(), x.y(), x.z()));
    if (!proj.IsDone() || proj.NbPoints() == 0) continue;
    double u, v;
    proj.LowerDistanceParameters(u, v);
    gp_Pnt q;
    s->D1(u, v, q, su, sv);
    const gp_Vec nn = su.Crossed(sv);
    if (nn.Magnitude() == 0.0) continue;
    const Eigen::Vector3d normal = side * Eigen::Vector3d(nn.X(), nn.Y(), nn.Z()) / nn.Magnitude();
    const Eigen::Vector3d off = x - Eigen::Vector3d(q.X(), q.Y(), q.Z());
    // A point beside the face's edge projects onto the edge, not along the normal there.
    if (off.cross(normal).norm() > 1e-6 * std::max(off.norm(), 1e-3)) continue;
    least = std::min(least, off.dot(normal));
  }
  return least;
}

// At the ForPosesAlong poses, no sampled point of the tool is under the face (SampledClearance).
void ExpectToolAboveFace(const TopoDS_Face& face, const Tool& tool,
                         const strategies::PassList& passes, double from, double step) {
  ForPosesAlong(passes, from, step,
                [&](const strategies::SurfacePass& pass, const PathSample& smp,
                    const strategies::ContactPoint& c) {
                  EXPECT_GT(SampledClearance(face, tool, smp.pose, c.uv, c.n), -1e-6)
                      << pass.Describe(smp.state);
                });
}

// Where a pass rides over from the previous one (RidesOverFromPrevious), the straight move between
// them (the axis turning as geometry::StraightMoveAxis turns it) keeps the tool above the face,
// at its quarter points (each takes OpenCASCADE a fifth of a second); the number of such moves.
int ExpectRidesAboveFace(const TopoDS_Face& face, const Tool& tool,
                         const strategies::PassList& passes) {
  int rides = 0;
  for (std::size_t k = 1; k < passes.passes.size(); ++k) {
    const strategies::SurfacePass& pass = *passes.passes[k];
    if (!pass.RidesOverFromPrevious()) continue;
    ++rides;
    const Pose a = passes.passes[k - 1]->EndPose(), b = pass.StartPose();
    strategies::ContactPoint c;
    EXPECT_EQ(pass.Evaluate(pass.Start(), &c), strategies::EvalStatus::kOk);
    for (int i = 1; i < 4; ++i) {
      const double t = i / 4.0;
      const Pose at{(1.0 - t) * a.tip + t * b.tip,
                    geometry::StraightMoveAxis(a.tip, b.tip, a.axis, b.axis, t)};
      EXPECT_GT(SampledClearance(face, tool, at, c.uv, c.n), -1e-6)
          << "riding over to pass " << pass.Index() << " at " << t;
    }
  }
  return rides;
}

TEST(SurfacePass, TiltedBullNoseTouchesACurvedFaceWithoutGoingIntoIt) {
  const TiltedTrj8 trj8;
  const TopoDS_Face& face = trj8.face;
  const Tool& bull = trj8.bull;
  const auto& passes = trj8.passes;
  ASSERT_FALSE(passes.passes.empty());
  int checked = 0;
  ForPosesAlong(passes, 0.2, 0.3,
                [&](const strategies::SurfacePass& pass, const PathSample& smp,
                    const strategies::ContactPoint& c) {
                  // No point of the tool is under the face...
                  EXPECT_GT(SampledClearance(face, bull, smp.pose, c.uv, c.n), -1e-6)
                      << pass.Describe(smp.state);
                  // ... and the contact point is on the tool's lower outer corner: r from the
                  // corner circle, below its plane and outside its radius.
                  const Eigen::Vector3d centre = smp.pose.tip + bull.corner_radius * smp.pose.axis;
                  const Eigen::Vector3d d = c.p - centre;
                  const Eigen::Vector3d across = d - d.dot(smp.pose.axis) * smp.pose.axis;
                  const Eigen::Vector3d corner = centre + across.normalized() * bull.TorusRadius();
                  EXPECT_NEAR((c.p - corner).norm(), bull.corner_radius, 1e-9);
                  EXPECT_LE((c.p - corner).dot(smp.pose.axis), 1e-9);
                  EXPECT_GE((c.p - corner).dot(across.normalized()), -1e-9);
                  ++checked;
                });
  EXPECT_GE(checked, 10);
}

std::string BuildError(const std::string& file, int face_index, const Tool& tool,
                       const StrategySpec& spec, const Eigen::Vector3d& rotate = {0, 0, 0}) {
  const StepModel m = StepModel::Load(test::Source(file));
  const FaceSurface surface(geometry::PlaceFace(m.Face(face_index), rotate, {0, 0, 0}), "the face");
  try {
    strategies::BuildPasses(surface, tool, Orientation{}, spec);
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

TEST(SurfaceErrors, NameTheFaceTheLineAndWhere) {
  StrategySpec spec;
  spec.stepover_mm = 5.0;
  spec.on_gouge = StrategySpec::OnGouge::kStop;
  const std::string gouge =
      BuildError("samples/parts/occt_bug29478_single_rational_face_worknc.stp", 1, Ball(3.0), spec);
  EXPECT_NE(gouge.find("gouges"), std::string::npos) << gouge;
  EXPECT_NE(gouge.find("0.3 mm"), std::string::npos) << gouge;

  const std::string undercut = BuildError(kTrj8, 1, Ball(3.0), spec);
  EXPECT_NE(undercut.find("undercut"), std::string::npos) << undercut;
  EXPECT_NE(undercut.find("arc length"), std::string::npos) << undercut;

  StrategySpec far = spec;
  far.range = std::array<double, 2>{500.0, 510.0};
  const std::string misses = BuildError(kStrip, 1, Ball(1.0), far);
  EXPECT_NE(misses.find("misses the face"), std::string::npos) << misses;
}

// More strategy lines than kMaxLines (a stepover of a micrometre, a range of 1e300 mm) are
// refused before any is traced, naming the key the job gave.
TEST(SurfaceErrors, TooManyLinesAreRefusedNamingTheKey) {
  StrategySpec spec;
  spec.stepover_mm = 1e-6;
  spec.stepover_key = "j.toml:9: key 'strategy.stepover_mm'";
  const std::string fine = BuildError(kStrip, 1, Ball(1.0), spec);
  EXPECT_EQ(fine.rfind("j.toml:9: key 'strategy.stepover_mm': ", 0), 0u) << fine;
  EXPECT_NE(fine.find("more than the 10000 a face is traced with"), std::string::npos) << fine;
  StrategySpec wide;
  wide.stepover_mm = 2.0;
  wide.range = std::array<double, 2>{-1e300, 1e300};
  wide.range_key = "j.toml:10: key 'strategy.range'";
  const std::string range = BuildError(kStrip, 1, Ball(1.0), wide);
  EXPECT_EQ(range.rfind("j.toml:10: key 'strategy.range': 1e+300 strategy lines", 0), 0u) << range;
}

TEST(SurfaceErrors, AnOrientationTheMachineCannotHoldStopsThePlanWithWhere) {
  const StepModel m = StepModel::Load(test::Source(kStrip));
  const FaceSurface surface(m.Face(1), "strip");
  Orientation o;
  o.kind = Orientation::Kind::kTiltYaw;
  o.tilt_rad = 0.2;
  StrategySpec spec;
  spec.stepover_mm = 1.0;
  spec.direction = Eigen::Vector3d::UnitY();
  const auto passes = strategies::BuildPasses(surface, Ball(2.0), o, spec);
  const auto xyz =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  interp::VpopOptions opt;
  opt.feed_mm_s = 50.0;
  test::Collect sink;
  try {
    interp::PlanVpop(*passes.passes[0], *xyz, opt, sink);
    FAIL() << "a tilted axis on an XYZ machine must fail";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("pass 1"), std::string::npos) << what;
    EXPECT_NE(what.find("(u, v)"), std::string::npos) << what;
  }
}

// Random faces, strategies and tools: every pass that builds is followed exactly: each sample is
// on its line (|g| within the Newton tolerance) and the march reaches the traced end.
TEST(SurfaceProperty, RandomStrategiesOnRealFaces) {
  std::mt19937_64 rng(test::g_seed + 3);
  std::uniform_real_distribution<double> uni(0.0, 1.0);
  const std::vector<std::string> files = {kTrj8, kStrip};
  std::vector<StepModel> models;
  for (const auto& f : files) models.push_back(StepModel::Load(test::Source(f)));
  const long cases = std::max<long>(4, test::g_count / 20);
  long built = 0;
  for (long k = 0; k < cases; ++k) {
    const std::size_t which = rng() % models.size();
    const Eigen::Vector3d rotate(0, which == 0 ? 90.0 : 0.0, 0);
    const TopoDS_Face face = geometry::PlaceFace(models[which].Face(1), rotate, {0, 0, 0});
    const FaceSurface surface(face, files[which]);
    StrategySpec spec;
    spec.kind = static_cast<StrategySpec::Kind>(rng() % 4);
    if (spec.kind == StrategySpec::Kind::kLeadingLine) {
      // A random cubic across the face's box, seen from above.
      const auto [lo, hi] = geometry::FaceBox(face);
      geometry::BSplineCurveData g{3, {0, 0, 0, 0, 0.5, 1, 1, 1, 1}, {}, {}};
      for (int i = 0; i < 5; ++i) {
        g.poles.emplace_back(lo.x() + (hi.x() - lo.x()) * (i / 4.0),
                             lo.y() + (hi.y() - lo.y()) * uni(rng), 0.0);
      }
      if (uni(rng) < 0.5) {
        for (auto& p : g.poles) std::swap(p.x(), p.y());
      }
      spec.guide = std::make_shared<const geometry::BSplineCurve>(std::move(g));
    }
    const double angle = uni(rng) * std::numbers::pi;
    spec.plane_normal = Eigen::Vector3d(std::cos(angle), std::sin(angle), 0.0);
    spec.direction = Eigen::Vector3d(-std::sin(angle), std::cos(angle), 0.0);
    spec.along_u = rng() % 2 == 0;
    spec.mode = rng() % 2 ? StrategySpec::PathMode::kZigzag : StrategySpec::PathMode::kForward;
    spec.stepover_mm = 2.0 + 6.0 * uni(rng);
    spec.max_passes = 2;
    const Tool tool = Ball(0.5 + 3.0 * uni(rng));
    strategies::PassList passes;
    try {
      passes = strategies::BuildPasses(surface, tool, Orientation{}, spec);
    } catch (const Error& e) {
      // Refusals must say where (undercuts and gouges are real on these faces), or why no pass
      // could start.
      const std::string what = e.what();
      EXPECT_TRUE(what.find("(u, v)") != std::string::npos ||
                  what.find("passes could not start: ") != std::string::npos)
          << what;
      continue;
    }
    ++built;
    for (const auto& pass : passes.passes) {
      PathState st = pass->Start();
      const double length = *pass->Length();
      const double step = 0.05 + 0.5 * uni(rng);
      bool early = false;
      for (double s = step;; s += step) {
        PathSample smp = pass->At(st, std::min(s, length));
        if (smp.status == PathStatus::kEnd) {
          // A pass meeting the boundary at a grazing angle may end before its traced length: it
          // ends on the boundary, or as far off it as a skim may go (0.01 mm, surface_pass.cpp).
          ASSERT_LE(pass->Evaluator().Face().DistanceOutside(smp.state.u, smp.state.v), 1e-2);
          early = true;
          break;
        }
        ASSERT_EQ(smp.status, PathStatus::kOk)
            << pass->Describe(st) << " asked " << s << " of " << length << " start "
            << pass->Start().u << "," << pass->Start().v << " end "
            << pass->EndPose().tip.transpose();
        strategies::ContactPoint c;
        ASSERT_EQ(pass->Evaluate(smp.state, &c), strategies::EvalStatus::kOk);
        ASSERT_LE(std::abs(c.g), 1e-6) << pass->Describe(smp.state);
        ASSERT_LT((c.tip - smp.pose.tip).norm(), 1e-12);
        st = smp.state;
        if (s >= length) break;
      }
      if (!early) {
        EXPECT_LT((pass->At(st, length).pose.tip - pass->EndPose().tip).norm(), 1e-6)
            << pass->Describe(st);
      }
    }
  }
  EXPECT_GT(built, 0);
}

}  // namespace
}  // namespace dtis

namespace dtis {
namespace {

// leading_line: every contact point of a pass, seen from above, lies its offset away from the
// guide curve (distance by OpenCASCADE's projection onto the guide, independent of ours).
TEST(SurfacePass, LeadingLineKeepsTheContactPointAtItsOffsetFromTheGuide) {
  const StepModel m = StepModel::Load(test::Source(kTrj8));
  const TopoDS_Face face = geometry::PlaceFace(m.Face(1), {0, 90, 0}, {0, 0, 0});
  const FaceSurface surface(face, "trj8");
  geometry::BSplineCurveData data{
      3,
      {0, 0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1, 1},
      {{-14, 4, 0}, {0, 8, 0}, {15, 1, 0}, {30, 7, 0}, {45, 2, 0}, {58, 7, 0}, {70, 4, 0}},
      {}};
  StrategySpec spec;
  spec.kind = StrategySpec::Kind::kLeadingLine;
  spec.guide = std::make_shared<const geometry::BSplineCurve>(std::move(data));
  spec.stepover_mm = 2.5;
  spec.range = std::array<double, 2>{-2.5, 2.5};
  const auto passes = strategies::BuildPasses(surface, Ball(3.0), Orientation{}, spec);
  ASSERT_GE(passes.passes.size(), 3u);
  const Handle(Geom_BSplineCurve) guide = geometry::ToOcct(*spec.guide);
  for (const auto& pass : passes.passes) {
    const double offset = pass->Evaluator().Constraint().value;
    PathState st = pass->Start();
    for (double s = 0.0;; s += 0.2) {
      const PathSample smp = pass->At(st, std::min(s, *pass->Length()));
      ASSERT_EQ(smp.status, PathStatus::kOk);
      strategies::ContactPoint c;
      ASSERT_EQ(pass->Evaluate(smp.state, &c), strategies::EvalStatus::kOk);
      GeomAPI_ProjectPointOnCurve proj(gp_Pnt(c.p.x(), c.p.y(), 0.0), guide);
      ASSERT_GT(proj.NbPoints(), 0);
      EXPECT_NEAR(proj.LowerDistance(), std::abs(offset), 1e-6) << pass->Describe(smp.state);
      // The tip is a ball radius off the exact surface.
      EXPECT_NEAR(DistanceToSurface(face, smp.pose.tip + smp.pose.axis * 3.0), 3.0, 1e-6);
      st = smp.state;
      if (s >= *pass->Length()) break;
    }
  }
}

}  // namespace
}  // namespace dtis

namespace dtis {
namespace {

// The trim grid answers Inside exactly as OpenCASCADE's classifier does, on every trimmed face of
// a real part (B-spline, plane, cylinder and cone faces with holes and slots), at random points of
// each face's UV box and at points on and beside its boundary, and it answers for most of the box.
TEST(FaceSurface, TrimGridAgreesWithTheClassifier) {
  const StepModel part =
      StepModel::Load(test::Source("samples/parts/occt_ec_turbine-A_53faces_rational.stp"));
  std::mt19937 rng(20261125);
  int trimmed = 0, total_surely_outside = 0;
  double coverage = 0.0;
  for (int f = 1; f <= part.FaceCount(); ++f) {
    const FaceSurface face(part.Face(f), "face " + std::to_string(f));
    if (!face.Trimmed()) continue;
    ++trimmed;
    coverage += face.GridCoverage();
    std::uniform_real_distribution<double> u(face.U0(), face.U1()), v(face.V0(), face.V1());
    int disagree = 0, surely_outside = 0;
    // SurelyOutside answers from the grid alone: never for a point on the face.
    const auto surely = [&](double a, double b) {
      if (!face.SurelyOutside(a, b)) return 0;
      ++surely_outside;
      return face.InsideByClassifier(a, b) ? 1 : 0;
    };
    for (int k = 0; k < 2000; ++k) {
      const double a = u(rng), b = v(rng);
      disagree += face.Inside(a, b) != face.InsideByClassifier(a, b);
      disagree += surely(a, b);
    }
    // Next to the boundary, where the grid must hand over to the classifier.
    const double eps = 1e-7 * std::max(face.U1() - face.U0(), face.V1() - face.V0());
    for (const auto& loop : face.Boundary(40)) {
      for (const Eigen::Vector2d& p : loop) {
        for (const Eigen::Vector2d& d :
             {Eigen::Vector2d(0, 0), Eigen::Vector2d(eps, 0), Eigen::Vector2d(-eps, 0),
              Eigen::Vector2d(0, eps), Eigen::Vector2d(0, -eps)}) {
          const Eigen::Vector2d q = p + d;
          disagree += face.Inside(q.x(), q.y()) != face.InsideByClassifier(q.x(), q.y());
          disagree += surely(q.x(), q.y());
        }
      }
    }
    EXPECT_EQ(disagree, 0) << face.Where();
    total_surely_outside += surely_outside;
  }
  EXPECT_GT(total_surely_outside, 1000);  // it does answer
  EXPECT_GE(trimmed, 10);
  EXPECT_GT(coverage / trimmed, 0.5);
  std::printf("trim grid: %d trimmed faces, %.0f %% of their UV boxes answered by the grid\n",
              trimmed, 100.0 * coverage / trimmed);
}

// A trimmed face: a disc of radius 20 mm cut from the plane z = 0. A ball end's passes in planes
// x = c are the chords of the disc: they start and end on the trimming circle and are
// 2 sqrt(R^2 - c^2) long (a closed form independent of the strategies' code).
// A valley z = y^2 / (2 rho), rho = 20 mm, over x, y in [-15, 15]: a Bezier surface, quadratic
// across the valley, linear along it.
// With `rho` and `half`: z = y^2 / (2 rho) over y in [-half, half].
TopoDS_Face Valley(double rho = 20.0, double half = 15.0) {
  TColgp_Array2OfPnt poles(1, 2, 1, 3);
  const double edge = half * half / (2.0 * rho);
  for (int i = 1; i <= 2; ++i) {
    const double x = i == 1 ? -15.0 : 15.0;
    poles(i, 1) = gp_Pnt(x, -half, edge);
    poles(i, 2) = gp_Pnt(x, 0.0, -edge);
    poles(i, 3) = gp_Pnt(x, half, edge);
  }
  return BRepBuilderAPI_MakeFace(Handle(Geom_BezierSurface)(new Geom_BezierSurface(poles)), 1e-7)
      .Face();
}

TEST(SurfaceErrors, AFlatBottomAcrossAValleyIsAGougeWithWhereAndHowDeep) {
  // A flat end R4 crossing the valley touches with its edge on the near flank, its bottom
  // reaching 8 mm towards the far one; once the contact is within 4 mm of the bottom of the
  // valley, the far flank rises above the contact there and the bottom goes into it. The contact's
  // own curvature says nothing of it (the edge touches a flank of radius 20 mm).
  const FaceSurface surface(Valley(), "valley");
  StrategySpec spec;
  spec.plane_normal = Eigen::Vector3d::UnitX();
  spec.direction = Eigen::Vector3d::UnitY();
  spec.stepover_mm = 5.0;
  for (const Tool& tool :
       {Torus(Tool::Kind::kFlatEnd, 4.0, 0.0), Torus(Tool::Kind::kBullNose, 4.0, 1.0)}) {
    SCOPED_TRACE(tool.Describe());
    StrategySpec stop = spec;
    stop.on_gouge = StrategySpec::OnGouge::kStop;
    test::ExpectError([&] { strategies::BuildPasses(surface, tool, Orientation{}, stop); },
                      {"the tool gouges", "mm into it at (", "line 1", "arc length"});
    // Skipping it instead: each line is finished up to where the tool stands centred over the
    // valley's floor (by symmetry the bottom then touches both flanks, and one step further its
    // far side goes into the face), and again from where it stands centred touching the other
    // flank; the stretch between is reported, and the tool rides over it from one to the other.
    const auto passes = strategies::BuildPasses(surface, tool, Orientation{}, spec);
    ASSERT_EQ(passes.passes.size(), 12u);
    ASSERT_EQ(passes.unreachable.size(), 6u);
    for (std::size_t k = 0; k < passes.passes.size(); ++k) {
      const auto& pass = passes.passes[k];
      EXPECT_EQ(pass->RidesOverFromPrevious(), k % 2 == 1) << k;
      EXPECT_NEAR(std::abs((k % 2 == 0 ? pass->StartPose() : pass->EndPose()).tip.y()),
                  15.0 - tool.radius, 0.5);
      EXPECT_NEAR((k % 2 == 0 ? pass->EndPose() : pass->StartPose()).tip.y(), 0.0, 1e-4);
      const PathSample end = pass->At(pass->Start(), *pass->Length());
      EXPECT_NEAR(end.pose.tip.y(), pass->EndPose().tip.y(), 1e-6);
    }
    EXPECT_EQ(ExpectRidesAboveFace(Valley(), tool, passes), 6);
    for (const auto& u : passes.unreachable) {
      EXPECT_TRUE(u.resumes);
      EXPECT_TRUE(u.ridden_over);
      EXPECT_NEAR(u.to.y(), -u.from.y(), 1e-4);
      EXPECT_NE(u.why.find("the tool gouges"), std::string::npos) << u.why;
      // The contact where the tool is centred: y + r n_y(y) + R = 0 on the near flank.
      double y = -tool.radius;
      for (int it = 0; it < 50; ++it) {
        const double n_y = (-y / 20.0) / std::sqrt(1.0 + y * y / 400.0);
        y = -tool.TorusRadius() - tool.corner_radius * n_y;
      }
      EXPECT_NEAR(std::abs(u.from.y()), -y, 1e-4);
      EXPECT_NEAR(u.from.z(), y * y / 40.0, 1e-4);
      // The length of the valley's section between the two, on the face.
      const double a = -y;
      EXPECT_NEAR(u.length_mm, a * std::sqrt(1.0 + a * a / 400.0) + 20.0 * std::asinh(a / 20.0),
                  1e-3);
    }
    ExpectToolAboveFace(Valley(), tool, passes, 0.05, 0.3);
    const std::string text = passes.UnreachableText(2);
    EXPECT_NE(text.find("6 stretches"), std::string::npos) << text;
    EXPECT_NE(text.find("and 4 more"), std::string::npos) << text;
  }
  // A ball narrower than the valley's radius finishes it, and no point of it is under the face.
  const Tool ball = Ball(3.0);
  const auto passes = strategies::BuildPasses(surface, ball, Orientation{}, spec);
  ASSERT_GE(passes.passes.size(), 5u);
  const TopoDS_Face face = Valley();
  ExpectToolAboveFace(face, ball, passes, 0.05, 0.3);
}

TEST(SurfacePass, ABallInAValleyTighterThanItLeavesTheFloorOut) {
  // A ball R3 in a valley of radius 2 mm (z = y^2 / 4): centred over the floor it touches both
  // flanks, at y = -+sqrt(R^2 - rho^2) (there y + R n_y = 0, n_z = rho / R). Past that its far
  // side would go into the face, until it stands centred again touching the other way: each line
  // is a pass up to the first place and another from the second, the stretch between reported.
  // (On plane_cl lines the ball's centre path folds back in between, where the valley's radius is
  // the ball's: the contact point is marched through.)
  const double rho = 2.0, big_r = 3.0;
  const TopoDS_Face face = Valley(rho, 8.0);
  const FaceSurface surface(face, "tight valley");
  const Tool ball = Ball(big_r);
  const double y = std::sqrt(big_r * big_r - rho * rho);
  for (const auto kind : {StrategySpec::Kind::kUv, StrategySpec::Kind::kPlaneCl}) {
    SCOPED_TRACE(StrategySpec::KindName(kind));
    StrategySpec spec;
    spec.kind = kind;
    spec.along_u = false;
    spec.plane_normal = Eigen::Vector3d::UnitX();
    spec.direction = Eigen::Vector3d::UnitY();
    spec.stepover_mm = 7.5;
    const auto passes = strategies::BuildPasses(surface, ball, Orientation{}, spec);
    ASSERT_EQ(passes.unreachable.size(), 4u);
    ASSERT_EQ(passes.passes.size(), 8u);
    for (const auto& u : passes.unreachable) {
      EXPECT_TRUE(u.resumes);
      EXPECT_NE(u.why.find("the tool gouges"), std::string::npos) << u.why;
      EXPECT_NEAR(std::abs(u.from.y()), y, 1e-4);
      EXPECT_NEAR(u.to.y(), -u.from.y(), 1e-4);
      EXPECT_NEAR(u.from.z(), y * y / (2.0 * rho), 1e-4);
      EXPECT_NEAR(u.length_mm, y * std::sqrt(1.0 + y * y / (rho * rho)) + rho * std::asinh(y / rho),
                  1e-3);
    }
    for (std::size_t k = 0; k < passes.passes.size(); ++k) {
      const auto& pass = passes.passes[k];
      const Pose at = k % 2 == 0 ? pass->EndPose() : pass->StartPose();
      EXPECT_NEAR(at.tip.y(), 0.0, 1e-4);
      EXPECT_NEAR(at.tip.z(), y * y / (2.0 * rho) + rho - big_r, 1e-4);
    }
    ExpectToolAboveFace(face, ball, passes, 0.05, 0.3);
  }
  // A valley no wider than that stretch leaves nothing to finish: an error that says where.
  const FaceSurface narrow(Valley(rho, 2.0), "narrow valley");
  StrategySpec spec;
  spec.stepover_mm = 7.5;
  test::ExpectError([&] { strategies::BuildPasses(narrow, ball, Orientation{}, spec); },
                    {"narrow valley", "the tool fits nowhere along the plane_cl strategy's passes",
                     "line 1, from (", "the tool gouges"});
}

TEST(SurfacePass, AFlatBottomOnAPlaneAcrossTheAxisHasItsTipOnThePlane) {
  const TopoDS_Face face = BRepBuilderAPI_MakeFace(gp_Pln(gp::XOY()), -20, 20, -20, 20).Face();
  const FaceSurface surface(face, "floor");
  const auto xyz =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  for (const Tool& tool :
       {Torus(Tool::Kind::kFlatEnd, 4.0, 0.0), Torus(Tool::Kind::kBullNose, 5.0, 1.0)}) {
    SCOPED_TRACE(tool.Describe());
    StrategySpec spec;
    spec.stepover_mm = 7.0;
    const auto passes = strategies::BuildPasses(surface, tool, Orientation{}, spec);
    ASSERT_EQ(passes.passes.size(), 6u);
    for (const auto& pass : passes.passes) {
      EXPECT_NEAR(*pass->Length(), 40.0, 1e-6);
      interp::VpopOptions opt;
      opt.feed_mm_s = 50.0;
      const test::Planned planned = test::PlanAndVerify(*pass, *xyz, opt);
      EXPECT_LE(planned.report.worst_ratio, 1.0) << planned.report.worst;
      for (const auto& sp : planned.points) EXPECT_NEAR(xyz->Forward(sp.q).tip.z(), 0.0, 1e-9);
    }
  }
}

// A dome z = 8 - (x^2 + y^2) / 100 near its top (0, 0, 8), over x, y in [-20, 20]: a biquadratic
// Bezier surface.
// With `ridge`, a ruled ridge z = 8 - y^2 / 100 instead (its top is the line y = 0).
TopoDS_Face Dome(bool ridge = false) {
  TColgp_Array2OfPnt poles(1, 3, 1, 3);
  for (int i = 1; i <= 3; ++i) {
    for (int j = 1; j <= 3; ++j) {
      const double z = (i == 2 && !ridge ? 8.0 : ridge ? 4.0 : 0.0) + (j == 2 ? 8.0 : 0.0);
      poles(i, j) = gp_Pnt(20.0 * (i - 2), 20.0 * (j - 2), z);
    }
  }
  return BRepBuilderAPI_MakeFace(Handle(Geom_BezierSurface)(new Geom_BezierSurface(poles)), 1e-7)
      .Face();
}

TEST(SurfacePass, AFlatBottomSlidesOverATopWithItsTipAtTheTopsHeight) {
  // Passes in x = const within R of the top carry the tool over it: there the bottom sits on the
  // top and the tip runs straight at z = 8 across the disc of radius R around it (over a ridge,
  // R either side of its line). Both planners follow it within every limit.
  const auto xyz =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  for (const Tool& tool :
       {Torus(Tool::Kind::kFlatEnd, 4.0, 0.0), Torus(Tool::Kind::kBullNose, 5.0, 1.0)}) {
    for (const bool ridge : {false, true}) {
      const TopoDS_Face face = Dome(ridge);
      const FaceSurface surface(face, ridge ? "ridge" : "dome");
      SCOPED_TRACE(tool.Describe() + (ridge ? " on the ridge" : " on the dome"));
      StrategySpec spec;
      spec.plane_normal = Eigen::Vector3d::UnitX();
      spec.direction = Eigen::Vector3d::UnitY();
      spec.range = std::array<double, 2>{-3.0, 3.0};
      spec.stepover_mm = 3.0;
      const auto passes = strategies::BuildPasses(surface, tool, Orientation{}, spec);
      ASSERT_EQ(passes.passes.size(), 3u);
      for (const auto& pass : passes.passes) {
        const double x = pass->Evaluator().Constraint().value;
        SCOPED_TRACE(x);
        const double big_r = tool.TorusRadius();
        // The chord over the top, from the planned setpoints.
        interp::VpopOptions opt;
        opt.feed_mm_s = 50.0;
        opt.planner =
            pass->Index() % 2 ? interp::PlannerKind::kVpop : interp::PlannerKind::kLookAhead;
        const test::Planned planned = test::PlanAndVerify(*pass, *xyz, opt);
        ASSERT_GT(planned.points.size(), 100u);
        EXPECT_LE(planned.report.worst_ratio, 1.0) << planned.report.worst;
        EXPECT_TRUE(planned.report.starts_at_rest && planned.report.ends_at_rest);
        double lo = INFINITY, hi = -INFINITY;
        for (const auto& sp : planned.points) {
          const Pose pose = xyz->Forward(sp.q);
          if (std::abs(pose.tip.z() - 8.0) < 1e-9) {
            lo = std::min(lo, pose.tip.y()), hi = std::max(hi, pose.tip.y());
          }
          EXPECT_LE(pose.tip.z(), 8.0 + 1e-9);
          EXPECT_NEAR(pose.tip.x(), x, 1e-6);
        }
        const double half = ridge ? big_r : std::sqrt(big_r * big_r - x * x);
        EXPECT_NEAR(lo, -half, 0.06);  // setpoints 1 ms apart at 50 mm/s at most
        EXPECT_NEAR(hi, half, 0.06);
      }
      // And the tool stays on the face, touching, not in it: OpenCASCADE's projection.
      ExpectToolAboveFace(face, tool, passes, 0.1, 0.2);
    }
  }
}

TEST(SurfaceErrors, AGuideBendTighterThanTheOffsetIsNamed) {
  // A guide along X that turns left towards +Y in a bend of a few mm: the pass 6 mm to its left
  // runs inside the bend, where the offset line folds over itself.
  const TopoDS_Face floor = BRepBuilderAPI_MakeFace(gp_Pln(gp::XOY()), -50, 50, -50, 50).Face();
  const FaceSurface surface(floor, "floor");
  StrategySpec spec;
  spec.kind = StrategySpec::Kind::kLeadingLine;
  spec.guide = std::make_shared<const geometry::BSplineCurve>(
      geometry::BSplineCurveData{2,
                                 {0, 0, 0, 0.45, 0.55, 1, 1, 1},
                                 {{-40, 0, 0}, {-4, 0, 0}, {0, 0, 0}, {0, 4, 0}, {0, 40, 0}},
                                 {}});
  spec.range = std::array<double, 2>{6.0, 6.0};
  spec.stepover_mm = 6.0;
  spec.on_gouge = StrategySpec::OnGouge::kStop;
  test::ExpectError([&] { strategies::BuildPasses(surface, Ball(2.0), Orientation{}, spec); },
                    {"bends tighter than the pass's offset", "arc length", "(u, v)"});
}

// The guide above on a plane tilted along X (z = 0.2 x), finished by a ball R2 at offsets -6 to
// 6 mm: where the guide's radius of curvature (0.514 mm at least, in its bend) comes within 1 %
// of the offset, on the inside of the bend (the lines 3 and 6 mm to its left), the offset line
// folds over itself. Those lines are finished up to the fold and from where it ends, every pass
// planned within every limit with the ball on the plane; the stretch between is left out, its
// ends and its length (along the offset curve on the face, through the fold's cusps) those
// computed from OpenCASCADE's curve of the guide: the parameters where offset times curvature
// is 0.99, and the offset curve lifted onto the plane, 400000 chords.
// The plane z = 0.2 x over x, y in [-50, 50].
TopoDS_Face TiltedFloor() {
  TColgp_Array2OfPnt poles(1, 2, 1, 2);
  for (int i = 1; i <= 2; ++i) {
    for (int j = 1; j <= 2; ++j) {
      const double x = i == 1 ? -50.0 : 50.0, y = j == 1 ? -50.0 : 50.0;
      poles(i, j) = gp_Pnt(x, y, 0.2 * x);
    }
  }
  return BRepBuilderAPI_MakeFace(Handle(Geom_BezierSurface)(new Geom_BezierSurface(poles)), 1e-7)
      .Face();
}

TEST(SurfacePass, AGuideBendTighterThanTheOffsetLeavesTheFoldOutAndMeasuresIt) {
  const TopoDS_Face face = TiltedFloor();
  const FaceSurface surface(face, "tilted floor");
  const std::vector<Eigen::Vector3d> guide_poles = {
      {-40, 0, 0}, {-4, 0, 0}, {0, 0, 0}, {0, 4, 0}, {0, 40, 0}};
  StrategySpec spec;
  spec.kind = StrategySpec::Kind::kLeadingLine;
  spec.guide = std::make_shared<const geometry::BSplineCurve>(
      geometry::BSplineCurveData{2, {0, 0, 0, 0.45, 0.55, 1, 1, 1}, guide_poles, {}});
  spec.range = std::array<double, 2>{-6.0, 6.0};
  spec.stepover_mm = 3.0;
  const auto passes = strategies::BuildPasses(surface, Ball(2.0), Orientation{}, spec);

  // OpenCASCADE's guide: offset times curvature, and the offset point lifted onto the plane.
  TColgp_Array1OfPnt2d occ_poles(1, 5);
  for (int k = 0; k < 5; ++k) occ_poles(k + 1) = gp_Pnt2d(guide_poles[k].x(), guide_poles[k].y());
  TColStd_Array1OfReal knots(1, 4);
  TColStd_Array1OfInteger mults(1, 4);
  const double kv[] = {0.0, 0.45, 0.55, 1.0};
  const int mv[] = {3, 1, 1, 3};
  for (int k = 0; k < 4; ++k) knots(k + 1) = kv[k], mults(k + 1) = mv[k];
  const Handle(Geom2d_BSplineCurve) guide = new Geom2d_BSplineCurve(occ_poles, knots, mults, 2);
  const auto fold = [&](double d, double t) {
    gp_Pnt2d p;
    gp_Vec2d d1, d2;
    guide->D2(t, p, d1, d2);
    return d * (d1.X() * d2.Y() - d1.Y() * d2.X()) / std::pow(d1.Magnitude(), 3);
  };
  const auto on_plane = [&](double d, double t) {
    gp_Pnt2d p;
    gp_Vec2d d1;
    guide->D1(t, p, d1);
    const double x = p.X() - d * d1.Y() / d1.Magnitude(), y = p.Y() + d * d1.X() / d1.Magnitude();
    return Eigen::Vector3d(x, y, 0.2 * x);
  };
  // Where the fold crosses 0.99 between a (below it) and b (above), by bisection.
  const auto crossing = [&](double d, double a, double b) {
    for (int i = 0; i < 100; ++i) {
      const double m = 0.5 * (a + b);
      (fold(d, m) > 0.99 ? b : a) = m;
    }
    return b;
  };
  int folded_lines = 0;
  for (int line = 1; line <= 5; ++line) {
    const double d = -6.0 + 3.0 * (line - 1);
    SCOPED_TRACE(fmt::format("offset {} mm", d));
    // The fold's parameters, from a scan and bisection at its ends.
    constexpr int kScan = 100000;
    double first = NAN, last = NAN;
    for (int k = 0; k <= kScan; ++k) {
      const double t = static_cast<double>(k) / kScan;
      if (fold(d, t) > 0.99) {
        if (std::isnan(first)) first = t;
        last = t;
      }
    }
    std::vector<const strategies::Unreachable*> stretches;
    for (const auto& u : passes.unreachable) {
      if (u.line == line) stretches.push_back(&u);
    }
    if (std::isnan(first)) {
      EXPECT_TRUE(stretches.empty()) << passes.UnreachableText(100);
      continue;
    }
    ++folded_lines;
    ASSERT_EQ(stretches.size(), 1u) << passes.UnreachableText(100);
    const strategies::Unreachable& u = *stretches.front();
    const double ta = crossing(d, first - 1.0 / kScan, first);
    const double tb = crossing(d, last + 1.0 / kScan, last);
    EXPECT_TRUE(u.resumes);
    EXPECT_NE(u.why.find("bends tighter than the pass's offset"), std::string::npos) << u.why;
    EXPECT_LT((u.from - on_plane(d, ta)).norm(), 1e-3) << u.from.transpose();
    EXPECT_LT((u.to - on_plane(d, tb)).norm(), 1e-3) << u.to.transpose();
    constexpr int kChords = 400000;
    double length = 0.0;
    for (int k = 1; k <= kChords; ++k) {
      length += (on_plane(d, ta + (tb - ta) * k / kChords) -
                 on_plane(d, ta + (tb - ta) * (k - 1) / kChords))
                    .norm();
    }
    EXPECT_NEAR(u.length_mm, length, 1e-3);
    EXPECT_GT(length, 1.0);
  }
  EXPECT_EQ(folded_lines, 2);
  // The run summary lists them.
  EXPECT_NE(passes.UnreachableText(8).find("bends tighter"), std::string::npos);
  // Every pass planned within every limit, the ball on the plane (its centre 2 mm from it).
  ASSERT_EQ(passes.passes.size(), 7u);
  const auto xyz =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  for (const auto& pass : passes.passes) {
    SCOPED_TRACE(pass->Index());
    interp::VpopOptions opt;
    opt.feed_mm_s = 50.0;
    const test::Planned planned = test::PlanAndVerify(*pass, *xyz, opt);
    ASSERT_GT(planned.points.size(), 10u);
    EXPECT_LE(planned.report.worst_ratio, 1.0) << planned.report.worst;
    for (const auto& sp : planned.points) {
      const Pose pose = xyz->Forward(sp.q);
      const Eigen::Vector3d centre = pose.tip + 2.0 * pose.axis;
      ASSERT_NEAR((centre.z() - 0.2 * centre.x()) / std::sqrt(1.04), 2.0, 1e-6);
    }
  }
}

TEST(SurfaceErrors, AFlatBottomOverASaddleIsRefusedWithWhere) {
  // z = (x^2 - y^2) / 100: at the saddle the bottom would rest on the two rising sides at once.
  TColgp_Array2OfPnt poles(1, 3, 1, 3);
  for (int i = 1; i <= 3; ++i) {
    for (int j = 1; j <= 3; ++j) {
      const double z = (i == 2 ? -4.0 : 4.0) - (j == 2 ? -4.0 : 4.0);
      poles(i, j) = gp_Pnt(20.0 * (i - 2), 20.0 * (j - 2), z);
    }
  }
  const FaceSurface surface(
      BRepBuilderAPI_MakeFace(Handle(Geom_BezierSurface)(new Geom_BezierSurface(poles)), 1e-7)
          .Face(),
      "saddle");
  StrategySpec spec;
  spec.range = std::array<double, 2>{0.0, 0.0};
  spec.stepover_mm = 1.0;
  spec.on_gouge = StrategySpec::OnGouge::kStop;
  try {
    strategies::BuildPasses(surface, Torus(Tool::Kind::kFlatEnd, 4.0, 0.0), Orientation{}, spec);
    ADD_FAILURE() << "a flat bottom over a saddle must be refused";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("(u, v)"), std::string::npos) << what;
    EXPECT_TRUE(what.find("gouges") != std::string::npos ||
                what.find("sits flat") != std::string::npos)
        << what;
  }
}

TEST(SurfacePass, APassAcrossASpheresPoleGoesOver) {
  // A hemisphere of radius 30 (its pole a collapsed edge of (u, v)), finished by a ball R3 in
  // planes x = const: the pass in x = 0 crosses the pole, and its ball centre runs on the sphere
  // of radius 33 over half a great circle.
  const Handle(Geom_SphericalSurface) sphere = new Geom_SphericalSurface(gp_Ax3(gp::XOY()), 30.0);
  const FaceSurface surface(
      BRepBuilderAPI_MakeFace(sphere, 0, 2 * std::numbers::pi, 0, std::numbers::pi / 2, 1e-7)
          .Face(),
      "hemisphere");
  StrategySpec spec;
  spec.range = std::array<double, 2>{-4.0, 4.0};
  spec.stepover_mm = 4.0;
  const auto passes = strategies::BuildPasses(surface, Ball(3.0), Orientation{}, spec);
  const auto xyz =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  bool over = false;
  for (const auto& pass : passes.passes) {
    const double x = pass->Evaluator().Constraint().value;
    SCOPED_TRACE(x);
    interp::VpopOptions opt;
    opt.feed_mm_s = 50.0;
    const test::Planned planned = test::PlanAndVerify(*pass, *xyz, opt);
    EXPECT_LE(planned.report.worst_ratio, 1.0) << planned.report.worst;
    for (const auto& sp : planned.points) {
      const Pose pose = xyz->Forward(sp.q);
      EXPECT_NEAR((pose.tip + 3.0 * pose.axis).norm(), 33.0, 1e-6);
      EXPECT_NEAR(pose.tip.x(), x, 1e-6);
    }
    if (std::abs(x) < 1e-9) {
      EXPECT_NEAR(*pass->Length(), std::numbers::pi * 33.0, 1e-6);
      over = true;
    }
  }
  EXPECT_TRUE(over);
}

using test::WavyRuledFace;

// The wavy face's 5-axis orientation: tilted 10 deg from the normal along the feed.
Orientation Tilted10() {
  Orientation o;
  o.kind = Orientation::Kind::kTiltYaw;
  o.tilt_rad = 10.0 * std::numbers::pi / 180.0;
  return o;
}

// The wavy face's leading_line guide: a cubic across it along Y, bending in X.
std::shared_ptr<const geometry::BSplineCurve> WavyGuide() {
  return std::make_shared<const geometry::BSplineCurve>(geometry::BSplineCurveData{
      3, {0, 0, 0, 0, 1, 1, 1, 1}, {{30, -5, 0}, {25, 20, 0}, {35, 40, 0}, {30, 65, 0}}, {}});
}

// A pass over a cubic face reports every knot line it crosses as a break of its path, at the arc
// length where its contact point is on the line: the planner sees the jumps of the axes' third
// derivatives coming. The wavy face is cubic along v with simple knots (C2 across each).
TEST(SurfacePass, APassReportsTheKnotLinesItCrossesAsBreaks) {
  const FaceSurface surface(WavyRuledFace(), "wavy");
  ASSERT_TRUE(surface.UKnotLines().empty());  // degree 1 across: no break of the third derivative
  const std::vector<double>& knots = surface.VKnotLines();
  ASSERT_GT(knots.size(), 10u);
  for (const Orientation& o : {Orientation{}, Tilted10()}) {
    StrategySpec spec;
    spec.plane_normal = Eigen::Vector3d::UnitX();
    spec.direction = Eigen::Vector3d::UnitY();
    spec.stepover_mm = 13.0;
    spec.max_passes = 3;
    const auto passes = strategies::BuildPasses(surface, Ball(3.0), o, spec);
    ASSERT_EQ(passes.passes.size(), 3u);
    for (const auto& pass : passes.passes) {
      SCOPED_TRACE(fmt::format("{}, pass {}", o.Describe(), pass->Index()));
      const double v0 = pass->Start().v;
      strategies::ContactPoint end;
      ASSERT_EQ(pass->Evaluate(pass->At(pass->Start(), *pass->Length()).state, &end),
                strategies::EvalStatus::kOk);
      const double lo = std::min(v0, end.uv.y()), hi = std::max(v0, end.uv.y());
      const auto crossed =
          std::count_if(knots.begin(), knots.end(), [&](double k) { return k > lo && k < hi; });
      ASSERT_GT(crossed, 5);
      const std::vector<double>& lines = pass->KnotLines();
      ASSERT_EQ(static_cast<long>(lines.size()), crossed);
      EXPECT_TRUE(std::is_sorted(lines.begin(), lines.end()));
      PathState st = pass->Start();
      for (const double s : lines) {
        const PathSample at = pass->At(st, s);
        ASSERT_EQ(at.status, PathStatus::kOk);
        const auto near = std::min_element(knots.begin(), knots.end(), [&](double a, double b) {
          return std::abs(a - at.state.v) < std::abs(b - at.state.v);
        });
        // On the line to the arc length's 1e-9 mm (v runs at about 1 per mm here).
        EXPECT_NEAR(at.state.v, *near, 1e-8) << "at s = " << s;
        st = at.state;
      }
      const std::vector<double> breaks = pass->Breaks(0.0, *pass->Length());
      EXPECT_EQ(breaks, lines);  // no flat piece on a ball's pass
    }
  }
}

// The closest point of a guide: the foot of the perpendicular from the point in XY, the same
// from a scan and from a hint nearby, with the guide's own derivatives there handed back.
TEST(SurfacePass, TheClosestPointOfAGuideIsTheFootOfThePerpendicular) {
  const auto guide = WavyGuide();
  for (const Eigen::Vector2d& p :
       {Eigen::Vector2d(20.0, 10.0), Eigen::Vector2d(36.0, 30.0), Eigen::Vector2d(31.0, 60.0)}) {
    SCOPED_TRACE(fmt::format("({}, {})", p.x(), p.y()));
    Eigen::Vector3d at[3];
    const double t = strategies::ClosestOnGuide(*guide, p.x(), p.y(), NAN, at);
    Eigen::Vector3d d[3];
    guide->Derivatives(t, 2, d);
    for (int k = 0; k < 3; ++k) EXPECT_LT((at[k] - d[k]).norm(), 1e-12 * (1.0 + d[k].norm()));
    const Eigen::Vector2d r(d[0].x() - p.x(), d[0].y() - p.y()), tangent(d[1].x(), d[1].y());
    EXPECT_LT(std::abs(r.dot(tangent.normalized())), 1e-9);
    const double hinted = strategies::ClosestOnGuide(*guide, p.x(), p.y(), t + 0.05, at);
    EXPECT_NEAR(hinted, t, 1e-12);
    guide->Derivatives(hinted, 2, d);
    EXPECT_LT((at[0] - d[0]).norm(), 1e-12);
  }
}

TEST(SurfaceProperty, AWavyRuledFaceWithEveryStrategyToolAndOrientation) {
  // What holds today: a ball R3 builds every pass of plane_cl, uv and leading_line, 3-axis and
  // tilted 10 deg, never under the face (3-axis passes planned and verified); a flat bottom (flat
  // end R4, bull nose R5 r1) cannot follow its valleys: with on_gouge = "stop" every combination
  // is refused with where and how deep, else the valleys are left out (ridden over where a
  // straight move keeps the tool out of the face, SurfaceJob.AFlatBottomRidesOver...).
  const TopoDS_Face face = WavyRuledFace();
  const FaceSurface surface(face, "wavy");
  const Orientation tilted = Tilted10();
  const auto guide = WavyGuide();
  const auto xyz =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  const auto xyzac =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyzac.toml"));
  for (const Tool& tool :
       {Ball(3.0), Torus(Tool::Kind::kBullNose, 5.0, 1.0), Torus(Tool::Kind::kFlatEnd, 4.0, 0.0)}) {
    for (const Orientation& o : {Orientation{}, tilted}) {
      for (const auto kind : {StrategySpec::Kind::kPlaneCl, StrategySpec::Kind::kUv,
                              StrategySpec::Kind::kLeadingLine}) {
        SCOPED_TRACE(
            fmt::format("{}, {}, {}", tool.Describe(), o.Describe(), StrategySpec::KindName(kind)));
        StrategySpec spec;
        spec.kind = kind;
        spec.stepover_mm = 6.0;
        spec.along_u = false;
        if (kind == StrategySpec::Kind::kLeadingLine) spec.guide = guide;
        if (tool.kind != Tool::Kind::kBallEnd) {
          StrategySpec stop = spec;
          stop.on_gouge = StrategySpec::OnGouge::kStop;
          test::ExpectError([&] { strategies::BuildPasses(surface, tool, o, stop); },
                            {"the tool gouges", "(u, v)"});
          // Skipping the valleys or riding over them, the rest is finished without going into
          // the face.
          spec.max_passes = 3;
          const auto passes = strategies::BuildPasses(surface, tool, o, spec);
          EXPECT_FALSE(passes.unreachable.empty());
          ExpectToolAboveFace(face, tool, passes, 0.1, 0.8);
          ExpectRidesAboveFace(face, tool, passes);
          continue;
        }
        spec.max_passes = 3;
        const auto passes = strategies::BuildPasses(surface, tool, o, spec);
        ASSERT_EQ(passes.passes.size(), 3u);
        if (o.kind == Orientation::Kind::kFixed) {
          // (Tilted, the axis passes within a degree of the XYZAC's pole, where C turns half a
          // revolution in a few millimetres: TiltedPassesOnAWavyFaceSetUpAwayFromThePole... plans
          // the tilted passes with the part set up away from it.)
          interp::VpopOptions opt;
          opt.feed_mm_s = 50.0;
          const test::Planned planned = test::PlanAndVerify(*passes.passes[1], *xyz, opt);
          EXPECT_LE(planned.report.worst_ratio, 1.0) << planned.report.worst;
        }
        ExpectToolAboveFace(face, tool, passes, 0.1, 0.4);
      }
    }
  }
}

// The wavy face as a CAM user sets it up away from the XYZAC's pole: rotated 60 deg about X.
TopoDS_Face WavyFaceSetUp60AboutX() {
  gp_Trsf set_up;
  set_up.SetRotation(gp::OX(), 60.0 * std::numbers::pi / 180.0);
  return TopoDS::Face(BRepBuilderAPI_Transform(WavyRuledFace(), set_up, Standard_True).Shape());
}

// Tilted 10 deg, every pass of the wavy face comes within 0.07 to 1.5 deg of vertical, the pole of
// a table-tilting machine (its C axis), where C turns half a revolution in a few millimetres. A
// CAM user sets the part up away from it: rotated 60 deg about X, the axis stays 18 to 82 deg from
// vertical, and the tilted passes plan on the XYZAC within every limit (look-ahead planner; one
// pass per strategy, the ball's and the bull nose's, whose flat part leaves the valleys out),
// never under the face.
TEST(SurfaceProperty, TiltedPassesOnAWavyFaceSetUpAwayFromThePolePlanAndVerify) {
  const TopoDS_Face face = WavyFaceSetUp60AboutX();
  const FaceSurface surface(face, "wavy, set up 60 deg about X");
  const Orientation tilted = Tilted10();
  const auto guide = WavyGuide();
  const auto xyzac =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyzac.toml"));
  const Tool bull = Torus(Tool::Kind::kBullNose, 5.0, 1.0);
  const std::pair<Tool, StrategySpec::Kind> cases[] = {{Ball(3.0), StrategySpec::Kind::kPlaneCl},
                                                       {bull, StrategySpec::Kind::kUv},
                                                       {bull, StrategySpec::Kind::kLeadingLine}};
  for (const auto& [tool, kind] : cases) {
    SCOPED_TRACE(fmt::format("{}, {}", tool.Describe(), StrategySpec::KindName(kind)));
    StrategySpec spec;
    spec.kind = kind;
    spec.stepover_mm = 6.0;
    spec.along_u = false;
    spec.max_passes = 2;
    if (kind == StrategySpec::Kind::kLeadingLine) spec.guide = guide;
    const auto passes = strategies::BuildPasses(surface, tool, tilted, spec);
    ASSERT_EQ(passes.passes.size(), 2u);
    // Both passes away from the pole all along (at every 500th of their length).
    double nearest = INFINITY;
    ForPosesAlong(passes, 0.0, 2e-3,
                  [&](const strategies::SurfacePass&, const PathSample& smp,
                      const strategies::ContactPoint&) {
                    nearest =
                        std::min(nearest, std::acos(std::clamp(smp.pose.axis.z(), -1.0, 1.0)));
                  });
    EXPECT_GT(nearest, 15.0 * std::numbers::pi / 180.0);
    const strategies::SurfacePass& pass = *passes.passes[1];
    const double length = pass.Length().value();
    interp::VpopOptions opt;
    opt.feed_mm_s = 50.0;
    opt.planner = interp::PlannerKind::kLookAhead;
    const test::Planned planned = test::PlanAndVerify(pass, *xyzac, opt);
    EXPECT_TRUE(planned.report.Passed()) << interp::FormatReport(planned.report);
    EXPECT_LE(planned.report.worst_ratio, 1.0) << planned.report.worst;
    EXPECT_NEAR(planned.points.back().s, length, 1e-6);
    ExpectToolAboveFace(face, tool, passes, 0.1, 0.8);
  }
}

// The axis smoothed within 0.09 deg ([orientation] axis_tolerance_deg) on the same set-up, with the
// bull nose that rests on both flanks of the valleys at its passes' ends: the passes are the same
// stretches of the face (their ends cut where the smoothed tool would touch the far flank), the
// axis stays within the tolerance of the rule's, no sampled point of the tool is under the face
// (ends included), the tool rides over the valleys it rode over with the rule's axis only where
// the straight move keeps it above the face, and a pass plans within every limit.
TEST(SurfaceProperty, ASmoothedAxisKeepsABullNoseOutOfAWavyFaceAtItsValleys) {
  const TopoDS_Face face = WavyFaceSetUp60AboutX();
  const FaceSurface surface(face, "wavy, set up 60 deg about X");
  const Tool bull = Torus(Tool::Kind::kBullNose, 5.0, 1.0);
  constexpr double kTol = 0.09 * std::numbers::pi / 180.0;
  Orientation smooth_axis = Tilted10();
  smooth_axis.axis_tolerance_rad = kTol;
  StrategySpec spec;
  spec.stepover_mm = 6.0;
  spec.max_passes = 4;
  const auto exact = strategies::BuildPasses(surface, bull, Tilted10(), spec);
  const auto smooth = strategies::BuildPasses(surface, bull, smooth_axis, spec);
  ASSERT_EQ(smooth.passes.size(), exact.passes.size());
  ASSERT_EQ(smooth.unreachable.size(), exact.unreachable.size());
  EXPECT_GE(smooth.unreachable.size(), 4u);  // the valleys' floors are left out
  for (std::size_t k = 0; k < smooth.passes.size(); ++k) {
    EXPECT_NEAR(smooth.passes[k]->Length().value(), exact.passes[k]->Length().value(), 0.05) << k;
  }
  double worst = 0.0;
  ForPosesAlong(
      smooth, 0.0, 1e-3,
      [&](const strategies::SurfacePass&, const PathSample& smp,
          const strategies::ContactPoint& c) {
        worst = std::max(
            worst, geometry::Angle(smp.pose.axis, strategies::ToolAxis(smooth_axis, c.n, c.feed)));
      });
  EXPECT_LE(worst, kTol);
  EXPECT_GT(worst, 0.2 * kTol);
  ExpectToolAboveFace(face, bull, smooth, 0.0, 0.1);
  for (const auto& pass : smooth.passes) {
    const PathSample end = pass->At(pass->Start(), pass->Length().value());
    strategies::ContactPoint c;
    ASSERT_EQ(pass->Evaluate(end.state, &c), strategies::EvalStatus::kOk);
    EXPECT_GT(SampledClearance(face, bull, end.pose, c.uv, c.n), -1e-6) << pass->Index();
    ASSERT_EQ(pass->Evaluate(pass->Start(), &c), strategies::EvalStatus::kOk);
    EXPECT_GT(SampledClearance(face, bull, pass->StartPose(), c.uv, c.n), -1e-6) << pass->Index();
  }
  ExpectRidesAboveFace(face, bull, smooth);
  const auto xyzac =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyzac.toml"));
  interp::VpopOptions opt;
  opt.feed_mm_s = 50.0;
  opt.planner = interp::PlannerKind::kLookAhead;
  const test::Planned planned = test::PlanAndVerify(*smooth.passes[1], *xyzac, opt);
  EXPECT_TRUE(planned.report.Passed()) << interp::FormatReport(planned.report);
  EXPECT_NEAR(planned.points.back().s, smooth.passes[1]->Length().value(), 1e-6);
}

// `faces` written as a STEP file named `name`.stp in the scratch folder, each face named as given.
std::string WriteNamedFaces(const std::string& name,
                            const std::vector<std::pair<TopoDS_Face, std::string>>& faces) {
  return test::WriteNamedFaces(faces, test::Scratch(name + ".stp"));
}

// The wavy ruled face cut in two along x = 30 (where u = 1/2), as faces "left" and "right".
std::string TwoNamedWavyFaces(const std::string& name) {
  const Handle(Geom_Surface) wave = BRep_Tool::Surface(WavyRuledFace());
  return WriteNamedFaces(
      name, {{BRepBuilderAPI_MakeFace(wave, 0.0, 0.5, 0.0, 1.0, 1e-7).Face(), "left"},
             {BRepBuilderAPI_MakeFace(wave, 0.5, 1.0, 0.0, 1.0, 1e-7).Face(), "right"}});
}

// The same with a ball R3.
io::Job BallJob(const std::string& step, const std::string& surface, const std::string& planes,
                const std::string& source) {
  return test::PlaneClJob(step, surface, "kind = \"ball_end\"\nradius_mm = 3", planes, source);
}

// The wavy faces' jobs: planes x = const, travelling along +Y, 7 mm apart.
io::Job WavyFacesJob(const std::string& step, const std::string& face, const std::string& source) {
  return BallJob(step, "face = " + face,
                 "plane_normal = [1, 0, 0]\ndirection = [0, 1, 0]\nstepover_mm = 7", source);
}

// A job of two faces (one by name, one by number) finishes both: passes on each, the links
// between them, and no point of the ball below either face (OpenCASCADE's distance from the
// ball's centre to the whole uncut face), every limit held.
// A solid sphere of radius 20 cut level at 30 deg of latitude (z = 10): its spherical face
// faces down over most of it, and side = "auto" machines its outside (the face's outward normal
// in the solid), not the side that points up: every ball centre is R + 3 from the centre.
TEST(SurfaceJob, SideAutoMachinesTheOutsideOfASolid) {
  const TopoDS_Shape solid =
      BRepPrimAPI_MakeSphere(20.0, -std::numbers::pi / 2, std::numbers::pi / 6).Shape();
  const std::string step = test::Scratch("cut_sphere.stp");
  test::WriteStep(solid, step);
  const StepModel model = StepModel::Load(step);
  int sphere = 0;
  for (int k = 1; k <= model.FaceCount(); ++k) {
    EXPECT_TRUE(model.BoundsSolid(k));
    if (model.Info(k).type == "sphere") sphere = k;
  }
  ASSERT_GT(sphere, 0);
  const io::Job job =
      BallJob(step, fmt::format("face = {}", sphere),
              "plane_normal = [1, 0, 0]\ndirection = [0, 1, 0]\nstepover_mm = 4\nrange = [-8, 8]",
              test::Scratch("cut_sphere.toml"));
  const io::SurfaceSetup setup = io::SetUpSurface(job, nullptr);
  ASSERT_FALSE(setup.passes.passes.empty());
  for (const auto& pass : setup.passes.passes) {
    PathState st = pass->Start();
    for (int i = 0; i <= 8; ++i) {
      const PathSample smp = pass->At(st, *pass->Length() * i / 8);
      st = smp.state;
      EXPECT_NEAR((smp.pose.tip + 3.0 * smp.pose.axis).norm(), 23.0, 1e-6)
          << pass->Describe(smp.state);
    }
  }
  // A face of no solid keeps the side that points up.
  const std::string lone = test::Scratch("lone_sphere_face.stp");
  test::WriteStep(model.Face(sphere), lone);
  EXPECT_FALSE(StepModel::Load(lone).BoundsSolid(1));
}

// Two whole spheres of radius 10, 30 mm apart, finished in one job in planes y = 4: each plane cuts
// each sphere in a circle that touches neither its seam nor a pole (a closed section). Both are
// finished, the ball (R3) on each sphere's offset.
TEST(SurfaceJob, ClosedSectionsAreFinishedOnEveryFaceOfAJob) {
  TopoDS_Compound both;
  BRep_Builder builder;
  builder.MakeCompound(both);
  for (const double x : {0.0, 30.0}) {
    const Handle(Geom_SphericalSurface) sphere =
        new Geom_SphericalSurface(gp_Ax3(gp_Pnt(x, 0, 0), gp::DZ()), 10.0);
    builder.Add(both, BRepBuilderAPI_MakeFace(sphere, 0, 2 * std::numbers::pi,
                                              -std::numbers::pi / 2, std::numbers::pi / 2, 1e-7)
                          .Face());
  }
  const std::string step = test::Scratch("two_spheres.stp");
  test::WriteStep(both, step);
  const io::Job job =
      BallJob(step, "face = [1, 2]",
              "plane_normal = [0, 1, 0]\ndirection = [1, 0, 0]\nstepover_mm = 1\nrange = [4, 4]",
              test::Scratch("two_spheres.toml"));
  const io::SurfaceSetup setup = io::SetUpSurface(job, nullptr);
  std::set<double> centres;
  for (const auto& pass : setup.passes.passes) {
    const Eigen::Vector3d centre = pass->StartPose().tip + 3.0 * pass->StartPose().axis;
    const double c = centre.x() < 15.0 ? 0.0 : 30.0;
    centres.insert(c);
    PathState st = pass->Start();
    for (int i = 0; i <= 8; ++i) {
      const PathSample smp = pass->At(st, *pass->Length() * i / 8);
      st = smp.state;
      EXPECT_NEAR((smp.pose.tip + 3.0 * smp.pose.axis - Eigen::Vector3d(c, 0, 0)).norm(), 13.0,
                  1e-6);
      EXPECT_NEAR(smp.pose.tip.y(), 4.0, 1e-6);
    }
  }
  EXPECT_EQ(centres, (std::set<double>{0.0, 30.0}));
}

TEST(SurfaceJob, TwoFacesByNameAndNumberAreBothFinished) {
  const std::string step = TwoNamedWavyFaces("two_faces");
  const StepModel model = StepModel::Load(step);
  ASSERT_EQ(model.FaceCount(), 2);
  EXPECT_EQ(model.FaceName(1), "left");
  EXPECT_EQ(model.FaceName(2), "right");
  EXPECT_EQ(model.FacesNamed("right"), std::vector<int>{2});
  EXPECT_EQ(model.Info(2).name, "right");
  const io::Job job = WavyFacesJob(step, "[\"left\", 2]", test::Scratch("two_faces.toml"));
  EXPECT_EQ(io::JobFaces(*job.surface, model), (std::vector<int>{1, 2}));
  EXPECT_EQ(io::DescribeFaces(*job.surface), "faces 'left', 2");
  const io::SurfaceSetup setup = io::SetUpSurface(job, nullptr);
  EXPECT_TRUE(setup.passes.unreachable.empty());
  int on_left = 0, on_right = 0;
  for (const auto& pass : setup.passes.passes) {
    // Planes x = const, each face's stepped from its own side: passes on one face only.
    const double x = pass->StartPose().tip.x();
    EXPECT_TRUE((x > 0.0 && x < 30.0) || (x > 30.0 && x < 60.0)) << x;
    (x < 30.0 ? on_left : on_right) += 1;
    EXPECT_GT(*pass->Length(), 60.0) << x;
  }
  EXPECT_GE(on_left, 4);
  EXPECT_GE(on_right, 4);

  const io::RunResult r = io::RunJob(job);
  ASSERT_TRUE(r.verify.Passed()) << interp::FormatReport(r.verify);
  EXPECT_LE(r.verify.worst_ratio, 1.0);
  EXPECT_EQ(r.passes, on_left + on_right);
  const std::string summary = io::FormatRunSummary(job, r);
  EXPECT_NE(summary.find("faces 'left', 2"), std::string::npos) << summary;
  // Both faces of the file are the job's: none besides them is checked, each against the other.
  EXPECT_EQ(r.checked_faces, 0);
  EXPECT_EQ(r.job_faces, 2);
  EXPECT_NE(summary.find("checked          each face's passes out of the job's 1 other face\n"),
            std::string::npos)
      << summary;
  EXPECT_EQ(summary.find("besides the job's"), std::string::npos) << summary;
  const TopoDS_Face whole = WavyRuledFace();
  const auto& c = r.table.columns;
  double closest = INFINITY;
  bool left_cut = false, right_cut = false;
  for (std::size_t k = 0; k < c[0].size(); k += 7) {
    const gp_Pnt centre(c[0][k], c[1][k], c[2][k] + 3.0);
    BRepExtrema_DistShapeShape d(BRepBuilderAPI_MakeVertex(centre).Vertex(), whole);
    ASSERT_TRUE(d.IsDone());
    closest = std::min(closest, d.Value());
    if (d.Value() < 3.0 + 1e-6) (c[0][k] < 30.0 ? left_cut : right_cut) = true;
  }
  EXPECT_GT(closest, 3.0 - 1e-6);
  EXPECT_TRUE(left_cut);
  EXPECT_TRUE(right_cut);
}

// A flat end R4 on a fixed axis cannot follow the wavy face's valleys (radius 7.6 mm across
// them): it rides over them, as a drop cutter would. plane_cl passes end where the tool rests on
// both sides of a valley, and the next starts there, a straight move of no more than the trace's
// resolution away (not a link); the floor between is reported, as ridden over. Near each of them
// no setpoint lifts the tool and none puts it under the face (OpenCASCADE's projection); every
// limit holds. Eight passes: on the fourth line the contact points close a loop in a valley,
// which the trace once went round for ever.
TEST(SurfaceJob, AFlatBottomRidesOverValleysNarrowerThanIt) {
  const std::string step = WriteNamedFaces("wavy_flat", {{WavyRuledFace(), "wavy"}});
  const io::Job job =
      test::PlaneClJob(step, "", "kind = \"flat_end\"\nradius_mm = 4",
                       "plane_normal = [1, 0, 0]\ndirection = [0, 1, 0]\nstepover_mm = "
                       "6\nmax_passes = 8",
                       test::Scratch("wavy_flat.toml"));
  const io::SurfaceSetup setup = io::SetUpSurface(job, nullptr);
  const auto& passes = setup.passes.passes;
  ASSERT_EQ(passes.size(), 8u);
  std::vector<Pose> creases;
  for (std::size_t k = 1; k < passes.size(); ++k) {
    if (!passes[k]->RidesOverFromPrevious()) continue;
    const Pose end = passes[k - 1]->EndPose(), start = passes[k]->StartPose();
    EXPECT_LT((start.tip - end.tip).norm(), 1e-3) << k;
    creases.push_back(end);
  }
  EXPECT_GE(creases.size(), 3u);
  int ridden = 0;
  for (const auto& u : setup.passes.unreachable) ridden += u.ridden_over;
  EXPECT_EQ(ridden, static_cast<int>(creases.size()));
  EXPECT_NE(setup.passes.UnreachableText(20).find("(the tool rides over it)"), std::string::npos);
  const TopoDS_Face face = WavyRuledFace();
  EXPECT_EQ(ExpectRidesAboveFace(face, job.surface->tool, setup.passes),
            static_cast<int>(creases.size()));

  const io::RunResult r = io::RunJob(job);
  ASSERT_TRUE(r.verify.Passed()) << interp::FormatReport(r.verify);
  EXPECT_LE(r.verify.worst_ratio, 1.0);
  const auto& c = r.table.columns;
  const auto tip = [&c](std::size_t k) { return Eigen::Vector3d(c[0][k], c[1][k], c[2][k]); };
  const std::size_t rows = c[0].size();
  std::size_t k = 0;
  for (std::size_t m = 1; m < passes.size(); ++m) {
    if (!passes[m]->RidesOverFromPrevious()) continue;
    const Eigen::Vector3d end = passes[m - 1]->EndPose().tip, start = passes[m]->StartPose().tip;
    // The motion stops where the pass ends and goes straight on to where the next starts, close
    // by and without lifting (a link would take a second or more).
    while (k < rows && (tip(k) - end).norm() > 1e-6) ++k;
    const std::size_t at_end = k;
    while (k < rows && (tip(k) - start).norm() > 1e-6) ++k;
    ASSERT_LT(k, rows) << "pass " << m + 1;
    EXPECT_LT(k - at_end, 100u) << "pass " << m + 1;
    for (std::size_t i = at_end; i <= k; ++i) EXPECT_LT((tip(i) - end).norm(), 1e-3) << i;
    // Around it the tool stays above the face.
    for (std::size_t i = at_end - std::min<std::size_t>(at_end, 200); i < k + 200 && i < rows;
         i += 40) {
      EXPECT_GT(SampledClearance(face, job.surface->tool, {tip(i), Eigen::Vector3d::UnitZ()},
                                 {0.5, 0.5}, Eigen::Vector3d::UnitZ()),
                -1e-6)
          << i;
    }
  }
}

// How a job names its faces, and what it is told when they are not there.
TEST(SurfaceJob, FacesAreGivenByNumberNameOrList) {
  const std::string step = TwoNamedWavyFaces("face_keys");
  const StepModel model = StepModel::Load(step);
  const auto job = [&](const std::string& face) { return WavyFacesJob(step, face, "faces.toml"); };
  EXPECT_EQ(io::JobFaces(*job("2").surface, model), std::vector<int>{2});
  EXPECT_EQ(io::JobFaces(*job("\"right\"").surface, model), std::vector<int>{2});
  EXPECT_EQ(io::JobFaces(*job("[2, 1]").surface, model), (std::vector<int>{2, 1}));
  test::ExpectError([&] { job("1.5"); }, "faces.toml:5: key 'surface.face'");
  test::ExpectError([&] { job("[]"); }, "faces.toml:5: key 'surface.face'");
  test::ExpectError([&] { job("[1, 2.5]"); }, "faces.toml:5: key 'surface.face'");
  test::ExpectError([&] { job("\"\""); }, "faces.toml:5: key 'surface.face'");
  test::ExpectError([&] { job("0"); }, "expected a face number from 1");
  test::ExpectError([&] { io::JobFaces(*job("3").surface, model); },
                    {"faces.toml:5: key 'surface.face': face 3 does not exist", "faces 1 to 2"});
  test::ExpectError([&] { io::JobFaces(*job("[\"left\", 1]").surface, model); },
                    "face 1 of " + step + " is given twice (as 'left' and 1)");
  test::ExpectError([&] { io::JobFaces(*job("\"top\"").surface, model); },
                    "has no face named 'top'; its named faces: 'left' (1), 'right' (2)");
}

// Several faces of one name (CAD systems name every face of a body after it): the name selects
// them all, and the summary says how many; "name#N" selects the N-th of them in the file's order.
TEST(SurfaceJob, ANameSelectsEveryFaceOfItAndNameNumberOneOfThem) {
  const Handle(Geom_Surface) wave = BRep_Tool::Surface(WavyRuledFace());
  const std::string step = WriteNamedFaces(
      "same_name", {{BRepBuilderAPI_MakeFace(wave, 0.0, 0.5, 0.0, 1.0, 1e-7).Face(), "PartBody"},
                    {BRepBuilderAPI_MakeFace(wave, 0.5, 1.0, 0.0, 1.0, 1e-7).Face(), "PartBody"}});
  const StepModel model = StepModel::Load(step);
  ASSERT_EQ(model.FacesNamed("PartBody"), (std::vector<int>{1, 2}));
  const auto job = [&](const std::string& face) {
    return WavyFacesJob(step, face, test::Scratch("same_name.toml"));
  };
  EXPECT_EQ(io::JobFaces(*job("\"PartBody\"").surface, model), (std::vector<int>{1, 2}));
  EXPECT_EQ(io::JobFaces(*job("\"PartBody#2\"").surface, model), std::vector<int>{2});
  EXPECT_EQ(io::JobFaces(*job("[\"PartBody#2\", \"PartBody#1\"]").surface, model),
            (std::vector<int>{2, 1}));
  test::ExpectError([&] { io::JobFaces(*job("\"PartBody#3\"").surface, model); },
                    {"same_name.toml:5: key 'surface.face'", "has 2 faces named 'PartBody'",
                     "'PartBody#1' to 'PartBody#2'", "there is no 'PartBody#3'"});
  test::ExpectError([&] { io::JobFaces(*job("\"PartBody#0\"").surface, model); },
                    "there is no 'PartBody#0'");
  test::ExpectError([&] { io::JobFaces(*job("[\"PartBody\", \"PartBody#1\"]").surface, model); },
                    "is given twice (as 'PartBody' and 'PartBody#1')");
  test::ExpectError([&] { io::JobFaces(*job("\"Body#1\"").surface, model); },
                    "has no face named 'Body#1'");
  // A face named "Body#2" is that face; "Body#1" the first named "Body".
  const std::string hashed = WriteNamedFaces(
      "hash_name", {{BRepBuilderAPI_MakeFace(wave, 0.0, 0.5, 0.0, 1.0, 1e-7).Face(), "Body#2"},
                    {BRepBuilderAPI_MakeFace(wave, 0.5, 1.0, 0.0, 1.0, 1e-7).Face(), "Body"}});
  const StepModel hashed_model = StepModel::Load(hashed);
  const auto hashed_job = [&](const std::string& face) {
    return WavyFacesJob(hashed, face, test::Scratch("hash_name.toml"));
  };
  EXPECT_EQ(io::JobFaces(*hashed_job("\"Body#2\"").surface, hashed_model), std::vector<int>{1});
  EXPECT_EQ(io::JobFaces(*hashed_job("\"Body#1\"").surface, hashed_model), std::vector<int>{2});

  const io::Job both = job("\"PartBody\"");
  io::RunResult r = io::RunJob(both);
  ASSERT_TRUE(r.verify.Passed()) << interp::FormatReport(r.verify);
  const std::string summary = io::FormatRunSummary(both, r);
  EXPECT_NE(summary.find("face 'PartBody' (2 faces: a name selects every face of that name"),
            std::string::npos)
      << summary;
  const io::Job one = job("\"PartBody#1\"");
  r.job_faces = 1;  // as a run of the one face would be
  EXPECT_EQ(io::FormatRunSummary(one, r).find("a name selects"), std::string::npos);
}

// A part moved out of the machine's travel is refused before planning, in the planner's words:
// the wavy face moved 290 mm along +Y leaves Y's travel [-300, 300] some 10 mm into its first
// pass, which runs along +Y. The check names the face, the pass, the arc length and the axis, as
// the planner does when it meets the same pose, and it takes a fraction of the time.
TEST(SurfaceJob, APartOutOfTravelIsRefusedBeforePlanning) {
  const std::string step = WriteNamedFaces("out_of_travel", {{WavyRuledFace(), "wavy"}});
  const io::Job job = BallJob(step, "translate_mm = [0, 290, 0]",
                              "plane_normal = [1, 0, 0]\ndirection = [0, 1, 0]\nstepover_mm = 7",
                              test::Scratch("out_of_travel.toml"));
  const io::SurfaceSetup setup = io::SetUpSurface(job, nullptr);
  ASSERT_GE(setup.passes.passes.size(), 2u);
  const auto machine = io::LoadJobMachine(job);
  std::string checked;
  try {
    io::CheckPassesInTravel(setup, *machine, job.file);
    FAIL() << "the part is out of travel";
  } catch (const Error& e) {
    checked = e.what();
  }
  for (const char* fragment : {"out_of_travel.toml: pass 1: cannot follow the path at ", "('wavy')",
                               ", pass 1 (", "arc length ", "axis Y would have to reach ",
                               "outside its travel [-300, 300] mm", "(found before planning)"}) {
    EXPECT_NE(checked.find(fragment), std::string::npos) << fragment << "\n" << checked;
  }
  // The arc length it names is where the tip's y has passed 300 mm, within a sampling step.
  const std::size_t at = checked.find("arc length ") + 11;
  const double s = std::stod(checked.substr(at));
  const double y0 = setup.passes.passes[0]->StartPose().tip.y();
  EXPECT_GT(y0 + s, 300.0);
  EXPECT_LE(y0 + s, 300.0 + io::kTravelCheckStepMm * 1.5);
  // The planner, given the same passes, fails on the same pass and axis.
  std::vector<const PathSource*> passes;
  for (const auto& p : setup.passes.passes) passes.push_back(p.get());
  test::ExpectError([&] { io::PlanPasses(passes, setup, *machine, {}, job.file); },
                    {"cannot follow the path at ", "('wavy')", ", pass 1 (",
                     "axis Y would have to reach ", "outside its travel [-300, 300] mm"});
  test::ExpectError([&] { io::RunJob(job); },
                    "out_of_travel.toml: pass 1: cannot follow the path at ");
  // A stream refuses it before its first segment, as a run does.
  test::ExpectError(
      [&] { io::JobSegments(job, *machine); },
      {"out_of_travel.toml: pass 1: cannot follow the path at ", "(found before planning)"});
  // In travel, the check passes.
  const io::Job inside =
      BallJob(step, "", "plane_normal = [1, 0, 0]\ndirection = [0, 1, 0]\nstepover_mm = 7",
              test::Scratch("in_travel.toml"));
  EXPECT_NO_THROW(
      io::CheckPassesInTravel(io::SetUpSurface(inside, nullptr), *machine, inside.file));
}

// The tilted floor and the guide bending tighter than the offset above, as a job: it plans and
// verifies, every limit held, and the run summary lists the two folds' stretches.
TEST(SurfaceJob, AGuideBendTighterThanTheOffsetPlansAndListsTheFolds) {
  const std::string step = WriteNamedFaces("guide_fold", {{TiltedFloor(), "floor"}});
  const std::string guide = test::Scratch("guide_fold_guide.toml");
  std::ofstream(guide) << "degree = 2\nknots = [0, 0, 0, 0.45, 0.55, 1, 1, 1]\n"
                          "poles = [[-40, 0], [-4, 0], [0, 0], [0, 4], [0, 40]]\n";
  const io::Job job = io::ParseJob(
      fmt::format(R"(machine = "{}"
feed_mm_min = 3000
[surface]
file = "{}"
[tool]
kind = "ball_end"
radius_mm = 2
[strategy]
kind = "leading_line"
guide = "{}"
stepover_mm = 3
range = [-6, 6]
)",
                  test::Source("samples/machines/mikron_ucp710_xyz.toml"), step, guide),
      test::Scratch("guide_fold.toml"));
  const io::RunResult r = io::RunJob(job);
  ASSERT_TRUE(r.verify.Passed()) << interp::FormatReport(r.verify);
  EXPECT_LE(r.verify.worst_ratio, 1.0);
  EXPECT_EQ(r.passes, 7);
  EXPECT_EQ(r.unreachable_count, 2u);
  const std::string summary = io::FormatRunSummary(job, r);
  for (const char* fragment :
       {"line 4, ", "line 5, ", "bends tighter than the pass's offset", "the offset is 6 mm"}) {
    EXPECT_NE(summary.find(fragment), std::string::npos) << fragment << "\n" << summary;
  }
}

// A part larger than the machine: a floor 700 mm long along Y, on a machine whose Y travels
// 600 mm, is refused before planning, naming the pass, the axis and its travel.
TEST(SurfaceJob, APartLargerThanTheTravelIsRefusedBeforePlanning) {
  const TopoDS_Face floor = BRepBuilderAPI_MakeFace(gp_Pln(gp::XOY()), -50, 50, -350, 350).Face();
  const std::string step = WriteNamedFaces("too_large", {{floor, "floor"}});
  const io::Job job =
      BallJob(step, "", "plane_normal = [1, 0, 0]\ndirection = [0, 1, 0]\nstepover_mm = 20",
              test::Scratch("too_large.toml"));
  test::ExpectError([&] { io::RunJob(job); },
                    {"too_large.toml: pass 1: cannot follow the path at ", "('floor')",
                     "axis Y would have to reach ", "outside its travel [-300, 300] mm",
                     "(found before planning)"});
}

// A link's corner out of travel: the part raised until the passes fit under Z's top (300 mm) but
// the height the links traverse at (the clearance above the face) does not.
TEST(SurfaceJob, ALinkOutOfTravelIsRefusedBeforePlanning) {
  const std::string step = WriteNamedFaces("link_out_of_travel", {{WavyRuledFace(), "wavy"}});
  const auto job = [&](double z) {
    return BallJob(step, fmt::format("translate_mm = [0, 0, {}]", z),
                   "plane_normal = [1, 0, 0]\ndirection = [0, 1, 0]\nstepover_mm = 7",
                   test::Scratch("link_out_of_travel.toml"));
  };
  const io::SurfaceSetup at0 = io::SetUpSurface(job(0.0), nullptr);
  double top = -INFINITY;
  for (const auto& p : at0.passes.passes) {
    top = std::max({top, p->StartPose().tip.z(), p->EndPose().tip.z()});
  }
  const double z = 300.0 - top - 0.5 * at0.clearance_mm;  // the pass ends fit, the links do not
  const io::Job raised = job(z);
  const io::SurfaceSetup setup = io::SetUpSurface(raised, nullptr);
  const auto machine = io::LoadJobMachine(raised);
  test::ExpectError([&] { io::CheckPassesInTravel(setup, *machine, raised.file); },
                    {"link_out_of_travel.toml: link from pass 1 to pass 2: cannot follow it at its "
                     "corner ",
                     "axis Z would have to reach ", "(found before planning)"});
}

// The distance to a tool in closed form: a ball R3 is a sphere about the point 3 mm up its axis, a
// bull nose R5 r1 has its corner's circle of centres at rho = 4, z = 1; inside is negative.
TEST(CheckFaces, DistanceToTheToolInClosedForm) {
  const Tool ball = Ball(3.0), bull = Torus(Tool::Kind::kBullNose, 5.0, 1.0);
  const Tool flat = Torus(Tool::Kind::kFlatEnd, 4.0, 0.0);
  EXPECT_NEAR(geometry::ToolSignedDistance(ball, INFINITY, 0.0, -1.0), 1.0, 1e-15);
  EXPECT_NEAR(geometry::ToolSignedDistance(ball, INFINITY, 4.0, 0.0), 2.0, 1e-15);  // 5 - 3
  EXPECT_NEAR(geometry::ToolSignedDistance(ball, INFINITY, 0.0, 0.5), -0.5, 1e-15);
  EXPECT_NEAR(geometry::ToolSignedDistance(ball, INFINITY, 3.5, 40.0), 0.5, 1e-15);  // the shank
  EXPECT_NEAR(geometry::ToolSignedDistance(ball, 10.0, 0.0, 12.0), 2.0, 1e-15);      // above it
  EXPECT_NEAR(geometry::ToolSignedDistance(bull, INFINITY, 5.5, 0.5), std::hypot(1.5, 0.5) - 1.0,
              1e-15);
  EXPECT_NEAR(geometry::ToolSignedDistance(bull, INFINITY, 2.0, -0.25), 0.25, 1e-15);
  EXPECT_NEAR(geometry::ToolSignedDistance(bull, INFINITY, 2.0, 0.25), -0.25, 1e-15);
  EXPECT_NEAR(geometry::ToolSignedDistance(flat, INFINITY, 5.0, 2.0), 1.0, 1e-15);
  EXPECT_NEAR(geometry::ToolSignedDistance(flat, INFINITY, 6.0, -2.0), std::hypot(2.0, 2.0), 1e-15);
  EXPECT_LT(geometry::ToolSignedDistance(flat, INFINITY, 3.9, 0.05), 0.0);
}

// A wall standing at x = 30 over y in [-1, 61], z from -5 to 20 (or, `slanted`, to a top edge
// rising from 18 to 22 along y: a trimmed face, its top edge a trimming loop).
TopoDS_Face Wall(bool slanted = false) {
  BRepBuilderAPI_MakePolygon outline(gp_Pnt(30, -1, -5), gp_Pnt(30, 61, -5),
                                     gp_Pnt(30, 61, slanted ? 22 : 20),
                                     gp_Pnt(30, -1, slanted ? 18 : 20), Standard_True);
  return BRepBuilderAPI_MakeFace(outline.Wire(), Standard_True).Face();
}

// A floor (the left half of the wavy face, x in [0, 30]) and the wall at its edge, as faces
// "floor" and "wall" of a STEP file `name`.stp.
std::string FloorAndWall(const std::string& name, const TopoDS_Face& wall = Wall()) {
  const Handle(Geom_Surface) wave = BRep_Tool::Surface(WavyRuledFace());
  const TopoDS_Face floor = BRepBuilderAPI_MakeFace(wave, 0.0, 0.5, 0.0, 1.0, 1e-7).Face();
  return WriteNamedFaces(name, {{floor, "floor"}, {wall, "wall"}});
}

// A ball end of radius r as an OpenCASCADE solid, `length` up its axis from the tip: its profile
// (the quarter circle of the ball, the shank's side and top) turned about the axis, then placed
// at `tip` along `axis`. Every radius is less `shrink` (the tip raised by it); a negative shrink
// grows the tool.
TopoDS_Shape BallSolid(double r, double length, const Eigen::Vector3d& tip,
                       const Eigen::Vector3d& axis, double shrink) {
  const double rs = r - shrink;
  const gp_Pnt bottom(0, 0, r - rs), side(rs, 0, r), top_side(rs, 0, length), top(0, 0, length);
  const gp_Pnt mid(rs * std::sin(M_PI / 4), 0, r - rs * std::cos(M_PI / 4));
  BRepBuilderAPI_MakeWire profile;
  profile.Add(BRepBuilderAPI_MakeEdge(GC_MakeArcOfCircle(bottom, mid, side).Value()).Edge());
  profile.Add(BRepBuilderAPI_MakeEdge(side, top_side).Edge());
  profile.Add(BRepBuilderAPI_MakeEdge(top_side, top).Edge());
  profile.Add(BRepBuilderAPI_MakeEdge(top, bottom).Edge());
  const TopoDS_Face half = BRepBuilderAPI_MakeFace(profile.Wire(), Standard_True).Face();
  const TopoDS_Shape tool = BRepPrimAPI_MakeRevol(half, gp::OZ(), 2 * M_PI).Shape();
  gp_Trsf place;
  place.SetDisplacement(gp_Ax3(gp::XOY()), gp_Ax3(gp_Pnt(tip.x(), tip.y(), tip.z()),
                                                  gp_Dir(axis.x(), axis.y(), axis.z())));
  return BRepBuilderAPI_Transform(tool, place, Standard_True).Shape();
}

// A floor (the left half of the wavy face) with a wall standing at its edge, x = 30: plane_cl
// passes towards the wall stop where the ball would go into it, 3 mm short (the tip at x = 27),
// the stretch reported; without the check they run on to the floor's edge. Every setpoint of the
// planned job keeps the ball out of the wall by OpenCASCADE's distance from its centre, to the
// check's tolerance.
TEST(CheckFaces, APassTowardsATallerNeighbourStopsWhereTheToolWouldGoIntoIt) {
  const TopoDS_Face wall = Wall();
  const std::string step = FloorAndWall("wall");
  const auto job = [&](const std::string& check) {
    return BallJob(step, "face = \"floor\"\n" + check,
                   "plane_normal = [0, 1, 0]\ndirection = [1, 0, 0]\nstepover_mm = 9",
                   test::Scratch("wall.toml"));
  };
  const io::Job checked = job("");
  const io::SurfaceSetup setup = io::SetUpSurface(checked, nullptr);
  ASSERT_GE(setup.passes.passes.size(), 6u);
  ASSERT_EQ(setup.passes.unreachable.size(), setup.passes.passes.size());
  for (const auto& u : setup.passes.unreachable) {
    EXPECT_NE(u.why.find("the tool goes into"), std::string::npos) << u.why;
    EXPECT_NE(u.why.find("face 2 ('wall')"), std::string::npos) << u.why;
  }
  const double tol = checked.surface->check_tolerance_mm;
  for (const auto& pass : setup.passes.passes) {
    const double end = pass->EndPose().tip.x();
    EXPECT_LE(end, 27.0 + tol) << pass->StartPose().tip.y();
    EXPECT_GE(end, 27.0 - 1e-3) << pass->StartPose().tip.y();
  }
  const io::SurfaceSetup unchecked = io::SetUpSurface(job("check_faces = \"none\""), nullptr);
  EXPECT_TRUE(unchecked.passes.unreachable.empty());
  for (const auto& pass : unchecked.passes.passes) EXPECT_GT(pass->EndPose().tip.x(), 29.0);
  // The same, with the wall named.
  EXPECT_EQ(io::SetUpSurface(job("check_faces = \"wall\""), nullptr).passes.passes.size(),
            setup.passes.passes.size());
  test::ExpectError(
      [&] { io::SetUpSurface(job("check_faces = [\"floor\"]"), nullptr); },
      {"wall.toml:6: key 'surface.check_faces': face 1 of", "is finished by the job"});

  const io::RunResult r = io::RunJob(checked);
  ASSERT_TRUE(r.verify.Passed()) << interp::FormatReport(r.verify);
  EXPECT_EQ(r.checked_faces, 1);
  const std::string summary = io::FormatRunSummary(checked, r);
  EXPECT_NE(summary.find("checked          the tool kept out of 1 face of the part besides the "
                         "job's (check_faces)\n"),
            std::string::npos)
      << summary;
  const auto& c = r.table.columns;
  double closest = INFINITY;
  for (std::size_t k = 0; k < c[0].size(); k += 5) {
    const gp_Pnt centre(c[0][k], c[1][k], c[2][k] + 3.0);
    BRepExtrema_DistShapeShape d(BRepBuilderAPI_MakeVertex(centre).Vertex(), wall);
    ASSERT_TRUE(d.IsDone());
    closest = std::min(closest, d.Value());
  }
  EXPECT_GE(closest, 3.0 - tol);
  EXPECT_LT(closest, 3.0 + 0.01);  // and it came to the wall
}

// More stretches left out than the summary lists: it says how many more and where to find them
// all, and the HTML report lists every one.
TEST(SurfaceJob, TheReportListsEveryUnreachableStretch) {
  const std::string step = FloorAndWall("many_left_out");
  const io::Job job = BallJob(step, "face = \"floor\"",
                              "plane_normal = [0, 1, 0]\ndirection = [1, 0, 0]\nstepover_mm = 3",
                              test::Scratch("many_left_out.toml"));
  const io::RunResult r = io::RunJob(job);
  ASSERT_GT(r.unreachable_count, io::kSummaryUnreachable);
  const std::string summary = io::FormatRunSummary(job, r);
  EXPECT_NE(
      summary.find(fmt::format("  and {} more\n", r.unreachable_count - io::kSummaryUnreachable)),
      std::string::npos)
      << summary;
  EXPECT_NE(summary.find("`dtis run --report F.html`, lists them all"), std::string::npos)
      << summary;
  std::size_t lines = 0;
  for (std::size_t at = r.unreachable_all.find("\n  line "); at != std::string::npos;
       at = r.unreachable_all.find("\n  line ", at + 1)) {
    ++lines;
  }
  EXPECT_EQ(lines, r.unreachable_count);
  EXPECT_EQ(r.unreachable_all.find("more\n"), std::string::npos);
  io::ReportInput in;
  in.title = job.name;
  in.machine = r.machine.get();
  in.table = &r.table;
  in.verify = &r.verify;
  in.unreachable = r.unreachable_all;
  const std::string html = io::RenderReport(in, "/* plotly */");
  EXPECT_NE(html.find(nlohmann::json(r.unreachable_all).dump()), std::string::npos);
}

// Tilted 10 deg towards the wall (tilt_yaw leans the axis towards the feed), the ball's shank
// reaches the wall before the ball does: passes stop earlier than 3-axis, where the tool, as an
// OpenCASCADE solid reaching 100 mm up its axis, touches the wall: shrunk by the check's tolerance
// it is clear of it (OpenCASCADE's distance between the solid and the wall), grown by 0.01 mm it
// meets it.
TEST(CheckFaces, ATiltedToolStopsWhereItsShankReachesTheWall) {
  for (const bool slanted : {false, true}) {
    const TopoDS_Face wall = Wall(slanted);
    ASSERT_EQ(FaceSurface(wall, "wall").Trimmed(), slanted);
    const std::string step = FloorAndWall(slanted ? "slanted_wall" : "tilted_wall", wall);
    const io::Job job =
        BallJob(step, "face = \"floor\"",
                "plane_normal = [0, 1, 0]\ndirection = [1, 0, 0]\nstepover_mm = 12\n"
                "[orientation]\nkind = \"tilt_yaw\"\ntilt_deg = 10",
                test::Scratch("tilted_wall.toml"));
    const io::SurfaceSetup setup = io::SetUpSurface(job, nullptr);
    ASSERT_GE(setup.passes.passes.size(), 4u);
    const double tol = job.surface->check_tolerance_mm;
    for (const auto& pass : setup.passes.passes) {
      const Pose end = pass->EndPose();
      SCOPED_TRACE(fmt::format("{} wall, pass at y = {}, ends at x = {}",
                               slanted ? "slanted" : "level", end.tip.y(), end.tip.x()));
      EXPECT_GT(end.axis.x(), 0.1);        // leaning towards the wall
      EXPECT_LT(end.tip.x(), 27.0 - 1.0);  // its shank, not the ball, stops it
      BRepExtrema_DistShapeShape clear(BallSolid(3.0, 100.0, end.tip, end.axis, tol + 1e-4), wall);
      ASSERT_TRUE(clear.IsDone());
      EXPECT_GT(clear.Value(), 0.0);
      BRepExtrema_DistShapeShape meets(BallSolid(3.0, 100.0, end.tip, end.axis, -0.01), wall);
      ASSERT_TRUE(meets.IsDone());
      EXPECT_LT(meets.Value(), 1e-9);
    }
  }
}

// A part larger than the machine's travel is finished in parts: with bounds, passes start and end
// where the tip reaches the box's sides (to the trace's bisection, 0.1 mm / 4096), and what lies
// outside is not reported as unreachable.
TEST(SurfacePass, BoundsEndThePassesWhereTheTipReachesTheirSides) {
  const TopoDS_Face face = WavyRuledFace();
  const FaceSurface surface(face, "wavy");
  StrategySpec spec;
  spec.kind = StrategySpec::Kind::kPlaneCl;
  spec.plane_normal = Eigen::Vector3d::UnitX();
  spec.direction = Eigen::Vector3d::UnitY();
  spec.stepover_mm = 10.0;
  const auto whole = strategies::BuildPasses(surface, Ball(3.0), Orientation{}, spec);
  spec.bounds = StrategySpec::Bounds{Eigen::Vector3d(-INFINITY, 20.0, -INFINITY),
                                     Eigen::Vector3d(INFINITY, 40.0, INFINITY)};
  const auto part = strategies::BuildPasses(surface, Ball(3.0), Orientation{}, spec);
  ASSERT_EQ(part.passes.size(), whole.passes.size());
  EXPECT_TRUE(part.unreachable.empty());
  constexpr double kBisection = 0.1 / 4096.0;
  for (const auto& pass : part.passes) {
    const double start = pass->StartPose().tip.y(), end = pass->EndPose().tip.y();
    EXPECT_GE(start, 20.0);
    EXPECT_LE(start, 20.0 + kBisection);
    EXPECT_LE(end, 40.0);
    EXPECT_GE(end, 40.0 - kBisection);
    // The planner's march ends there too, to the Newton tolerance (1e-6 mm).
    EXPECT_NEAR(pass->At(pass->Start(), *pass->Length()).pose.tip.y(), end, 1e-6);
  }
  spec.bounds->min.y() = 100.0;
  spec.bounds->max.y() = 200.0;
  test::ExpectError([&] { strategies::BuildPasses(surface, Ball(3.0), Orientation{}, spec); },
                    {"wavy: no pass of the plane_cl strategy keeps the tool tip within its bounds",
                     "the face spans"});
}

TEST(SurfacePass, TrimmedFacePassesEndOnTheTrimmingCurve) {
  constexpr double kR = 20.0;
  const gp_Circ circle(gp_Ax2(gp_Pnt(0, 0, 0), gp_Dir(0, 0, 1)), kR);
  const TopoDS_Wire wire = BRepBuilderAPI_MakeWire(BRepBuilderAPI_MakeEdge(circle));
  const TopoDS_Face disc = BRepBuilderAPI_MakeFace(gp_Pln(gp::XOY()), wire);
  const FaceSurface surface(disc, "disc");
  ASSERT_TRUE(surface.Trimmed());
  StrategySpec spec;
  spec.kind = StrategySpec::Kind::kPlaneCc;
  spec.plane_normal = Eigen::Vector3d::UnitX();
  spec.direction = Eigen::Vector3d::UnitY();
  spec.stepover_mm = 3.0;
  const auto passes = strategies::BuildPasses(surface, Ball(2.0), Orientation{}, spec);
  ASSERT_GE(passes.passes.size(), 12u);
  for (const auto& pass : passes.passes) {
    const double c = pass->Evaluator().Constraint().value;
    const double half = std::sqrt(kR * kR - c * c);
    EXPECT_NEAR(*pass->Length(), 2.0 * half, 1e-6) << "x = " << c;
    EXPECT_NEAR(pass->StartPose().tip.y(), -half, 1e-6) << "x = " << c;
    EXPECT_NEAR(pass->EndPose().tip.y(), half, 1e-6) << "x = " << c;
    // The planner's march ends there too.
    const PathSample end = pass->At(pass->Start(), *pass->Length());
    EXPECT_NEAR(end.pose.tip.y(), half, 1e-6) << "x = " << c;
  }
}

// The contact point's path along a pass on the face, mm: chords between its contact points every
// `step` mm of the tip's arc length (over a crest the contact point stays on it).
double ContactPathLength(const strategies::SurfacePass& pass, double step) {
  const double length = *pass.Length();
  const int n = std::max(2, static_cast<int>(std::ceil(length / step)));
  PathState st = pass.Start();
  strategies::ContactPoint c;
  EXPECT_EQ(pass.Evaluate(st, &c), strategies::EvalStatus::kOk);
  Eigen::Vector3d last = c.p;
  double sum = 0.0;
  for (int i = 1; i <= n; ++i) {
    const PathSample smp = pass.At(st, length * i / n);
    EXPECT_TRUE(smp.status == PathStatus::kOk || smp.status == PathStatus::kEnd);
    EXPECT_EQ(pass.Evaluate(smp.state, &c), strategies::EvalStatus::kOk);
    sum += (c.p - last).norm();
    last = c.p;
    st = smp.state;
  }
  return sum;
}

// The cubic wave without its slope: its crest near y = 20 and its trough near y = 60 are level
// lines along x. Every strategy's lines run along y, in planes x = const (leading_line: offsets
// from a guide along x = 40), so each line's contact points follow the wave's section, the same
// curve for every line.
// What each line of `passes` (keyed by `key` of a contact point on it) finishes and leaves out
// (every stretch left out an undercut), mm.
template <typename Key>
std::map<long, double> LineCoverage(const strategies::PassList& passes, const Key& key) {
  std::map<long, double> covered;
  for (const auto& pass : passes.passes) {
    strategies::ContactPoint c;
    EXPECT_EQ(pass->Evaluate(pass->Start(), &c), strategies::EvalStatus::kOk);
    covered[key(c.p)] += ContactPathLength(*pass, 0.05);
  }
  for (const auto& u : passes.unreachable) {
    EXPECT_NE(u.why.find("undercut"), std::string::npos) << u.why;
    covered[key(u.from)] += u.length_mm;
  }
  return covered;
}

TEST(SurfacePass, AFlatBottomCrossesALevelCrestOnEveryStrategy) {
  const Handle(Geom_BSplineSurface) wave = parts::CubicWaveSurface(0.0);
  const TopoDS_Face face = BRepBuilderAPI_MakeFace(Handle(Geom_Surface)(wave), 1e-7).Face();
  const FaceSurface surface(face, "level cubic wave");
  // The section's length, from OpenCASCADE's curve of the surface at u = 40.
  const double section = GCPnts_AbscissaPoint::Length(GeomAdaptor_Curve(wave->UIso(40.0)));
  const auto xyz =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  for (const Tool& tool :
       {Torus(Tool::Kind::kFlatEnd, 4.0, 0.0), Torus(Tool::Kind::kBullNose, 5.0, 1.0)}) {
    for (const auto kind : {StrategySpec::Kind::kPlaneCl, StrategySpec::Kind::kPlaneCc,
                            StrategySpec::Kind::kUv, StrategySpec::Kind::kLeadingLine}) {
      SCOPED_TRACE(tool.Describe() + " " + StrategySpec::KindName(kind));
      StrategySpec spec;
      spec.kind = kind;
      spec.stepover_mm = 10.0;
      spec.along_u = false;
      spec.plane_normal = Eigen::Vector3d::UnitX();
      spec.direction = Eigen::Vector3d::UnitY();
      spec.guide = std::make_shared<const geometry::BSplineCurve>(
          geometry::BSplineCurveData{1, {0, 0, 1, 1}, {{40, -5, 0}, {40, 85, 0}}, {}});
      const auto passes = strategies::BuildPasses(surface, tool, Orientation{}, spec);
      // Every line is finished from one side of the face to the other, but for what is left out
      // (the flat bottom cannot follow the trough), and the two add up to the section.
      std::map<int, double> covered;
      for (const auto& pass : passes.passes) {
        const double x = pass->StartPose().tip.x();
        covered[static_cast<int>(std::lround(x))] += ContactPathLength(*pass, 0.05);
      }
      for (const auto& u : passes.unreachable) {
        EXPECT_TRUE(u.resumes) << passes.UnreachableText(100);
        EXPECT_NE(u.why.find("valley"), std::string::npos) << u.why;
        EXPECT_GT(u.length_mm, 5.0);
        covered[static_cast<int>(std::lround(u.from.x()))] += u.length_mm;
      }
      EXPECT_EQ(covered.size(), kind == StrategySpec::Kind::kLeadingLine ? 7u : 8u);
      for (const auto& [x, length] : covered) EXPECT_NEAR(length, section, 0.01) << "x = " << x;
      // A pass across the crest: planned within every limit, the tip at the crest's height over
      // it, the tool above the face.
      const strategies::SurfacePass& first = *passes.passes.front();
      ASSERT_TRUE(first.HasBridges());
      interp::VpopOptions opt;
      opt.feed_mm_s = 50.0;
      const test::Planned planned = test::PlanAndVerify(first, *xyz, opt);
      EXPECT_LE(planned.report.worst_ratio, 1.0) << planned.report.worst;
      double highest = -INFINITY;
      for (const auto& sp : planned.points) highest = std::max(highest, xyz->Forward(sp.q).tip.z());
      // Over the crest (the contact point on it, the normal the axis), every 2 mm: OpenCASCADE's
      // projection of the tool's bottom and corner.
      int over = 0;
      PathState st = first.Start();
      for (double at = 0.0; at < *first.Length(); at += 2.0) {
        const PathSample smp = first.At(st, at);
        st = smp.state;
        strategies::ContactPoint c;
        ASSERT_EQ(first.Evaluate(smp.state, &c), strategies::EvalStatus::kOk);
        if (c.n.dot(c.axis) < 1.0 - 1e-12) continue;
        ++over;
        EXPECT_GT(SampledClearance(face, tool, smp.pose, c.uv, c.n), -1e-6)
            << first.Describe(smp.state);
      }
      EXPECT_GE(over, 3);
      double top = -INFINITY;
      for (int k = 0; k <= 4000; ++k) top = std::max(top, wave->Value(40.0, 10.0 + k * 0.005).Z());
      EXPECT_NEAR(highest, top, 1e-6);
    }
  }
}

// A whole sphere of radius 10 (its poles collapsed edges of (u, v), its seam the half meridian
// y = 0, x > 0) finished by a ball R1 on a fixed axis: plane_cl lines through its pole and beside
// it, closed sections (planes y = c cut it in circles that touch neither the seam nor a pole) and
// uv lines from pole to pole. Every line is found, and what its passes finish and what is left out
// (the lower half, where the ball would touch with its upper side) add up to the whole line:
// a circle of radius sqrt(100 - d^2), d the contact points' distance from the centre's plane
// (10/11 of the tip plane's), or half a great circle.
TEST(SurfacePass, ASphereIsFinishedThroughItsPolesAndRoundItsClosedSections) {
  const Handle(Geom_SphericalSurface) sphere = new Geom_SphericalSurface(gp_Ax3(gp::XOY()), 10.0);
  const TopoDS_Face face =
      BRepBuilderAPI_MakeFace(sphere, 0, 2 * std::numbers::pi, -std::numbers::pi / 2,
                              std::numbers::pi / 2, 1e-7)
          .Face();
  const FaceSurface surface(face, "sphere");
  const auto xyz =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  const auto coverage = [](const strategies::PassList& passes, const auto& key) {
    return LineCoverage(passes, key);
  };
  for (const Eigen::Vector3d normal : {Eigen::Vector3d::UnitX(), Eigen::Vector3d::UnitY()}) {
    // Through the pole (x = 0, a great circle through both), beside it (x = +-0.25), the whole
    // face (stepover 1 mm); planes y = c: closed sections, but y = 0 along the seam.
    for (const auto& [first, last, step] :
         {std::tuple{0.0, 0.0, 1.0}, std::tuple{-0.25, 0.25, 0.5}, std::tuple{-10.5, 10.5, 1.0}}) {
      SCOPED_TRACE(
          fmt::format("normal ({}, {}, 0), lines {} to {}", normal.x(), normal.y(), first, last));
      StrategySpec spec;
      spec.plane_normal = normal;
      spec.direction = normal.cross(Eigen::Vector3d::UnitZ());
      spec.range = std::array<double, 2>{first, last};
      spec.stepover_mm = step;
      const auto passes = strategies::BuildPasses(surface, Ball(1.0), Orientation{}, spec);
      const auto covered = coverage(passes, [&](const Eigen::Vector3d& p) {
        return std::lround(p.dot(normal) * 1.1 / 0.25);  // the tip plane, in quarter mm
      });
      EXPECT_EQ(covered.size(), static_cast<std::size_t>(std::lround((last - first) / step)) + 1)
          << passes.UnreachableText(100);
      for (const auto& [quarter, length] : covered) {
        const double d = static_cast<double>(quarter) * 0.25 / 1.1;
        EXPECT_NEAR(length, 2.0 * std::numbers::pi * std::sqrt(100.0 - d * d), 0.01)
            << "tip plane at " << static_cast<double>(quarter) * 0.25
            << passes.UnreachableText(100);
      }
      // Each pass of the lines through and beside the pole planned within every limit, the ball
      // on the sphere and the tip on its plane.
      if (first == -10.5) continue;
      for (const auto& pass : passes.passes) {
        interp::VpopOptions opt;
        opt.feed_mm_s = 50.0;
        const test::Planned planned = test::PlanAndVerify(*pass, *xyz, opt);
        EXPECT_LE(planned.report.worst_ratio, 1.0) << planned.report.worst;
        const double plane = pass->Evaluator().Constraint().value;
        for (const auto& sp : planned.points) {
          const Pose pose = xyz->Forward(sp.q);
          ASSERT_NEAR((pose.tip + pose.axis).norm(), 11.0, 1e-6);
          ASSERT_NEAR(pose.tip.dot(normal), plane, 1e-6);
        }
      }
    }
  }
  // uv lines along v, from the south pole to the north one: the upper half of each meridian.
  StrategySpec spec;
  spec.kind = StrategySpec::Kind::kUv;
  spec.along_u = false;
  spec.stepover_mm = 5.0;
  const auto passes = strategies::BuildPasses(surface, Ball(1.0), Orientation{}, spec);
  const auto covered = coverage(
      passes, [](const Eigen::Vector3d& p) { return std::lround(std::atan2(p.y(), p.x()) * 1e3); });
  EXPECT_EQ(covered.size(), 8u);
  for (const auto& [angle, length] : covered) {
    EXPECT_NEAR(length, std::numbers::pi * 10.0, 0.01)
        << "u = " << static_cast<double>(angle) * 1e-3;
  }
  for (const auto& pass : passes.passes) {
    EXPECT_NEAR((pass->EndPose().tip - Eigen::Vector3d(0, 0, 10)).norm(), 0.0, 1e-3);
  }
}

// The whole sphere of radius 10 above, its north pole a top, finished on a fixed axis by a flat
// end R4 and a bull nose R5 r1: plane_cl lines through the pole and beside it, uv lines from pole
// to pole. At every setpoint of every pass the tool touches the sphere (its corner circle's
// distance from the centre is 10 + r, in closed form, within 1e-6 mm) and a plane_cl tip stays on
// its plane; over the pole the bottom slides across with the tip at the pole's height. What each
// line's passes finish and what is left out (the lower half: an undercut) add up to its contact
// curve: for a plane x = c, where ((10 + r) cos(lat) + R - r) cos(long) is c (Simpson's rule on
// the latitude, two branches), for a uv line half a great circle.
TEST(SurfacePass, AFlatBottomIsCarriedOverASpheresPole) {
  const Handle(Geom_SphericalSurface) sphere = new Geom_SphericalSurface(gp_Ax3(gp::XOY()), 10.0);
  const TopoDS_Face face =
      BRepBuilderAPI_MakeFace(sphere, 0, 2 * std::numbers::pi, -std::numbers::pi / 2,
                              std::numbers::pi / 2, 1e-7)
          .Face();
  const FaceSurface surface(face, "sphere");
  const auto xyz =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  for (const Tool& tool :
       {Torus(Tool::Kind::kFlatEnd, 4.0, 0.0), Torus(Tool::Kind::kBullNose, 5.0, 1.0)}) {
    const double big_r = tool.TorusRadius(), r = tool.corner_radius;
    // How far the tool's lower side is from the sphere: its corner's centres lie on the circle
    // of radius R - r, r above the tip.
    const auto gap = [&](const Pose& pose) {
      const double out = std::max(0.0, pose.tip.head<2>().norm() - big_r);
      return std::hypot(out, pose.tip.z() + r) - r - 10.0;
    };
    // Each pass planned within every limit, the tool touching the sphere, a plane_cl tip on its
    // plane; the highest tip, and how many setpoints have it at the pole's height.
    const auto plan = [&](const strategies::SurfacePass& pass, bool plane, int* over) {
      SCOPED_TRACE(pass.Describe(pass.Start()));
      interp::VpopOptions opt;
      opt.feed_mm_s = 50.0;
      opt.planner = pass.Index() % 2 ? interp::PlannerKind::kVpop : interp::PlannerKind::kLookAhead;
      const test::Planned planned = test::PlanAndVerify(pass, *xyz, opt);
      ASSERT_GT(planned.points.size(), 10u);
      EXPECT_LE(planned.report.worst_ratio, 1.0) << planned.report.worst;
      const double value = pass.Evaluator().Constraint().value;
      for (const auto& sp : planned.points) {
        const Pose pose = xyz->Forward(sp.q);
        ASSERT_NEAR(gap(pose), 0.0, 1e-6) << pose.tip.transpose();
        if (plane) {
          ASSERT_NEAR(pose.tip.x(), value, 1e-6);
        }
        if (std::abs(pose.tip.z() - 10.0) < 1e-9) ++*over;
      }
    };
    const auto coverage = [](const strategies::PassList& passes, const auto& key) {
      return LineCoverage(passes, key);
    };
    {
      SCOPED_TRACE(tool.Describe() + " plane_cl");
      StrategySpec spec;
      spec.range = std::array<double, 2>{-3.0, 3.0};
      spec.stepover_mm = 1.5;
      const auto passes = strategies::BuildPasses(surface, tool, Orientation{}, spec);
      // One pass a line, carried over the pole on the bottom: the tip at the pole's height for
      // a chord of 2 sqrt(R^2 - c^2) mm, 1 ms setpoints at 50 mm/s at most.
      ASSERT_EQ(passes.passes.size(), 5u);
      int over = 0;
      for (const auto& pass : passes.passes) {
        EXPECT_TRUE(pass->HasBridges());
        plan(*pass, true, &over);
      }
      double chords = 0.0;
      for (const double c : {-3.0, -1.5, 0.0, 1.5, 3.0}) {
        chords += 2.0 * std::sqrt(big_r * big_r - c * c) / 0.05;
      }
      EXPECT_GT(over, chords);
      // The tip plane of contact point p (tip = p + r n + (R - r) w - r a, n = p / 10 and w the
      // unit part of p across the axis), keyed in quarter mm.
      const auto covered = coverage(passes, [&](const Eigen::Vector3d& p) {
        const double h = p.head<2>().norm();
        const double x = h > 1e-9 ? p.x() * (1.0 + r / 10.0 + big_r / h) : 0.0;
        return std::lround(x / 0.25);
      });
      EXPECT_EQ(covered.size(), 5u) << passes.UnreachableText(100);
      for (const auto& [quarter, length] : covered) {
        const double c = static_cast<double>(quarter) * 0.25;
        // One branch of the contact curve, latitude from -90 to 90 deg: Simpson's rule.
        const auto speed = [&](double lat) {
          const double d = (10.0 + r) * std::cos(lat) + big_r;
          const double cos_long = c / d;
          const double sin_long = std::sqrt(1.0 - cos_long * cos_long);
          const double dlong = -c * (10.0 + r) * std::sin(lat) / (d * d * sin_long);
          return std::hypot(10.0, 10.0 * std::cos(lat) * dlong);
        };
        constexpr int kIntervals = 200000;
        const double h = std::numbers::pi / kIntervals;
        double branch = speed(-std::numbers::pi / 2) + speed(std::numbers::pi / 2);
        for (int k = 1; k < kIntervals; ++k) {
          branch += (k % 2 ? 4.0 : 2.0) * speed(-std::numbers::pi / 2 + k * h);
        }
        branch *= h / 3.0;
        EXPECT_NEAR(length, 2.0 * branch, 0.01) << "x = " << c << passes.UnreachableText(100);
      }
    }
    // plane_cc and leading_line (its guide along Y through the pole): the contact point on the
    // sections x = c, whose circles' whole lengths the passes and the stretches left out add up to.
    for (const auto kind : {StrategySpec::Kind::kPlaneCc, StrategySpec::Kind::kLeadingLine}) {
      SCOPED_TRACE(tool.Describe() + " " + StrategySpec::KindName(kind));
      StrategySpec spec;
      spec.kind = kind;
      spec.range = std::array<double, 2>{-2.0, 2.0};
      spec.stepover_mm = 1.0;
      spec.guide = std::make_shared<const geometry::BSplineCurve>(
          geometry::BSplineCurveData{1, {0, 0, 1, 1}, {{0, -20, 0}, {0, 20, 0}}, {}});
      const auto passes = strategies::BuildPasses(surface, tool, Orientation{}, spec);
      // The line through the pole is one pass, carried over it: its tip at the pole's height
      // across the bottom's diameter.
      int over = 0, bridged = 0;
      for (const auto& pass : passes.passes) {
        bridged += pass->HasBridges();
        plan(*pass, false, &over);
      }
      EXPECT_EQ(bridged, 1);
      EXPECT_GT(over, 2.0 * big_r / 0.05);
      const auto covered =
          coverage(passes, [](const Eigen::Vector3d& p) { return std::lround(p.x() / 0.25); });
      EXPECT_EQ(covered.size(), 5u) << passes.UnreachableText(100);
      for (const auto& [quarter, length] : covered) {
        const double c = static_cast<double>(quarter) * 0.25;
        EXPECT_NEAR(length, 2.0 * std::numbers::pi * std::sqrt(100.0 - c * c), 0.01)
            << "x = " << c << passes.UnreachableText(100);
      }
    }
    {
      SCOPED_TRACE(tool.Describe() + " uv");
      StrategySpec spec;
      spec.kind = StrategySpec::Kind::kUv;
      spec.along_u = false;
      spec.stepover_mm = 5.0;
      const auto passes = strategies::BuildPasses(surface, tool, Orientation{}, spec);
      // Each ends with its contact point at the pole, the bottom's edge on it.
      int over = 0;
      for (const auto& pass : passes.passes) {
        plan(*pass, false, &over);
        const Eigen::Vector3d end = pass->EndPose().tip;
        EXPECT_NEAR(end.z(), 10.0, 1e-3);
        EXPECT_NEAR(end.head<2>().norm(), big_r, 1e-3);
      }
      const auto covered = coverage(passes, [](const Eigen::Vector3d& p) {
        return std::lround(std::atan2(p.y(), p.x()) * 1e3);
      });
      EXPECT_EQ(covered.size(), 8u);
      for (const auto& [angle, length] : covered) {
        EXPECT_NEAR(length, std::numbers::pi * 10.0, 0.01)
            << "u = " << static_cast<double>(angle) * 1e-3 << passes.UnreachableText(100);
      }
    }
  }
}

}  // namespace
}  // namespace dtis
