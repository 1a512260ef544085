// The tool kept out of the part's other faces (geometry/check_faces.hpp), measured independently:
// a floor with B-spline walls standing at three of its edges (a pocket of spline faces), the
// walls sharing the floor's edges, finished with a ball; the depth of every wall in the tool at
// points of the planned passes the trace never looked at, by OpenCASCADE's distance between the
// tool's axis and the wall. With walls that lean into the pocket and wave, where the tool fits
// beside them only in places: every line's pieces and stretches left out, against OpenCASCADE's
// section of the floor.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <BRepBndLib.hxx>
#include <BRepBuilderAPI_MakeEdge.hxx>
#include <BRepBuilderAPI_MakeFace.hxx>
#include <BRepExtrema_DistShapeShape.hxx>
#include <BRep_Tool.hxx>
#include <Bnd_Box.hxx>
#include <GeomAPI_IntSS.hxx>
#include <GeomAPI_PointsToBSpline.hxx>
#include <GeomAPI_PointsToBSplineSurface.hxx>
#include <GeomFill.hxx>
#include <Geom_BSplineCurve.hxx>
#include <Geom_BSplineSurface.hxx>
#include <Geom_Plane.hxx>
#include <TColgp_Array1OfPnt.hxx>
#include <TColgp_Array2OfPnt.hxx>
#include <algorithm>
#include <cmath>
#include <map>
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
// start, did not check), short of the pass's end (which it did: where a wall stops a pass, its
// end lies where the wall comes to the check's tolerance).
DeepestWall DeepestAlongPasses(const io::SurfaceSetup& setup, double r, const Walls& walls,
                               double step) {
  DeepestWall deepest(walls, r);
  for (std::size_t k = 0; k < setup.passes.passes.size(); ++k) {
    const auto& pass = *setup.passes.passes[k];
    const double length = *pass.Length();
    PathState state = pass.Start();
    for (int i = 0; (i + 0.5) * step < length - 1e-6; ++i) {
      const double s = (i + 0.5) * step;
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

// The floor's section by the plane normal . x = c, from OpenCASCADE's intersection of the two
// surfaces: its points about 1 um apart in order along `along` (the lines' travel), each with
// the arc length (chords) from the section's start.
class Section {
 public:
  Section(const Handle(Geom_Surface) & floor, const Eigen::Vector3d& normal, double c,
          const Eigen::Vector3d& along)
      : along_(along) {
    const Handle(Geom_Plane) plane =
        new Geom_Plane(gp_Pln(gp_Pnt(c * normal.x(), c * normal.y(), c * normal.z()),
                              gp_Dir(normal.x(), normal.y(), normal.z())));
    GeomAPI_IntSS cut(floor, plane, 1e-9);
    EXPECT_TRUE(cut.IsDone());
    EXPECT_EQ(cut.NbLines(), 1);
    if (!cut.IsDone() || cut.NbLines() < 1) return;
    const Handle(Geom_Curve) line = cut.Line(1);
    constexpr int kPoints = 40000;
    const double t0 = line->FirstParameter(), t1 = line->LastParameter();
    for (int i = 0; i <= kPoints; ++i) {
      const gp_Pnt q = line->Value(t0 + (t1 - t0) * i / kPoints);
      points_.emplace_back(q.X(), q.Y(), q.Z());
    }
    if (points_.front().dot(along) > points_.back().dot(along)) {
      std::reverse(points_.begin(), points_.end());
    }
    arc_.push_back(0.0);
    for (std::size_t i = 1; i < points_.size(); ++i) {
      arc_.push_back(arc_.back() + (points_[i] - points_[i - 1]).norm());
    }
  }
  double Length() const { return arc_.empty() ? 0.0 : arc_.back(); }
  // The arc length from the section's start to its point where it passes p along `along`
  // (the section runs one way along it), linear between the two points either side.
  double ArcAt(const Eigen::Vector3d& p) const {
    if (points_.empty()) return 0.0;
    const double x = p.dot(along_);
    std::size_t lo = 0, hi = points_.size() - 1;
    if (x <= points_[lo].dot(along_)) return 0.0;
    if (x >= points_[hi].dot(along_)) return arc_.back();
    while (hi - lo > 1) {
      const std::size_t mid = (lo + hi) / 2;
      (points_[mid].dot(along_) <= x ? lo : hi) = mid;
    }
    const double a = points_[lo].dot(along_), b = points_[hi].dot(along_);
    return arc_[lo] + (arc_[hi] - arc_[lo]) * (x - a) / (b - a);
  }

 private:
  Eigen::Vector3d along_;
  std::vector<Eigen::Vector3d> points_;
  std::vector<double> arc_;
};

// The contact point's path along a pass on the face, mm: chords between its contact points every
// `step` mm of the tip's arc length; and its first and last contact points.
double ContactPath(const strategies::SurfacePass& pass, double step, Eigen::Vector3d* first,
                   Eigen::Vector3d* last) {
  const double length = *pass.Length();
  const int n = std::max(2, static_cast<int>(std::ceil(length / step)));
  PathState st = pass.Start();
  strategies::ContactPoint c;
  EXPECT_EQ(pass.Evaluate(st, &c), strategies::EvalStatus::kOk);
  *first = *last = c.p;
  double sum = 0.0;
  for (int i = 1; i <= n; ++i) {
    const PathSample smp = pass.At(st, length * i / n);
    EXPECT_TRUE(smp.status == PathStatus::kOk || smp.status == PathStatus::kEnd);
    EXPECT_EQ(pass.Evaluate(smp.state, &c), strategies::EvalStatus::kOk);
    sum += (c.p - *last).norm();
    *last = c.p;
    st = smp.state;
  }
  return sum;
}

// A stretch of a line as the planner gives it (a pass, or what it leaves out) and as the
// section measures it: where it starts and ends along the section and its length there.
struct OnLine {
  double from = 0.0, to = 0.0;  // arc length along the section, mm
  double length = 0.0;          // the planner's, mm
  std::string what;
};

// For every plane_cc line of `passes` (planes normal . x = c, travelling along `along`) on the
// floor: the pieces the planner finishes and the stretches it leaves out, in order along the
// line, each with the section's arc length between its ends (a pass: its contact points; a
// stretch: from and to), keyed by c in units of 1e-3 mm.
std::map<long, std::vector<OnLine>> Lines(const strategies::PassList& passes,
                                          const Handle(Geom_Surface) & floor,
                                          const Eigen::Vector3d& normal,
                                          const Eigen::Vector3d& along,
                                          std::map<long, Section>* sections) {
  std::map<long, std::vector<OnLine>> lines;
  const auto on = [&](const Eigen::Vector3d& p) -> const Section& {
    const long key = std::lround(normal.dot(p) * 1e3);
    auto it = sections->find(key);
    if (it == sections->end()) {
      it = sections->emplace(key, Section(floor, normal, static_cast<double>(key) * 1e-3, along))
               .first;
    }
    return it->second;
  };
  for (const auto& pass : passes.passes) {
    Eigen::Vector3d a, b;
    const double length = ContactPath(*pass, 0.02, &a, &b);
    const Section& s = on(a);
    lines[std::lround(normal.dot(a) * 1e3)].push_back(
        {s.ArcAt(a), s.ArcAt(b), length, fmt::format("pass {}", pass->Index())});
  }
  for (const auto& u : passes.unreachable) {
    const Section& s = on(u.from);
    lines[std::lround(normal.dot(u.from) * 1e3)].push_back(
        {s.ArcAt(u.from), s.ArcAt(u.to), u.length_mm,
         fmt::format("stretch of line {} ({})", u.line, u.why.substr(0, 60))});
  }
  for (auto& [key, l] : lines) {
    for (OnLine& o : l) {
      if (o.from > o.to) std::swap(o.from, o.to);  // traced from the line's other end
    }
    std::sort(l.begin(), l.end(), [](const OnLine& x, const OnLine& y) {
      return x.from != y.from ? x.from < y.from : x.to < y.to;
    });
  }
  return lines;
}

// The pocket with its walls leaning into it, over the floor: their tops 1 mm in on average and
// waving 2 mm in and out, every 8 mm along the side walls and 6.5 mm along the back one, so that
// beside them a ball R1 or R3 and a flat end R2 (of unlimited length) fit only in places.
WallShape LeaningWaves() {
  WallShape w;
  w.lean_mm = -1.0;
  w.wave_mm = 2.0;
  w.side_period_mm = 8.0;
  w.back_period_mm = 6.5;
  w.points = 161;
  return w;
}

// A 3-axis job on the floor of the pocket in `step`, with `tool` and `strategy` (its [tool] and
// [strategy] keys).
io::Job FloorJob(const std::string& step, const std::string& tool, const std::string& strategy) {
  return io::ParseJob(
      fmt::format(R"(machine = "{}"
feed_mm_min = 3000
[surface]
file = "{}"
face = "floor"
[tool]
{}
[strategy]
{}
)",
                  test::Source("samples/machines/mikron_ucp710_xyz.toml"), step, tool, strategy),
      test::Scratch("waving_pocket.toml"));
}

// Every plane_cc line of `setup` (planes normal . x = c, travelling along `along`): its pieces and
// the stretches it leaves out follow one another along the floor's section from one side of the
// floor to the other (each starts where the one before ends, within `tolerance` mm of the
// section's arc length), and each is as long as the section between its ends. Returns the lines.
std::map<long, std::vector<OnLine>> ExpectEachLineOnce(const io::SurfaceSetup& setup,
                                                       const TopoDS_Face& floor,
                                                       const Eigen::Vector3d& normal,
                                                       const Eigen::Vector3d& along,
                                                       double tolerance) {
  std::map<long, Section> sections;
  const auto lines = Lines(setup.passes, BRep_Tool::Surface(floor), normal, along, &sections);
  for (const auto& [key, l] : lines) {
    std::string all;
    for (const OnLine& o : l)
      all += fmt::format("\n  [{:.6f}, {:.6f}] {:.6f} mm: {}", o.from, o.to, o.length, o.what);
    SCOPED_TRACE(fmt::format("line {} mm:{}", static_cast<double>(key) * 1e-3, all));
    double at = 0.0, sum = 0.0;
    for (const OnLine& o : l) {
      EXPECT_NEAR(o.from, at, tolerance) << o.what;
      EXPECT_NEAR(o.length, o.to - o.from, tolerance) << o.what;
      at = o.to;
      sum += o.length;
    }
    const double section = sections.at(key).Length();
    EXPECT_NEAR(at, section, tolerance);
    EXPECT_NEAR(sum, section, tolerance * static_cast<double>(l.size()));
  }
  return lines;
}

// A flat end R2 along the planes y = 8.75 and 10.05 mm (plane_cc, travelling along x) across the
// floor's valley at x = 20. Where its bottom's edge touches the valley, the tool's path folds back
// (its tip moves against the travel as the contact point moves on), and the tool fits at points on
// either side of the fold from which its travel leads back into the valley. Each line is finished
// in two pieces, the valley and the two walls' sides left out, and these follow one another along
// the floor's section (OpenCASCADE's intersection of the floor and the plane) each as long as the
// section between its ends. The march of the contact point through the valley used to stop at
// such a point: the piece from there went straight back into the valley, whose stretch was marched
// back to the point on the other side, and so on (4 million trace steps, then an error).
TEST(CheckFaces, AFlatEndMarchesThroughAValleyWhereItsPathFoldsBack) {
  const Pocket p = MakePocket(LeaningWaves());
  const std::string step = test::WriteNamedFaces(
      {{p.floor, "floor"}, {p.left, "left"}, {p.right, "right"}, {p.back, "back"}},
      test::Scratch("leaning_pocket.stp"));
  const io::Job job = FloorJob(step, "kind = \"flat_end\"\nradius_mm = 2",
                               "kind = \"plane_cc\"\nplane_normal = [0, 1, 0]\ndirection = [1, 0, "
                               "0]\nstepover_mm = 1.3\nrange = [8.75, 10.05]");
  const io::SurfaceSetup setup = io::SetUpSurface(job, nullptr);
  const auto lines =
      ExpectEachLineOnce(setup, p.floor, Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitX(), 1e-4);
  ASSERT_EQ(lines.size(), 2u);
  for (const auto& [key, l] : lines) {
    SCOPED_TRACE(fmt::format("line {} mm", static_cast<double>(key) * 1e-3));
    int passes = 0, valley = 0;
    for (const OnLine& o : l) {
      if (o.what.rfind("pass", 0) == 0) {
        ++passes;
      } else if (o.from > 15.0 && o.to < 25.0) {
        ++valley;
      }
    }
    EXPECT_EQ(passes, 2);
    EXPECT_EQ(valley, 1);
    EXPECT_EQ(l.size(), 5u);
  }
}

// Balls R1 and R3 finishing the floor of the pocket whose walls lean into it and wave (plane_cc,
// along the side walls and towards the back one): every line's pieces and the stretches left out
// beside the walls follow one another along the floor's section, each as long as the section
// between its ends (1e-4 mm), and no wall goes into the ball by more than the check's tolerance
// in the middle of every 0.1 mm of every pass (points the trace did not check), by OpenCASCADE's
// distance.
TEST(CheckFaces, APocketWithWavingWallsLeaningInIsFinishedOrLeftOutOnceAlongEveryLine) {
  const Pocket p = MakePocket(LeaningWaves());
  const Walls walls = {{p.left, "left"}, {p.right, "right"}, {p.back, "back"}};
  const std::string step = test::WriteNamedFaces({{p.floor, "floor"}, walls[0], walls[1], walls[2]},
                                                 test::Scratch("leaning_pocket.stp"));
  for (const double r : {1.0, 3.0}) {
    for (const bool along_y : {true, false}) {
      SCOPED_TRACE(fmt::format("ball R{}, planes {} = const", r, along_y ? "x" : "y"));
      const io::Job job = FloorJob(
          step, fmt::format("kind = \"ball_end\"\nradius_mm = {}", r),
          along_y ? "kind = \"plane_cc\"\nplane_normal = [1, 0, 0]\ndirection = [0, 1, 0]\n"
                    "stepover_mm = 1.3"
                  : "kind = \"plane_cc\"\nplane_normal = [0, 1, 0]\ndirection = [1, 0, 0]\n"
                    "stepover_mm = 1.3");
      const io::SurfaceSetup setup = io::SetUpSurface(job, nullptr);
      ASSERT_GE(setup.passes.passes.size(), 25u);
      const Eigen::Vector3d normal = along_y ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
      const Eigen::Vector3d along = along_y ? Eigen::Vector3d::UnitY() : Eigen::Vector3d::UnitX();
      const auto lines = ExpectEachLineOnce(setup, p.floor, normal, along, 1e-4);
      // Beside the walls, where their tops wave over the floor, lines are cut into pieces.
      std::size_t most = 0;
      for (const auto& [key, l] : lines) most = std::max(most, l.size());
      EXPECT_GE(most, 9u);
      const DeepestWall d = DeepestAlongPasses(setup, r, walls, 0.1);
      EXPECT_LE(d.depth, job.surface->check_tolerance_mm) << d.where;
      EXPECT_GT(d.depth, -0.01) << d.where;  // the passes come to the walls
    }
  }
}

}  // namespace
}  // namespace dtis
