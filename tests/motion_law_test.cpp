// The discrete jerk-limited laws: the stop law reaches rest within its limits from any state it
// can stop from, and the cap law never overshoots its cap.
#include "dtis/interp/motion_law.hpp"

#include <gtest/gtest.h>

#include <random>

#include "test_support.hpp"

namespace dtis::interp {
namespace {

TEST(MotionLaw, ReleaseGainMatchesASimulatedRelease) {
  const double J = 5000.0, dt = 1e-3;
  for (const double a : {0.0, 1.0, 4.99, 5.0, 5.01, 123.4, 2500.0}) {
    double v = 0.0, acc = a;
    while (acc > 0.0) {
      acc = std::max(acc - J * dt, 0.0);
      v += acc * dt;
    }
    EXPECT_NEAR(ReleaseGain(a, J, dt), v, 1e-12 * (1.0 + v)) << "a = " << a;
  }
}

TEST(MotionLaw, StopReachesRestWithinLimits) {
  std::mt19937_64 rng(test::g_seed + 3);
  std::uniform_real_distribution<double> jerk(100.0, 1e5), acc(10.0, 1e4), frac(0.0, 1.0);
  const double dt = 1e-3;
  for (long c = 0; c < test::g_count * 5; ++c) {
    const double J = jerk(rng), A = acc(rng), v0 = frac(rng) * 200.0, a0 = (frac(rng) - 0.2) * A;
    if (v0 - ReleaseGain(-a0, J, dt) < 0.0) continue;  // braked too hard to stop forwards
    double v = v0, a = a0;
    int k = 0;
    for (; k < 1000000 && (v != 0.0 || a != 0.0); ++k) {
      double next = StopAcceleration(v, a, J, A, dt);
      ASSERT_LE(std::abs(next - a), J * dt * (1 + 1e-9)) << "case " << c << " jerk";
      ASSERT_LE(next, std::max(a, 0.0) + 1e-9) << "case " << c << " accelerates";
      double v_next = v + next * dt;
      ASSERT_GE(v_next, -1e-9 * (1.0 + v0)) << "case " << c << " reverses at period " << k;
      if (std::abs(v_next) <= 1e-12 * (1.0 + v0)) v_next = 0.0, next = -v / dt;
      v = v_next;
      a = next;
    }
    ASSERT_LT(k, 1000000) << "case " << c << " never stops";
    const StopDistance d = StopDistanceFrom(v0, a0, J, A, dt);
    ASSERT_FALSE(d.reverses) << "case " << c;
  }
}

TEST(MotionLaw, CapIsApproachedWithoutOvershoot) {
  std::mt19937_64 rng(test::g_seed + 5);
  std::uniform_real_distribution<double> jerk(100.0, 1e5), frac(0.0, 1.0);
  const double dt = 1e-3;
  for (long c = 0; c < test::g_count * 5; ++c) {
    const double J = jerk(rng), cap = 1.0 + frac(rng) * 500.0;
    double v = 0.0, a = 0.0, peak = 0.0;
    for (int k = 0; k < 100000; ++k) {
      const double next =
          std::min(MaxAccelerationUnderCap(v, cap, J * kReleaseJerkFraction, dt), a + J * dt);
      ASSERT_GE(next - a, -J * dt * (1 + 1e-9)) << "case " << c << ": cannot release in time";
      a = next;
      v += a * dt;
      peak = std::max(peak, v);
      if (std::abs(v - cap) < 1e-9 * cap && std::abs(a) < 1e-6) break;
    }
    ASSERT_LE(peak, cap * (1 + 1e-12)) << "case " << c;
    ASSERT_NEAR(v, cap, 1e-6 * cap) << "case " << c << " did not settle";
  }
}

}  // namespace
}  // namespace dtis::interp

namespace dtis::interp {
namespace {

// The closed-form phases give the simulation's distance, period count and verdict, including for
// laws whose stops take tens of thousands of periods (small path jerk near a rotary singularity).
TEST(MotionLaw, StopDistanceSumsPhasesLikeTheSimulation) {
  std::mt19937_64 rng(test::g_seed + 11);
  std::uniform_real_distribution<double> frac(0.0, 1.0);
  const double dt = 1e-3;
  double worst = 0.0;
  for (long c = 0; c < test::g_count * 2; ++c) {
    const double J = std::pow(10.0, 1.0 + 4.0 * frac(rng)),
                 A = std::pow(10.0, 0.5 + 3.5 * frac(rng));
    const double v0 = frac(rng) * 200.0, a0 = (frac(rng) * 1.4 - 1.0) * A;
    const StopDistance sim = StopDistanceBySimulation(v0, a0, J, A, dt);
    const StopDistance fast = StopDistanceFrom(v0, a0, J, A, dt);
    ASSERT_EQ(fast.reverses, sim.reverses) << "case " << c << " v " << v0 << " a " << a0;
    if (!std::isfinite(sim.distance)) continue;
    ASSERT_NEAR(fast.periods, sim.periods, 1) << "case " << c;
    const double err = std::abs(fast.distance - sim.distance) / (1.0 + sim.distance);
    worst = std::max(worst, err);
    ASSERT_LT(err, 1e-11) << "case " << c << " v " << v0 << " a " << a0 << " J " << J << " A " << A;
  }
  std::printf("stop distance: worst relative difference to the simulation %.3g\n", worst);
}

// StopReach is the distance the look-ahead plans a stop or a slow-down with. A motion that the law
// cannot bring to rest (it brakes too hard to release in time) must not count as stopping short
// of the end of the path: this state, from the last periods of the 10-degree-tilt sample's pass,
// had 6.8e-5 mm left and was taken for one that stops in time.
TEST(MotionLaw, StopReachCountsAStopThatCannotComeToRest) {
  const double dt = 1e-3, J = 640.0, A = 27.6, v = 0.13619, a = -13.535;
  const StopDistance sim = StopDistanceBySimulation(v, a, J, A, dt);
  ASSERT_TRUE(sim.reverses);
  const double reach = StopReach(v, a, J, A, dt, 0.0);
  EXPECT_NEAR(reach, sim.distance, 1e-12);
  EXPECT_GT(reach, 10.0 * 6.8e-5);
  // Above a slow point's feed the same state passes the point below that feed: no constraint.
  EXPECT_EQ(StopReach(v, a, J, A, dt, 0.05), -std::numeric_limits<double>::infinity());
  // Below the feed, or just reaching it: nothing to brake for.
  EXPECT_EQ(StopReach(v, 0.0, J, A, dt, 2.0 * v), -std::numeric_limits<double>::infinity());
}

TEST(MotionLaw, StopReachIsTheStopDistanceOfTheExcess) {
  std::mt19937_64 rng(test::g_seed + 13);
  std::uniform_real_distribution<double> frac(0.0, 1.0);
  const double dt = 1e-3;
  for (long c = 0; c < test::g_count; ++c) {
    const double J = std::pow(10.0, 2.0 + 3.0 * frac(rng)),
                 A = std::pow(10.0, 1.0 + 3.0 * frac(rng));
    const double feed = frac(rng) < 0.3 ? 0.0 : 100.0 * frac(rng);
    const double v = feed + 100.0 * frac(rng), a = (frac(rng) - 0.5) * A;
    const StopDistance sim = StopDistanceBySimulation(v - feed, a, J, A, dt);
    if (sim.reverses || !std::isfinite(sim.distance)) continue;
    const double reach = StopReach(v, a, J, A, dt, feed);
    if (v - feed + ReleaseGain(a, J, dt) <= 0.0) {
      EXPECT_EQ(reach, -std::numeric_limits<double>::infinity()) << "case " << c;
      continue;
    }
    const double expected = sim.distance + feed * sim.periods * dt;
    // The periods of the closed-form sum may differ from the simulation's by one (its last
    // partial period), at a feed of up to 100 mm/s.
    EXPECT_NEAR(reach, expected, 1e-10 * (1.0 + expected) + feed * dt) << "case " << c;
  }
}

}  // namespace
}  // namespace dtis::interp
