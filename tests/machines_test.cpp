// The 5-axis kinematics users have (table-tilting XYZAC and XYZBC, head-table XYZAC and XYZBC):
// inverse-then-forward round trips, the same joints as LinuxCNC's own kinematics modules for the
// same pivots, continuity through the vertical; LinuxCNC INI files read to the limits they state;
// machine files written back out read to the same machine.
#include "dtis/kinematics/machines.hpp"

#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <filesystem>
#include <numbers>
#include <random>

#include "dtis/core/error.hpp"
#include "dtis/core/file_text.hpp"
#include "test_support.hpp"

namespace dtis {
namespace {

using kinematics::Kinematics;
using kinematics::MachineDescription;
constexpr double kDeg = std::numbers::pi / 180.0;

Axis Linear(const char* name) { return {name, false, -1e4, 1e4, false, 100.0, 1000.0, 1e4}; }
Axis Rotary(const char* name, double min_deg, double max_deg) {
  return {name, true, min_deg * kDeg, max_deg * kDeg, false, 1.0, 10.0, 100.0};
}
Axis Continuous(const char* name) {
  return {name, true, -INFINITY, INFINITY, true, 1.0, 10.0, 100.0};
}

MachineDescription Describe(Kinematics k) {
  MachineDescription d;
  d.name = kinematics::KinematicsName(k);
  d.kinematics = k;
  const bool b = k == Kinematics::kXyzbcTrt || k == Kinematics::kXyzbcHeadTable;
  d.axes = {Linear("X"), Linear("Y"), Linear("Z"), Rotary(b ? "B" : "A", -120, 120),
            Continuous("C")};
  d.tilt_pivot = Eigen::Vector3d(10, -20, 35);
  d.c_pivot = Eigen::Vector3d(3, 4, -5);
  d.head_length_mm = 250.0;
  return d;
}

// Every 5-axis arrangement, head directions both ways.
std::vector<MachineDescription> AllFiveAxis() {
  std::vector<MachineDescription> out;
  for (Kinematics k : {Kinematics::kXyzacTrt, Kinematics::kXyzbcTrt, Kinematics::kXyzacHeadTable,
                       Kinematics::kXyzbcHeadTable}) {
    out.push_back(Describe(k));
  }
  for (Kinematics k : {Kinematics::kXyzacHeadTable, Kinematics::kXyzbcHeadTable}) {
    MachineDescription d = Describe(k);
    d.head_direction = -1.0;
    d.c_direction = -1.0;
    d.c_pivot = Eigen::Vector3d::Zero();
    out.push_back(d);
  }
  return out;
}

std::string Label(const MachineDescription& d) {
  return fmt::format("{} directions {} {}", d.name, d.head_direction, d.c_direction);
}

TEST(FiveAxis, InverseThenForwardReturnsThePose) {
  std::mt19937_64 rng(test::g_seed + 41);
  std::uniform_real_distribution<double> coord(-200.0, 200.0), unit(-1.0, 1.0);
  for (const MachineDescription& d : AllFiveAxis()) {
    const auto m = kinematics::BuildMachine(d);
    for (long c = 0; c < test::g_count * 5; ++c) {
      Pose pose;
      pose.tip = Eigen::Vector3d(coord(rng), coord(rng), coord(rng));
      do {
        pose.axis = Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
      } while (pose.axis.norm() < 0.1 || pose.axis.normalized().z() < -0.45);
      pose.axis.normalize();
      AxisVector q;
      ASSERT_EQ(m->Inverse(pose, nullptr, &q).status, InverseStatus::kOk) << Label(d) << c;
      const Pose back = m->Forward(q);
      ASSERT_LE((back.tip - pose.tip).norm(), 1e-9) << Label(d) << " case " << c;
      ASSERT_LE((back.axis - pose.axis).norm(), 1e-12) << Label(d) << " case " << c;
      // From its own positions the inverse stays on them.
      AxisVector again;
      ASSERT_EQ(m->Inverse(back, &q, &again).status, InverseStatus::kOk);
      ASSERT_LE((again - q).norm(), 1e-9) << Label(d) << " case " << c;
    }
  }
}

// LinuxCNC's xyzac-trt-kins, xyzbc-trt-kins and maxkins inverse kinematics, written out from
// their published equations (machine position of workpiece point p at the rotary angles t, c).
Eigen::Vector3d LinuxcncXyzacTrt(const Eigen::Vector3d& p, double a, double c,
                                 const Eigen::Vector3d& rot, double dy, double dz) {
  const Eigen::Vector3d d = p - rot;
  const double ca = std::cos(a), sa = std::sin(a), cc = std::cos(c), sc = std::sin(c);
  return {cc * d.x() - sc * d.y() + rot.x(),
          sc * ca * d.x() + cc * ca * d.y() - sa * d.z() - ca * dy + sa * dz + dy + rot.y(),
          sc * sa * d.x() + cc * sa * d.y() + ca * d.z() - sa * dy - ca * dz + dz + rot.z()};
}

Eigen::Vector3d LinuxcncXyzbcTrt(const Eigen::Vector3d& p, double b, double c,
                                 const Eigen::Vector3d& rot, double dx, double dz) {
  const Eigen::Vector3d d = p - rot;
  const double cb = std::cos(b), sb = std::sin(b), cc = std::cos(c), sc = std::sin(c);
  const double dpx = -cb * dx - sb * dz + dx, dpz = sb * dx - cb * dz + dz;
  return {cc * cb * d.x() - sc * cb * d.y() + sb * d.z() + dpx + rot.x(),
          sc * d.x() + cc * d.y() + rot.y(),
          -cc * sb * d.x() + sc * sb * d.y() + cb * d.z() + dpz + rot.z()};
}

Eigen::Vector3d LinuxcncMaxkins(const Eigen::Vector3d& p, double b, double c, double pivot) {
  const double r = std::hypot(p.x(), p.y()), theta = std::atan2(p.y(), p.x()) - c;
  return {r * std::cos(theta) - pivot * std::sin(b), r * std::sin(theta),
          p.z() + pivot * std::cos(b) - pivot};
}

// For random axis positions q: the tool tip dtis says q holds, and a point h up its tool axis,
// are where LinuxCNC's equations put the linear axes, h apart along the spindle.
template <typename Oracle>
void ExpectSameAsLinuxcnc(const Machine& m, const Oracle& oracle, const Eigen::Vector3d& spindle_at,
                          bool head) {
  std::mt19937_64 rng(test::g_seed + 43);
  std::uniform_real_distribution<double> coord(-150.0, 150.0), angle(-1.5, 1.5), turn(-7.0, 7.0);
  for (long c = 0; c < test::g_count * 5; ++c) {
    AxisVector q(5);
    q << coord(rng), coord(rng), coord(rng), angle(rng), turn(rng);
    const Pose pose = m.Forward(q);
    const Eigen::Vector3d xyz = oracle(pose.tip, q[3], q[4]);
    ASSERT_LE((xyz - q.head<3>()).norm(), 1e-9) << m.Name() << " case " << c;
    const double h = 40.0;
    const Eigen::Vector3d up = oracle(pose.tip + h * pose.axis, q[3], q[4]);
    // A table machine's spindle is +Z; a head's is where the head turns it.
    const Eigen::Vector3d expected =
        head ? Eigen::Vector3d(-std::sin(q[3]), 0, std::cos(q[3])) : spindle_at;
    ASSERT_LE((up - xyz - h * expected).norm(), 1e-9) << m.Name() << " case " << c;
  }
}

TEST(FiveAxis, SameJointsAsLinuxcncKinematics) {
  const Eigen::Vector3d rot(12.5, -7.0, 30.0);
  MachineDescription ac = Describe(Kinematics::kXyzacTrt);
  ac.c_pivot = rot;
  ac.tilt_pivot = rot + Eigen::Vector3d(0, 15.0, -22.0);
  ExpectSameAsLinuxcnc(
      *kinematics::BuildMachine(ac),
      [&](const Eigen::Vector3d& p, double a, double c) {
        return LinuxcncXyzacTrt(p, a, c, rot, 15.0, -22.0);
      },
      Eigen::Vector3d::UnitZ(), false);

  MachineDescription bc = Describe(Kinematics::kXyzbcTrt);
  bc.c_pivot = rot;
  bc.tilt_pivot = rot + Eigen::Vector3d(-20.0, 0, -15.0);
  ExpectSameAsLinuxcnc(
      *kinematics::BuildMachine(bc),
      [&](const Eigen::Vector3d& p, double b, double c) {
        return LinuxcncXyzbcTrt(p, b, c, rot, -20.0, -15.0);
      },
      Eigen::Vector3d::UnitZ(), false);

  // maxkins as LinuxCNC 2.9 ships it: head B and table C both reversed, C about the Z axis.
  MachineDescription max = Describe(Kinematics::kXyzbcHeadTable);
  max.c_pivot = Eigen::Vector3d::Zero();
  max.head_length_mm = 95.0;
  max.head_direction = -1.0;
  max.c_direction = -1.0;
  ExpectSameAsLinuxcnc(
      *kinematics::BuildMachine(max),
      [&](const Eigen::Vector3d& p, double b, double c) { return LinuxcncMaxkins(p, b, c, 95.0); },
      Eigen::Vector3d::UnitZ(), true);
}

TEST(FiveAxis, StaysContinuousThroughTheVertical) {
  // The tool axis sweeps through +Z across the tilting axis: the tilt changes sign, C stays.
  for (const MachineDescription& d : AllFiveAxis()) {
    const auto m = kinematics::BuildMachine(d);
    const bool about_y = d.axes[3].name == "B";
    AxisVector q, previous;
    for (int i = -50; i <= 50; ++i) {
      const double s = std::sin(i * 0.5 * kDeg), c = std::cos(i * 0.5 * kDeg);
      const Pose pose{Eigen::Vector3d(1, 2, 3),
                      about_y ? Eigen::Vector3d(s, 0, c) : Eigen::Vector3d(0, s, c)};
      ASSERT_EQ(m->Inverse(pose, i > -50 ? &previous : nullptr, &q).status, InverseStatus::kOk)
          << Label(d) << " step " << i;
      if (i > -50) {
        EXPECT_LT(std::abs(q[4] - previous[4]), 1e-9) << Label(d) << " C jumped at step " << i;
        EXPECT_LT(std::abs(q[3] - previous[3]), 0.6 * kDeg) << Label(d) << " step " << i;
      }
      previous = q;
    }
  }
}

TEST(FiveAxis, ReportsTravel) {
  for (const MachineDescription& d : AllFiveAxis()) {
    const auto m = kinematics::BuildMachine(d);
    AxisVector q;
    const Pose tilted{
        Eigen::Vector3d::Zero(),
        Eigen::Vector3d(std::sin(130 * kDeg), 0.2, std::cos(130 * kDeg)).normalized()};
    const InverseResult r = m->Inverse(tilted, nullptr, &q);
    EXPECT_EQ(r.status, InverseStatus::kOutOfTravel) << Label(d);
    EXPECT_EQ(r.axis, 3) << Label(d);
  }
}

TEST(MachineFile, FormatReadsBackToTheSameMachine) {
  std::mt19937_64 rng(test::g_seed + 47);
  std::uniform_real_distribution<double> coord(-100.0, 100.0), angle(-1.5, 1.5);
  for (const MachineDescription& d : AllFiveAxis()) {
    const std::string text = kinematics::FormatMachineFile(d);
    const MachineDescription back = kinematics::ParseMachineDescription(text, "formatted.toml");
    ASSERT_EQ(back.kinematics, d.kinematics) << text;
    ASSERT_EQ(back.axes.size(), d.axes.size());
    for (std::size_t i = 0; i < d.axes.size(); ++i) {
      EXPECT_EQ(back.axes[i].name, d.axes[i].name);
      EXPECT_EQ(back.axes[i].continuous, d.axes[i].continuous);
      EXPECT_NEAR(back.axes[i].vmax, d.axes[i].vmax, 1e-12 * d.axes[i].vmax);
      EXPECT_NEAR(back.axes[i].amax, d.axes[i].amax, 1e-12 * d.axes[i].amax);
      EXPECT_NEAR(back.axes[i].jmax, d.axes[i].jmax, 1e-12 * d.axes[i].jmax);
      if (!d.axes[i].continuous) {
        EXPECT_NEAR(back.axes[i].travel_min, d.axes[i].travel_min, 1e-12);
        EXPECT_NEAR(back.axes[i].travel_max, d.axes[i].travel_max, 1e-12);
      }
    }
    const auto m = kinematics::BuildMachine(d), n = kinematics::BuildMachine(back);
    for (int c = 0; c < 20; ++c) {
      AxisVector q(5);
      q << coord(rng), coord(rng), coord(rng), angle(rng), angle(rng);
      const Pose a = m->Forward(q), b = n->Forward(q);
      EXPECT_LE((a.tip - b.tip).norm(), 1e-9) << Label(d);
      EXPECT_LE((a.axis - b.axis).norm(), 1e-12) << Label(d);
    }
  }
}

TEST(MachineFile, InchUnits) {
  const auto m = kinematics::ParseMachine(R"(
name = "inch"
kinematics = "xyz"
[units]
length = "in"
linear_velocity = "in/s"
linear_acceleration = "in/s^2"
linear_jerk = "in/s^3"
[axes.X]
travel = [-10, 10]
velocity = 4
acceleration = 100
jerk = 5000
[axes.Y]
travel = [-10, 10]
velocity = 4
acceleration = 100
jerk = 5000
[axes.Z]
travel = [-8, 0.12]
velocity = 2
acceleration = 50
jerk = 2500
)",
                                          "inch.toml");
  const auto a = m->Axes();
  EXPECT_DOUBLE_EQ(a[0].vmax, 101.6);
  EXPECT_DOUBLE_EQ(a[1].amax, 2540.0);
  EXPECT_DOUBLE_EQ(a[2].jmax, 2500 * 25.4);
  EXPECT_DOUBLE_EQ(a[2].travel_max, 0.12 * 25.4);
}

// LinuxCNC's own sim configurations, where LinuxCNC is installed (linuxcnc-uspace).
const std::string kSimConfigs = "/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/";

void ExpectAxis(const Axis& a, double vmax, double amax, double jmax, double min, double max) {
  EXPECT_NEAR(a.vmax, vmax, 1e-12 * vmax) << a.name;
  EXPECT_NEAR(a.amax, amax, 1e-12 * amax) << a.name;
  EXPECT_NEAR(a.jmax, jmax, 1e-12 * jmax) << a.name;
  EXPECT_NEAR(a.travel_min, min, 1e-12 * std::abs(min)) << a.name;
  EXPECT_NEAR(a.travel_max, max, 1e-12 * std::abs(max)) << a.name;
}

TEST(LinuxcncIni, SimConfigsImportToTheirLimits) {
  if (!std::filesystem::exists(kSimConfigs + "axis_mm.ini")) {
    GTEST_SKIP() << "LinuxCNC's sample configurations are not installed";
  }
  kinematics::MachineLoadOptions o;
  o.jerk_time_s = 0.02;
  // axis_mm.ini: mm, every axis 30.48 mm/s and 508 mm/s^2.
  const auto mm = kinematics::ReadMachineDescription(kSimConfigs + "axis_mm.ini", o);
  EXPECT_EQ(mm.kinematics, Kinematics::kXyz);
  ASSERT_EQ(mm.axes.size(), 3u);
  ExpectAxis(mm.axes[0], 30.48, 508, 508 / 0.02, -254, 254);
  ExpectAxis(mm.axes[2], 30.48, 508, 508 / 0.02, -50.8, 101.6);
  // axis.ini, in inches: [AXIS_X] 4 in/s and 100 in/s^2, [JOINT_0] 5 in/s and 50 in/s^2; with
  // identity kinematics LinuxCNC holds the joint to both. Z from -8 to 0.12 in.
  const auto in = kinematics::ReadMachineDescription(kSimConfigs + "axis.ini", o);
  ExpectAxis(in.axes[0], 4 * 25.4, 50 * 25.4, 50 * 25.4 / 0.02, -10 * 25.4, 10 * 25.4);
  ExpectAxis(in.axes[2], 4 * 25.4, 50 * 25.4, 50 * 25.4 / 0.02, -8 * 25.4, 0.12 * 25.4);
  // The table-tilting XYZBC sim: joint limits, and the offsets its HALCMD lines set through
  // signals (x-offset -20, z-offset -15).
  const auto trt = kinematics::ReadMachineDescription(
      kSimConfigs + "vismach/5axis/table-rotary-tilting/xyzbc-trt.ini", o);
  EXPECT_EQ(trt.kinematics, Kinematics::kXyzbcTrt);
  ASSERT_EQ(trt.axes.size(), 5u);
  ExpectAxis(trt.axes[3], 30 * kDeg, 300 * kDeg, 300 * kDeg / 0.02, -100 * kDeg, 50 * kDeg);
  EXPECT_LE((trt.tilt_pivot - Eigen::Vector3d(-20, 0, -15)).norm(), 1e-12);
  EXPECT_LE(trt.c_pivot.norm(), 1e-12);
  // maxkins: head B, table C, the pivot length from an #INCLUDEd [MAX] value (0).
  const auto max =
      kinematics::ReadMachineDescription(kSimConfigs + "vismach/5axis/max5/max5kins.ini", o);
  EXPECT_EQ(max.kinematics, Kinematics::kXyzbcHeadTable);
  EXPECT_EQ(max.axes[3].name, "B");
  ExpectAxis(max.axes[3], 45 * kDeg, 225 * kDeg, 225 * kDeg / 0.02, -90 * kDeg, 90 * kDeg);
  EXPECT_EQ(max.head_direction, -1.0);
}

TEST(LinuxcncIni, ReadsUnitsJointsPinsAndIncludes) {
  kinematics::MachineLoadOptions o;
  o.jerk_time_s = 0.05;
  const auto d = kinematics::ReadMachineDescription(test::Source("tests/data/ini/trt_inch.ini"), o);
  EXPECT_EQ(d.name, "trt inch test mill");
  EXPECT_EQ(d.kinematics, Kinematics::kXyzbcTrt);
  ASSERT_EQ(d.axes.size(), 5u);
  constexpr double in = 25.4;
  // X: the tighter of joint and axis, the joint's travel, the axis' jerk.
  ExpectAxis(d.axes[0], 3 * in, 50 * in, 2000 * in, -9 * in, 9.5 * in);
  // Y: a continued line; no jerk anywhere, so acceleration / jerk time.
  ExpectAxis(d.axes[1], 4 * in, 40 * in, 40 * in / 0.05, -6 * in, 6 * in);
  ExpectAxis(d.axes[2], 2 * in, 30 * in, 30 * in / 0.05, -8 * in, 0.5 * in);
  ExpectAxis(d.axes[3], 90 * kDeg, 400 * kDeg, 400 * kDeg / 0.05, -95 * kDeg, 95 * kDeg);
  EXPECT_TRUE(d.axes[4].continuous);
  EXPECT_NEAR(d.axes[4].jmax, 16000 * kDeg, 1e-9);
  // Pivots: rot-point from [TRT] values (#INCLUDE) and a `pin = value` line; offsets by setp and
  // by a signal; y-offset is not an xyzbc-trt-kins offset.
  EXPECT_LE((d.c_pivot - Eigen::Vector3d(1.5, -0.25, 2) * in).norm(), 1e-12);
  EXPECT_LE((d.tilt_pivot - Eigen::Vector3d(2.25, -0.25, 1.5) * in).norm(), 1e-12);
}

TEST(LinuxcncIni, ErrorsNameTheFileLineAndKey) {
  const std::string dir = test::Source("tests/data/ini/");
  test::ExpectError([&] { kinematics::LoadMachineFile(dir + "trt_inch.ini"); },
                    "trt_inch.ini: neither [JOINT_1] nor [AXIS_Y] gives MAX_JERK; give the job "
                    "key machine_jerk_time_ms");
  test::ExpectError([&] { kinematics::LoadMachineFile(dir + "hexapod.ini"); },
                    "hexapod.ini:2: [KINS] KINEMATICS: kinematics 'genhexkins' is not one dtis "
                    "models");
  kinematics::MachineLoadOptions o;
  o.jerk_time_s = 0.02;
  test::ExpectError(
      [&] {
        kinematics::ParseLinuxcncIni(
            "[KINS]\nKINEMATICS = trivkins\n[TRAJ]\nLINEAR_UNITS = "
            "furlong\n",
            "m.ini", o);
      },
      "m.ini:4: [TRAJ] LINEAR_UNITS: expected mm, inch or a number of units per mm, got "
      "'furlong'");
  test::ExpectError(
      [&] {
        kinematics::ParseLinuxcncIni(
            "[KINS]\nKINEMATICS = trivkins\n[JOINT_0]\nMAX_VELOCITY = "
            "fast\n",
            "m.ini", o);
      },
      "m.ini:4: [JOINT_0] MAX_VELOCITY: expected a number, got 'fast'");
  test::ExpectError(
      [&] {
        kinematics::ParseLinuxcncIni(
            "[KINS]\nKINEMATICS = trivkins\n[TRAJ]\nCOORDINATES = X Y Z A\n", "m.ini", o);
      },
      "m.ini:4: [TRAJ] COORDINATES: axis A of coordinates XYZA: a trivkins machine in dtis has "
      "the axes XYZ");
  // A HAL file that cannot be read might set the pivots: never read as pivots at 0.
  std::string trt = *ReadFileText(dir + "trt_inch.ini");
  trt.replace(trt.find("HALFILE = trt_inch.hal"), 22, "HALFILE = no_such.hal");
  test::ExpectError([&] { kinematics::ParseLinuxcncIni(trt, dir + "trt_inch.ini", o); },
                    "trt_inch.ini:14: [HAL] HALFILE: cannot read " + dir +
                        "no_such.hal, where xyzbc-trt-kins's pivots may be set");
  test::ExpectError([&] { kinematics::ParseLinuxcncIni("[TRAJ]\n", "m.ini", o); },
                    "m.ini: [KINS] KINEMATICS is missing");
}

// What LinuxCNC itself would refuse or ignore is refused, naming the line: a joint count past its
// 16, a second section of a name whose first LinuxCNC reads alone, a jerk time out of range.
TEST(LinuxcncIni, NonsenseIsRefused) {
  const std::string dir = test::Source("tests/data/ini/");
  const std::string trt = *ReadFileText(dir + "trt_inch.ini");
  kinematics::MachineLoadOptions o;
  o.jerk_time_s = 0.02;
  EXPECT_NO_THROW(kinematics::ParseLinuxcncIni(trt, dir + "trt_inch.ini", o));
  std::string joints = trt;
  joints.replace(joints.find("[KINS]"), 6, "[KINS]\nJOINTS = 1000000000");
  test::ExpectError([&] { kinematics::ParseLinuxcncIni(joints, dir + "trt_inch.ini", o); },
                    "[KINS] JOINTS: expected a whole number of joints from 1 to 16 (LinuxCNC's "
                    "most), got '1000000000'");
  const std::string twice = trt + "\n[AXIS_X]\nMAX_VELOCITY = 99\n";
  test::ExpectError([&] { kinematics::ParseLinuxcncIni(twice, dir + "trt_inch.ini", o); },
                    {"[AXIS_X] appears a second time (first at " + dir + "trt_inch.ini:",
                     "LinuxCNC reads only the first"});
  // Sections dtis does not read may repeat, as LinuxCNC allows.
  EXPECT_NO_THROW(kinematics::ParseLinuxcncIni(trt + "\n[DISPLAY]\nA = 1\n[DISPLAY]\nB = 2\n",
                                               dir + "trt_inch.ini", o));
  for (const double t : {1e-303, 0.0, -1.0, 20.0, std::nan("")}) {
    kinematics::MachineLoadOptions bad;
    bad.jerk_time_s = t;
    test::ExpectError([&] { kinematics::ReadMachineDescription(dir + "trt_inch.ini", bad); },
                      "(machine_jerk_time_ms or --jerk-time-ms)");
  }
}

}  // namespace
}  // namespace dtis
