#include "dtis/geometry/path_fit.hpp"

#include <ceres/ceres.h>
#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <memory>

#include "dtis/core/error.hpp"
#include "dtis/geometry/angle.hpp"

namespace dtis::geometry {
namespace {

// Exports aim this far inside their tolerance at the samples, so that the path between samples
// (sampled every few µm, where a chord's error changes by far less than this) stays within it too.
constexpr double kMargin = 0.98;
constexpr int kDegree = 3;

}  // namespace

double DistanceToSegment(const Eigen::Vector3d& x, const Eigen::Vector3d& a,
                         const Eigen::Vector3d& b, double* t) {
  const Eigen::Vector3d ab = b - a;
  const double l2 = ab.squaredNorm();
  const double tau = l2 > 0.0 ? std::clamp((x - a).dot(ab) / l2, 0.0, 1.0) : 0.0;
  if (t) *t = tau;
  return (x - (a + tau * ab)).norm();
}

PathSamples SamplePath(const PathSource& path, double step_mm, const std::string& what) {
  if (!(step_mm > 0.0)) throw Error("{}: the sampling step must be > 0 mm", what);
  const std::optional<double> length = path.Length();
  if (!length || !(*length > 0.0)) {
    throw Error("{}: the path's length must be known and positive to sample it", what);
  }
  const long n = std::max(1L, static_cast<long>(std::ceil(*length / step_mm)));
  PathSamples out;
  out.s.reserve(static_cast<std::size_t>(n + 1));
  PathState state = path.Start();
  for (long k = 0; k <= n; ++k) {
    const double s = k == n ? *length : *length * static_cast<double>(k) / static_cast<double>(n);
    const PathSample sample = path.At(state, s);
    const bool end_ok = k == n && sample.status == PathStatus::kEnd;
    if (sample.status != PathStatus::kOk && !end_ok) {
      throw Error("{}: no pose at arc length {:.6f} mm ({})", what, s, path.Describe(state));
    }
    state = sample.state;
    out.s.push_back(s);
    out.state.push_back(sample.state);
    out.tip.push_back(sample.pose.tip);
    out.axis.push_back(sample.pose.axis);
    out.turning_axis = out.turning_axis || (sample.pose.axis - out.axis.front()).norm() > 1e-12;
  }
  return out;
}

std::vector<std::size_t> ChordalVertices(const PathSamples& samples,
                                         const ExportTolerance& tolerance) {
  const std::size_t last = samples.Size() - 1;
  const double tip_tol = kMargin * tolerance.tip_mm;
  const double axis_tol = kMargin * tolerance.axis_deg;
  const auto fits = [&](std::size_t i, std::size_t j) {
    const Eigen::Vector3d& a = samples.tip[i];
    const Eigen::Vector3d& b = samples.tip[j];
    for (std::size_t k = i + 1; k < j; ++k) {
      double t = 0.0;
      if (DistanceToSegment(samples.tip[k], a, b, &t) > tip_tol) return false;
      if (samples.turning_axis) {
        // Tip and top interpolated alike: top - tip = h ((1 - t) axis_i + t axis_j).
        const Eigen::Vector3d axis = (1 - t) * samples.axis[i] + t * samples.axis[j];
        if (AngleDeg(axis, samples.axis[k]) > axis_tol) return false;
      }
    }
    return true;
  };
  std::vector<std::size_t> vertices{0};
  std::size_t i = 0;
  while (i < last) {
    // Double the chord while it fits, then bisect between the last fit and the first miss.
    std::size_t good = i + 1, bad = last + 1;
    for (std::size_t probe = std::min(i + 2, last); probe > good;
         probe = std::min(i + 2 * (probe - i), last)) {
      if (!fits(i, probe)) {
        bad = probe;
        break;
      }
      good = probe;
    }
    while (bad - good > 1 && bad <= last) {
      const std::size_t mid = good + (bad - good) / 2;
      (fits(i, mid) ? good : bad) = mid;
    }
    vertices.push_back(good);
    i = good;
  }
  return vertices;
}

double ClosestOnCurve(const BSplineCurve& curve, const Eigen::Vector3d& x, double u) {
  const double a = curve.FirstParameter(), b = curve.LastParameter();
  u = std::clamp(u, a, b);
  std::array<Eigen::Vector3d, 3> d;
  for (int it = 0; it < 20; ++it) {
    curve.Derivatives(u, 2, d.data());
    const Eigen::Vector3d r = d[0] - x;
    const double f = r.dot(d[1]);
    const double df = d[1].squaredNorm() + r.dot(d[2]);
    if (!(df > 0.0)) break;
    const double next = std::clamp(u - f / df, a, b);
    const double moved = std::abs(next - u) * d[1].norm();
    u = next;
    if (moved < 1e-13) break;
  }
  return u;
}

namespace {

// sum_j N_j P_j - target, for the 4 poles a sample depends on.
class PointResidual final : public ceres::SizedCostFunction<3, 3, 3, 3, 3> {
 public:
  PointResidual(const std::array<double, kDegree + 1>& n, const Eigen::Vector3d& target)
      : n_(n), target_(target) {}
  bool Evaluate(double const* const* poles, double* residuals, double** jacobians) const override {
    Eigen::Map<Eigen::Vector3d> r(residuals);
    r = -target_;
    for (int j = 0; j <= kDegree; ++j) {
      r += n_[static_cast<std::size_t>(j)] * Eigen::Map<const Eigen::Vector3d>(poles[j]);
    }
    if (jacobians) {
      for (int j = 0; j <= kDegree; ++j) {
        if (!jacobians[j]) continue;
        Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> jac(jacobians[j]);
        jac = n_[static_cast<std::size_t>(j)] * Eigen::Matrix3d::Identity();
      }
    }
    return true;
  }

 private:
  std::array<double, kDegree + 1> n_;
  Eigen::Vector3d target_;
};

// Clamped cubic knots on [a, b] with `spans` equal spans.
std::vector<double> UniformKnots(double a, double b, int spans) {
  std::vector<double> knots(kDegree, a);
  for (int k = 0; k <= spans; ++k) {
    knots.push_back(k == spans ? b : a + (b - a) * static_cast<double>(k) / spans);
  }
  knots.insert(knots.end(), kDegree, b);
  return knots;
}

// The poles of the least-squares fit to `points` at parameters `t`, ends interpolated.
std::vector<Eigen::Vector3d> SolvePoles(const std::vector<double>& knots,
                                        const std::vector<double>& t,
                                        const std::vector<Eigen::Vector3d>& points,
                                        const std::string& what) {
  const std::size_t poles = knots.size() - kDegree - 1;
  // Start from the samples at the Greville abscissae: close to the answer, so the solver's first
  // step lands on it (the problem is linear).
  std::vector<Eigen::Vector3d> p(poles);
  for (std::size_t i = 0; i < poles; ++i) {
    double g = 0.0;
    for (int k = 1; k <= kDegree; ++k) g += knots[i + static_cast<std::size_t>(k)];
    g /= kDegree;
    const std::size_t k =
        static_cast<std::size_t>(std::lower_bound(t.begin(), t.end(), g) - t.begin());
    p[i] = points[std::min(k, points.size() - 1)];
  }
  p.front() = points.front();
  p.back() = points.back();
  ceres::Problem::Options po;
  ceres::Problem problem(po);
  std::array<double, kDegree + 1> n{};
  for (std::size_t i = 0; i < t.size(); ++i) {
    const std::size_t first =
        static_cast<std::size_t>(NonZeroBasis(knots, kDegree, t[i], n.data()));
    problem.AddResidualBlock(new PointResidual(n, points[i]), nullptr, p[first].data(),
                             p[first + 1].data(), p[first + 2].data(), p[first + 3].data());
  }
  problem.SetParameterBlockConstant(p.front().data());
  problem.SetParameterBlockConstant(p.back().data());
  // The problem is linear: with a trust region too wide to damp it, the first step is the
  // Gauss-Newton solution and two more refine its rounding. Left to iterate on, the solver only
  // meets steps that cannot lower the cost any more and, after five of them, reports a failure
  // for the answer it holds (it did, on a pass whose last sample moved by 2e-12 mm).
  ceres::Solver::Options so;
  so.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
  so.initial_trust_region_radius = 1e16;
  so.max_num_iterations = 3;
  so.function_tolerance = 1e-16;
  so.gradient_tolerance = 1e-16;
  so.parameter_tolerance = 1e-14;
  so.num_threads = 1;
  so.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(so, &problem, &summary);
  if (!summary.IsSolutionUsable()) {
    throw Error("{}: the least-squares B-spline fit failed: {}", what, summary.message);
  }
  return p;
}

BSplineCurve MakeCurve(const std::vector<double>& knots, std::vector<Eigen::Vector3d> poles,
                       const std::string& what) {
  BSplineCurveData data;
  data.degree = kDegree;
  data.knots = knots;
  data.poles = std::move(poles);
  return BSplineCurve(std::move(data), what);
}

}  // namespace

BSplineFit FitCubicBSpline(const PathSamples& samples, const BSplineFitOptions& options,
                           const std::string& what) {
  const std::size_t m = samples.Size();
  if (m < 2) throw Error("{}: a B-spline fit needs at least 2 samples", what);
  const std::vector<double>& t = samples.s;
  const double a = t.front(), b = t.back();
  const bool five = samples.turning_axis;
  std::vector<Eigen::Vector3d> tops;
  if (five) {
    tops.resize(m);
    for (std::size_t i = 0; i < m; ++i) {
      tops[i] = samples.tip[i] + options.tolerance.top_height_mm * samples.axis[i];
    }
  }
  const double tip_tol = kMargin * options.tolerance.tip_mm;
  const double axis_tol = kMargin * options.tolerance.axis_deg;
  // Every span must hold enough samples for its poles to be determined.
  constexpr std::size_t kMinSamplesPerSpan = 8;
  const int max_spans = std::max(1, static_cast<int>(m / kMinSamplesPerSpan));
  // Start coarse (a span per 50 mm) and refine: a CAM system's fit has no more poles than the
  // tolerance needs.
  int spans = std::clamp(static_cast<int>(std::ceil((b - a) / 50.0)), 1, max_spans);
  std::vector<double> knots = UniformKnots(a, b, spans);

  for (int round = 1; round <= options.max_rounds; ++round) {
    BSplineFit fit{MakeCurve(knots, SolvePoles(knots, t, samples.tip, what), what), std::nullopt,
                   round, 0.0, 0.0};
    if (five) fit.top = MakeCurve(knots, SolvePoles(knots, t, tops, what), what);
    // The largest distance of a sample to the curve(s), per knot span.
    const std::size_t n_spans = knots.size() - 2 * kDegree - 1;
    std::vector<bool> out(n_spans, false);
    std::vector<std::size_t> count(n_spans, 0);
    std::size_t span = 0;  // the knot span of sample i: the samples are in parameter order
    for (std::size_t i = 0; i < m; ++i) {
      while (span + 1 < n_spans && t[i] >= knots[kDegree + span + 1]) ++span;
      ++count[span];
      const double u = ClosestOnCurve(fit.bottom, samples.tip[i], t[i]);
      const Eigen::Vector3d foot = fit.bottom.Point(u);
      const double d = (foot - samples.tip[i]).norm();
      fit.max_tip_mm = std::max(fit.max_tip_mm, d);
      bool bad = d > tip_tol;
      if (five) {
        const double e = AngleDeg(fit.top->Point(u) - foot, samples.axis[i]);
        fit.max_axis_deg = std::max(fit.max_axis_deg, e);
        bad = bad || e > axis_tol;
      }
      if (bad) out[span] = true;
    }
    if (std::none_of(out.begin(), out.end(), [](bool o) { return o; })) return fit;

    if (options.uniform_knots) {
      const int more = std::min(max_spans, spans + std::max(1, spans / 4));
      if (more == spans) break;
      spans = more;
      knots = UniformKnots(a, b, spans);
      continue;
    }
    std::vector<double> next(knots.begin(), knots.begin() + kDegree + 1);
    bool split = false;
    for (std::size_t k = 0; k < n_spans; ++k) {
      const double lo = knots[kDegree + k], hi = knots[kDegree + k + 1];
      if (out[k] && count[k] >= 2 * kMinSamplesPerSpan) {
        next.push_back(0.5 * (lo + hi));
        split = true;
      }
      next.push_back(hi);
    }
    if (!split) break;
    next.insert(next.end(), kDegree, b);
    knots = std::move(next);
  }
  throw Error(
      "{}: no cubic B-spline within {:g} mm of the path with knot spans of at least {} samples; "
      "sample the path more finely (sample_step_mm)",
      what, options.tolerance.tip_mm, kMinSamplesPerSpan);
}

PathProjector::PathProjector(const PathSource& path, const PathSamples& samples)
    : path_(path), samples_(samples) {
  if (samples.Size() < 2) throw Error("a path projector needs at least 2 samples");
}

PathProjector::Foot PathProjector::Project(const Eigen::Vector3d& x, std::size_t* hint) const {
  const std::size_t segments = samples_.Size() - 1;
  const auto& tip = samples_.tip;
  // The nearest chord: search a window around the hint, moving it while the best is at its edge.
  constexpr std::size_t kWindow = 32;
  std::size_t k = std::min(*hint, segments - 1);
  std::size_t best = k;
  double t = 0.0;
  for (int moves = 0; moves < 1 << 20; ++moves) {
    const std::size_t lo = k > kWindow ? k - kWindow : 0;
    const std::size_t hi = std::min(segments - 1, k + kWindow);
    double best_d = std::numeric_limits<double>::infinity();
    for (std::size_t j = lo; j <= hi; ++j) {
      double tj = 0.0;
      const double d = DistanceToSegment(x, tip[j], tip[j + 1], &tj);
      if (d < best_d) {
        best_d = d;
        best = j;
        t = tj;
      }
    }
    const bool at_edge = (best == lo && lo > 0) || (best == hi && hi < segments - 1);
    if (!at_edge || best == k) break;
    k = best;
  }
  const double length = samples_.s.back();
  double s = samples_.s[best] + t * (samples_.s[best + 1] - samples_.s[best]);
  // Newton along the exact path: move s by the offset's component along the tangent (the chord's
  // direction, within a sample step's turn of the true tangent: the foot it finds is off by
  // distance * turn, which changes the distance by a negligible second-order amount).
  // Newton along the exact path on f(s) = (x - P(s)) . P'(s), without the curvature term: it
  // converges at the rate distance * curvature, a few iterations at the distances measured here.
  // The first step takes the chord's direction for P'; then a central difference of the path.
  const auto index_of = [&](double at) {
    while (best > 0 && at < samples_.s[best]) --best;
    while (best + 1 < segments && at > samples_.s[best + 1]) ++best;
    return best;
  };
  PathSample at = path_.At(samples_.state[best], s);
  Eigen::Vector3d tangent = (tip[best + 1] - tip[best]).normalized();
  for (int it = 0; it < 12 && tangent.allFinite(); ++it) {
    const double next = std::clamp(s + (x - at.pose.tip).dot(tangent), 0.0, length);
    const bool done = std::abs(next - s) < 1e-13;
    s = next;
    const PathState& near = samples_.state[index_of(s)];
    at = path_.At(near, s);
    if (done) break;
    constexpr double kH = 1e-5;
    const double lo = std::max(0.0, s - kH), hi = std::min(length, s + kH);
    tangent = (path_.At(near, hi).pose.tip - path_.At(near, lo).pose.tip) / (hi - lo);
  }
  *hint = best;
  return {s, at.pose, (x - at.pose.tip).norm()};
}

}  // namespace dtis::geometry
