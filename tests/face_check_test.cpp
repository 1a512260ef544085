// The tool kept out of the part's other faces (geometry/check_faces.hpp), measured independently:
// a floor with B-spline walls standing at three of its edges (a pocket of spline faces), the
// walls sharing the floor's edges, finished with a ball; the depth of every wall in the tool at
// points of the planned passes the trace never looked at, by OpenCASCADE's distance between the
// tool's axis and the wall.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <BRepBndLib.hxx>
#include <BRepBuilderAPI_MakeEdge.hxx>
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepExtrema_DistShapeShape.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <GeomAPI_PointsToBSpline.hxx>
#include <GeomAPI_PointsToBSplineSurface.hxx>
#include <GeomFill.hxx>
#include <Geom_BSplineCurve.hxx>
#include <Geom_BSplineSurface.hxx>
#include <TColgp_Array1OfPnt.hxx>
#include <TColgp_Array2OfPnt.hxx>
#include <cmath>
#include <numbers>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "dtis/geometry/check_faces.hpp"
#include "dtis/io/job.hpp"
#include "dtis/strategies/strategy.hpp"
#include "fixture_shapes.hpp"
#include "test_support.hpp"

namespace dtis {
namespace {

using geometry::Tool;

constexpr double kPi = std::numbers::pi;

// The floor: a bicubic B-spline over x, y in [0, 40], z = 1.2 sin(2 pi y / 40) + 0.8 cos(2 pi x /
// 40), interpolated on a grid every 2 mm (u along x, v along y).
Handle(Geom_BSplineSurface) Floor() {
  constexpr int kN = 21;
  TColgp_Array2OfPnt points(1, kN, 1, kN);
  for (int i = 1; i <= kN; ++i) {
    for (int j = 1; j <= kN; ++j) {
      const double x = 2.0 * (i - 1), y = 2.0 * (j - 1);
      points(i, j) =
          gp_Pnt(x, y, 1.2 * std::sin(2.0 * kPi * y / 40.0) + 0.8 * std::cos(2.0 * kPi * x / 40.0));
    }
  }
  return GeomAPI_PointsToBSplineSurface(points, 3, 3, GeomAbs_C2, 1e-5).Surface();
}

// A cubic B-spline curve through `n` points of f(t), t in [0, 1].
template <typename F>
Handle(Geom_BSplineCurve) CurveThrough(int n, F&& f) {
  TColgp_Array1OfPnt points(1, n);
  for (int i = 1; i <= n; ++i) points(i) = f(static_cast<double>(i - 1) / (n - 1));
  return GeomAPI_PointsToBSpline(points, 3, 3, GeomAbs_C2, 1e-5).Curve();
}

// A wall ruled from `bottom` (an edge of the floor, shared with it) up to `top`.
TopoDS_Face Wall(const Handle(Geom_Curve) & bottom, const Handle(Geom_Curve) & top) {
  return BRepBuilderAPI_MakeFace(GeomFill::Surface(bottom, top), 1e-7).Face();
}

struct Pocket {
  TopoDS_Face floor, left, right, back;
};

// How the pocket's walls stand: each leans out of the pocket by `lean_mm` at its top (negative:
// into it, over the floor) and waves along its length, its top `wave_mm` in and out with a
// period of `side_period_mm` (the left and right walls) or `back_period_mm` (the back one), the
// top interpolated through `points` points.
struct WallShape {
  double lean_mm = 3.5, wave_mm = 0.8, side_period_mm = 20.0, back_period_mm = 13.0;
  int points = 41;
};

// The floor and three walls 12 mm tall at its edges x = 0, x = 40 and y = 40, shaped as `shape`
// says: by default each leans out of the pocket by about 15 deg (none overhangs the floor), its
// top 0.8 mm in and out over 20 mm (the left and right walls) or 13 mm (the back one).
Pocket MakePocket(const WallShape& shape = {}) {
  const Handle(Geom_BSplineSurface) floor = Floor();
  double u0, u1, v0, v1;
  floor->Bounds(u0, u1, v0, v1);
  Pocket p;
  p.floor = BRepBuilderAPI_MakeFace(Handle(Geom_Surface)(floor), 1e-7).Face();
  // The top of the wall at x0 (or y0), `outward` the way out of the pocket (+1 or -1).
  const auto top = [&](double x0, double outward, bool along_y, double period) {
    return CurveThrough(shape.points, [=](double t) {
      const double w = 40.0 * t,
                   out = outward * shape.lean_mm + shape.wave_mm * std::sin(2.0 * kPi * w / period);
      return along_y ? gp_Pnt(x0 + out, w, 12.0) : gp_Pnt(w, x0 + out, 12.0);
    });
  };
  p.left = Wall(floor->UIso(u0), top(0.0, -1.0, true, shape.side_period_mm));
  p.right = Wall(floor->UIso(u1), top(40.0, 1.0, true, shape.side_period_mm));
  p.back = Wall(floor->VIso(v1), top(40.0, 1.0, false, shape.back_period_mm));
  return p;
}

// How deep `face` lies in a ball end of radius r (unlimited length) with tip `tip` and axis
// `axis`: r less OpenCASCADE's distance between the face and the ball centres' segment, 100 mm up
// the axis from the centre (the tool is that segment widened by r).
double DepthIn(const TopoDS_Face& face, double r, const Eigen::Vector3d& tip,
               const Eigen::Vector3d& axis) {
  const Eigen::Vector3d c = tip + r * axis, top = c + 100.0 * axis;
  const TopoDS_Edge segment =
      BRepBuilderAPI_MakeEdge(gp_Pnt(c.x(), c.y(), c.z()), gp_Pnt(top.x(), top.y(), top.z()))
          .Edge();
  BRepExtrema_DistShapeShape d(segment, face);
  EXPECT_TRUE(d.IsDone());
  return r - d.Value();
}

using Walls = std::vector<std::pair<TopoDS_Face, std::string>>;

// The deepest any of `walls` goes into a ball end of radius r with tip `tip` and a vertical axis
// (these jobs are 3-axis), into `deepest` with `where` and the wall's name when deeper than it;
// walls whose box is farther than r + 0.1 mm from the ball centres' segment are skipped.
class DeepestWall {
 public:
  DeepestWall(const Walls& walls, double r) : walls_(walls), r_(r) {
    for (const auto& w : walls) {
      Bnd_Box b;
      BRepBndLib::AddOptimal(w.first, b, false, false);
      b.Enlarge(r + 0.1);
      boxes_.push_back(b);
    }
  }
  void At(const Eigen::Vector3d& tip, const std::string& place) {
    const Eigen::Vector3d c = tip + r_ * Eigen::Vector3d::UnitZ();
    Bnd_Box column;
    column.Add(gp_Pnt(c.x(), c.y(), c.z()));
    column.Add(gp_Pnt(c.x(), c.y(), c.z() + 100.0));
    for (std::size_t w = 0; w < walls_.size(); ++w) {
      if (boxes_[w].IsOut(column)) continue;
      const double d = DepthIn(walls_[w].first, r_, tip, Eigen::Vector3d::UnitZ());
      if (d > depth) depth = d, where = place + ", " + walls_[w].second;
    }
  }
  double depth = -INFINITY;
  std::string where;

 private:
  const Walls& walls_;
  double r_;
  std::vector<Bnd_Box> boxes_;
};

// The deepest any of `walls` goes into the ball of radius r along every pass of `setup`, at the
// middle of every `step` mm of arc length (points the trace, stepping 0.1 mm from the pass's
// start, did not check).
DeepestWall DeepestAlongPasses(const io::SurfaceSetup& setup, double r, const Walls& walls,
                               double step) {
  DeepestWall deepest(walls, r);
  for (std::size_t k = 0; k < setup.passes.passes.size(); ++k) {
    const auto& pass = *setup.passes.passes[k];
    const double length = *pass.Length();
    PathState state = pass.Start();
    for (double s = 0.5 * step; s < length; s += step) {
      const PathSample smp = pass.At(state, s);
      if (smp.status != PathStatus::kOk) continue;
      state = smp.state;
      const Eigen::Vector3d& tip = smp.pose.tip;
      deepest.At(tip, fmt::format("pass {}, s = {:.4f} mm, tip ({:.5f}, {:.5f}, {:.5f})", k + 1, s,
                                  tip.x(), tip.y(), tip.z()));
    }
  }
  return deepest;
}

// A ball R1 finishing the floor of the pocket, along the side walls (planes x = const) and
// towards the back wall (planes y = const): no wall goes into the ball by more than the check's
// tolerance between the points the trace checked, by OpenCASCADE's distance.
TEST(CheckFaces, NoNeighbourGoesIntoTheToolBetweenTheCheckedPoints) {
  const Pocket p = MakePocket();
  const Walls walls = {{p.left, "left"}, {p.right, "right"}, {p.back, "back"}};
  const std::string step = test::WriteNamedFaces({{p.floor, "floor"}, walls[0], walls[1], walls[2]},
                                                 test::Scratch("spline_pocket.stp"));
  for (const char* planes :
       {"plane_normal = [1, 0, 0]\ndirection = [0, 1, 0]\nstepover_mm = 1.3",
        "plane_normal = [0, 1, 0]\ndirection = [1, 0, 0]\nstepover_mm = 1.7"}) {
    SCOPED_TRACE(planes);
    const io::Job job =
        test::PlaneClJob(step, "face = \"floor\"", "kind = \"ball_end\"\nradius_mm = 1", planes,
                         test::Scratch("spline_pocket.toml"));
    const io::SurfaceSetup setup = io::SetUpSurface(job, nullptr);
    ASSERT_GE(setup.passes.passes.size(), 20u);
    EXPECT_FALSE(setup.passes.unreachable.empty());
    const DeepestWall d = DeepestAlongPasses(setup, 1.0, walls, 0.05);
    EXPECT_LE(d.depth, job.surface->check_tolerance_mm) << d.where;
    EXPECT_GT(d.depth, -0.01) << d.where;  // the passes come to the walls
    // And as planned, along the side walls: the middle of every other period of the job (passes,
    // links, moves riding over a stretch), between two setpoints, the tip's XYZ being the table's
    // first three columns.
    if (std::string(planes).rfind("plane_normal = [1", 0) != 0) continue;
    const io::RunResult r = io::RunJob(job);
    ASSERT_TRUE(r.verify.Passed());
    const auto& c = r.table.columns;
    DeepestWall planned(walls, 1.0);
    for (std::size_t k = 0; k + 1 < c[0].size(); k += 2) {
      const Eigen::Vector3d tip(0.5 * (c[0][k] + c[0][k + 1]), 0.5 * (c[1][k] + c[1][k + 1]),
                                0.5 * (c[2][k] + c[2][k + 1]));
      planned.At(tip, fmt::format("setpoint {} + 0.5, tip ({:.5f}, {:.5f}, {:.5f})", k, tip.x(),
                                  tip.y(), tip.z()));
    }
    EXPECT_LE(planned.depth, job.surface->check_tolerance_mm) << planned.where;
  }
}

// Balls R1 and R3 placed into a wall of the pocket by a known depth (their centre that much less
// than the radius from a random point of it, along its normal, their axis vertical or leaning
// 20 deg away from the wall): where OpenCASCADE's distance between the wall and the tool's axis
// puts the wall deeper in the tool than the tolerance, the check finds it, never deeper than that;
// placed as far out of it, it finds none, and a clearance no larger than the true one.
TEST(CheckFaces, FindsTheDepthOfANeighbourAtRandomPoses) {
  const Pocket p = MakePocket();
  std::mt19937_64 rng(test::g_seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (const double r : {1.0, 3.0}) {
    Tool ball;
    ball.kind = Tool::Kind::kBallEnd;
    ball.radius = ball.corner_radius = r;
    const geometry::CheckFaces check({{p.left, "left"}, {p.right, "right"}, {p.back, "back"}}, ball,
                                     INFINITY, 1e-3);
    const std::vector<TopoDS_Face> walls = {p.left, p.right, p.back};
    int found = 0;
    for (int n = 0; n < 40; ++n) {
      const TopoDS_Face& wall = walls[static_cast<std::size_t>(n % 3)];
      const Handle(Geom_Surface) s = BRep_Tool::Surface(wall);
      double u0, u1, v0, v1;
      s->Bounds(u0, u1, v0, v1);
      // Away from the wall's top and bottom by the ball's radius: the wall's inside there.
      const double u = u0 + (u1 - u0) * (0.1 + 0.8 * unit(rng));
      const double v = v0 + (v1 - v0) * (0.35 + 0.4 * unit(rng));
      gp_Pnt at;
      gp_Vec su, sv;
      s->D1(u, v, at, su, sv);
      Eigen::Vector3d normal(su.Crossed(sv).X(), su.Crossed(sv).Y(), su.Crossed(sv).Z());
      normal.normalize();
      // Into the pocket: towards the floor's middle (20, 20).
      if (normal.dot(Eigen::Vector3d(20.0 - at.X(), 20.0 - at.Y(), 0.0)) < 0.0) normal = -normal;
      const double lean = n % 2 == 0 ? 0.0 : 20.0 * kPi / 180.0;
      const Eigen::Vector3d across = Eigen::Vector3d(normal.x(), normal.y(), 0.0).normalized();
      const Eigen::Vector3d axis =
          std::sin(lean) * across + std::cos(lean) * Eigen::Vector3d::UnitZ();
      for (const double depth : {0.005, 0.002, -0.002}) {
        const Eigen::Vector3d centre =
            Eigen::Vector3d(at.X(), at.Y(), at.Z()) + (r - depth) * normal;
        const Eigen::Vector3d tip = centre - r * axis;
        const double truth = DepthIn(wall, r, tip, axis);
        SCOPED_TRACE(fmt::format("R{}, wall point ({:.4f}, {:.4f}, {:.4f}), depth {}, true {}", r,
                                 at.X(), at.Y(), at.Z(), depth, truth));
        ASSERT_GE(truth, depth - 1e-9);
        const geometry::CheckFaces::Near near = check.Around(tip, axis, 1.0);
        if (truth > 1e-3 + 1e-5) {
          ASSERT_TRUE(near.hit.has_value());
          EXPECT_GT(near.hit->depth_mm, 1e-3);  // (its descent stops once past the tolerance)
          EXPECT_LE(near.hit->depth_mm, truth + 1e-6);
          EXPECT_LT(near.clearance_mm, -1e-3);
          ++found;
        } else if (truth < 0.0) {
          EXPECT_FALSE(near.hit.has_value());
          // A clearance is a bound the trace relies on: never more than the true one.
          EXPECT_LE(near.clearance_mm, -truth + 1e-6);
          EXPECT_GE(near.clearance_mm, 0.0);
        }
      }
    }
    EXPECT_GE(found, 60);
  }
}

}  // namespace
}  // namespace dtis
