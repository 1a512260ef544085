#include "dtis/strategies/surface_pass.hpp"

#include <ceres/jet.h>
#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <limits>

#include "dtis/geometry/angle.hpp"

namespace dtis::strategies {
namespace {

using Jet = ceres::Jet<double, 2>;
using Vec3J = Eigen::Matrix<Jet, 3, 1>;

Jet Seed(double value, double du, double dv) {
  Jet j(value);
  j.v << du, dv;
  return j;
}

Eigen::Vector3d Value(const Vec3J& v) { return {v.x().a, v.y().a, v.z().a}; }

Eigen::Matrix<double, 3, 2> Gradient(const Vec3J& v) {
  Eigen::Matrix<double, 3, 2> m;
  for (int i = 0; i < 3; ++i) m.row(i) = v[i].v.transpose();
  return m;
}

}  // namespace

const char* EvalStatusText(EvalStatus status) {
  switch (status) {
    case EvalStatus::kOk:
      return "ok";
    case EvalStatus::kDegenerateNormal:
      return "the surface normal is undefined (S_u x S_v vanishes: a collapsed edge or pole)";
    case EvalStatus::kFeedUndefined:
      return "the feed direction is undefined (the surface normal is along the strategy plane's "
             "normal)";
    case EvalStatus::kFlatContact:
      return "the tool sits flat on the surface (normal along the tool axis) where it is not a "
             "top, a ridge or a plane (a saddle, the edge of a flat region), or the strategy holds "
             "the contact point there: the bottom rests on more than one place; tilt the tool or "
             "use a ball end";
    case EvalStatus::kGuideFold:
      return "the guide curve bends tighter than the pass's offset from it (its radius of "
             "curvature here is within 1 % of the offset): the offset line folds over itself; "
             "use offsets below the guide's radius of curvature or a smoother guide";
    case EvalStatus::kStalled:
      return "the pass has no direction here (the constraint is singular)";
  }
  return "?";
}

std::string PassConstraint::Describe() const {
  switch (kind) {
    case Kind::kPlaneCl:
    case Kind::kPlaneCc:
      return fmt::format("{} plane ({:.6g}, {:.6g}, {:.6g}) . x = {:.9g} mm",
                         kind == Kind::kPlaneCl ? "tip" : "contact", normal.x(), normal.y(),
                         normal.z(), value);
    case Kind::kIsoV:
      return fmt::format("iso-v line v = {:.9g}", value);
    case Kind::kIsoU:
      return fmt::format("iso-u line u = {:.9g}", value);
    case Kind::kGuide:
      return fmt::format("guide curve offset {:.9g} mm", value);
  }
  return "?";
}

PassEvaluator::PassEvaluator(const geometry::FaceSurface& face, const geometry::Tool& tool,
                             const Orientation& orientation, int side,
                             const PassConstraint& constraint)
    : face_(face), tool_(tool), orientation_(orientation), side_(side), constraint_(constraint) {}

EvalStatus PassEvaluator::EvaluateAt(const Eigen::Vector2d& uv, double at_s, ContactPoint* out,
                                     double guide_hint) const {
  Eigen::Vector3d guide_point = Eigen::Vector3d::Zero();
  Eigen::Vector2d guide_left = Eigen::Vector2d::Zero();
  geometry::SurfaceDerivatives d;
  face_.D2(uv.x(), uv.y(), &d);
  Vec3J s, su, sv;
  for (int i = 0; i < 3; ++i) {
    s[i] = Seed(d.p[i], d.su[i], d.sv[i]);
    su[i] = Seed(d.su[i], d.suu[i], d.suv[i]);
    sv[i] = Seed(d.sv[i], d.suv[i], d.svv[i]);
  }
  const Vec3J big_n = su.cross(sv);
  const Jet n_norm = sqrt(big_n.squaredNorm());
  // Degenerate: S_u and S_v parallel, or one of them vanishing against the other (a collapsed edge:
  // there the vanishing tangent is rounding noise, whose direction means nothing).
  const double longer = std::max(d.su.norm(), d.sv.norm());
  if (!(n_norm.a > 1e-10 * longer * longer) || !(n_norm.a > 1e-300)) {
    return EvalStatus::kDegenerateNormal;
  }
  const Vec3J n = big_n * (Jet(side_) / n_norm);
  out->guide_fold = 0.0;
  Vec3J f;
  switch (constraint_.kind) {
    case PassConstraint::Kind::kPlaneCl:
    case PassConstraint::Kind::kPlaneCc: {
      const Vec3J m = n.cross(constraint_.normal.cast<Jet>());
      const Jet m_norm = sqrt(m.squaredNorm());
      if (!(m_norm.a > 1e-9)) return EvalStatus::kFeedUndefined;
      f = m * (Jet(constraint_.feed_sign) / m_norm);
      break;
    }
    case PassConstraint::Kind::kGuide: {
      Eigen::Vector3d gd[3];
      out->guide_t = ClosestOnGuide(*constraint_.guide, d.p.x(), d.p.y(), guide_hint, gd);
      const Eigen::Vector2d tangent(gd[1].x(), gd[1].y());
      if (!(tangent.norm() > 0.0)) return EvalStatus::kFeedUndefined;
      const Eigen::Vector2d left = Eigen::Vector2d(-tangent.y(), tangent.x()).normalized();
      const double curvature =
          (gd[1].x() * gd[2].y() - gd[1].y() * gd[2].x()) / std::pow(tangent.norm(), 3);
      out->guide_fold =
          curvature * Eigen::Vector2d(d.p.x() - gd[0].x(), d.p.y() - gd[0].y()).dot(left);
      guide_point = gd[0];
      guide_left = left;
      const Vec3J m = Eigen::Vector3d(left.x(), left.y(), 0.0).cast<Jet>();
      const Vec3J cross = n.cross(m);
      const Jet c_norm = sqrt(cross.squaredNorm());
      if (!(c_norm.a > 1e-9)) return EvalStatus::kFeedUndefined;
      f = cross * (Jet(constraint_.feed_sign) / c_norm);
      break;
    }
    case PassConstraint::Kind::kIsoV:
    case PassConstraint::Kind::kIsoU: {
      const Vec3J& t = constraint_.kind == PassConstraint::Kind::kIsoV ? su : sv;
      const Jet t_norm = sqrt(t.squaredNorm());
      if (!(t_norm.a > 1e-300)) return EvalStatus::kDegenerateNormal;
      f = t * (Jet(constraint_.feed_sign) / t_norm);
      break;
    }
  }
  const bool on_law = law_ != nullptr && std::isfinite(at_s);
  Eigen::Vector3d law_turn = Eigen::Vector3d::Zero();  // d a / d s
  const Vec3J a =
      on_law ? Vec3J(law_->At(at_s, &law_turn).cast<Jet>()) : Vec3J(ToolAxis(orientation_, n, f));
  Vec3J tip;
  bool flat = false;  // sitting flat where the contact point does not fix the tip
  if (!geometry::TipFromContact(tool_, s, n, a, &tip)) {
    // Sitting flat. Where the face is flat too (a plane across the axis), the whole bottom
    // touches and the tool is placed with its tip on the contact point; at a top (the face
    // bends away) the contact point does not fix the tip: the builder's Bridge. A strategy that
    // holds the contact point still gets its residual there (the tip on the contact point, one
    // of the places the tool may stand), with kFlatContact.
    const Eigen::Vector3d nv = Value(n);
    const double e = d.su.squaredNorm(), g = d.sv.squaredNorm();
    const double bend = std::max({std::abs(nv.dot(d.suu)) / e, std::abs(nv.dot(d.svv)) / g,
                                  std::abs(nv.dot(d.suv)) / std::sqrt(e * g)});
    flat = !(bend < 1e-9);
    if (flat && constraint_.kind == PassConstraint::Kind::kPlaneCl) {
      return EvalStatus::kFlatContact;
    }
    tip = s + (n - a) * Jet(tool_.corner_radius);
  }
  Jet g;
  switch (constraint_.kind) {
    case PassConstraint::Kind::kPlaneCl:
      g = tip.dot(constraint_.normal.cast<Jet>()) - Jet(constraint_.value);
      break;
    case PassConstraint::Kind::kPlaneCc:
      g = s.dot(constraint_.normal.cast<Jet>()) - Jet(constraint_.value);
      break;
    case PassConstraint::Kind::kIsoV:
      g = (Seed(uv.y(), 0.0, 1.0) - Jet(constraint_.value)) * Jet(constraint_.iso_scale);
      break;
    case PassConstraint::Kind::kIsoU:
      g = (Seed(uv.x(), 1.0, 0.0) - Jet(constraint_.value)) * Jet(constraint_.iso_scale);
      break;
    case PassConstraint::Kind::kGuide:
      // The signed distance to the guide in XY; its gradient is the normal at the closest point.
      g = (s.x() - Jet(guide_point.x())) * Jet(guide_left.x()) +
          (s.y() - Jet(guide_point.y())) * Jet(guide_left.y()) - Jet(constraint_.value);
      break;
  }
  out->uv = uv;
  out->p = d.p;
  out->n = Value(n);
  out->feed = Value(f);
  out->axis = Value(a);
  out->s = on_law ? at_s : std::numeric_limits<double>::quiet_NaN();
  out->rule_axis = on_law ? ToolAxis(orientation_, out->n, out->feed) : out->axis;
  out->tip = Value(tip);
  out->dp << d.su, d.sv;
  out->dtip = Gradient(tip);
  out->g = g.a;
  out->dg = g.v;
  // The travel: the direction in (u, v) that keeps g = 0, oriented along the feed.
  Eigen::Vector2d perp(-out->dg.y(), out->dg.x());
  Eigen::Vector3d w = out->dtip * perp;
  const double speed = w.norm();
  if (!(speed > 1e-12 * (1.0 + out->dg.norm()))) return EvalStatus::kStalled;
  if (w.dot(out->feed) < 0.0) perp = -perp, w = -w;
  out->duv = perp / speed;
  out->tangent = w / speed;
  if (on_law) {
    // The axis turns along s by law_turn, which moves the tip (and, for plane_cl, g) at a fixed
    // contact point: the travel is uv' = q + lambda perp with g's derivative along s zero and
    // |tip'| = 1, tip' = w0 + lambda w1.
    const Eigen::Vector3d an = out->axis, nv = out->n;
    Eigen::Vector3d tip_s = -tool_.corner_radius * law_turn;
    const double big_r = tool_.TorusRadius();
    if (big_r > 0.0) {
      const Eigen::Vector3d side = nv - an * nv.dot(an);
      const double norm = side.norm();
      if (norm > geometry::kFlatContactSine) {
        const Eigen::Vector3d u = side / norm;
        const Eigen::Vector3d d_side = -(law_turn * nv.dot(an) + an * nv.dot(law_turn));
        tip_s += big_r * (d_side - u * u.dot(d_side)) / norm;
      }
    }
    const double g_s =
        constraint_.kind == PassConstraint::Kind::kPlaneCl ? constraint_.normal.dot(tip_s) : 0.0;
    const Eigen::Vector2d q = -out->dg * (g_s / out->dg.squaredNorm());
    const Eigen::Vector3d w0 = out->dtip * q + tip_s, w1 = out->dtip * (out->duv);
    const double aa = w1.squaredNorm(), bb = w0.dot(w1), cc = w0.squaredNorm() - 1.0;
    const double disc = bb * bb - aa * cc;
    if (!(disc >= 0.0) || !(aa > 0.0)) return EvalStatus::kStalled;
    const double lambda = (-bb + std::sqrt(disc)) / aa;
    out->duv = q + lambda * out->duv;
    out->tangent = (w0 + lambda * w1).normalized();
  }
  // With the normal on the tool's side: positive bends towards the tool.
  out->concave_curvature = CurvatureTowards(d, out->n);
  return flat ? EvalStatus::kFlatContact : EvalStatus::kOk;
}

double CurvatureTowards(const geometry::SurfaceDerivatives& d, const Eigen::Vector3d& n) {
  const double e = d.su.dot(d.su), ff = d.su.dot(d.sv), gg = d.sv.dot(d.sv);
  const double l = n.dot(d.suu), m = n.dot(d.suv), nn = n.dot(d.svv);
  const double det1 = e * gg - ff * ff, b = e * nn - 2.0 * ff * m + gg * l, det2 = l * nn - m * m;
  const double disc = std::max(0.0, b * b - 4.0 * det1 * det2);
  return (b + std::sqrt(disc)) / (2.0 * det1);
}

namespace {

// On the inside of a guide's bend, as far from it as its radius of curvature, the closest point
// stops being one (the distance is stationary there, then largest): the offset line folds over
// itself, and which stationary point a solve finds depends on where it starts. A solution is
// refused short of it, where the closest point already moves a hundred times faster than the
// contact point.
bool Folded(const ContactPoint& c, EvalStatus* status) {
  if (!(c.guide_fold > 0.99)) return false;
  *status = EvalStatus::kGuideFold;
  return true;
}

}  // namespace

int PassEvaluator::Solve(const Eigen::Vector3d& anchor, const Eigen::Vector3d* anchor_tangent,
                         double target, double anchor_guide_t, Eigen::Vector2d uv,
                         const NewtonOptions& options, ContactPoint* out, EvalStatus* status,
                         double s) const {
  // F1 = g; F2 = m - target, with m the chord |tip - anchor|, or with an anchor tangent the arc
  // from the chord and the two tangents. The Jacobian of the arc is the chord's scaled by
  // arc / chord: it leaves out how the tangents' angle moves, a relative term of order
  // theta^2 / 12, so the iteration still converges at once.
  const double limit = std::max(4.0 * target, options.max_step_mm);
  // A chord solve that runs out of iterations may stand within the tolerance; an arc solve must
  // meet its arc tightly (summed arcs must agree, see NewtonOptions::arc_tolerance_mm).
  const double f2_at_worst = anchor_tangent ? options.arc_tolerance_mm : options.tolerance_mm;
  double hint = anchor_guide_t;
  for (int it = 0;; ++it) {
    *status = EvaluateAt(uv, s, out, hint);
    if (*status != EvalStatus::kOk) return -1;
    hint = out->guide_t;
    const Eigen::Vector3d d = out->tip - anchor;
    const double dist = d.norm();
    const double m = anchor_tangent ? ArcFromChord(dist, *anchor_tangent, out->tangent) : dist;
    const double f1 = out->g, f2 = m - target;
    // Converge as far as Newton goes cheaply: poses that sit anywhere within the tolerance would
    // jitter from one setpoint to the next by up to twice it, which the axis jerk sees (a period's
    // jerk budget is J dt^3, 5e-6 mm at 5 m/s^3 and 1 ms). The tolerance is what must hold.
    if (std::abs(f1) <= options.arc_tolerance_mm && std::abs(f2) <= options.arc_tolerance_mm) {
      return Folded(*out, status) ? -1 : it;
    }
    if (it == options.max_iterations || !(dist > 0.0)) {
      return std::abs(f1) <= options.tolerance_mm && std::abs(f2) <= f2_at_worst &&
                     !Folded(*out, status)
                 ? it
                 : -1;
    }
    Eigen::Matrix2d j;
    j.row(0) = out->dg.transpose();
    j.row(1) = (d.transpose() * out->dtip) * (m / (dist * dist));
    const double det = j.determinant();
    if (!(std::abs(det) > 1e-300)) return -1;
    Eigen::Vector2d step = -j.inverse() * Eigen::Vector2d(f1, f2);
    const double move = (out->dtip * step).norm();
    if (move > limit) step *= limit / move;
    uv += step;
  }
}

int PassEvaluator::SolveChord(const Eigen::Vector3d& anchor, double chord, Eigen::Vector2d uv,
                              const NewtonOptions& options, ContactPoint* out, EvalStatus* status,
                              double anchor_guide_t, double s) const {
  return Solve(anchor, nullptr, chord, anchor_guide_t, uv, options, out, status, s);
}

int PassEvaluator::SolveArc(const ContactPoint& from, double delta, Eigen::Vector2d uv,
                            const NewtonOptions& options, ContactPoint* out,
                            EvalStatus* status) const {
  return Solve(from.tip, &from.tangent, std::abs(delta), from.guide_t, uv, options, out, status,
               from.s + delta);
}

bool PassEvaluator::Step(const ContactPoint& from, double delta, const NewtonOptions& options,
                         ContactPoint* to, EvalStatus* status, int* iterations) const {
  const int its = SolveArc(from, delta, from.uv + from.duv * delta, options, to, status);
  if (its < 0) return false;
  *iterations += its;
  // The arc sphere is cut by the pass twice: make sure the solve took the requested side. And a
  // step that turns the tangent by more than kMaxTurn may have jumped to another branch of the
  // strategy's line: the caller retries shorter.
  // Likewise when the contact point runs far ahead of the tip (a concave radius not much larger
  // than the tool's: the contact moves rho / (rho - r) times faster).
  constexpr double kMaxTurn = 0.05;  // rad: a radius of curvature of 2 mm at 0.1 mm steps
  return (to->tip - from.tip).dot(from.tangent) * delta > 0.0 &&
         from.tangent.dot(to->tangent) > std::cos(kMaxTurn) &&
         (to->p - from.p).norm() <= std::max(1.5 * options.max_step_mm, 4.0 * std::abs(delta));
}

ContactPoint PassEvaluator::LastInside(const ContactPoint& inside, double sign, double chord_out,
                                       const NewtonOptions& options) const {
  constexpr double kBoundaryMm = 1e-10;
  double lo = 0.0, hi = chord_out;
  ContactPoint best = inside, p;
  EvalStatus status;
  while (hi - lo > kBoundaryMm) {
    const double mid = 0.5 * (lo + hi);
    const Eigen::Vector2d guess = inside.uv + inside.duv * (sign * mid);
    if (SolveChord(inside.tip, mid, guess, options, &p, &status, inside.guide_t,
                   inside.s + sign * mid) >= 0 &&
        (p.tip - inside.tip).dot(inside.tangent) * sign > 0.0 && Inside(p.uv)) {
      lo = mid;
      best = p;
    } else {
      hi = mid;
    }
  }
  return best;
}

double ClosestOnGuide(const geometry::BSplineCurve& guide, double x, double y, double hint,
                      Eigen::Vector3d at[3]) {
  const double t0 = guide.FirstParameter(), t1 = guide.LastParameter();
  const Eigen::Vector2d p(x, y);
  const auto dist2 = [&](double t) {
    const Eigen::Vector3d q = guide.Point(t);
    return (Eigen::Vector2d(q.x(), q.y()) - p).squaredNorm();
  };
  Eigen::Vector3d d[3];
  double d_at = std::numeric_limits<double>::quiet_NaN();  // where d was evaluated
  const auto newton = [&](double t) {
    for (int it = 0; it < 30; ++it) {
      guide.Derivatives(t, 2, d);
      d_at = t;
      const Eigen::Vector2d r(d[0].x() - x, d[0].y() - y), g1(d[1].x(), d[1].y()),
          g2(d[2].x(), d[2].y());
      const double f = r.dot(g1), fp = g1.squaredNorm() + r.dot(g2);
      if (!(fp > 0.0)) break;
      const double next = std::clamp(t - f / fp, t0, t1);
      // Within 1e-15 of the root: t is the answer (its derivatives are at hand).
      if (std::abs(next - t) <= 1e-15 * (1.0 + std::abs(t))) return t;
      t = next;
    }
    return t;
  };
  double best = std::numeric_limits<double>::quiet_NaN();
  if (std::isfinite(hint)) best = newton(hint);
  // From a scan when there is no hint, or when the hint's answer is not a local minimum inside.
  if (!std::isfinite(best)) {
    constexpr int kScan = 256;
    double t_best = t0, d_best = INFINITY;
    for (int k = 0; k <= kScan; ++k) {
      const double t = t0 + (t1 - t0) * k / kScan;
      const double dd = dist2(t);
      if (dd < d_best) d_best = dd, t_best = t;
    }
    best = newton(t_best);
  }
  if (at != nullptr) {
    if (!(d_at == best)) guide.Derivatives(best, 2, d);
    std::copy(d, d + 3, at);
  }
  return best;
}

double ArcFromChord(double chord, const Eigen::Vector3d& ta, const Eigen::Vector3d& tb) {
  const double theta = geometry::Angle(ta, tb);
  const double h = 0.5 * theta;
  if (h < 1e-4) return chord * (1.0 + h * h / 6.0);
  return chord * h / std::sin(h);
}

Eigen::Vector3d Bridge::Tip(double s) const {
  const Eigen::Vector3d tip_out = tip_in + (s_out - s_in) * direction;
  if (s <= s_in) {
    return s_in > s_start ? entry.tip + (tip_in - entry.tip) * ((s - s_start) / (s_in - s_start))
                          : tip_in;
  }
  if (s <= s_out) return tip_in + (s - s_in) * direction;
  return s_exit > s_out ? tip_out + (exit.tip - tip_out) * ((s - s_out) / (s_exit - s_out))
                        : tip_out;
}

SurfacePass::SurfacePass(const PassEvaluator& evaluator, int index, const ContactPoint& start,
                         const ContactPoint& end, double length, const NewtonOptions& options,
                         std::vector<Bridge> bridges, std::vector<double> knot_lines)
    : eval_(evaluator),
      index_(index),
      start_(start),
      end_(end),
      length_(length),
      options_(options),
      bridges_(std::move(bridges)),
      knot_lines_(std::move(knot_lines)) {}

const Bridge* SurfacePass::BridgeAt(double s) const {
  for (const Bridge& f : bridges_) {
    if (s >= f.s_start && s <= f.s_exit) return &f;
  }
  return nullptr;
}

PathSample SurfacePass::OnBridge(const Bridge& flat, double s) const {
  PathSample out;
  out.state.s = s;
  out.state.u = flat.top_uv.x();
  out.state.v = flat.top_uv.y();
  out.state.w = std::numeric_limits<double>::quiet_NaN();
  out.state.piece = static_cast<std::int32_t>(&flat - bridges_.data()) + 1;
  out.pose = {flat.Tip(s), flat.entry.axis};
  return out;
}

std::vector<double> SurfacePass::Breaks(double s0, double s1) const {
  std::vector<double> out;
  for (const Bridge& f : bridges_) {
    for (const double b : {f.s_in, f.s_out}) {
      if (b >= s0 && b <= s1) out.push_back(b);
    }
  }
  for (const double k : knot_lines_) {
    if (k >= s0 && k <= s1) out.push_back(k);
  }
  std::sort(out.begin(), out.end());
  return out;
}

PathState SurfacePass::Start() const {
  PathState st;
  st.u = start_.uv.x();
  st.v = start_.uv.y();
  st.w = start_.guide_t;
  return st;
}

Pose SurfacePass::StartPose() const { return {start_.tip, start_.axis}; }
Pose SurfacePass::EndPose() const { return {end_.tip, end_.axis}; }

EvalStatus SurfacePass::Evaluate(const PathState& state, ContactPoint* out) const {
  if (state.piece > 0 && static_cast<std::size_t>(state.piece) <= bridges_.size()) {
    // On a top: the bottom sits on it, the normal is the axis.
    const Bridge& f = bridges_[static_cast<std::size_t>(state.piece - 1)];
    *out = f.entry;
    out->uv = f.top_uv;
    out->p = f.top;
    out->n = f.entry.axis;
    out->tip = f.Tip(state.s);
    out->tangent = f.direction;
    // The contact point stays on the strategy's line; a plane_cl line holds the tip.
    const PassConstraint& c = eval_.Constraint();
    out->g = c.kind == PassConstraint::Kind::kPlaneCl ? c.normal.dot(out->tip) - c.value : 0.0;
    return EvalStatus::kOk;
  }
  return eval_.EvaluateAt({state.u, state.v}, LawS(state.s), out, state.w);
}

const ContactPoint& SurfacePass::From(const PathState& state, int* slot) const {
  const Eigen::Vector2d uv(state.u, state.v);
  for (int k = 0; k < 2; ++k) {
    if (cache_valid_[k] && cache_[k].uv == uv) return cache_[*slot = k];
  }
  *slot = 0;
  if (uv == start_.uv) return start_;
  if (uv == end_.uv) return end_;
  // States come from this pass, so they evaluate; if one does not, the next solve reports it.
  eval_.EvaluateAt(uv, LawS(state.s), &cache_[0], state.w);
  cache_valid_[0] = true;
  return cache_[0];
}

PathSample SurfacePass::At(const PathState& from, double s) const {
  PathSample out;
  if (s <= 0.0) {
    out.state = Start();
    out.pose = StartPose();
    return out;
  }
  // Past the end: the pose at the end, reached by marching like any other (so that it agrees with
  // the poses before it to the arc tolerance, not just to the trace's).
  const double target = std::min(s, length_);
  if (s > length_) out.status = PathStatus::kEnd;
  if (const Bridge* flat = BridgeAt(target)) {
    const PathStatus status = out.status;
    out = OnBridge(*flat, target);
    out.status = status;
    return out;
  }
  int from_slot = 0;
  ContactPoint cur;
  double cur_s = from.s;
  if (from.piece > 0 && static_cast<std::size_t>(from.piece) <= bridges_.size()) {
    // From a top: march on from the contact point on the side of the target.
    const Bridge& f = bridges_[static_cast<std::size_t>(from.piece - 1)];
    const bool ahead = target > from.s;
    cur = ahead ? f.exit : f.entry;
    cur_s = ahead ? f.s_exit : f.s_start;
  } else {
    cur = From(from, &from_slot);
  }
  // The march stops at the traced contact point before a top it would cross, and goes on from
  // the one after it.
  const auto next_bridge = [&]() -> const Bridge* {
    if (target > cur_s) {
      for (const Bridge& f : bridges_) {
        if (f.s_start >= cur_s && f.s_start < target) return &f;
      }
    } else {
      for (auto f = bridges_.rbegin(); f != bridges_.rend(); ++f) {
        if (f->s_exit <= cur_s && f->s_exit > target) return &*f;
      }
    }
    return nullptr;
  };
  const Bridge* hop = next_bridge();
  // The march and the builder's trace sum their arcs over different steps: they agree to far
  // better than this. Within it of an end, the face's boundary is that end.
  constexpr double kSnapMm = 1e-4;
  // A pass may skim the boundary between its ends by what the trace's step cannot see; more than
  // this off the face is another pass.
  constexpr double kOffFaceMm = 1e-2;
  bool stalled = false;
  double longest = options_.max_step_mm;
  for (;;) {
    const double goal = hop ? (target > cur_s ? hop->s_start : hop->s_exit) : target;
    // A rounding error from the target is the target: a step of 1e-16 mm is below what the
    // Newton of a step resolves, and the march would halve it until it gave up (the look-ahead's
    // searches ask for such arc lengths).
    if (std::abs(goal - cur_s) < 1e-12 * (1.0 + std::abs(goal))) cur_s = goal;
    if (hop && cur_s == goal) {
      const bool ahead = target > cur_s;
      cur = ahead ? hop->exit : hop->entry;
      cur_s = ahead ? hop->s_exit : hop->s_start;
      hop = next_bridge();
      continue;
    }
    if (target == cur_s || stalled) break;
    const double delta = std::clamp(goal - cur_s, -longest, longest);
    ContactPoint next;
    EvalStatus status = EvalStatus::kOk;
    if (!eval_.Step(cur, delta, options_, &next, &status, &out.iterations)) {
      // Shorter steps where the pass bends hard, as the builder's trace did.
      if (status == EvalStatus::kOk && longest > options_.max_step_mm / 1024.0) {
        longest = 0.5 * std::abs(delta);
        continue;
      }
      out.status = PathStatus::kNoConvergence;
      out.state = from;
      return out;
    }
    // The pass is what the builder traced from its start to its end: the trace found it on the
    // face between them. So the march is classified only as far as the trim grid answers alone
    // (OpenCASCADE's classifier next to the trimming loops is what the planner paid for, marching
    // near the pass's ends again and again while it brakes for them); a pass that skims the
    // boundary between its ends (closer than the trace's step could see) is followed on the
    // surface's natural extension. Within the snap of an end, a point the march puts past the
    // traced end (along the pass's travel there) is that end: the same point however the march
    // came to it.
    const double reached = cur_s + delta;
    const bool near_end = delta > 0.0 ? reached >= length_ - kSnapMm : reached <= kSnapMm;
    if (near_end) {
      const ContactPoint& end = delta > 0.0 ? end_ : start_;
      if ((next.tip - end.tip).dot(end.tangent) * (delta > 0.0 ? 1.0 : -1.0) > 0.0) {
        next = end;
        stalled = true;
      }
    } else if (!eval_.SurelyOutside(next.uv)) {
      // On the face, or next to its trimming loops: as the trace found it.
    } else if (const double off_face = eval_.DistanceOutside(next.uv); off_face <= kOffFaceMm) {
      // Skimming the boundary between the pass's ends: followed on the surface's extension.
    } else if (delta > 0.0) {
      // The pass leaves the face here, before the trace said (the march has come onto another
      // branch of the strategy's line, or the pass meets the boundary at a grazing angle): report
      // the end here (the planner stops there; links start from where it stops).
      const ContactPoint x = eval_.LastInside(cur, 1.0, (next.tip - cur.tip).norm(), options_);
      out.status = PathStatus::kEnd;
      out.state.s = cur_s + ArcFromChord((x.tip - cur.tip).norm(), cur.tangent, x.tangent);
      out.state.u = x.uv.x();
      out.state.v = x.uv.y();
      out.state.w = x.guide_t;
      out.pose = {x.tip, x.axis};
      return out;
    } else {
      out.status = PathStatus::kLeftDomain;
      out.state = from;
      return out;
    }
    cur = next;
    cur_s += delta;
  }
  cache_[1 - from_slot] = cur;
  cache_valid_[1 - from_slot] = true;
  out.state.s = target;
  out.state.u = cur.uv.x();
  out.state.v = cur.uv.y();
  out.state.w = cur.guide_t;
  out.pose = {cur.tip, cur.axis};
  return out;
}

std::string SurfacePass::Describe(const PathState& state) const {
  return fmt::format("{}, pass {} ({}), arc length {:.6f} mm, (u, v) = ({:.9g}, {:.9g})",
                     eval_.Face().Where(), index_, eval_.Constraint().Describe(), state.s, state.u,
                     state.v);
}

}  // namespace dtis::strategies
