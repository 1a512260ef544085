// libFuzzer target for one parser, chosen by DTIS_FUZZ_PARSER (see CMakeLists.txt): any input
// either parses or throws dtis::Error; nothing else may escape.
#include <cstddef>
#include <cstdint>
#include <string_view>

#include "dtis/core/error.hpp"
#include "dtis/io/curve_file.hpp"
#include "dtis/io/gcode.hpp"
#include "dtis/io/job.hpp"
#include "dtis/io/setpoint_file.hpp"
#include "dtis/io/tool_table.hpp"
#include "dtis/kinematics/machines.hpp"

namespace {

#define DTIS_PARSER_job 1
#define DTIS_PARSER_curve 2
#define DTIS_PARSER_machine 3
#define DTIS_PARSER_setpoints 4
#define DTIS_PARSER_gcode 5
#define DTIS_PARSER_limiters 6
#define DTIS_PARSER_rs274 7
#define DTIS_PARSER_machine_ini 8
#define DTIS_PARSER_tool_table 9
#define DTIS_CAT(a, b) a##b
#define DTIS_SELECT(x) DTIS_CAT(DTIS_PARSER_, x)
#define DTIS_PARSER DTIS_SELECT(DTIS_FUZZ_PARSER)

void Parse(std::string_view text) {
#if DTIS_PARSER == DTIS_PARSER_job
  dtis::io::ParseJob(text, "fuzz.toml");
#elif DTIS_PARSER == DTIS_PARSER_curve
  dtis::io::ParseCurveFile(text, "fuzz.toml");
#elif DTIS_PARSER == DTIS_PARSER_machine
  dtis::kinematics::ParseMachine(text, "fuzz.toml");
#elif DTIS_PARSER == DTIS_PARSER_machine_ini
  dtis::kinematics::MachineLoadOptions o;
  o.jerk_time_s = 0.02;
  dtis::kinematics::BuildMachine(dtis::kinematics::ParseLinuxcncIni(text, "fuzz.ini", o));
#elif DTIS_PARSER == DTIS_PARSER_setpoints
  dtis::io::ParseSetpoints(text, "fuzz.csv");
#elif DTIS_PARSER == DTIS_PARSER_gcode
  dtis::io::ParseGcode(text, "fuzz.ngc");
#elif DTIS_PARSER == DTIS_PARSER_rs274
  dtis::io::ParseRs274Records(text, "fuzz.ngc");
#elif DTIS_PARSER == DTIS_PARSER_tool_table
  dtis::io::ParseToolTable(text, "fuzz.tbl");
#elif DTIS_PARSER == DTIS_PARSER_limiters
  dtis::io::ParseLimiters(text, "fuzz.csv", {"X", "Y", "Z", "A", "C"});
#else
#error \
    "DTIS_FUZZ_PARSER must be job, curve, machine, machine_ini, setpoints, limiters, gcode, rs274 or tool_table"
#endif
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    Parse(std::string_view(reinterpret_cast<const char*>(data), size));
  } catch (const dtis::Error&) {
  }
  return 0;
}
