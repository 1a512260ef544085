// Six-joint serial arms: inverse-then-forward round trips over random reachable poses (a chain of
// joint frames and a modified Denavit-Hartenberg chain), the locked joint staying locked, the
// configuration never flipping, a pass through the wrist singularity refused naming it and one
// beside it slowed; machine files read, refused and written back.
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <Eigen/Geometry>
#include <filesystem>
#include <numbers>
#include <random>
#include <sstream>

#include "dtis/core/error.hpp"
#include "dtis/core/file_text.hpp"
#include "dtis/geometry/curve_path.hpp"
#include "dtis/kinematics/machines.hpp"
#include "test_support.hpp"

namespace dtis {
namespace {

using kinematics::MachineDescription;
using kinematics::SerialArmMachine;
constexpr double kDeg = std::numbers::pi / 180.0;

const std::string kRx170b = "samples/machines/staubli_rx170b.toml";

MachineDescription Rx170b() { return kinematics::ReadMachineDescription(test::Source(kRx170b)); }

// LinuxCNC's PUMA 560 simulation (puma560_dh.hal, genserkins) in mm, with a tool and J6 locked.
MachineDescription Puma560() {
  MachineDescription d;
  d.name = "puma560";
  d.kinematics = kinematics::Kinematics::kSerialArm;
  for (int i = 1; i <= 6; ++i) {
    d.axes.push_back(
        {fmt::format("J{}", i), true, -170 * kDeg, 170 * kDeg, false, 2.0, 10.0, 100.0});
  }
  auto& arm = d.arm;
  arm.form = kinematics::ArmDescription::Form::kDh;
  const double in = 25.4, h = std::numbers::pi / 2;
  arm.a = {0, 0, 17 * in, 0, 0, 0};
  arm.alpha = {0, h, 0, h, -h, h};
  arm.d = {26.45 * in, -5.5 * in, 0, 17.05 * in, 0, 2.2 * in};
  arm.tool_tip = {0, 0, 150};
  arm.home = {0, -30 * kDeg, -60 * kDeg, 0, 45 * kDeg, 0};
  return d;
}

double Angle(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

// The smallest singular value of the five free joints' Jacobian of the pose (the tip over 1 m, the
// tool axis across itself), by central differences of the forward transform: near 0 at every
// singularity of the five-joint problem, the shoulder, elbow and wrist ones and, with a tool off
// J6's axis, its own.
double TaskSingularValue(const SerialArmMachine& arm, const MachineDescription& d,
                         const AxisVector& q) {
  const Pose at = arm.Forward(q);
  const Eigen::Vector3d e1 = at.axis.unitOrthogonal(), e2 = at.axis.cross(e1);
  Eigen::Matrix<double, 5, 5> j;
  for (int i = 0, k = 0; i < 6; ++i) {
    if (i == d.arm.locked_joint) continue;
    AxisVector lo = q, hi = q;
    lo[i] -= 1e-6;
    hi[i] += 1e-6;
    const Pose a = arm.Forward(lo), b = arm.Forward(hi);
    j.col(k++) << (b.tip - a.tip) / 2e-3, e1.dot(b.axis - a.axis) / 2e-6,
        e2.dot(b.axis - a.axis) / 2e-6;
  }
  return Eigen::JacobiSVD<Eigen::Matrix<double, 5, 5>>(j).singularValues()[4];
}

// Random joints within travel, the locked joint at its value, away from every singularity: the pose
// they hold, solved from joints near them, gives them back, and the pose to 1e-9 mm and 1e-9 rad.
void RoundTrips(const MachineDescription& d, std::uint64_t seed) {
  const SerialArmMachine arm(d);
  std::mt19937_64 rng(test::g_seed + seed);
  std::uniform_real_distribution<double> unit(0.0, 1.0), nudge(-0.02, 0.02);
  long tried = 0, solved = 0, from_home = 0;
  for (long c = 0; solved < test::g_count && tried < 50 * test::g_count; ++c) {
    ++tried;
    AxisVector q(6);
    for (int i = 0; i < 6; ++i) {
      const Axis& a = d.axes[static_cast<std::size_t>(i)];
      const double lo = std::max(a.travel_min, -3.0), hi = std::min(a.travel_max, 3.0);
      q[i] = lo + (hi - lo) * unit(rng);
    }
    q[d.arm.locked_joint] = d.arm.locked_at;
    if (arm.Configuration(q).cwiseAbs().minCoeff() < 0.05) continue;
    if (TaskSingularValue(arm, d, q) < 0.05) continue;
    const Pose pose = arm.Forward(q);
    AxisVector near = q;
    for (int i = 0; i < 6; ++i) near[i] += i == d.arm.locked_joint ? 0.0 : nudge(rng);
    AxisVector back;
    const InverseResult r = arm.Inverse(pose, &near, &back);
    ASSERT_EQ(r.status, InverseStatus::kOk)
        << d.name << " case " << c << ": " << DescribeInverseFailure(arm, r);
    ++solved;
    EXPECT_EQ(back[d.arm.locked_joint], d.arm.locked_at) << "the locked joint moved";
    ASSERT_LE((back - q).cwiseAbs().maxCoeff(), 1e-8) << d.name << " case " << c;
    const Pose again = arm.Forward(back);
    ASSERT_LE((again.tip - pose.tip).norm(), 1e-9) << d.name << " case " << c;
    ASSERT_LE(Angle(again.axis, pose.axis), 1e-9) << d.name << " case " << c;
    // From the home posture: the configuration may differ, the pose may not.
    if (arm.Inverse(pose, nullptr, &back).status == InverseStatus::kOk) {
      ++from_home;
      const Pose h = arm.Forward(back);
      ASSERT_LE((h.tip - pose.tip).norm(), 1e-9) << d.name << " case " << c;
      ASSERT_LE(Angle(h.axis, pose.axis), 1e-9) << d.name << " case " << c;
      EXPECT_EQ(back[d.arm.locked_joint], d.arm.locked_at);
    }
  }
  EXPECT_EQ(solved, test::g_count) << "too few random poses away from singularities";
  EXPECT_GT(from_home, 0);
}

TEST(SerialArm, InverseThenForwardFramesChain) { RoundTrips(Rx170b(), 101); }

TEST(SerialArm, InverseThenForwardDhChain) { RoundTrips(Puma560(), 103); }

// A tool off J6's axis (a spindle mounted at 45 degrees, its tip 80 mm aside) leaves J6 useful:
// here J4 is the joint locked instead. The shoulder, elbow and wrist measures do not see this
// five-joint problem's own singularities, near which two solutions lie close: the poses tried keep
// away from those too.
TEST(SerialArm, InverseThenForwardOtherJointLocked) {
  MachineDescription d = Puma560();
  d.arm.tool_tip = {80, 0, 150};
  d.arm.tool_axis = Eigen::Vector3d(1, 0, -1).normalized();
  d.arm.locked_joint = 3;
  d.arm.locked_at = 0.3;
  d.arm.home[3] = 0.3;
  RoundTrips(d, 109);
}

// The modified DH chain is Craig's: joint i's frame is RotX(alpha) TransX(a) RotZ(q) TransZ(d)
// from the previous one; written out by hand for one posture.
TEST(SerialArm, DhChainIsCraigs) {
  const MachineDescription d = Puma560();
  const SerialArmMachine arm(d);
  AxisVector q(6);
  q << 0.3, -0.7, 0.4, 1.1, 0.6, 0.0;
  Eigen::Matrix4d t = Eigen::Matrix4d::Identity();
  for (std::size_t i = 0; i < 6; ++i) {
    const double ca = std::cos(d.arm.alpha[i]), sa = std::sin(d.arm.alpha[i]);
    const double ct = std::cos(q[static_cast<int>(i)]), st = std::sin(q[static_cast<int>(i)]);
    Eigen::Matrix4d m;
    m << ct, -st, 0, d.arm.a[i], st * ca, ct * ca, -sa, -sa * d.arm.d[i], st * sa, ct * sa, ca,
        ca * d.arm.d[i], 0, 0, 0, 1;
    t = t * m;
  }
  EXPECT_LE((arm.Flange(q).matrix() - t).cwiseAbs().maxCoeff(), 1e-9);
}

// A line with the tool vertical through the pose where the forearm hangs straight down (J5 = 0, J4
// and J6 in line), across the arm's plane: J4 would have to turn half a turn at once there.
struct WristPass {
  MachineDescription d = Rx170b();
  Pose singular;
  WristPass() {
    d.arm.part_origin.setZero();
    AxisVector q(6);
    q << 0.0, 60 * kDeg, -120 * kDeg, 0.0, 0.0, 0.0;
    singular = SerialArmMachine(d).Forward(q);
  }
};

TEST(SerialArm, PassThroughTheWristSingularityIsRefusedNamingIt) {
  const WristPass w;
  const SerialArmMachine arm(w.d);
  ASSERT_LE(Angle(w.singular.axis, Eigen::Vector3d::UnitZ()), 1e-12);
  const Eigen::Vector3d side(0, 20, 0);
  const geometry::LinePath line(w.singular.tip - side, w.singular.tip + side,
                                Eigen::Vector3d::UnitZ());
  interp::VpopOptions o;
  o.feed_mm_s = 50.0;
  try {
    test::PlanAndVerify(line, arm, o);
    FAIL() << "planned through the wrist singularity";
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("wrist singularity"), std::string::npos) << what;
    EXPECT_NE(what.find("J5"), std::string::npos) << what;
    EXPECT_NE(what.find("arc length"), std::string::npos) << what;  // where on the path
  }
  // The pose itself, solved from either side, is refused the same way.
  AxisVector q;
  const InverseResult r = arm.Inverse(w.singular, nullptr, &q);
  EXPECT_EQ(r.status, InverseStatus::kSingular);
  EXPECT_EQ(r.axis, 4);
}

// Along the arm's plane with the tool tilted 0.3 deg across it: the forearm turns through the
// tool's direction 0.3 deg away from it, J4 swings half a turn and J5 passes near 0. The planner
// slows the tool there, every setpoint keeps the joints' limits and the configuration never flips.
TEST(SerialArm, PassBesideTheWristSingularityIsSlowed) {
  const WristPass w;
  const SerialArmMachine arm(w.d);
  const Eigen::Vector3d along(20, 0, 0);
  const Eigen::Vector3d tilted =
      Eigen::AngleAxisd(0.3 * kDeg, Eigen::Vector3d::UnitX()) * Eigen::Vector3d::UnitZ();
  const geometry::LinePath line(w.singular.tip - along, w.singular.tip + along, tilted);
  interp::VpopOptions o;
  o.feed_mm_s = 50.0;
  const test::Planned p = test::PlanAndVerify(line, arm, o);
  EXPECT_TRUE(p.report.Passed()) << p.report.worst;
  double slowest = INFINITY, j4_min = INFINITY, j4_max = -INFINITY;
  for (std::size_t k = 1; k < p.points.size(); ++k) {
    if (std::abs(p.points[k].s - 20.0) < 10.0) {
      slowest = std::min(slowest, (p.points[k].s - p.points[k - 1].s) / o.period_s);
    }
    j4_min = std::min(j4_min, p.points[k].q[3]);
    j4_max = std::max(j4_max, p.points[k].q[3]);
    const Eigen::Vector3d a = arm.Configuration(p.points[k - 1].q);
    const Eigen::Vector3d b = arm.Configuration(p.points[k].q);
    ASSERT_GT(a.cwiseProduct(b).minCoeff(), 0.0) << "configuration flipped at setpoint " << k;
  }
  EXPECT_GT(j4_max - j4_min, 120 * kDeg) << "J4 did not swing: not near the singularity";
  EXPECT_LT(slowest, 0.5 * o.feed_mm_s);
}

// The paper's open pocket on the RX170B (the sample job): verified on the joint positions, at rest
// at both ends, J6 never moving and the configuration the same at every setpoint.
TEST(SerialArm, OpenPocketOnTheRx170b) {
  const io::Job job = io::LoadJob(test::Source("samples/jobs/open_pocket_rx170b.toml"));
  const io::RunResult r = io::RunJob(job);
  EXPECT_TRUE(r.verify.Passed()) << r.verify.worst;
  EXPECT_TRUE(r.verify.starts_at_rest);
  EXPECT_TRUE(r.verify.ends_at_rest);
  const auto& arm = dynamic_cast<const SerialArmMachine&>(*r.machine);
  const io::FileUnits units(arm);
  Eigen::Vector3d first;
  for (std::size_t k = 0; k < r.table.Rows(); ++k) {
    std::vector<double> row;
    for (const auto& column : r.table.columns) row.push_back(column[k]);
    const AxisVector q = units.ToPlanner(row);
    ASSERT_EQ(q[5], 0.0) << "J6 moved at row " << k;
    const Eigen::Vector3d c = arm.Configuration(q);
    if (k == 0) first = c;
    ASSERT_GT(c.cwiseProduct(first).minCoeff(), 0.0) << "configuration flipped at row " << k;
    ASSERT_GT(c.cwiseAbs().minCoeff(), 0.05) << "near a singularity at row " << k;
  }
}

TEST(SerialArm, MachineFileWrittenBackReadsToTheSameArm) {
  for (const MachineDescription& d : {Rx170b(), Puma560()}) {
    const std::string text = kinematics::FormatMachineFile(d);
    const MachineDescription back = kinematics::ParseMachineDescription(text, "written.toml");
    const SerialArmMachine a(d), b(back);
    AxisVector q(6);
    q << 0.1, 0.5, -1.2, 0.3, 0.8, 0.0;
    EXPECT_LE((a.Flange(q).matrix() - b.Flange(q).matrix()).cwiseAbs().maxCoeff(), 1e-9) << text;
    EXPECT_LE((a.Forward(q).tip - b.Forward(q).tip).norm(), 1e-9) << text;
    EXPECT_EQ(back.arm.locked_joint, d.arm.locked_joint);
    for (std::size_t i = 0; i < 6; ++i) {
      EXPECT_NEAR(back.axes[i].vmax, d.axes[i].vmax, 1e-12);
      EXPECT_NEAR(back.arm.home[i], d.arm.home[i], 1e-12);
    }
  }
}

TEST(SerialArm, BadArmFilesNameTheKey) {
  const std::string text = *ReadFileText(test::Source(kRx170b));
  const auto fails = [&](const std::string& from, const std::string& to, const std::string& key) {
    std::string t = text;
    const auto at = t.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    t.replace(at, from.size(), to);
    try {
      kinematics::ParseMachine(t, "arm.toml");
      ADD_FAILURE() << "accepted " << to;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  };
  fails("locked_joint = \"J6\"", "locked_joint = \"J7\"", "arm.locked_joint");
  fails("[0, 0, 1], [0, 1, 0], [0, -1, 0]", "[0, 0, 1], [0, 1, 0]", "frames.axis");
  fails("[frames]", "[dh]\nconvention = \"modified\"\n[frames]", "dh");
  fails("[axes.J6]", "[axes.J7]", "J6");
  fails("home = [0, 45, -75, 0, 60, 0]", "home = [0, 45, -75, 0, 60]", "arm.home");
  fails("axis = [0, 0, -1]", "axis = [0, 0, 0]", "tool.axis");
  fails("home = [0, 45, -75, 0, 60, 0]", "home = [0, 45, -175, 0, 60, 0]", "arm.home");
  fails("locked_joint = \"J6\"", "locked_joint = \"J4\"", "arm.locked_joint");
  {
    std::string t = text;
    const std::string continuous = "travel = \"continuous\"", locked = "locked_at = 0";
    t.replace(t.find(continuous), continuous.size(), "travel = [-90, 90]");
    t.replace(t.find(locked), locked.size(), "locked_at = 100");
    try {
      kinematics::ParseMachine(t, "arm.toml");
      ADD_FAILURE() << "accepted J6 locked outside its travel";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("arm.locked_at"), std::string::npos) << e.what();
    }
  }
}

const std::string kPuma = "/usr/share/doc/linuxcnc/examples/sample-configs/sim/axis/vismach/puma/";

// LinuxCNC's PUMA simulations as they ship: puma560.ini (genserkins, inch) and puma.ini
// (pumakins, mm) with the joint limits of their INI, and the arm's pose at random joints where
// pumakins' own closed forms (pumakins.c, pumaKinematicsForward) put it.
TEST(SerialArm, LinuxcncArmsImportAsTheyStand) {
  if (!std::filesystem::exists(kPuma + "puma560.ini")) {
    GTEST_SKIP() << "LinuxCNC's sample configurations are not installed";
  }
  kinematics::MachineLoadOptions o;
  o.jerk_time_s = 0.05;
  const MachineDescription g = kinematics::ReadMachineDescription(kPuma + "puma560.ini", o);
  EXPECT_EQ(g.kinematics, kinematics::Kinematics::kSerialArm);
  ASSERT_EQ(g.axes.size(), 6u);
  EXPECT_NEAR(g.axes[2].travel_min, -215 * kDeg, 1e-12);  // [JOINT_2] MIN_LIMIT
  EXPECT_NEAR(g.axes[2].travel_max, 35 * kDeg, 1e-12);
  EXPECT_NEAR(g.axes[0].vmax, 30 * kDeg, 1e-12);
  EXPECT_NEAR(g.axes[0].jmax, 200 * kDeg / 0.05, 1e-9);
  EXPECT_NEAR(g.arm.a[2], 17 * 25.4, 1e-9);  // genserkins.A-2 17 (inch)
  EXPECT_NEAR(g.arm.d[3], 17.05 * 25.4, 1e-9);
  EXPECT_NEAR(g.arm.home[4], 0.1 * kDeg, 1e-12);  // [JOINT_4] HOME

  const MachineDescription p = kinematics::ReadMachineDescription(kPuma + "puma.ini", o);
  const SerialArmMachine arm(p);
  const double a2 = 400, a3 = 50, d3 = 100, d4 = 400, d6 = 95;  // puma_dh.hal
  std::mt19937_64 rng(test::g_seed + 107);
  std::uniform_real_distribution<double> angle(-3.0, 3.0);
  for (long c = 0; c < test::g_count; ++c) {
    AxisVector q(6);
    for (int i = 0; i < 6; ++i) q[i] = angle(rng);
    const double c1 = std::cos(q[0]), s1 = std::sin(q[0]), c2 = std::cos(q[1]), s2 = std::sin(q[1]),
                 c4 = std::cos(q[3]), s4 = std::sin(q[3]), c5 = std::cos(q[4]), s5 = std::sin(q[4]);
    const double s23 = std::sin(q[1] + q[2]), c23 = std::cos(q[1] + q[2]);
    const double t1 = a2 * c2 + a3 * c23 - d4 * s23;
    const Eigen::Vector3d wrist(c1 * t1 - d3 * s1, s1 * t1 + d3 * c1,
                                -a3 * s23 - a2 * s2 - d4 * c23);
    const double u = c23 * c4 * s5 + s23 * c5;
    const Eigen::Vector3d z(-c1 * u - s1 * s4 * s5, -s1 * u + c1 * s4 * s5,
                            s23 * c4 * s5 - c23 * c5);
    const Pose pose = arm.Forward(q);
    ASSERT_LE((pose.tip - (wrist + d6 * z)).norm(), 1e-9) << "case " << c;
    ASSERT_LE((pose.axis + z).norm(), 1e-12) << "case " << c;
  }
}

// LinuxCNC's genserkins, run headless on its PUMA 560 pins by bench/linuxcnc/arm_kins.py: at each
// recorded posture dtis' arm, imported from puma560.ini, holds the pose LinuxCNC reported, and
// solving that pose (J6 locked where LinuxCNC had it) gives LinuxCNC's joints back.
TEST(SerialArm, AgreesWithLinuxcncGenserkins) {
  if (!std::filesystem::exists(kPuma + "puma560.ini")) {
    GTEST_SKIP() << "LinuxCNC's sample configurations are not installed";
  }
  kinematics::MachineLoadOptions o;
  o.jerk_time_s = 0.05;
  MachineDescription d = kinematics::ReadMachineDescription(kPuma + "puma560.ini", o);
  const auto text = ReadFileText(test::Source("tests/data/linuxcnc_arm/puma560_genserkins.txt"));
  ASSERT_TRUE(text);
  std::istringstream lines(*text);
  int postures = 0;
  for (std::string line; std::getline(lines, line);) {
    if (line.empty() || line[0] == '#') continue;
    std::istringstream in(line);
    double v[12];
    for (double& x : v) ASSERT_TRUE(in >> x) << line;
    AxisVector q(6);
    for (int i = 0; i < 6; ++i) q[i] = v[i] * kDeg;
    d.arm.locked_at = q[5];
    const SerialArmMachine arm(d);
    const Eigen::Vector3d tip = Eigen::Vector3d(v[6], v[7], v[8]) * 25.4;
    const Eigen::Matrix3d r = (Eigen::AngleAxisd(v[11] * kDeg, Eigen::Vector3d::UnitZ()) *
                               Eigen::AngleAxisd(v[10] * kDeg, Eigen::Vector3d::UnitY()) *
                               Eigen::AngleAxisd(v[9] * kDeg, Eigen::Vector3d::UnitX()))
                                  .toRotationMatrix();
    EXPECT_LE((arm.Flange(q).translation() - tip).norm(), 1e-9) << line;
    EXPECT_LE((arm.Flange(q).linear() - r).cwiseAbs().maxCoeff(), 1e-9) << line;
    AxisVector near = q, back;
    for (int i = 0; i < 5; ++i) near[i] += 0.01;
    const Pose pose{tip, -r.col(2)};
    const InverseResult result = arm.Inverse(pose, &near, &back);
    ASSERT_EQ(result.status, InverseStatus::kOk) << DescribeInverseFailure(arm, result);
    EXPECT_LE((back - q).cwiseAbs().maxCoeff(), 1e-9) << line;
    ++postures;
  }
  EXPECT_EQ(postures, 4);
}

}  // namespace
}  // namespace dtis
