// dtis-rs274: a G-code program run through LinuxCNC's own RS274/NGC interpreter (librs274), its
// canonical machining calls written to standard output as text records that dtis reads
// (io/src/rs274.cpp). This program is the only part of dtis linked with LinuxCNC's interpreter,
// which is GPL-2: it is a separate program so that the dtis library keeps its own licence, and so
// that an interpreter failure cannot take the planner (or a machine it feeds) down with it.
//
//   dtis-rs274 PROGRAM.ngc [-s X,Y,Z,A,B,C] [-p NUMBER=VALUE,...] [-n MAX_BLOCKS]
//              [-t TOOL=POCKET,X,Y,Z,A,B,C,U,V,W,DIAMETER ...]
//
// With -n, the interpreter executes at most MAX_BLOCKS blocks (each repetition of a loop and each
// block of a called subroutine counted), so that a loop that never ends ends here.
//
// -s: where the machine is as the program starts (mm and degrees, the machine frame; default the
// origin). -p: the numbered parameters the interpreter starts with, as LinuxCNC's parameter file
// gives them (the work offsets of G54 … G59.3 and the one in force, G92, G28/G30). The arguments
// after -t are a tool table (dtis reads and checks the user's file, in mm
// and degrees, io/src/tool_table.cpp); with one, G43/G43.2/G49 offsets move the controlled point
// as LinuxCNC's canon layer moves it, added to every point written. Without one, every tool number
// exists with no offsets, and G43 is noted: dtis plans the programmed tip.
//
// Records, one per line, numbers written with 17 significant digits; lengths in mm in the machine
// frame (work offsets, G92 and the XY rotation applied, as LinuxCNC's canon layer applies them),
// angles in degrees, feeds in mm/min:
//   T <line> x y z a b c                     rapid (STRAIGHT_TRAVERSE)
//   L <line> x y z a b c                     feed move (STRAIGHT_FEED)
//   A <line> x y z cx cy cz nx ny nz turns a b c
//                                            arc or helix (ARC_FEED): end point, a point on its
//                                            axis, the axis (unit; turns > 0 counterclockwise about
//                                            it), whole turns + 1
//   N <line> order z a b c count x y w ...   NURBS in the XY plane (NURBS_FEED, G5.2)
//   F <line> feed                            feed rate for what follows (in inverse time, G93, the
//                                            interpreter sets each move's own)
//   P <line> mode tolerance                  path control: 1 exact stop (G61.1), 2 exact path
//                                            (G61), 3 blending (G64) within tolerance mm, 0 none
//   D <line> seconds                         dwell (G4)
//   I <line> what                            a call that moves nothing (spindle, coolant, tool)
//   E <line> message                         the interpreter's error; the last record
//   B <line>                                 the block after MAX_BLOCKS executed (-n); the last record
//   X                                        the program's end; the last record
// Exit status: 0 after X, 1 after E, 2 on bad usage.
#include <unistd.h>

#include <array>
#include <canon.hh>
#include <cctype>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <interp_base.hh>
#include <interp_return.hh>
#include <string>
#include <utility>
#include <vector>

// The tool table the interpreter looks tools up in (G43 H, M6 T). LinuxCNC's libtooldata keeps it
// in a memory map shared with a running LinuxCNC; this program must not touch that, so it answers
// here (these definitions take the place of libtooldata's). As LinuxCNC's non-random tool changer
// lays it out, index 0 is the spindle (the tool M6 loaded) and the tools follow from index 1.
CANON_TOOL_TABLE tooldata_entry_init() {
  CANON_TOOL_TABLE entry = {};
  entry.toolno = -1;
  entry.pocketno = -1;
  return entry;
}
namespace {
bool tool_table_given = false;                               // the arguments named a tool table
std::vector<CANON_TOOL_TABLE> tools = {CANON_TOOL_TABLE{}};  // [0]: the spindle, empty (T0)
}  // namespace
int tooldata_find_index_for_tool(int toolno) {
  if (!tool_table_given) return toolno >= 0 ? toolno : -1;
  if (toolno == 0) return 0;  // no tool
  for (std::size_t i = 1; i < tools.size(); ++i) {
    if (tools[i].toolno == toolno) return static_cast<int>(i);
  }
  return -1;
}
int tooldata_get(CANON_TOOL_TABLE* entry, int index) {
  *entry = tooldata_entry_init();
  if (index < 0) return -1;
  if (!tool_table_given) {  // every tool number exists, with no offsets
    entry->toolno = index;
    entry->pocketno = index;
    return 0;
  }
  if (static_cast<std::size_t>(index) >= tools.size()) return -1;
  *entry = tools[static_cast<std::size_t>(index)];
  return 0;
}

USER_DEFINED_FUNCTION_TYPE USER_DEFINED_FUNCTION[USER_DEFINED_FUNCTION_NUM] = {};
// The interpreter's embedded Python (O-word and remap plugins) registers these modules.
extern "C" void* PyInit_interpreter();
extern "C" void* PyInit_emccanon();
struct _inittab {
  const char* name;
  void* (*initfunc)();
};
struct _inittab builtin_modules[] = {
    {"interpreter", PyInit_interpreter}, {"emccanon", PyInit_emccanon}, {nullptr, nullptr}};
int _task = 0;  // not LinuxCNC's task process

namespace {

// A pose of the nine axes X Y Z A B C U V W: mm and degrees in the machine frame, or program
// units and degrees in the program's.
using Pose = std::array<double, 9>;
constexpr bool kLinear[9] = {true, true, true, false, false, false, true, true, true};

Pose ToPose(const EmcPose& p) {
  return {p.tran.x, p.tran.y, p.tran.z, p.a, p.b, p.c, p.u, p.v, p.w};
}

// The canon layer's state: what the interpreter told it and asks back.
struct Canon {
  double units = 1.0;  // mm per program unit
  CANON_UNITS unit_type = CANON_UNITS_MM;
  CANON_PLANE plane = CANON_PLANE_XY;
  // Where the controlled point is, in the machine frame with every offset in force (as LinuxCNC's
  // canon keeps its end point): the program position is derived from it with the offsets of the
  // moment, so that it follows a change of work or tool offset as the interpreter expects.
  Pose position{};
  // Offsets in mm and degrees, converted from program units when they are set.
  Pose g5x{}, g92{}, tool{};
  double xy_rotation = 0.0;  // degrees
  double feed = 0.0;         // program units per minute (in G93 too: the interpreter converts)
  CANON_MOTION_MODE motion_mode = CANON_CONTINUOUS;
  double tolerance = 0.0;
  double traverse_rate = 1e9;
  bool optional_stop = false, block_delete = false;
  int tool_slot = 0, selected_slot = 0;
  double spindle_speed = 0.0;
  CANON_DIRECTION spindle = CANON_STOPPED;
  int flood = 0, mist = 0;
  bool tool_offset_noted = false;  // a G43 was noted and no G49 since
  bool pallet_shuttle = false;     // asked, and neither the program's end nor its stop yet
};
Canon canon;
InterpBase* interp = nullptr;  // the interpreter running the program

// Whether the block being executed writes G49: the interpreter's canon call is the same for G43
// of a tool without offsets and for G49, so the block tells them apart (comments left out).
bool BlockCancelsToolOffset() {
  char text[1024] = {};
  if (!interp || !interp->line_text(text, sizeof text)) return false;
  std::string words;
  int depth = 0;
  for (const char* p = text; *p && *p != ';'; ++p) {
    if (*p == '(') ++depth;
    if (depth == 0 && *p != ' ' && *p != '\t') {
      words += static_cast<char>(std::toupper(static_cast<unsigned char>(*p)));
    }
    if (*p == ')' && depth > 0) --depth;
  }
  for (std::size_t at = words.find("G49"); at != std::string::npos;
       at = words.find("G49", at + 1)) {
    const char next = at + 3 < words.size() ? words[at + 3] : '\0';
    if (!std::isdigit(static_cast<unsigned char>(next)) && next != '.') return true;
  }
  return false;
}

double Scale(std::size_t k) { return kLinear[k] ? canon.units : 1.0; }

// (x, y) turned about Z by `degrees`: the XY rotation (G10 L2 R).
void RotateXY(double degrees, double* x, double* y) {
  const double r = degrees * M_PI / 180.0;
  const double x0 = *x, y0 = *y;
  *x = std::cos(r) * x0 - std::sin(r) * y0;
  *y = std::sin(r) * x0 + std::cos(r) * y0;
}

// A program point to the machine frame, as LinuxCNC's canon maps it: G92, the rotation about Z,
// the work offset, the tool offset.
Pose ToMachine(const Pose& program) {
  Pose m;
  for (std::size_t k = 0; k < 9; ++k) m[k] = program[k] * Scale(k) + canon.g92[k];
  RotateXY(canon.xy_rotation, &m[0], &m[1]);
  for (std::size_t k = 0; k < 9; ++k) m[k] += canon.g5x[k] + canon.tool[k];
  return m;
}
// The inverse: the program position of the machine pose `m` under the offsets in force.
Pose ToProgram(const Pose& m) {
  Pose p;
  for (std::size_t k = 0; k < 9; ++k) p[k] = m[k] - canon.g5x[k] - canon.tool[k];
  RotateXY(-canon.xy_rotation, &p[0], &p[1]);
  for (std::size_t k = 0; k < 9; ++k) p[k] = (p[k] - canon.g92[k]) / Scale(k);
  return p;
}
double ProgramPosition(std::size_t k) { return ToProgram(canon.position)[k]; }
// A machine pose as written: without a tool table, dtis plans the programmed tip, so the tool
// offset the interpreter set (G43.1, or G43 of a table LinuxCNC would hold) is taken back out.
Pose Written(const Pose& m) {
  Pose out = m;
  if (!tool_table_given) {
    for (std::size_t k = 0; k < 9; ++k) out[k] -= canon.tool[k];
  }
  return out;
}
void Record(const char* kind, int line, std::initializer_list<double> values) {
  std::printf("%s %d", kind, line);
  for (const double v : values) std::printf(" %.17g", v);
  std::printf("\n");
}

void Note(int line, const char* what) { std::printf("I %d %s\n", line, what); }

int current_line = 0;  // the line of the block being executed, for calls without one

void Straight(const char* kind, int line, const Pose& program) {
  canon.position = ToMachine(program);
  const Pose p = Written(canon.position);
  Record(kind, line, {p[0], p[1], p[2], p[3], p[4], p[5]});
}

}  // namespace

// ---- What the interpreter calls: motion. ----

void STRAIGHT_TRAVERSE(int line, double x, double y, double z, double a, double b, double c,
                       double u, double v, double w) {
  Straight("T", line, {x, y, z, a, b, c, u, v, w});
}

void STRAIGHT_FEED(int line, double x, double y, double z, double a, double b, double c, double u,
                   double v, double w) {
  Straight("L", line, {x, y, z, a, b, c, u, v, w});
}

void ARC_FEED(int line, double first_end, double second_end, double first_axis, double second_axis,
              int rotation, double axis_end_point, double a, double b, double c, double u, double v,
              double w) {
  // The plane's first and second axes and its normal (first x second): XY, YZ, ZX.
  std::size_t i1 = 0, i2 = 1, in = 2;
  if (canon.plane == CANON_PLANE_YZ) i1 = 1, i2 = 2, in = 0;
  if (canon.plane == CANON_PLANE_XZ) i1 = 2, i2 = 0, in = 1;
  const Pose start = ToProgram(canon.position);
  Pose end = {0, 0, 0, a, b, c, u, v, w};
  end[i1] = first_end, end[i2] = second_end, end[in] = axis_end_point;
  Pose centre = end;  // a point on the arc's axis: in the start's plane
  centre[i1] = first_axis, centre[i2] = second_axis, centre[in] = start[in];
  double n[3] = {0, 0, 0};  // the arc's axis, turned to the machine frame
  n[in] = 1.0;
  RotateXY(canon.xy_rotation, &n[0], &n[1]);
  canon.position = ToMachine(end);
  const Pose e = Written(canon.position);
  const Pose k = Written(ToMachine(centre));
  Record("A", line,
         {e[0], e[1], e[2], k[0], k[1], k[2], n[0], n[1], n[2], static_cast<double>(rotation), e[3],
          e[4], e[5]});
}

void NURBS_FEED(int line, std::vector<CONTROL_POINT> points, unsigned int order) {
  if (points.empty()) return;
  Pose program = ToProgram(canon.position);
  const Pose at = Written(canon.position);
  std::printf("N %d %u %.17g %.17g %.17g %.17g %zu", line, order, at[2], at[3], at[4], at[5],
              points.size());
  for (const CONTROL_POINT& p : points) {
    program[0] = p.X, program[1] = p.Y;
    const Pose q = Written(ToMachine(program));
    std::printf(" %.17g %.17g %.17g", q[0], q[1], p.W);
  }
  std::printf("\n");
  canon.position = ToMachine(program);
}

void RIGID_TAP(int line, double, double, double, double) {
  std::printf("E %d rigid tapping (G33.1) is not supported by dtis\n", line);
  std::fflush(stdout);
  std::_Exit(1);
}
void STRAIGHT_PROBE(int line, double, double, double, double, double, double, double, double,
                    double, unsigned char) {
  std::printf("E %d probing (G38) is not supported by dtis\n", line);
  std::fflush(stdout);
  std::_Exit(1);
}
void START_SPEED_FEED_SYNCH(int, double, bool) {
  std::printf("E %d spindle-synchronised motion (G33, G76, G95) is not supported by dtis\n",
              current_line);
  std::fflush(stdout);
  std::_Exit(1);
}
void STOP_SPEED_FEED_SYNCH() {}

void SET_FEED_RATE(double rate) {
  canon.feed = rate;
  Record("F", current_line, {rate * canon.units});
}
void SET_FEED_MODE(int, int mode) {
  if (mode != 0) START_SPEED_FEED_SYNCH(0, 0.0, false);
}
void SET_FEED_REFERENCE(CANON_FEED_REFERENCE) {}
void SET_TRAVERSE_RATE(double rate) { canon.traverse_rate = rate; }
void SET_MOTION_CONTROL_MODE(CANON_MOTION_MODE mode, double tolerance) {
  canon.motion_mode = mode;
  canon.tolerance = tolerance;
  const int m = mode == CANON_EXACT_STOP ? 1 : mode == CANON_EXACT_PATH ? 2 : 3;
  Record("P", current_line, {static_cast<double>(m), tolerance * canon.units});
}
void SET_NAIVECAM_TOLERANCE(double) {}
void DWELL(double seconds) { Record("D", current_line, {seconds}); }
void SELECT_PLANE(CANON_PLANE plane) {
  if (plane != CANON_PLANE_XY && plane != CANON_PLANE_YZ && plane != CANON_PLANE_XZ) {
    std::printf("E %d the UVW planes (G17.1, G18.1, G19.1) are not supported by dtis\n",
                current_line);
    std::fflush(stdout);
    std::_Exit(1);
  }
  canon.plane = plane;
}
void USE_LENGTH_UNITS(CANON_UNITS u) {
  canon.unit_type = u;
  canon.units = u == CANON_UNITS_INCHES ? 25.4 : u == CANON_UNITS_CM ? 10.0 : 1.0;
}
void SET_G5X_OFFSET(int, double x, double y, double z, double a, double b, double c, double u,
                    double v, double w) {
  canon.g5x = {x, y, z, a, b, c, u, v, w};
  for (std::size_t k = 0; k < 9; ++k) canon.g5x[k] *= Scale(k);
}
void SET_G92_OFFSET(double x, double y, double z, double a, double b, double c, double u, double v,
                    double w) {
  canon.g92 = {x, y, z, a, b, c, u, v, w};
  for (std::size_t k = 0; k < 9; ++k) canon.g92[k] *= Scale(k);
}
void SET_XY_ROTATION(double degrees) { canon.xy_rotation = degrees; }
void USE_TOOL_LENGTH_OFFSET(EmcPose offset) {
  // In program units; kept in mm, as a later G20/G21 does not change the offset in force.
  canon.tool = ToPose(offset);
  for (std::size_t k = 0; k < 9; ++k) canon.tool[k] *= Scale(k);
  if (BlockCancelsToolOffset()) {
    // A G49 with no offset in force (as programs begin, to be safe) changes nothing.
    if (canon.tool_offset_noted) Note(current_line, "tool length offset cancelled (G49)");
    canon.tool_offset_noted = false;
    return;
  }
  canon.tool_offset_noted = true;
  if (!tool_table_given) {
    Note(current_line, "tool length offset (G43): the machine applies it, dtis plans the tip");
    return;
  }
  char what[160];
  std::snprintf(what, sizeof what, "tool length offset (G43) applied: X %g Y %g Z %g mm",
                canon.tool[0], canon.tool[1], canon.tool[2]);
  Note(current_line, what);
}
void SET_CUTTER_RADIUS_COMPENSATION(double) {}
void START_CUTTER_RADIUS_COMPENSATION(int) {}
void STOP_CUTTER_RADIUS_COMPENSATION() {}
void START_SPINDLE_CLOCKWISE(int, int) {
  canon.spindle = CANON_CLOCKWISE;
  Note(current_line, "spindle on (M3)");
}
void START_SPINDLE_COUNTERCLOCKWISE(int, int) {
  canon.spindle = CANON_COUNTERCLOCKWISE;
  Note(current_line, "spindle on (M4)");
}
void STOP_SPINDLE_TURNING(int) { canon.spindle = CANON_STOPPED; }
void SET_SPINDLE_SPEED(int, double speed) { canon.spindle_speed = speed; }
void SET_SPINDLE_MODE(int, double) {}
void ORIENT_SPINDLE(int, double, int) { Note(current_line, "spindle orientation (M19)"); }
void WAIT_SPINDLE_ORIENT_COMPLETE(int, double) {}
void SPINDLE_RETRACT() {}
void SPINDLE_RETRACT_TRAVERSE() {}
void USE_NO_SPINDLE_FORCE() {}
void SELECT_TOOL(int) {}
void START_CHANGE() {}
void CHANGE_TOOL(int slot) {
  canon.tool_slot = slot;
  // The tool from `slot` (an index of the table) is now in the spindle, index 0.
  if (tool_table_given && slot >= 0 && static_cast<std::size_t>(slot) < tools.size()) {
    tools[0] = tools[static_cast<std::size_t>(slot)];
  }
  Note(current_line, "tool change (M6): the program's tool is the job's");
}
void CHANGE_TOOL_NUMBER(int slot) { canon.tool_slot = slot; }
void RELOAD_TOOLDATA() {}
void SET_TOOL_TABLE_ENTRY(int, int, EmcPose, double, double, double, int) {}
void CLAMP_AXIS(CANON_AXIS) {}
int LOCK_ROTARY(int, int) { return 0; }
int UNLOCK_ROTARY(int, int) { return 0; }
void COMMENT(const char*) {}
void MESSAGE(char*) {}
void LOG(char*) {}
void LOGOPEN(char*) {}
void LOGAPPEND(char*) {}
void LOGCLOSE() {}
void DISABLE_ADAPTIVE_FEED() {}
void ENABLE_ADAPTIVE_FEED() {}
void DISABLE_FEED_OVERRIDE() {}
void ENABLE_FEED_OVERRIDE() {}
void DISABLE_SPEED_OVERRIDE(int) {}
void ENABLE_SPEED_OVERRIDE(int) {}
void DISABLE_FEED_HOLD() {}
void ENABLE_FEED_HOLD() {}
void FLOOD_OFF() { canon.flood = 0; }
void FLOOD_ON() {
  canon.flood = 1;
  Note(current_line, "coolant (M8)");
}
void MIST_OFF() { canon.mist = 0; }
void MIST_ON() {
  canon.mist = 1;
  Note(current_line, "coolant (M7)");
}
// M30 shuttles the pallet, then ends the program; M60 shuttles it, then stops. Only M60's is
// noted: M30 is the program's end.
void PALLET_SHUTTLE() { canon.pallet_shuttle = true; }
void TURN_PROBE_ON() {}
void TURN_PROBE_OFF() {}
int WAIT(int, int, int, double) { return 0; }
void SET_AUX_OUTPUT_BIT(int) {}
void CLEAR_AUX_OUTPUT_BIT(int) {}
void SET_AUX_OUTPUT_VALUE(int, double) {}
void SET_MOTION_OUTPUT_BIT(int) {}
void CLEAR_MOTION_OUTPUT_BIT(int) {}
void SET_MOTION_OUTPUT_VALUE(int, double) {}
void OPTIONAL_PROGRAM_STOP() { Note(current_line, "optional stop (M1): not taken"); }
void PROGRAM_STOP() {
  Note(current_line, std::exchange(canon.pallet_shuttle, false)
                         ? "pallet shuttle and program stop (M60): not taken"
                         : "program stop (M0): not taken");
}
void PROGRAM_END() { canon.pallet_shuttle = false; }
void FINISH() {}
void ON_RESET() {}
void INIT_CANON() {}
void SET_PARAMETER_FILE_NAME(const char*) {}
void SET_BLOCK_DELETE(bool on) { canon.block_delete = on; }
void SET_OPTIONAL_PROGRAM_STOP(bool on) { canon.optional_stop = on; }
void PLUGIN_CALL(int, const char*) {}
void IO_PLUGIN_CALL(int, const char*) {}
void UPDATE_TAG(StateTag) {}
void CANON_ERROR(const char* fmt, ...) {
  char buffer[512];
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(buffer, sizeof buffer, fmt, args);
  va_end(args);
  for (char* p = buffer; *p; ++p) {
    if (*p == '\n') *p = ' ';
  }
  std::printf("E %d %s\n", current_line, buffer);
  std::fflush(stdout);
  std::_Exit(1);
}

// ---- What the interpreter asks. ----

double GET_EXTERNAL_FEED_RATE() { return canon.feed; }
double GET_EXTERNAL_TRAVERSE_RATE() { return canon.traverse_rate; }
// The machine's length unit per mm: dtis' machines are in mm (tool tables, G28/G30 positions).
double GET_EXTERNAL_LENGTH_UNITS() { return 1.0; }
CANON_UNITS GET_EXTERNAL_LENGTH_UNIT_TYPE() { return canon.unit_type; }
double GET_EXTERNAL_ANGLE_UNITS() { return 1.0; }
double GET_EXTERNAL_POSITION_X() { return ProgramPosition(0); }
double GET_EXTERNAL_POSITION_Y() { return ProgramPosition(1); }
double GET_EXTERNAL_POSITION_Z() { return ProgramPosition(2); }
double GET_EXTERNAL_POSITION_A() { return ProgramPosition(3); }
double GET_EXTERNAL_POSITION_B() { return ProgramPosition(4); }
double GET_EXTERNAL_POSITION_C() { return ProgramPosition(5); }
double GET_EXTERNAL_POSITION_U() { return ProgramPosition(6); }
double GET_EXTERNAL_POSITION_V() { return ProgramPosition(7); }
double GET_EXTERNAL_POSITION_W() { return ProgramPosition(8); }
double GET_EXTERNAL_PROBE_POSITION_X() { return ProgramPosition(0); }
double GET_EXTERNAL_PROBE_POSITION_Y() { return ProgramPosition(1); }
double GET_EXTERNAL_PROBE_POSITION_Z() { return ProgramPosition(2); }
double GET_EXTERNAL_PROBE_POSITION_A() { return ProgramPosition(3); }
double GET_EXTERNAL_PROBE_POSITION_B() { return ProgramPosition(4); }
double GET_EXTERNAL_PROBE_POSITION_C() { return ProgramPosition(5); }
double GET_EXTERNAL_PROBE_POSITION_U() { return ProgramPosition(6); }
double GET_EXTERNAL_PROBE_POSITION_V() { return ProgramPosition(7); }
double GET_EXTERNAL_PROBE_POSITION_W() { return ProgramPosition(8); }
double GET_EXTERNAL_PROBE_VALUE() { return 0.0; }
int GET_EXTERNAL_PROBE_TRIPPED_VALUE() { return 0; }
int GET_EXTERNAL_QUEUE_EMPTY() { return 1; }
CANON_PLANE GET_EXTERNAL_PLANE() { return canon.plane; }
CANON_MOTION_MODE GET_EXTERNAL_MOTION_CONTROL_MODE() { return canon.motion_mode; }
double GET_EXTERNAL_MOTION_CONTROL_TOLERANCE() { return canon.tolerance; }
double GET_EXTERNAL_MOTION_CONTROL_NAIVECAM_TOLERANCE() { return canon.tolerance; }
double GET_EXTERNAL_SPEED(int) { return canon.spindle_speed; }
CANON_DIRECTION GET_EXTERNAL_SPINDLE(int) { return canon.spindle; }
int GET_EXTERNAL_SPINDLE_OVERRIDE_ENABLE(int) { return 1; }
int GET_EXTERNAL_FEED_OVERRIDE_ENABLE() { return 1; }
int GET_EXTERNAL_ADAPTIVE_FEED_ENABLE() { return 0; }
int GET_EXTERNAL_FEED_HOLD_ENABLE() { return 1; }
int GET_EXTERNAL_FLOOD() { return canon.flood; }
int GET_EXTERNAL_MIST() { return canon.mist; }
int GET_EXTERNAL_AXIS_MASK() { return 0x3f; }  // X Y Z A B C
int GET_EXTERNAL_TOOL_SLOT() { return canon.tool_slot; }
int GET_EXTERNAL_SELECTED_TOOL_SLOT() { return canon.selected_slot; }
int GET_EXTERNAL_TC_FAULT() { return 0; }
int GET_EXTERNAL_TC_REASON() { return 0; }
int GET_EXTERNAL_OFFSET_APPLIED() { return 0; }
EmcPose GET_EXTERNAL_OFFSETS() { return EmcPose{}; }
double GET_EXTERNAL_TOOL_LENGTH_XOFFSET() { return canon.tool[0] / Scale(0); }
double GET_EXTERNAL_TOOL_LENGTH_YOFFSET() { return canon.tool[1] / Scale(1); }
double GET_EXTERNAL_TOOL_LENGTH_ZOFFSET() { return canon.tool[2] / Scale(2); }
double GET_EXTERNAL_TOOL_LENGTH_AOFFSET() { return canon.tool[3] / Scale(3); }
double GET_EXTERNAL_TOOL_LENGTH_BOFFSET() { return canon.tool[4] / Scale(4); }
double GET_EXTERNAL_TOOL_LENGTH_COFFSET() { return canon.tool[5] / Scale(5); }
double GET_EXTERNAL_TOOL_LENGTH_UOFFSET() { return canon.tool[6] / Scale(6); }
double GET_EXTERNAL_TOOL_LENGTH_VOFFSET() { return canon.tool[7] / Scale(7); }
double GET_EXTERNAL_TOOL_LENGTH_WOFFSET() { return canon.tool[8] / Scale(8); }
CANON_TOOL_TABLE GET_EXTERNAL_TOOL_TABLE(int index) {
  CANON_TOOL_TABLE entry;
  tooldata_get(&entry, index);
  return entry;
}
double GET_EXTERNAL_ANALOG_INPUT(int, double def) { return def; }
int GET_EXTERNAL_DIGITAL_INPUT(int, int def) { return def; }
bool GET_BLOCK_DELETE() { return canon.block_delete; }
bool GET_OPTIONAL_PROGRAM_STOP() { return canon.optional_stop; }
// The interpreter reads its numbered parameters from a file and writes them back; it gets one of
// its own in a scratch folder, never a file of the user's or of a LinuxCNC session.
std::string parameter_file;
void GET_EXTERNAL_PARAMETER_FILE_NAME(char* name, int size) {
  if (size > 0) std::snprintf(name, static_cast<std::size_t>(size), "%s", parameter_file.c_str());
}

// ---- The program. ----

// "TOOL=POCKET,X,Y,Z,A,B,C,U,V,W,DIAMETER" into a table entry; false when it is not one.
bool ReadTool(const char* text, CANON_TOOL_TABLE* entry) {
  *entry = tooldata_entry_init();
  double v[10];
  int used = 0;
  if (std::sscanf(text, "%d=%d,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf,%lf%n", &entry->toolno,
                  &entry->pocketno, &v[0], &v[1], &v[2], &v[3], &v[4], &v[5], &v[6], &v[7], &v[8],
                  &v[9], &used) != 12 ||
      text[used] != '\0') {
    return false;
  }
  entry->offset.tran.x = v[0], entry->offset.tran.y = v[1], entry->offset.tran.z = v[2];
  entry->offset.a = v[3], entry->offset.b = v[4], entry->offset.c = v[5];
  entry->offset.u = v[6], entry->offset.v = v[7], entry->offset.w = v[8];
  entry->diameter = v[9];
  return true;
}

int main(int argc, char** argv) {
  constexpr const char* kUsage =
      "usage: dtis-rs274 PROGRAM.ngc [-s X,Y,Z,A,B,C] [-p NUMBER=VALUE,...] [-n MAX_BLOCKS] "
      "[-t TOOL=POCKET,X,Y,Z,A,B,C,U,V,W,D ...]\n";
  if (argc < 2) {
    std::fputs(kUsage, stderr);
    return 2;
  }
  std::string parameters;  // the parameter file's lines
  // -n: the most blocks the interpreter executes (loops and calls counted), then "B line".
  long max_blocks = 0;
  for (int i = 2; i < argc; ++i) {
    if (std::strcmp(argv[i], "-n") == 0 && i + 1 < argc) {
      char* end = nullptr;
      max_blocks = std::strtol(argv[++i], &end, 10);
      if (end == argv[i] || *end != '\0' || max_blocks < 1) {
        std::fprintf(stderr, "dtis-rs274: -n '%s' is not a number of blocks\n", argv[i]);
        return 2;
      }
    } else if (std::strcmp(argv[i], "-t") == 0) {
      tool_table_given = true;
      for (++i; i < argc; ++i) {
        CANON_TOOL_TABLE entry;
        if (!ReadTool(argv[i], &entry)) {
          std::fprintf(stderr, "dtis-rs274: '%s' is not TOOL=POCKET,X,Y,Z,A,B,C,U,V,W,D\n",
                       argv[i]);
          return 2;
        }
        tools.push_back(entry);
      }
    } else if (std::strcmp(argv[i], "-s") == 0 && i + 1 < argc) {
      double v[6];
      int used = 0;
      if (std::sscanf(argv[++i], "%lf,%lf,%lf,%lf,%lf,%lf%n", &v[0], &v[1], &v[2], &v[3], &v[4],
                      &v[5], &used) != 6 ||
          argv[i][used] != '\0') {
        std::fprintf(stderr, "dtis-rs274: '%s' is not X,Y,Z,A,B,C\n", argv[i]);
        return 2;
      }
      for (std::size_t k = 0; k < 6; ++k) canon.position[k] = v[k];
    } else if (std::strcmp(argv[i], "-p") == 0 && i + 1 < argc) {
      // NUMBER=VALUE,... in increasing numbers, as the interpreter wants its file.
      for (const char* p = argv[++i]; *p;) {
        int number = 0, used = 0;
        double value = 0.0;
        if (std::sscanf(p, "%d=%lf%n", &number, &value, &used) != 2 ||
            (p[used] != ',' && p[used] != '\0')) {
          std::fprintf(stderr, "dtis-rs274: '%s' is not NUMBER=VALUE,...\n", argv[i]);
          return 2;
        }
        char line[64];
        std::snprintf(line, sizeof line, "%d\t%.17g\n", number, value);
        parameters += line;
        p += used;
        if (*p == ',') ++p;
      }
    } else {
      std::fprintf(stderr, "dtis-rs274: unexpected '%s'\n%s", argv[i], kUsage);
      return 2;
    }
  }
  // The interpreter reads the INI a LinuxCNC session names in the environment (its subroutine
  // path, remaps, Python plugins, log file): a program must read the same wherever dtis runs.
  ::unsetenv("INI_FILE_NAME");
  interp = makeInterp();
  const auto fail = [&](int status) -> int {
    char text[512] = {};
    interp->error_text(status, text, sizeof text);
    const int line = interp->sequence_number();
    for (char* p = text; *p; ++p) {
      if (*p == '\n') *p = ' ';
    }
    std::printf("E %d %s\n", line, text[0] ? text : "the interpreter failed");
    std::fflush(stdout);
    std::_Exit(1);
  };
  const char* tmp = std::getenv("TMPDIR");
  std::string scratch = std::string(tmp && *tmp ? tmp : "/tmp") + "/dtis-rs274-XXXXXX";
  if (mkdtemp(scratch.data()) == nullptr) {
    std::printf("E 0 cannot make a scratch folder for the interpreter's parameters\n");
    return 1;
  }
  parameter_file = scratch + "/rs274ngc.var";
  if (std::FILE* f = std::fopen(parameter_file.c_str(), "w")) {
    std::fputs(parameters.c_str(), f);
    std::fclose(f);
  }
  int status = interp->init();
  // Read and written back at init; the program's parameters are its own and not kept.
  std::remove(parameter_file.c_str());
  std::remove((parameter_file + ".bak").c_str());
  ::rmdir(scratch.c_str());
  if (status > INTERP_MIN_ERROR) return fail(status);
  // Subroutines called by name (o<name> call) are looked for in the working folder: the
  // program's own, so that files next to it are found wherever dtis was started.
  std::string program = argv[1];
  if (char* full = ::realpath(argv[1], nullptr)) {
    program = full;
    std::free(full);
    const std::string folder = program.substr(0, program.find_last_of('/') + 1);
    if (::chdir(folder.c_str()) != 0) {
      std::printf("E 0 cannot enter the program's folder %s\n", folder.c_str());
      return 1;
    }
  }
  status = interp->open(program.c_str());
  if (status > INTERP_MIN_ERROR) return fail(status);
  for (long blocks = 1;; ++blocks) {
    status = interp->read();
    if (status == INTERP_ENDFILE) break;
    if (status > INTERP_MIN_ERROR) return fail(status);
    current_line = interp->sequence_number();
    if (max_blocks > 0 && blocks > max_blocks) {  // the first block past them, not executed
      std::printf("B %d\n", current_line);
      std::fflush(stdout);
      std::_Exit(1);
    }
    status = interp->execute();
    if (status == INTERP_EXIT) break;
    if (status > INTERP_MIN_ERROR) return fail(status);
  }
  std::printf("X\n");
  std::fflush(stdout);
  std::_Exit(0);  // the interpreter's exit handlers would write to the parameter file
}
