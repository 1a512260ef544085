#include "dtis/strategies/strategy.hpp"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <optional>

#include "dtis/core/error.hpp"
#include "dtis/core/golden_section.hpp"
#include "dtis/geometry/angle.hpp"
#include "dtis/geometry/curve_path.hpp"
#include "dtis/strategies/axis_law.hpp"

namespace dtis::strategies {
namespace {

constexpr double kProbeMm = 1e-3;  // step used to tell an entry from an exit

// Passes shorter than this (mm) between two unreachable stretches, or before or after one, are
// left out with them.
constexpr double kMinPieceMm = 1e-3;

// A stretch of a crossing where the tool does not fit (OnGouge::kSkip), by arc length on its trace.
struct Gap {
  double s_begin = 0.0, s_end = 0.0;
  ContactPoint before;  // the last point where the tool fits
  ContactPoint after;   // the first where it fits again (resumes), else where the trace stopped
  bool resumes = false;
  double contact_mm = 0.0;  // of the contact point's path on the face through it
  std::string why;
  bool outside_bounds = false;  // the tip leaves the job's bounds: not reported as unreachable
  // Opened where the trace could not step on (a uv line, whose other end is not traced): it
  // closes only where the tool fits a whole march step on.
  bool stuck = false;
};

struct Candidate {
  int line = 0;
  PassConstraint constraint;
  ContactPoint start, end;
  double length = 0.0;
  double order = 0.0;  // position of the start along the travel, to sort passes of one line
  std::vector<Bridge> bridges;
  std::vector<double> knot_lines;  // arc lengths where the trace crosses a knot line of the face
  std::vector<Gap> gaps;  // sorted by arc length: the crossing's passes are the pieces between
  // The contact points the trace went through (at most a step apart): where the line was traced.
  std::vector<Eigen::Vector3d> trail;
  bool closed = false;  // a closed section of the face: it ends where it starts
};

class Builder {
 public:
  Builder(const geometry::FaceSurface& face, const geometry::Tool& tool,
          const Orientation& orientation, const StrategySpec& spec)
      : face_(face), tool_(tool), orientation_(orientation), spec_(spec) {
    side_ = DetermineSide();
    switch (tool_.kind) {
      case geometry::Tool::Kind::kBallEnd:
        max_curvature_ = 1.0 / tool_.radius;
        break;
      case geometry::Tool::Kind::kBullNose:
        max_curvature_ = 1.0 / tool_.corner_radius;
        break;
      case geometry::Tool::Kind::kFlatEnd:
        max_curvature_ = INFINITY;
        break;
    }
  }

  PassList Build() {
    PassList list;
    list.side = side_;
    list.stepover_mm = spec_.stepover_mm > 0.0
                           ? spec_.stepover_mm
                           : StepoverFromScallop(tool_, orientation_, spec_.scallop_mm);
    const std::vector<PassConstraint> lines = Lines(list.stepover_mm);
    std::vector<Candidate> found;
    for (std::size_t k = 0; k < lines.size(); ++k) {
      // Passes are taken line by line: once max_passes are found, later lines add none.
      if (spec_.max_passes > 0 && found.size() >= static_cast<std::size_t>(spec_.max_passes)) {
        break;
      }
      const std::size_t before = found.size();
      FindPasses(static_cast<int>(k), lines[k], &found);
      if (IsPlane()) {
        FindInteriorPasses(static_cast<int>(k), lines[k], &found);
      } else {
        FindPoleStart(static_cast<int>(k), lines[k], &found);
      }
      if (found.size() == before && spec_.range) {
        throw Error("{}: the strategy line {} misses the face ({}); the face spans {} here",
                    face_.Where(), k + 1, lines[k].Describe(), ExtentText());
      }
    }
    if (found.empty()) {
      throw Error(
          "{}: no pass of the {} strategy crosses the face{}", face_.Where(),
          StrategySpec::KindName(spec_.kind),
          refused_ ? fmt::format(" (passes could not start: {})", EvalStatusText(*refused_)) : "");
    }
    std::stable_sort(found.begin(), found.end(), [](const Candidate& a, const Candidate& b) {
      return a.line != b.line ? a.line < b.line : a.order < b.order;
    });
    // For each pass made, the stretch it rides over from the previous one (-1: none).
    std::vector<int> ridden;
    for (const Candidate& c : found) {
      const PassEvaluator e(face_, tool_, orientation_, side_, c.constraint);
      // The pieces of the crossing between its unreachable stretches, each a pass.
      // Whether it was made (not too short, not past max_passes); `rides`: the tool rides over
      // the stretch before it from the previous piece.
      const auto piece = [&](const ContactPoint& from, double s0, const ContactPoint& to, double s1,
                             bool rides) {
        if (s1 - s0 < kMinPieceMm) return false;
        if (spec_.max_passes > 0 && static_cast<int>(list.passes.size()) == spec_.max_passes) {
          return false;
        }
        std::vector<Bridge> bridges;
        for (Bridge b : c.bridges) {
          if (b.s_start < s0 || b.s_exit > s1) continue;
          for (double* x : {&b.s_start, &b.s_in, &b.s_out, &b.s_exit}) *x -= s0;
          bridges.push_back(b);
        }
        std::vector<double> knot_lines;
        for (const double k : c.knot_lines) {
          if (k > s0 && k < s1) knot_lines.push_back(k - s0);
        }
        list.passes.push_back(std::make_unique<SurfacePass>(
            e, static_cast<int>(list.passes.size()) + 1, from, to, s1 - s0, spec_.newton,
            std::move(bridges), std::move(knot_lines)));
        list.passes.back()->SetRidesOverFromPrevious(rides);
        ridden.push_back(rides ? static_cast<int>(list.unreachable.size()) - 1 : -1);
        return true;
      };
      ContactPoint from = c.start;
      double s0 = 0.0;
      bool open = true, rides = false;
      // The piece after a stretch, made if the tool rides over the stretch from the one before:
      // the stretch is then said to be ridden over.
      const auto piece_after = [&](const ContactPoint& to, double s1) {
        const bool made = piece(from, s0, to, s1, rides);
        if (made && rides) list.unreachable.back().ridden_over = true;
        return made;
      };
      for (const Gap& g : c.gaps) {
        const bool made = piece_after(g.before, g.s_begin);
        rides = made && g.resumes && !g.outside_bounds && RidesOver(g.before, g.after);
        if (!g.outside_bounds) {
          list.unreachable.push_back(
              {c.line + 1, g.before.p, g.after.p, g.contact_mm, g.resumes, false, g.why, {}});
        }
        if (!g.resumes) {
          open = false;
          break;
        }
        from = g.after;
        s0 = g.s_end;
      }
      if (open) piece_after(c.end, c.length);
    }
    if (list.passes.empty() && list.unreachable.empty() && !spec_.bounds) {
      // Every crossing shorter than a piece is (a line grazing the face's edge).
      throw Error("{}: no pass of the {} strategy crosses the face for more than {} mm",
                  face_.Where(), StrategySpec::KindName(spec_.kind), kMinPieceMm);
    }
    if (list.passes.empty() && list.unreachable.empty()) {
      const Eigen::Vector3d& lo = spec_.bounds->min;
      const Eigen::Vector3d& hi = spec_.bounds->max;
      const auto [face_lo, face_hi] = geometry::FaceBox(face_.Face());
      throw Error(
          "{}: no pass of the {} strategy keeps the tool tip within its bounds, ({}, {}, {}) to "
          "({}, {}, {}) mm; the face spans ({:.6g}, {:.6g}, {:.6g}) to ({:.6g}, {:.6g}, {:.6g}) mm",
          face_.Where(), StrategySpec::KindName(spec_.kind), lo.x(), lo.y(), lo.z(), hi.x(), hi.y(),
          hi.z(), face_lo.x(), face_lo.y(), face_lo.z(), face_hi.x(), face_hi.y(), face_hi.z());
    }
    if (list.passes.empty()) {
      const Unreachable& u = list.unreachable.front();
      throw Error(
          "{}: the tool fits nowhere along the {} strategy's passes (line {}, from ({:.6g}, "
          "{:.6g}, {:.6g}): {})",
          face_.Where(), StrategySpec::KindName(spec_.kind), u.line, u.from.x(), u.from.y(),
          u.from.z(), u.why);
    }
    if (orientation_.kind == Orientation::Kind::kTiltYaw && orientation_.axis_tolerance_rad > 0.0) {
      SmoothAxes(&list, ridden);
    }
    return list;
  }

 private:
  int FaceSign() const { return face_.Face().Orientation() == TopAbs_REVERSED ? -1 : 1; }

  int DetermineSide() const {
    if (spec_.side == StrategySpec::Side::kFace) return FaceSign();
    if (spec_.side == StrategySpec::Side::kReversed) return -FaceSign();
    // A face of a solid: its outside, where the material is not.
    if (spec_.bounds_solid) return FaceSign();
    double up = 0.0;
    geometry::SurfaceDerivatives d;
    ForGrid(16, true, [&](const Eigen::Vector2d& uv) {
      face_.D2(uv.x(), uv.y(), &d);
      const Eigen::Vector3d n = d.su.cross(d.sv);
      if (n.norm() > 0.0) up += n.z() / n.norm();
    });
    return up >= 0.0 ? 1 : -1;
  }

  // Calls visit(uv) at the (n + 1)^2 points of a regular grid over the face's UV box; with
  // inside_only, only at those in its (trimmed) domain.
  template <typename Visit>
  void ForGrid(int n, bool inside_only, Visit&& visit) const {
    for (int i = 0; i <= n; ++i) {
      for (int j = 0; j <= n; ++j) {
        const Eigen::Vector2d uv(face_.U0() + (face_.U1() - face_.U0()) * i / n,
                                 face_.V0() + (face_.V1() - face_.V0()) * j / n);
        if (!inside_only || face_.Inside(uv.x(), uv.y())) visit(uv);
      }
    }
  }

  // Plane strategies and leading_line choose the feed's orientation; uv lines have their own.
  bool IsPlane() const { return spec_.kind != StrategySpec::Kind::kUv; }
  bool IsGuide() const { return spec_.kind == StrategySpec::Kind::kLeadingLine; }

  // How far a pass goes along the strategy's direction of travel (negative: against it).
  double Along(const Candidate& c, const Eigen::Vector3d& direction) const {
    if (IsGuide()) return c.end.guide_t - c.start.guide_t;
    return IsPlane() ? (c.end.tip - c.start.tip).dot(direction) : 1.0;
  }

  std::string ExtentText() const {
    if (IsGuide()) return fmt::format("[{:.6g}, {:.6g}] mm of offset from the guide", lo_, hi_);
    return IsPlane() ? fmt::format("[{:.6g}, {:.6g}] mm along the plane normal", lo_, hi_)
                     : fmt::format("[{:.6g}, {:.6g}] in {}", lo_, hi_, spec_.along_u ? "v" : "u");
  }

  // How many lines `step` apart (in the lines' own unit) cover the face or the range: at most
  // StrategySpec::kMaxLines.
  void CheckLineCount(double stepover, double step) const {
    double count = 0.0;
    if (spec_.range) {
      const auto [first, last] = *spec_.range;
      count = std::floor((last - first) / step) + 1.0;
    } else if (IsGuide()) {
      count = std::floor(hi_ / step) - std::ceil(lo_ / step) + 1.0;
    } else {
      count = std::ceil((hi_ - lo_) / step);
    }
    if (count <= static_cast<double>(StrategySpec::kMaxLines)) return;
    const bool range = spec_.range.has_value();
    const std::string& key = range ? spec_.range_key : spec_.stepover_key;
    throw Error(
        "{}: {:.3g} strategy lines, {:.6g} mm apart across {}, more than the {} a face is traced "
        "with ({}); expected {}",
        key.empty() ? (range ? "range" : "stepover_mm") : key, count, stepover,
        range ? fmt::format("the range [{:g}, {:g}]{}", (*spec_.range)[0], (*spec_.range)[1],
                            IsPlane() ? " mm" : "")
              : ExtentText(),
        StrategySpec::kMaxLines, face_.Where(),
        range ? "a range across the face (it spans " + ExtentText() + ") or a larger stepover"
              : "a larger stepover_mm (or scallop_mm)");
  }

  std::vector<PassConstraint> Lines(double stepover) {
    PassConstraint base;
    base.normal = spec_.plane_normal;
    base.value = 0.0;
    std::vector<PassConstraint> lines;
    double step = stepover;
    if (IsPlane()) {
      base.kind = spec_.kind == StrategySpec::Kind::kPlaneCl ? PassConstraint::Kind::kPlaneCl
                  : IsGuide()                                ? PassConstraint::Kind::kGuide
                                                             : PassConstraint::Kind::kPlaneCc;
      base.guide = spec_.guide;
      // The face's extent along the normal, from a grid of (tip or contact) points.
      lo_ = INFINITY, hi_ = -INFINITY;
      ContactPoint c;
      EvalStatus why = EvalStatus::kOk;
      // Both feed orientations built once: a PassEvaluator copies the face (and its classifier).
      PassConstraint flipped = base;
      flipped.feed_sign = -base.feed_sign;
      const PassEvaluator along(face_, tool_, orientation_, side_, base);
      const PassEvaluator against(face_, tool_, orientation_, side_, flipped);
      ForGrid(40, true, [&](const Eigen::Vector2d& uv) {
        // The feed oriented along `direction` at this point (a tilted tip depends on it).
        EvalStatus st = along.Evaluate(uv, &c);
        if (st == EvalStatus::kOk && !IsGuide() && c.feed.dot(spec_.direction) < 0.0) {
          st = against.Evaluate(uv, &c);
        }
        if (st != EvalStatus::kOk) {
          why = st;
          return;
        }
        lo_ = std::min(lo_, c.g);
        hi_ = std::max(hi_, c.g);
      });
      if (!(lo_ <= hi_)) {
        throw Error("{}: no point of the face gives a cutter location: {}", face_.Where(),
                    EvalStatusText(why));
      }
    } else {
      base.kind = spec_.along_u ? PassConstraint::Kind::kIsoV : PassConstraint::Kind::kIsoU;
      lo_ = spec_.along_u ? face_.V0() : face_.U0();
      hi_ = spec_.along_u ? face_.V1() : face_.U1();
      // mm per parameter unit across the lines, averaged over the face.
      double sum = 0.0;
      int count = 0;
      geometry::SurfaceDerivatives d;
      ForGrid(16, false, [&](const Eigen::Vector2d& uv) {
        face_.D2(uv.x(), uv.y(), &d);
        sum += (spec_.along_u ? d.sv : d.su).norm();
        ++count;
      });
      base.iso_scale = sum / count;
      if (!(base.iso_scale > 0.0)) throw Error("{}: the face is degenerate", face_.Where());
      step = stepover / base.iso_scale;
    }
    CheckLineCount(stepover, step);
    std::vector<double> values;
    if (spec_.range) {
      const auto [first, last] = *spec_.range;
      for (int k = 0; first + k * step <= last + 1e-9 * (1.0 + std::abs(last)); ++k) {
        values.push_back(first + k * step);
      }
    } else if (IsGuide()) {
      // The guide itself, then offsets by whole stepovers to both sides, over the face.
      for (long k = static_cast<long>(std::ceil(lo_ / step)); static_cast<double>(k) * step <= hi_;
           ++k) {
        values.push_back(static_cast<double>(k) * step);
      }
    } else {
      const int n = std::max(1, static_cast<int>(std::ceil((hi_ - lo_) / step - 1e-9)));
      const double actual = (hi_ - lo_) / n;
      for (int k = 0; k < n; ++k) values.push_back(lo_ + (k + 0.5) * actual);
    }
    for (std::size_t k = 0; k < values.size(); ++k) {
      PassConstraint c = base;
      c.value = values[k];
      const bool reverse = spec_.mode == StrategySpec::PathMode::kZigzag && k % 2 == 1;
      c.feed_sign = reverse ? -1 : 1;
      lines.push_back(c);
    }
    return lines;
  }

  Eigen::Vector3d Direction(const PassConstraint& c) const {
    return spec_.direction * static_cast<double>(c.feed_sign);
  }

  [[noreturn]] void Fail(int line, const PassConstraint& c, double s, const Eigen::Vector2d& uv,
                         const std::string& what) const {
    throw Error(
        "{}, line {} ({}), arc length {:.6f} mm from the pass start, (u, v) = ({:.9g}, "
        "{:.9g}): {}",
        face_.Where(), line + 1, c.Describe(), s, uv.x(), uv.y(), what);
  }

  // Roots of the line on the face's boundary, each traced if the pass enters the face there.
  // For plane strategies both orientations of the feed are tried (with a tilted tool they are
  // different passes): each crossing of the face is traced from the root where its travel enters
  // the face, and kept if it goes along the strategy's direction.
  void FindPasses(int line, const PassConstraint& constraint, std::vector<Candidate>* out) const {
    const std::vector<int> signs =
        IsPlane() ? std::vector<int>{1, -1} : std::vector<int>{constraint.feed_sign};
    for (const int sign : signs) {
      PassConstraint c = constraint;
      c.feed_sign = sign;
      const PassEvaluator e(face_, tool_, orientation_, side_, c);
      for (const auto& loop : face_.Boundary(64)) {
        ContactPoint a, b;
        EvalStatus sa = EvalStatus::kStalled;
        for (std::size_t i = 0; i < loop.size(); ++i) {
          const EvalStatus sb = e.Evaluate(loop[i], &b);
          if (i > 0 && sa == EvalStatus::kOk && sb == EvalStatus::kOk &&
              ((a.g <= 0.0 && b.g > 0.0) || (a.g > 0.0 && b.g <= 0.0))) {
            Root(line, constraint, e, loop[i - 1], a.g, loop[i], out);
          }
          a = b;
          sa = sb;
        }
      }
    }
  }

  void Root(int line, const PassConstraint& constraint, const PassEvaluator& e, Eigen::Vector2d a,
            double ga, Eigen::Vector2d b, std::vector<Candidate>* out) const {
    const Eigen::Vector3d direction = Direction(constraint);
    const PassConstraint& c = e.Constraint();
    ContactPoint r;
    for (int it = 0; it < 80 && (b - a).norm() > 1e-15 * (1.0 + a.norm()); ++it) {
      const Eigen::Vector2d m = 0.5 * (a + b);
      if (e.Evaluate(m, &r) != EvalStatus::kOk) return;
      if ((r.g <= 0.0) == (ga <= 0.0)) {
        a = m, ga = r.g;
      } else {
        b = m;
      }
    }
    if (e.Evaluate(a, &r) != EvalStatus::kOk) return;
    const NewtonOptions& o = spec_.newton;
    EvalStatus status;
    ContactPoint fwd, back;
    int its = 0;
    const bool f_ok = e.Step(r, kProbeMm, o, &fwd, &status, &its) && e.Inside(fwd.uv);
    if (!f_ok) {
      // The pass leaves the face here (or only touches it), or cannot start: say why if no
      // pass is found at all.
      if (status != EvalStatus::kOk) refused_ = status;
      return;
    }
    ContactPoint start;
    if (!e.Inside(r.uv)) {
      start = Bisect(e, fwd, -1.0, kProbeMm);
    } else {
      // Walk back until outside, then bisect: the boundary crossing behind r.
      ContactPoint cur = r;
      double h = kProbeMm;
      bool found = false;
      for (int k = 0; k < 40; ++k) {
        if (!e.Step(cur, -h, o, &back, &status, &its)) return;
        if (!e.Inside(back.uv)) {
          start = Bisect(e, cur, -1.0, h);
          found = true;
          break;
        }
        cur = back;
        h = std::min(2.0 * h, spec_.newton.max_step_mm);
      }
      if (!found) return;  // an interior root: its pass is found from its own entry
    }
    Candidate cand;
    cand.line = line;
    cand.constraint = c;
    cand.start = start;
    Trace(e, &cand);
    cand.order = IsGuide() ? start.guide_t : start.tip.dot(direction);
    // Each crossing is traced from both ends (one per feed orientation): keep the one that goes
    // further along the strategy's direction (with a tilted tool, a crossing that runs across the
    // direction may go slightly against it both ways).
    // Iso lines travel towards increasing (or, reversed, decreasing) parameter: no choice here.
    const double along = Along(cand, direction);
    // With a tilted tool the two orientations are different passes (the tilt follows the feed)
    // whose ends lie within a few tool radii: keep the one that goes further along `direction`.
    const double near = 2.0 * tool_.radius + 1e-3;
    for (Candidate& other : *out) {
      if (other.line != line) continue;
      // The same crossing found again (not the other one leaving the same point of a seam).
      if ((other.start.tip - start.tip).norm() < 1e-6 &&
          (other.start.uv - start.uv).norm() < 1e-6 * (1.0 + start.uv.norm())) {
        return;
      }
      if (IsPlane() && (other.start.tip - cand.end.tip).norm() < near &&
          (other.end.tip - cand.start.tip).norm() < near && SameWay(other, cand)) {
        const double other_along = Along(other, direction);
        if (other_along >= along) return;
        other = cand;
        return;
      }
    }
    out->push_back(cand);
  }

  // Whether the trace's step from `cur` to `next` (about `h` mm) comes back to `start`, the point
  // a closed section was traced from: it crosses the plane through start across its tangent,
  // from behind, within the step.
  static bool Closes(const ContactPoint& start, const ContactPoint& cur, const ContactPoint& next,
                     double h) {
    return (cur.tip - start.tip).dot(start.tangent) < 0.0 &&
           (next.tip - start.tip).dot(start.tangent) >= 0.0 &&
           (next.tip - start.tip).norm() <= 2.0 * h && (cur.tip - start.tip).norm() <= 2.0 * h;
  }

  // The UV box's cells, each way, scanned for the roots of lines that cross no side of the face.
  static constexpr int kSeedGrid = 48;

  // The strategy's function with value 0 (g + value: a plane's normal . tip or . contact point,
  // a guide's offset) at the nodes of a kSeedGrid grid over the UV box, for one feed orientation
  // (NaN off the face or where nothing evaluates); computed once per face.
  const std::vector<double>& SeedGrid(const PassConstraint& constraint) const {
    std::vector<double>& grid = seed_grid_[constraint.feed_sign > 0 ? 0 : 1];
    if (!grid.empty()) return grid;
    PassConstraint zero = constraint;
    zero.value = 0.0;
    const PassEvaluator e(face_, tool_, orientation_, side_, zero);
    ContactPoint c;
    ForGrid(kSeedGrid, false, [&](const Eigen::Vector2d& uv) {
      grid.push_back(face_.Inside(uv.x(), uv.y()) && Evaluates(e, uv, &c) ? c.g : NAN);
    });
    return grid;
  }

  // Whether two traces between the same ends go the same way (not round the two sides of a
  // section cut at a seam): the middle of one's trail lies on the other's.
  bool SameWay(const Candidate& a, const Candidate& b) const {
    if (b.trail.empty()) return true;
    const Eigen::Vector3d& middle = b.trail[b.trail.size() / 2];
    const double near = spec_.newton.max_step_mm;
    for (const Eigen::Vector3d& q : a.trail) {
      if ((q - middle).squaredNorm() < near * near) return true;
    }
    return false;
  }

  // Whether a pass of line `line` traced so far went through contact point p.
  bool Traced(int line, const Eigen::Vector3d& p, const std::vector<Candidate>& found) const {
    const double near = spec_.newton.max_step_mm;
    for (const Candidate& c : found) {
      if (c.line != line) continue;
      for (const Eigen::Vector3d& q : c.trail) {
        if ((q - p).squaredNorm() < near * near) return true;
      }
    }
    return false;
  }

  // The passes of a plane or guide line that crosses no side of the face: a closed section (a
  // plane cutting a sphere in a circle that stays on it), or one that ends at poles (collapsed
  // edges of the UV box, which the boundary scan skips). The grid's cell sides are scanned for
  // the line's roots; from a root no pass of the line went through, the line is traced backwards:
  // if it comes back to the root it is a closed section, traced from there (and ending there);
  // otherwise the pass starts where the backward trace ended, unless a pass of the line already
  // starts or ends there (a line whose trace stopped where the tool could not go on).
  void FindInteriorPasses(int line, const PassConstraint& constraint,
                          std::vector<Candidate>* out) const {
    const std::vector<double>& grid = SeedGrid(constraint);
    const PassEvaluator e(face_, tool_, orientation_, side_, constraint);
    const auto node = [&](int i, int j) {
      return Eigen::Vector2d(face_.U0() + (face_.U1() - face_.U0()) * i / kSeedGrid,
                             face_.V0() + (face_.V1() - face_.V0()) * j / kSeedGrid);
    };
    const auto value = [&](int i, int j) {
      return grid[static_cast<std::size_t>(i * (kSeedGrid + 1) + j)] - constraint.value;
    };
    for (int i = 0; i <= kSeedGrid; ++i) {
      for (int j = 0; j <= kSeedGrid; ++j) {
        for (const auto& [di, dj] : {std::pair{1, 0}, std::pair{0, 1}}) {
          if (i + di > kSeedGrid || j + dj > kSeedGrid) continue;
          const double ga = value(i, j), gb = value(i + di, j + dj);
          if (!std::isfinite(ga) || !std::isfinite(gb) || (ga <= 0.0) == (gb <= 0.0)) continue;
          // The root on this side of the cell: regula falsi (Illinois) on the side's parameter.
          const Eigen::Vector2d a = node(i, j), b = node(i + di, j + dj);
          double ta = 0.0, tb = 1.0, fa = ga, fb = gb;
          int kept = 0;  // which end stayed the last time (-1: b, +1: a)
          ContactPoint r;
          bool ok = false;
          for (int it = 0; it < 60; ++it) {
            const double t = (ta * fb - tb * fa) / (fb - fa);
            if (e.Evaluate(a + (b - a) * t, &r) != EvalStatus::kOk) break;
            if (std::abs(r.g) <= 1e-9 || tb - ta <= 1e-15) {
              ok = true;
              break;
            }
            if ((r.g <= 0.0) == (fa <= 0.0)) {
              ta = t, fa = r.g;
              if (kept == -1) fb *= 0.5;
              kept = -1;
            } else {
              tb = t, fb = r.g;
              if (kept == 1) fa *= 0.5;
              kept = 1;
            }
          }
          if (!ok || !e.Inside(r.uv) || Traced(line, r.p, *out)) continue;
          TraceFromSeed(line, e, r, out);
        }
      }
    }
  }

  // FindInteriorPasses from root r of line `line` (evaluator e).
  void TraceFromSeed(int line, const PassEvaluator& e, const ContactPoint& r,
                     std::vector<Candidate>* out) const {
    PassConstraint reversed = e.Constraint();
    reversed.feed_sign = -reversed.feed_sign;
    const PassEvaluator back_e(face_, tool_, orientation_, side_, reversed);
    Candidate back;
    back.line = line;
    back.constraint = reversed;
    if (back_e.Evaluate(r.uv, &back.start, r.guide_t) != EvalStatus::kOk) return;
    Trace(back_e, &back, &back.start);
    Candidate cand;
    cand.line = line;
    cand.constraint = e.Constraint();
    if (back.closed) {
      cand.start = r;
      Trace(e, &cand, &cand.start);
    } else {
      // (The same point in (u, v) too: a section cut at a seam has two passes between the same
      // two points of it.)
      const double box = std::hypot(face_.U1() - face_.U0(), face_.V1() - face_.V0());
      const auto same = [&](const ContactPoint& p) {
        return (p.tip - back.end.tip).norm() < 1e-3 && (p.uv - back.end.uv).norm() < 1e-3 * box;
      };
      for (const Candidate& other : *out) {
        if (other.line == line && (same(other.start) || same(other.end))) return;
      }
      if (e.Evaluate(back.end.uv, &cand.start, back.end.guide_t) != EvalStatus::kOk) return;
      Trace(e, &cand);
    }
    cand.order = IsGuide() ? cand.start.guide_t : cand.start.tip.dot(Direction(cand.constraint));
    out->push_back(std::move(cand));
  }

  // A uv line from a collapsed edge of the UV box (a sphere's pole: the boundary scan skips it,
  // and the line has no root on the face's sides): its pass starts at the pole, at the first
  // parameter off it (by doubling from 1e-9 of the box) where the normal is defined.
  void FindPoleStart(int line, const PassConstraint& constraint,
                     std::vector<Candidate>* out) const {
    const int k = constraint.kind == PassConstraint::Kind::kIsoV ? 0 : 1;  // the running one
    const double lo = k == 0 ? face_.U0() : face_.V0(), hi = k == 0 ? face_.U1() : face_.V1();
    const double from = constraint.feed_sign > 0 ? lo : hi;
    const double inward = constraint.feed_sign > 0 ? 1.0 : -1.0;
    Eigen::Vector2d uv;
    uv[k] = from;
    uv[1 - k] = constraint.value;
    geometry::SurfaceDerivatives d;
    face_.D2(uv.x(), uv.y(), &d);
    if (!(std::min(d.su.norm(), d.sv.norm()) < 1e-9 * std::max(d.su.norm(), d.sv.norm()))) {
      return;
    }
    const PassEvaluator e(face_, tool_, orientation_, side_, constraint);
    Candidate cand;
    cand.line = line;
    cand.constraint = constraint;
    for (double t = 1e-9;; t *= 2.0) {
      if (t > 1e-3) return;
      uv[k] = from + inward * t * (hi - lo);
      if (e.Evaluate(uv, &cand.start) == EvalStatus::kOk) break;
    }
    if (!e.Inside(cand.start.uv)) return;
    for (const Candidate& other : *out) {
      if (other.line == line && (other.start.tip - cand.start.tip).norm() < 1e-3) return;
    }
    Trace(e, &cand);
    cand.order = 0.0;
    out->push_back(std::move(cand));
  }

  // The last point inside the face on the way from `inside` (sign +1: along the travel) towards a
  // point `chord_out` mm away that is outside.
  ContactPoint Bisect(const PassEvaluator& e, const ContactPoint& inside, double sign,
                      double chord_out) const {
    return e.LastInside(inside, sign, chord_out, spec_.newton);
  }

  // Traces a crossing from its start to where it leaves the face: its length, its bridges, and
  // where the tool does not fit (refused, or with OnGouge::kSkip recorded as gaps). Through a gap
  // the contact point is marched along the strategy's line on the face (MarchContact: the tool's
  // path may fold back there, where the tool's curvature exceeds the face's); each end of a gap is
  // found to 1/4096 of a step.
  // With `loop`, a closed section traced from that point: the trace ends when it comes back to it.
  void Trace(const PassEvaluator& e, Candidate* cand, const ContactPoint* loop = nullptr) const {
    const bool skip = spec_.on_gouge == StrategySpec::OnGouge::kSkip;
    ContactPoint cur = cand->start, next;
    double s = 0.0;
    EvalStatus status = EvalStatus::kOk;
    int its = 0;
    std::optional<Gap> gap;   // the one the trace is in
    Eigen::Vector2d gap_dir;  // the march's direction in (u, v) inside it
    std::string why;          // the last reason the tool did not fit
    // Whether the tool fits at p (arc length at); refuses the job unless gaps are skipped (or
    // the tip is only out of the job's bounds).
    const auto fits = [&](const ContactPoint& p, double at) {
      const std::optional<std::string> w = UnfitAt(p);
      if (!w) return true;
      if (!skip && *w != kOutsideBounds) Fail(cand->line, cand->constraint, at, p.uv, *w);
      why = *w;
      return false;
    };
    // Bisection on a step x in (0, h) from `from` (where the tool fits if `fits_from`, as `fit`
    // says) to a point where that changes: the points on either side of the change, to h / 4096,
    // and their steps. `step` takes x.
    struct Change {
      ContactPoint fit, unfit;
      double x_fit = 0.0, x_unfit = 0.0;
    };
    const auto change_by = [&](bool fits_from, double h, const ContactPoint& from, const auto& step,
                               const auto& fit) {
      double lo = 0.0, hi = h;
      ContactPoint p_lo = from, p_hi, p;
      bool have_hi = false;
      for (int k = 0; k < 12; ++k) {
        const double mid = 0.5 * (lo + hi);
        const bool ok = step(mid, &p);
        if (ok && fit(p) == fits_from) {
          lo = mid, p_lo = p;
        } else {
          hi = mid, p_hi = p, have_hi = ok;
        }
      }
      if (!have_hi) {
        have_hi = step(hi, &p_hi);
        if (!have_hi) p_hi = p_lo, hi = lo;
      }
      Change c;
      if (fits_from) {
        c = {p_lo, p_hi, lo, hi};
      } else {
        c = {p_hi, p_lo, hi, lo};
      }
      return c;
    };
    const auto change = [&](bool fits_from, double h, const ContactPoint& from, const auto& step) {
      return change_by(fits_from, h, from, step,
                       [this](const ContactPoint& p) { return !UnfitAt(p).has_value(); });
    };
    const auto tip_step = [&](const ContactPoint& from) {
      return [&e, &from, this](double x, ContactPoint* to) {
        EvalStatus st;
        int n = 0;
        return e.Step(from, x, spec_.newton, to, &st, &n);
      };
    };
    const auto open_gap = [&](const ContactPoint& p, double at) {
      gap.emplace();
      gap->before = p;
      gap->s_begin = at;
      gap->why = why;
      gap->outside_bounds = why == kOutsideBounds;
      gap_dir = p.duv.norm() > 0.0 ? Eigen::Vector2d(p.duv.normalized()) : Eigen::Vector2d::Zero();
    };
    const auto close_gap = [&](const ContactPoint& p, double at, bool resumes) {
      gap->after = p;
      gap->s_end = at;
      gap->resumes = resumes;
      cand->gaps.push_back(*gap);
      gap.reset();
    };
    // The line cannot be followed on from cur inside a gap: the crossing ends there, and what lies
    // beyond is traced from its other end (plane strategies) or left out.
    const auto end_in_gap = [&] {
      // A uv line is traced from one end only: what lies past here to where it leaves the face
      // is left out too.
      if (!IsPlane()) gap->contact_mm += RestOfIsoLine(cur, gap_dir);
      close_gap(cur, s, false);
      cand->end = cur;
      cand->length = s;
    };
    if (!fits(cur, s)) open_gap(cur, s);
    const double full = spec_.newton.max_step_mm;
    double h = full, gap_step = full;
    for (long k = 0;; ++k) {
      if (k > 4000000)
        Fail(cand->line, cand->constraint, s, cur.uv, "the pass never leaves the face");
      cand->trail.push_back(cur.p);
      if (gap) {
        Eigen::Vector2d dir = gap_dir;
        const bool marched = MarchContact(e, cur, gap_step, &dir, &next);
        const double su = cur.dp.col(0).norm(), sv = cur.dp.col(1).norm();
        const bool by_pole = std::min(su, sv) < 0.05 * std::max(su, sv);
        if (!by_pole && (!marched || !e.Inside(next.uv))) {
          // The line leaves the face within the step: left out up to where it does (bisection
          // on the step, to 1/4096 of it).
          double lo = 0.0, hi = gap_step;
          ContactPoint last = cur, p;
          for (int i = 0; i < 12; ++i) {
            const double mid = 0.5 * (lo + hi);
            Eigen::Vector2d d = gap_dir;
            if (MarchContact(e, cur, mid, &d, &p) && e.Inside(p.uv)) {
              lo = mid, last = p;
            } else {
              hi = mid;
            }
          }
          gap->contact_mm += (last.p - cur.p).norm();
          s += (last.tip - cur.tip).norm();
          cur = last;
          return end_in_gap();
        }
        if (!marched || !e.Inside(next.uv)) {
          // Next to a pole, shorter steps up to it, then across it as the trace bridges it.
          if (gap_step > full / 1024.0) {
            gap_step *= 0.5;
            continue;
          }
          Bridge pole;
          if (!AcrossPole(e, cur, s, &pole)) return end_in_gap();
          gap->contact_mm += (pole.exit.p - cur.p).norm();
          s = pole.s_exit;
          cur = pole.exit;
          gap_dir = cur.duv.normalized();
          gap_step = full;
          continue;
        }
        if (loop && Closes(*loop, cur, next, full)) {
          // Round a closed section inside the stretch: it ends where the section started.
          gap->contact_mm += (loop->p - cur.p).norm();
          s += (loop->tip - cur.tip).norm();
          cur = *loop;
          cand->closed = true;
          return end_in_gap();
        }
        // Back where the gap began: the line's contact points close a loop here (in a valley
        // narrower than the tool, where it touches on both sides), and the march would go round
        // it for ever. The line is not followed past it.
        if (gap->contact_mm > 4.0 * full && (next.p - gap->before.p).norm() < full) {
          return end_in_gap();
        }
        const double chord = (next.tip - cur.tip).norm();
        // A piece resumes only where the tool fits and its travel (the tip along the feed) carries
        // the contact point on in the march's direction. Where the tool's path is folded back
        // (the face tighter than the tool: a flat bottom's edge in a valley), the tool may fit at
        // a point whose travel takes the contact point back into the stretch just marched: a
        // piece from there would end at once, and the stretch it opened would be marched back to
        // the last such point, and so on for ever.
        const auto onward = [](const ContactPoint& p, const Eigen::Vector2d& d) {
          return p.duv.dot(d) > 0.0;
        };
        if (gap->stuck && fits(next, s + chord) && onward(next, dir)) {
          s += chord;
          gap->contact_mm += (next.p - cur.p).norm();
          cur = next;
          close_gap(cur, s, true);
          h = full / 1024.0;
          continue;
        }
        if (fits(next, s + chord) && onward(next, dir)) {
          // The tool fits again: the next piece starts where it does, traced on from there.
          const ContactPoint from = cur;
          const Eigen::Vector2d from_dir = gap_dir;
          const Change c = change_by(
              false, full, from,
              [&](double m, ContactPoint* to) {
                Eigen::Vector2d d = from_dir;
                return MarchContact(e, from, m, &d, to);
              },
              [&](const ContactPoint& p) { return onward(p, from_dir) && !UnfitAt(p); });
          s += (c.fit.tip - from.tip).norm();
          gap->contact_mm += (c.fit.p - from.p).norm();
          cur = c.fit;
          close_gap(cur, s, true);
          h = full / 1024.0;
          continue;
        }
        gap_dir = dir;
        s += chord;
        gap->contact_mm += (next.p - cur.p).norm();
        cur = next;
        continue;
      }
      if (!e.Step(cur, h, spec_.newton, &next, &status, &its)) {
        // Shorter steps first: where the pass bends hard (a gouge ahead) they get close enough
        // for the curvature check to say so.
        // A flat bottom coming onto a top: the contact point stops there (kFlatContact once the
        // normal is the axis, no convergence just before).
        const bool flat = status == EvalStatus::kFlatContact;
        if ((status == EvalStatus::kOk || flat) && h > full / 1024.0) {
          h *= 0.5;
          continue;
        }
        if (status == EvalStatus::kGuideFold && skip) {
          // The offset line folds over itself ahead (a guide bend tighter than the offset): the
          // pass ends at the last point before the fold (to h / 4096), and the line's stretch
          // through the fold is left out, up to where the offset line unfolds.
          double lo = 0.0, hi = h;
          ContactPoint before = cur, p;
          for (int i = 0; i < 12; ++i) {
            const double mid = 0.5 * (lo + hi);
            EvalStatus st;
            int n = 0;
            if (e.Step(cur, mid, spec_.newton, &p, &st, &n) && !UnfitAt(p)) {
              lo = mid, before = p;
            } else {
              hi = mid;
            }
          }
          Fold fold;
          if (AcrossFold(e, before, &fold)) {
            why = FoldText(e.Constraint(), fold);
            open_gap(before, s + lo);
            gap->contact_mm = fold.contact_mm;
            cand->trail.insert(cand->trail.end(), fold.points.begin(), fold.points.end());
            s += lo + (fold.last.tip - before.tip).norm();
            cur = fold.last;
            if (!fold.resumes) return end_in_gap();
            if (fits(cur, s)) {
              close_gap(cur, s, true);
            } else {
              gap_dir = cur.duv.normalized();
            }
            h = full / 1024.0;
            continue;
          }
        }
        Bridge piece;
        const bool top = OverTop(e, cur, s, &piece) || OverCrest(e, cur, s, &piece);
        if (top || AcrossPole(e, cur, s, &piece)) {
          // Over a top the bottom's disc rides the chord: checked along it like any step.
          for (int i = 1; i < 8 && top; ++i) {
            ContactPoint on = cur;
            on.p = piece.top;
            on.uv = piece.top_uv;
            on.n = cur.axis;
            on.tip = piece.Tip(piece.s_in + (piece.s_out - piece.s_in) * i / 8.0);
            if (const auto w = GougeAt(on)) {
              Fail(cand->line, cand->constraint, piece.s_in, on.uv, *w);
            }
          }
          cand->bridges.push_back(piece);
          cur = piece.exit;
          s = piece.s_exit;
          if (!fits(cur, s)) open_gap(cur, s);
          h = full / 1024.0;  // where the halving left it
          continue;
        }
        const std::string stuck =
            status == EvalStatus::kOk
                ? fmt::format(
                      "the Newton solve did not converge to {} mm (even in steps of {} "
                      "mm): the strategy's line is singular here (surface radius of "
                      "curvature {:.3g} mm, normal . tool axis {:.3g})",
                      spec_.newton.tolerance_mm, h, std::abs(1.0 / cur.concave_curvature),
                      cur.n.dot(cur.axis))
                : EvalStatusText(status);
        if (!IsPlane() && NearPole(cur)) {
          // A uv line ends at a pole, as at a side of the face.
          cand->end = cur;
          cand->length = s;
          return;
        }
        if (skip && (status == EvalStatus::kOk || flat)) {
          // A flat bottom resting on the face away from the strategy's contact point (a saddle
          // on a uv or plane_cc line): plane strategies trace the line's far side from its other
          // end, so the line ends here, said so; a uv line goes on by its contact point to where
          // the tool fits again.
          why = stuck;
          open_gap(cur, s);
          if (IsPlane()) return end_in_gap();
          gap->stuck = true;
          continue;
        }
        Fail(cand->line, cand->constraint, s, cur.uv, stuck);
      }
      // A pass that skims the boundary may leave and re-enter between two steps: look at the
      // middle of the step (cubic Hermite in (u, v)) and, if it is off the face, solve there.
      double out_chord = e.Inside(next.uv) ? 0.0 : h;
      if (out_chord == 0.0) {
        const Eigen::Vector2d mid = 0.5 * (cur.uv + next.uv) + (cur.duv - next.duv) * (h / 8.0);
        ContactPoint m;
        EvalStatus ms;
        if (!e.Inside(mid) &&
            e.SolveChord(cur.tip, 0.5 * (next.tip - cur.tip).norm(), mid, spec_.newton, &m, &ms,
                         cur.guide_t) >= 0 &&
            !e.Inside(m.uv)) {
          out_chord = (m.tip - cur.tip).norm();
        }
      }
      if (out_chord > 0.0) {
        const ContactPoint end = Bisect(e, cur, 1.0, out_chord);
        const double arc = ArcFromChord((end.tip - cur.tip).norm(), cur.tangent, end.tangent);
        const bool fits_at_end = fits(end, s + arc);
        if (fits_at_end) {
          if (const auto x = FirstIntoAlong(e, cur, end, arc)) {
            h = *x;
            continue;
          }
        } else {
          const Change c = change(true, arc, cur, tip_step(cur));
          if (const auto x = FirstIntoAlong(e, cur, c.fit, c.x_fit)) {
            h = *x;
            continue;
          }
          open_gap(c.fit, s + c.x_fit);
          gap->contact_mm = (end.p - c.fit.p).norm();
          close_gap(end, s + arc, false);
        }
        s += arc;
        cand->end = end;
        cand->length = s;
        return;
      }
      if (loop && Closes(*loop, cur, next, h)) {
        // Round a closed section: it ends exactly where it started.
        s += ArcFromChord((loop->tip - cur.tip).norm(), cur.tangent, loop->tangent);
        cand->end = *loop;
        cand->length = s;
        cand->closed = true;
        return;
      }
      if (!fits(next, s + h)) {
        // The gap starts after the last point where the tool fits; the march goes on from the
        // first where it does not.
        const Change c = change(true, h, cur, tip_step(cur));
        if (const auto x = FirstIntoAlong(e, cur, c.fit, c.x_fit)) {
          h = *x;
          continue;
        }
        open_gap(c.fit, s + c.x_fit);
        gap->contact_mm = (c.unfit.p - c.fit.p).norm();
        cur = c.unfit;
        s += c.x_unfit;
        continue;
      }
      if (const auto x = FirstIntoAlong(e, cur, next, h)) {
        // A checked face comes into the tool between the two: the step ends where it does.
        h = *x;
        continue;
      }
      AddKnotLines(e, cur, next, s, h, &cand->knot_lines);
      s += h;
      cur = next;
      h = std::min(full, 2.0 * h);
    }
  }

  // The axis of every pass smoothed within the orientation's tolerance (AxisLaw): each pass is
  // replaced by the same line followed with the law's axis, its cutter locations solved on the
  // face for that axis, checked as the trace checks them. A pass whose ends no longer fit (the
  // tool touched a second place there: a valley it rides over) is cut to where it fits; one that
  // rode over from the previous pass is linked if the straight move between the new ends does
  // not keep out of the face. `ridden`: for each pass, the stretch it rides over (-1: none).
  void SmoothAxes(PassList* list, const std::vector<int>& ridden) const {
    ContactPoint previous_end;
    for (std::size_t k = 0; k < list->passes.size(); ++k) {
      const SurfacePass& exact = *list->passes[k];
      ContactPoint start, end;
      std::unique_ptr<SurfacePass> smooth = SmoothPass(exact, &start, &end);
      if (exact.RidesOverFromPrevious()) {
        const bool rides = k > 0 && RidesOver(previous_end, start);
        smooth->SetRidesOverFromPrevious(rides);
        if (!rides && ridden[k] >= 0) {
          list->unreachable[static_cast<std::size_t>(ridden[k])].ridden_over = false;
        }
      }
      previous_end = end;
      list->passes[k] = std::move(smooth);
    }
  }

  // Arc length between the samples of the rule's axis a law is fitted to, mm (at most).
  static constexpr double kAxisSampleMm = 0.04;
  // The law's knot spans to start with, at most (mm).
  static constexpr double kAxisSpanMm = 20.0;
  // A knot span of the law is not split below this (mm): the axis cannot be smoothed within the
  // tolerance then.
  static constexpr double kMinAxisSpanMm = 0.5;
  // The fit aims at this fraction of the tolerance at its samples; the check between the
  // smoothed pass's points holds to the whole tolerance.
  static constexpr double kAxisFitAim = 0.8;
  // Halvings of the smoothing's range of 22 decades: to 0.005 of a decade (1.2 % in the smoothing).
  static constexpr int kSmoothingBisections = 12;

  [[noreturn]] void FailSmoothing(const SurfacePass& pass, double s, const Eigen::Vector2d& uv,
                                  const std::string& what) const {
    throw Error(
        "{}, pass {} ({}), arc length {:.6f} mm{}: [orientation] axis_tolerance_deg = "
        "{:.6g}: {}",
        face_.Where(), pass.Index(), pass.Evaluator().Constraint().Describe(), s,
        std::isfinite(uv.x()) ? fmt::format(", (u, v) = ({:.9g}, {:.9g})", uv.x(), uv.y()) : "",
        orientation_.axis_tolerance_rad * 180.0 / M_PI, what);
  }

  // The quintic law with knots refined (in the middle of every span where a sample is more than
  // `aim` off the least-squares fit) until every sample can be within it, then smoothed as much
  // as that allows (Smoothest).
  AxisLaw FitLaw(const SurfacePass& pass, const std::vector<double>& s,
                 const std::vector<Eigen::Vector3d>& axes, double aim) const {
    // Equal spans of at most kAxisSpanMm to start with: room for the smoothing to shape the law.
    const int m = std::max(1, static_cast<int>(std::ceil((s.back() - s.front()) / kAxisSpanMm)));
    std::vector<double> breaks;
    for (int i = 0; i <= m; ++i) breaks.push_back(s.front() + (s.back() - s.front()) * i / m);
    for (;;) {
      AxisLaw law = FitAxisLaw(s, axes, breaks);
      std::vector<bool> off(breaks.size() - 1, false);
      bool any = false;
      std::size_t span = 0;
      double worst = 0.0, worst_s = 0.0;
      for (std::size_t i = 0; i < s.size(); ++i) {
        while (span + 2 < breaks.size() && s[i] >= breaks[span + 1]) ++span;
        const double dev = geometry::Angle(law.At(s[i]), axes[i]);
        if (dev > aim) off[span] = any = true;
        if (dev > worst) worst = dev, worst_s = s[i];
      }
      if (!any) return Smoothest(s, axes, breaks, aim, std::move(law));
      std::vector<double> refined{breaks.front()};
      for (std::size_t j = 0; j + 1 < breaks.size(); ++j) {
        if (off[j]) {
          if (breaks[j + 1] - breaks[j] < 2.0 * kMinAxisSpanMm) {
            FailSmoothing(pass, worst_s, Eigen::Vector2d::Constant(NAN),
                          fmt::format("the rule's axis turns too abruptly here: a quintic law with "
                                      "knots {:.3g} mm apart is still {:.3g} deg from it; give a "
                                      "larger tolerance or 0 (the rule's axis)",
                                      breaks[j + 1] - breaks[j], worst * 180.0 / M_PI));
          }
          refined.push_back(0.5 * (breaks[j] + breaks[j + 1]));
        }
        refined.push_back(breaks[j + 1]);
      }
      breaks = std::move(refined);
    }
  }

  // The law on `breaks` with the largest smoothing (FitAxisLaw) that keeps every sample within
  // `aim`: of the laws that follow the rule as closely, the one whose axis turns most evenly.
  // `plain` is the unsmoothed law, within `aim`.
  static AxisLaw Smoothest(const std::vector<double>& s, const std::vector<Eigen::Vector3d>& axes,
                           const std::vector<double>& breaks, double aim, AxisLaw plain) {
    const auto within = [&](const AxisLaw& law) {
      for (std::size_t i = 0; i < s.size(); ++i) {
        if (geometry::Angle(law.At(s[i]), axes[i]) > aim) return false;
      }
      return true;
    };
    // Bisection on log10(smoothing), mm^6, between one that holds and one that does not.
    double lo = -8.0, hi = 14.0;
    AxisLaw best = std::move(plain);
    {
      AxisLaw at_lo = FitAxisLaw(s, axes, breaks, std::pow(10.0, lo));
      if (!within(at_lo)) return best;
      best = std::move(at_lo);
    }
    for (int k = 0; k < kSmoothingBisections; ++k) {
      const double mid = 0.5 * (lo + hi);
      AxisLaw law = FitAxisLaw(s, axes, breaks, std::pow(10.0, mid));
      if (within(law)) {
        lo = mid;
        best = std::move(law);
      } else {
        hi = mid;
      }
    }
    return best;
  }

  // `exact` with its axis smoothed (SmoothAxes); its start and end contact points in `start`
  // and `end`.
  std::unique_ptr<SurfacePass> SmoothPass(const SurfacePass& exact, ContactPoint* start_out,
                                          ContactPoint* end_out) const {
    const double length = exact.Length().value();
    const double tol = orientation_.axis_tolerance_rad;
    if (exact.HasBridges()) {
      FailSmoothing(exact, 0.0, Eigen::Vector2d(exact.Start().u, exact.Start().v),
                    "the pass crosses a pole of the face, where its axis is not smoothed; give 0");
    }
    // The rule's axis along the exact pass.
    const int n = std::max(64, static_cast<int>(std::ceil(length / kAxisSampleMm)));
    std::vector<double> ss;
    std::vector<Eigen::Vector3d> axes;
    PathState state = exact.Start();
    ContactPoint exact_start, exact_end;
    exact.Evaluate(state, &exact_start);
    for (int i = 0; i <= n; ++i) {
      const double s = length * i / n;
      const PathSample smp = exact.At(state, s);
      if (smp.status != PathStatus::kOk && smp.status != PathStatus::kEnd) {
        FailSmoothing(exact, s, Eigen::Vector2d(state.u, state.v),
                      DescribePathFailure(smp.status, s));
      }
      state = smp.state;
      ss.push_back(s);
      axes.push_back(smp.pose.axis);
    }
    exact.Evaluate(state, &exact_end);
    const NewtonOptions& o = spec_.newton;
    const double full = o.max_step_mm;
    double aim = kAxisFitAim * tol;
    for (int round = 0;; ++round) {
      auto law = std::make_shared<AxisLaw>(FitLaw(exact, ss, axes, aim));
      PassEvaluator e = exact.Evaluator();
      e.SetAxisLaw(law);
      // The start: the exact one moved across the line onto it for the law's axis (g depends on
      // the axis for plane_cl: by a few micrometres).
      ContactPoint cur;
      Eigen::Vector2d uv = exact_start.uv;
      for (int it = 0;; ++it) {
        const EvalStatus st = e.EvaluateAt(uv, 0.0, &cur, exact_start.guide_t);
        if (st != EvalStatus::kOk) FailSmoothing(exact, 0.0, uv, EvalStatusText(st));
        if (std::abs(cur.g) <= o.arc_tolerance_mm) break;
        if (it == o.max_iterations) {
          FailSmoothing(exact, 0.0, uv, "the pass's start does not converge for the smoothed axis");
        }
        uv -= cur.dg * (cur.g / cur.dg.squaredNorm());
      }
      // March to where the tip crosses the exact end's plane across the travel.
      std::vector<ContactPoint> points{cur};
      std::vector<double> knot_lines;  // where the march crosses the face's knot lines
      const auto beyond = [&](const ContactPoint& p) {
        return (p.tip - exact_end.tip).dot(exact_end.tangent);
      };
      double h = full;
      for (;;) {
        ContactPoint next;
        EvalStatus st = EvalStatus::kOk;
        int its = 0;
        if (!e.Step(cur, h, o, &next, &st, &its)) {
          if (st == EvalStatus::kOk && h > full / 1024.0) {
            h *= 0.5;
            continue;
          }
          FailSmoothing(exact, cur.s, cur.uv,
                        st == EvalStatus::kOk ? "the Newton solve for the smoothed axis did not "
                                                "converge"
                                              : EvalStatusText(st));
        }
        if (beyond(next) >= 0.0) {
          // Bisection on the step for the crossing.
          double lo = 0.0, hi = h;
          ContactPoint p;
          for (int k = 0; k < 60 && hi - lo > 1e-12; ++k) {
            const double mid = 0.5 * (lo + hi);
            if (e.Step(cur, mid, o, &p, &st, &its) && beyond(p) < 0.0) {
              lo = mid;
            } else {
              hi = mid;
              next = p;
            }
          }
          if (!e.Step(cur, hi, o, &next, &st, &its)) {
            FailSmoothing(exact, cur.s, cur.uv, "the smoothed pass's end does not converge");
          }
          AddKnotLines(e, cur, next, cur.s, hi, &knot_lines);
          points.push_back(next);
          break;
        }
        AddKnotLines(e, cur, next, cur.s, h, &knot_lines);
        points.push_back(next);
        cur = next;
        h = std::min(full, 2.0 * h);
        if (cur.s > 2.0 * length + 1.0) {
          FailSmoothing(exact, cur.s, cur.uv,
                        "the smoothed pass does not reach the exact one's end");
        }
      }
      // The axis within the tolerance of the rule's at every point and halfway between them
      // (points the law was not fitted from: its samples lie on the exact pass).
      double worst = 0.0;
      const ContactPoint* worst_at = &points.front();
      for (std::size_t i = 0; i < points.size(); ++i) {
        const double dev = geometry::Angle(points[i].axis, points[i].rule_axis);
        if (dev > worst) worst = dev, worst_at = &points[i];
        if (i + 1 == points.size()) break;
        ContactPoint mid;
        EvalStatus st;
        int its = 0;
        if (e.Step(points[i], 0.5 * (points[i + 1].s - points[i].s), o, &mid, &st, &its)) {
          const double d = geometry::Angle(mid.axis, mid.rule_axis);
          if (d > worst) worst = d;
        }
      }
      if (worst > tol) {
        if (round == 6) {
          FailSmoothing(exact, worst_at->s, worst_at->uv,
                        fmt::format("the smoothed axis stays {:.3g} deg from the rule's after "
                                    "fitting its samples to {:.3g} deg; give a larger tolerance "
                                    "or 0 (the rule's axis)",
                                    worst * 180.0 / M_PI, aim * 180.0 / M_PI));
        }
        aim *= 0.7;
        continue;
      }
      // The tool checked as the trace checks it; ends where it does not fit are cut off.
      std::size_t first = 0, last = points.size() - 1;
      while (first < points.size() && UnfitAt(points[first])) ++first;
      if (first == points.size()) {
        FailSmoothing(exact, 0.0, points.front().uv,
                      "the tool fits nowhere along the pass with the smoothed axis: " +
                          *UnfitAt(points.front()));
      }
      while (UnfitAt(points[last])) --last;
      for (std::size_t i = first; i <= last; ++i) {
        if (const auto why = UnfitAt(points[i]))
          FailSmoothing(exact, points[i].s, points[i].uv, *why);
        // The checked faces between the points too (FirstInto).
        if (i < last) {
          if (const auto x =
                  FirstIntoAlong(e, points[i], points[i + 1], points[i + 1].s - points[i].s)) {
            ContactPoint p;
            EvalStatus st;
            int its = 0;
            if (e.Step(points[i], *x, o, &p, &st, &its)) {
              if (const auto why = UnfitAt(p)) FailSmoothing(exact, p.s, p.uv, *why);
            }
          }
        }
      }
      // Where the tool first (last) fits, between two points: bisection to 1/4096 of their step.
      const auto fits_from = [&](const ContactPoint& from, double step, bool fit_at_end) {
        double lo = 0.0, hi = step;
        ContactPoint p, best = fit_at_end ? ContactPoint() : from;
        EvalStatus st;
        int its = 0;
        bool have = false;
        for (int k = 0; k < 12; ++k) {
          const double mid = 0.5 * (lo + hi);
          const bool ok = e.Step(from, mid, o, &p, &st, &its);
          const bool fit = ok && !UnfitAt(p);
          if (ok && fit != fit_at_end) {
            lo = mid;
            if (!fit_at_end) best = p;
          } else {
            hi = mid;
            if (ok && fit_at_end) best = p, have = true;
          }
        }
        if (fit_at_end && !have && !e.Step(from, hi, o, &best, &st, &its)) {
          FailSmoothing(exact, from.s, from.uv, "the smoothed pass's new end does not converge");
        }
        return best;
      };
      ContactPoint start = points[first], end = points[last];
      if (first > 0) {
        start = fits_from(points[first - 1], points[first].s - points[first - 1].s, true);
      }
      if (last + 1 < points.size()) {
        end = fits_from(points[last], points[last + 1].s - points[last].s, false);
      }
      const double shift = start.s, new_length = end.s - start.s;
      if (!(new_length >= kMinPieceMm)) {
        FailSmoothing(exact, start.s, start.uv,
                      "the tool fits on less than a piece of the pass with the smoothed axis");
      }
      if (shift != 0.0) {
        auto shifted = std::make_shared<AxisLaw>(*law);
        shifted->SetShift(shift);
        e.SetAxisLaw(shifted);
      }
      if (e.EvaluateAt(start.uv, 0.0, start_out, start.guide_t) != EvalStatus::kOk ||
          e.EvaluateAt(end.uv, new_length, end_out, end.guide_t) != EvalStatus::kOk) {
        FailSmoothing(exact, start.s, start.uv, "the smoothed pass's ends do not evaluate");
      }
      std::vector<double> knots_on_pass;
      for (const double k : knot_lines) {
        if (k > shift && k - shift < new_length) knots_on_pass.push_back(k - shift);
      }
      return std::make_unique<SurfacePass>(e, exact.Index(), *start_out, *end_out, new_length, o,
                                           std::vector<Bridge>{}, std::move(knots_on_pass));
    }
  }

  // The knot lines of the face the step of h mm from `from` (at arc length s) to `to` crosses:
  // the arc length of each crossing, found by bisection on the step to 1e-9 mm.
  void AddKnotLines(const PassEvaluator& e, const ContactPoint& from, const ContactPoint& to,
                    double s, double h, std::vector<double>* out) const {
    std::vector<double> found;
    for (const int axis : {0, 1}) {
      const std::vector<double>& knots = axis == 0 ? face_.UKnotLines() : face_.VKnotLines();
      const double a = from.uv[axis], b = to.uv[axis];
      for (const double k : knots) {
        if (!((a < k && b >= k) || (a > k && b <= k))) continue;
        double lo = 0.0, hi = h;
        ContactPoint p;
        EvalStatus st;
        int its = 0;
        while (hi - lo > 1e-9) {
          const double mid = 0.5 * (lo + hi);
          if (!e.Step(from, mid, spec_.newton, &p, &st, &its)) break;
          ((p.uv[axis] - k) * (a - k) > 0.0 ? lo : hi) = mid;
        }
        found.push_back(s + 0.5 * (lo + hi));
      }
    }
    std::sort(found.begin(), found.end());
    out->insert(out->end(), found.begin(), found.end());
  }

  // The length of the iso-parametric line through `from` (a uv line's contact point), from it in
  // the direction `dir` in (u, v) to where it first leaves the face, mm: the chords of 1024
  // steps of the parameter to the UV box's side.
  double RestOfIsoLine(const ContactPoint& from, const Eigen::Vector2d& dir) const {
    const int k = spec_.along_u ? 0 : 1;
    if (!(std::abs(dir[k]) > 0.0)) return 0.0;
    const double end =
        dir[k] > 0.0 ? (k == 0 ? face_.U1() : face_.V1()) : (k == 0 ? face_.U0() : face_.V0());
    constexpr int kSteps = 1024;
    Eigen::Vector2d uv = from.uv;
    Eigen::Vector3d last = from.p;
    geometry::SurfaceDerivatives d;
    double length = 0.0;
    for (int i = 1; i <= kSteps; ++i) {
      uv[k] = from.uv[k] + (end - from.uv[k]) * i / kSteps;
      if (!face_.Inside(uv.x(), uv.y())) break;
      face_.D2(uv.x(), uv.y(), &d);
      length += (d.p - last).norm();
      last = d.p;
    }
    return length;
  }

  // One step of about `h` mm of the contact point along the strategy's line on the face (not of
  // the tool's tip: this one goes on where the tip's path folds back), from `from`, in the
  // direction `dir` in (u, v) (updated to the line's direction there). False if the line cannot be
  // followed (no convergence, an evaluation refused).
  bool MarchContact(const PassEvaluator& e, const ContactPoint& from, double h,
                    Eigen::Vector2d* dir, ContactPoint* to) const {
    Eigen::Vector2d t(-from.dg.y(), from.dg.x());
    if (!(t.norm() > 0.0)) return false;
    t.normalize();
    if (t.dot(*dir) < 0.0) t = -t;
    const double speed = (from.dp * t).norm();  // mm of contact per unit of (u, v)
    if (!(speed > 0.0)) return false;
    Eigen::Vector2d uv = from.uv + t * (h / speed);
    ContactPoint c;
    for (int it = 0; it < 20; ++it) {
      if (!face_.InBox(uv.x(), uv.y())) return false;
      if (!Evaluates(e, uv, &c, from.guide_t)) return false;
      if (std::abs(c.g) <= spec_.newton.tolerance_mm) {
        *to = c;
        *dir = t;
        return true;
      }
      const double n2 = c.dg.squaredNorm();
      if (!(n2 > 0.0)) return false;
      uv -= c.dg * (c.g / n2);
    }
    return false;
  }

  // Whether the point of the face at uv gives a contact point: evaluated, or sitting flat on a
  // top where the strategy holds the contact point (kFlatContact: the tip on the contact point,
  // one of the places the tool may stand there, checked like any other).
  static bool Evaluates(const PassEvaluator& e, const Eigen::Vector2d& uv, ContactPoint* out,
                        double guide_hint = std::numeric_limits<double>::quiet_NaN()) {
    const EvalStatus st = e.Evaluate(uv, out, guide_hint);
    return st == EvalStatus::kOk || (st == EvalStatus::kFlatContact &&
                                     e.Constraint().kind != PassConstraint::Kind::kPlaneCl);
  }

  // A leading_line's stretch through a fold of its offset line (AcrossFold).
  struct Fold {
    // The line's points through it, 0.05 mm apart or more (where the line was traced).
    std::vector<Eigen::Vector3d> points;
    // Where the offset line unfolds (resumes), or the last point of it on the face.
    ContactPoint last;
    bool resumes = false;
    double contact_mm = 0.0;         // of the line on the face through the fold
    double least_radius = INFINITY;  // the guide's least radius of curvature along it, mm
  };

  // Guide arc length between the points a fold's stretch is measured by, mm.
  static constexpr double kFoldStepMm = 0.01;

  // The trace of a leading_line pass stops at `a`, just before the guide's radius of curvature
  // comes within 1 % of the offset on the inside of a bend (kGuideFold): beyond it the closest
  // point of the guide stops being one and the offset line folds over itself (a swallowtail:
  // cusp, loop, cusp). The stretch left out is the line's points there, each the guide's point at
  // t offset by the pass's offset along its left normal (in XY, projected along Z onto the face),
  // from a's guide parameter on in the pass's direction to the first parameter past the bend where
  // the fold is below 0.99 again (bisection to 1e-13 of the guide's parameter); its length is
  // the chords between those points of the face every kFoldStepMm of the guide. The pass resumes
  // there. Where the offset line leaves the face first (to 1e-6 of the step by bisection) or the
  // guide ends in the bend, the line ends there. False if no fold is met within 1 mm of the guide
  // from a (not such a place).
  bool AcrossFold(const PassEvaluator& e, const ContactPoint& a, Fold* out) const {
    const PassConstraint& c = e.Constraint();
    if (c.kind != PassConstraint::Kind::kGuide || !c.guide || !std::isfinite(a.guide_t)) {
      return false;
    }
    const geometry::BSplineCurve& guide = *c.guide;
    const double offset = c.value;
    const double t0 = guide.FirstParameter(), t1 = guide.LastParameter();
    Eigen::Vector3d gd[3];
    guide.Derivatives(a.guide_t, 1, gd);
    const double way = gd[1].x() * a.tangent.x() + gd[1].y() * a.tangent.y();
    if (!(std::abs(way) > 0.0)) return false;
    const double sign = way > 0.0 ? 1.0 : -1.0;
    // The guide at t: the offset point in XY, the fold (offset times curvature, signed) and the
    // guide's speed.
    struct OnGuide {
      Eigen::Vector2d q;
      double fold = 0.0, speed = 0.0;
    };
    const auto at = [&](double t) {
      guide.Derivatives(t, 2, gd, sign < 0.0);
      const Eigen::Vector2d d1(gd[1].x(), gd[1].y()), d2(gd[2].x(), gd[2].y());
      OnGuide g;
      g.speed = d1.norm();
      if (!(g.speed > 0.0)) return g;
      const Eigen::Vector2d left = Eigen::Vector2d(-d1.y(), d1.x()) / g.speed;
      g.q = Eigen::Vector2d(gd[0].x(), gd[0].y()) + offset * left;
      g.fold = offset * (d1.x() * d2.y() - d1.y() * d2.x()) / (g.speed * g.speed * g.speed);
      return g;
    };
    // The face's point over q in XY (the contact point there), by Newton in (u, v) from uv.
    const auto lift = [&](const Eigen::Vector2d& q, Eigen::Vector2d* uv, Eigen::Vector3d* p) {
      geometry::SurfaceDerivatives d;
      for (int it = 0; it < 30; ++it) {
        if (!face_.InBox(uv->x(), uv->y())) return false;
        face_.D2(uv->x(), uv->y(), &d);
        const Eigen::Vector2d f(d.p.x() - q.x(), d.p.y() - q.y());
        if (f.norm() <= 1e-10) {
          *p = d.p;
          return face_.Inside(uv->x(), uv->y());
        }
        Eigen::Matrix2d j;
        j << d.su.x(), d.sv.x(), d.su.y(), d.sv.y();
        if (!(std::abs(j.determinant()) > 1e-300)) return false;
        *uv -= j.inverse() * f;
      }
      return false;
    };
    constexpr double kFold = 0.99;  // as the evaluator's refusal (surface_pass.cpp)
    double t = a.guide_t, guide_mm = 0.0;
    bool folded = false;
    Eigen::Vector2d uv = a.uv;
    Eigen::Vector3d last = a.p;
    out->points.clear();
    out->contact_mm = 0.0;
    out->resumes = false;
    double most = 0.0;  // the largest fold met
    // Ends the stretch at the line's point at parameter `end` (lifted from uv): the pass resumes
    // there if `resumes` and it evaluates.
    const auto finish = [&](double end, const Eigen::Vector2d& end_uv, const Eigen::Vector3d& p,
                            bool resumes) {
      out->contact_mm += (p - last).norm();
      out->points.push_back(p);
      out->least_radius = std::abs(offset) / most;
      const EvalStatus st = e.Evaluate(end_uv, &out->last, end);
      if (st != EvalStatus::kOk && st != EvalStatus::kFlatContact) {
        out->last = a;
        out->last.uv = end_uv;
        out->last.p = p;
        out->resumes = false;
        return true;
      }
      out->resumes = resumes && st == EvalStatus::kOk && out->last.guide_fold <= kFold &&
                     std::abs(out->last.g) <= spec_.newton.tolerance_mm;
      return true;
    };
    for (;;) {
      const OnGuide here = at(t);
      if (!(here.speed > 0.0)) return false;
      const bool last_one = sign > 0.0 ? t >= t1 : t <= t0;
      if (last_one) {
        // The guide ends in the bend: so does the line.
        return folded && finish(t, uv, last, false);
      }
      const double next = std::clamp(t + sign * kFoldStepMm / here.speed, t0, t1);
      const OnGuide there = at(next);
      if (!(there.speed > 0.0)) return false;
      Eigen::Vector2d next_uv = uv;
      Eigen::Vector3d p;
      if (folded && !(there.fold > kFold)) {
        // Past the bend: where the fold comes down to kFold, by bisection.
        double lo = t, hi = next;
        for (int i = 0; i < 200 && std::abs(hi - lo) > 1e-13 * (1.0 + std::abs(hi)); ++i) {
          const double mid = 0.5 * (lo + hi);
          (at(mid).fold > kFold ? lo : hi) = mid;
        }
        if (lift(at(hi).q, &next_uv, &p)) return finish(hi, next_uv, p, true);
      } else if (lift(there.q, &next_uv, &p)) {
        folded = folded || there.fold > kFold;
        most = std::max(most, there.fold);
        out->contact_mm += (p - last).norm();
        if (out->points.empty() || (p - out->points.back()).norm() >= 0.05) {
          out->points.push_back(p);
        }
        last = p;
        uv = next_uv;
        t = next;
        guide_mm += kFoldStepMm;
        if (!folded && guide_mm > 1.0) return false;
        continue;
      }
      // The line leaves the face between t and next: to where it does, by bisection.
      if (!folded) return false;
      double lo = t, hi = next;
      Eigen::Vector2d lo_uv = uv;
      Eigen::Vector3d lo_p = last;
      for (int i = 0; i < 20; ++i) {
        const double mid = 0.5 * (lo + hi);
        Eigen::Vector2d m_uv = lo_uv;
        Eigen::Vector3d m_p;
        if (lift(at(mid).q, &m_uv, &m_p)) {
          lo = mid, lo_uv = m_uv, lo_p = m_p;
        } else {
          hi = mid;
        }
      }
      return finish(lo, lo_uv, lo_p, false);
    }
  }

  // Why a fold's stretch is left out.
  static std::string FoldText(const PassConstraint& c, const Fold& fold) {
    return fmt::format(
        "the guide curve bends tighter than the pass's offset from it (its radius of curvature "
        "comes down to {:.4g} mm, the offset is {:.4g} mm): the offset line folds over itself; "
        "use offsets below the guide's radius of curvature or a smoother guide",
        fold.least_radius, std::abs(c.value));
  }

  // The trace, at contact point `cur` (arc length s), cannot step on: where a flat end or bull
  // nose on a fixed axis comes onto a top or a crest of the face along a strategy line that
  // holds the contact point (uv, plane_cc, leading_line), the piece over it (Bridge). The contact
  // point stays on the crest while the bottom slides across it: the tip runs straight at the
  // crest's height from where it stands on this side (R from the crest, as the contact point
  // comes onto it) to where it stands on the far side, as the contact point leaves it. Every tool
  // position of that chord is at most R from the crest point, so the bottom keeps touching it.
  // False if this is not such a place: another tool, orientation or strategy, no point ahead on
  // the line where the normal's part across the axis turns over, or a face that does not bend
  // away from the tool all round there (a saddle, a valley: the bottom would rest on two places).
  // A pole on top of the face within 0.01 mm of cur (a sphere's) is the crest itself.
  bool OverCrest(const PassEvaluator& e, const ContactPoint& cur, double s, Bridge* piece) const {
    const PassConstraint& c = e.Constraint();
    if (!(tool_.TorusRadius() > 0.0) || orientation_.kind != Orientation::Kind::kFixed ||
        c.kind == PassConstraint::Kind::kPlaneCl) {
      return false;
    }
    const Eigen::Vector3d a = cur.axis;
    const Eigen::Vector3d side = cur.n - cur.n.dot(a) * a;
    if (!(side.norm() > 0.0) || !(cur.duv.norm() > 0.0)) return false;
    const Eigen::Vector3d w_in = side.normalized();
    // Which side of the crest a contact point is on: + before it (the bottom's edge on this
    // side), - past it; 0 sitting flat.
    const auto before = [&](const ContactPoint& p) { return (p.n - p.n.dot(a) * a).dot(w_in); };
    constexpr double kPast = 1e-4;
    // A crest at a pole on top (a sphere's pole on a plane_cc or leading_line line through it):
    // (u, v) is degenerate there and the line cannot be marched through it. The pole is the
    // crest; the contact point leaves it on the far side, at the first point of the line, by
    // doubling from kPast from the pole (the parameter line leaving the pole nearest the
    // direction the contact point came in, of 720, then Newton across the line), whose tip it
    // fixes.
    Pole pole;
    const bool iso = c.kind == PassConstraint::Kind::kIsoU || c.kind == PassConstraint::Kind::kIsoV;
    if (!iso && PoleNear(cur, 1e-2, &pole)) {
      const Eigen::Vector3d n =
          pole.inside.su.cross(pole.inside.sv).normalized() * static_cast<double>(side_);
      const Eigen::Vector3d in = pole.at.p - cur.p;
      if (n.dot(a) < 1.0 - 1e-9 || CurvatureTowards(pole.inside, n) > 1e-9 || !(in.norm() > 0.0)) {
        return false;
      }
      ContactPoint exit;
      bool past_it = false;
      for (double past = kPast; past <= tool_.radius && !past_it; past *= 2.0) {
        Eigen::Vector2d uv = NearestLeavingPole(pole, past, pole.at.p + in.normalized() * past);
        for (int it = 0; it < 20; ++it) {
          if (!face_.InBox(uv.x(), uv.y()) || !Evaluates(e, uv, &exit, cur.guide_t)) break;
          if (std::abs(exit.g) <= spec_.newton.tolerance_mm) {
            past_it =
                e.Evaluate(exit.uv, &exit, cur.guide_t) == EvalStatus::kOk && before(exit) < 0.0;
            break;
          }
          const double n2 = exit.dg.squaredNorm();
          if (!(n2 > 0.0)) break;
          uv -= exit.dg * (exit.g / n2);
        }
      }
      if (!past_it || !e.Inside(exit.uv) || exit.tangent.dot(cur.tangent) < 0.0) return false;
      piece->entry = cur;
      piece->exit = exit;
      piece->top_uv = pole.uv;
      piece->top = pole.at.p;
      piece->tip_in = cur.tip;
      piece->direction = (exit.tip - cur.tip).normalized();
      piece->s_start = piece->s_in = s;
      piece->s_out = piece->s_exit = s + (exit.tip - cur.tip).norm();
      return true;
    }
    // The contact point `length` mm along the line from cur (false: the line cannot be followed).
    const auto along = [&](double length, ContactPoint* out) {
      Eigen::Vector2d dir = cur.duv.normalized();
      return MarchContact(e, cur, length, &dir, out);
    };
    // The first point past the crest, by doubling from 1e-4 mm (the trace's last step), at most
    // a tool radius ahead.
    double lo = 0.0, hi = kPast;
    ContactPoint p;
    for (;; hi *= 2.0) {
      if (hi > tool_.radius || !along(hi, &p)) return false;
      if (before(p) < 0.0) break;
      lo = hi;
    }
    // The crest between: bisection on the contact's path to 1e-12 mm.
    ContactPoint top = p;
    while (hi - lo > 1e-12) {
      const double mid = 0.5 * (lo + hi);
      if (!along(mid, &p)) return false;
      if (before(p) > 0.0) {
        lo = mid;
      } else {
        hi = mid, top = p;
      }
    }
    geometry::SurfaceDerivatives d;
    face_.D2(top.uv.x(), top.uv.y(), &d);
    if (CurvatureTowards(d, top.n) > 1e-9 || top.n.dot(a) < 1.0 - 1e-9) return false;
    // The contact point leaving the crest on the far side: the first, from kPast beyond it on,
    // whose tip the contact point fixes.
    ContactPoint exit;
    double past = hi;
    for (;; past *= 2.0) {
      if (past > tool_.radius || !along(past + kPast, &exit)) return false;
      if (e.Evaluate(exit.uv, &exit, cur.guide_t) == EvalStatus::kOk && before(exit) < 0.0) break;
    }
    if (!e.Inside(exit.uv) || exit.tangent.dot(cur.tangent) < 0.0) return false;
    piece->entry = cur;
    piece->exit = exit;
    piece->top_uv = top.uv;
    piece->top = top.p;
    piece->tip_in = cur.tip;
    piece->direction = (exit.tip - cur.tip).normalized();
    piece->s_start = piece->s_in = s;
    piece->s_out = piece->s_exit = s + (exit.tip - cur.tip).norm();
    return true;
  }

  // The trace, at contact point `cur` (arc length s), cannot step on: where a flat end or bull
  // nose on a fixed axis comes onto a top of the face, the piece over it (Bridge). False if
  // this is not such a place: another tool, orientation or strategy (their contact point is
  // held by the strategy), no point nearby where the normal is the axis, a face that does not
  // bend away from the tool all round there (a saddle or a valley: the bottom would rest on two
  // places), or a plane that misses the bottom's disc around the top.
  bool OverTop(const PassEvaluator& e, const ContactPoint& cur, double s, Bridge* piece) const {
    const PassConstraint& c = e.Constraint();
    const double big_r = tool_.TorusRadius();
    if (!(big_r > 0.0) || orientation_.kind != Orientation::Kind::kFixed ||
        c.kind != PassConstraint::Kind::kPlaneCl) {
      return false;
    }
    const Eigen::Vector3d a = cur.axis;
    const Eigen::Vector3d e1 = a.unitOrthogonal(), e2 = a.cross(e1);
    // The top: S_u x S_v along a, by Newton from the contact point.
    Eigen::Vector2d uv = cur.uv;
    geometry::SurfaceDerivatives d;
    bool found = false;
    for (int it = 0; it < 30; ++it) {
      face_.D2(uv.x(), uv.y(), &d);
      const Eigen::Vector3d big_n = d.su.cross(d.sv);
      // No normal here (a pole): tried below.
      const double longer = std::max(d.su.norm(), d.sv.norm());
      if (!(big_n.norm() > 1e-10 * longer * longer)) break;
      const Eigen::Vector2d f(big_n.dot(e1), big_n.dot(e2));
      if (f.norm() <= 1e-13 * big_n.norm()) {
        found = true;
        break;
      }
      const Eigen::Vector3d nu = d.suu.cross(d.sv) + d.su.cross(d.suv);
      const Eigen::Vector3d nv = d.suv.cross(d.sv) + d.su.cross(d.svv);
      Eigen::Matrix2d j;
      j << nu.dot(e1), nv.dot(e1), nu.dot(e2), nv.dot(e2);
      // A crest (the top is a line) leaves j singular: the least-norm step to it. Along a level
      // crest j's column is rounding noise, which must not count as rank (the step would slide
      // along the crest, to the top of another chord).
      Eigen::CompleteOrthogonalDecomposition<Eigen::Matrix2d> cod;
      cod.setThreshold(1e-9);
      uv -= cod.compute(j).solve(f);
    }
    // A top at a pole of the parametrization (a sphere's pole on top): S_u x S_v vanishes there,
    // so the Newton finds no normal; the pole is the top if the normal next to it is the axis.
    Pole pole;
    const bool top_here = found && (d.p - cur.p).norm() <= 1e-2;
    const bool at_pole = !top_here && PoleNear(cur, 1e-2, &pole);
    if (!top_here && !at_pole) return false;
    if (at_pole) uv = pole.uv, d = pole.at;
    const geometry::SurfaceDerivatives& bend = at_pole ? pole.inside : d;
    const Eigen::Vector3d n = bend.su.cross(bend.sv).normalized() * static_cast<double>(side_);
    if (at_pole ? n.dot(a) < 1.0 - 1e-9 : n.dot(a) < 0.0) return false;
    // Bends away from the tool all round (a crest's zero curvature along it too).
    if (CurvatureTowards(bend, n) > 1e-9) return false;
    // The bottom's disc around the top, cut by the strategy's plane.
    const Eigen::Vector3d across = c.normal - c.normal.dot(a) * a;
    if (across.norm() < 1e-9) return false;
    const Eigen::Vector3d m_dir = across.normalized();
    Eigen::Vector3d dir = a.cross(m_dir);
    if (dir.dot(cur.tangent) < 0.0) dir = -dir;
    const double t0 = (c.value - c.normal.dot(d.p)) / c.normal.dot(m_dir);
    if (!(std::abs(t0) < big_r)) return false;
    const double half = std::sqrt(big_r * big_r - t0 * t0);
    const Eigen::Vector3d middle = d.p + t0 * m_dir;
    const Eigen::Vector3d tip_in = middle - half * dir, tip_out = middle + half * dir;
    if ((tip_in - cur.tip).norm() > 1e-3) return false;
    // The contact point leaving the top on the far side, just past the chord.
    constexpr double kPast = 1e-4;
    const Eigen::Vector3d away = (tip_out - d.p).normalized();
    Eigen::Vector2d guess;
    if (at_pole) {
      // (u, v) is degenerate at a pole: of the parameter lines leaving it (720 of them), the
      // point kPast from the pole that is nearest the pole moved kPast away, as AcrossPole does.
      guess = NearestLeavingPole(pole, kPast, d.p + away * kPast);
    } else {
      Eigen::Matrix<double, 3, 2> dp;
      dp << d.su, d.sv;
      guess = uv + dp.completeOrthogonalDecomposition().solve(away * kPast);
    }
    ContactPoint exit;
    EvalStatus status;
    if (e.SolveChord(tip_out, kPast, guess, spec_.newton, &exit, &status) < 0 ||
        (exit.tip - tip_out).dot(dir) < 0.9 * kPast || exit.tangent.dot(dir) < 0.99 ||
        !e.Inside(exit.uv)) {
      return false;
    }
    piece->entry = cur;
    piece->exit = exit;
    piece->top_uv = uv;
    piece->top = d.p;
    piece->direction = dir;
    piece->tip_in = tip_in;
    piece->s_start = s;
    piece->s_in = s + (tip_in - cur.tip).norm();
    piece->s_out = piece->s_in + 2.0 * half;
    piece->s_exit = piece->s_out + (exit.tip - tip_out).norm();
    return true;
  }

  // A collapsed edge of the UV box (a pole: S_u or S_v vanishes along it).
  struct Pole {
    Eigen::Vector2d uv;               // on the edge, at the contact point's other parameter
    int fixed = 0;                    // the parameter that is constant along the edge (0: u, 1: v)
    double inward = 1.0;              // the sign of a step of that parameter into the box
    double across_mm = 0.0;           // |dS / d(that parameter)| at the edge, mm per unit
    geometry::SurfaceDerivatives at;  // at uv
    geometry::SurfaceDerivatives inside;  // 1e-6 of the box inside, where the normal is defined
  };

  // Of the 720 parameter lines leaving `pole`, the point `past` mm from it (across the edge) that
  // is nearest `target`, as (u, v): (u, v) is degenerate at a pole, and this starts a solve there.
  Eigen::Vector2d NearestLeavingPole(const Pole& pole, double past,
                                     const Eigen::Vector3d& target) const {
    const int m = 1 - pole.fixed;  // the parameter that runs along the collapsed edge
    const double m0 = m == 0 ? face_.U0() : face_.V0(), m1 = m == 0 ? face_.U1() : face_.V1();
    Eigen::Vector2d q = pole.uv, nearest = pole.uv;
    q[pole.fixed] += pole.inward * past / pole.across_mm;
    geometry::SurfaceDerivatives dq;
    double best = INFINITY;
    constexpr int kScan = 720;
    for (int k = 0; k <= kScan; ++k) {
      q[m] = m0 + (m1 - m0) * k / kScan;
      face_.D2(q.x(), q.y(), &dq);
      if ((dq.p - target).norm() < best) best = (dq.p - target).norm(), nearest = q;
    }
    return nearest;
  }

  // The pole whose point is within `near` mm of contact point c, if any.
  bool PoleNear(const ContactPoint& c, double near, Pole* pole) const {
    for (int k = 0; k < 2; ++k) {
      const double lo = k == 0 ? face_.U0() : face_.V0(), hi = k == 0 ? face_.U1() : face_.V1();
      for (const double edge : {lo, hi}) {
        Eigen::Vector2d uv = c.uv;
        uv[k] = edge;
        face_.D2(uv.x(), uv.y(), &pole->at);
        const Eigen::Vector3d& along = k == 0 ? pole->at.sv : pole->at.su;
        const Eigen::Vector3d& across = k == 0 ? pole->at.su : pole->at.sv;
        if (!(along.norm() < 1e-9 * across.norm()) || (pole->at.p - c.p).norm() > near) continue;
        pole->uv = uv;
        pole->fixed = k;
        pole->inward = edge == lo ? 1.0 : -1.0;
        pole->across_mm = across.norm();
        Eigen::Vector2d in = uv;
        in[k] += pole->inward * 1e-6 * (hi - lo);
        face_.D2(in.x(), in.y(), &pole->inside);
        return true;
      }
    }
    return false;
  }

  // The trace, at contact point `cur` (arc length s), cannot step on because the contact point
  // has come to a collapsed edge of the (u, v) parametrization (a pole: S_u or S_v vanishes along
  // an edge of the UV box): the bridge across it (see Bridge), to the point as far past the pole
  // on the parameter line that leaves it the way the contact point came in. False if `cur` is not
  // at such an edge.
  bool AcrossPole(const PassEvaluator& e, const ContactPoint& cur, double s, Bridge* piece) const {
    if (!NearPole(cur)) return false;
    const double su = cur.dp.col(0).norm(), sv = cur.dp.col(1).norm();
    // The pole's parameter: the UV box edge the collapsing direction's other parameter is near.
    const bool u_collapses = su < sv;  // then the pole is an edge v = const, meridians u = const
    const double along = u_collapses ? cur.uv.y() : cur.uv.x();
    const double lo = u_collapses ? face_.V0() : face_.U0(),
                 hi = u_collapses ? face_.V1() : face_.U1();
    const double pole = std::abs(along - lo) < std::abs(along - hi) ? lo : hi;
    Eigen::Vector2d at_pole = cur.uv;
    (u_collapses ? at_pole.y() : at_pole.x()) = pole;
    geometry::SurfaceDerivatives d;
    face_.D2(at_pole.x(), at_pole.y(), &d);
    const Eigen::Vector3d pole_point = d.p;
    // As far past the pole as the contact point is before it, on the line through the pole.
    const Eigen::Vector3d mirrored = 2.0 * pole_point - cur.p;
    Eigen::Vector2d guess = cur.uv;
    double best = INFINITY;
    const double m0 = u_collapses ? face_.U0() : face_.V0(),
                 m1 = u_collapses ? face_.U1() : face_.V1();
    constexpr int kScan = 720;
    for (int k = 0; k <= kScan; ++k) {
      Eigen::Vector2d uv = cur.uv;
      (u_collapses ? uv.x() : uv.y()) = m0 + (m1 - m0) * k / kScan;
      face_.D2(uv.x(), uv.y(), &d);
      if ((d.p - mirrored).norm() < best) best = (d.p - mirrored).norm(), guess = uv;
    }
    ContactPoint guessed;
    if (e.Evaluate(guess, &guessed) != EvalStatus::kOk) return false;
    ContactPoint exit;
    EvalStatus status;
    if (e.SolveChord(cur.tip, (guessed.tip - cur.tip).norm(), guess, spec_.newton, &exit, &status,
                     cur.guide_t) < 0 ||
        (exit.tip - cur.tip).dot(cur.tangent) <= 0.0 || exit.tangent.dot(cur.tangent) < 0.99 ||
        (exit.tip - cur.tip).norm() > 1e-2 || !e.Inside(exit.uv)) {
      return false;
    }
    piece->entry = cur;
    piece->exit = exit;
    piece->top_uv = at_pole;
    piece->top = pole_point;
    piece->tip_in = cur.tip;
    piece->direction = (exit.tip - cur.tip).normalized();
    piece->s_start = piece->s_in = s;
    piece->s_out = piece->s_exit = s + (exit.tip - cur.tip).norm();
    return true;
  }

  // Whether contact point c is next to a collapsed edge of the (u, v) parametrization (a pole: one
  // of S_u, S_v nearly vanishes there).
  static bool NearPole(const ContactPoint& c) {
    const double su = c.dp.col(0).norm(), sv = c.dp.col(1).norm();
    return std::min(su, sv) < 1e-3 * std::max(su, sv);
  }

  // Whether the tool moved straight from a to b, its axis turning as a link's straight move turns
  // it (geometry::StraightMove), stays out of the face and the checked faces: the tool checked as
  // at a contact point (DeepestToolPoint) every kRideStepMm of the move.
  bool RidesOver(const ContactPoint& a, const ContactPoint& b) const {
    constexpr double kRideStepMm = 0.05;
    const double chord = (b.tip - a.tip).norm();
    const int n = std::max(2, static_cast<int>(std::ceil(chord / kRideStepMm)));
    for (int i = 1; i < n; ++i) {
      const double t = static_cast<double>(i) / n;
      ContactPoint q = t < 0.5 ? a : b;  // where the drops start from
      q.tip = (1.0 - t) * a.tip + t * b.tip;
      q.axis = geometry::StraightMoveAxis(a.tip, b.tip, a.axis, b.axis, t);
      if (DeepestToolPoint(q).depth > kGougeMm) return false;
    }
    // The checked faces all along the move, not only at its samples (FirstInto).
    if (spec_.check) {
      const auto pose = [&](double x, Placed* out) {
        const double t = chord > 0.0 ? x / chord : 0.0;
        out->tip = (1.0 - t) * a.tip + t * b.tip;
        out->axis = geometry::StraightMoveAxis(a.tip, b.tip, a.axis, b.axis, t);
        return true;
      };
      const Placed from{a.tip, a.axis}, to{b.tip, b.axis};
      const Neighbours at_a = NeighboursAt(from), at_b = NeighboursAt(to);
      if (at_a.hit || at_b.hit ||
          FirstIntoFrom(pose, from, at_a.clearance_mm, 0.0, to, at_b.clearance_mm, chord)) {
        return false;
      }
    }
    return true;
  }

  // A pose of the tool: its tip and unit axis.
  struct Placed {
    Eigen::Vector3d tip, axis;
  };

  // Clearances of the checked faces this far from the tool are found (mm): a check within that
  // of the last few (the most the tool moved since, CheckFaces::Displacement) is not made.
  static constexpr double kCheckReachMm = 0.5;
  // FirstInto halves a way no further than this (mm).
  static constexpr double kShortestBetweenMm = 1e-4;

  struct Neighbours {
    std::optional<geometry::CheckFaces::Hit> hit;
    double clearance_mm = 0.0;  // no checked face nearer the tool (at most kCheckReachMm)
  };

  // The checked faces around the tool at pose q (spec_.check): a face deeper in it than the
  // check's tolerance, and the clearance. Where q lies within the clearance found at one of the
  // last kRemembered poses checked, less the most the tool moved from it, no face can be nearer
  // than what is left of it: nothing is looked at.
  Neighbours NeighboursAt(const Placed& q) const {
    const geometry::CheckFaces& check = *spec_.check;
    double best = -INFINITY;
    for (const Remembered& m : remembered_) {
      if (!(m.clearance_mm > 0.0)) continue;
      best =
          std::max(best, m.clearance_mm - check.Displacement(m.at.tip, m.at.axis, q.tip, q.axis));
    }
    if (best >= 0.0) return {std::nullopt, best};
    const geometry::CheckFaces::Near near = check.Around(q.tip, q.axis, kCheckReachMm);
    remembered_[next_remembered_] = {q, near.clearance_mm};
    next_remembered_ = (next_remembered_ + 1) % kRemembered;
    return {near.hit, near.clearance_mm};
  }

  // Where a checked face first goes into the tool deeper than the check's tolerance on its way
  // from pose a to pose b, both clear of them (`pose(x, &q)` places it x mm along the tip's path,
  // `length` mm long): an x where it does, or nothing. No face lies nearer the tool than c_a at a
  // and c_b at b, and no point of the tool moves more than D between them (the tip's path, and the
  // axis's turn as CheckFaces::Displacement counts it, a quarter more for a turn that is not even):
  // between them a face can come into it by at most (D - c_a - c_b) / 2. Where that may exceed
  // the tolerance the middle is checked, then each half, down to kShortestBetweenMm.
  template <typename PoseAt>
  std::optional<double> FirstInto(const PoseAt& pose, const Placed& a, const Placed& b,
                                  double length) const {
    return FirstIntoFrom(pose, a, NeighboursAt(a).clearance_mm, 0.0, b,
                         NeighboursAt(b).clearance_mm, length);
  }

  template <typename PoseAt>
  std::optional<double> FirstIntoFrom(const PoseAt& pose, const Placed& a, double c_a, double x_a,
                                      const Placed& b, double c_b, double x_b) const {
    const geometry::CheckFaces& check = *spec_.check;
    const double chord = (b.tip - a.tip).norm();
    const double turn = check.Displacement(a.tip, a.axis, b.tip, b.axis) - chord;
    const double moved = (x_b - x_a) + 1.25 * turn;
    if (c_a + c_b + 2.0 * check.ToleranceMm() >= moved || x_b - x_a < kShortestBetweenMm) {
      return std::nullopt;
    }
    const double x_m = 0.5 * (x_a + x_b);
    Placed m;
    if (!pose(x_m, &m)) return std::nullopt;
    const Neighbours at_m = NeighboursAt(m);
    if (at_m.hit) return x_m;
    if (const auto x = FirstIntoFrom(pose, a, c_a, x_a, m, at_m.clearance_mm, x_m)) return x;
    return FirstIntoFrom(pose, m, at_m.clearance_mm, x_m, b, c_b, x_b);
  }

  // FirstInto along a pass's trace from contact point `from`, h mm of the tip's path on to `to`.
  std::optional<double> FirstIntoAlong(const PassEvaluator& e, const ContactPoint& from,
                                       const ContactPoint& to, double h) const {
    if (!spec_.check) return std::nullopt;
    const auto pose = [&](double x, Placed* out) {
      ContactPoint p;
      EvalStatus st;
      int its = 0;
      if (!e.Step(from, x, spec_.newton, &p, &st, &its)) return false;
      *out = {p.tip, p.axis};
      return true;
    };
    return FirstInto(pose, {from.tip, from.axis}, {to.tip, to.axis}, h);
  }

  static constexpr const char* kOutsideBounds = "the tool tip leaves the strategy's bounds";

  // Why the tool may not be at p: its tip out of the strategy's bounds, or GougeAt.
  std::optional<std::string> UnfitAt(const ContactPoint& p) const {
    if (spec_.bounds && !spec_.bounds->Contain(p.tip)) return kOutsideBounds;
    return GougeAt(p);
  }

  // Why the tool does not fit touching the face at p (it would touch with its upper side, or go
  // into the face), or nothing.
  std::optional<std::string> GougeAt(const ContactPoint& p) const {
    // Contact above the ball's equator by less than 0.006 deg overlaps the shank by < r 1e-8.
    if (p.n.dot(p.axis) < -1e-4) {
      return fmt::format(
          "undercut: the surface normal points {:.3g} deg away from the tool axis, so the tool "
          "would touch with its upper side (use a 5-axis orientation or another side)",
          std::acos(std::clamp(p.n.dot(p.axis), -1.0, 1.0)) * 180.0 / M_PI);
    }
    if (p.concave_curvature > max_curvature_) {
      return fmt::format(
          "the tool gouges: the surface's concave radius of curvature here is {:.6g} mm, smaller "
          "than the tool's {} mm ({})",
          1.0 / p.concave_curvature, 1.0 / max_curvature_, tool_.Describe());
    }
    const Depth d = DeepestToolPoint(p);
    if (d.depth > kGougeMm) {
      return fmt::format(
          "the tool gouges: touching the face here, it goes {:.3g} mm into it at ({:.6g}, {:.6g}, "
          "{:.6g}), (u, v) = ({:.9g}, {:.9g}), {:.3g} mm from the contact point (a concave region "
          "narrower than the {}{})",
          d.depth, d.at.x(), d.at.y(), d.at.z(), d.uv.x(), d.uv.y(), (d.at - p.p).norm(),
          tool_.Describe(),
          tool_.kind == geometry::Tool::Kind::kBallEnd
              ? ": use a smaller ball"
              : ": a flat bottom cannot follow a valley; use a ball end");
    }
    if (spec_.check) {
      if (const auto hit = NeighboursAt({p.tip, p.axis}).hit) {
        return fmt::format(
            "the tool goes into {}: {:.3g} mm deep at ({:.6g}, {:.6g}, {:.6g}), (u, v) = ({:.9g}, "
            "{:.9g}) on that face",
            hit->where, hit->depth_mm, hit->at.x(), hit->at.y(), hit->at.z(), hit->uv.x(),
            hit->uv.y());
      }
    }
    return std::nullopt;
  }

  // A point of the tool further into the face than this is a gouge (the Newton tolerance).
  static constexpr double kGougeMm = 1e-6;

  struct Depth {
    double depth = -INFINITY;  // mm under the face (along its normal at the foot)
    Eigen::Vector3d at = Eigen::Vector3d::Zero();
    Eigen::Vector2d uv = Eigen::Vector2d::Zero();
  };

  // The deepest point of the tool's lower side (its flat bottom, and its corner from the bottom
  // to the widest circle) when it touches the face at p, if more than kGougeMm deep (else depth
  // -inf). Points of the side are dropped along the tool axis onto the face (Newton in (u, v) from
  // the contact point), and a point's depth is how far it lies under the face's tangent plane
  // there. The side is sampled on a grid (16 directions around the axis, 2 rings of the bottom, 4
  // angles of the corner), and around every sample that comes closer to the face than its
  // neighbours (away from the contact itself), the closest point is searched for between them: a
  // corner touching between two samples of a 1 mm corner could otherwise go 0.01 mm into the face
  // unseen. Points with no face below them (off the face's domain, or no convergence on a wall
  // along the axis) are left out. The contact's own curvature is GougeAt's first test; this one
  // finds the face rising into the tool further away, where no local test can (a flat bottom
  // across a valley, a ball over a bump beside the contact).
  Depth DeepestToolPoint(const ContactPoint& p) const {
    const Eigen::Vector3d& a = p.axis;
    Eigen::Vector3d e1 = p.n - p.n.dot(a) * a;
    e1 = e1.norm() > 1e-9 ? e1.normalized() : Eigen::Vector3d(a.unitOrthogonal());
    const Eigen::Vector3d e2 = a.cross(e1);
    const double r = tool_.corner_radius, big_r = tool_.TorusRadius();
    constexpr int kAround = 16, kRings = 2, kCorner = 4;
    Depth deepest;
    geometry::SurfaceDerivatives d;
    // The depth of tool point x (-inf: no face under it).
    const auto drop = [&](const Eigen::Vector3d& x) -> double {
      // (S(u, v) - x) . e1 = (S(u, v) - x) . e2 = 0, from the contact's first-order guess.
      Eigen::Matrix2d j;
      j << e1.dot(p.dp.col(0)), e1.dot(p.dp.col(1)), e2.dot(p.dp.col(0)), e2.dot(p.dp.col(1));
      if (!(std::abs(j.determinant()) > 1e-12)) return -INFINITY;
      Eigen::Vector2d uv =
          p.uv - j.inverse() * Eigen::Vector2d((p.p - x).dot(e1), (p.p - x).dot(e2));
      for (int it = 0; it < 12; ++it) {
        if (!face_.InBox(uv.x(), uv.y())) return -INFINITY;
        face_.D2(uv.x(), uv.y(), &d);
        const Eigen::Vector3d off = d.p - x;
        const Eigen::Vector2d f(off.dot(e1), off.dot(e2));
        if (f.norm() <= 1e-10) {
          // How far the point lies under the face's tangent plane at the foot (on a wall nearly
          // along the axis, the depth along the axis would magnify a rounding error).
          // A point above the face along the axis counts as no deeper than touching it.
          const Eigen::Vector3d normal = d.su.cross(d.sv);
          const double under = off.dot(normal) * (static_cast<double>(side_) / normal.norm());
          const double depth = off.dot(a) > 0.0 ? under : std::min(under, 0.0);
          // Only a gouge asks whether the face is there (near a trimming loop the classifier).
          if (depth > std::max(deepest.depth, kGougeMm) && face_.Inside(uv.x(), uv.y())) {
            deepest = {depth, x, uv};
          }
          return depth;
        }
        j << e1.dot(d.su), e1.dot(d.sv), e2.dot(d.su), e2.dot(d.sv);
        if (!(std::abs(j.determinant()) > 1e-12)) return -INFINITY;
        uv -= j.inverse() * f;
      }
      return -INFINITY;
    };
    // The side's point at angle phi around the axis and position t along its outline: t in
    // [0, kRings] on the bottom (radius R t / kRings), then the corner (angle 90 deg (t - kRings)
    // / kCorner from the bottom).
    const bool bottom = big_r > 0.0, corner = r > 0.0;
    // (A ball has no bottom: its outline starts at the tip, t = kRings, sampled once.)
    const double t0 = bottom ? 1.0 : kRings + 1.0, t1 = corner ? kRings + kCorner : kRings;
    const double t_min = bottom ? 0.0 : kRings;
    const auto point = [&](double phi, double t) -> Eigen::Vector3d {
      const Eigen::Vector3d e = std::cos(phi) * e1 + std::sin(phi) * e2;
      if (t <= kRings) return p.tip + e * (big_r * t / kRings);
      const double psi = 0.5 * M_PI * (t - kRings) / kCorner;
      return p.tip + r * a + big_r * e + r * (std::sin(psi) * e - std::cos(psi) * a);
    };
    drop(p.tip);
    const int n_t = static_cast<int>(t1 - t0) + 1;
    std::vector<double> grid(static_cast<std::size_t>(kAround * n_t));
    const auto at = [&](int k, int i) -> double& {
      return grid[static_cast<std::size_t>(((k + kAround) % kAround) * n_t + i)];
    };
    const double dphi = 2.0 * M_PI / kAround;
    for (int k = 0; k < kAround; ++k) {
      for (int i = 0; i < n_t; ++i) at(k, i) = drop(point(k * dphi, t0 + i));
    }
    // Refine around the local maxima of the depth that are not the contact: coordinate-wise
    // golden sections over the cell on either side, twice. Between two samples the side is
    // nearer the face than they are by at most about (R + r) (1 - cos 11.25 deg) < 0.02 (R + r):
    // samples farther from it cannot hide a gouge.
    const double near = 0.05 * (big_r + r) + 1e-3;
    for (int k = 0; k < kAround; ++k) {
      for (int i = 0; i < n_t; ++i) {
        const double v = at(k, i);
        if (!std::isfinite(v) || v < -0.03 * (big_r + r)) continue;
        bool top = true;
        for (int dk = -1; dk <= 1 && top; ++dk) {
          for (int di = -1; di <= 1; ++di) {
            if ((dk || di) && i + di >= 0 && i + di < n_t && at(k + dk, i + di) > v) top = false;
          }
        }
        if (!top || (point(k * dphi, t0 + i) - p.p).norm() < near) continue;
        double phi = k * dphi, t = t0 + i;
        for (int round = 0; round < 2; ++round) {
          for (int axis = 0; axis < 2; ++axis) {
            const double lo = axis == 0 ? phi - dphi : std::max(t_min, t - 1.0);
            const double hi = axis == 0 ? phi + dphi : std::min(t1, t + 1.0);
            const auto f = [&](double x) {
              return axis == 0 ? drop(point(x, t)) : drop(point(phi, x));
            };
            (axis == 0 ? phi : t) = GoldenSectionMax(f, lo, hi, 6).first;
          }
        }
      }
    }
    return deepest;
  }

  const geometry::FaceSurface& face_;
  const geometry::Tool& tool_;
  const Orientation& orientation_;
  const StrategySpec& spec_;
  int side_ = 1;
  double max_curvature_ = INFINITY;
  double lo_ = 0.0, hi_ = 0.0;
  // Why the last pass that could not start from a root was refused (none: no such pass).
  mutable std::optional<EvalStatus> refused_;
  // SeedGrid's values, for the feed along and against the strategy's direction.
  mutable std::vector<double> seed_grid_[2];
  // The last poses checked against the checked faces, and their clearances (NeighboursAt).
  static constexpr std::size_t kRemembered = 4;
  struct Remembered {
    Placed at{Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitZ()};
    double clearance_mm = -INFINITY;
  };
  mutable std::array<Remembered, kRemembered> remembered_{};
  mutable std::size_t next_remembered_ = 0;
};

}  // namespace

const char* StrategySpec::KindName(Kind kind) {
  switch (kind) {
    case Kind::kPlaneCl:
      return "plane_cl";
    case Kind::kPlaneCc:
      return "plane_cc";
    case Kind::kUv:
      return "uv";
    case Kind::kLeadingLine:
      return "leading_line";
  }
  return "?";
}

std::string PassList::UnreachableText(std::size_t most) const {
  if (unreachable.empty()) return "";
  double total = 0.0;
  for (const Unreachable& u : unreachable) total += u.length_mm;
  std::string out = fmt::format(
      "{} stretch{} of the strategy's lines left out where the tool does not fit: {:.6g} mm along "
      "the face, about {:.3g} mm^2 at the stepover\n",
      unreachable.size(), unreachable.size() == 1 ? "" : "es", total, total * stepover_mm);
  for (std::size_t k = 0; k < unreachable.size() && k < most; ++k) {
    const Unreachable& u = unreachable[k];
    out += fmt::format(
        "  {}line {}, {:.6g} mm from ({:.6g}, {:.6g}, {:.6g}) to ({:.6g}, {:.6g}, "
        "{:.6g}){}: {}\n",
        u.face.empty() ? "" : u.face + ", ", u.line, u.length_mm, u.from.x(), u.from.y(),
        u.from.z(), u.to.x(), u.to.y(), u.to.z(),
        u.ridden_over ? " (the tool rides over it)"
        : u.resumes   ? ""
                      : " (the line is not traced past it)",
        u.why);
  }
  if (unreachable.size() > most) {
    out += fmt::format("  and {} more\n", unreachable.size() - most);
  }
  return out;
}

std::string PassList::Summary() const {
  double total = 0.0;
  for (const auto& p : passes) total += *p->Length();
  return fmt::format("{} passes, {:.6g} mm of tip path, stepover {:.6g} mm", passes.size(), total,
                     stepover_mm);
}

double StepoverFromScallop(const geometry::Tool& tool, const Orientation& orientation, double h) {
  if (!(h > 0.0)) throw Error("scallop height: expected a positive number of mm, got {}", h);
  double radius = tool.corner_radius;
  if (tool.kind == geometry::Tool::Kind::kBallEnd) radius = tool.radius;
  if (tool.kind != geometry::Tool::Kind::kBallEnd &&
      orientation.kind == Orientation::Kind::kTiltYaw && orientation.tilt_rad != 0.0) {
    radius = tool.corner_radius + tool.TorusRadius() / std::abs(std::sin(orientation.tilt_rad));
  }
  if (!(radius > h)) {
    throw Error(
        "scallop height {} mm: the tool's effective radius across the feed is {} mm; "
        "give stepover_mm instead",
        h, radius);
  }
  return 2.0 * std::sqrt(h * (2.0 * radius - h));
}

PassList BuildPasses(const geometry::FaceSurface& face, const geometry::Tool& tool,
                     const Orientation& orientation, const StrategySpec& spec) {
  Builder builder(face, tool, orientation, spec);
  return builder.Build();
}

}  // namespace dtis::strategies
