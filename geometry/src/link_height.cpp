#include "dtis/geometry/link_height.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <vector>

#include "dtis/geometry/face_surface.hpp"

namespace dtis::geometry {
namespace {

using V2 = Eigen::Vector2d;

// A vertical axis: its Z component within this of 1.
constexpr double kVertical = 1e-12;

// The links' mesh of the face: coarser than the reports' (its deflection is added to every
// height), and small enough to scan once per link.
FaceMeshOptions LinkMeshOptions() {
  FaceMeshOptions o;
  o.relative_deflection = 1e-3;
  o.angle_deg = 10.0;
  o.max_triangles = 50000;
  return o;
}

double PointSegment(const V2& p, const V2& a, const V2& b) {
  const V2 ab = b - a;
  const double len2 = ab.squaredNorm();
  const double t = len2 > 0.0 ? std::clamp((p - a).dot(ab) / len2, 0.0, 1.0) : 0.0;
  return (a + t * ab - p).norm();
}

double Cross(const V2& a, const V2& b) { return a.x() * b.y() - a.y() * b.x(); }

// Distance between the segments ab and cd in the plane (0 where they cross).
double SegmentSegment(const V2& a, const V2& b, const V2& c, const V2& d) {
  const double d1 = Cross(b - a, c - a), d2 = Cross(b - a, d - a);
  const double d3 = Cross(d - c, a - c), d4 = Cross(d - c, b - c);
  if (((d1 > 0.0 && d2 < 0.0) || (d1 < 0.0 && d2 > 0.0)) &&
      ((d3 > 0.0 && d4 < 0.0) || (d3 < 0.0 && d4 > 0.0))) {
    return 0.0;
  }
  return std::min(
      {PointSegment(a, c, d), PointSegment(b, c, d), PointSegment(c, a, b), PointSegment(d, a, b)});
}

bool InTriangle(const V2& p, const V2& a, const V2& b, const V2& c) {
  const double s1 = Cross(b - a, p - a), s2 = Cross(c - b, p - b), s3 = Cross(a - c, p - c);
  return (s1 >= 0.0 && s2 >= 0.0 && s3 >= 0.0) || (s1 <= 0.0 && s2 <= 0.0 && s3 <= 0.0);
}

// The segment pq widened by r, in X and Y: what the tool covers during a traverse.
struct Footprint {
  V2 p, q;
  double r;
  bool Covers(const V2& x) const { return PointSegment(x, p, q) <= r; }
  // Whether the triangle abc comes within r of the segment.
  bool Touches(const V2& a, const V2& b, const V2& c) const {
    if (InTriangle(p, a, b, c)) return true;
    return SegmentSegment(p, q, a, b) <= r || SegmentSegment(p, q, b, c) <= r ||
           SegmentSegment(p, q, c, a) <= r;
  }
};

// The highest point within the footprint of the triangle abc (the plane through its vertices),
// or minus infinity: a triangle only partly in it is split in four, down to sides of an eighth
// of the tool's radius (a large triangle on a slope would otherwise count its far, high corner).
double HighestIn(const Footprint& f, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                 const Eigen::Vector3d& c, int depth) {
  const V2 a2 = a.head<2>(), b2 = b.head<2>(), c2 = c.head<2>();
  if (f.Covers(a2) && f.Covers(b2) && f.Covers(c2)) return std::max({a.z(), b.z(), c.z()});
  if (!f.Touches(a2, b2, c2)) return -std::numeric_limits<double>::infinity();
  const double size = std::max({(a2 - b2).norm(), (b2 - c2).norm(), (c2 - a2).norm()});
  if (depth == 0 || size <= 0.125 * f.r) return std::max({a.z(), b.z(), c.z()});
  const Eigen::Vector3d ab = 0.5 * (a + b), bc = 0.5 * (b + c), ca = 0.5 * (c + a);
  return std::max({HighestIn(f, a, ab, ca, depth - 1), HighestIn(f, ab, b, bc, depth - 1),
                   HighestIn(f, ca, bc, c, depth - 1), HighestIn(f, ab, bc, ca, depth - 1)});
}

}  // namespace

struct LinkHeights::Data {
  double top_z = 0.0;
  double deflection = 0.0;
  struct Triangle {
    std::array<Eigen::Vector3d, 3> p;
    V2 lo, hi;   // X, Y box
    double top;  // highest vertex
  };
  std::vector<Triangle> triangles;
};

LinkHeights::LinkHeights(std::vector<NamedFace> faces, double tool_radius_mm, double clearance_mm)
    : faces_(std::move(faces)), tool_radius_mm_(tool_radius_mm), clearance_mm_(clearance_mm) {}

LinkHeights::~LinkHeights() = default;

const LinkHeights::Data& LinkHeights::Get() const {
  std::call_once(once_, [this] {
    auto d = std::make_unique<Data>();
    d->top_z = -std::numeric_limits<double>::infinity();
    for (const NamedFace& f : faces_) d->top_z = std::max(d->top_z, FaceBox(f.face).second.z());
    const FaceMesh mesh = MeshFaces(faces_, LinkMeshOptions());
    d->deflection = mesh.deflection_mm;
    d->triangles.reserve(mesh.triangles.size());
    for (const auto& t : mesh.triangles) {
      Data::Triangle tri;
      tri.top = -std::numeric_limits<double>::infinity();
      for (int k = 0; k < 3; ++k) {
        tri.p[static_cast<std::size_t>(k)] = mesh.vertices[static_cast<std::size_t>(t[k])];
        tri.top = std::max(tri.top, tri.p[static_cast<std::size_t>(k)].z());
      }
      tri.lo = tri.p[0].head<2>().cwiseMin(tri.p[1].head<2>()).cwiseMin(tri.p[2].head<2>());
      tri.hi = tri.p[0].head<2>().cwiseMax(tri.p[1].head<2>()).cwiseMax(tri.p[2].head<2>());
      d->triangles.push_back(tri);
    }
    data_ = std::move(d);
  });
  return *data_;
}

double LinkHeights::TopZ() const { return Get().top_z; }

double LinkHeights::TraverseZ(const Pose& from, const Pose& to) const {
  const Eigen::Vector3d out1 = from.tip + from.axis * clearance_mm_;
  const Eigen::Vector3d out2 = to.tip + to.axis * clearance_mm_;
  const double floor = std::max(out1.z(), out2.z());
  const Data& d = Get();
  double z = d.top_z + clearance_mm_;
  if (from.axis.z() >= 1.0 - kVertical && to.axis.z() >= 1.0 - kVertical) {
    // The highest point of the triangles within R of the traverse, in X and Y.
    const Footprint f{out1.head<2>(), out2.head<2>(), tool_radius_mm_};
    const V2 lo = f.p.cwiseMin(f.q).array() - f.r, hi = f.p.cwiseMax(f.q).array() + f.r;
    double highest = -std::numeric_limits<double>::infinity();
    constexpr int kMaxSplits = 6;
    for (const Data::Triangle& t : d.triangles) {
      if (t.top <= highest || (t.lo.array() > hi.array()).any() ||
          (t.hi.array() < lo.array()).any()) {
        continue;
      }
      highest = std::max(highest, HighestIn(f, t.p[0], t.p[1], t.p[2], kMaxSplits));
    }
    // Nothing of the face under the traverse: it stays at the height it backs off to.
    z = std::isfinite(highest) ? std::min(z, highest + d.deflection + clearance_mm_) : floor;
  }
  return std::max(z, floor);
}

}  // namespace dtis::geometry
