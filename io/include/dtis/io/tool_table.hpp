// LinuxCNC tool tables: the file a LinuxCNC machine names in [EMCIO]TOOL_TABLE, one tool per line,
//   T1 P1 Z50.0 D6 ;6 mm end mill
//   T2 P2 X0.5 Z42.25 D3 ;3 mm ball, offset in X too
// words T (tool number), P (pocket), X Y Z A B C U V W (offsets), D (diameter), I J Q (lathe:
// front and back angle, orientation), in any order and either case, then an optional ';' comment.
// Lengths in mm (dtis' machine unit), angles in degrees. A job that names one
// ([path] tool_table) has G43/G43.2 apply these offsets as LinuxCNC does (gcode.hpp).
#pragma once

#include <array>
#include <string>
#include <string_view>
#include <vector>

namespace dtis::io {

// Offsets larger than this (mm, or degrees for A B C) are refused: no tool is 100 m long, and a
// typo of that size would move the machine off its travel.
inline constexpr double kMaxToolOffset = 1e5;

struct ToolEntry {
  int tool = 0;
  int pocket = 0;
  std::array<double, 9> offset{};  // X Y Z A B C U V W
  double diameter = 0.0;
  int line = 0;  // in the file
};

struct ToolTable {
  std::string file;
  std::vector<ToolEntry> tools;  // in the file's order; tool numbers are distinct
};

// Throws dtis::Error "<file>:<line>: ..." naming the word and what was expected.
ToolTable LoadToolTable(const std::string& path);
ToolTable ParseToolTable(std::string_view text, const std::string& source_name);

}  // namespace dtis::io
