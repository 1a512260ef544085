// Job files (TOML): what to plan, on which machine, with which interpolator and where the outputs
// go. Input paths are relative to the job file; output paths are relative to the current folder.
// See samples/jobs/ and the README for every key.
#pragma once

#include <cmath>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>

#include "dtis/core/machine.hpp"
#include "dtis/core/path_source.hpp"
#include "dtis/geometry/arc_length.hpp"
#include "dtis/geometry/face_mesh.hpp"
#include "dtis/geometry/link_height.hpp"
#include "dtis/geometry/step_model.hpp"
#include "dtis/geometry/tool.hpp"
#include "dtis/interp/taylor.hpp"
#include "dtis/interp/verifier.hpp"
#include "dtis/interp/vpop.hpp"
#include "dtis/io/gcode_program.hpp"
#include "dtis/kinematics/machines.hpp"
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

// A face of a STEP file: by the number `dtis faces` gives it, or by the name the file gives it.
struct FaceRef {
  int index = 0;     // 1-based; 0 when named
  std::string name;  // a name stands for every face the file gives it
};

// A surface job (DTIS): faces of a STEP file, a tool, an orientation rule and a strategy.
struct SurfaceSpec {
  std::string step_file;  // resolved
  // The faces finished, in this order: each face's passes, then the next face's.
  std::vector<FaceRef> faces{FaceRef{1, {}}};
  // "job.toml:3: key 'surface.face'": where the faces were given, for what only the STEP file
  // shows wrong (a name no face has).
  std::string faces_key;
  // The faces the tool must not go into besides those it finishes: every other face of the
  // file (nullopt, `check_faces = "others"`), none (empty), or these.
  std::optional<std::vector<FaceRef>> check_faces;
  std::string check_faces_key;
  double check_tolerance_mm = 1e-3;  // how far a checked face may lie inside the tool
  // The tool's reach up its axis from the tip, holder included, checked against those faces.
  double tool_length_mm = INFINITY;
  // Set-up: the part rotated about X, then Y, then Z (degrees), then moved (mm).
  Eigen::Vector3d rotate_deg = Eigen::Vector3d::Zero();
  Eigen::Vector3d translate_mm = Eigen::Vector3d::Zero();
  geometry::Tool tool;
  strategies::Orientation orientation;
  strategies::StrategySpec strategy;
  double clearance_mm = 5.0;    // links clear the faces by this (geometry/link_height.hpp)
  double link_feed_mm_s = 0.0;  // 0: the job's feed
};

// What `dtis compare` measures a surface job against: the exports a CAM system would make of its
// passes (Beudaert et al. 2014, Tab. 1).
struct CompareSpec {
  std::vector<double> g1_tolerances_mm{0.01, 0.001};       // chordal tolerance of each G1 export
  std::vector<double> bspline_tolerances_mm{0.01, 0.001};  // of each B-spline export
  // 5-axis exports keep the tool axis within this of the exact one (as the top point, top_height_mm
  // up the axis, within top_height * tan(orientation_tol)).
  double orientation_tol_deg = 0.1;
  double sample_step_mm = 0.01;  // the exact passes are sampled this finely for the exports
  // Corner smoothing of the G1 variants (contour_tol_mm, orientation_tol_mm, top_height_mm).
  geometry::CornerOptions corners;
};

struct Job {
  std::string file;  // the job file itself
  std::string name;
  std::string machine_file;                        // resolved
  kinematics::MachineLoadOptions machine_options;  // machine_jerk_time_ms, for INI machines
  PathSpec path;
  std::optional<SurfaceSpec> surface;  // set for surface jobs ([surface] instead of [path])
  CompareSpec compare;                 // [compare], surface jobs only
  InterpolatorKind interpolator = InterpolatorKind::kVpop;
  interp::VpopOptions vpop;
  interp::TaylorOptions taylor;
  geometry::ArcLengthOptions arc_length;
  std::string setpoints_out;  // as written in the job ("" if none)
  std::string limiters_out;
};

// Bounds every job is held to, so that a mistyped number is an error naming its key, never a run
// that does not end: the period, and the least motion time the path can take at the job's feed and
// tangential limits (checked before planning; the planner itself refuses a motion that has not
// ended after as long, wherever its feed collapses).
inline constexpr double kMinPeriodMs = 0.01, kMaxPeriodMs = 100.0;
inline constexpr double kMaxMotionHours = interp::kMaxMotionS / 3600.0;
// [interpolator] end_tolerance_mm at most (a motion may end this far from the path's end) and
// commit_horizon at most (as `--horizon`).
inline constexpr double kMaxEndToleranceMm = 0.01;
inline constexpr long kMaxCommitHorizon = 1L << 30;
// The most setpoints `dtis run` plans (it holds them all; 2.8 h of motion at 1 ms): a longer
// motion streams (`dtis stream`), in constant memory.
inline constexpr long kMaxRunSetpoints = 10'000'000;

// The job's machine, read with the job's machine options, and CheckPeriod'ed.
std::unique_ptr<Machine> LoadJobMachine(const Job& job);
// The planner plans each axis' limits down by what rounding the written positions costs
// (interp::ShortestPeriods): throws dtis::Error naming the key to change (period_ms,
// [interpolator] limit_fraction, or the machine's axis limit) with the shortest period or least
// fraction that plans, when the job's period is too short for `machine`.
void CheckPeriod(const Job& job, const Machine& machine);

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
  // G-code: what the program asked that moves nothing (GcodeProgram::notes).
  std::vector<std::pair<std::string, int>> gcode_notes;
  // Surface jobs.
  int passes = 0;
  int links = 0;
  int checked_faces = 0;  // SurfaceSetup::checked_faces
  int job_faces = 0;      // SurfaceSetup::job_faces
  double stepover_mm = 0.0;
  double pass_motion_s = 0.0;  // time spent on the passes (links excluded)
  // The rows [first, end) of `table` on each pass, in order (PassRows); the rows between are links.
  std::vector<std::pair<long, long>> pass_rows;
  // What the passes leave out where the tool does not fit (PassList::UnreachableText), or "":
  // the first kSummaryUnreachable stretches, then how many more; `unreachable_all` lists them all
  // (for the HTML report).
  std::string unreachable, unreachable_all;
  std::size_t unreachable_count = 0;
};

// How far a run has come, for a progress display.
struct RunProgress {
  // "reading STEP", "tracing passes", "reading G-code", "building contours", "planning",
  // "planning passes", "planning links", "verifying".
  std::string_view phase;
  // Of a planning phase: the share of its path length planned, 0 to 1; < 0 in the other phases.
  double fraction = -1.0;
  double motion_s = 0.0;  // motion time planned so far, the run's earlier phases included
  int segments_done = 0, segments = 0;  // of a planning phase: passes, links or contours finished
};

struct RunOptions {
  int threads = 0;  // surface jobs plan passes in parallel; 0: all cores
  // Called at each phase's start and, while planning, up to 20 times a second (also within a
  // segment) and as each segment finishes. From any thread, never two calls at once.
  std::function<void(const RunProgress&)> progress;
};

// Throws dtis::Error, naming the job and the key to look at, when a path of `length_mm` cannot be
// followed in less than kMaxMotionHours at the job's feed (not for G-code: its F words rule),
// within its tangential acceleration and jerk (a rest-to-rest move of that length needs at least
// 2 sqrt(L / A) and (32 L / J)^(1/3)), with a Taylor interpolator's ramps (2 accel_time_s), or
// in `program_least_s` (a G-code program's GcodePlan::least_time_s).
void CheckMotionBound(const Job& job, double length_mm, double program_least_s = 0.0);
// CheckMotionBound, and for `dtis run`, which holds every setpoint (about 300 bytes each), no
// more than kMaxRunSetpoints setpoints at the job's period.
void CheckRunBound(const Job& job, double length_mm, double program_least_s = 0.0);

// Loads the machine and the path, plans, and verifies the result with the independent verifier.
RunResult RunJob(const Job& job, const RunOptions& options = {});

// The summary a run prints on stderr.
std::string FormatRunSummary(const Job& job, const RunResult& result);

// "VPOp", "Taylor order 1", "Taylor order 2".
const char* InterpolatorName(InterpolatorKind kind);

// Whether a run's setpoints may be written: VPOp setpoints the verifier fails never reach a file a
// machine could be fed from. The Taylor interpolators keep no limits (they are there to compare
// with): theirs always may.
bool FitToWrite(const Job& job, const RunResult& result);
// Why a run is not FitToWrite: "JOB: the verifier fails these setpoints (worst ratio R, WHERE)".
std::string UnfitMessage(const Job& job, const RunResult& result);

// Writes the setpoints (and the limiter report if asked) atomically. Throws dtis::Error, writing
// nothing, when the run is not FitToWrite, unless `keep_failed` (to study a failure).
void WriteRunOutputs(const Job& job, const RunResult& result, const std::string& setpoints_path,
                     const std::string& limiters_path, bool keep_failed = false);

// A surface job's passes and how they are linked (for RunJob and the comparison of exports).
// How many unreachable stretches the run summary lists (the report lists them all).
inline constexpr std::size_t kSummaryUnreachable = 8;

struct SurfaceSetup {
  strategies::PassList passes;
  // How many faces of the file the tool was kept out of that the job does not finish (the part's
  // others, or check_faces); each face's passes are also kept out of the job's other faces.
  int checked_faces = 0;
  int job_faces = 0;  // how many faces the job finishes
  // The heights links traverse at: the clearance above the face where the tool passes
  // (geometry/link_height.hpp). Found on first use, from any thread: a job with one pass and no
  // link to it never meshes the face.
  std::shared_ptr<const geometry::LinkHeights> link_heights;
  double clearance_mm = 0.0;  // links back off this far along the tool axis first
  interp::VpopOptions pass_options, link_options;
  // The links' corners are smoothed as the G1 variants' rapids are ([compare] contour_tol_mm ...).
  geometry::CornerOptions link_corners;
};
// `phase`, if given, is called as the STEP file is read and as the passes are traced.
SurfaceSetup SetUpSurface(const Job& job, const std::function<void(std::string_view)>& phase = {});
// Refuses a surface job before planning where its passes leave the machine's travel: each pass's
// start, end and poses every `step_mm` of arc length between, and the ends of the link moves
// between passes (where they back off, rise, traverse and come down), through machine.Inverse.
// Throws dtis::Error in the planner's words (axis, required value, travel), naming the face, pass
// and arc length, prefixed with `job_file`. A pose the planner would fail on for another reason
// (no convergence, a branch jump) is left for the planner to report.
inline constexpr double kTravelCheckStepMm = 5.0;
void CheckPassesInTravel(const SurfaceSetup& setup, const Machine& machine,
                         const std::string& job_file, double step_mm = kTravelCheckStepMm);
// The faces a surface job names, as numbers of its STEP file's faces, in the job's order. Throws
// dtis::Error naming the job's key for a name no face has or a face given twice.
std::vector<int> JobFaces(const SurfaceSpec& spec, const geometry::StepModel& model);
// "3", "3, 'floor'": the job's faces as it gives them.
std::string FaceRefsText(const SurfaceSpec& spec);
// "face 3", "faces 3, 'floor'".
std::string DescribeFaces(const SurfaceSpec& spec);
// A surface job's faces as triangles, placed as the job places them (for reports).
geometry::FaceMesh MeshJobSurface(const Job& job);

struct PassProgram {
  interp::ProgramResult program;
  std::vector<int> pass_of_segment;  // per segment of `program`: its pass (0-based), -1: a link
  int links = 0;
};
// Paths planned as a surface job's passes, in order, each linked to the next by LinkMoves from
// where it really ended (its last setpoint). `passes[k]` may be the exact pass k or any export of
// it (a fitted B-spline): the links are the same. Throws dtis::Error prefixed with `job_file`.
PassProgram PlanPasses(const std::vector<const PathSource*>& passes, const SurfaceSetup& setup,
                       const Machine& machine, const RunOptions& options,
                       const std::string& job_file);
// The setpoint rows [first, end) of each pass of `pp`, in pass order (links left out).
std::vector<std::pair<long, long>> PassRows(const PassProgram& pp);

// Builds the PathSource a job describes (for library users and tests).
std::unique_ptr<PathSource> BuildPath(const Job& job);

}  // namespace dtis::io
