// G-code programs in the RS274/NGC dialect that LinuxCNC runs, read into moves (issue 4's first
// step; corner smoothing and planning build on it).
//
// Supported: G0 G1 G2 G3 (arcs in the XY plane, G17, with I/J centre offsets or R), G17, G20/G21,
// G90/G91, G94, G40/G49/G80 (cancels, accepted), F, N, S, T, M2/M30 (end), M3/M4/M5/M6/M7/M8/M9
// (spindle, tool, coolant: accepted, no motion), comments in ( ) and after ;, a lone % line.
// Linear axes X Y Z in the program's units (converted to mm), rotary axes A B C in degrees. Any
// other word is an error naming the line and column.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

namespace dtis::io {

struct GcodeMove {
  enum class Kind : std::uint8_t { kRapid, kLinear, kArcCw, kArcCcw };
  Kind kind = Kind::kLinear;
  Eigen::Vector3d to = Eigen::Vector3d::Zero();      // absolute, mm
  std::array<double, 3> rotary{};                    // absolute A, B, C, degrees
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  // arcs: absolute centre (z of the start)
  double feed_mm_min = 0.0;                          // 0 for rapids
  int line = 0;                                      // 1-based line of the block
};

struct GcodeProgram {
  std::string file;
  std::vector<GcodeMove> moves;
  std::array<bool, 3> uses_rotary{};  // A, B, C appear in the program
};

// Throws dtis::Error "<file>:<line>:<column>: ..." on the first bad block.
GcodeProgram ReadGcode(const std::string& path);
GcodeProgram ParseGcode(std::string_view text, const std::string& source_name);

}  // namespace dtis::io
