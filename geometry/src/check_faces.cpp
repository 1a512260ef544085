#include "dtis/geometry/check_faces.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <utility>

#include "dtis/geometry/face_surface.hpp"

namespace dtis::geometry {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;

// Samples per side of a block, whose box decides whether its samples are looked at.
constexpr int kBlock = 16;
// Samples per face, at most: past this the spacing grows.
constexpr double kMaxSamples = 1e6;  // about 41 MB

// The distance to the tool in its half-plane (rho >= 0, z), and that distance's gradient there.
struct Profile {
  double d;
  Vector2d grad;  // (d/drho, d/dz)
};

Profile ToolProfile(const Tool& tool, double length, double rho, double z) {
  const double r = tool.corner_radius, big_r = tool.TorusRadius(), outer = tool.radius;
  // The bottom: the segment (0..R, z = r) widened by r.
  const Vector2d foot(std::clamp(rho, 0.0, big_r), r);
  Vector2d away = Vector2d(rho, z) - foot;
  const double to_foot = away.norm();
  Profile bottom{to_foot - r, to_foot > 0.0 ? Vector2d(away / to_foot) : Vector2d(0.0, -1.0)};
  // The body: |rho| <= R + r, r <= z <= length (the half-plane's mirror makes rho = 0 inside).
  const double dx = rho - outer;
  const double dz = std::max(r - z, z - length);
  const double sz = z < 0.5 * (r + length) ? -1.0 : 1.0;  // which end dz measures to
  Profile body;
  if (dx > 0.0 || dz > 0.0) {
    const Vector2d out(std::max(dx, 0.0), sz * std::max(dz, 0.0));
    body = {out.norm(), out.normalized()};
  } else if (dx > dz) {
    body = {dx, Vector2d(1.0, 0.0)};
  } else {
    body = {dz, Vector2d(0.0, sz)};
  }
  if (!(length > r)) return bottom;  // (a tool shorter than its corner: the bottom alone)
  return bottom.d < body.d ? bottom : body;
}

// The point q relative to the tool: its distance and (3D) gradient.
struct ToolDistance {
  double d;
  Vector3d grad;
};

ToolDistance Measure(const Tool& tool, double length, const Vector3d& tip, const Vector3d& axis,
                     const Vector3d& q) {
  const Vector3d rel = q - tip;
  const double z = rel.dot(axis);
  const Vector3d across = rel - z * axis;
  const double rho = across.norm();
  const Profile p = ToolProfile(tool, length, rho, z);
  const Vector3d out = rho > 0.0 ? Vector3d(across / rho) : Vector3d::Zero();
  return {p.d, p.grad.x() * out + p.grad.y() * axis};
}

struct Box {
  Vector3d lo = Vector3d::Constant(INFINITY), hi = Vector3d::Constant(-INFINITY);
  void Add(const Vector3d& p) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  Vector3d Centre() const { return 0.5 * (lo + hi); }
  double HalfDiagonal() const { return 0.5 * (hi - lo).norm(); }
  void Add(const Box& b) {
    lo = lo.cwiseMin(b.lo);
    hi = hi.cwiseMax(b.hi);
  }
};

// A bounding-volume hierarchy of boxes (items 0..n-1): each node splits its items at the median
// of their centres along its box's longest side, down to leaves of at most kLeaf items.
class BoxTree {
 public:
  BoxTree() = default;
  explicit BoxTree(const std::vector<Box>& boxes) : boxes_(boxes) {
    order_.resize(boxes.size());
    for (std::size_t i = 0; i < order_.size(); ++i) order_[i] = static_cast<int>(i);
    if (order_.empty()) return;
    nodes_.resize(1);
    Split(0, 0, static_cast<int>(order_.size()));
  }

  // Calls visit(item) for every item whose node boxes all pass `near(centre, half_diagonal)`
  // (false prunes the node), the item's own box included.
  template <typename Near, typename Visit>
  void Query(const Near& near, const Visit& visit) const {
    if (nodes_.empty()) return;
    int stack[64];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const Node& n = nodes_[static_cast<std::size_t>(stack[--top])];
      if (!near(n.centre, n.half_diagonal)) continue;
      if (n.left < 0) {
        for (int i = n.first; i < n.first + n.count; ++i) {
          const Box& b = boxes_[static_cast<std::size_t>(order_[static_cast<std::size_t>(i)])];
          if (near(b.Centre(), b.HalfDiagonal())) visit(order_[static_cast<std::size_t>(i)]);
        }
        continue;
      }
      stack[top++] = n.left;
      stack[top++] = n.left + 1;
    }
  }

 private:
  static constexpr int kLeaf = 4;
  struct Node {
    Vector3d centre;
    double half_diagonal;
    int left = -1;  // the children are left and left + 1; -1 for a leaf
    int first = 0, count = 0;
  };

  // Fills node `at` with items [first, first + count) of order_, splitting it while it holds
  // more than a leaf.
  void Split(std::size_t at, int first, int count) {
    Box box;
    for (int i = first; i < first + count; ++i) {
      box.Add(boxes_[static_cast<std::size_t>(order_[static_cast<std::size_t>(i)])]);
    }
    nodes_[at] = {box.Centre(), box.HalfDiagonal(), -1, first, count};
    if (count <= kLeaf) return;
    int axis = 0;
    (box.hi - box.lo).maxCoeff(&axis);
    const auto begin = order_.begin() + first, end = begin + count, mid = begin + count / 2;
    std::nth_element(begin, mid, end, [&](int a, int b) {
      return boxes_[static_cast<std::size_t>(a)].Centre()[axis] <
             boxes_[static_cast<std::size_t>(b)].Centre()[axis];
    });
    const std::size_t left = nodes_.size();
    nodes_.resize(left + 2);
    nodes_[at].left = static_cast<int>(left);
    Split(left, first, count / 2);
    Split(left + 1, first + count / 2, count - count / 2);
  }

  std::vector<Box> boxes_;
  std::vector<int> order_;
  std::vector<Node> nodes_;
};

}  // namespace

double ToolSignedDistance(const Tool& tool, double length, double rho, double z) {
  return ToolProfile(tool, length, std::abs(rho), z).d;
}

// A face's samples: a grid in (u, v), row-major (u by v), with whether each lies on the face.
struct CheckFaces::Sampled {
  int nu = 0, nv = 0;
  std::vector<Vector3d> p;
  std::vector<Vector2d> uv;
  std::vector<std::uint8_t> on;
  double cover = 0.0;  // every point of the face lies within this of a sample (mm)
  struct Block {
    int i0, i1, j0, j1;  // samples [i0, i1) x [j0, j1)
  };
  std::vector<Block> blocks;
  BoxTree block_tree;  // the blocks' boxes (item k: blocks[k])
  // A trimmed face's loops, sampled a sixteenth of the grid's spacing apart: the descent stops at
  // a loop, so the deepest point on one (the rim of a hole) is found among these. Blocks of 64
  // consecutive points ([i0, i1)).
  std::vector<Vector3d> rim;
  std::vector<Vector2d> rim_uv;
  std::vector<Block> rim_blocks;
  BoxTree rim_tree;  // item k: rim_blocks[k]
};

struct CheckFaces::Tree {
  BoxTree faces;
};

struct CheckFaces::Face {
  NamedFace named;
  Box box;  // the face's bounding box
  mutable std::once_flag once;
  mutable std::unique_ptr<Sampled> samples;
  mutable std::mutex eval_mutex;  // guards `surface` (its evaluation cache)
  mutable std::unique_ptr<FaceSurface> surface;
};

CheckFaces::CheckFaces(std::vector<NamedFace> faces, const Tool& tool, double length_mm,
                       double tolerance_mm)
    : tool_(tool), length_mm_(length_mm), tolerance_mm_(tolerance_mm) {
  spacing_mm_ = std::clamp(0.25 * tool.radius, 0.02, 1.0);
  for (NamedFace& f : faces) {
    auto face = std::make_shared<Face>();
    const auto [lo, hi] = FaceBox(f.face);
    face->box.Add(lo);
    face->box.Add(hi);
    face->named = std::move(f);
    faces_.push_back(std::move(face));
  }
  BuildTree();
}

CheckFaces::~CheckFaces() = default;

void CheckFaces::BuildTree() {
  std::vector<Box> boxes;
  Box all;
  for (const auto& f : faces_) {
    boxes.push_back(f->box);
    all.Add(f->box);
  }
  lo_ = all.lo;
  hi_ = all.hi;
  auto tree = std::make_shared<Tree>();
  tree->faces = BoxTree(boxes);
  tree_ = std::move(tree);
}

CheckFaces CheckFaces::Without(std::size_t except) const {
  CheckFaces less = *this;
  less.faces_.erase(less.faces_.begin() + static_cast<std::ptrdiff_t>(except));
  less.BuildTree();
  return less;
}

double CheckFaces::Displacement(const Vector3d& tip_a, const Vector3d& axis_a,
                                const Vector3d& tip_b, const Vector3d& axis_b) const {
  const double moved = (tip_b - tip_a).norm();
  const double turn = (axis_b - axis_a).norm();
  if (!(turn > 0.0) || faces_.empty()) return moved;
  // Only the tool's points within a millimetre of the faces' box can come near a face: those
  // whose point of the axis at their height lies in the box widened by the tool's radius and a
  // millimetre. How far up the axis from the tip that reaches, at either pose (the ray through
  // the widened box, by its slabs); a point at distance l from the tip moves by at most l times
  // the chord between the axes.
  const double outer = tool_.radius;
  const Vector3d lo = lo_ - Vector3d::Constant(outer + 1.0),
                 hi = hi_ + Vector3d::Constant(outer + 1.0);
  const auto reach_up = [&](const Vector3d& tip, const Vector3d& axis) {
    double t0 = 0.0, t1 = length_mm_;
    for (int i = 0; i < 3; ++i) {
      if (std::abs(axis[i]) < 1e-12) {
        if (tip[i] < lo[i] || tip[i] > hi[i]) return 0.0;
        continue;
      }
      double a = (lo[i] - tip[i]) / axis[i], b = (hi[i] - tip[i]) / axis[i];
      if (a > b) std::swap(a, b);
      t0 = std::max(t0, a);
      t1 = std::min(t1, b);
    }
    return t1 >= t0 ? t1 : 0.0;
  };
  const double up = std::max(reach_up(tip_a, axis_a), reach_up(tip_b, axis_b));
  return moved + std::hypot(up, outer) * turn;
}

const CheckFaces::Sampled& CheckFaces::Samples(const Face& face) const {
  std::call_once(face.once, [&] {
    face.surface = std::make_unique<FaceSurface>(face.named.face, face.named.where);
    const FaceSurface& s = *face.surface;
    auto out = std::make_unique<Sampled>();
    // The face's extent along u and along v: the longest of 9 iso-lines, at 64 points each.
    const auto extent = [&](bool along_u) {
      double longest = 0.0;
      for (int k = 0; k <= 8; ++k) {
        double len = 0.0;
        Vector3d prev;
        for (int i = 0; i <= 64; ++i) {
          const double a = i / 64.0, b = k / 8.0;
          const double u = s.U0() + (along_u ? a : b) * (s.U1() - s.U0());
          const double v = s.V0() + (along_u ? b : a) * (s.V1() - s.V0());
          const Vector3d p = s.Point(u, v);
          if (i > 0) len += (p - prev).norm();
          prev = p;
        }
        longest = std::max(longest, len);
      }
      return longest;
    };
    const double lu = extent(true), lv = extent(false);
    double h = spacing_mm_;
    while ((lu / h + 2.0) * (lv / h + 2.0) > kMaxSamples) h *= 1.25;
    out->nu = std::max(2, static_cast<int>(std::ceil(lu / h)) + 1);
    out->nv = std::max(2, static_cast<int>(std::ceil(lv / h)) + 1);
    const std::size_t n = static_cast<std::size_t>(out->nu) * static_cast<std::size_t>(out->nv);
    out->p.resize(n);
    out->uv.resize(n);
    out->on.resize(n);
    for (int i = 0; i < out->nu; ++i) {
      for (int j = 0; j < out->nv; ++j) {
        const std::size_t k = static_cast<std::size_t>(i) * out->nv + j;
        const double u = s.U0() + (s.U1() - s.U0()) * i / (out->nu - 1);
        const double v = s.V0() + (s.V1() - s.V0()) * j / (out->nv - 1);
        out->uv[k] = Vector2d(u, v);
        out->p[k] = s.Point(u, v);
        out->on[k] = s.Inside(u, v) ? 1 : 0;
      }
    }
    // The covering radius: half the largest cell diagonal (the cells are nearly flat at this
    // spacing; a tenth more for their bend).
    double cover = 0.0;
    for (int i = 0; i + 1 < out->nu; ++i) {
      for (int j = 0; j + 1 < out->nv; ++j) {
        const std::size_t k = static_cast<std::size_t>(i) * out->nv + j;
        const std::size_t across = k + static_cast<std::size_t>(out->nv) + 1;
        const std::size_t up = k + static_cast<std::size_t>(out->nv);
        cover = std::max(
            {cover, (out->p[across] - out->p[k]).norm(), (out->p[up] - out->p[k + 1]).norm()});
      }
    }
    out->cover = 0.55 * cover;
    std::vector<Box> block_boxes;
    for (int i0 = 0; i0 < out->nu; i0 += kBlock) {
      for (int j0 = 0; j0 < out->nv; j0 += kBlock) {
        const Sampled::Block b{i0, std::min(out->nu, i0 + kBlock + 1), j0,
                               std::min(out->nv, j0 + kBlock + 1)};
        Box box;
        bool any = false;
        for (int i = b.i0; i < b.i1; ++i) {
          for (int j = b.j0; j < b.j1; ++j) {
            const std::size_t k = static_cast<std::size_t>(i) * out->nv + j;
            box.Add(out->p[k]);
            any = any || out->on[k];
          }
        }
        if (!any) continue;
        out->blocks.push_back(b);
        block_boxes.push_back(box);
      }
    }
    out->block_tree = BoxTree(block_boxes);
    if (s.Trimmed()) {
      // The loops, refined until their chords are a sixteenth of the grid's spacing.
      int per_edge = 64;
      for (int round = 0; round < 2; ++round) {
        double longest = 0.0;
        out->rim.clear();
        out->rim_uv.clear();
        for (const auto& loop : s.Boundary(per_edge)) {
          for (std::size_t k = 0; k < loop.size(); ++k) {
            out->rim_uv.push_back(loop[k]);
            out->rim.push_back(s.Point(loop[k].x(), loop[k].y()));
            if (k > 0) {
              longest = std::max(longest, (out->rim.back() - out->rim[out->rim.size() - 2]).norm());
            }
          }
        }
        const double wanted = h / 16.0;
        if (longest <= wanted) break;
        per_edge = std::min(20000, static_cast<int>(std::ceil(per_edge * longest / wanted)));
      }
      std::vector<Box> rim_boxes;
      for (std::size_t i0 = 0; i0 < out->rim.size(); i0 += 64) {
        const std::size_t i1 = std::min(out->rim.size(), i0 + 64);
        Box box;
        for (std::size_t i = i0; i < i1; ++i) box.Add(out->rim[i]);
        out->rim_blocks.push_back({static_cast<int>(i0), static_cast<int>(i1), 0, 0});
        rim_boxes.push_back(box);
      }
      out->rim_tree = BoxTree(rim_boxes);
    }
    face.samples = std::move(out);
  });
  return *face.samples;
}

std::optional<CheckFaces::Hit> CheckFaces::Into(const Vector3d& tip, const Vector3d& axis) const {
  return Around(tip, axis, 0.0).hit;
}

CheckFaces::Near CheckFaces::Around(const Vector3d& tip, const Vector3d& axis,
                                    double reach_mm) const {
  Near out;
  out.clearance_mm = reach_mm;
  std::optional<Hit>& deepest = out.hit;
  const auto record = [&](const Face& face, double d, const Vector3d& at, const Vector2d& uv) {
    out.clearance_mm = std::min(out.clearance_mm, d);
    if (-d > tolerance_mm_ && (!deepest || -d > deepest->depth_mm)) {
      deepest = Hit{-d, at, uv, face.named.where};
    }
  };
  const auto distance = [&](const Vector3d& q) {
    return Measure(tool_, length_mm_, tip, axis, q).d;
  };
  std::vector<int> near_faces;
  // A box within `reach_mm` of the tool: the tool lies within R + r of the segment of its axis
  // from the tip up its length, and every point of the box within its half diagonal of the
  // centre.
  tree_->faces.Query(
      [&](const Vector3d& centre, double half) { return distance(centre) <= half + reach_mm; },
      [&](int k) { near_faces.push_back(k); });
  std::sort(near_faces.begin(), near_faces.end());  // (in the list's order, as before)
  for (const int near_face : near_faces) {
    const Face& face = *faces_[static_cast<std::size_t>(near_face)];
    const Sampled& s = Samples(face);
    struct Seed {
      double d;
      std::size_t k;
    };
    std::vector<Seed> seeds;
    s.block_tree.Query([&](const Vector3d& centre,
                           double half) { return distance(centre) <= half + s.cover + reach_mm; },
                       [&](int index) {
                         const Sampled::Block& b = s.blocks[static_cast<std::size_t>(index)];
                         Seed best{INFINITY, 0};
                         for (int i = b.i0; i < b.i1; ++i) {
                           for (int j = b.j0; j < b.j1; ++j) {
                             const std::size_t k = static_cast<std::size_t>(i) * s.nv + j;
                             if (!s.on[k]) continue;
                             const double d = distance(s.p[k]);
                             if (d < best.d) best = {d, k};
                           }
                         }
                         if (best.d < -tolerance_mm_)
                           record(face, best.d, s.p[best.k], s.uv[best.k]);
                         if (best.d < s.cover) {
                           seeds.push_back(best);
                         } else {
                           // Every point of the face in the block's cells lies within `cover` of a
                           // sample.
                           out.clearance_mm = std::min(out.clearance_mm, best.d - s.cover);
                         }
                       });
    s.rim_tree.Query(
        [&](const Vector3d& centre, double half) { return distance(centre) <= half + reach_mm; },
        [&](int index) {
          const Sampled::Block& b = s.rim_blocks[static_cast<std::size_t>(index)];
          for (int i = b.i0; i < b.i1; ++i) {
            const auto k = static_cast<std::size_t>(i);
            record(face, distance(s.rim[k]), s.rim[k], s.rim_uv[k]);
          }
        });
    if (seeds.empty()) continue;
    // From each seed, descend on the exact face: a step along the distance's gradient projected
    // onto the tangent plane, mapped to (u, v) and projected onto the UV box (the deepest point
    // may lie on a side: the top edge of a wall), halved until the distance falls.
    std::lock_guard lock(face.eval_mutex);
    const FaceSurface& surface = *face.surface;
    for (const Seed& seed : seeds) {
      Vector2d uv = s.uv[seed.k];
      Vector3d q = s.p[seed.k];
      double d = seed.d;
      double step = s.cover;
      for (int it = 0; it < 60 && step > 1e-9 && d >= -tolerance_mm_; ++it) {
        SurfaceDerivatives der;
        surface.D2(uv.x(), uv.y(), &der);
        const ToolDistance here = Measure(tool_, length_mm_, tip, axis, der.p);
        Eigen::Matrix<double, 3, 2> jac;
        jac << der.su, der.sv;
        const Vector2d g = jac.transpose() * here.grad;
        const Eigen::Matrix2d metric = jac.transpose() * jac;
        Vector2d dir = -metric.ldlt().solve(g);
        const double len = (jac * dir).norm();
        if (!(len > 0.0) || !dir.allFinite()) break;
        dir /= len;  // a unit step in space
        bool moved = false;
        while (step > 1e-9) {
          // Projected onto the UV box: along a side where the deepest point lies on it.
          const Vector2d next(std::clamp(uv.x() + step * dir.x(), surface.U0(), surface.U1()),
                              std::clamp(uv.y() + step * dir.y(), surface.V0(), surface.V1()));
          if (next != uv && surface.Inside(next.x(), next.y())) {
            const Vector3d p = surface.Point(next.x(), next.y());
            const double dn = Measure(tool_, length_mm_, tip, axis, p).d;
            if (dn < d) {
              uv = next, q = p, d = dn;
              moved = true;
              step *= 1.5;
              break;
            }
          }
          step *= 0.5;
        }
        if (!moved) break;
      }
      record(face, d, q, uv);
    }
  }
  return out;
}

}  // namespace dtis::geometry
