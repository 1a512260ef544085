// G-code programs in the RS274/NGC dialect that LinuxCNC runs, read into moves (corner
// smoothing and planning build on them), by LinuxCNC's own interpreter (io/src/rs274.cpp) or by
// dtis' built-in reader.
//
// The built-in reader supports: G0 G1 G2 G3 (arcs in the XY plane, G17, with I/J centre offsets or
// R), G17, G20/G21, G90/G91, G94, G40/G49/G80 (cancels, accepted), G54 … G59.3 (work offsets, from
// GcodeStart's parameters), F, N, S, T, M2/M30 (end),
// M3/M4/M5/M6/M7/M8/M9 (spindle, tool, coolant: accepted, no motion), comments in ( ) and after ;,
// a lone % line. Linear axes X Y Z in the program's units (converted to mm), rotary axes A B C in
// degrees. Any other word is an error naming the line and column.
#pragma once

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <iosfwd>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

namespace dtis::io {

class Cancel;  // cancel.hpp
class Rs274Reader;
struct ToolTable;  // tool_table.hpp

struct GcodeMove {
  enum class Kind : std::uint8_t { kRapid, kLinear, kArcCw, kArcCcw, kNurbs };
  Kind kind = Kind::kLinear;
  Eigen::Vector3d to = Eigen::Vector3d::Zero();      // absolute, mm
  std::array<double, 3> rotary{};                    // absolute A, B, C, degrees
  Eigen::Vector3d center = Eigen::Vector3d::Zero();  // arcs: absolute centre (z of the start)
  double feed_mm_min = 0.0;                          // 0 for rapids
  int line = 0;                                      // 1-based line of the block
  // Arcs and helices: the axis (+Z for G17, +Y for G18, +X for G19; G2 turns clockwise seen from
  // its tip) and the number of turns begun (LinuxCNC's P word; 1: less than one whole turn).
  Eigen::Vector3d normal = Eigen::Vector3d::UnitZ();
  int turns = 1;
  // Path control (G61, G61.1, G64 P): the tip stays within this distance of the programmed
  // corners, mm; 0: the job's contour tolerance. `stop` (exact stop or exact path): the machine
  // comes to rest at the end of this move. `rest_before`: at its start (after a dwell), where it
  // holds still `dwell_s` seconds (G4 P, the dwells since the previous move summed).
  double tolerance_mm = 0.0;
  bool stop = false;
  bool rest_before = false;
  double dwell_s = 0.0;
  // G5.2 NURBS (LinuxCNC's interpreter only): the control points, from the start of the move to
  // `to`, their weights and the order (degree + 1); the knots are LinuxCNC's, clamped and uniform.
  struct Nurbs {
    std::vector<Eigen::Vector3d> poles;
    std::vector<double> weights;
    int order = 0;
  };
  std::shared_ptr<const Nurbs> nurbs;
};

// Which interpreter reads a program: LinuxCNC's own (rs274ngc, through the dtis-rs274 program:
// the whole dialect, O-words, parameters, every plane, work offsets) or dtis' built-in reader
// (the subset above, in the library itself).
enum class GcodeInterpreter : std::uint8_t { kRs274ngc, kDtis };

// rs274ngc when dtis was built with LinuxCNC's interpreter, else dtis.
GcodeInterpreter DefaultGcodeInterpreter();
// "rs274ngc" or "dtis".
const char* GcodeInterpreterName(GcodeInterpreter interpreter);

// What LinuxCNC holds when it runs a program: where the machine is, and its numbered parameters
// (its parameter file, rs274ngc.var), among them the work offsets of G54 … G59.3 and the one in
// force as the program starts.
struct GcodeStart {
  // Where the machine is: the controlled point in the machine frame (no offset applied), mm, and
  // the rotary axes A, B, C, degrees. A program's first move starts here.
  Eigen::Vector3d tip = Eigen::Vector3d::Zero();
  std::array<double, 3> rotary{};
  // Number -> value; a parameter not given is LinuxCNC's default (0; 5220, the coordinate system
  // in force, 1: G54).
  std::map<int, double> parameters;
};

// LinuxCNC's numbers for the work offsets: coordinate system n (1: G54 … 6: G59, 7: G59.1,
// 8: G59.2, 9: G59.3) keeps X Y Z A B C U V W in WorkOffsetParameter(n) + 0 … 8 (5221 for G54's X)
// and its XY rotation (G10 L2 R) in + 9; parameter 5220 is the system in force.
inline constexpr int kCoordinateSystemParameter = 5220;
inline constexpr int WorkOffsetParameter(int system) { return 5221 + 20 * (system - 1); }
// "G54" … "G59", "G59.1" … "G59.3" for 1 … 9.
std::string CoordinateSystemName(int system);

// A LinuxCNC parameter file: "NUMBER VALUE" lines (anything after them ignored, as LinuxCNC does).
// Throws dtis::Error naming the file and line.
std::map<int, double> ReadParameterFile(const std::string& path);
std::map<int, double> ParseParameters(std::string_view text, const std::string& source_name);

struct GcodeProgram {
  std::string file;
  std::vector<GcodeMove> moves;
  std::array<bool, 3> uses_rotary{};  // A, B, C appear in the program
  // What the program asks that moves nothing (spindle, coolant, tool changes, dwells), with how
  // many times: listed in the run summary.
  std::vector<std::pair<std::string, int>> notes;
};

// Bounds on reading a program, so that one that does not end (an O-word loop, with or without
// moves) or is longer than its reader may hold is an error naming its line, never a read that
// does not end.
struct GcodeReadOptions {
  // The most blocks read, each repetition of a loop counted (LinuxCNC's interpreter: blocks
  // executed, subroutine calls and loops included; dtis' reader: lines that are not empty); 0: no
  // limit. Past it, Next() throws dtis::Error "<file>:<line>: the program runs more than N
  // blocks ...", naming the first block past them.
  long max_blocks = kDefaultMaxBlocks;
  // Added to that message: what the user can do about it.
  std::string remedy;
  // A bound on loops that never end, for a reader that holds nothing (a stream): 100 million
  // blocks take dtis' reader under a minute. What a reader that holds the program takes is
  // bounded by the job ([path] max_blocks).
  static constexpr long kDefaultMaxBlocks = 100'000'000;
};

// A program read one move at a time, in constant memory (a line and the modal state), for programs
// too long to hold: Next() throws dtis::Error "<file>:<line>:<column>: ..." at a bad block.
class GcodeReader {
 public:
  // Reads the file at `path` (throws when it cannot be opened) with `interpreter`. With a tool
  // table (LinuxCNC's interpreter only), G43 and G43.2 apply its tool length offsets to the moves
  // that follow, as LinuxCNC does; without one, G43 is noted and the programmed tip is planned.
  // `cancel` (which must outlive the reader), once requested, stops LinuxCNC's interpreter at once,
  // even one that runs without a move: Next() then throws (check `cancel` between moves).
  // `start`: where the machine is and the work offsets (by default at the origin, G54 without
  // offsets).
  explicit GcodeReader(const std::string& path,
                       GcodeInterpreter interpreter = GcodeInterpreter::kDtis,
                       std::shared_ptr<const ToolTable> tools = nullptr, Cancel* cancel = nullptr,
                       const GcodeStart& start = {}, const GcodeReadOptions& options = {});
  // Reads `text`, which must outlive the reader; `source_name` names it in messages.
  GcodeReader(std::string_view text, const std::string& source_name, const GcodeStart& start = {},
              const GcodeReadOptions& options = {});
  ~GcodeReader();
  GcodeReader(const GcodeReader&) = delete;
  GcodeReader& operator=(const GcodeReader&) = delete;

  // The next move, or nothing at the end of the program (M2/M30 or the end of the text).
  std::optional<GcodeMove> Next();
  const std::string& File() const;
  // A, B, C words seen so far (rs274ngc: rotary axes moved away from zero so far).
  const std::array<bool, 3>& UsesRotary() const;
  // GcodeProgram::notes, so far.
  const std::vector<std::pair<std::string, int>>& Notes() const;

 private:
  class Blocks;
  GcodeReadOptions options_;
  long blocks_read_ = 0;  // lines that were not empty
  std::unique_ptr<Blocks> blocks_;
  std::unique_ptr<Rs274Reader> rs274_;  // LinuxCNC's interpreter, when it reads
  std::unique_ptr<std::ifstream> in_;   // the file; without one, text_ from offset_
  std::string_view text_;
  std::size_t offset_ = 0;
  std::string line_text_;
  int line_ = 0;
  bool ended_ = false;
};

// The whole program. Throws dtis::Error "<file>:<line>:<column>: ..." on the first bad block.
GcodeProgram ReadGcode(const std::string& path,
                       GcodeInterpreter interpreter = GcodeInterpreter::kDtis,
                       std::shared_ptr<const ToolTable> tools = nullptr,
                       const GcodeStart& start = {}, const GcodeReadOptions& options = {});
GcodeProgram ParseGcode(std::string_view text, const std::string& source_name,
                        const GcodeStart& start = {}, const GcodeReadOptions& options = {});
// The records dtis-rs274 writes (tools/rs274/dtis_rs274.cpp), as they would be read from it: for
// tests and the fuzz target. Throws dtis::Error on the interpreter's error or a bad record.
GcodeProgram ParseRs274Records(std::string_view records, const std::string& source_name);

}  // namespace dtis::io
