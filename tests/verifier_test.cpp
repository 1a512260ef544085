// The verifier on hand-made sequences whose derivatives are known.
#include "dtis/interp/verifier.hpp"

#include <gtest/gtest.h>

#include "dtis/core/error.hpp"
#include "dtis/kinematics/machines.hpp"
#include "test_support.hpp"

namespace dtis::interp {
namespace {

std::unique_ptr<Machine> Xyz() {
  return kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
}

SetpointTable Table(const std::vector<double>& x, double dt) {
  SetpointTable t;
  t.axes = {"X", "Y", "Z"};
  t.columns.resize(3);
  for (std::size_t k = 0; k < x.size(); ++k) {
    t.t.push_back(static_cast<double>(k) * dt);
    t.columns[0].push_back(x[k]);
    t.columns[1].push_back(0.0);
    t.columns[2].push_back(0.0);
  }
  return t;
}

TEST(Verifier, MeasuresJerkOfAKnownSequence) {
  // Jerk +J, -J, -J, +J for one period each: from rest to rest, |j| = J = 0.8 of the X limit.
  const double dt = 1e-3, J = 4000.0;
  std::vector<double> x = {0.0};
  double v = 0.0, a = 0.0;
  for (const double j : {J, -J, -J, J, 0.0, 0.0, 0.0}) {
    a += j * dt;
    v += a * dt;
    x.push_back(x.back() + v * dt);
  }
  auto r = Verify(Table(x, dt), *Xyz());
  EXPECT_NEAR(r.axes[0].j_ratio, 0.8, 1e-6);
  EXPECT_NEAR(r.axes[0].a_ratio, J * dt / 2500.0, 1e-9);
  EXPECT_TRUE(r.uniform_period);
  EXPECT_TRUE(r.starts_at_rest);
  EXPECT_TRUE(r.ends_at_rest);
  EXPECT_TRUE(r.Passed());
  // Cut before it settles: the hold after the last row is a stop the verifier must see.
  x.resize(3);
  r = Verify(Table(x, dt), *Xyz());
  EXPECT_FALSE(r.ends_at_rest);
  EXPECT_FALSE(r.Passed());
}

// Jerk chatter: a period whose jerk has the other sign than the one before, both beyond half the
// limit. A stretch S (one switch from +0.8 J to -0.8 J, twenty periods alternating +-0.8 J, twenty
// alternating +-0.4 J, rest between) and S, -S, -S, S from rest to rest: 4 x 20 flips.
TEST(Verifier, CountsThePeriodsWhoseJerkFlipsBeyondHalfTheLimit) {
  const double dt = 1e-3, J = 5000.0;  // X's limit
  std::vector<double> stretch;
  const auto add = [&](int n, double j) { stretch.insert(stretch.end(), n, j); };
  add(10, 0.8 * J), add(10, -0.8 * J), add(5, 0.0);
  for (int k = 0; k < 20; ++k) add(1, k % 2 ? -0.8 * J : 0.8 * J);
  add(5, 0.0);
  for (int k = 0; k < 20; ++k) add(1, k % 2 ? -0.4 * J : 0.4 * J);
  add(10, 0.0);
  std::vector<double> x = {0.0, 0.0};
  double v = 0.0, a = 0.0;
  for (const double sign : {1.0, -1.0, -1.0, 1.0}) {
    for (const double j : stretch) {
      a += sign * j * dt;
      v += a * dt;
      x.push_back(x.back() + v * dt);
    }
  }
  const auto r = Verify(Table(x, dt), *Xyz());
  EXPECT_TRUE(r.Passed()) << FormatReport(r);
  EXPECT_EQ(r.axes[0].jerk_flips, 80);
  EXPECT_EQ(r.axes[1].jerk_flips, 0);
  EXPECT_NE(FormatReport(r).find("jerk flips"), std::string::npos);
}

TEST(Verifier, DetectsJumpsPeriodsAndAxisMismatch) {
  auto t = Table({0, 0, 0, 1e-3, 1e-3, 1e-3, 1e-3}, 1e-3);
  auto r = Verify(t, *Xyz());
  EXPECT_GT(r.worst_ratio, 100.0);  // a 1 um step in 1 ms is a huge jerk
  EXPECT_TRUE(r.ends_at_rest);
  t.t[3] += 1e-5;
  r = Verify(t, *Xyz());
  EXPECT_FALSE(r.uniform_period);
  t.axes[1] = "Q";
  EXPECT_THROW(Verify(t, *Xyz()), Error);
}

TEST(Verifier, MotionTimeSpansFirstToLastMove) {
  const auto r = Verify(Table({0, 0, 0, 1e-9, 3e-9, 4e-9, 4e-9, 4e-9, 4e-9}, 1e-3), *Xyz());
  EXPECT_NEAR(r.motion_time_s, 3e-3, 1e-12);  // rows 2 -> 5
}

}  // namespace
}  // namespace dtis::interp
