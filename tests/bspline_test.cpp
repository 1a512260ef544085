// dtis' curve kernel against OpenCASCADE's Geom_BSplineCurve (an independent implementation), the
// NURBS circle of Cheng et al. (a closed form: radius 50 mm), and the arc-length map.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>

#include "dtis/core/error.hpp"
#include "dtis/geometry/arc_length.hpp"
#include "dtis/geometry/bspline_curve.hpp"
#include "dtis/geometry/curve_path.hpp"
#include "dtis/geometry/occt_convert.hpp"
#include "test_support.hpp"

namespace dtis {
namespace {

using geometry::BSplineCurve;
using geometry::BSplineCurveData;

BSplineCurveData RandomCurve(std::mt19937_64& rng, bool rational) {
  std::uniform_int_distribution<int> degree(1, 5), extra(0, 6);
  std::uniform_real_distribution<double> coord(-50.0, 50.0), weight(0.3, 3.0), gap(0.1, 1.0);
  BSplineCurveData d;
  d.degree = degree(rng);
  const int poles = d.degree + 1 + extra(rng);
  for (int i = 0; i < poles; ++i) d.poles.emplace_back(coord(rng), coord(rng), coord(rng));
  for (int i = 0; i <= d.degree; ++i) d.knots.push_back(0.0);
  double k = 0.0;
  for (int i = 0; i < poles - d.degree - 1; ++i) d.knots.push_back(k += gap(rng));
  k += gap(rng);
  for (int i = 0; i <= d.degree; ++i) d.knots.push_back(k);
  if (rational) {
    for (int i = 0; i < poles; ++i) d.weights.push_back(weight(rng));
  }
  return d;
}

TEST(BSplineCurve, MatchesOpenCascadePointsAndDerivatives) {
  std::mt19937_64 rng(test::g_seed);
  const long cases = std::max(50L, test::g_count / 4);
  for (long c = 0; c < cases; ++c) {
    const BSplineCurve curve(RandomCurve(rng, c % 2 == 1));
    const auto occt = geometry::ToOcct(curve);
    std::uniform_real_distribution<double> u(curve.FirstParameter(), curve.LastParameter());
    for (int k = 0; k < 8; ++k) {
      const double t = k == 0 ? curve.FirstParameter() : k == 1 ? curve.LastParameter() : u(rng);
      Eigen::Vector3d d[4];
      curve.Derivatives(t, 3, d);
      gp_Pnt p;
      gp_Vec v1, v2, v3;
      occt->D3(t, p, v1, v2, v3);
      const gp_Vec ref[4] = {gp_Vec(p.XYZ()), v1, v2, v3};
      for (int o = 0; o <= 3; ++o) {  // OCCT evaluates at knots from the right, as dtis does
        const Eigen::Vector3d r(ref[o].X(), ref[o].Y(), ref[o].Z());
        ASSERT_LE((d[o] - r).norm(), 1e-9 * (1.0 + r.norm()))
            << "case " << c << " degree " << curve.Degree() << " order " << o << " u " << t;
      }
      ASSERT_LE((curve.Point(t) - d[0]).norm(), 1e-12 * (1.0 + d[0].norm()));
    }
  }
}

BSplineCurveData NurbsCircleData() {
  BSplineCurveData d;
  d.degree = 2;
  d.knots = {0, 0, 0, 0.25, 0.5, 0.5, 0.75, 1, 1, 1};
  d.poles = {{0, 0, 0},     {0, 50, 0},  {100, 50, 0}, {100, 0, 0},
             {100, -50, 0}, {0, -50, 0}, {0, 0, 0}};
  d.weights = {1.0, 0.5, 0.5, 1.0, 0.5, 0.5, 1.0};
  return d;
}

BSplineCurve NurbsCircle() { return BSplineCurve(NurbsCircleData()); }

TEST(BSplineCurve, NurbsCircleHasRadius50Everywhere) {
  const BSplineCurve circle = NurbsCircle();
  const Eigen::Vector3d centre(50, 0, 0);
  for (int i = 0; i <= 100000; ++i) {
    const double u = i / 100000.0;
    ASSERT_NEAR((circle.Point(u) - centre).norm(), 50.0, 1e-9) << "u = " << u;
  }
}

TEST(ArcLength, CircleLengthAndInverseAreExact) {
  const BSplineCurve circle = NurbsCircle();
  const geometry::CurvePath path(circle, Eigen::Vector3d::UnitZ());
  EXPECT_NEAR(path.Map().Length(), 2.0 * std::numbers::pi * 50.0, 1e-9);
  // s(u(s)) = s, measured with an independent quadrature, on a fine grid.
  int hint = 0;
  for (int i = 0; i <= 2000; ++i) {
    const double s = path.Map().Length() * i / 2000.0;
    const double u = path.Map().Parameter(s, &hint);
    ASSERT_NEAR(path.Map().Integrate(circle.FirstParameter(), u), s, 1e-8) << "s = " << s;
  }
  EXPECT_LE(path.Map().MaxErrorMm(), 1e-10);
}

TEST(ArcLength, RandomCurvesInvertWithinTolerance) {
  std::mt19937_64 rng(test::g_seed + 7);
  for (long c = 0; c < std::max(20L, test::g_count / 20); ++c) {
    const BSplineCurve curve(RandomCurve(rng, c % 2 == 0));
    const geometry::CurvePath path(curve, Eigen::Vector3d::UnitZ());
    int hint = 0;
    for (int i = 0; i <= 50; ++i) {
      const double s = path.Map().Length() * i / 50.0;
      const double u = path.Map().Parameter(s, &hint);
      ASSERT_NEAR(path.Map().Integrate(curve.FirstParameter(), u), s, 1e-6 * (1.0 + s))
          << "case " << c;
    }
  }
}

// A curve 1 km across (the circle with one pole at the bound): a double resolves s only to about
// 1e-10 mm there, so the map's tolerance follows s's resolution; the map ends, small, and inverts
// within it.
TEST(ArcLength, KilometreCurveMapsWithinWhatADoubleResolves) {
  BSplineCurveData d = NurbsCircleData();
  d.poles[2].y() = 1e6;
  const BSplineCurve curve(d);
  const geometry::CurvePath path(curve, Eigen::Vector3d::UnitZ());
  EXPECT_GT(path.Map().Length(), 1e6);
  EXPECT_LT(path.Map().Intervals(), 10000);
  int hint = 0;
  for (int i = 0; i <= 200; ++i) {
    const double s = path.Map().Length() * i / 200.0;
    const double u = path.Map().Parameter(s, &hint);
    // The map's floor, 64 ulps of s, and as much again for the check's own quadrature sum.
    const double floor = 64.0 * std::numeric_limits<double>::epsilon() * s;
    ASSERT_NEAR(path.Map().Integrate(curve.FirstParameter(), u), s, 2.0 * std::max(1e-10, floor))
        << "s = " << s;
  }
}

// Poles that all coincide (the fuzzer's find): |C'| is rounding noise, the length under the
// tolerance; the map is a handful of linear pieces (it once bisected every span 40 times deep).
TEST(ArcLength, CoincidentPolesMapAsAPoint) {
  BSplineCurveData d;
  d.degree = 3;
  d.knots = {0, 0, 0, 0, 5.421010862427522e-19, 1, 1, 1, 1};
  d.poles.assign(5, Eigen::Vector3d(-60, -60, -60));
  const geometry::CurvePath path(BSplineCurve(d), Eigen::Vector3d::UnitZ());
  EXPECT_LT(path.Map().Length(), 1e-10);
  EXPECT_LE(path.Map().Intervals(), 4);
}

// A speed that overflows, or a map that needs more pieces than allowed: an error, not a hang.
TEST(ArcLength, RefusesWhatItCannotMap) {
  const geometry::ArcLengthMap::Evaluator overflowing = [](double u, int order, Eigen::Vector3d* d,
                                                           bool) {
    for (int k = 0; k <= order; ++k) d[k] = Eigen::Vector3d(u, 0, 0) * 1e200;
    d[1] = Eigen::Vector3d(1e200, 1e200, 0);  // |C'| overflows
  };
  try {
    geometry::ArcLengthMap map(overflowing, {0.0, 1.0});
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("speed |C'(u)| is not finite"), std::string::npos)
        << e.what();
  }
  // A spiral whose speed grows so fast that no quintic piece is exact to 1e-10 mm in few pieces.
  const geometry::ArcLengthMap::Evaluator spiral = [](double u, int order, Eigen::Vector3d* d,
                                                      bool) {
    const double r = std::exp(8 * u), w = 40.0;
    d[0] = r * Eigen::Vector3d(std::cos(w * u), std::sin(w * u), 0);
    if (order >= 1) {
      d[1] = r * Eigen::Vector3d(8 * std::cos(w * u) - w * std::sin(w * u),
                                 8 * std::sin(w * u) + w * std::cos(w * u), 0);
    }
    if (order >= 2) {
      d[2] = r * Eigen::Vector3d((64 - w * w) * std::cos(w * u) - 16 * w * std::sin(w * u),
                                 (64 - w * w) * std::sin(w * u) + 16 * w * std::cos(w * u), 0);
    }
  };
  EXPECT_NO_THROW(geometry::ArcLengthMap(spiral, {0.0, 1.0}));
  geometry::ArcLengthOptions tight;
  tight.pieces_per_span = 2;
  tight.min_piece_budget = 4;
  try {
    geometry::ArcLengthMap map(spiral, {0.0, 1.0}, tight);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("needs more than 4 pieces"), std::string::npos)
        << e.what();
  }
}

void ExpectError(BSplineCurveData d, const std::string& fragment) {
  try {
    BSplineCurve c(std::move(d), "test curve");
    FAIL() << "expected an error containing '" << fragment << "'";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

TEST(BSplineCurve, RejectsBadDefinitions) {
  BSplineCurveData good;
  good.degree = 2;
  good.knots = {0, 0, 0, 1, 1, 1};
  good.poles = {{0, 0, 0}, {1, 1, 0}, {2, 0, 0}};
  EXPECT_NO_THROW(BSplineCurve{good});

  auto d = good;
  d.knots = {0, 0, 0, 1, 1};
  ExpectError(d, "5 knots for 3 poles");
  d = good;
  d.knots = {0, 0, 0.5, 0.2, 1, 1};
  ExpectError(d, "must not decrease");
  d = good;
  d.weights = {1, 0, 1};
  ExpectError(d, "weight 1 is 0");
  d = good;
  d.weights = {1, -2, 1};
  ExpectError(d, "weight 1 is -2");
  d = good;
  d.degree = 0;
  ExpectError(d, "degree 0");
  d = good;
  d.poles[1].x() = NAN;
  ExpectError(d, "pole 1");
  d = good;
  d.poles[1].y() = 1e300;  // a typo or a unit error: refused, not planned for hours
  ExpectError(d, "pole 1 (1, 1e+300, 0) is more than 1e+06 mm from the origin");
  d.poles[1].y() = -1.000001e6;
  ExpectError(d, "pole 1");
  d.poles[1].y() = 1e6;
  EXPECT_NO_THROW(BSplineCurve{d});
  d = good;
  d.knots = {0, 0, 0, 0.5, 0.5, 0.5, 1, 1, 1};
  d.poles = {{0, 0, 0}, {1, 1, 0}, {2, 0, 0}, {3, 1, 0}, {4, 0, 0}, {5, 1, 0}};
  ExpectError(d, "multiplicity 3; at most 2 is allowed inside the domain");
}

// The look-ahead samples the axis derivatives on either side of a curve's knots (where q_sss
// jumps): Breaks gives their arc lengths, which a polyline of 200 000 chords independently
// confirms.
TEST(CurvePath, BreaksAreTheArcLengthsOfTheInnerKnots) {
  BSplineCurveData d;
  d.degree = 3;
  d.knots = {0, 0, 0, 0, 0.25, 0.5, 0.75, 1, 1, 1, 1};
  d.poles = {{10, 0, 0}, {20, 27, 0}, {12, 8, 0}, {10, 20, 0}, {8, 8, 0}, {0, 27, 0}, {10, 0, 0}};
  const BSplineCurve curve(d);
  const geometry::CurvePath path(curve, Eigen::Vector3d::UnitZ());
  const double length = path.Length().value();
  const std::vector<double> breaks = path.Breaks(0.0, length);
  ASSERT_EQ(breaks.size(), 3u);
  const int chords = 200000;
  std::size_t next = 0;
  double s = 0.0;
  Eigen::Vector3d last = curve.Point(0.0);
  for (int k = 1; k <= chords && next < 3; ++k) {
    const double u = static_cast<double>(k) / chords;
    const Eigen::Vector3d p = curve.Point(u);
    s += (p - last).norm();
    last = p;
    if (std::abs(u - d.knots[4 + next]) < 0.5 / chords) {
      EXPECT_NEAR(breaks[next], s, 1e-6) << "knot " << d.knots[4 + next];
      ++next;
    }
  }
  EXPECT_EQ(next, 3u);
  // Only the breaks inside the asked stretch, the stretch's start excluded.
  EXPECT_EQ(path.Breaks(breaks[0], breaks[2] - 1e-9), std::vector<double>{breaks[1]});
  EXPECT_TRUE(path.Breaks(0.0, breaks[0] - 1e-9).empty());
}

}  // namespace
}  // namespace dtis
