// Machine models: inverse-then-forward returns the pose (randomized), branches stay continuous,
// travel and reachability failures are reported, machine files are read with their units.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <numbers>
#include <random>

#include "dtis/core/error.hpp"
#include "dtis/kinematics/machines.hpp"
#include "test_support.hpp"

namespace dtis {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

std::unique_ptr<Machine> Mikron() {
  return kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyzac.toml"));
}

TEST(MachineFile, ReadsTable1InItsUnits) {
  const auto m = Mikron();
  ASSERT_EQ(m->AxisCount(), 5);
  const auto a = m->Axes();
  EXPECT_DOUBLE_EQ(a[0].vmax, 30.0 * 1000.0 / 60.0);                  // 30 m/min in mm/s
  EXPECT_DOUBLE_EQ(a[1].amax, 3000.0);                                // 3 m/s^2
  EXPECT_DOUBLE_EQ(a[2].jmax, 50000.0);                               // 50 m/s^3
  EXPECT_DOUBLE_EQ(a[3].vmax, 15.0 * 2.0 * std::numbers::pi / 60.0);  // 15 rpm in rad/s
  EXPECT_DOUBLE_EQ(a[4].jmax, 100.0 * 2.0 * std::numbers::pi);        // 100 rev/s^3
  EXPECT_DOUBLE_EQ(a[3].travel_min, -100.0 * kDeg);
  EXPECT_TRUE(a[4].continuous);
}

TEST(Xyzac, InverseThenForwardReturnsThePose) {
  const auto m = kinematics::ParseMachine(R"(
name = "offset pivots"
kinematics = "xyzac"
[units]
length = "mm"
angle = "deg"
linear_velocity = "mm/s"
linear_acceleration = "mm/s^2"
linear_jerk = "mm/s^3"
rotary_velocity = "deg/s"
rotary_acceleration = "deg/s^2"
rotary_jerk = "deg/s^3"
[axes.X]
travel = [-1e4, 1e4]
velocity = 1
acceleration = 1
jerk = 1
[axes.Y]
travel = [-1e4, 1e4]
velocity = 1
acceleration = 1
jerk = 1
[axes.Z]
travel = [-1e4, 1e4]
velocity = 1
acceleration = 1
jerk = 1
[axes.A]
travel = [-120, 120]
velocity = 1
acceleration = 1
jerk = 1
[axes.C]
travel = "continuous"
velocity = 1
acceleration = 1
jerk = 1
[pivot]
a_axis = [10, -20, 35]
c_axis = [3, 4, -5]
)",
                                          "inline");
  std::mt19937_64 rng(test::g_seed + 11);
  std::uniform_real_distribution<double> coord(-200.0, 200.0), unit(-1.0, 1.0);
  for (long c = 0; c < test::g_count * 10; ++c) {
    Pose pose;
    pose.tip = Eigen::Vector3d(coord(rng), coord(rng), coord(rng));
    do {
      pose.axis = Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
    } while (pose.axis.norm() < 0.1 || pose.axis.normalized().z() < -0.45);
    pose.axis.normalize();
    AxisVector q;
    const InverseResult r = m->Inverse(pose, nullptr, &q);
    ASSERT_EQ(r.status, InverseStatus::kOk) << "case " << c;
    const Pose back = m->Forward(q);
    ASSERT_LE((back.tip - pose.tip).norm(), 1e-9) << "case " << c;
    ASSERT_LE((back.axis - pose.axis).norm(), 1e-12) << "case " << c;
  }
}

TEST(Xyzac, BranchStaysContinuousThroughTheVertical) {
  // The tool axis sweeps through +Z in the XZ plane: A changes sign, C does not flip.
  const auto m = Mikron();
  AxisVector q, previous;
  bool first = true;
  for (int i = -50; i <= 50; ++i) {
    const double angle = i * 0.5 * kDeg;
    const Pose pose{Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(std::sin(angle), 0, std::cos(angle))};
    ASSERT_EQ(m->Inverse(pose, first ? nullptr : &previous, &q).status, InverseStatus::kOk);
    if (!first) {
      EXPECT_LT(std::abs(q[4] - previous[4]), 1e-9) << "C jumped at step " << i;
      EXPECT_LT(std::abs(q[3] - previous[3]), 0.6 * kDeg) << "A jumped at step " << i;
    }
    previous = q;
    first = false;
  }
}

TEST(Xyzac, UnwrapsCAcrossTurns) {
  const auto m = Mikron();
  AxisVector q, previous;
  for (int i = 0; i <= 1000; ++i) {
    const double phi = i * 2.0 * std::numbers::pi / 250.0;  // four turns of the tool axis
    const Pose pose{Eigen::Vector3d(0, 0, 0),
                    Eigen::Vector3d(0.3 * std::cos(phi), 0.3 * std::sin(phi), 1.0).normalized()};
    ASSERT_EQ(m->Inverse(pose, i ? &previous : nullptr, &q).status, InverseStatus::kOk);
    if (i) {
      ASSERT_LT(std::abs(q[4] - previous[4]), 0.1);
    }
    previous = q;
  }
  // C = atan2(nx, ny) falls as the axis turns anticlockwise: 4 turns down from pi/2.
  EXPECT_NEAR(q[4], std::numbers::pi / 2.0 - 8.0 * std::numbers::pi, 1e-9);
}

TEST(Xyzac, ReportsTravelAndReach) {
  const auto m = Mikron();
  AxisVector q;
  // 130 deg of tilt on either branch is beyond A's [-100, 120].
  const Pose tilted{Eigen::Vector3d::Zero(),
                    Eigen::Vector3d(std::sin(130 * kDeg), 0, std::cos(130 * kDeg))};
  const InverseResult r = m->Inverse(tilted, nullptr, &q);
  EXPECT_EQ(r.status, InverseStatus::kOutOfTravel);
  EXPECT_NE(DescribeInverseFailure(*m, r).find("travel"), std::string::npos);
  const Pose far{Eigen::Vector3d(1000, 0, 0), Eigen::Vector3d::UnitZ()};
  EXPECT_EQ(m->Inverse(far, nullptr, &q).status, InverseStatus::kOutOfTravel);
  // An overrun of a hair is printed with the digits that show it.
  const auto& x = m->Axes()[0];
  const std::string hair =
      DescribeInverseFailure(*m, {InverseStatus::kOutOfTravel, 0, x.travel_max + 4e-4});
  EXPECT_NE(hair.find(fmt::format("reach {:.10g} mm, 0.0004 mm outside its travel [{}, {}] mm",
                                  x.travel_max + 4e-4, x.travel_min, x.travel_max)),
            std::string::npos)
      << hair;

  const auto xyz =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  EXPECT_EQ(
      xyz->Inverse({Eigen::Vector3d::Zero(), Eigen::Vector3d(0.1, 0, 1).normalized()}, nullptr, &q)
          .status,
      InverseStatus::kUnreachable);
}

void ExpectMachineError(const std::string& text, const std::string& fragment) {
  try {
    kinematics::ParseMachine(text, "m.toml");
    FAIL() << "expected an error containing '" << fragment << "'";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find(fragment), std::string::npos) << e.what();
  }
}

TEST(MachineFile, BadInputNamesFileLineAndKey) {
  const std::string units = R"(
[units]
length = "mm"
angle = "deg"
linear_velocity = "mm/s"
linear_acceleration = "mm/s^2"
linear_jerk = "mm/s^3"
rotary_velocity = "deg/s"
rotary_acceleration = "deg/s^2"
rotary_jerk = "deg/s^3"
)";
  const std::string axes = R"(
[axes.X]
travel = [-1, 1]
velocity = 1
acceleration = 1
jerk = 1
[axes.Y]
travel = [-1, 1]
velocity = 1
acceleration = 1
jerk = 1
)";
  const std::string z_ok = "[axes.Z]\ntravel = [-1, 1]\nvelocity = 1\nacceleration = 1\njerk = 1\n";
  const std::string head = "name = \"m\"\nkinematics = \"xyz\"\n";
  EXPECT_NO_THROW(kinematics::ParseMachine(head + units + axes + z_ok, "m.toml"));
  ExpectMachineError(head + units + axes +
                         "[axes.Z]\ntravel = [-1, 1]\nvelocity = -3\n"
                         "acceleration = 1\njerk = 1\n",
                     "m.toml:26: key 'axes.Z.velocity': expected a number > 0, got -3");
  ExpectMachineError(head + units + axes +
                         "[axes.Z]\ntravel = [-1, 1]\nvelocity = nan\n"
                         "acceleration = 1\njerk = 1\n",
                     "axes.Z.velocity': expected a finite number");
  ExpectMachineError(head + units + axes + z_ok + "speed = 3\n", "unknown key 'axes.Z.speed'");
  ExpectMachineError(head + units + axes, "missing axis table [axes.Z]");
  // An XYZ machine needs no angle or rotary units; when it states them they are checked, and a
  // machine with rotary axes must state them.
  const std::string linear_units =
      "[units]\nlength = \"mm\"\nlinear_velocity = \"mm/s\"\n"
      "linear_acceleration = \"mm/s^2\"\nlinear_jerk = \"mm/s^3\"\n";
  EXPECT_NO_THROW(kinematics::ParseMachine(head + linear_units + axes + z_ok, "m.toml"));
  ExpectMachineError(head + linear_units + "rotary_jerk = \"deg/h\"\n" + axes + z_ok,
                     "key 'units.rotary_jerk': 'deg/h' is not one of");
  const std::string rotary =
      "[axes.A]\ntravel = [-90, 90]\nvelocity = 1\nacceleration = 1\njerk = 1\n"
      "[axes.C]\ntravel = \"continuous\"\nvelocity = 1\nacceleration = 1\njerk = 1\n"
      "[pivot]\na_axis = [0, 0, 0]\nc_axis = [0, 0, 0]\n";
  ExpectMachineError("name = \"m\"\nkinematics = \"xyzac\"\n" + linear_units + axes + z_ok + rotary,
                     "missing key 'units.angle'");
  ExpectMachineError("name = \"m\"\nkinematics = \"hexapod\"\n",
                     "key 'kinematics': 'hexapod' is not one of 'xyz', 'xyzac'");
  ExpectMachineError("name = \"m\"\nkinematics = [\n", "m.toml:2:");
}

}  // namespace
}  // namespace dtis
