// Job files (TOML): what to plan, on which machine, with which interpolator and where the outputs
// go. Input paths are relative to the job file; output paths are relative to the current folder.
// See samples/jobs/ and the README for every key.
#pragma once

#include <memory>
#include <string>

#include "dtis/core/machine.hpp"
#include "dtis/core/path_source.hpp"
#include "dtis/geometry/arc_length.hpp"
#include "dtis/interp/taylor.hpp"
#include "dtis/interp/verifier.hpp"
#include "dtis/interp/vpop.hpp"

namespace dtis::io {

enum class InterpolatorKind { kVpop, kTaylor1, kTaylor2 };

struct PathSpec {
  enum class Kind { kLine, kCurve } kind = Kind::kLine;
  Eigen::Vector3d from = Eigen::Vector3d::Zero(), to = Eigen::Vector3d::Zero();
  std::string curve_file;  // resolved
  Eigen::Vector3d tool_axis = Eigen::Vector3d::UnitZ();
};

struct Job {
  std::string file;  // the job file itself
  std::string name;
  std::string machine_file;  // resolved
  PathSpec path;
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
};

// Loads the machine and the path, plans, and verifies the result with the independent verifier.
RunResult RunJob(const Job& job);

// The summary a run prints on stderr.
std::string FormatRunSummary(const Job& job, const RunResult& result);

// Writes the setpoints (and the limiter report if asked) atomically.
void WriteRunOutputs(const Job& job, const RunResult& result, const std::string& setpoints_path,
                     const std::string& limiters_path);

// Builds the PathSource a job describes (for library users and tests).
std::unique_ptr<PathSource> BuildPath(const Job& job);

}  // namespace dtis::io
