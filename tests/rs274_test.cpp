// G-code through LinuxCNC's own interpreter (dtis-rs274): the programs post-processors write in
// tests/data/gcode read, their arcs in every plane followed exactly, G64 P as the contour
// tolerance, inverse-time feeds, and LinuxCNC's own messages for bad programs.
#include <fmt/format.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "dtis/core/error.hpp"
#include "dtis/geometry/g1_path.hpp"
#include "dtis/io/gcode.hpp"
#include "dtis/io/gcode_program.hpp"
#include "dtis/io/tool_table.hpp"
#include "dtis/kinematics/machines.hpp"
#include "test_support.hpp"

namespace dtis::io {
namespace {

using Eigen::Vector3d;

std::string Corpus(const std::string& name) { return test::Source("tests/data/gcode/" + name); }

class Rs274 : public ::testing::Test {
 protected:
  void SetUp() override {
    if (DefaultGcodeInterpreter() != GcodeInterpreter::kRs274ngc) {
      GTEST_SKIP() << "dtis was built without LinuxCNC's interpreter";
    }
  }
};

// Both readers turn the lock program into the same moves.
TEST_F(Rs274, ReadsWhatTheBuiltInReaderReads) {
  const std::string file = test::Source("samples/gcode/lock.ngc");
  const GcodeProgram ours = ReadGcode(file, GcodeInterpreter::kDtis);
  const GcodeProgram linuxcnc = ReadGcode(file, GcodeInterpreter::kRs274ngc);
  ASSERT_EQ(ours.moves.size(), linuxcnc.moves.size());
  for (std::size_t k = 0; k < ours.moves.size(); ++k) {
    const GcodeMove& a = ours.moves[k];
    const GcodeMove& b = linuxcnc.moves[k];
    EXPECT_EQ(a.kind, b.kind) << k;
    EXPECT_LT((a.to - b.to).norm(), 1e-12) << k;
    EXPECT_EQ(a.feed_mm_min, b.feed_mm_min) << k;
    EXPECT_EQ(a.line, b.line) << k;
  }
}

// Every arc of a program with arcs in XY, XZ (G18), YZ (G19) and a two-turn helix: the smoothed
// path follows the exact circle or helix within 1e-6 mm and ends where the program ends it.
TEST_F(Rs274, ArcsInEveryPlaneAndHelicesAreExact) {
  const GcodeProgram p = ReadGcode(Corpus("mastercam_arcs.ngc"), GcodeInterpreter::kRs274ngc);
  const auto machine =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  int arcs = 0;
  std::array<int, 3> planes{};
  for (std::size_t k = 1; k < p.moves.size(); ++k) {
    const GcodeMove& m = p.moves[k];
    if (m.kind != GcodeMove::Kind::kArcCw && m.kind != GcodeMove::Kind::kArcCcw) continue;
    ++arcs;
    for (int i = 0; i < 3; ++i) planes[static_cast<std::size_t>(i)] += m.normal[i] != 0.0;
    const Vector3d from = p.moves[k - 1].to;
    geometry::ChainMove c;
    c.kind = geometry::ChainMove::Kind::kArc;
    c.tip = m.to;
    c.center = m.center;
    c.normal = m.normal;
    c.clockwise = m.kind == GcodeMove::Kind::kArcCw;
    c.turns = m.turns;
    c.line = m.line;
    const geometry::G1Path path(from, Vector3d::UnitZ(), {c}, *machine);
    const double length = *path.Length();
    const Vector3d r0 = (from - m.center) - (from - m.center).dot(m.normal) * m.normal;
    const double radius = r0.norm();
    const double rise = m.normal.dot(m.to - from);
    // The exact helix: the angle swept grows linearly with arc length, the rise too.
    const double sweep_abs = std::sqrt(length * length - rise * rise) / radius;
    const double sign = c.clockwise ? -1.0 : 1.0;
    PathState st = path.Start();
    double worst = 0.0;
    for (int i = 0; i <= 400; ++i) {
      const double s = length * i / 400.0;
      const PathSample at = path.At(st, s);
      st = at.state;
      const double angle = sign * sweep_abs * s / length;
      const Vector3d exact = m.center + (from - m.center).dot(m.normal) * m.normal +
                             std::cos(angle) * r0 + std::sin(angle) * m.normal.cross(r0) +
                             (rise * s / length) * m.normal;
      worst = std::max(worst, (at.pose.tip - exact).norm());
    }
    EXPECT_LT(worst, 1e-6) << "line " << m.line;
    EXPECT_LT((path.At(st, length).pose.tip - m.to).norm(), 1e-9) << "line " << m.line;
    if (m.turns == 2) {
      EXPECT_NEAR(sweep_abs, 4.0 * std::numbers::pi, 1e-9);  // two whole turns, P2
      EXPECT_NEAR(rise, -4.0, 1e-12);
    }
  }
  EXPECT_EQ(arcs, 4);
  EXPECT_EQ(planes[0], 1);  // G19
  EXPECT_EQ(planes[1], 1);  // G18
  EXPECT_EQ(planes[2], 2);  // G17, the quarter and the helix
}

// G5.2: the exact NURBS with LinuxCNC's knots, each curve its own contour. The rational quadratic
// of the program is a quarter circle of radius 20: every point of the planned path lies on it.
TEST_F(Rs274, NurbsAreExact) {
  const GcodeProgram p = ReadGcode(Corpus("nurbs.ngc"), GcodeInterpreter::kRs274ngc);
  const auto machine =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  const GcodePlan plan = BuildGcodePlan(p, *machine, interp::VpopOptions{}, GcodeOptions{});
  int curves = 0;
  for (std::size_t k = 0; k < plan.paths.size(); ++k) {
    if (plan.segments[k].name.find("NURBS") == std::string::npos) continue;
    ++curves;
    const PathSource& path = *plan.paths[k];
    const double length = *path.Length();
    PathState st = path.Start();
    if (curves == 1) {
      EXPECT_NEAR(length, 10.0 * std::numbers::pi, 1e-6);
      double worst = 0.0;
      for (int i = 0; i <= 200; ++i) {
        const PathSample at = path.At(st, length * i / 200.0);
        st = at.state;
        worst = std::max(worst, std::abs(at.pose.tip.head<2>().norm() - 20.0));
        EXPECT_NEAR(at.pose.tip.z(), 0.0, 1e-12);
      }
      EXPECT_LT(worst, 1e-9);
      EXPECT_LT((path.At(st, length).pose.tip - Vector3d(0, 20, 0)).norm(), 1e-9);
    } else {
      // The cubic starts where the circle ended and ends at its last control point.
      EXPECT_LT((path.At(st, 0.0).pose.tip - Vector3d(0, 20, 0)).norm(), 1e-9);
      EXPECT_LT((path.At(st, length).pose.tip - Vector3d(-40, 20, 0)).norm(), 1e-9);
    }
  }
  EXPECT_EQ(curves, 2);
}

// G64 P0.01 in the program: its contours' corners stay within 0.01 mm of the programmed polyline
// (measured on the smoothed path), where the job's own tolerance (0.05 mm here) would allow more.
TEST_F(Rs274, G64PIsTheContourTolerance) {
  const GcodeProgram p = ReadGcode(Corpus("fusion_post.ngc"), GcodeInterpreter::kRs274ngc);
  const auto machine =
      kinematics::LoadMachineFile(test::Source("samples/machines/mikron_ucp710_xyz.toml"));
  interp::VpopOptions base;
  GcodeOptions options;
  options.corners.contour_tol_mm = 0.05;
  const GcodePlan plan = BuildGcodePlan(p, *machine, base, options);
  // The distance from a point to the programmed polyline of the feed moves.
  std::vector<Vector3d> polyline;
  for (const GcodeMove& m : p.moves) polyline.push_back(m.to);
  const auto to_polyline = [&](const Vector3d& x) {
    double best = INFINITY;
    for (std::size_t k = 0; k + 1 < polyline.size(); ++k) {
      const Vector3d a = polyline[k], d = polyline[k + 1] - a;
      const double t =
          d.squaredNorm() > 0 ? std::clamp((x - a).dot(d) / d.squaredNorm(), 0.0, 1.0) : 0.0;
      best = std::min(best, (a + t * d - x).norm());
    }
    return best;
  };
  double worst = 0.0;
  int corners = 0;
  for (std::size_t k = 0; k < plan.paths.size(); ++k) {
    if (plan.rapid[k]) continue;
    const auto& path = static_cast<const geometry::G1Path&>(*plan.paths[k]);
    for (const auto& c : path.Corners()) {
      ++corners;
      PathState st = path.Start();
      for (int i = 0; i <= 50; ++i) {
        const PathSample at = path.At(st, c.s0 + (c.s1 - c.s0) * i / 50.0);
        st = at.state;
        worst = std::max(worst, to_polyline(at.pose.tip));
        // The corner's middle lies exactly the tolerance away from the programmed corner (Eq. 3).
        if (i == 25) {
          double to_vertex = INFINITY;
          for (const Vector3d& v : polyline)
            to_vertex = std::min(to_vertex, (v - at.pose.tip).norm());
          EXPECT_NEAR(to_vertex, 0.01, 1e-6) << "corner at line " << c.line;
        }
      }
    }
  }
  EXPECT_GT(corners, 8);
  EXPECT_LE(worst, 0.01 + 1e-9);
}

// G93: each F is the inverse of the move's time in minutes; the interpreter's feed per move is the
// move's length times F.
TEST_F(Rs274, InverseTimeFeedsArePerMove) {
  const GcodeProgram p = ReadGcode(Corpus("inverse_time.ngc"), GcodeInterpreter::kRs274ngc);
  ASSERT_EQ(p.moves.size(), 6u);
  EXPECT_DOUBLE_EQ(p.moves[2].feed_mm_min, 20.0 * 60.0);                      // X20 in 1/60 min
  EXPECT_DOUBLE_EQ(p.moves[3].feed_mm_min, 10.0 * 120.0);                     // Y10 in 1/120 min
  EXPECT_NEAR(p.moves[4].feed_mm_min, std::numbers::pi * 10.0 * 30.0, 1e-9);  // a half circle
  EXPECT_DOUBLE_EQ(p.moves[5].feed_mm_min, 1200.0);                           // back in G94
}

// G20: lengths and feeds in inches become mm.
TEST_F(Rs274, InchProgramsAreInMm) {
  const GcodeProgram p = ReadGcode(Corpus("inch.ngc"), GcodeInterpreter::kRs274ngc);
  ASSERT_GE(p.moves.size(), 4u);
  EXPECT_NEAR(p.moves[2].to.x(), 25.4, 1e-12);
  EXPECT_NEAR(p.moves[2].feed_mm_min, 40.0 * 25.4, 1e-9);
  EXPECT_NEAR(p.moves[1].to.z(), -0.05 * 25.4, 1e-12);
}

// What moves nothing is listed, not refused.
TEST_F(Rs274, ListsWhatMovesNothing) {
  const GcodeProgram p = ReadGcode(Corpus("fusion_post.ngc"), GcodeInterpreter::kRs274ngc);
  std::string notes;
  for (const auto& [what, count] : p.notes) notes += what + "\n";
  EXPECT_NE(notes.find("tool change (M6)"), std::string::npos) << notes;
  EXPECT_NE(notes.find("spindle on (M3)"), std::string::npos) << notes;
  EXPECT_NE(notes.find("coolant (M8)"), std::string::npos) << notes;
}

// With a tool table, G43 H, G43 after M6, G43.2 and G49 move the controlled point as LinuxCNC's
// canon layer does (program point + work offset + tool offset), in mm whatever G20/G21 says, and
// an axis the block does not name stays where the machine is when the offset changes.
TEST_F(Rs274, ToolTableOffsetsAreAppliedAsLinuxCncAppliesThem) {
  const auto tools = std::make_shared<const ToolTable>(LoadToolTable(Corpus("tool_offsets.tbl")));
  const GcodeProgram p = ReadGcode(Corpus("tool_offsets.ngc"), GcodeInterpreter::kRs274ngc, tools);
  ASSERT_EQ(p.moves.size(), 6u);
  const Vector3d expected[] = {{0, 0, 20},            // before G43
                               {10, 0, 55},           // Z5 + tool 1's 50
                               {25.4, 0, 12.7 + 50},  // G20: X1 Z0.5 in
                               {30.5, 0, 62.7},       // G43.2 H2 adds X0.5 Z2; Z stays
                               {40, 0, 62.7},         // G49
                               {50.5, 0, 62.7}};      // T2 M6 G43: tool 2's X0.5
  for (std::size_t k = 0; k < 6; ++k) {
    EXPECT_LT((p.moves[k].to - expected[k]).norm(), 1e-12)
        << "move " << k << " at line " << p.moves[k].line;
  }
  // Without a table the programmed tip is planned, and G43 is noted.
  const GcodeProgram tip = ReadGcode(Corpus("tool_offsets.ngc"), GcodeInterpreter::kRs274ngc);
  EXPECT_LT((tip.moves[1].to - Vector3d(10, 0, 5)).norm(), 1e-12);
  EXPECT_LT((tip.moves[5].to - Vector3d(50, 0, 12.7)).norm(), 1e-12);
}

// M6 makes the interpreter ask where the machine is: after G55 moved the program frame, the
// answer is the machine's position in the new frame, so the next block moves X only (dtis-rs274
// once answered in the old frame, and Y jumped by G55's 50 mm).
TEST_F(Rs274, AnOffsetChangeBeforeAToolChangeMovesNoOtherAxis) {
  const GcodeProgram p = ReadGcode(Corpus("offset_then_m6.ngc"), GcodeInterpreter::kRs274ngc);
  ASSERT_EQ(p.moves.size(), 2u);
  EXPECT_LT((p.moves[1].to - Vector3d(105, 0, 10)).norm(), 1e-12);
}

// A post-processor's program with its tool table: every point from the G43 block on is the
// program's without the table, raised by the tool length, except G28's return to the machine's
// home, which is a machine position.
TEST_F(Rs274, ToolTableRaisesAPostProcessorsProgramByTheToolLength) {
  const auto tools = std::make_shared<const ToolTable>(LoadToolTable(Corpus("fusion_post.tbl")));
  const GcodeProgram with =
      ReadGcode(Corpus("fusion_post.ngc"), GcodeInterpreter::kRs274ngc, tools);
  const GcodeProgram without = ReadGcode(Corpus("fusion_post.ngc"), GcodeInterpreter::kRs274ngc);
  ASSERT_EQ(with.moves.size(), without.moves.size());
  int raised = 0;
  for (std::size_t k = 0; k < with.moves.size(); ++k) {
    const Vector3d d = with.moves[k].to - without.moves[k].to;
    const int line = with.moves[k].line;
    const bool home = line == 29 && k + 1 == with.moves.size();  // G28 G91 Z0
    const double rise = line >= 13 && !home ? 42.5 : 0.0;
    EXPECT_LT((d - Vector3d(0, 0, rise)).norm(), 1e-12) << "line " << line;
    raised += rise > 0;
  }
  EXPECT_GT(raised, 20);
}

// A tool the table does not have: LinuxCNC's message. dtis' own reader does not apply offsets.
TEST_F(Rs274, AToolMissingFromTheTableIsLinuxCncsError) {
  const auto tools = std::make_shared<const ToolTable>(ParseToolTable("T1 Z5\n", "t.tbl"));
  test::ExpectError(
      [&] {
        ReadGcode(Corpus("fusion_post.ngc"), GcodeInterpreter::kRs274ngc,
                  std::make_shared<const ToolTable>(ParseToolTable("T2 Z5\n", "t.tbl")));
      },
      "fusion_post.ngc:8: Requested tool 1 not found in the tool table");
  test::ExpectError([&] { ReadGcode(Corpus("fusion_post.ngc"), GcodeInterpreter::kDtis, tools); },
                    "are applied by LinuxCNC's interpreter");
}

// A bad program: LinuxCNC's own message, with the file and the line.
TEST_F(Rs274, BadProgramsGiveLinuxCncsMessageWithFileAndLine) {
  test::ExpectError([] { ReadGcode(Corpus("bad_word.ngc"), GcodeInterpreter::kRs274ngc); },
                    "bad_word.ngc:4: E word with no G70, G76, M66, M67 or M68 to use it");
  test::ExpectError([] { ReadGcode(Corpus("bad_arc.ngc"), GcodeInterpreter::kRs274ngc); },
                    "bad_arc.ngc:4: Arc radius too small to reach end point");
  test::ExpectError(
      [] { ReadGcode(test::Source("tests/data/gcode/missing.ngc"), GcodeInterpreter::kRs274ngc); },
      "missing.ngc");
}

// G5.2 in inverse time: LinuxCNC's interpreter gives the curve no feed (it converts F for lines
// and arcs only), so it is an error that says so, at the G5.3 that ends the curve (the line
// LinuxCNC gives the curve).
TEST_F(Rs274, NurbsInInverseTimeIsAClearError) {
  const std::string program = test::Scratch("nurbs_g93.ngc");
  std::ofstream(program) << "G21 G90 G17\nG0 X0 Y0 Z0\nG93\nG5.2 X0 Y0 P1 L3 F30\n"
                            "X10 Y0 P1\nX10 Y10 P1\nX20 Y10 P1\nG5.3\nG94\nM2\n";
  test::ExpectError([&] { ReadGcode(program, GcodeInterpreter::kRs274ngc); },
                    "nurbs_g93.ngc:8: a NURBS (G5.2) with no feed rate: LinuxCNC gives none in "
                    "inverse time (G93)");
}

// Run from a terminal of a LinuxCNC session, the interpreter would read the session's INI
// (INI_FILE_NAME): its log file, subroutine path, remaps and Python plugins. It must not: a
// program reads the same wherever dtis runs.
TEST_F(Rs274, IgnoresTheSessionsIni) {
  const std::string ini = test::Scratch("session.ini"), log = test::Scratch("interp.log");
  std::ofstream(ini) << "[RS274NGC]\nLOG_LEVEL = 1\nLOG_FILE = " << log << "\n";
  ::setenv("INI_FILE_NAME", ini.c_str(), 1);
  const GcodeProgram p = ReadGcode(Corpus("inch.ngc"), GcodeInterpreter::kRs274ngc);
  ::unsetenv("INI_FILE_NAME");
  EXPECT_GE(p.moves.size(), 4u);
  EXPECT_FALSE(std::filesystem::exists(log)) << "the interpreter opened the session's log file";
}

// A subroutine in a file of its own (o<name> call), next to the program: found wherever dtis was
// started (the interpreter looks in its working folder, which is the program's).
TEST_F(Rs274, FindsSubroutineFilesNextToTheProgram) {
  const std::filesystem::path folder = test::Scratch("subroutines");
  std::filesystem::create_directories(folder);
  std::ofstream(folder / "square.ngc") << "o<square> sub\nG1 X10 F600\nG1 Y10\n"
                                          "o<square> endsub\nM2\n";
  std::ofstream(folder / "main.ngc") << "G21 G90\nG0 X0 Y0 Z0\no<square> call\nM2\n";
  ASSERT_NE(std::filesystem::current_path(), folder);
  const GcodeProgram p = ReadGcode((folder / "main.ngc").string(), GcodeInterpreter::kRs274ngc);
  ASSERT_EQ(p.moves.size(), 3u);
  EXPECT_EQ(p.moves[2].to, Eigen::Vector3d(10, 10, 0));
}

// A reader dropped before the program's end stops the interpreter (no process is left behind,
// and the next reader works).
TEST_F(Rs274, ADroppedReaderStopsTheInterpreter) {
  for (int k = 0; k < 3; ++k) {
    GcodeReader reader(test::Source("samples/gcode/fine_wave.ngc"), GcodeInterpreter::kRs274ngc);
    ASSERT_TRUE(reader.Next().has_value());
  }
  const GcodeProgram p = ReadGcode(Corpus("freecad_post.ngc"), GcodeInterpreter::kRs274ngc);
  EXPECT_GT(p.moves.size(), 5u);
}

// The records dtis-rs274 writes, read without it: what each becomes, and a clear error (never a
// crash) for a record that is not one; the fuzz target fuzz_rs274 reads the same way.
TEST(Rs274Records, ReadIntoMovesOrAClearError) {
  const GcodeProgram p = ParseRs274Records(
      "T 1 0 0 5 0 0 0\nF 2 600\nL 2 10 0 5 0 0 0\nP 3 3 0.01\n"
      "A 4 10 10 5 10 5 5 0 0 1 -2 0 0 0\nD 5 0.5\nI 6 spindle on (M3)\n"
      "N 7 3 5 0 0 0 3 10 10 1 20 10 0.5 20 20 1\nX\n",
      "p.ngc");
  ASSERT_EQ(p.moves.size(), 4u);
  EXPECT_EQ(p.moves[0].kind, GcodeMove::Kind::kRapid);
  EXPECT_EQ(p.moves[1].feed_mm_min, 600.0);
  EXPECT_EQ(p.moves[2].kind, GcodeMove::Kind::kArcCw);
  EXPECT_EQ(p.moves[2].turns, 2);
  EXPECT_EQ(p.moves[2].tolerance_mm, 0.01);
  EXPECT_EQ(p.moves[3].kind, GcodeMove::Kind::kNurbs);
  EXPECT_TRUE(p.moves[3].rest_before);
  EXPECT_EQ(p.moves[3].dwell_s, 0.5);
  EXPECT_EQ(p.moves[3].nurbs->poles.size(), 3u);
  ASSERT_EQ(p.notes.size(), 2u);
  for (const auto& [record, message] : std::vector<std::pair<std::string, std::string>>{
           {"L 3 1 2\nX\n", "expected 6 numbers"},
           {"Z 1\nX\n", "unknown record"},
           {"F 1 100\nL 2 1 2 3 0 0 0\n", "ended before the program's end"},
           {"F 1 100\nA 2 1 0 0 0 0 0 0 0 2 1 0 0 0\nX\n", "not a unit"},
           {"F 1 100\nN 2 4 0 0 0 0 2 0 0 1 1 1 1\nX\n", "at least as many control points"},
           {"L 2 1 0 0 0 0 0\nX\n", "p.ngc:2: a feed move with no feed rate"},
           {"E 9 Arc radius too small\n", "p.ngc:9: Arc radius too small"},
           {"L x\n", "no line number"},
           {"D 3 -1\nX\n", "p.ngc:3: a dwell (G4) of -1 s: expected 0 to 1e6 s"}}) {
    test::ExpectError([&] { ParseRs274Records(record, "p.ngc"); }, message);
  }
}

// LinuxCNC's interpreter starts where the machine is, with the parameters it is given (its
// parameter file's work offsets): the moves dtis' own reader finds for the same program.
TEST_F(Rs274, WorkOffsetsAndTheStartAreWhatTheBuiltInReaderFinds) {
  GcodeStart start;
  start.tip = {1, 2, 30};
  start.parameters = {{5220, 2},  {5221, 100}, {5223, -10}, {5241, 50},
                      {5242, 25}, {5243, -20}, {5381, 7}};
  const std::string file = test::Scratch("offsets.ngc");
  std::ofstream(file) << "G0 Z5\nG0 X10 Y0\nG54 G0 X10\nG59.3 G1 Y1 F100\nG91 G1 X1\nM2\n";
  const GcodeProgram linuxcnc = ReadGcode(file, GcodeInterpreter::kRs274ngc, nullptr, start);
  const GcodeProgram ours = ReadGcode(file, GcodeInterpreter::kDtis, nullptr, start);
  ASSERT_EQ(linuxcnc.moves.size(), 5u);
  ASSERT_EQ(ours.moves.size(), 5u);
  for (std::size_t k = 0; k < 5; ++k) {
    EXPECT_LT((linuxcnc.moves[k].to - ours.moves[k].to).norm(), 1e-9) << k;
  }
  EXPECT_LT((linuxcnc.moves[0].to - Vector3d(1, 2, -15)).norm(), 1e-9);
  EXPECT_LT((linuxcnc.moves[4].to - Vector3d(111, 1, -15)).norm(), 1e-9);
  // G10 L2, which only LinuxCNC's interpreter reads, sets the same offsets.
  std::ofstream(file) << "G10 L2 P2 X50 Y25 Z-20\nG55 G0 X10 Y0 Z5\nM2\n";
  const GcodeProgram g10 = ReadGcode(file, GcodeInterpreter::kRs274ngc);
  ASSERT_EQ(g10.moves.size(), 1u);
  EXPECT_LT((g10.moves[0].to - Vector3d(60, 25, -15)).norm(), 1e-9);
}

// The notes list what the program asks that the machine would do: not M30's pallet shuttle (the
// interpreter's way of ending a program), nor a G49 with no offset in force.
TEST_F(Rs274, NotesNeitherM30NorALoneG49) {
  const std::string file = test::Scratch("notes.ngc");
  std::ofstream(file) << "G49\nG0 X10\nG43 H1\nG1 X20 F600\nG49\nM30\n";
  const GcodeProgram p = ReadGcode(file, GcodeInterpreter::kRs274ngc);
  std::string notes;
  for (const auto& [what, count] : p.notes) notes += fmt::format("{} x {}\n", count, what);
  EXPECT_EQ(notes,
            "1 x tool length offset (G43): the machine applies it, dtis plans the tip\n"
            "1 x tool length offset cancelled (G49)\n")
      << notes;
}

// A loop that never ends, with or without moves, ends at max_blocks blocks executed (each
// repetition counted), naming the first block past them.
TEST_F(Rs274, LoopsEndAtTheBlockBudget) {
  const std::string moving = test::Scratch("loop_moving.ngc");
  std::ofstream(moving) << "G21 G90\nG0 X0 Y0\no100 while [1]\nG1 X10 F600\nG1 X0\n"
                           "o100 endwhile\nM2\n";
  const std::string still = test::Scratch("loop_still.ngc");
  std::ofstream(still) << "G21 G90\nG0 X0 Y0\nG1 X10 F600\no100 while [1]\no100 endwhile\nM2\n";
  GcodeReadOptions o;
  o.max_blocks = 1000;
  o.remedy = "the remedy";
  for (const std::string& file : {moving, still}) {
    test::ExpectError([&] { ReadGcode(file, GcodeInterpreter::kRs274ngc, nullptr, {}, o); },
                      {"the program runs more than 1000 blocks (each repetition of a loop "
                       "counted), the most it may run here; the remedy"});
  }
  test::ExpectError([&] { ReadGcode(still, GcodeInterpreter::kRs274ngc, nullptr, {}, o); },
                    "loop_still.ngc:5: the program runs more than 1000 blocks");
  // A program within the budget reads whole.
  EXPECT_EQ(ReadGcode(Corpus("inch.ngc"), GcodeInterpreter::kRs274ngc, nullptr, {}, o).moves.size(),
            ReadGcode(Corpus("inch.ngc"), GcodeInterpreter::kRs274ngc).moves.size());
}

}  // namespace
}  // namespace dtis::io
