// Job files (TOML): what to plan, on which machine, with which interpolator and where the outputs
// go. Input paths are relative to the job file; output paths are relative to the current folder.
// See samples/jobs/ and the README for every key.
#pragma once

#include <functional>
#include <memory>
#include <optional>
#include <string>

#include "dtis/core/machine.hpp"
#include "dtis/core/path_source.hpp"
#include "dtis/geometry/arc_length.hpp"
#include "dtis/geometry/tool.hpp"
#include "dtis/interp/taylor.hpp"
#include "dtis/interp/verifier.hpp"
#include "dtis/interp/vpop.hpp"
#include "dtis/io/gcode_program.hpp"
#include "dtis/strategies/strategy.hpp"

namespace dtis::io {

enum class InterpolatorKind { kVpop, kTaylor1, kTaylor2 };

struct PathSpec {
  enum class Kind { kLine, kCurve, kGcode } kind = Kind::kLine;
  Eigen::Vector3d from = Eigen::Vector3d::Zero(), to = Eigen::Vector3d::Zero();
  std::string curve_file;  // resolved
  std::string gcode_file;  // resolved
  GcodeOptions gcode;
  Eigen::Vector3d tool_axis = Eigen::Vector3d::UnitZ();
};

// A surface job (DTIS): a face of a STEP file, a tool, an orientation rule and a strategy.
struct SurfaceSpec {
  std::string step_file;  // resolved
  int face = 1;
  // Set-up: the part rotated about X, then Y, then Z (degrees), then moved (mm).
  Eigen::Vector3d rotate_deg = Eigen::Vector3d::Zero();
  Eigen::Vector3d translate_mm = Eigen::Vector3d::Zero();
  geometry::Tool tool;
  strategies::Orientation orientation;
  strategies::StrategySpec strategy;
  double clearance_mm = 5.0;    // links retract to this height above the face's highest point
  double link_feed_mm_s = 0.0;  // 0: the job's feed
};

struct Job {
  std::string file;  // the job file itself
  std::string name;
  std::string machine_file;  // resolved
  PathSpec path;
  std::optional<SurfaceSpec> surface;  // set for surface jobs ([surface] instead of [path])
  InterpolatorKind interpolator = InterpolatorKind::kVpop;
  interp::VpopOptions vpop;
  interp::TaylorOptions taylor;
  geometry::ArcLengthOptions arc_length;
  std::string setpoints_out;  // as written in the job ("" if none)
  std::string limiters_out;
};

// Throws dtis::Error naming the file, line and key.
Job LoadJob(const std::string& path);
Job ParseJob(std::string_view text, const std::string& source_name);

// What a run produced, before anything is written.
struct RunResult {
  std::unique_ptr<Machine> machine;
  interp::SetpointTable table;
  std::vector<double> arc_length;           // per setpoint (VPOp only)
  std::vector<interp::LimiterId> limiters;  // per setpoint (VPOp only)
  interp::VpopSummary vpop;
  interp::TaylorResult taylor;
  interp::VerifyReport verify;
  double compute_s = 0.0;  // planning time, wall clock
  double path_length_mm = 0.0;
  // G-code jobs.
  int blocks = 0, chains = 0, rapids = 0, corners = 0;
  // Surface jobs.
  int passes = 0;
  int links = 0;
  double stepover_mm = 0.0;
  double pass_motion_s = 0.0;  // time spent on the passes (links excluded)
};

struct RunOptions {
  int threads = 0;  // surface jobs plan passes in parallel; 0: all cores
  // Called as segments (passes and links) finish: (done, total). From any thread.
  std::function<void(int, int)> progress;
};

// Loads the machine and the path, plans, and verifies the result with the independent verifier.
RunResult RunJob(const Job& job, const RunOptions& options = {});

// The summary a run prints on stderr.
std::string FormatRunSummary(const Job& job, const RunResult& result);

// Writes the setpoints (and the limiter report if asked) atomically.
void WriteRunOutputs(const Job& job, const RunResult& result, const std::string& setpoints_path,
                     const std::string& limiters_path);

// Builds the PathSource a job describes (for library users and tests).
std::unique_ptr<PathSource> BuildPath(const Job& job);

}  // namespace dtis::io
