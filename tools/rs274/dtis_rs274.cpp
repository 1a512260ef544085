// dtis-rs274: a G-code program run through LinuxCNC's own RS274/NGC interpreter (librs274), its
// canonical machining calls written to standard output as text records that dtis reads
// (io/src/rs274.cpp). This program is the only part of dtis linked with LinuxCNC's interpreter,
// which is GPL-2: it is a separate program so that the dtis library keeps its own licence, and so
// that an interpreter failure cannot take the planner (or a machine it feeds) down with it.
//
//   dtis-rs274 PROGRAM.ngc
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
//   X                                        the program's end; the last record
// Exit status: 0 after X, 1 after E, 2 on bad usage.
#include <unistd.h>

#include <canon.hh>
#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <interp_base.hh>
#include <interp_return.hh>
#include <string>

// The tool table the interpreter looks tools up in (G43 H, M6 T). LinuxCNC's libtooldata keeps it
// in a memory map shared with a running LinuxCNC; this program must not touch that, so it answers
// here (these definitions take the place of libtooldata's): every tool number exists, with no
// offsets. dtis plans the tool tip; the machine applies tool length offsets.
CANON_TOOL_TABLE tooldata_entry_init() {
  CANON_TOOL_TABLE entry = {};
  entry.toolno = -1;
  entry.pocketno = -1;
  return entry;
}
int tooldata_find_index_for_tool(int toolno) { return toolno >= 0 ? toolno : -1; }
int tooldata_get(CANON_TOOL_TABLE* entry, int index) {
  *entry = tooldata_entry_init();
  if (index < 0) return -1;
  entry->toolno = index;
  entry->pocketno = index;
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

// The canon layer's state: what the interpreter told it and asks back.
struct Canon {
  double units = 1.0;  // mm per program unit
  CANON_UNITS unit_type = CANON_UNITS_MM;
  CANON_PLANE plane = CANON_PLANE_XY;
  // Position in program units and the work frame, as the interpreter reckons it.
  double x = 0, y = 0, z = 0, a = 0, b = 0, c = 0, u = 0, v = 0, w = 0;
  double g5x[9] = {}, g92[9] = {};
  double xy_rotation = 0.0;  // degrees
  double feed = 0.0;         // program units per minute (in G93 too: the interpreter converts)
  CANON_MOTION_MODE motion_mode = CANON_CONTINUOUS;
  double tolerance = 0.0;
  double traverse_rate = 1e9;
  bool optional_stop = false, block_delete = false;
  int tool_slot = 0, selected_slot = 0;
  EmcPose tool_offset = {};
  double spindle_speed = 0.0;
  CANON_DIRECTION spindle = CANON_STOPPED;
  int flood = 0, mist = 0;
};
Canon canon;

struct Xyz {
  double x, y, z;
};

// A program-frame point to the machine frame in mm: G92, the XY rotation, the work offset.
Xyz ToMachine(double x, double y, double z) {
  x = (x + canon.g92[0]) * canon.units;
  y = (y + canon.g92[1]) * canon.units;
  z = (z + canon.g92[2]) * canon.units;
  const double r = canon.xy_rotation * M_PI / 180.0;
  const double cr = std::cos(r), sr = std::sin(r);
  return {cr * x - sr * y + canon.g5x[0] * canon.units,
          sr * x + cr * y + canon.g5x[1] * canon.units, z + canon.g5x[2] * canon.units};
}
// A direction (the arc's axis) to the machine frame.
Xyz Rotated(double x, double y, double z) {
  const double r = canon.xy_rotation * M_PI / 180.0;
  return {std::cos(r) * x - std::sin(r) * y, std::sin(r) * x + std::cos(r) * y, z};
}
double Angle(double value, int k) { return value + canon.g92[k] + canon.g5x[k]; }

void Record(const char* kind, int line, std::initializer_list<double> values) {
  std::printf("%s %d", kind, line);
  for (const double v : values) std::printf(" %.17g", v);
  std::printf("\n");
}

void Note(int line, const char* what) { std::printf("I %d %s\n", line, what); }

int current_line = 0;  // the line of the block being executed, for calls without one

void Straight(const char* kind, int line, double x, double y, double z, double a, double b,
              double c, double u, double v, double w) {
  const Xyz p = ToMachine(x, y, z);
  Record(kind, line, {p.x, p.y, p.z, Angle(a, 3), Angle(b, 4), Angle(c, 5)});
  canon.x = x, canon.y = y, canon.z = z, canon.a = a, canon.b = b, canon.c = c;
  canon.u = u, canon.v = v, canon.w = w;
}

}  // namespace

// ---- What the interpreter calls: motion. ----

void STRAIGHT_TRAVERSE(int line, double x, double y, double z, double a, double b, double c,
                       double u, double v, double w) {
  Straight("T", line, x, y, z, a, b, c, u, v, w);
}

void STRAIGHT_FEED(int line, double x, double y, double z, double a, double b, double c, double u,
                   double v, double w) {
  Straight("L", line, x, y, z, a, b, c, u, v, w);
}

void ARC_FEED(int line, double first_end, double second_end, double first_axis, double second_axis,
              int rotation, double axis_end_point, double a, double b, double c, double u, double v,
              double w) {
  // The plane's first and second axes and its normal (first x second): XY, YZ, ZX.
  double end[3], centre[3], normal[3] = {0, 0, 0};
  int i1 = 0, i2 = 1, in = 2;
  if (canon.plane == CANON_PLANE_YZ) i1 = 1, i2 = 2, in = 0;
  if (canon.plane == CANON_PLANE_XZ) i1 = 2, i2 = 0, in = 1;
  const double start[3] = {canon.x, canon.y, canon.z};
  end[i1] = first_end, end[i2] = second_end, end[in] = axis_end_point;
  centre[i1] = first_axis, centre[i2] = second_axis, centre[in] = start[in];
  normal[in] = 1.0;
  const Xyz e = ToMachine(end[0], end[1], end[2]);
  const Xyz k = ToMachine(centre[0], centre[1], centre[2]);
  const Xyz n = Rotated(normal[0], normal[1], normal[2]);
  Record("A", line,
         {e.x, e.y, e.z, k.x, k.y, k.z, n.x, n.y, n.z, static_cast<double>(rotation), Angle(a, 3),
          Angle(b, 4), Angle(c, 5)});
  canon.x = end[0], canon.y = end[1], canon.z = end[2];
  canon.a = a, canon.b = b, canon.c = c, canon.u = u, canon.v = v, canon.w = w;
}

void NURBS_FEED(int line, std::vector<CONTROL_POINT> points, unsigned int order) {
  if (points.empty()) return;
  std::printf("N %d %u %.17g %.17g %.17g %.17g %zu", line, order, ToMachine(0, 0, canon.z).z,
              Angle(canon.a, 3), Angle(canon.b, 4), Angle(canon.c, 5), points.size());
  for (const CONTROL_POINT& p : points) {
    const Xyz q = ToMachine(p.X, p.Y, canon.z);
    std::printf(" %.17g %.17g %.17g", q.x, q.y, p.W);
  }
  std::printf("\n");
  canon.x = points.back().X, canon.y = points.back().Y;
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
  const double o[9] = {x, y, z, a, b, c, u, v, w};
  std::memcpy(canon.g5x, o, sizeof o);
}
void SET_G92_OFFSET(double x, double y, double z, double a, double b, double c, double u, double v,
                    double w) {
  const double o[9] = {x, y, z, a, b, c, u, v, w};
  std::memcpy(canon.g92, o, sizeof o);
}
void SET_XY_ROTATION(double degrees) { canon.xy_rotation = degrees; }
void USE_TOOL_LENGTH_OFFSET(EmcPose offset) {
  canon.tool_offset = offset;
  Note(current_line, "tool length offset (G43/G49): the machine applies it, dtis plans the tip");
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
void PALLET_SHUTTLE() { Note(current_line, "pallet shuttle (M30, M60)"); }
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
void PROGRAM_STOP() { Note(current_line, "program stop (M0): not taken"); }
void PROGRAM_END() {}
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
double GET_EXTERNAL_LENGTH_UNITS() { return 1.0 / canon.units; }
CANON_UNITS GET_EXTERNAL_LENGTH_UNIT_TYPE() { return canon.unit_type; }
double GET_EXTERNAL_ANGLE_UNITS() { return 1.0; }
double GET_EXTERNAL_POSITION_X() { return canon.x; }
double GET_EXTERNAL_POSITION_Y() { return canon.y; }
double GET_EXTERNAL_POSITION_Z() { return canon.z; }
double GET_EXTERNAL_POSITION_A() { return canon.a; }
double GET_EXTERNAL_POSITION_B() { return canon.b; }
double GET_EXTERNAL_POSITION_C() { return canon.c; }
double GET_EXTERNAL_POSITION_U() { return canon.u; }
double GET_EXTERNAL_POSITION_V() { return canon.v; }
double GET_EXTERNAL_POSITION_W() { return canon.w; }
double GET_EXTERNAL_PROBE_POSITION_X() { return canon.x; }
double GET_EXTERNAL_PROBE_POSITION_Y() { return canon.y; }
double GET_EXTERNAL_PROBE_POSITION_Z() { return canon.z; }
double GET_EXTERNAL_PROBE_POSITION_A() { return canon.a; }
double GET_EXTERNAL_PROBE_POSITION_B() { return canon.b; }
double GET_EXTERNAL_PROBE_POSITION_C() { return canon.c; }
double GET_EXTERNAL_PROBE_POSITION_U() { return canon.u; }
double GET_EXTERNAL_PROBE_POSITION_V() { return canon.v; }
double GET_EXTERNAL_PROBE_POSITION_W() { return canon.w; }
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
double GET_EXTERNAL_TOOL_LENGTH_XOFFSET() { return canon.tool_offset.tran.x; }
double GET_EXTERNAL_TOOL_LENGTH_YOFFSET() { return canon.tool_offset.tran.y; }
double GET_EXTERNAL_TOOL_LENGTH_ZOFFSET() { return canon.tool_offset.tran.z; }
double GET_EXTERNAL_TOOL_LENGTH_AOFFSET() { return canon.tool_offset.a; }
double GET_EXTERNAL_TOOL_LENGTH_BOFFSET() { return canon.tool_offset.b; }
double GET_EXTERNAL_TOOL_LENGTH_COFFSET() { return canon.tool_offset.c; }
double GET_EXTERNAL_TOOL_LENGTH_UOFFSET() { return canon.tool_offset.u; }
double GET_EXTERNAL_TOOL_LENGTH_VOFFSET() { return canon.tool_offset.v; }
double GET_EXTERNAL_TOOL_LENGTH_WOFFSET() { return canon.tool_offset.w; }
CANON_TOOL_TABLE GET_EXTERNAL_TOOL_TABLE(int pocket) {
  (void)pocket;
  return tooldata_entry_init();
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

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: dtis-rs274 PROGRAM.ngc\n");
    return 2;
  }
  // The interpreter reads the INI a LinuxCNC session names in the environment (its subroutine
  // path, remaps, Python plugins, log file): a program must read the same wherever dtis runs.
  ::unsetenv("INI_FILE_NAME");
  InterpBase* interp = makeInterp();
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
  if (std::FILE* f = std::fopen(parameter_file.c_str(), "w")) std::fclose(f);
  int status = interp->init();
  // Read (empty) and written back at init; the program's parameters are its own and not kept.
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
  for (;;) {
    status = interp->read();
    if (status == INTERP_ENDFILE) break;
    if (status > INTERP_MIN_ERROR) return fail(status);
    current_line = interp->sequence_number();
    status = interp->execute();
    if (status == INTERP_EXIT) break;
    if (status > INTERP_MIN_ERROR) return fail(status);
  }
  std::printf("X\n");
  std::fflush(stdout);
  std::_Exit(0);  // the interpreter's exit handlers would write to the parameter file
}
