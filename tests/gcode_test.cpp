// The G-code reader: modal state, units, incremental moves, arcs by I/J and R, and one clear error
// with line and column for each kind of bad block.
#include "dtis/io/gcode.hpp"

#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numbers>
#include <string>

#include "dtis/core/error.hpp"
#include "dtis/io/tool_table.hpp"
#include "test_support.hpp"

namespace dtis::io {
namespace {

std::string ErrorOf(const std::string& text, const GcodeReadOptions& options = {}) {
  try {
    ParseGcode(text, "p.ngc", {}, options);
  } catch (const Error& e) {
    return e.what();
  }
  return "no error";
}

TEST(Gcode, ReadsModalMovesUnitsAndComments) {
  const GcodeProgram p = ParseGcode(
      "%\n"
      "(lock contour) G21 G90 G17 G94\n"
      "N10 G0 X0 Y0 Z5 ; rapid above\n"
      "G1 Z0 F600\n"
      "X10 (modal G1, modal F)\n"
      "Y10 F1200\n"
      "G91 X-5 Y-5\n"
      "G90 G20 X1\n"
      "M30\n"
      "G1 X99 (after the end: not read)\n",
      "p.ngc");
  ASSERT_EQ(p.moves.size(), 6u);
  EXPECT_EQ(p.moves[0].kind, GcodeMove::Kind::kRapid);
  EXPECT_EQ(p.moves[0].feed_mm_min, 0.0);
  EXPECT_EQ(p.moves[1].to, Eigen::Vector3d(0, 0, 0));
  EXPECT_EQ(p.moves[1].feed_mm_min, 600.0);
  EXPECT_EQ(p.moves[2].to, Eigen::Vector3d(10, 0, 0));
  EXPECT_EQ(p.moves[2].kind, GcodeMove::Kind::kLinear);
  EXPECT_EQ(p.moves[3].feed_mm_min, 1200.0);
  EXPECT_EQ(p.moves[4].to, Eigen::Vector3d(5, 5, 0));
  EXPECT_EQ(p.moves[5].to, Eigen::Vector3d(25.4, 5, 0));
  EXPECT_EQ(p.moves[5].line, 8);
  EXPECT_FALSE(p.uses_rotary[0]);
}

TEST(Gcode, ArcsByCentreOffsetAndByRadius) {
  // A quarter circle of radius 10 around the origin, counter-clockwise, both ways.
  const GcodeProgram ij = ParseGcode("G0 X10 Y0\nG3 X0 Y10 I-10 J0 F500\n", "p.ngc");
  ASSERT_EQ(ij.moves.size(), 2u);
  EXPECT_EQ(ij.moves[1].kind, GcodeMove::Kind::kArcCcw);
  EXPECT_NEAR(ij.moves[1].center.norm(), 0.0, 1e-12);
  const GcodeProgram r = ParseGcode("G0 X10 Y0\nG3 X0 Y10 R10 F500\n", "p.ngc");
  EXPECT_NEAR(r.moves[1].center.norm(), 0.0, 1e-12);
  // R < 0: the long way round, centre on the other side of the chord.
  const GcodeProgram lr = ParseGcode("G0 X10 Y0\nG3 X0 Y10 R-10 F500\n", "p.ngc");
  EXPECT_NEAR((lr.moves[1].center.head<2>() - Eigen::Vector2d(10, 10)).norm(), 0.0, 1e-12);
  // Clockwise with R > 0 from (10, 0) to (0, 10): the short arc turning right.
  const GcodeProgram cw = ParseGcode("G0 X10 Y0\nG2 X0 Y10 R10 F500\n", "p.ngc");
  EXPECT_NEAR((cw.moves[1].center.head<2>() - Eigen::Vector2d(10, 10)).norm(), 0.0, 1e-12);
}

TEST(Gcode, FiveAxisWordsAreDegreesAndAbsolute) {
  const GcodeProgram p = ParseGcode("G1 X1 A10 C-90 F100\nG91 A5\n", "p.ngc");
  ASSERT_EQ(p.moves.size(), 2u);
  EXPECT_EQ(p.moves[1].rotary[0], 15.0);
  EXPECT_EQ(p.moves[1].rotary[2], -90.0);
  EXPECT_TRUE(p.uses_rotary[0]);
  EXPECT_FALSE(p.uses_rotary[1]);
  EXPECT_TRUE(p.uses_rotary[2]);
}

TEST(Gcode, BadBlocksNameLineAndColumn) {
  EXPECT_EQ(ErrorOf("G1 X1 F100\nG1 X2 Q5\n"), "p.ngc:2:7: word 'Q' is not supported");
  EXPECT_NE(ErrorOf("G18\n").find("p.ngc:1:1: G18 is not supported"), std::string::npos);
  EXPECT_EQ(ErrorOf("G1 X1 F0\n"), "p.ngc:1:7: feed F must be positive, got 0");
  EXPECT_EQ(ErrorOf("G1 X1\n"), "p.ngc:1:1: a feed move before any feed F was given");
  EXPECT_EQ(ErrorOf("G0 X10\nG2 X0 Y10 F100\n"),
            "p.ngc:2:1: an arc (G2/G3) needs I and/or J, or R");
  EXPECT_NE(ErrorOf("G0 X10\nG3 X0 Y12 I-10 F100\n").find("p.ngc:2:1: arc radius mismatch"),
            std::string::npos);
  EXPECT_NE(ErrorOf("G0 X10\nG3 X-20 Y0 R5 F100\n").find("less than half the chord"),
            std::string::npos);
  EXPECT_EQ(ErrorOf("X5\n"), "p.ngc:1:1: an axis word before any motion mode (G0, G1, G2, G3)");
  EXPECT_EQ(ErrorOf("G1 X1 X2 F9\n"), "p.ngc:1:7: X appears twice in the block");
  EXPECT_EQ(ErrorOf("G1 X F9\n"), "p.ngc:1:4: word 'X' needs a number");
  EXPECT_EQ(ErrorOf("G1 (open X1\n"), "p.ngc:1:4: unclosed comment '('");
  EXPECT_EQ(ErrorOf("G1 X1 F9 *\n"),
            "p.ngc:1:10: expected a word (a letter and a number), got '*'");
  EXPECT_NE(ErrorOf("M99\n").find("p.ngc:1:1: M99 is not supported"), std::string::npos);
}

TEST(Gcode, ReaderGivesTheProgramsMovesOneAtATime) {
  const std::string text =
      "G21 G90\nG0 X0 Y0 Z5\nG1 Z0 F600\nX10 (comment)\n\nG2 X20 Y0 R5\nG1 G91 Y2 A3\nM2\nG1 X99\n";
  const GcodeProgram whole = ParseGcode(text, "p.ngc");
  GcodeReader reader(text, "p.ngc");
  std::size_t k = 0;
  while (const std::optional<GcodeMove> m = reader.Next()) {
    ASSERT_LT(k, whole.moves.size());
    const GcodeMove& w = whole.moves[k++];
    EXPECT_EQ(m->kind, w.kind);
    EXPECT_EQ(m->line, w.line);
    EXPECT_EQ(m->to, w.to);
    EXPECT_EQ(m->center, w.center);
    EXPECT_EQ(m->rotary, w.rotary);
    EXPECT_EQ(m->feed_mm_min, w.feed_mm_min);
  }
  EXPECT_EQ(k, whole.moves.size());
  EXPECT_EQ(reader.UsesRotary(), whole.uses_rotary);
  EXPECT_FALSE(reader.Next());  // stays at the end
}

TEST(Gcode, ReaderReportsABadBlockWhenItReachesIt) {
  GcodeReader reader(std::string_view("G0 X0\nG1 X1 F100\nG1 X2 Q7\n"), "p.ngc");
  ASSERT_TRUE(reader.Next());
  ASSERT_TRUE(reader.Next());
  try {
    reader.Next();
    FAIL() << "no error";
  } catch (const Error& e) {
    EXPECT_EQ(std::string(e.what()), "p.ngc:3:7: word 'Q' is not supported");
  }
}

// dtis' reader reads at most max_blocks lines, naming the first one past them.
TEST(Gcode, ReadingIsBounded) {
  const std::string three = "G0 X0\nG1 X1 F100\nG1 X2\n";
  GcodeReadOptions o;
  o.max_blocks = 3;
  o.remedy = "raise it";
  EXPECT_EQ(ParseGcode(three, "p.ngc", {}, o).moves.size(), 3u);
  EXPECT_EQ(ParseGcode(three + "\n\n", "p.ngc", {}, o).moves.size(), 3u);  // empty lines: no blocks
  EXPECT_EQ(ErrorOf(three + "G1 X3\nM2\n", o),
            "p.ngc:4: the program runs more than 3 blocks (each repetition of a loop counted), "
            "the most it may run here; raise it");
}

// LinuxCNC tool tables: every word LinuxCNC writes, either case, '+' signs, comments.
TEST(ToolTable, ReadsLinuxCncsFormat) {
  const ToolTable t = ParseToolTable(
      "; a comment line\n"
      "T1 P1 D0.125000 Z+0.511000 ;1/8 end mill\n"
      "\n"
      "t2 p4 x0.5 y-1 z2 a1 b2 c3 u4 v5 w6 d1.5 i10 j20 q3\r\n"
      "T99999 P123     Z+0.100000 ;big tool number\n"
      "T0 P0 ;no tool\n"
      "T5 Z7\n",
      "sim.tbl");
  ASSERT_EQ(t.tools.size(), 5u);
  EXPECT_EQ(t.tools[0].tool, 1);
  EXPECT_EQ(t.tools[0].line, 2);
  EXPECT_DOUBLE_EQ(t.tools[0].offset[2], 0.511);
  EXPECT_DOUBLE_EQ(t.tools[0].diameter, 0.125);
  EXPECT_EQ(t.tools[1].pocket, 4);
  const std::array<double, 9> two = {0.5, -1, 2, 1, 2, 3, 4, 5, 6};
  EXPECT_EQ(t.tools[1].offset, two);
  EXPECT_EQ(t.tools[2].tool, 99999);
  EXPECT_EQ(t.tools[3].tool, 0);
  EXPECT_EQ(t.tools[4].pocket, 5);  // P left out: the tool's own number
}

TEST(ToolTable, BadLinesNameTheFileLineAndWord) {
  const auto bad = [](const std::string& text, const std::string& fragment) {
    test::ExpectError([&] { ParseToolTable(text, "tool.tbl"); }, fragment);
  };
  bad("T1 P1 Z1\nT2 P2 Z1 K4\n", "tool.tbl:2: 'K4': expected a word T P X Y Z");
  bad("T1 Zfoo\n", "tool.tbl:1: Z: expected a number, got 'foo'");
  bad("T1 Z1 Z2\n", "tool.tbl:1: Z appears twice");
  bad("P1 Z1\n", "tool.tbl:1: expected a tool number (T word)");
  bad("T1.5 Z1\n", "tool.tbl:1: T: expected a whole number");
  bad("T-1 Z1\n", "tool.tbl:1: T: expected a whole number");
  bad("T1 Z1\n\nT1 Z2\n", "tool.tbl:3: tool T1 is already in the table, on line 1");
  bad("T1 Z1e9\n", "tool.tbl:1: Z: expected an offset within ±100000 mm");
  bad("T1 Znan\n", "tool.tbl:1: Z: expected a number");
  bad("T1 D-3\n", "tool.tbl:1: D: expected a diameter");
  bad("T1 Z++1\n", "tool.tbl:1: Z: expected a number");
  bad("TOOLNO POCKET LENGTH DIAMETER COMMENT\n1 1 0.5 0.1\n",
      "tool.tbl:1: this is the tool table format of LinuxCNC before 2.4");
  test::ExpectError([] { LoadToolTable(test::Source("tests/data/gcode/missing.tbl")); },
                    "missing.tbl: cannot open the tool table");
}

// Work offsets: G54 … G59.3 from LinuxCNC's parameters (its parameter file, or the job's
// [path.work_offsets]), the system in force from parameter 5220, G92 while 5210 is 1; axes a
// block does not name stay where the machine is, which is where the program starts.
TEST(Gcode, WorkOffsetsAndTheStartAreLinuxCncs) {
  GcodeStart start;
  start.tip = {1, 2, 30};
  start.parameters = ParseParameters(
      "5220\t2\n5221 100\n5222 0\n5223 -10\n5241 50 extra words are ignored\n5242 25\n"
      "5243 -20\n5244 90\n5381 7\n",
      "sim.var");
  const GcodeProgram p = ParseGcode(
      "G0 Z5\n"             // G55 in force (5220): Z5 - 20
      "G0 X10 Y0 A0\n"      // G55: X60 Y25, A 90
      "G54 G0 X10\n"        // G54: X110; Y stays
      "G59.3 G1 Y1 F100\n"  // G59.3: Y1 (its Y offset 0); X stays
      "G91 G1 X1\n",        // incremental: no offset
      "p.ngc", start);
  ASSERT_EQ(p.moves.size(), 5u);
  const Eigen::Vector3d expected[] = {
      {1, 2, -15}, {60, 25, -15}, {110, 25, -15}, {110, 1, -15}, {111, 1, -15}};
  for (std::size_t k = 0; k < 5; ++k) {
    EXPECT_LT((p.moves[k].to - expected[k]).norm(), 1e-12) << k;
  }
  EXPECT_EQ(p.moves[1].rotary[0], 90.0);
  // G92 from the parameters, added to the work offset.
  start.parameters = {{5210, 1}, {5211, 3}, {5221, 100}};
  EXPECT_LT(
      (ParseGcode("G0 X0 Y0 Z0\n", "p.ngc", start).moves[0].to - Eigen::Vector3d(103, 0, 0)).norm(),
      1e-12);
  // What the built-in reader cannot do, and bad files, are named.
  start.parameters = {{5230, 15}};
  test::ExpectError(
      [&] { ParseGcode("G0 X1\n", "p.ngc", start); },
      {"G54 turns the program 15 degrees about Z (parameter 5230)", "interpreter = \"rs274ngc\""});
  start.parameters = {{5220, 12}};
  test::ExpectError([&] { ParseGcode("G0 X1\n", "p.ngc", start); },
                    "p.ngc: parameter 5220 (the coordinate system in force) is 12");
  test::ExpectError([] { ParseParameters("5220 1\n5221 x\n", "sim.var"); },
                    "sim.var:2: expected a parameter number and its value");
  test::ExpectError([] { ReadParameterFile(test::Scratch("no-such.var")); }, "no-such.var");
}

}  // namespace
}  // namespace dtis::io
